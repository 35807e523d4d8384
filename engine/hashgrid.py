"""A hashed uniform grid over points: the photon search structure of pbrt-v4's SPPM.

pbrt-v4 (src/pbrt/cpu/integrators.cpp, SPPMIntegrator::Render) sizes the grid cells by the
largest search radius (resolution = bounds diagonal / max radius) and maps each cell to a
bucket with a hash modulo the number of stored items; pbrt stores the camera's visible
points and looks them up per photon. Here the photons are stored and a query scans the
buckets of every cell its search sphere overlaps (27 cells when the radius is at most the
cell size). Buckets are a compressed sparse row layout (a counting sort by bucket: one
start offset per bucket, the points in bucket order), so there are no lists or pointers.
Cells that hash to one bucket share it: a query scans each bucket once and the distance
test drops the other cells' points.

Memory: the points (float32, 12 B) plus one int32 bucket start per point (the table has
the next power of two >= N buckets: 4-8 B per point).

The queries match engine/kdtree.py's (knn, ball, ball_count) in arguments and results,
with `grid` = (origin x, y, z, cell size) and `start` the bucket offsets in place of the
kd-tree's axis array.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up
from .kdtree import heap_insert, heap_sort

# Teschner et al. 2003, "Optimized Spatial Hashing for Collision Detection of Deformable
# Objects": three large primes, xor-combined.
P1, P2, P3 = 73856093, 19349663, 83492791


@kernel
def _bucket(ix, iy, iz, mask):
    return ((ix * P1) ^ (iy * P2) ^ (iz * P3)) & mask


@kernel
def _cell(v, o, cell):
    return np.int64(math.floor((v - o) / cell))


@kernel
def build(points, ox, oy, oz, cell, table):
    """Counting sort of points (N,3) float32 into `table` (a power of two) buckets.
    Returns (order (N,) int64: slot i holds points[order[i]], start (table+1,) int32)."""
    n = points.shape[0]
    mask = table - 1
    key = np.empty(n, np.int64)
    start = np.zeros(table + 1, np.int32)
    for i in range(n):
        b = _bucket(_cell(np.float64(points[i, 0]), ox, cell),
                    _cell(np.float64(points[i, 1]), oy, cell),
                    _cell(np.float64(points[i, 2]), oz, cell), mask)
        key[i] = b
        start[b + 1] += 1
    for b in range(table):
        start[b + 1] += start[b]
    fill = start[:table].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        b = key[i]
        order[fill[b]] = i
        fill[b] += 1
    return order, start


@kernel
def _scan(pos, start, grid, qx, qy, qz, r2, mode, kq, d2, idx, buckets, cap):
    """One query over the buckets of the cells the sphere (q, sqrt(r2)) overlaps.
    mode 0: knn (kq nearest with d^2 < r2 into the max-heap d2/idx); 1: ball (indices with
    d^2 <= r2 into idx, stop after cap); 2: ball_count. buckets: scratch for the visited
    buckets (at least the number of overlapped cells). Returns the count (ball: cap + 1
    when more than cap)."""
    ox, oy, oz, cell = grid[0], grid[1], grid[2], grid[3]
    mask = start.shape[0] - 2
    r = math.sqrt(r2)
    x0, x1 = _cell(qx - r, ox, cell), _cell(qx + r, ox, cell)
    y0, y1 = _cell(qy - r, oy, cell), _cell(qy + r, oy, cell)
    z0, z1 = _cell(qz - r, oz, cell), _cell(qz + r, oz, cell)
    nb = 0
    count = 0
    bound = r2
    for ix in range(x0, x1 + 1):
        for iy in range(y0, y1 + 1):
            for iz in range(z0, z1 + 1):
                b = _bucket(ix, iy, iz, mask)
                seen = False
                for t in range(nb):
                    if buckets[t] == b:
                        seen = True
                        break
                if seen:
                    continue
                buckets[nb] = b
                nb += 1
                for j in range(start[b], start[b + 1]):
                    dx = qx - np.float64(pos[j, 0])
                    dy = qy - np.float64(pos[j, 1])
                    dz = qz - np.float64(pos[j, 2])
                    dist2 = dx * dx + dy * dy + dz * dz
                    if mode == 0:
                        if dist2 < bound:
                            count = heap_insert(d2, idx, count, kq, dist2, j)
                            if count == kq:
                                bound = d2[0]
                    elif dist2 <= r2:
                        if mode == 1:
                            if count == cap:
                                return cap + 1
                            idx[count] = j
                        count += 1
    if mode == 0:
        heap_sort(d2, idx, count, kq)
    return count


@kernel
def cells_spanned(grid, radius):
    """Upper bound on the cells a query sphere of this radius overlaps (scratch size)."""
    per_axis = np.int64(math.floor(2.0 * radius / grid[3])) + 2
    return per_axis * per_axis * per_axis


@kernel
def knn(pos, start, grid, qx, qy, qz, kq, r2, d2, idx, buckets):
    """As kdtree.knn: the kq nearest with d^2 < r2 into d2/idx (increasing distance)."""
    if pos.shape[0] == 0 or kq <= 0:
        return 0
    return _scan(pos, start, grid, qx, qy, qz, r2, 0, kq, d2, idx, buckets, 0)


@kernel
def ball(pos, start, grid, qx, qy, qz, r2, out, cap, buckets):
    """As kdtree.ball: indices with d^2 <= r2 into out (cap + 1 when more than cap)."""
    if pos.shape[0] == 0:
        return 0
    return _scan(pos, start, grid, qx, qy, qz, r2, 1, 0, out[:0].astype(np.float64), out,
                 buckets, cap)


@kernel
def ball_count(pos, start, grid, qx, qy, qz, r2, buckets):
    """As kdtree.ball_count: how many points have d^2 <= r2."""
    if pos.shape[0] == 0:
        return 0
    empty = np.empty(0, np.int64)
    return _scan(pos, start, grid, qx, qy, qz, r2, 2, 0, empty.astype(np.float64), empty,
                 buckets, 0)


@kernel
def knn_batch(pos, start, grid, queries, kq, radius):
    """As kdtree.knn_batch (scipy cKDTree.query form)."""
    m = queries.shape[0]
    n = pos.shape[0]
    dist = np.full((m, kq), np.inf)
    out = np.full((m, kq), n, np.int64)
    d2 = np.empty(max(kq, 1), np.float64)
    idx = np.empty(max(kq, 1), np.int64)
    buckets = np.empty(cells_spanned(grid, radius), np.int64)
    r2 = radius * radius
    for i in range(m):
        c = knn(pos, start, grid, queries[i, 0], queries[i, 1], queries[i, 2], kq, r2, d2,
                idx, buckets)
        for j in range(c):
            dist[i, j] = np.sqrt(d2[j])
            out[i, j] = idx[j]
    return dist, out


class HashGrid:
    """Points (N,3) hashed into cells of size `cell` (the search radius it is built for;
    any radius can be queried, larger ones scan more cells). self.order maps slot ->
    input index."""

    def __init__(self, points: np.ndarray, cell: float):
        pts = np.ascontiguousarray(points, dtype=np.float32)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"HashGrid: points must have shape (N, 3), got {pts.shape}")
        if not (cell > 0 and math.isfinite(cell)):
            raise ValueError(f"HashGrid: cell size must be positive and finite, got {cell!r}")
        lo = pts.min(axis=0).astype(np.float64) if len(pts) else np.zeros(3)
        # Cell indices must fit the hash's int64 products: coarsen a cell far too small
        # for the points' extent (at most 2^20 cells per axis).
        extent = float((pts.max(axis=0) - pts.min(axis=0)).max()) if len(pts) else 0.0
        cell = max(float(cell), extent / (1 << 20))
        self.grid = np.array([lo[0], lo[1], lo[2], cell], np.float64)
        table = 1 << max(1, int(len(pts) - 1).bit_length())
        self.order, self.start = build(pts, lo[0], lo[1], lo[2], cell, table)
        self.position = np.ascontiguousarray(pts[self.order])

    def __len__(self):
        return len(self.position)

    @property
    def nbytes(self) -> int:
        return self.position.nbytes + self.start.nbytes

    def query(self, queries: np.ndarray, k: int, radius: float):
        """(dist, idx) like cKDTree.query with distance_upper_bound; idx are slots."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        return knn_batch(self.position, self.start, self.grid, q, int(k), float(radius))


@register_warm_up
def _warm_up():
    pts = np.random.default_rng(0).random((40, 3)).astype(np.float32)
    g = HashGrid(pts, 0.2)
    g.query(pts[:3].astype(np.float64), 4, 0.2)
    buckets = np.empty(cells_spanned(g.grid, 0.2), np.int64)
    out = np.empty(8, np.int64)
    ball(g.position, g.start, g.grid, 0.5, 0.5, 0.5, 0.04, out, 8, buckets)
    ball_count(g.position, g.start, g.grid, 0.5, 0.5, 0.5, 0.04, buckets)
