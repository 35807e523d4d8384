"""Closed diffuse furnace (issue 4): inside a closed box whose walls emit Le and reflect rho,
the radiance is Le / (1 - rho) everywhere. Photon mapping with its indirect light (global
map + final gather) must reach it within 1 % at rho = 0.5 and 3 % at rho = 0.9.

tests/test_stability_photons.py::test_furnace_inside_an_emitting_box checks rho = 0.5 at
5 %; this file asserts the issue's tolerances. The photon depth is raised from the default
8: a hard cap of 8 bounces keeps only sum_{k<=9} rho^k, 65 % of the answer at rho = 0.9
(measured 0.655) -- any depth-capped tracer (Cycles too) darkens a closed high-albedo room.
light_samples is raised from 1 to 16: direct light from emissive mesh triangles is sampled
by area (cos cos / r^2, no MIS), heavy-tailed where a wall meets an emitting wall; with 1
sample the direct pass's mean swings 0.93..1.10 of rho Le between seeds (median 0.84).
"""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, box_mesh
from engine.scene import Material

from test_stability_common import assert_film_sane


def furnace(rho, Le=1.0, size=24, **settings):
    s = PaperScene(width=size, height=size)
    s.add_material(Material("glow", (rho,) * 3, emission=(Le,) * 3))
    v, f = box_mesh((0, 0, 0), 2.0)
    s.add_triangles(v, f, "glow", name="furnace_box")
    s.set_camera((0, -0.5, 0), (0, 1, 0.1), view_angle=90)
    # (every bounce: the furnace's series runs to infinity; tests/test_bounce_limits.py
    # checks the series cut by Cycles' limits)
    st = dict(photons=40_000, caustic_photons=0, spp=16, max_photon_depth=200, seed=1,
              light_samples=16, max_bounces=1024, diffuse_bounces=1024, glossy_bounces=1024,
              transmission_bounces=1024)
    st.update(settings)
    film = s.render(RenderSettings(**st))
    assert_film_sane(film)
    return film


@pytest.mark.parametrize("rho, tol", [(0.5, 0.01), (0.9, 0.03)])
def test_furnace_radiance_is_le_over_one_minus_rho(rho, tol):
    Le = 1.0
    film = furnace(rho, Le)
    expected = Le / (1 - rho)
    c = np.asarray(film.combined, np.float64)[..., :3]
    mean = c.mean()
    assert abs(mean / expected - 1) < tol, (rho, mean, expected)
    # grey in, grey out
    np.testing.assert_allclose(c.mean(axis=(0, 1)), mean, rtol=1e-3)
    # not only on average: most pixels near the answer (direct light from the emitting
    # walls is sampled per pixel and noisy, so this is a loose per-pixel band)
    assert abs(np.median(c) / expected - 1) < 0.1, np.median(c)
    # emission is exactly Le, the rest is reflected light: rho Le / (1 - rho)
    p = film.passes()
    np.testing.assert_allclose(np.asarray(p["emission"])[..., :3].mean(), Le, rtol=1e-6)


def test_furnace_indirect_pass_is_smooth():
    """The photon-map part (indirect) alone must be close to its share everywhere: no
    blotches, no dark corners (the seams of the box are in view)."""
    rho, Le = 0.5, 1.0
    film = furnace(rho, Le)
    ind = np.asarray(film.passes()["indirect"], np.float64)[..., 0]
    # indirect = everything after the first reflection: rho^2 Le / (1 - rho) = 0.5
    expected = rho * rho * Le / (1 - rho)
    assert abs(ind.mean() / expected - 1) < 0.03, ind.mean()
    assert np.percentile(np.abs(ind / expected - 1), 95) < 0.15
