"""Ray origins and ends kept off their surfaces by bounds on floating-point error.

No length here comes from the scene's size: every offset is a bound on the rounding error
of one point (pbrt-v4's approach: `OffsetRayOrigin` and `SpawnRayTo` in
src/pbrt/interaction.h and ray.h, with the error bounds of its section 6.8 "Managing
Rounding Error"). Two sources of error are bounded:

1. Where the point is. Hit points are interpolated in float64 from barycentrics
   (`Geometry.hit_points`): error <= gamma64(7) * (|b0 v0| + |b1 v1| + |b2 v2|) per
   component (pbrt-v4's triangle pError). Embree, however, traces the float32 copy of
   each triangle (`Geometry.vertices32`): the difference of the two triangles at the
   point is bounded by the exact per-vertex rounding, b0 |d0| + b1 |d1| + b2 |d2|. And a
   ray origin or end is itself rounded to float32 when handed to Embree: one float32 ulp
   of the point's coordinates covers that.
2. Where Embree puts the plane. Embree intersects in float32 relative to the ray origin o
   (its robust Pluecker test computes T = dot(v0 - o, Ng) and compares t = T / dot(Ng, D)
   with the ray's extent). Rounding v_i - o moves the triangle's plane, along its unit
   normal n, by at most about gamma32(k) * sum_c |n_c| max_i |v_i,c - o_c|. For an
   axis-aligned triangle this is exactly 0 off its axis (a floor of any size needs no
   more offset than a small one); for a tilted triangle it grows with the triangle's own
   size and the ray's length, never with the scene's. The parametric distance t itself
   (float32, compared with tfar) is good to a few float32 ulps of the ray's length.
3. Which way the plane tilts. Embree's float32 normal of a thin (sliver) triangle is good
   only to about gamma32(2) |e1||e2| / |e1 x e2| radians (`triangle_tilt`; exactly 0 for an
   axis-aligned float32 triangle), and its plane test dots that normal with v0 - o: the
   plane may move by the tilt times the distance to the farthest corner (`_offset_row`).
   Measured: without this term 1 % of rays leaving 1:100 slivers hit them again.

Offsets are applied along the geometric normal (towards the side the ray leaves), as
pbrt-v4 does: an offset along the ray would have to grow without bound at grazing angles.
Checked against Embree on random, huge, tilted and sliver triangles by
tests/test_ray_offsets.py (no self-hits). Shadow rays (segments to a light sample, ended
before an emitting surface by its error bound, pbrt-v4's SpawnRayTo) and Cycles' shadow
terminator offsets are made in the compiled direct-light kernels, engine/directlight.py.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up
from .sampling import dot, norm3

U64 = 2.0 ** -53  # unit roundoff of float64
U32 = 2.0 ** -24  # unit roundoff of float32


def gamma(n: int, u: float) -> float:
    """Higham's gamma_n = n u / (1 - n u): the relative error bound of n roundings."""
    return n * u / (1.0 - n * u)


# Safety factors on the bounds above (pbrt-v4 uses gamma(7) for the interpolation; the
# Embree terms count the roundings of its Pluecker test generously).
G64 = gamma(10, U64)
G32_PLANE = gamma(16, U32)
G32_T = gamma(16, U32)
# The tilt of a float32 plane: about two roundings relative to |e1||e2| (measured: slivers
# of aspect 1:10 .. 1:100000 still hit themselves below 0.25 u32; gamma(2) is 8x that).
G32_TILT = gamma(2, U32)


TINY32 = float(np.finfo(np.float32).tiny)


def ulp32(x: np.ndarray) -> np.ndarray:
    """Upper bound on the spacing of float32 numbers at |x| (as float64): 2^-23 |x|, at
    least float32's smallest normal. Continuous in x rather than the exact, stepped
    spacing, so offsets scale exactly with the scene: a scene scaled by 1e-3 takes the
    same paths (tests/test_stability_geometry.py)."""
    return np.maximum(2.0 * U32 * np.abs(x), TINY32)


@kernel
def ulp32_scalar(x):
    """ulp32 of one float, inside kernels (the same value)."""
    return max(2.0 * U32 * abs(x), TINY32)


def triangle_point_error(v0, e1, e2, round32, b1, b2, p) -> np.ndarray:
    """(N,3) per-component bound on how far the float64 point p = v0 + b1 e1 + b2 e2 may
    lie from the float32 triangle Embree traces, including p's own rounding to float32.

    v0, e1, e2  (N,3) float64 triangle corner and edges (Geometry's tables, per point)
    round32     (N,3,3) bound on |float32 corner - float64 corner| (Geometry.round32)
    b1, b2      (N,) barycentric weights of corners 1 and 2
    p           (N,3) the point
    Computed by the kernel _point_error (one implementation with surface_offset)."""
    v0, e1, e2, p = (np.ascontiguousarray(a, dtype=np.float64) for a in (v0, e1, e2, p))
    b1 = np.ascontiguousarray(b1, dtype=np.float64)
    b2 = np.ascontiguousarray(b2, dtype=np.float64)
    err = np.empty((len(p), 3))
    _point_errors(v0, e1, e2, np.ascontiguousarray(round32, dtype=np.float64),
                  np.arange(len(p)), b1, b2, p, err)
    return err


@kernel
def winding_normal(e1, e2, t):
    """Triangle row t's geometric normal on its winding's outside: e1 x e2 (np.cross's
    order of operations) from the edge tables e1, e2 (T,3) float64; not unit (its length
    is twice the triangle's area). The one place for it in the kernels."""
    return (e1[t, 1] * e2[t, 2] - e1[t, 2] * e2[t, 1],
            e1[t, 2] * e2[t, 0] - e1[t, 0] * e2[t, 2],
            e1[t, 0] * e2[t, 1] - e1[t, 1] * e2[t, 0])


@kernel
def tilt32(a0x, a0y, a0z, a1x, a1y, a1z, a2x, a2y, a2z):
    """triangle_tilt of one triangle (corner a0, edges a1, a2, float64) rounded to float32
    corners, as geometry._tilt32_rows computes it, inside kernels (the same value)."""
    c0x, c0y, c0z = np.float32(a0x), np.float32(a0y), np.float32(a0z)
    c1x, c1y, c1z = np.float32(a0x + a1x), np.float32(a0y + a1y), np.float32(a0z + a1z)
    c2x, c2y, c2z = np.float32(a0x + a2x), np.float32(a0y + a2y), np.float32(a0z + a2z)
    if ((c0x == c1x and c0x == c2x) or (c0y == c1y and c0y == c2y)
            or (c0z == c1z and c0z == c2z)):
        return 0.0  # an axis-aligned float32 plane cannot tilt
    ux = np.float64(c1x) - np.float64(c0x)
    uy = np.float64(c1y) - np.float64(c0y)
    uz = np.float64(c1z) - np.float64(c0z)
    wx = np.float64(c2x) - np.float64(c0x)
    wy = np.float64(c2y) - np.float64(c0y)
    wz = np.float64(c2z) - np.float64(c0z)
    cx = uy * wz - uz * wy
    cy = uz * wx - ux * wz
    cz = ux * wy - uy * wx
    cross = math.sqrt(cx * cx + cy * cy + cz * cz)
    lengths = math.sqrt(ux * ux + uy * uy + uz * uz) * math.sqrt(wx * wx + wy * wy + wz * wz)
    return min(G32_TILT * lengths / max(cross, 1e-300), 1.0)


@kernel
def _point_error(v0, e1, e2, round32, t, b1, b2, px, py, pz, c):
    """Component c of triangle_point_error for triangle row t of the tables."""
    b0 = 1.0 - b1 - b2
    a0, a1, a2 = abs(b0), abs(b1), abs(b2)
    interp = G64 * (a0 * abs(v0[t, c]) + a1 * abs(v0[t, c] + e1[t, c])
                    + a2 * abs(v0[t, c] + e2[t, c]))
    tri32 = a0 * round32[t, 0, c] + a1 * round32[t, 1, c] + a2 * round32[t, 2, c]
    pc = px if c == 0 else (py if c == 1 else pz)
    return interp + tri32 + max(2.0 * U32 * abs(pc), TINY32)


@kernel
def _point_errors(v0, e1, e2, round32, tri, b1, b2, p, err):
    for i in range(p.shape[0]):
        for c in range(3):
            err[i, c] = _point_error(v0, e1, e2, round32, tri[i], b1[i], b2[i],
                                     p[i, 0], p[i, 1], p[i, 2], c)


@kernel
def _offset_row(ex, ey, ez, v0, e1, e2, t, nx, ny, nz, px, py, pz, tilt):
    """origin_offset for one point: error (ex, ey, ez), triangle row t, unit normal n."""
    anx, any_, anz = abs(nx), abs(ny), abs(nz)
    along = anx * ex + any_ * ey + anz * ez
    # Embree's plane test from origin p (note 2), and the tilt (note 3).
    r0 = max(max(abs(v0[t, 0] - px), abs(v0[t, 0] + e1[t, 0] - px)),
             abs(v0[t, 0] + e2[t, 0] - px))
    r1 = max(max(abs(v0[t, 1] - py), abs(v0[t, 1] + e1[t, 1] - py)),
             abs(v0[t, 1] + e2[t, 1] - py))
    r2 = max(max(abs(v0[t, 2] - pz), abs(v0[t, 2] + e1[t, 2] - pz)),
             abs(v0[t, 2] + e2[t, 2] - pz))
    plane = G32_PLANE * (anx * r0 + any_ * r1 + anz * r2)
    far = 0.0
    for k in range(3):
        x = v0[t, 0] - px
        y = v0[t, 1] - py
        z = v0[t, 2] - pz
        if k == 1:
            x = v0[t, 0] + e1[t, 0] - px
            y = v0[t, 1] + e1[t, 1] - py
            z = v0[t, 2] + e1[t, 2] - pz
        elif k == 2:
            x = v0[t, 0] + e2[t, 0] - px
            y = v0[t, 1] + e2[t, 1] - py
            z = v0[t, 2] + e2[t, 2] - pz
        d = math.sqrt(x * x + y * y + z * z)
        far = d if k == 0 else max(far, d)
    return along + plane + tilt * far


@kernel
def surface_offset(v0, e1, e2, round32, tilt32, tri, b1, b2, p, n):
    """(N,) origin_offset of hit points p (N,3) on triangles tri (N,) of the tables v0,
    e1, e2 (T,3), round32 (T,3,3), tilt32 (T,) (Geometry's), at barycentrics b1, b2 (N,),
    with unit geometric normals n (N,3): triangle_point_error and origin_offset fused,
    without the (N,3) per-point copies of the tables."""
    m = p.shape[0]
    out = np.empty(m)
    for i in range(m):
        t = tri[i]
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        ex = _point_error(v0, e1, e2, round32, t, b1[i], b2[i], px, py, pz, 0)
        ey = _point_error(v0, e1, e2, round32, t, b1[i], b2[i], px, py, pz, 1)
        ez = _point_error(v0, e1, e2, round32, t, b1[i], b2[i], px, py, pz, 2)
        out[i] = _offset_row(ex, ey, ez, v0, e1, e2, t, n[i, 0], n[i, 1], n[i, 2],
                             px, py, pz, tilt32[t])
    return out


@kernel
def _offsets_from_error(err, v0, e1, e2, n, p, tilt):
    m = p.shape[0]
    out = np.empty(m)
    for i in range(m):
        out[i] = _offset_row(err[i, 0], err[i, 1], err[i, 2], v0, e1, e2, i, n[i, 0],
                             n[i, 1], n[i, 2], p[i, 0], p[i, 1], p[i, 2], tilt[i])
    return out


def triangle_tilt(corners32: np.ndarray) -> np.ndarray:
    """(T,) bound on the angle (radians) by which float32 arithmetic may tilt each
    triangle's plane: gamma32(2) |e1||e2| / |e1 x e2| of its float32 corners (T,3,3), and 0
    where all three corners share one coordinate exactly (an axis-aligned plane)."""
    c = corners32.astype(np.float64)
    e1, e2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    cross = np.linalg.norm(np.cross(e1, e2), axis=1)
    lengths = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    tilt = G32_TILT * lengths / np.maximum(cross, 1e-300)
    aligned = np.any((corners32[:, 0] == corners32[:, 1]) & (corners32[:, 0] == corners32[:, 2]),
                     axis=1)
    return np.where(aligned, 0.0, np.minimum(tilt, 1.0))


def origin_offset(err: np.ndarray, v0, e1, e2, n, p, tilt) -> np.ndarray:
    """(N,) distance along the unit normal n that takes a ray origin at p clear of its own
    triangle: the point's error projected on the normal (pbrt-v4's d = |n| . pError) plus
    the error of Embree's plane test from that origin (notes 2 and 3): along its unit
    normal, gamma32(16) sum_c |n_c| max_i |v_i,c - p_c|, plus the tilt bound times the
    distance from p to the farthest corner. err (N,3), v0, e1, e2, n, p (N,3), tilt (N,);
    the kernel _offset_row computes it (surface_offset fuses it with the point's error).
    Geometry.origin_offset calls surface_offset directly."""
    err, v0, e1, e2, n, p, tilt = (np.ascontiguousarray(a, dtype=np.float64)
                                   for a in (err, v0, e1, e2, n, p, tilt))
    return _offsets_from_error(err, v0, e1, e2, n, p, tilt)


def offset_along_normal(p: np.ndarray, n: np.ndarray, towards: np.ndarray,
                        distance: np.ndarray) -> np.ndarray:
    """p moved by `distance` along n, to the side where dot(towards, n) >= 0 (a direction
    leaving the surface)."""
    side = np.where(dot(towards, n) >= 0.0, 1.0, -1.0)
    return p + (side * distance)[:, None] * n


@register_warm_up
def _warm_up():
    rng = np.random.default_rng(0)
    v0, e1, e2, p, n = (rng.random((4, 3)) for _ in range(5))
    r32 = rng.random((4, 3, 3))
    tilt = rng.random(4)
    b = rng.random(4)
    surface_offset(v0, e1, e2, r32, tilt, np.arange(4), b, b, p, n)
    origin_offset(triangle_point_error(v0, e1, e2, r32, b, b, p), v0, e1, e2, n, p, tilt)
