"""A BVH over boxes and its compiled traversal: the top level of two-level tracing of
instances (engine/instancing.py).

The traversal lists, for each ray, every box it enters before its tmax, nearest entry
first (the caller traces them in that order and skips the boxes behind the nearest hit
found so far); a ray that enters no box costs one test of the root.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .jit import kernel, register_warm_up

LEAF_SIZE = 2      # boxes per leaf
STACK_DEPTH = 96   # median splits: depth <= log2(boxes) + 1


@dataclass
class TopLevel:
    """A BVH over boxes (I,3) lo / hi: nodes (N,) with boxes, `child` (first of two
    consecutive children, internal nodes) or `first` / `count` into `order` (leaves)."""

    node_lo: np.ndarray
    node_hi: np.ndarray
    child: np.ndarray
    first: np.ndarray
    count: np.ndarray
    order: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def build_top_level(lo: np.ndarray, hi: np.ndarray) -> TopLevel:
    """Median-split BVH over the boxes lo, hi (I,3) float64 (largest centroid extent
    first; leaves of up to LEAF_SIZE boxes). O(I log I) numpy work, ~2I/LEAF_SIZE nodes."""
    lo = np.ascontiguousarray(lo, np.float64)
    hi = np.ascontiguousarray(hi, np.float64)
    n = len(lo)
    cap = max(1, 2 * n)
    node_lo = np.zeros((cap, 3))
    node_hi = np.zeros((cap, 3))
    child = np.full(cap, -1, np.int64)
    first = np.zeros(cap, np.int64)
    count = np.zeros(cap, np.int64)
    order = np.arange(n, dtype=np.int64)
    centre = (lo + hi) / 2.0
    used = 1
    stack = [(0, 0, n)] if n else []
    while stack:
        node, a, b = stack.pop()
        items = order[a:b]
        node_lo[node] = lo[items].min(axis=0)
        node_hi[node] = hi[items].max(axis=0)
        if b - a <= LEAF_SIZE:
            first[node], count[node] = a, b - a
            continue
        c = centre[items]
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        mid = (b - a) // 2
        part = np.argpartition(c[:, axis], mid)
        order[a:b] = items[part]
        child[node] = used
        stack.append((used, a, a + mid))
        stack.append((used + 1, a + mid, b))
        used += 2
    return TopLevel(node_lo[:max(used, 1)].copy(), node_hi[:max(used, 1)].copy(),
                    child[:max(used, 1)].copy(), first[:max(used, 1)].copy(),
                    count[:max(used, 1)].copy(), order, lo, hi)


@kernel
def _slab(ox, oy, oz, ix, iy, iz, lo, hi, b, tmax):
    """Entry parameter of the ray (origin o, inverse direction i) into box b of lo, hi
    (N,3) within [0, tmax], or -1. Scalars: this runs ~10-20 times per ray."""
    t1 = (lo[b, 0] - ox) * ix
    t2 = (hi[b, 0] - ox) * ix
    tn = min(t1, t2)
    tf = max(t1, t2)
    t1 = (lo[b, 1] - oy) * iy
    t2 = (hi[b, 1] - oy) * iy
    tn = max(tn, min(t1, t2))
    tf = min(tf, max(t1, t2))
    t1 = (lo[b, 2] - oz) * iz
    t2 = (hi[b, 2] - oz) * iz
    tn = max(tn, min(t1, t2), 0.0)
    tf = min(tf, max(t1, t2), tmax)
    if tn <= tf:  # NaN rays fail every comparison: no box
        return tn
    return -1.0


@kernel
def top_level_candidates(o, d, tmax, node_lo, node_hi, child, first, count, order, lo, hi):
    """For each ray (o, d (R,3) float64, tmax (R,)): the boxes it enters before tmax,
    nearest entry first. Returns offsets (R+1,) int64 and, for rows offsets[r] ..
    offsets[r+1], the instance (M,) int64 and entry parameter (M,) float64. The tree is
    walked with a stack (STACK_DEPTH nodes); a ray with no box costs one node test."""
    R = o.shape[0]
    cap = max(64, 2 * R)
    inst = np.empty(cap, np.int64)
    tent = np.empty(cap, np.float64)
    offsets = np.zeros(R + 1, np.int64)
    stack = np.empty(STACK_DEPTH, np.int64)
    m = 0
    if node_lo.shape[0] == 0 or order.shape[0] == 0:
        return offsets, inst[:0], tent[:0]
    for r in range(R):
        ox, oy, oz = o[r, 0], o[r, 1], o[r, 2]
        ix = 1.0 / d[r, 0] if d[r, 0] != 0.0 else 1e300
        iy = 1.0 / d[r, 1] if d[r, 1] != 0.0 else 1e300
        iz = 1.0 / d[r, 2] if d[r, 2] != 0.0 else 1e300
        tm = tmax[r]
        start = m
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            if _slab(ox, oy, oz, ix, iy, iz, node_lo, node_hi, node, tm) < 0.0:
                continue
            if child[node] >= 0:
                stack[top] = child[node]
                stack[top + 1] = child[node] + 1
                top += 2
                continue
            for j in range(first[node], first[node] + count[node]):
                i = order[j]
                te = _slab(ox, oy, oz, ix, iy, iz, lo, hi, i, tm)
                if te < 0.0:
                    continue
                if m == inst.shape[0]:
                    inst = np.concatenate((inst, np.empty(m, np.int64)))
                    tent = np.concatenate((tent, np.empty(m, np.float64)))
                # Insertion into this ray's list, nearest entry first.
                q = m
                while q > start and tent[q - 1] > te:
                    inst[q] = inst[q - 1]
                    tent[q] = tent[q - 1]
                    q -= 1
                inst[q] = i
                tent[q] = te
                m += 1
        offsets[r + 1] = m
    return offsets, inst[:m], tent[:m]


@kernel
def to_object_rays(to_object, which, rows, o, d):
    """Rays rows (n,) of o, d (N,3) float64 taken by the affine maps to_object[which]
    (n,) of (I,3,4): float32 origins and directions (n,3) (directions not normalised,
    so the ray parameter t is unchanged)."""
    n = rows.shape[0]
    ol = np.empty((n, 3), np.float32)
    dl = np.empty((n, 3), np.float32)
    for j in range(n):
        A = to_object[which[j]]
        r = rows[j]
        for k in range(3):
            ol[j, k] = A[k, 0] * o[r, 0] + A[k, 1] * o[r, 1] + A[k, 2] * o[r, 2] + A[k, 3]
            dl[j, k] = A[k, 0] * d[r, 0] + A[k, 1] * d[r, 1] + A[k, 2] * d[r, 2]
    return ol, dl


@register_warm_up
def _warm_up():
    lo = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    top = build_top_level(lo, lo + 1.0)
    o = np.array([[-1.0, 0.5, 0.5]])
    d = np.array([[1.0, 0.0, 0.0]])
    top_level_candidates(o, d, np.array([np.inf]), top.node_lo, top.node_hi, top.child,
                         top.first, top.count, top.order, top.lo, top.hi)
    to_object_rays(np.zeros((1, 3, 4)), np.zeros(1, np.int64), np.zeros(1, np.int64), o, d)
