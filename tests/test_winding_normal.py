"""One kernel for a triangle's winding normal e1 x e2 (rayoffset.winding_normal) and one
for its float32 tilt bound (rayoffset.tilt32), used by the camera, photon and shadow
kernels: bitwise numpy's np.cross and rayoffset.triangle_tilt."""
import numpy as np

from engine import photonkernels as pk
from engine.rayoffset import tilt32, triangle_tilt, winding_normal


def _triangles(n=500, seed=7):
    rng = np.random.default_rng(seed)
    v0 = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-3, 4, size=(n, 1))
    e1 = rng.normal(size=(n, 3))
    e2 = rng.normal(size=(n, 3))
    e2[:50] = e1[:50] * 1e-3 + rng.normal(size=(50, 3)) * 1e-9  # slivers
    e1[50:60, 2] = e2[50:60, 2] = 0.0  # axis-aligned: tilt 0
    v0[50:60, 2] = 2.5
    return v0, e1, e2


def test_winding_normal_is_np_cross_bitwise():
    _, e1, e2 = _triangles()
    want = np.cross(e1, e2)
    got = np.array([winding_normal(e1, e2, t) for t in range(len(e1))])
    assert got.tobytes() == want.tobytes()


def test_tilt32_is_triangle_tilt_of_the_float32_corners_bitwise():
    v0, e1, e2 = _triangles()
    corners32 = np.stack([v0, v0 + e1, v0 + e2], axis=1).astype(np.float32)
    want = triangle_tilt(corners32)
    got = np.array([tilt32(*v0[t], *e1[t], *e2[t]) for t in range(len(v0))])
    assert np.all(got[50:60] == 0.0) and np.any(got > 0.0)
    assert got.tobytes() == want.tobytes()
    # The photon kernels' per-row form reads the same helper.
    assert np.array([pk._tilt(v0, e1, e2, t) for t in range(len(v0))]).tobytes() == \
        want.tobytes()
