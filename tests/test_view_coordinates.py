"""Texture Coordinate Camera and Window (engine/shadernodes.py CameraView,
ViewCoordinates): a point on a camera ray through an image position reads that position
back as its Window coordinates (0..1 from the frame's lower left corner), and its Camera
z is its depth along the view. Against Cycles' renders: the texcoord_* cases of
tests/blender/test_color_nodes_cycles.py."""
import math

import numpy as np
import pytest

from engine.integrator import camera_rays
from engine.scene import Camera
from engine.shadernodes import CameraView, ViewCoordinates


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("size", [(64, 48), (30, 50)])
def test_window_of_a_camera_ray_point_is_its_image_position(kind, size):
    w, h = size
    cam = Camera.look_at((0.4, -3.0, 1.2), (0.1, 0.2, 0.3), fov_degrees=50.0, kind=kind,
                         ortho_scale=2.5, shift_x=0.07, shift_y=-0.04)
    rng = np.random.default_rng(7)
    px, py = rng.integers(0, w, 50), rng.integers(0, h, 50)
    jx, jy = rng.random(50), rng.random(50)
    o, d, _ = camera_rays(cam, np.zeros(3), w, h, px, py, jx, jy)
    t = rng.uniform(0.5, 6.0, 50)
    p = o + t[:, None] * d
    view = CameraView(cam, w, h)
    ndc = view.to_ndc(p)
    np.testing.assert_allclose(ndc[:, 0], (px + jx) / w, atol=1e-9)
    np.testing.assert_allclose(ndc[:, 1], 1.0 - (py + jy) / h, atol=1e-9)
    assert np.all(ndc[:, 2] == 0.0)
    cz = view.to_camera(p)[:, 2]
    forward = -cam.rotation[:, 2]
    np.testing.assert_allclose(cz, (p - cam.position) @ forward, atol=1e-9)
    assert np.all(cz > 0)  # in front of the camera: positive z, as Cycles' camera space


class _Geo:
    """The least a Geometry gives ViewCoordinates: hit points, offset and camera_view."""

    def __init__(self, pts, view):
        self.pts, self.offset, self.camera_view = pts, np.zeros(3), view

    def hit_points(self, prim, u, v):
        return self.pts[prim]


def test_view_coordinates_without_camera_read_zeros_and_camera_node_reads_view():
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, -1.0]])
    prim, z = np.arange(2), np.zeros(2)
    assert np.all(ViewCoordinates("WINDOW").evaluate(_Geo(pts, None), prim, z, z) == 0)
    cam = Camera(position=(0.0, 0.0, 5.0), fov=math.radians(60.0))
    got = ViewCoordinates("CAMERA").evaluate(_Geo(pts, CameraView(cam, 4, 4)), prim, z, z)
    np.testing.assert_allclose(got, [[0.0, 0.0, 5.0], [1.0, 2.0, 6.0]])
    with pytest.raises(ValueError):
        ViewCoordinates("PANORAMA")
