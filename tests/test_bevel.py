"""Bevel node (engine/bevel.py): the falloff's sampling, and the bevelled normal on a
cube: its own normal farther than Radius from every edge, leaning half-way to the side
face at an edge's middle (by symmetry), and the same for a hit in any batch."""
import numpy as np
import pytest

from engine.api import PaperScene
from engine.bevel import Bevel, cubic_eval, cubic_sample
from engine.render import prepare_context
from engine.scene import Material
from engine.settings import RenderSettings


def test_cubic_sample_draws_the_cubic_falloff():
    """r from cubic_sample follows 2 pi r cubic_eval(R, r) (a density on the disk): its
    mean is R/3 (the integral of r 20 (R - r)^3 / R^5)."""
    xi = (np.arange(20000) + 0.5) / 20000
    r, h = cubic_sample(0.2, xi)
    assert r.min() >= 0.0 and r.max() <= 0.2
    np.testing.assert_allclose(r * r + h * h, 0.04, rtol=1e-9)
    np.testing.assert_allclose(r.mean(), 0.2 / 3.0, rtol=2e-3)
    x = np.linspace(0, 0.2, 20001)
    ring = 2 * np.pi * x * cubic_eval(0.2, x)
    np.testing.assert_allclose(np.sum(ring) * (x[1] - x[0]), 1.0, rtol=1e-3)


@pytest.fixture(scope="module")
def cube():
    s = PaperScene(width=8, height=8)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_box((0, 0, 0), (1, 1, 1), "grey", name="cube")
    s.set_camera((0, 0, 5), (0, 0, 0), view_angle=30)
    return prepare_context(s, RenderSettings(workers=1))


def _top_hits(ctx, xy):
    xy = np.asarray(xy, np.float64)
    o = np.column_stack([xy, np.full(len(xy), 2.0)]) - ctx.geo.offset
    _, prim, u, v = ctx.accel.intersect(o, np.tile([0.0, 0.0, -1.0], (len(xy), 1)))
    assert (prim >= 0).all()
    return prim, u, v


def test_far_from_edges_the_normal_is_the_face_own(cube):
    prim, u, v = _top_hits(cube, [[0.0, 0.0], [0.2, -0.25], [-0.3, 0.1]])
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    out = Bevel(0.1, samples=16).perturb(cube.geo, prim, u, v, n)
    np.testing.assert_allclose(out, n, atol=1e-12)


def test_at_an_edge_the_normal_leans_half_way(cube):
    """Hits along the top face's +y edge (0.5 mm inside): the mean bevelled normal lies
    between +z and +y, equally (the edge's symmetry), within the sampling noise."""
    xs = np.linspace(-0.3, 0.3, 64)
    prim, u, v = _top_hits(cube, np.column_stack([xs, np.full(64, 0.4995)]))
    n = np.tile([0.0, 0.0, 1.0], (64, 1))
    out = Bevel(0.1, samples=16).perturb(cube.geo, prim, u, v, n)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)
    mean = out.mean(axis=0)
    assert abs(mean[0]) < 0.05
    assert abs(mean[1] - mean[2]) < 0.08 and mean[1] > 0.5
    # A batch's reverse gives every hit the same normal (samples hash the hit).
    rev = Bevel(0.1, samples=16).perturb(cube.geo, prim[::-1], u[::-1], v[::-1], n)
    np.testing.assert_array_equal(out, rev[::-1])


def test_an_axis_aligned_cube_renders_with_photons():
    """A Bevel at an axis-aligned cube's edge can bend the normal to the next face's, 90
    degrees off the smooth one: the bump shadowing term's tan^2 / 8 clamps to 1 there
    (it divided by cos = 0 and stopped the render in the photon pass: new-user trial s35,
    Blender's default cube with a Bevel into its BSDF's Normal)."""
    from engine import render
    from engine.normalmap import bump_shadowing_term
    assert bump_shadowing_term(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.6, 0.0, 0.8, True) == \
        pytest.approx(bump_shadowing_term(0.0, 0.0, 1.0, 0.8, 0.0, 0.33, 0.6, 0.0, 0.8, True))
    s = PaperScene(width=24, height=18)
    s.add_material(Material("bevelled", (0.6, 0.6, 0.6), normal_map=Bevel(radius=0.2)))
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_box((0, 0, 0.5), (1, 1, 1), "bevelled", name="cube")
    s.add_box((0, 0, -0.05), (6, 6, 0.1), "floor", name="floor")
    s.add_point_light((2.0, -2.0, 4.0), 800.0)
    s.set_camera((3.0, -4.0, 3.0), (0, 0, 0.5), view_angle=40)
    film = render(s, RenderSettings(spp=4, photons=20_000, caustic_photons=5_000, seed=1,
                                    workers=1))
    img = np.asarray(film.combined)
    assert np.isfinite(img).all() and img[..., :3].mean() > 0.01
