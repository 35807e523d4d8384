"""The glow shot's size from the glow's share (engine/render.py glow_split, engine/
visualimportance.py glow_share; docs/performance.md "exterior42").

The glow (light whose first scatter is a rough specular layer: L S_rough D) comes from a
caustic-only shot of GLOW_SPLIT x lighter photons where the global shot is aimed by visual
importance. Its size now follows the glow's rms share of the light the camera sees: a
split between 1 and GLOW_SPLIT. Whatever the split, the shot's expected power anywhere is
the lights' own (the same emission-space split, photons split x lighter), so the glow's
power on a wall must agree between the largest and the smallest shot within
the photons' own statistical error; and a scene whose surfaces have no specular layer
holds no caustic-kind photon: share 0.
"""
import importlib
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.photons import CAUSTIC
from engine.render import prepare_context, shoot_photons
from engine.scene import Material
from engine import visualimportance as vi

render_mod = importlib.import_module("engine.render")  # (engine.render is also a function)

WALL_Y = 2.0


def _yard(plaster: bool = True):
    """A 12 m ground and a 4 x 0.2 x 2.5 m wall facing -y, the sun behind the wall (its
    front in shade, lit by the sunlit ground's rough metal: the glow); the camera in front of the wall."""
    s = PaperScene(width=48, height=36, background=(0.0, 0.0, 0.0))
    ground = "white_plastic_dull"
    if plaster:
        # Half rough metal (too rough to focus light: no caustic caster; half diffuse,
        # so gather rays from the wall end on it) and a plaster wall.
        s.add_material(Material("brushed", (0.6, 0.6, 0.6), metallic=0.5, roughness=0.5))
        s.add_material(Material("plaster", (0.8, 0.78, 0.72), roughness=0.9, specular=1.0))
        ground = "brushed"
    s.add_plane((0, 0, 0), size=12.0, material=ground, name="ground")
    s.add_box((0, WALL_Y + 0.1, 1.25), (4.0, 0.2, 2.5), "plaster" if plaster else ground,
              name="wall")
    # From behind the wall (+y), 35 degrees up: the wall's front (y = WALL_Y) is shaded.
    e = math.radians(35)
    s.add_sun(direction=(0.0, -math.cos(e), -math.sin(e)), strength=3.0)
    s.set_camera((0.3, -6.5, 1.3), (0, WALL_Y, 1.25), view_angle=40)
    return s


def _shots(scene, full_share, monkeypatch, seed=2, photons=20_000):
    monkeypatch.setattr(render_mod, "GLOW_SHARE_FULL", full_share)
    # (every global photon: the glow shot's split alone is under test, not the pilot's
    # count, render.global_photon_count)
    monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.0)
    st = RenderSettings(photons=photons, caustic_photons=5_000, seed=seed, workers=1)
    ctx = prepare_context(scene, st)
    try:
        stats = {}
        shots = shoot_photons(ctx, stats)
        return shots, ctx.geo.offset, stats
    finally:
        ctx.accel.close()


def _wall_glow(ph, offset):
    """Power (W, red) of the caustic-kind photons on the wall and its standard error
    (sqrt of the summed squared powers), and their count."""
    p = ph.position.astype(np.float64) + offset
    sel = (ph.kind == CAUSTIC) & (p[:, 2] > 0.01)  # (the ground holds none: a plane)
    w = ph.power[sel, 0].astype(np.float64)
    return w.sum(), math.sqrt((w * w).sum()), int(sel.sum())


def test_glow_split_follows_the_share_between_one_and_glow_split():
    split, full = render_mod.glow_split, render_mod.GLOW_SHARE_FULL
    assert split(None) == render_mod.GLOW_SPLIT and split(float("nan")) == render_mod.GLOW_SPLIT
    assert split(0.0) == 1.0 and split(full / render_mod.GLOW_SPLIT) == 1.0
    assert split(full / 2) == pytest.approx(render_mod.GLOW_SPLIT / 2)
    assert split(full) == render_mod.GLOW_SPLIT and split(1.0) == render_mod.GLOW_SPLIT


def test_the_glow_on_a_wall_is_the_same_from_the_largest_and_smallest_shot(
        monkeypatch):
    scene = _yard()
    big, off, st_big = _shots(scene, 1e-12, monkeypatch)     # split GLOW_SPLIT
    small, _, st_small = _shots(scene, 1e12, monkeypatch)    # split 1
    assert st_big["glow_split"] == render_mod.GLOW_SPLIT and st_small["glow_split"] == 1.0
    assert 0.0 < st_big["glow_share"] <= 1.0
    # The glow shot is the caustic map here (nothing focuses light) and shrinks with the split.
    ratio = st_big["glow_photons_emitted"] / st_small["glow_photons_emitted"]
    assert ratio == pytest.approx(render_mod.GLOW_SPLIT, rel=0.02), ratio
    P_big, err_big, n_big = _wall_glow(big[1], off)
    P_small, err_small, n_small = _wall_glow(small[1], off)
    assert n_small > 300 and n_big > 2.5 * n_small, (n_big, n_small)
    assert abs(P_big - P_small) < 4 * math.hypot(err_big, err_small), (
        P_big, err_big, P_small, err_small)


def test_a_scene_without_specular_layers_has_no_glow_share():
    scene = _yard(plaster=False)
    st = RenderSettings(photons=5_000, caustic_photons=0, seed=1, workers=1)
    ctx = prepare_context(scene, st)
    try:
        shot = shoot_photons(ctx, {})[0]
        assert not (shot.kind == CAUSTIC).any()
        assert vi.glow_share(ctx, shot, 0.1 * ctx.geo.extent) == 0.0
    finally:
        ctx.accel.close()


def test_the_glow_and_secondary_shares_come_from_one_search(monkeypatch):
    """glow_and_secondary_shares gives glow_share's and secondary_share's values exactly
    (one search with a power mask per kind: the bits of the zeroed-power estimates); a
    render with a glow shot and final gathering (no pilot here) asks the share estimates
    twice (the glow and secondary shares together, then the indirect share), not three
    times, and reports the secondary share secondary_share gives (fast46)."""
    plain = vi._kind_estimates
    groups = []

    def counted(ctx, shot, radius, rows, kinds, rays, max_photons):
        groups.append(list(kinds))
        return plain(ctx, shot, radius, rows, kinds, rays, max_photons)
    monkeypatch.setattr(vi, "_kind_estimates", counted)
    monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.0)  # (no pilot)
    ctx = prepare_context(_yard(), RenderSettings(photons=20_000, caustic_photons=5_000,
                                                  seed=2, workers=1))
    try:
        stats = {}
        shot = shoot_photons(ctx, stats)[0]
        assert stats.get("glow_photons_emitted") and ctx.secondary_map is not None
        assert groups == [[(CAUSTIC,), (render_mod.CAUSTIC_DIFFUSE,)],
                          [(render_mod.INDIRECT,)]], groups
        r = ctx.global_radius
        assert stats["glow_share"] == vi.glow_share(ctx, shot, r) > 0
        assert stats["secondary_share"] == vi.secondary_share(ctx, shot, r) > 0
        assert vi.glow_and_secondary_shares(ctx, shot, r) == (stats["glow_share"],
                                                              stats["secondary_share"])
    finally:
        ctx.accel.close()
