"""Work sized by the light it carries (docs/performance.md "worldfast43"): the gather map's
points follow the indirect share (render.gather_points), the guide's grids are built only
where "auto" could guide (guiding.can_guide), a glow-only caustic map is estimated at
integrator.GLOW_SAMPLES_PER_PIXEL samples a pixel, and glow_share is capped by the
global search radius. Each is checked for its bounds and for keeping the image's mean."""
import importlib
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.guiding import AUTO_GAIN, CELLS, MAX_GAIN, can_guide
from engine.render import prepare_context, shoot_photons
from engine.scene import Material
from engine import visualimportance as vi

render_mod = importlib.import_module("engine.render")  # (engine.render is also a function)
integrator = importlib.import_module("engine.integrator")


def test_gather_points_follow_the_share_within_bounds():
    gp, full, most = render_mod.gather_points, render_mod.POINTS_SHARE_FULL, \
        render_mod.GATHER_POINTS
    n, k = 400_000, 64
    for share in (None, float("nan"), full, 0.5, 1.0):
        assert gp(n, share, k) == most
    assert gp(n, full / 2, k) == math.ceil(most / 2)
    # never fewer than one point per k / 4 photons, never more than GATHER_POINTS
    assert gp(n, 0.0, k) == math.ceil(4 * n / k)
    assert gp(1_000_000, 0.001, k) == most  # (the floor above GATHER_POINTS)
    assert gp(100_000, 0.001, k) == math.ceil(4 * 100_000 / k)
    shares = np.linspace(0.0, 0.2, 41)
    counts = [gp(300_000, s, k) for s in shares]
    assert all(a <= b for a, b in zip(counts, counts[1:]))  # monotone in the share


def test_can_guide_only_where_a_grid_could_reach_auto_gain():
    assert MAX_GAIN == CELLS - 1
    edge = math.sqrt(AUTO_GAIN / MAX_GAIN)  # 0.080
    assert not can_guide(None) and not can_guide(float("nan")) and not can_guide(0.0)
    assert not can_guide(0.99 * edge) and can_guide(1.01 * edge) and can_guide(1.0)


def _lawn(**st):
    """A sunlit 10 m grey ground with a 1 m box on it, seen from above at an angle: the
    light the camera sees is mostly direct (indirect share ~1-3 %)."""
    s = PaperScene(width=32, height=24, background=(0.0, 0.0, 0.0))
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), size=10.0, material="grey", name="ground")
    s.add_box((0, 0, 0.5), (1.0, 1.0, 1.0), "grey", name="box")
    e = math.radians(40)
    s.add_sun(direction=(0.3, -math.cos(e), -math.sin(e)), strength=3.0)
    s.set_camera((2.5, -4.0, 3.0), (0, 0, 0.4), view_angle=45)
    d = dict(photons=20_000, caustic_photons=0, spp=4, seed=3, workers=1)
    d.update(st)
    return s.render(RenderSettings(**d))


def test_auto_builds_no_grid_at_a_small_share_and_keeps_the_cosine_image():
    auto = _lawn()
    share = auto.stats["indirect_share"]
    assert share is not None and 0.0 < share < math.sqrt(AUTO_GAIN / MAX_GAIN), share
    assert auto.stats["gather_guided"] is False and auto.stats["gather_guide_points"] == 0
    assert "time_gather_guide" not in auto.stats  # (not built)
    off = _lawn(gather_guiding="off")
    np.testing.assert_array_equal(np.asarray(auto.combined), np.asarray(off.combined))


def test_fewer_gather_points_at_a_small_share_keep_the_indirect_mean(monkeypatch):
    """The same photons and camera samples with every point (POINTS_SHARE_FULL 1e-9) and
    with the share's, over 6 seeds: fewer points, the indirect pass's mean the same within
    3 standard errors of the paired differences (other photons become points and others
    estimate: the maps' noise differs, not their mean). GATHER_POINTS scaled down with the
    photons (20k, not 400k) so the share's count binds as in a full render; the photons
    kept at 20k (PHOTONS_SHARE_FULL 0: no pilot, test_photons_by_share.py's rule)."""
    made = []
    monkeypatch.setattr(render_mod, "GATHER_POINTS", 2_000)
    monkeypatch.setattr(render_mod, "PHOTONS_SHARE_FULL", 0.0)

    class Counting(render_mod.GatherMap):
        def __init__(self, *a, **kw):
            super().__init__(*a, **kw)
            made.append(len(self.position))

    def indirect(film):
        return float(np.asarray(film.passes()["indirect"], np.float64)[..., :3].mean())
    monkeypatch.setattr(render_mod, "GatherMap", Counting)
    fewer, every = [], []
    for seed in range(1, 7):
        monkeypatch.setattr(render_mod, "POINTS_SHARE_FULL", 0.1)
        fewer.append(indirect(_lawn(seed=seed, spp=2)))
        monkeypatch.setattr(render_mod, "POINTS_SHARE_FULL", 1e-9)
        every.append(indirect(_lawn(seed=seed, spp=2)))
    assert all(f < e for f, e in zip(made[0::2], made[1::2])), made
    assert sum(made[0::2]) < 0.85 * sum(made[1::2]), made
    d = np.array(fewer) - np.array(every)
    assert min(every) > 0.0
    assert abs(d.mean()) < 3 * d.std(ddof=1) / math.sqrt(len(d)) + 0.005 * np.mean(every), (
        fewer, every)


def _glow_yard():
    """test_glow_split's yard: a shaded wall lit by a sunlit half-metallic rough ground
    (roughness 0.5: a glow, nothing focuses light: the caustic map holds the glow alone)."""
    s = PaperScene(width=32, height=24, background=(0.0, 0.0, 0.0))
    s.add_material(Material("brushed", (0.6, 0.6, 0.6), metallic=0.5, roughness=0.5))
    s.add_material(Material("plaster", (0.8, 0.78, 0.72), roughness=0.9, specular=1.0))
    s.add_plane((0, 0, 0), size=12.0, material="brushed", name="ground")
    s.add_box((0, 2.1, 1.25), (4.0, 0.2, 2.5), "plaster", name="wall")
    e = math.radians(35)
    s.add_sun(direction=(0.0, -math.cos(e), -math.sin(e)), strength=3.0)
    s.set_camera((0.3, -6.5, 1.3), (0, 2.0, 1.25), view_angle=40)
    return s


def test_a_glow_only_caustic_map_at_fewer_samples_keeps_its_mean(monkeypatch):
    """The glow's estimate at GLOW_SAMPLES_PER_PIXEL of 16 samples a pixel, each weighted
    for its block: the Caustic pass's mean as at every sample within 2 % (the same
    photons; a pixel's samples read nearly the same smooth estimate)."""
    scene = _glow_yard()
    st = RenderSettings(photons=20_000, caustic_photons=5_000, spp=16, seed=4, workers=1)

    def caustic():
        film = scene.render(st)
        return np.asarray(film.passes()["caustic"], np.float64)[..., :3]
    assert integrator.GLOW_SAMPLES_PER_PIXEL < 16
    strided = caustic()
    monkeypatch.setattr(integrator, "GLOW_SAMPLES_PER_PIXEL", 16)
    every = caustic()
    assert every.mean() > 0.0 and not np.array_equal(strided, every)
    assert strided.mean() == pytest.approx(every.mean(), rel=0.02)


@pytest.mark.parametrize("seed", [2, 3])
def test_glow_share_capped_by_the_global_radius_reads_no_lower(seed):
    """The glow's rms share with the global search radius as the k-NN cap (the photon
    pass's) against the old cap of 0.1 x the scene's extent: where the glow's photons are
    sparse (this shaded wall) the narrower discs hold fewer photons and the per-hit ratios
    spread, so the rms reads higher (measured 1.8-2.9x here: a larger glow shot, never a
    smaller one); in the bench's yards, 400k photons, the two agree to 4 digits."""
    scene = _glow_yard()
    ctx = prepare_context(scene, RenderSettings(photons=20_000, caustic_photons=5_000,
                                                seed=seed, workers=1))
    try:
        shot = shoot_photons(ctx, {})[0]
        r, _ = render_mod.global_search_radius(ctx, shot, render_mod._diffuse_area(ctx))
        assert 0.0 < r < 0.1 * ctx.geo.extent
        near = vi.glow_share(ctx, shot, r)
        wide = vi.glow_share(ctx, shot, 0.1 * ctx.geo.extent)
        assert 0.0 < wide <= near <= 1.0, (near, wide)
    finally:
        ctx.accel.close()


def test_gather_points_are_estimated_lazily_where_few_lookups_a_point_are_expected():
    """render.gather_points_lazy: the expected level-0 lookups (pixels x spp x gather rays
    x the pre-pass' rate of gather-ray ends on photon-storing surfaces) under
    LAZY_LOOKUPS_PER_POINT a point; never without the pre-pass' lookups or points."""
    from types import SimpleNamespace
    R = importlib.import_module("engine.render")
    rays = vi.ROI_RAYS * vi.ROI_GATHER

    def ctx(lookups, spp=16):
        return SimpleNamespace(scene=SimpleNamespace(width=160, height=120),
                               settings=SimpleNamespace(spp=spp),
                               lookups=None if lookups is None else np.zeros((lookups, 3)))
    # 160 x 120 x 16 x 1 ray x 940 / 16,384 = 17,625 lookups (the world-lit yard's)
    assert R.gather_points_lazy(ctx(940), 17_739, 1)
    assert not R.gather_points_lazy(ctx(940), 17_739 // 4, 1)
    assert not R.gather_points_lazy(ctx(940, spp=64), 17_739, 1)
    assert not R.gather_points_lazy(ctx(rays), 60_000, 2)  # (every ray ends: Figure 6-like)
    assert not R.gather_points_lazy(ctx(None), 17_739, 1)
    assert not R.gather_points_lazy(ctx(940), 0, 1)
