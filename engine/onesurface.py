"""Photon visibility's pre-test (engine/photonvisibility.py): which density-estimate rows
have no surface near them that could hide a photon of their disc, so that their
visibility rays need not be traced.

Plain Python (numpy, scipy.ndimage): no kernels here, so that editing this module does
not recompile the engine's kernels (engine/jit.py's stamp hashes only the files that
define kernels).

Scale (issues 13/14, docs/performance.md "scale"): a scene with many triangle
orientations (300 randomly rotated rocks and trees on a 200 m ground) has tens of
thousands of them, and the rows ask for thousands. The rows' orientation lookup compared
every row orientation with every triangle orientation (a (B, K, 3) bool array, hundreds
of MB a call); it is now a sort (_orientation_index). The own-orientation grids were one
full fine-grid bool array per orientation asked for, kept for the render (thousands of
them); they are now one int32 grid for every orientation at once (OneSurfaceCells._sole),
from which any orientation's grid is read exactly.
"""
from __future__ import annotations

import threading

import numpy as np

# The pre-test's grid: its most cells and (triangle, cell) entries; beyond either, every
# row is tested.
CELLS_MAX = 1 << 24
ENTRIES_MAX = 1 << 24
# Normals closer than this (unit normals' components) are one orientation for the
# pre-test (a mesh's coplanar triangles round a little differently).
PLANE_TOLERANCE = 1e-4
# The own-orientation pre-test's cells (OneSurfaceCells.free with normals): this many to
# the search radius, and its most cells.
FINE_DIVISIONS = 4
FINE_CELLS_MAX = 1 << 22
# What a OneSurfaceCells keeps at most (bytes): its busy grid (bool, CELLS_MAX cells), its
# fine grid and sole-orientation grid (int32 each, FINE_CELLS_MAX cells; int64 only past
# 2^31 orientations). engine/resources.py counts it for each radius photon visibility
# asks with (the global, caustic and secondary maps').
KEPT_BYTES_MAX = CELLS_MAX + 8 * FINE_CELLS_MAX


def _orientation_keys(normals):
    """(N,3) int64: unit normals (N,3) up to sign, rounded to PLANE_TOLERANCE (equal keys:
    one orientation for the pre-tests)."""
    ng = np.asarray(normals, np.float64)
    ng = ng / np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-300)
    big = np.argmax(np.abs(ng), axis=1)
    ng = ng * np.where(ng[np.arange(len(ng)), big] < 0, -1.0, 1.0)[:, None]
    return np.round(ng / PLANE_TOLERANCE).astype(np.int64)


def _unique_keys(rk):
    """np.unique(rk, axis=0, return_inverse=True) (inverse flat) for orientation keys rk
    (N,3) int64 (_orientation_keys: |key| <= 1 / PLANE_TOLERANCE): rows that all equal
    the first need no sort, the others sort as one int64 key (three 15-bit fields, the
    same order). np.unique's axis=0 sort (structured rows) was 0.38 of Figure 7's 33
    CPU s."""
    if len(rk) and (rk == rk[0]).all():
        return rk[:1].copy(), np.zeros(len(rk), np.int64)
    off = int(round(1.0 / PLANE_TOLERANCE))
    if len(rk) and rk.min() >= -off and rk.max() <= off and 2 * off < (1 << 15):
        key = ((rk[:, 0] + off) << 30) | ((rk[:, 1] + off) << 15) | (rk[:, 2] + off)
        u, which = np.unique(key, return_inverse=True)
        both = np.column_stack([(u >> 30) - off, ((u >> 15) & 0x7FFF) - off,
                                (u & 0x7FFF) - off])
        return both, which.reshape(-1)
    both, which = np.unique(rk, axis=0, return_inverse=True)
    return both, which.reshape(-1)


def _packed_keys(rk):
    """(N,) int64: orientation keys rk (N,3) int64 packed as _unique_keys packs them (three
    15-bit fields: the rows' lexicographic order), or None when a component lies outside
    +-1 / PLANE_TOLERANCE (no packing); (N,) bool beside it: the rows inside that range."""
    off = int(round(1.0 / PLANE_TOLERANCE))
    if 2 * off >= (1 << 15):
        return None, None
    inside = np.all((rk >= -off) & (rk <= off), axis=1)
    r = np.where(inside[:, None], rk, 0) + off
    return (r[:, 0] << 30) | (r[:, 1] << 15) | r[:, 2], inside


class KeyIndex:
    """Distinct orientation keys (K,3) int64 sorted once, so that each call's rows find
    theirs by a binary search (O(Q log K)) instead of sorting the K keys with the Q rows
    (_orientation_index's np.unique: a hair groom's tubes have ~10^5 orientations, ~30 ms
    a call; docs/performance.md hair39)."""

    def __init__(self, keys):
        self.keys = np.asarray(keys, np.int64).reshape(-1, 3)
        packed, inside = _packed_keys(self.keys)
        self.sorted = None
        if packed is not None and inside.all():
            self.order = np.argsort(packed, kind="stable")
            self.sorted = packed[self.order]

    def find(self, queries) -> np.ndarray:
        """(Q,) int64: the index in keys of each row of queries (Q,3) int64, -1 where
        keys has no such row (_orientation_index's answer)."""
        queries = np.asarray(queries, np.int64).reshape(-1, 3)
        if self.sorted is None:
            return _unique_index(self.keys, queries)
        if not len(self.keys) or not len(queries):
            return np.full(len(queries), -1, np.int64)
        packed, inside = _packed_keys(queries)
        at = np.minimum(np.searchsorted(self.sorted, packed), len(self.sorted) - 1)
        found = inside & (self.sorted[at] == packed)
        return np.where(found, self.order[at], -1).astype(np.int64)


def _orientation_index(keys, queries):
    """(Q,) int64: for each row of queries (Q,3) int64, the index of the equal row of keys
    (K,3) int64 (rows distinct), -1 where keys has none: the same answer as comparing
    every query with every key (O(K Q)), by KeyIndex's binary search (keys whose
    components pack) or one sort of both together (_unique_index)."""
    return KeyIndex(keys).find(queries)


def _unique_index(keys, queries):
    """_orientation_index by one sort of keys and queries together (np.unique over rows:
    O((K + Q) log(K + Q)) time, O(K + Q) memory)."""
    keys = np.asarray(keys, np.int64).reshape(-1, 3)
    queries = np.asarray(queries, np.int64).reshape(-1, 3)
    if not len(keys) or not len(queries):
        return np.full(len(queries), -1, np.int64)
    _, inv = _unique_keys(np.concatenate([keys, queries]))
    at = np.full(int(inv.max()) + 1, -1, np.int64)
    at[inv[:len(keys)]] = np.arange(len(keys))
    return at[inv[len(keys):]]


def _code_type(orientations: int):
    """The grids' integer type for codes -2 .. orientations - 1 (int32 but for more than
    2^31 - 2 orientations: the fine and sole grids' bytes are KEPT_BYTES_MAX's)."""
    return np.int32 if orientations < np.iinfo(np.int32).max - 1 else np.int64


class OneSurfaceCells:
    """Which points have only surfaces parallel to their own within `cell` of them, so
    that no occluder can stand between them and the photons of a disc of radius <= cell:
    the scene's triangles (Geometry v0, e1, e2, ng) binned by their bounding boxes into a
    grid of side `cell`; a cell is 'busy' when the triangles overlapping it have more
    than one orientation (normals up to sign); a point is free when no cell of the
    3 x 3 x 3 around its own is busy. A segment from a point to a photon within `cell`
    lies in those 27 cells, and any triangle it crosses overlaps them (its box does); a
    triangle parallel to the point's plane cannot cross the segment, which follows that
    plane a ray offset above it, so a crossing triangle makes a cell busy. (A parallel
    surface within a ray offset of the plane, closer than any renderer resolves, is the
    only case a traced ray could read differently.) Conservative otherwise: a busy
    neighbourhood only means the rays are traced (Figure 8's caustic rows on its open
    floor and a thin wall's face skip them; a lamp shade piercing a wall, corners,
    curved objects do not)."""

    def __init__(self, geo, cell: float):
        self.cell = float(cell)
        self.busy = None  # None: test every row
        v0 = np.asarray(geo.v0, np.float64)
        if not len(v0) or not self.cell > 0 or getattr(geo, "shared", None) is not None:
            return
        v1, v2 = v0 + np.asarray(geo.e1, np.float64), v0 + np.asarray(geo.e2, np.float64)
        lo = np.minimum(np.minimum(v0, v1), v2)
        hi = np.maximum(np.maximum(v0, v1), v2)
        self.origin = lo.min(axis=0) - self.cell
        dims = np.floor((hi.max(axis=0) + self.cell - self.origin) / self.cell).astype(
            np.int64) + 1
        if np.prod(dims.astype(np.float64)) > CELLS_MAX:
            return
        a = np.floor((lo - self.origin) / self.cell).astype(np.int64)
        b = np.floor((hi - self.origin) / self.cell).astype(np.int64)
        span = b - a + 1
        count = np.prod(span, axis=1)
        if count.sum() > ENTRIES_MAX:
            return
        # A triangle's orientation up to sign: parallel planes (a thin wall's back face,
        # a shelf above a floor) cannot cross the point's own plane, which the lifted
        # visibility ray follows, so only orientations count.
        keys, plane = _unique_keys(_orientation_keys(geo.ng))
        plane = plane.reshape(-1)
        self._fine(lo, hi, keys, plane)
        tri = np.repeat(np.arange(len(v0)), count)
        local = np.arange(len(tri)) - np.repeat(np.cumsum(count) - count, count)
        sx, sy = span[tri, 0], span[tri, 1]
        ix = a[tri, 0] + local % sx
        iy = a[tri, 1] + (local // sx) % sy
        iz = a[tri, 2] + local // (sx * sy)
        flat = (ix * dims[1] + iy) * dims[2] + iz
        # A cell is busy when any of its entries' plane differs from the one written
        # last there (fancy assignment keeps one of the duplicates: any one will do).
        some = np.full(int(np.prod(dims)), -1, _code_type(len(keys)))
        some[flat] = plane[tri]
        busy = np.zeros(len(some), bool)
        busy[flat[some[flat] != plane[tri]]] = True
        from scipy.ndimage import binary_dilation
        self.dims = dims
        self.busy = binary_dilation(busy.reshape(tuple(dims)), np.ones((3, 3, 3), bool))

    def _fine(self, lo, hi, keys, plane):
        """The own-orientation grid: cells of side cell / FINE_DIVISIONS, each the one
        orientation (index into keys) of the triangles overlapping it, -1 for none, -2
        for more than one (None: too many cells or entries)."""
        self.fine = None
        self.keys = keys
        self.key_index = KeyIndex(keys)  # sorted once: free()'s rows search it
        self._sole_grid = None
        self._sole_lock = threading.Lock()
        side = self.cell / FINE_DIVISIONS
        origin = lo.min(axis=0) - self.cell
        dims = np.floor((hi.max(axis=0) + self.cell - origin) / side).astype(np.int64) + 1
        if np.prod(dims.astype(np.float64)) > FINE_CELLS_MAX:
            return
        a = np.floor((lo - origin) / side).astype(np.int64)
        b = np.floor((hi - origin) / side).astype(np.int64)
        span = b - a + 1
        count = np.prod(span, axis=1)
        if count.sum() > ENTRIES_MAX:
            return
        tri = np.repeat(np.arange(len(lo)), count)
        local = np.arange(len(tri)) - np.repeat(np.cumsum(count) - count, count)
        sx, sy = span[tri, 0], span[tri, 1]
        flat = (((a[tri, 0] + local % sx) * dims[1] + a[tri, 1] + (local // sx) % sy)
                * dims[2] + a[tri, 2] + local // (sx * sy))
        code = np.full(int(np.prod(dims)), -1, _code_type(len(keys)))
        code[flat] = plane[tri]
        mixed = flat[code[flat] != plane[tri]]
        code[mixed] = -2
        self.fine = code.reshape(tuple(dims))
        self.fine_origin, self.fine_side, self.fine_dims = origin, side, dims

    def _sole(self) -> np.ndarray:
        """The fine grid's cells' sole orientation over their neighbourhood (every cell a
        disc of radius cell, centred in the cell, can reach, plus one for the rays' lifted
        ends: a cube of 2 (FINE_DIVISIONS + 1) + 1 cells), of the fine grid's dtype and
        shape): -1 when no triangle overlaps the neighbourhood, o >= 0 when every
        triangle overlapping it has orientation o, -2 otherwise. A cell is clear for
        orientation o (the neighbourhood holds triangles of orientation o alone, or none)
        exactly when its value is -1 or o: one grid for every orientation (_clear_of),
        built once (thread-safe: the render's worker threads share this object), from
        the neighbourhood's least and greatest codes (empty cells left out), equal to o
        exactly when all its codes are o."""
        got = self._sole_grid
        if got is not None:
            return got
        with self._sole_lock:
            if self._sole_grid is None:
                from scipy.ndimage import maximum_filter, minimum_filter
                dtype = self.fine.dtype.type
                none = np.iinfo(dtype).max
                size = 2 * (FINE_DIVISIONS + 1) + 1
                code = self.fine.copy()
                # Outside the grid: no triangle (the constant mode's cval, as empty cells).
                hi = maximum_filter(code, size=size, mode="constant", cval=-1)
                code[code == -1] = none
                lo = minimum_filter(code, size=size, mode="constant", cval=none)
                del code
                sole = np.where(lo == hi, lo, dtype(-2))
                sole[lo == none] = -1
                self._sole_grid = sole
        return self._sole_grid

    def _clear_of(self, o: int) -> np.ndarray:
        """(fine grid's shape) bool: the fine grid's cells whose neighbourhood (_sole's)
        holds triangles of orientation o alone, or none."""
        sole = self._sole()
        return (sole == -1) | (sole == o)

    def free(self, p, reach, n=None) -> np.ndarray:
        """(M,) bool: the points p (M,3) whose discs (radius <= reach (M,)) meet no
        occluder (class docstring); all False without a grid or for a disc wider than a
        cell. n: (M,3) the points' unit normals, or None: also free are the points whose
        disc meets only triangles parallel to their own plane (the fine grid, _fine),
        which cannot cross the visibility rays, that follow the plane a ray offset
        above it (the same reasoning as the class docstring's, without needing the
        point's own surface in each cell the rays cross)."""
        p = np.asarray(p, np.float64)
        out = np.zeros(len(p), bool)
        if self.busy is None or not len(p):
            return out
        reach = np.broadcast_to(np.asarray(reach, np.float64), (len(p),))
        c = np.floor((p - self.origin) / self.cell).astype(np.int64)
        inside = np.all((c >= 0) & (c < self.dims), axis=1) & (reach <= self.cell)
        ci = c[inside]
        out[inside] = ~self.busy[ci[:, 0], ci[:, 1], ci[:, 2]]
        if n is None or self.fine is None:
            return out
        f = np.floor((p - self.fine_origin) / self.fine_side).astype(np.int64)
        ask = (~out & (reach <= self.cell)
               & np.all((f >= 0) & (f < self.fine_dims), axis=1))
        if not ask.any():
            return out
        rows = np.flatnonzero(ask)
        # The rows' orientations that some triangle has (index into keys, else -1).
        o_of = self.key_index.find(_orientation_keys(np.asarray(n)[rows]))
        found = o_of >= 0
        if not found.any():
            return out
        # One sole-orientation grid answers every orientation at once (until s29 the 16
        # commonest a call: one grid each had been built per orientation).
        here, o = rows[found], o_of[found]
        fi = f[here]
        s = self._sole()[fi[:, 0], fi[:, 1], fi[:, 2]]
        out[here] = (s == -1) | (s == o)
        return out


_CELLS_LOCK = threading.Lock()


def one_surface_cells(geo, cell: float) -> OneSurfaceCells:
    """The render's OneSurfaceCells of side `cell`, built once and kept on geo (the
    render's threads share it)."""
    with _CELLS_LOCK:
        cache = geo.__dict__.setdefault("_one_surface_cells", {})
        got = cache.get(float(cell))
        if got is None:
            got = cache[float(cell)] = OneSurfaceCells(geo, cell)
    return got
