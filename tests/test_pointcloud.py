"""engine/pointcloud.py: a point cloud's points as icospheres of the sphere's surface area
(Cauchy: the same mean projected area), smooth normals straight out, faces wound out."""
import math

import numpy as np
import pytest

from engine import pointcloud


@pytest.mark.parametrize("level", [0, 1, 2])
def test_spheres_have_the_spheres_area_and_outward_faces(level):
    centres = np.array([[0.0, 0.0, 0.0], [2.0, -1.0, 0.5]])
    radius = np.array([0.5, 0.02])
    verts, faces, normals, point = pointcloud.sphere_mesh(centres, radius, level)
    assert len(faces) == 2 * 20 * 4 ** level and np.array_equal(
        np.bincount(point), [20 * 4 ** level] * 2)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    for i, r in enumerate(radius):
        assert area[point == i].sum() == pytest.approx(4.0 * math.pi * r * r, rel=1e-9)
    outward = np.einsum("ij,ij->i", cross, (a + b + c) / 3.0 - centres[point])
    assert np.all(outward > 0.0)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=1e-12)
    # normals straight out from each point's centre
    owner = np.repeat(np.arange(2), len(verts) // 2)
    out = verts - centres[owner]
    np.testing.assert_allclose(out / np.linalg.norm(out, axis=1)[:, None], normals,
                               atol=1e-12)


def test_a_projected_outline_averages_the_discs_area():
    """Cauchy: the polyhedron's shadow, averaged over directions, is the sphere's pi r^2
    (the 20-face icosahedron too)."""
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(400, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    verts, faces, _n, _p = pointcloud.sphere_mesh([[0, 0, 0]], [1.0], level=0)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    cross = 0.5 * np.cross(b - a, c - a)
    shadow = 0.5 * np.abs(cross @ dirs.T).sum(axis=0)  # each direction's projected area
    assert shadow.mean() == pytest.approx(math.pi, rel=0.01)


def test_bad_points_are_left_out_and_the_level_fits_the_budget():
    centres = np.array([[0, 0, 0], [np.nan, 0, 0], [1, 1, 1], [2, 2, 2]], float)
    radius = np.array([0.1, 0.1, 0.0, np.inf])
    verts, faces, normals, point = pointcloud.sphere_mesh(centres, radius, level=1)
    assert set(point.tolist()) == {0} and np.isfinite(verts).all()
    assert pointcloud.sphere_level(1000) == 2
    assert pointcloud.sphere_level(40_000) == 1
    assert pointcloud.sphere_level(10_000_000) == 0
    with pytest.raises(ValueError):
        pointcloud.sphere_mesh(np.zeros((3, 3)), np.ones(2))
