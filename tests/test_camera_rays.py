"""Camera-ray generation kernel (engine/camerarays.py) against the numpy stage it
replaced, bitwise: perspective and orthographic cameras, lens shift, sensor fits, clip
distances, integer and float pixel positions."""
import math

import numpy as np
import pytest

from engine.integrator import camera_rays
from engine.scene import Camera


def _numpy_camera_rays(camera, offset, width, height, px, py, jx, jy):
    """The numpy stage (7be1f83's integrator.camera_rays), kept as the oracle."""
    hw, hh = camera.half_extents(width, height)
    sx = (px + jx) / width * 2.0 - 1.0
    sy = 1.0 - (py + jy) / height * 2.0
    big = 2.0 * max(hw, hh)
    x = sx * hw + camera.shift_x * big
    y = sy * hh + camera.shift_y * big
    R = camera.rotation
    pos = camera.position - offset
    n = len(px)
    if camera.kind == "ORTHO":
        o = pos + x[:, None] * R[:, 0] + y[:, None] * R[:, 1]
        d = np.broadcast_to(-R[:, 2], (n, 3)).copy()
        scale = np.ones(n)
    else:
        d = np.empty((n, 3))
        for c in range(3):
            d[:, c] = x * R[c, 0] + y * R[c, 1] - R[c, 2]
        scale = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        d /= scale[:, None]
        o = np.broadcast_to(pos, (n, 3)).copy()
    t_start = camera.clip_start * scale
    t_end = camera.clip_end * scale
    o = o + t_start[:, None] * d
    return o, d, t_end - t_start


CAMERAS = [
    dict(),
    dict(kind="ORTHO", ortho_scale=3.3),
    dict(shift_x=0.2, shift_y=-0.1, sensor_fit="VERTICAL", clip_start=0.3, clip_end=40.0),
    dict(kind="ORTHO", sensor_fit="HORIZONTAL", shift_y=0.25, clip_start=1.5),
]


@pytest.mark.parametrize("kw", CAMERAS)
@pytest.mark.parametrize("size", [(64, 48), (30, 70)])
def test_camera_rays_kernel_is_bitwise_the_numpy_stage(kw, size):
    rng = np.random.default_rng(5)
    cam = Camera.look_at((1.0, -7.0, 2.5), (0.2, 0.0, 1.1), fov_degrees=38.0, **kw)
    W, H = size
    pix = rng.integers(0, W * H, 5000)
    px, py = pix % W, pix // W
    jx, jy = rng.random(5000), rng.random(5000)
    offset = np.array([0.5, -0.25, 1.0])
    for args in ((px, py, jx, jy), (px.astype(float), py.astype(float), jx, jy)):
        got = camera_rays(cam, offset, W, H, *args)
        want = _numpy_camera_rays(cam, offset, W, H, *args)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
    o, d, t = got
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert np.all(t > 0)
    if kw.get("kind") != "ORTHO":
        # Clip start measured along the view axis, as Blender clips by depth.
        depth = (o - (cam.position - offset)) @ -cam.rotation[:, 2]
        np.testing.assert_allclose(depth, cam.clip_start, atol=1e-12)
    assert math.isfinite(o.sum())
