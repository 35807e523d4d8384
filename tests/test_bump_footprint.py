"""The Bump node's differences over the ray footprint (engine/bump.py), as Cycles'
svm_node_set_bump takes them: the height at P + filter_width dP/dx and P + filter_width
dP/dy, dP/dx and dP/dy the compact differential along make_orthonormals(Ng) (Blender 5.0
kernel/svm/displace.h, kernel/util/differential.h); the camera's differential
(kernel/camera/camera.h)."""
import math

import numpy as np
import pytest

from engine import shadernodes as sn
from engine.bsdf import surface_hit
from engine.bump import DEEPER, Bump, ViewFootprint, camera_differential, make_orthonormals
from engine.geometry import prepare
from engine.scene import Camera, Material, Mesh, Scene


def _quad(nmap, camera=None):
    """A unit quad at z = 0 facing +z, UV = xy, of one material with normal map nmap."""
    s = Scene(camera=camera, width=64, height=64)
    s.add_material(Material("b", (0.8,) * 3, normal_map=nmap))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2],
                    materials=["b"]))
    return prepare(s)


def _normals(geo, table, xy, footprint=None):
    """Shading normals seen from above at points xy (N,2) of _quad's plane."""
    xy = np.asarray(xy, float)
    low = xy[:, 0] >= xy[:, 1]  # triangle 0: p = (u + v, v); triangle 1: p = (u, u + v)
    prim = np.where(low, 0, 1)
    bu = np.where(low, xy[:, 0] - xy[:, 1], xy[:, 0])
    bv = np.where(low, xy[:, 1], xy[:, 1] - xy[:, 0])
    d = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    return surface_hit(geo, table, prim, bu, bv, d, footprint=footprint).ns


def test_differences_of_a_linear_height_are_its_gradient_at_any_footprint():
    # h = 0.5 x: n' = normalize((0, 0, 1) - 0.8 (0.5, 0, 0)) whatever the step.
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    geo, table = _quad(Bump(h, distance=0.8))
    want = np.array([-0.4, 0, 1]) / math.hypot(0.4, 1)
    xy = [[0.3, 0.2], [0.2, 0.6], [0.7, 0.65]]
    for r in (1e-4, 1e-2, 0.3):
        got = _normals(geo, table, xy, np.full(3, r))
        np.testing.assert_allclose(got, np.tile(want, (3, 1)), atol=1e-9)


def test_a_step_bends_the_normal_over_the_filter_width_of_the_footprint():
    """h = 1 beyond x = 0.5. make_orthonormals((0, 0, 1)) gives a = (1, -1, 0) / sqrt 2,
    b = (1, 1, 0) / sqrt 2: at a point delta before the step both samples (s a, s b away,
    s = filter_width r) cross it while delta < s / sqrt 2, and the gradient is
    (a + b) / s = (sqrt 2 / s, 0, 0); beyond that the normal is unbent. Twice the
    footprint: twice the band, half the slope."""
    h = sn.Math("GREATER_THAN", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    a, b = make_orthonormals(np.array([[0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(a[0], [1 / math.sqrt(2), -1 / math.sqrt(2), 0], atol=1e-12)
    np.testing.assert_allclose(b[0], [1 / math.sqrt(2), 1 / math.sqrt(2), 0], atol=1e-12)
    dist = 0.05
    geo, table = _quad(Bump(h, distance=dist))
    for r in (0.02, 0.04):
        s = 0.1 * r
        delta = np.array([0.2, 0.6, 0.9, 1.2]) * s / math.sqrt(2)
        xy = np.column_stack([0.5 - delta, np.full(4, 0.3)])
        got = _normals(geo, table, xy, np.full(4, r))
        bent = np.array([-math.sqrt(2) * dist / s, 0.0, 1.0])
        bent /= np.linalg.norm(bent)
        np.testing.assert_allclose(got[:3], np.tile(bent, (3, 1)), atol=1e-9)
        np.testing.assert_allclose(got[3], [0, 0, 1], atol=1e-12)


def test_zero_filter_width_or_footprint_leaves_the_normal():
    h = sn.Math("MULTIPLY", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    geo, table = _quad(Bump(h, distance=0.8, filter_width=0.0))
    np.testing.assert_allclose(_normals(geo, table, [[0.3, 0.2]], np.array([0.01])),
                               [[0, 0, 1]], atol=1e-12)
    geo, table = _quad(Bump(h, distance=0.8))
    np.testing.assert_allclose(_normals(geo, table, [[0.3, 0.2]], np.array([0.0])),
                               [[0, 0, 1]], atol=1e-12)


def _cycles_dd(cam, width, height, px, py):
    """Cycles' compact camera dD at pixel (px, py) by its definition: the normalised
    directions through the pixel and one pixel to the right / up, differenced."""
    hw, hh = cam.half_extents(width, height)
    pixel = 2 * hw / width

    def ray(x, y):
        c = np.array([(x - width / 2) * pixel, (y - height / 2) * pixel, -1.0])
        w = cam.rotation @ c
        return w / np.linalg.norm(w)
    d = ray(px, py)
    return d, 0.5 * (np.linalg.norm(ray(px + 1, py) - d) + np.linalg.norm(ray(px, py + 1) - d))


def test_camera_differential_is_cycles_per_pixel_direction_difference():
    cam = Camera.look_at((0, -3, 1), (0.3, 0, 0.2), fov_degrees=90.0)
    for px, py in ((32, 24), (2, 3), (60, 45), (5, 40)):
        d, want = _cycles_dd(cam, 64, 48, px, py)
        got = camera_differential(cam, 64, 48, d[None])[0]
        assert got == pytest.approx(want, rel=0.03)
    ortho = Camera.look_at((0, -3, 1), (0, 0, 0), kind="ORTHO", ortho_scale=2.0)
    np.testing.assert_allclose(camera_differential(ortho, 64, 48, np.zeros((2, 3))),
                               2.0 / 64)


def test_hits_without_a_footprint_take_the_cameras_at_their_distance():
    """surface_hit without footprints: the geometry's ViewFootprint, the camera's
    differential towards the hit times DEEPER times its distance (set by prepare)."""
    h = sn.Math("GREATER_THAN", sn.SeparateChannel(sn.UVCoord(), 0), 0.5)
    cam = Camera.look_at((0.5, 0.5, 2.0), (0.5, 0.5, 0.0), fov_degrees=40.0)
    geo, table = _quad(Bump(h, distance=0.05), camera=cam)
    assert isinstance(geo.view_footprint, ViewFootprint)
    p = np.array([[0.49, 0.3, 0.0]]) - geo.offset
    r = geo.view_footprint.at(p)
    d = (p + geo.offset) - cam.position
    dist = np.linalg.norm(d)
    assert r[0] == pytest.approx(camera_differential(cam, 64, 64, d / dist)[0] * dist * DEEPER)
    xy = [[0.49, 0.3], [0.495, 0.7]]
    hp = np.array([[0.49, 0.3, 0.0], [0.495, 0.7, 0.0]]) - geo.offset
    np.testing.assert_allclose(_normals(geo, table, xy),
                               _normals(geo, table, xy, geo.view_footprint.at(hp)),
                               atol=1e-12)
