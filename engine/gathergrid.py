"""A uniform grid over the gather points (engine/photonmap.GatherMap): the final gather's
nearest-point lookups in a few neighbouring cells instead of a kd-tree descent.

Layout: the points' box, padded by one cell on every side, cut into cubes of side h; the
points sorted by cell (a counting sort), so a cell's points are one range
[start[c], start[c+1]) of `index` (the point's index in the caller's arrays) and of
`position` (their float32 copies, in the same order, for cache locality). Cells are
numbered x fastest, so the three cells of a row along x are one range too.

The query (`candidate`) scans the 3 x 3 x 3 block of cells around the query point (its
own cell first; a cell whose nearest wall lies beyond the best distance so far is
skipped). A point found there is the exact nearest when its distance is no more than the query's
distance to the block's outside (at least h): no point outside the block can be nearer.
Otherwise (the nearest lies farther than the block reaches, or the query lies outside the
grid) the answer is `UNDECIDED` and the caller asks its kd-tree; the grid never returns a
different point than an exhaustive search would (except between points at exactly equal
distances, which the two may break differently). Distances are computed as the kd-tree
computes them (float64 differences from the float32 positions), so both see the same
squared distances.

Cell size: GRID_SPACINGS x the points' median nearest-neighbour distance, so the block
holds the nearest point of almost every query on the points' surfaces; raised where the
grid would exceed MAX_CELLS_PER_POINT cells per point (a few points spread over a large
box), which costs more points per cell, never a wrong answer. Memory: 20 B per point plus
8 B per cell (at most MAX_CELLS_PER_POINT x 8 B per point).
"""
from __future__ import annotations

import math

import numpy as np

from . import kdtree
from .jit import kernel, register_warm_up

GRID_SPACINGS = 1.5  # cell side / median nearest-neighbour spacing (measured: 1 - 2 within 10 %)
MAX_CELLS_PER_POINT = 8
SPACING_SAMPLE = 4096  # points whose nearest-neighbour distance sets the spacing
UNDECIDED = -2  # the block cannot settle the answer: ask the kd-tree


class GatherGrid:
    """The grid over points (N,3) float32 (indices into the caller's arrays: row order).
    tree: a kdtree.KdTree over the same points in the same order (its `position` are
    `points`), used once to measure their spacing. Raises ValueError for a shape other
    than (N,3)."""

    def __init__(self, points: np.ndarray, tree: kdtree.KdTree | None = None):
        pts = np.ascontiguousarray(points, dtype=np.float32)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"GatherGrid: points must have shape (N, 3), got {pts.shape}")
        n = len(pts)
        self.lo = np.zeros(3)
        self.dims = np.ones(3, np.int64)
        self.h = 1.0
        if n == 0:
            self.start = np.zeros(2, np.int64)
            self.index = np.zeros(0, np.int64)
            self.position = np.zeros((0, 3), np.float32)
            return
        p64 = pts.astype(np.float64)
        lo, hi = p64.min(axis=0), p64.max(axis=0)
        extent = float(np.max(hi - lo))
        h = GRID_SPACINGS * self._spacing(pts, tree)
        # Never finer than the float32 resolution of the coordinates (all points equal).
        h = max(h, 1e-6 * (float(np.max(np.abs(p64))) + extent), 1e-30)
        while True:
            dims = np.floor((hi - lo) / h).astype(np.int64) + 3  # one cell of padding
            if np.prod(dims.astype(np.float64)) <= MAX_CELLS_PER_POINT * n + 27:
                break
            h *= 1.25
        self.h = float(h)
        self.lo = lo - h
        self.dims = dims
        self.start, self.index, self.position = _build(pts, self.lo, self.h, self.dims)

    @staticmethod
    def _spacing(pts, tree):
        """Median distance from a point to its nearest other point (a strided sample)."""
        if len(pts) < 2:
            return 0.0
        if tree is None:
            tree = kdtree.KdTree(pts)
            pts = tree.position
        step = max(1, len(pts) // SPACING_SAMPLE)
        d, _ = tree.query(pts[::step].astype(np.float64), 2, np.inf)
        d = d[:, 1]
        d = d[np.isfinite(d) & (d > 0)]
        return float(np.median(d)) if len(d) else 0.0

    @property
    def nbytes(self) -> int:
        return self.start.nbytes + self.index.nbytes + self.position.nbytes

    @property
    def arrays(self):
        """(start, index, position, lo, h, dims): what the query kernels take."""
        return self.start, self.index, self.position, self.lo, self.h, self.dims


@kernel
def _build(pts, lo, h, dims):
    """Counting sort of pts (N,3) float32 into the cells: (start (cells+1,) int64,
    index (N,) int64, position (N,3) float32 in cell order)."""
    n = pts.shape[0]
    cells = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, np.int64)
    start = np.zeros(cells + 1, np.int64)
    for i in range(n):
        c = _cell_of(np.float64(pts[i, 0]), np.float64(pts[i, 1]), np.float64(pts[i, 2]),
                     lo, h, dims)
        cell[i] = c
        start[c + 1] += 1
    for c in range(cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    index = np.empty(n, np.int64)
    position = np.empty((n, 3), np.float32)
    for i in range(n):
        k = fill[cell[i]]
        fill[cell[i]] += 1
        index[k] = i
        position[k, 0], position[k, 1], position[k, 2] = pts[i, 0], pts[i, 1], pts[i, 2]
    return start, index, position


@kernel
def _axis_cell(x, lo, h, n):
    v = (x - lo) / h
    i = int(v) if v > 0.0 else 0
    return min(i, n - 1)


@kernel
def _cell_of(x, y, z, lo, h, dims):
    ix = _axis_cell(x, lo[0], h, dims[0])
    iy = _axis_cell(y, lo[1], h, dims[1])
    iz = _axis_cell(z, lo[2], h, dims[2])
    return (iz * dims[1] + iy) * dims[0] + ix


@kernel
def _block(q, lo, h, n, reach):
    """One axis of the query's block (the cells within `reach` cells of the query's):
    (first cell, last cell, the query's cell, the query's distance to the block's outside
    along this axis (inf where the block reaches the grid's edge)), or first > last when
    the query lies outside the grid (or is NaN)."""
    v = (q - lo) / h
    if not (v >= 0.0 and v < n):
        return 1, 0, 0, 0.0
    i = int(v)
    a = max(i - reach, 0)
    b = min(i + reach, n - 1)
    m = np.inf
    if a > 0:
        m = q - (lo + a * h)
    if b < n - 1:
        m = min(m, lo + (b + 1) * h - q)
    return a, b, i, m


@kernel
def _gap(i, iq, q, lo, h, eps):
    """A lower bound on the distance along one axis from q (in cell iq) to cell i: the
    wall between them, less eps (the walls' rounding error, see candidate_in)."""
    if i < iq:
        g = q - (lo + (i + 1) * h)
    elif i > iq:
        g = (lo + i * h) - q
    else:
        return 0.0
    return max(g - eps, 0.0)


@kernel
def _scan(start, index, position, normal, lo, h, dims, qx, qy, qz, nx, ny, nz, agreement,
          x0, x1, y0, y1, z0, z1, ix, iy, iz, eps, bound, mode):
    """One pass over the block's cells, the query's own cell first, skipping every cell
    whose nearest wall is no nearer than `bound` (its points cannot pass the test below).
    mode 0: the nearest point with squared distance < bound; 1: the same among the points
    whose normal agrees; both return (slot in the cell order, its squared distance) or
    (-1, bound). mode 2: (number of points with squared distance < bound, bound)."""
    best = -1
    count = 0
    for pass_ in range(2):
        for cz in range(z0, z1 + 1):
            gz = _gap(cz, iz, qz, lo[2], h, eps)
            for cy in range(y0, y1 + 1):
                gy = _gap(cy, iy, qy, lo[1], h, eps)
                for cx in range(x0, x1 + 1):
                    own = cx == ix and cy == iy and cz == iz
                    if own != (pass_ == 0):
                        continue
                    gx = _gap(cx, ix, qx, lo[0], h, eps)
                    if gx * gx + gy * gy + gz * gz >= bound:
                        continue
                    c = (cz * dims[1] + cy) * dims[0] + cx
                    for k in range(start[c], start[c + 1]):
                        dx = qx - np.float64(position[k, 0])
                        dy = qy - np.float64(position[k, 1])
                        dz = qz - np.float64(position[k, 2])
                        d2 = dx * dx + dy * dy + dz * dz
                        if d2 < bound:
                            if mode == 2:
                                count += 1
                                continue
                            if mode == 1:
                                j = index[k]
                                if normal[j, 0] * nx + normal[j, 1] * ny \
                                        + normal[j, 2] * nz <= agreement:
                                    continue
                            best = k
                            bound = d2
    if mode == 2:
        return count, bound
    return best, bound


@kernel
def candidate(start, index, position, lo, h, dims, normal, qx, qy, qz, nx, ny, nz, agreement,
              r2, kmax):
    """The gather lookup's rule (candidate_in) in the 3 x 3 x 3 block around the query's
    cell, then, if that cannot tell, in the 5 x 5 x 5 block."""
    c, near = candidate_in(start, index, position, lo, h, dims, normal, qx, qy, qz, nx, ny,
                           nz, agreement, r2, kmax, 1)
    if c != UNDECIDED:
        return c, near
    return candidate_in(start, index, position, lo, h, dims, normal, qx, qy, qz, nx, ny, nz,
                        agreement, r2, kmax, 2)


@kernel
def candidate_in(start, index, position, lo, h, dims, normal, qx, qy, qz, nx, ny, nz,
                 agreement, r2, kmax, reach):
    """The gather lookup's rule in the grid: the nearest point j with squared distance
    < r2 if its normal agrees (normal[j] . n > agreement); else the nearest agreeing
    point, if fewer than kmax points are nearer than it; else none (-1). Returns
    (point, nearest point found (-1: none)), or (UNDECIDED, -1) where the block cannot
    tell (see the module docstring). normal: (N,3) in the caller's order; reach: the
    block's half width in cells (1: 3 x 3 x 3)."""
    x0, x1, ix, mx = _block(qx, lo[0], h, dims[0], reach)
    y0, y1, iy, my = _block(qy, lo[1], h, dims[1], reach)
    z0, z1, iz, mz = _block(qz, lo[2], h, dims[2], reach)
    if x0 > x1 or y0 > y1 or z0 > z1:
        return UNDECIDED, -1
    # The cell walls are computed in float64 from lo and h: keep a margin far above
    # their rounding error, so a point just across a wall is never missed.
    eps = 1e-9 * (abs(qx) + abs(qy) + abs(qz) + abs(lo[0]) + abs(lo[1]) + abs(lo[2]) + h
                  * (dims[0] + dims[1] + dims[2]))
    m = min(mx, my, mz)
    if m < np.inf:
        m -= eps
        margin2 = m * m if m > 0.0 else 0.0
    else:
        margin2 = np.inf
    best, bd2 = _scan(start, index, position, normal, lo, h, dims, qx, qy, qz, nx, ny, nz,
                      agreement, x0, x1, y0, y1, z0, z1, ix, iy, iz, eps, r2, 0)
    if best < 0:
        return (-1, -1) if margin2 >= r2 else (UNDECIDED, -1)
    if bd2 > margin2:
        return UNDECIDED, -1
    j = index[best]
    if normal[j, 0] * nx + normal[j, 1] * ny + normal[j, 2] * nz > agreement:
        return j, j
    if kmax <= 1:
        return -1, j
    # The nearest faces another way: the nearest facing point, then the rank test.
    fbest, fd2 = _scan(start, index, position, normal, lo, h, dims, qx, qy, qz, nx, ny, nz,
                       agreement, x0, x1, y0, y1, z0, z1, ix, iy, iz, eps, r2, 1)
    if fbest < 0:
        return (-1, j) if margin2 >= r2 else (UNDECIDED, -1)
    if fd2 > margin2:
        return UNDECIDED, -1
    # Every point nearer than the facing one lies in the block (fd2 <= margin2).
    closer, _ = _scan(start, index, position, normal, lo, h, dims, qx, qy, qz, nx, ny, nz,
                      agreement, x0, x1, y0, y1, z0, z1, ix, iy, iz, eps, fd2, 2)
    return (index[fbest] if closer < kmax else -1), j


@register_warm_up
def _warm_up():
    pts = np.random.default_rng(0).random((40, 3)).astype(np.float32)
    g = GatherGrid(pts)
    nrm = np.zeros((40, 3))
    nrm[:, 2] = 1.0
    candidate(*g.arrays, nrm, 0.5, 0.5, 0.5, 0.0, 0.0, 1.0, 0.7, 0.1, 64)
