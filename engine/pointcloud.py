"""Point clouds (Blender's Point Cloud objects: Geometry Nodes points) as triangle spheres.

Cycles renders each point of a point cloud as a sphere of the point's radius (its Point
primitive, scene/pointcloud.cpp). Embree is handed triangles here, so each point becomes
an icosphere whose vertices carry the sphere's own normals (straight out from the centre:
smooth shading reads the true sphere's normals) and whose size is chosen so that its
surface area is the sphere's, 4 pi r^2. By Cauchy's formula a convex body's projected
area averaged over all directions is a quarter of its surface area, so the polyhedron
blocks, receives and reflects as much light as the sphere on average (as engine/hair.py
gives a strand's polygon the circle's perimeter, its mean width).

The finest of SPHERE_LEVELS (icosphere subdivisions) whose triangles fit
POINT_TRIANGLE_BUDGET is used: 320 triangles a point for up to 12,500 points, 80 for up to
50,000, 20 beyond.
"""
from __future__ import annotations

import math

import numpy as np

SPHERE_LEVELS = (2, 1, 0)  # icosphere subdivisions, finest first: 320, 80, 20 triangles
POINT_TRIANGLE_BUDGET = 4_000_000
DEFAULT_RADIUS = 0.01  # m: Cycles' radius of a point without the "radius" attribute


def icosphere(level: int) -> tuple:
    """The unit icosphere subdivided `level` times: (vertices (V,3) float64 on the unit
    sphere, faces (F,3) int64 wound outwards), F = 20 x 4^level."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
             (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
             (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    v = [np.array(p, np.float64) / np.linalg.norm(p) for p in verts]
    f = faces
    for _ in range(level):
        middle = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in middle:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                middle[key] = len(v) - 1
            return middle[key]

        f = [tri for a, b, c in f for tri in
             ((a, mid(a, b), mid(c, a)), (b, mid(b, c), mid(a, b)),
              (c, mid(c, a), mid(b, c)), (mid(a, b), mid(b, c), mid(c, a)))]
    return np.array(v), np.array(f, np.int64)


def area_scale(verts: np.ndarray, faces: np.ndarray) -> float:
    """The factor that gives the unit-sphere polyhedron (verts, faces) the unit sphere's
    surface area 4 pi (module docstring: Cauchy's mean projected area)."""
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    return math.sqrt(4.0 * math.pi / area)


def sphere_level(points: int, budget: int = POINT_TRIANGLE_BUDGET) -> int:
    """The finest icosphere level of SPHERE_LEVELS whose triangles for `points` spheres
    fit `budget`, else the coarsest."""
    for level in SPHERE_LEVELS:
        if points * 20 * 4 ** level <= budget:
            return level
    return SPHERE_LEVELS[-1]


def sphere_mesh(centres, radius, level: int | None = None):
    """Triangle spheres round points.

    centres (N,3) float m, radius (N,) float m (non-finite or <= 0: the point is left
    out, as are non-finite centres); level: icosphere subdivisions (None: sphere_level).
    Returns (vertices (V,3) float64, faces (F,3) int64 wound outwards, normals (V,3) unit,
    straight out from the centre, point (F,) int64 the point each face belongs to)."""
    centres = np.asarray(centres, np.float64).reshape(-1, 3)
    radius = np.asarray(radius, np.float64).reshape(-1)
    if len(radius) != len(centres):
        raise ValueError(f"point cloud: {len(radius)} radii for {len(centres)} points")
    keep = np.flatnonzero(np.isfinite(centres).all(axis=1) & np.isfinite(radius)
                          & (radius > 0.0))
    if level is None:
        level = sphere_level(len(keep))
    unit, tris = icosphere(level)
    scale = area_scale(unit, tris)
    n, nv = len(keep), len(unit)
    verts = (centres[keep][:, None, :]
             + (radius[keep] * scale)[:, None, None] * unit[None, :, :]).reshape(-1, 3)
    normals = np.broadcast_to(unit, (n, nv, 3)).reshape(-1, 3).copy()
    faces = (tris[None, :, :] + (np.arange(n, dtype=np.int64) * nv)[:, None, None])
    point = np.repeat(keep.astype(np.int64), len(tris))
    return verts, faces.reshape(-1, 3), normals, point
