"""The smooth estimates' samples a pixel follow their shares (docs/performance.md
"worldcolour44"): a glow-only caustic map's and the secondary map's estimates are taken at
integrator.smooth_per_pixel(...) of a pixel's samples, from their rms shares of the light
the camera sees (visualimportance.glow_share / secondary_share, render.smooth_counts).
Checked: the count's bounds, rounding and monotony; the shares' range; and that fewer
estimates keep the Caustic and Indirect passes' means (each estimate weighs for its block
of samples: unbiased) in a world-lit yard whose glow and secondary caustic are small."""
import importlib
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import prepare_context, shoot_photons
from engine.scene import Material
from engine import visualimportance as vi

integrator = importlib.import_module("engine.integrator")


def test_smooth_per_pixel_follows_the_share_within_bounds():
    spp, full = integrator.smooth_per_pixel, integrator.SMOOTH_SHARE_FULL
    for share in (None, float("nan"), float("inf")):
        assert spp(4, share) == 4
    assert spp(4, full) == 4 and spp(4, 1.0) == 4 and spp(16, 0.5) == 16
    assert spp(4, 0.0) == 1 and spp(4, 1e-6) == 1  # never under one
    # rounded to the nearest: 4 x 0.024 / 0.08 = 1.2 -> 1 (ceiled: 2), 1.6 -> 2, 2.5 -> 3
    assert spp(4, 0.3 * full) == 1 and spp(4, 0.4 * full) == 2 and spp(4, 0.625 * full) == 3
    assert spp(4, 0.5, full=1.0) == 2  # an explicit full
    # a glow map's floor (GLOW_LEAST_PER_PIXEL: thick panes' edges bunch its photons)
    least = integrator.GLOW_LEAST_PER_PIXEL
    assert spp(4, 0.0, least=least) == least and spp(4, full, least=least) == 4
    shares = np.linspace(0.0, 0.12, 61)
    counts = [spp(4, s) for s in shares]
    assert all(a <= b for a, b in zip(counts, counts[1:]))  # monotone in the share


def _world_yard():
    """A 2 m box on a 12 m ground under a constant blue-white world, both Principled
    with a rough specular layer (roughness 0.5 / 0.6): a glow-only caustic map and a
    secondary caustic, each a few per cent of the light the camera sees."""
    s = PaperScene(width=32, height=24, background=(0.5, 0.65, 0.9))
    s.add_material(Material("ground", (0.35, 0.33, 0.25), roughness=0.5, specular=0.5))
    s.add_material(Material("walls", (0.75, 0.7, 0.6), roughness=0.6, specular=0.5))
    s.add_plane((0, 0, 0), size=12.0, material="ground", name="ground")
    s.add_box((0, 0, 1.0), (2.0, 2.0, 2.0), "walls", name="house")
    s.set_camera((4.0, -6.0, 2.5), (0, 0, 0.8), view_angle=45)
    return s


def test_shares_are_fractions_and_none_without_photons():
    ctx = prepare_context(_world_yard(), RenderSettings(photons=20_000, caustic_photons=5_000,
                                                        seed=1, workers=1))
    try:
        shot = shoot_photons(ctx, {})[0]
        r = ctx.global_radius
        g, sec = vi.glow_share(ctx, shot, r), vi.secondary_share(ctx, shot, r)
        assert 0.0 < sec < g < 0.2, (g, sec)  # light one diffuse bounce after the glow
        assert vi.secondary_share(ctx, shot.take(np.zeros(0, np.int64)), r) is None
    finally:
        ctx.accel.close()


@pytest.mark.parametrize("seed", [2, 3])
def test_fewer_estimates_at_small_shares_keep_the_passes_means(monkeypatch, seed):
    """The same photons and camera samples with the estimates at their shares' counts and
    at every 4th sample (SMOOTH_SHARE_FULL 1e-9: the constants, as before): the same
    photon maps, so the passes differ by the estimates' stride alone. Their means agree
    within what the stride's noise allows on this small map (73 glow photons, 768 pixels;
    measured over seeds 1-8, fewer / every - 1: Caustic -1.1 +- 1.0 % (standard error),
    single seeds within 5 %; Indirect +0.01 +- 0.01 %, within 0.08 %): 8 % and 0.5 %, a
    block weight wrong by a factor (1 for 4, 4 for 16) is off by 75-300 %; the images
    differ (fewer estimates were taken)."""
    scene = _world_yard()
    st = RenderSettings(photons=20_000, caustic_photons=5_000, spp=16, seed=seed, workers=1)

    def passes():
        film = scene.render(st)
        p = film.passes()
        return film.stats, {k: np.asarray(p[k], np.float64)[..., :3]
                            for k in ("caustic", "indirect")}
    stats, fewer = passes()
    assert stats["glow_per_pixel"] < integrator.GLOW_SAMPLES_PER_PIXEL
    assert stats["secondary_per_pixel"] < integrator.SECONDARY_SAMPLES_PER_PIXEL
    monkeypatch.setattr(integrator, "SMOOTH_SHARE_FULL", 1e-9)
    stats_all, every = passes()
    assert stats_all["glow_per_pixel"] == integrator.GLOW_SAMPLES_PER_PIXEL
    assert stats_all["secondary_per_pixel"] == integrator.SECONDARY_SAMPLES_PER_PIXEL
    tol = {"caustic": 0.08, "indirect": 0.005}
    for k in ("caustic", "indirect"):
        assert every[k].mean() > 0.0 and not np.array_equal(fewer[k], every[k])
        assert fewer[k].mean() == pytest.approx(every[k].mean(), rel=tol[k]), k
    assert math.isclose(stats["secondary_share"], stats_all["secondary_share"])
