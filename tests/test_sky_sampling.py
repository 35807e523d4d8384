"""A low-sun Hosek / Wilkie sky as the world's shadow rays and photons sample it
(engine/lights/sky.py bake, engine/lights/environment.py distributions, world.py mixture),
and the global radius under a light at infinity (engine/render.py region_photons): issue
14, s18 skynoise (docs/performance.md, "skynoise")."""
import math

import numpy as np
import pytest

from engine.lights.sky import SkyTexture
from engine.render import region_photons
from engine.visualimportance import Region
from helpers import sphere_grid

ELEVATION, AZIMUTH = math.radians(7.0), math.radians(60.0)
SUN = (math.cos(ELEVATION) * math.sin(AZIMUTH), math.cos(ELEVATION) * math.cos(AZIMUTH),
       math.sin(ELEVATION))


def _hosek(width=256, height=128):
    return SkyTexture(sky_type="HOSEK_WILKIE", sun_vector=SUN, turbidity=2.2,
                      ground_albedo=0.3).environment(width, height)


def test_low_sun_hosek_map_pdfs_integrate_to_one():
    """Below the horizon Cycles' Hosek / Wilkie sky is the horizon's (60 % of the map's
    sin-weighted luminance at 7 degrees): both distributions still integrate to 1."""
    env = _hosek()
    d, sin_t, cell = sphere_grid(4 * env.height, 4 * env.width)
    assert abs(float(np.sum(env.pdf(d) * sin_t) * cell) - 1.0) < 1e-6
    for n in [(0, 0, 1.0), (0.87, 0.5, 0.0), (0.5, -0.3, 0.8)]:
        n = np.asarray(n) / np.linalg.norm(n)
        total = float(np.sum(env.cosine_pdf(d, n[None]) * sin_t) * cell)
        assert abs(total - 1.0) < 1e-6, (n, total)


@pytest.mark.parametrize("normal, bound", [((0.0, 0.0, 1.0), 0.05),
                                           ((0.87, 0.5, 0.0), 0.08),
                                           ((-0.87, -0.5, 0.0), 0.08),
                                           ((0.5, -0.3, 0.8), 0.3)])
def test_low_sun_hosek_shadow_rays_unbiased_and_calm(normal, bound):
    """The world's shadow rays (directlight.sample_lights) under the baked 1024 x 512
    Hosek / Wilkie sky with the sun 7 degrees up: irradiance (without visibility)
    unbiased against quadrature of the map, per-sample relative variance under `bound`
    (measured 0.023 / 0.040 / 0.045 / 0.15; the cosine hemisphere alone 0.54 / 0.39 /
    0.17 / 0.82)."""
    from test_environment_cosine import assert_world_irradiance_unbiased
    env = _hosek(1024, 512)
    assert_world_irradiance_unbiased(env, normal, bound, (1024, 2048))


def test_region_photons_are_those_inside_the_spheres():
    rng = np.random.default_rng(3)
    pos = rng.uniform(-20, 20, (20000, 3))
    region = Region(np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]), np.array([2.0, 1.0]),
                    0.9, 4096)
    got = region_photons(pos, region, 8)
    inside = (np.linalg.norm(pos, axis=1) <= 2.0) | (np.linalg.norm(pos - [5, 0, 0], axis=1)
                                                       <= 1.0)
    np.testing.assert_array_equal(got, pos[inside])
    # No region, or too few photons inside for a spacing: every photon.
    assert region_photons(pos, None, 8) is pos
    assert region_photons(pos, region, int(inside.sum())) is pos


def test_world_lit_ground_radius_is_the_spacing_near_the_objects():
    """A 40 m ground under a uniform sky with a ball and the camera on the ball: the
    global radius comes from the photons where the camera looks (visual importance's
    region), several times narrower than the whole shot's, and the lit ground reads the
    same as without visual importance (the natural shot and its radius)."""
    from engine import RenderSettings
    from engine.api import PaperScene
    from engine.render import render
    from engine.scene import Material

    s = PaperScene(48, 36)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, Material("Ground", (0.5,) * 3), name="Ground")
    s.add_sphere((0, 0, 0.5), 0.5, Material("Ball", (0.7, 0.3, 0.2)), name="Ball")
    s.set_camera((0, -4.0, 1.6), (0, 0, 0.4), view_angle=40.0)
    s.set_environment(np.full((16, 32, 3), 0.8, np.float32))
    kw = dict(photons=60_000, caustic_photons=0, spp=8, final_gather=True, gather_rays=2,
              k_nearest=32, workers=1)
    aimed = render(s, RenderSettings(**kw, seed=1, photon_importance=True))
    natural = render(s, RenderSettings(**kw, seed=1, photon_importance=False))
    assert aimed.stats["radius_global"] < 0.5 * natural.stats["radius_global"], (
        aimed.stats["radius_global"], natural.stats["radius_global"])
    a, b = aimed.combined.mean(axis=(0, 1)), natural.combined.mean(axis=(0, 1))
    assert np.allclose(a, b, rtol=0.02), (a, b)
