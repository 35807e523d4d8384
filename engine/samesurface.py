"""Which stored photons (or gather points) lie on a query's surface: the surface test every
estimate applies beside the normal test (photonmap._accepted, causticcache, the gather
map's lookups; issue 14, docs/accuracy.md "surfaceid32").

The normal test (photon normal . N > NORMAL_AGREEMENT) alone accepted the floor's photons
under a small ball's upper half: they face within 60 degrees of its normals there, so a
5 cm ball resting on a floor read 0.30 of its light at its top while the floor beside it
read 1.16 of its own (the ball's photons counted in). A local test of the two points and
normals fitting one surface cannot tell that contact from a concave fold of one mesh.
Each stored photon therefore keeps its surface (Photons.surface: the object_id of the
triangle it was stored on; an instance has its own) and a photon of another object is
accepted only where it continues the query's plane: its normal within COPLANAR_ANGLE of
the query's and its point within COPLANAR_ANGLE of the query's tangent plane, seen from
the query: ((x_j - q) . N)^2 <= sin^2(COPLANAR_ANGLE) |x_j - q|^2 + e^2, e the float32
resolution of the positions (1e-6 |q|). A floor built of coplanar tiles stays one surface across its seams; a
ball on a floor, a wall on a floor or a box on a table are two. A fold inside one mesh is
unchanged (the normal test alone, as before).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel
from .photonlayout import read_vector

COPLANAR_ANGLE = math.radians(1.0)
COPLANAR_COS = math.cos(COPLANAR_ANGLE)  # normals of two coplanar surfaces agree this well
COPLANAR_SIN = math.sin(COPLANAR_ANGLE)  # the point's elevation over the query's plane
COPLANAR_SIN2 = COPLANAR_SIN * COPLANAR_SIN
# Positions are float32 (Photons.position) around the scene's re-centred origin: an
# exactly coplanar point sits up to a few ulps off the plane.
POSITION_RESOLUTION = 1e-6
NO_SURFACE = np.zeros(0, np.int32)  # no surfaces known: every photon passes this test


def surface_ids(photons) -> np.ndarray:
    """(N,) int32 contiguous: photons.surface, or all -1 (unknown) where it is None; the
    all -1 array is made once per Photons (kept on it) for the kernels that read a
    photon's surface without a branch (photonmap._accepted)."""
    if photons.surface is not None:
        s = photons.surface
        if s.dtype != np.int32 or not s.flags.c_contiguous:
            s = photons.surface = np.ascontiguousarray(s, dtype=np.int32)
        return s
    got = getattr(photons, "_unknown_surface", None)
    if got is None or len(got) != len(photons):
        got = np.full(len(photons), -1, np.int32)
        object.__setattr__(photons, "_unknown_surface", got)
    return got


def query_surfaces(surface, m) -> np.ndarray:
    """(m,) int32, C-contiguous and writable: the queries' surfaces `surface` (an (m,)
    array or one id for all). Always a fresh writable array, so the kernels that take it
    see one array type (a broadcast view is read-only: a second compiled variant, which
    the warm-up compile did not make: tests/test_warm_up.py)."""
    return np.array(np.broadcast_to(np.asarray(surface), (m,)), dtype=np.int32, order="C")


@kernel
def continues_plane(pos, normal, j, qx, qy, qz, nx, ny, nz):
    """Whether point j (pos (N,3), normal (N,3)) continues the plane of the query at
    (qx, qy, qz) float64 with unit normal (nx, ny, nz): its normal within COPLANAR_ANGLE
    of the query's and its point within COPLANAR_ANGLE of the query's tangent plane seen
    from the query, with the float32 resolution of the positions (module docstring)."""
    m0, m1, m2 = read_vector(normal, j)  # (photonlayout: float32 or octahedral)
    if m0 * nx + m1 * ny + m2 * nz < COPLANAR_COS:
        return False
    return not off_plane(pos, j, qx, qy, qz, nx, ny, nz)


@kernel
def off_plane(pos, j, qx, qy, qz, nx, ny, nz):
    """Whether point j of pos (N,3) lies farther than COPLANAR_ANGLE off the plane through
    (qx, qy, qz) float64 with unit normal (nx, ny, nz), seen from that point, beyond the
    float32 resolution of the positions (module docstring). Branch-free, so the loops
    that call it stay vectorised (photonmap._accepted)."""
    dx = np.float64(pos[j, 0]) - qx
    dy = np.float64(pos[j, 1]) - qy
    dz = np.float64(pos[j, 2]) - qz
    h = dx * nx + dy * ny + dz * nz
    res = POSITION_RESOLUTION * max(abs(qx), abs(qy), abs(qz))
    return h * h > COPLANAR_SIN2 * (dx * dx + dy * dy + dz * dz) + res * res


@kernel
def same_surface(surface, pos, normal, j, qs, qx, qy, qz, nx, ny, nz):
    """Whether point j (a stored photon or gather point: pos (N,3), normal (N,3), surface
    (N,) int32 object ids, in the same order) lies on the query's surface: the query's
    object qs, or another object's continuing the query's plane (continues_plane). The
    query: point (qx, qy, qz) float64, unit normal (nx, ny, nz), surface qs (< 0:
    unknown). True where either surface is unknown (surface empty, qs < 0 or
    surface[j] < 0): the normal test alone decides there.

    photonmap._accepted has the same rule without branches (its loops vectorise)."""
    if qs < 0 or surface.shape[0] == 0:
        return True
    sj = surface[j]
    if sj < 0 or sj == qs:
        return True
    return continues_plane(pos, normal, j, qx, qy, qz, nx, ny, nz)
