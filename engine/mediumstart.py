"""The medium a point is in: a camera inside a fog box (or under water) starts its paths in
that medium.

engine/media.py carries each path's medium from the crossings it makes; a path that starts
inside a closed medium object (a camera inside a fog cube that holds the whole scene) has
crossed nothing, and without this its segments to surfaces inside the fog would see
neither the fog's extinction nor its in-scattering (engine/volumescatter.py), only the
segments that end on the fog's own walls (media.py's back-face rule).

point_medium walks one ray from the point through every surface (a fixed direction off
the axes, so it does not graze axis-aligned boxes' edges) and reads the first medium
surface it leaves without having entered it on the way: the object's medium the point is
inside (meshes closed, normals outward, as media.py and Cycles ask). One level, as
media.py: the innermost medium.
"""
from __future__ import annotations

import numpy as np

# The walk's direction (unit, off every axis and diagonal) and its bound in surfaces.
WALK_DIRECTION = np.array([0.2897, 0.4511, 0.8440]) / np.linalg.norm([0.2897, 0.4511, 0.8440])
MAX_SURFACES = 256


def point_medium(ctx, point, sigma, outside: int = -1) -> int:
    """The material row of the medium (sigma (M,3) media.absorption_table: rows with a
    channel > 0) that contains `point` (3,) (the scene's re-centred frame), or `outside`
    when it lies in none (the world volume's row, engine/worldmedium.medium_row; -1:
    none), or -1 without media (sigma with 0 rows)."""
    if sigma.shape[0] == 0:
        return -1
    d = WALK_DIRECTION[None, :].copy()
    o = np.asarray(point, np.float64).reshape(1, 3).copy()
    entered = set()
    for _ in range(MAX_SURFACES):
        t, prim, _, _ = ctx.accel.intersect(o, d)
        if prim[0] < 0 or not np.isfinite(t[0]):
            return outside
        rows, (material, e1, e2) = ctx.geo.hit_tables(prim, "material", "e1", "e2")
        r = int(rows[0])
        m = int(material[r])
        if np.any(sigma[m] > 0):
            facing = float(d[0] @ np.cross(e1[r], e2[r]))
            if facing > 0.0:  # leaving m's object through its back face
                if m not in entered:
                    return m
                entered.discard(m)
            elif facing < 0.0:
                entered.add(m)
        hit = o + d * t[0]
        # Past the surface: a step relative to the coordinates' size (float32 BVH).
        o = hit + d * (1e-4 * (1.0 + float(np.abs(hit).max())))
    return outside
