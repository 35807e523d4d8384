"""Hair curves as triangle tubes: what Cycles renders as curves (Blender's Curves objects:
hair), tessellated so that Embree's triangle BVH, the camera and photon passes and every
material treat a strand as a thin smooth-shaded surface.

Cycles (intern/cycles/blender/curves.cpp, export_hair_curves) takes each curve's control
points and radii (the point attribute "radius", 0.005 m where there is none) and traces
them as a Catmull-Rom spline swept by a circle ("3D Curves") or as a ribbon facing the ray
whose normals are rounded to look like one ("Ribbons", scene.cycles_curves.shape: the
default in Blender 5.0). Both show a strand 2 r wide from every side. Here each strand is
the same Catmull-Rom spline (uniform, its end points repeated as their own neighbours),
`substeps` pieces per key interval, swept by a regular polygon of `sides` corners whose
normals point straight out from the axis (smooth shading: a round look, as both of
Cycles' shapes). The polygon's corners lie at

    r' = r pi / (sides sin(pi / sides))

so that its perimeter is the circle's, 2 pi r: by Cauchy's formula the width a convex
cross-section shows, averaged over directions, is its perimeter / pi, so the tube casts
and catches light over the circle's mean width 2 r (a square through the circle's
points would show 1.8 r: a tenth less coverage, darker hair and lighter shadows).
No end caps (Cycles' curves have none either)."""
from __future__ import annotations

import math

import numpy as np

# Cycles' radius where a Curves object has no "radius" attribute (blender/curves.cpp).
DEFAULT_RADIUS = 0.005
# Tessellation, finest first; the first whose triangles fit HAIR_TRIANGLE_BUDGET is used
# for an object (a groom of 100k strands cannot take 24 triangles per key interval).
TESSELLATIONS = ((8, 2), (6, 2), (4, 2), (4, 1), (3, 1))  # (sides, substeps)
HAIR_TRIANGLE_BUDGET = 4_000_000
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0  # strand c's roll: frac(c x this) of a sector


def mean_width_radius(radius, sides: int):
    """The corner radius r' of a regular `sides`-gon whose perimeter is 2 pi radius (the
    same mean projected width as the circle: module docstring)."""
    return np.asarray(radius, np.float64) * (math.pi / (sides * math.sin(math.pi / sides)))


def tessellation(interval_count: int, budget: int = HAIR_TRIANGLE_BUDGET):
    """(sides, substeps) for `interval_count` key intervals over all strands: the finest
    of TESSELLATIONS within `budget` triangles (2 sides substeps each), else the
    coarsest."""
    for sides, substeps in TESSELLATIONS:
        if 2 * sides * substeps * interval_count <= budget:
            return sides, substeps
    return TESSELLATIONS[-1]


def catmull_rom(keys: np.ndarray, substeps: int) -> tuple:
    """Points along uniform Catmull-Rom splines through keys (m, n, 3) (n >= 2; the end
    keys their own outer neighbours): (m, (n - 1) substeps + 1, 3) samples, and per
    sample its key interval i (ns,) and parameter t in [0, 1] (ns,)."""
    m, n, _ = keys.shape
    i = np.repeat(np.arange(n - 1), substeps)
    t = np.tile(np.arange(substeps) / substeps, n - 1)
    i = np.append(i, n - 2)
    t = np.append(t, 1.0)
    p0 = keys[:, np.maximum(i - 1, 0)]
    p1 = keys[:, i]
    p2 = keys[:, i + 1]
    p3 = keys[:, np.minimum(i + 2, n - 1)]
    tt = t[None, :, None]
    pts = 0.5 * (2.0 * p1 + (p2 - p0) * tt + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * tt ** 2
                 + (3.0 * p1 - p0 - 3.0 * p2 + p3) * tt ** 3)
    return pts, i, t


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _perpendicular(tangent):
    """Unit vectors (m,3) perpendicular to unit tangents (m,3): crossed with the axis the
    tangent leans on least."""
    axis = np.zeros_like(tangent)
    axis[np.arange(len(tangent)), np.argmin(np.abs(tangent), axis=1)] = 1.0
    return _unit(np.cross(tangent, axis))


def _frames(pts, roll):
    """Unit tangents T and a normal u transported along each strand (m, ns, 3): u keeps
    its direction as far as the strand's bending allows (each u the last one made
    perpendicular to the next tangent), so the tube does not twist. roll (m,): the first
    u turned by this angle about the strand."""
    T = _unit(np.gradient(pts, axis=1))
    u = np.empty_like(pts)
    u0 = _perpendicular(T[:, 0])
    u[:, 0] = (np.cos(roll)[:, None] * u0
               + np.sin(roll)[:, None] * np.cross(T[:, 0], u0))
    for j in range(1, pts.shape[1]):
        prev = u[:, j - 1]
        w = prev - np.sum(prev * T[:, j], axis=1, keepdims=True) * T[:, j]
        bad = np.linalg.norm(w, axis=1) < 1e-6  # a kink of ~90 degrees: start again
        if bad.any():
            w[bad] = _perpendicular(T[bad, j])
        u[:, j] = _unit(w)
    return T, u


def tube_mesh(points, radius, offsets, sides: int | None = None,
              substeps: int | None = None, params: bool = False):
    """Triangle tubes round hair curves.

    points (P,3) float control points, radius (P,) float radii (m) at them, offsets (C+1,)
    int: curve c's points are points[offsets[c]:offsets[c + 1]] (Blender's
    curve_offset_data). sides / substeps: the polygon's corners and the spline pieces per
    key interval (None: `tessellation` of the object's key intervals).
    Returns (vertices (V,3) float64, faces (F,3) int64 wound outwards, normals (V,3) unit,
    straight out from the axis, curve (F,) int64 the curve each face belongs to); with
    params also (intercept (V,), radius (V,) m): the share of the strand's key polyline
    length from its root, linear between keys (Cycles' Curves Info Intercept,
    ATTR_STD_CURVE_INTERCEPT) and the spline's radius at the vertex's ring.
    Curves of fewer than 2 points and non-finite points (the whole curve) are left out;
    negative or non-finite radii read 0, and the triangles a ring of radius 0 makes lines
    of are left out. Raises ValueError on inconsistent offsets."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    radius = np.asarray(radius, np.float64).reshape(-1)
    offsets = np.asarray(offsets, np.int64).reshape(-1)
    if len(radius) != len(points):
        raise ValueError(f"hair: {len(radius)} radii for {len(points)} points")
    if len(offsets) < 1 or offsets[0] != 0 or offsets[-1] != len(points) or \
            np.any(np.diff(offsets) < 0):
        raise ValueError("hair: curve offsets must rise from 0 to the point count")
    radius = np.where(np.isfinite(radius) & (radius > 0), radius, 0.0)
    counts = np.diff(offsets)
    broken = np.concatenate([[0], np.cumsum(~np.isfinite(points).all(axis=1))])
    curve_ok = (broken[offsets[1:]] == broken[offsets[:-1]]) & (counts >= 2)
    if sides is None or substeps is None:
        auto = tessellation(int(np.sum(counts[curve_ok] - 1)))
        sides = auto[0] if sides is None else sides
        substeps = auto[1] if substeps is None else substeps
    if sides < 3 or substeps < 1:
        raise ValueError(f"hair: sides {sides} (>= 3) and substeps {substeps} (>= 1)")
    theta = 2.0 * math.pi * np.arange(sides) / sides
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    verts, faces, normals, curve_of, intercepts, radii = [], [], [], [], [], []
    base = 0
    for n in np.unique(counts[curve_ok]):
        which = np.flatnonzero(curve_ok & (counts == n))
        idx = offsets[which][:, None] + np.arange(n)[None, :]
        pts, i, t = catmull_rom(points[idx], substeps)
        r = radius[idx]
        r = r[:, i] * (1.0 - t) + r[:, i + 1] * t  # linear along each interval
        # Each strand's polygon rolled by its own angle within one corner's sector (a
        # fixed sequence, no random stream): strands lying alike (a combed tuft, a
        # test's strands in one plane) would otherwise all show the polygon's widest
        # or narrowest side, not its mean width.
        roll = (2.0 * math.pi / sides) * ((which * _GOLDEN) % 1.0)
        T, u = _frames(pts, roll)
        v = np.cross(T, u)
        # (m, ns, sides, 3) directions straight out from the axis
        out = (cos_t[None, None, :, None] * u[:, :, None, :]
               + sin_t[None, None, :, None] * v[:, :, None, :])
        rr = mean_width_radius(r, sides)
        m, ns = pts.shape[:2]
        verts.append((pts[:, :, None, :] + rr[:, :, None, None] * out).reshape(-1, 3))
        normals.append(out.reshape(-1, 3))
        if params:
            seg = np.linalg.norm(np.diff(points[idx], axis=1), axis=2)  # (m, n - 1)
            run = np.concatenate([np.zeros((len(which), 1)), np.cumsum(seg, axis=1)], 1)
            total = np.where(run[:, -1:] > 0, run[:, -1:], 1.0)
            at = (run[:, i] * (1.0 - t) + run[:, i + 1] * t) / total  # (m, ns)
            intercepts.append(np.repeat(at.reshape(-1), sides))
            radii.append(np.repeat(r.reshape(-1), sides))
        # Quads between rings j, j + 1 and corners k, k + 1: (a, b, c), (a, c, d).
        j = np.arange(ns - 1)[:, None]
        k = np.arange(sides)[None, :]
        a = j * sides + k
        b = j * sides + (k + 1) % sides
        c = (j + 1) * sides + (k + 1) % sides
        d = (j + 1) * sides + k
        quad = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 2).reshape(-1, 3)
        strand = (np.arange(m) * ns * sides)[:, None, None] + base
        tri = (quad[None] + strand).reshape(m, -1, 3)
        # A ring of radius 0 (a tip tapered to a point) makes one triangle of each of its
        # quads a line: (a, b, c) at ring j, (a, c, d) at ring j + 1; left out.
        keep = np.stack([np.broadcast_to((r[:, :-1] > 0)[:, :, None], (m, ns - 1, sides)),
                         np.broadcast_to((r[:, 1:] > 0)[:, :, None], (m, ns - 1, sides))],
                        3).reshape(m, -1)
        faces.append(tri[keep])
        curve_of.append(np.repeat(which, keep.sum(axis=1)))
        base += m * ns * sides
    if not verts:
        empty = (np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)),
                 np.zeros(0, np.int64))
        return empty + (np.zeros(0), np.zeros(0)) if params else empty
    out = (np.concatenate(verts), np.concatenate(faces).astype(np.int64),
           np.concatenate(normals), np.concatenate(curve_of).astype(np.int64))
    return out + (np.concatenate(intercepts), np.concatenate(radii)) if params else out
