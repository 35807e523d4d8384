"""Hair curves as triangle tubes (engine/hair.py): the spline through the keys, the tube's
corner radius (the circle's mean width), outward faces and radial normals, frames that do
not twist, bad input, and a render of strands against the analytic coverage."""
import math

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.api import PaperScene
from engine.hair import (DEFAULT_RADIUS, TESSELLATIONS, catmull_rom, mean_width_radius,
                         tessellation, tube_mesh)
from engine.scene import Material, Mesh


def _straight(n=4, length=3.0, r=0.1):
    z = np.linspace(0.0, length, n)
    return np.column_stack([np.zeros(n), np.zeros(n), z]), np.full(n, r)


def test_a_straight_strand_is_a_tube_of_the_mean_width_radius():
    pts, rad = _straight()
    for sides, sub in ((3, 1), (8, 2)):
        v, f, nrm, curve = tube_mesh(pts, rad, [0, 4], sides, sub)
        rings = 3 * sub + 1
        assert v.shape == (rings * sides, 3) and f.shape == (2 * sides * (rings - 1), 3)
        assert np.all(curve == 0)
        # Corners at r' = r pi / (sides sin(pi / sides)) from the axis, normals radial.
        np.testing.assert_allclose(np.hypot(v[:, 0], v[:, 1]),
                                   mean_width_radius(0.1, sides), rtol=1e-12)
        np.testing.assert_allclose(nrm[:, :2] / np.hypot(nrm[:, 0], nrm[:, 1])[:, None],
                                   v[:, :2] / np.hypot(v[:, 0], v[:, 1])[:, None], atol=1e-12)
        np.testing.assert_allclose(nrm[:, 2], 0.0, atol=1e-12)
        # Rings along the axis, through the keys, in order (the spline stays on the line).
        z = v[::sides, 2]
        np.testing.assert_allclose(z[::sub], [0.0, 1.0, 2.0, 3.0], atol=1e-12)
        assert np.all(np.diff(z) > 0) and np.ptp(v.reshape(rings, sides, 3)[..., 2],
                                                  axis=1).max() < 1e-12
        # Every face wound outwards: its normal agrees with its corners' normals.
        fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        assert np.all(np.einsum("ij,ij->i", fn, nrm[f].sum(axis=1)) > 0)


@pytest.mark.parametrize("sides", [3, 4, 6, 8])
def test_the_polygon_shows_the_circles_mean_width(sides):
    """Cauchy: a convex section's width averaged over directions is its perimeter / pi;
    with corners at mean_width_radius the polygon's is the circle's 2 r."""
    r = 0.01
    rr = mean_width_radius(r, sides)
    theta = 2 * np.pi * np.arange(sides) / sides
    corners = rr * np.column_stack([np.cos(theta), np.sin(theta)])
    phi = np.linspace(0.0, np.pi, 20001)[:-1]
    proj = corners @ np.stack([np.cos(phi), np.sin(phi)])
    width = proj.max(axis=0) - proj.min(axis=0)
    assert width.mean() == pytest.approx(2 * r, rel=1e-6)


def test_catmull_rom_passes_through_the_keys():
    keys = np.array([[[0, 0, 0], [1, 0, 0.5], [1.5, 1, 1.0], [1.0, 2.0, 1.2], [0, 2.5, 1]]],
                    float)
    pts, i, t = catmull_rom(keys, 4)
    assert pts.shape == (1, 17, 3)
    np.testing.assert_allclose(pts[0, ::4], keys[0], atol=1e-12)
    # Between keys 1 and 2 at t = 1/2 (uniform Catmull-Rom): (-p0 + 9 p1 + 9 p2 - p3) / 16
    mid = (-keys[0, 0] + 9 * keys[0, 1] + 9 * keys[0, 2] - keys[0, 3]) / 16
    np.testing.assert_allclose(pts[0, 6], mid, atol=1e-12)
    assert i[6] == 1 and t[6] == 0.5


def test_a_helix_does_not_twist_its_tube():
    """Frames carried along the strand: consecutive rings' first corners stay on the
    same side (no quarter turns that would pinch the quads)."""
    s = np.linspace(0, 4 * np.pi, 40)
    pts = np.column_stack([np.cos(s), np.sin(s), 0.2 * s])
    sides = 6
    v, f, nrm, _ = tube_mesh(pts, np.full(40, 0.02), [0, 40], sides, 2)
    first = nrm[::sides]
    assert np.all(np.einsum("ij,ij->i", first[1:], first[:-1]) > 0.9)
    # Corners stay r' from the spline (no squashed rings).
    centres = v.reshape(-1, sides, 3).mean(axis=1)
    d = np.linalg.norm(v.reshape(-1, sides, 3) - centres[:, None], axis=2)
    np.testing.assert_allclose(d, mean_width_radius(0.02, sides), rtol=1e-6)


def test_material_curves_and_bad_input():
    pts, rad = _straight(4)
    many = np.vstack([pts, pts + 1.0, pts[:1] + 5.0, pts + 2.0])
    radius = np.concatenate([rad, rad, rad[:1], rad])
    radius[4] = np.nan  # a NaN radius reads 0: the strand narrows to a point there
    many[9 + 2, 0] = np.inf  # a non-finite point drops its whole curve (curve 3)
    offsets = [0, 4, 8, 9, 13]  # curve 2 has one point: no strand
    v, f, nrm, curve = tube_mesh(many, radius, offsets, 4, 1)
    assert sorted(set(curve.tolist())) == [0, 1]
    assert np.isfinite(v).all() and np.isfinite(nrm).all()
    ring0 = v[f[curve == 1]].reshape(-1, 3)
    assert np.min(np.hypot(ring0[:, 0] - 1.0, ring0[:, 1] - 1.0)) < 1e-12  # radius 0
    with pytest.raises(ValueError):
        tube_mesh(pts, rad, [0, 3])  # offsets do not reach the point count
    with pytest.raises(ValueError):
        tube_mesh(pts, rad[:2], [0, 4])
    v, f, _, _ = tube_mesh(pts[:1], rad[:1], [0, 1])
    assert len(v) == 0 and len(f) == 0
    assert DEFAULT_RADIUS == 0.005  # Cycles' radius without a "radius" attribute


def test_tessellation_fits_the_budget():
    assert tessellation(10) == TESSELLATIONS[0]
    sides, sub = tessellation(200_000, budget=4_000_000)
    assert 2 * sides * sub * 200_000 <= 4_000_000
    assert tessellation(10 ** 9) == TESSELLATIONS[-1]


def test_strands_in_front_of_a_glowing_plane_cover_their_mean_width():
    """Black strands (radius r, length L, each in its own cell of an 8 x 8 grid, every
    direction in the plane) between an orthographic camera and an emissive plane of
    radiance 1: the image's mean is 1 minus their share, 2 r L / A each (their mean
    width, the rolls spread over a sector). Measured 0.99994 of it at 8 sides."""
    rng = np.random.default_rng(2)
    r, L, cells = 0.004, 0.2, 8
    g = (np.arange(cells) + 0.5) / cells * 2.0 - 1.0
    centres = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    n = len(centres)
    phi = rng.uniform(0, np.pi, n)
    d = np.column_stack([np.cos(phi), np.sin(phi)])
    pts = np.zeros((n, 2, 3))
    pts[:, 0, :2] = centres - 0.5 * L * d
    pts[:, 1, :2] = centres + 0.5 * L * d
    pts[..., 2] = 0.5
    v, f, nrm, _ = tube_mesh(pts.reshape(-1, 3), np.full(2 * n, r), np.arange(n + 1) * 2, 8, 1)
    s = PaperScene(200, 200, background=(0.0, 0.0, 0.0))
    s.add_material(Material("black", (0.0, 0.0, 0.0), roughness=1.0, specular=0.0))
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "glow", name="glow")
    s.add_mesh(Mesh("strands", v, f, normals=nrm, materials=["black"]))
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=2.0)
    film = render(s, RenderSettings(spp=16, workers=1, seed=1, photon_mapping=False))
    img = np.asarray(film.combined, np.float64)[..., 0]
    covered = 1.0 - img.mean()
    expect = n * 2 * r * L / 4.0
    assert covered == pytest.approx(expect, rel=0.01), (covered, expect)


def test_a_tip_tapered_to_a_point_makes_no_zero_area_faces():
    """Radius 0 at the tip (a common groom): the last ring is a point, and the triangles
    it makes lines of are left out (they read "dropped zero-area faces" for every tapered
    groom, newuser37); all radii 0: no faces at all."""
    pts, _ = _straight(3)
    v, f, _, curve = tube_mesh(pts, np.array([0.1, 0.05, 0.0]), [0, 3], 4, 1)
    area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    assert len(f) == 2 * 4 + 4 and area.min() > 0 and len(curve) == len(f)
    v, f, _, _ = tube_mesh(pts, np.zeros(3), [0, 3], 4, 1)
    assert len(f) == 0
