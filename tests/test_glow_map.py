"""The glow shot's photons as a map of their own beside an aimed caustic map
(engine/render.py GLOW_MAP_APART, glow_radius; docs/accuracy.md "tableroom45").

Where a caster is aimed at and rough specular layers send light onto diffuse surfaces
too, the glow shot's photons (L S_rough D) used to join the aimed caustic photons in one
map under the caustic cap (the global photons' spacing); on a window-lit room's back wall
that left 4 photons (1.9 effective) a disc: blotches. They now make a map of their own,
capped at their own spacing. The photons are the same ones: the two maps hold together
exactly what the one map held, and the glow's cap is never below the caustic map's.
"""
import importlib
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import prepare_context, shoot_photons
from engine.scene import Material

render_mod = importlib.import_module("engine.render")  # (engine.render is also a function)


def _yard_with_ball():
    """A sunlit ground of rough metal (its glow lights the shaded front of a wall) and a
    glass ball on it (an aimed caustic caster); the camera faces the wall."""
    s = PaperScene(width=24, height=18, background=(0.0, 0.0, 0.0))
    s.add_material(Material("brushed", (0.6, 0.6, 0.6), metallic=0.5, roughness=0.5))
    s.add_material(Material("plaster", (0.8, 0.78, 0.72), roughness=0.9, specular=1.0))
    s.add_plane((0, 0, 0), size=12.0, material="brushed", name="ground")
    s.add_box((0, 2.1, 1.25), (4.0, 0.2, 2.5), "plaster", name="wall")
    s.add_sphere((3.0, 0.5, 0.3), 0.3, "glass", name="Ball")  # (beside the shade)
    e = math.radians(35)
    s.add_sun(direction=(0.0, -math.cos(e), -math.sin(e)), strength=3.0)
    s.set_camera((0.3, -6.5, 1.3), (0, 2.0, 1.0), view_angle=40)
    return s


def _maps(apart, monkeypatch):
    monkeypatch.setattr(render_mod, "GLOW_MAP_APART", apart)
    monkeypatch.setattr(render_mod, "EDGE_IMAGES", False)  # (the photons alone)
    monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.0)  # every global photon
    ctx = prepare_context(_yard_with_ball(), RenderSettings(
        photons=8_000, caustic_photons=2_000, seed=2, workers=1))
    try:
        stats = {}
        shots = shoot_photons(ctx, stats)
        return ctx, stats, shots
    finally:
        ctx.accel.close()


def _photons(pmap):
    """(position, power) of a map's stored photons, ordered by position."""
    ph = pmap.photons
    key = np.lexsort(ph.position.T)
    return ph.position[key], ph.power[key]


def test_the_glow_map_holds_the_glow_photons_the_caustic_map_held(monkeypatch):
    one, st_one, shots_one = _maps(False, monkeypatch)
    two, st_two, shots_two = _maps(True, monkeypatch)
    assert st_one.get("glow_photons_emitted") and st_two.get("glow_photons_emitted")
    assert one.glow_map is None and two.glow_map is not None
    assert st_two["glow_photons"] > 0 and st_two["caustic_photons"] > 0
    # The same photons, split between the two maps.
    merged = st_one["caustic_photons"]
    assert st_two["caustic_photons"] + st_two["glow_photons"] == merged
    p1, w1 = _photons(one.caustic_map)
    pc, wc = _photons(two.caustic_map)
    pg, wg = _photons(two.glow_map)
    both = np.concatenate([pc, pg])
    key = np.lexsort(both.T)
    assert np.array_equal(both[key], p1)
    assert np.array_equal(np.concatenate([wc, wg])[key], w1)
    # The glow's cap: its own spacing, never below the caustic cap, at most 0.1 x extent.
    assert st_two["radius_caustic"] == st_one["radius_caustic"]
    assert two.glow_radius >= two.caustic_radius
    assert two.glow_radius <= 0.1 * two.geo.extent + 1e-12
    # The photons the pass returns for the photon-hit view, and the shots' bytes it
    # counts: the same with the glow photons in a map of their own (global, glow, caustic
    # shots); the maps' bytes count the glow map too.
    assert len(shots_one) == 2 and len(shots_two) == 3
    assert len(shots_two[1]) >= st_two["glow_photons"] > 0
    assert sum(map(len, shots_two)) == sum(map(len, shots_one))
    assert st_two["shot_bytes"] == st_one["shot_bytes"] == sum(
        ph.nbytes for ph in shots_two)
    from engine.resources import held_bytes
    for ctx, st in ((one, st_one), (two, st_two)):
        assert st["photon_bytes"] == held_bytes(*(getattr(ctx, f)
                                                  for f in render_mod.MAP_FIELDS))
    # The stored photons the teaching table counts: the same (glow ones included).
    from engine.teaching import _photons_stored
    assert _photons_stored(st_two) == _photons_stored(st_one) > st_one["global_photons"]
    # The maps line says how many are in the glow map and its own cap.
    settings = RenderSettings()
    line = render_mod.photon_map_report(settings, st_two)[0]
    assert (f"stored in the Caustic pass ({st_two['glow_photons']:,} of them, in a map of "
            f"their own: search radius at most {two.glow_radius:.4g} m)") in line, line
    assert "in a map of their own" not in render_mod.photon_map_report(settings, st_one)[0]


def test_glow_radius_is_the_own_spacing_between_the_caustic_cap_and_the_scene_bound():
    rng = np.random.default_rng(5)
    # 1,000 photons spread over a 4 x 4 m floor: the 64th nearest at ~sqrt(64 / (pi x
    # 62.5 / m^2)) = 0.57 m (more at the floor's edges), the cap twice the median.
    pos = np.c_[rng.uniform(-2, 2, 1000), rng.uniform(-2, 2, 1000), np.zeros(1000)]
    r = render_mod.glow_radius(0.05, 16.0, pos, 64, 20.0)
    assert 1.1 < r < 1.4, r
    assert render_mod.glow_radius(2.0, 16.0, pos, 64, 20.0) == 2.0   # the caustic cap
    assert render_mod.glow_radius(0.05, 16.0, pos, 64, 4.0) == pytest.approx(0.4)
    assert render_mod.glow_radius(0.07, 16.0, pos[:0], 64, 20.0) == 0.07


@pytest.mark.parametrize("kept", [0, 3])
def test_a_glow_shot_of_none_or_few_stored_photons_renders(kept, monkeypatch):
    """A glow shot that stores none (or 3) photons still makes its map: no photon, the
    image of the caustic map alone, bit for bit (GLOW_MAP_APART off holds the same
    photons in one map), its cap the caustic one; 3 photons, a finite, non-negative image
    whose glow cap is auto_radius's area-based one (fewer photons than k), at most 0.1 x
    the scene's extent."""
    traced = render_mod.trace_photons

    def few(*a, **kw):
        ph = traced(*a, **kw)
        return ph.take(np.arange(min(kept, len(ph)))) if kw.get("stream") == \
            render_mod.GLOW_STREAM else ph
    monkeypatch.setattr(render_mod, "trace_photons", few)
    settings = RenderSettings(photons=8_000, caustic_photons=2_000, seed=2, workers=1, spp=1)
    films = {}
    for apart in (True, False):
        monkeypatch.setattr(render_mod, "GLOW_MAP_APART", apart)
        films[apart] = _yard_with_ball().render(settings)
    st = films[True].stats
    assert st["glow_photons"] == kept and st["glow_photons_emitted"] > 1000
    img = np.asarray(films[True].combined)
    assert np.isfinite(img).all() and img.min() >= 0.0
    if kept == 0:
        assert st["radius_glow"] == st["radius_caustic"]
        np.testing.assert_array_equal(img, np.asarray(films[False].combined))
    else:
        assert st["radius_caustic"] < st["radius_glow"] <= 0.1 * st["extent"] + 1e-12
