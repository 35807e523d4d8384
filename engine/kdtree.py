"""Jensen's left-balanced kd-tree: the photon map's search structure, in one array.

Layout (Jensen, "Realistic Image Synthesis Using Photon Mapping", 2001, sect. 6.3): node i
is point i; its children are nodes 2i+1 and 2i+2 (a complete binary tree stored like a
heap, so there are no pointers); `axis[i]` is its splitting axis. Building permutes the
points so that every node is the median of its subtree along the axis of the subtree's
largest extent, with the left subtree as full as a complete tree needs. The caller
reorders its per-point data by `order` once, so a node index is also the data index.

Memory: the points (float32, 12 B) plus one byte of axis per point.

Queries run inside compiled kernels (engine/jit.py) with fixed scratch memory:
  knn         the k nearest points with squared distance < r2 (Jensen's max-heap search),
              returned in increasing distance
  nearest     the one nearest point with squared distance < r2 (knn with k = 1, no heap)
  ball        the points with squared distance <= r2, up to a caller's capacity
  ball_count  how many points have squared distance <= r2 (whole subtrees inside the
              sphere are counted by their size: the points' box is kept for that)
Distances are computed in float64 from the float32 positions (as scipy's cKDTree does on
a float64 copy), so neighbour sets match it except for exact ties.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel, register_warm_up

STACK = 64  # traversal stack: one entry per tree level (a tree of 2^63 points at most)


@kernel
def _left_size(m):
    """Nodes in the left subtree of a left-balanced (complete) tree of m nodes."""
    depth = 0
    while (2 << depth) <= m:  # 2^(depth+1) <= m: level depth+1 exists
        depth += 1
    if depth == 0:
        return 0
    half = 1 << (depth - 1)
    last = m - ((1 << depth) - 1)  # nodes on the last, partly filled level
    return half - 1 + min(last, half)


@kernel
def _select(pts, perm, lo, hi, kth, ax):
    """Reorder pts[lo:hi] (and perm with it) so that pts[kth] holds the point of that rank
    along ax, the ones before it no greater, the ones after no smaller. The points move
    with their indices, so every pass reads memory in order. A three-way partition keeps
    many equal coordinates (a focused caustic) linear instead of quadratic."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        a, b, c = pts[lo, ax], pts[mid, ax], pts[hi - 1, ax]
        pivot = max(min(a, b), min(max(a, b), c))  # median of three
        lt = lo
        i = lo
        gt = hi
        while i < gt:
            v = pts[i, ax]
            if v < pivot:
                _swap(pts, perm, i, lt)
                lt += 1
                i += 1
            elif v > pivot:
                gt -= 1
                _swap(pts, perm, i, gt)
            else:
                i += 1
        if kth < lt:
            hi = lt
        elif kth >= gt:
            lo = gt
        else:
            return


@kernel
def _swap(pts, perm, i, j):
    for c in range(3):
        t = pts[i, c]
        pts[i, c] = pts[j, c]
        pts[j, c] = t
    u = perm[i]
    perm[i] = perm[j]
    perm[j] = u


@kernel
def build(points):
    """Left-balanced kd-tree over points (N,3) float32. Returns (order (N,) int64: node
    i is points[order[i]], axis (N,) uint8). Each node splits its cell (the points' box
    cut by the splits above it, as Jensen builds it) along the cell's longest side.
    O(N log N), no recursion."""
    n = points.shape[0]
    perm = np.arange(n)
    pts = points.copy()
    order = np.empty(n, np.int64)
    axis = np.zeros(n, np.uint8)
    st = np.empty((2 * STACK, 3), np.int64)  # lo, hi, node
    st_box = np.empty((2 * STACK, 6), np.float64)
    sp = 0
    if n > 0:
        st[0, 0], st[0, 1], st[0, 2] = 0, n, 0
        for c in range(3):
            st_box[0, c] = np.inf
            st_box[0, 3 + c] = -np.inf
        for i in range(n):
            for c in range(3):
                st_box[0, c] = min(st_box[0, c], pts[i, c])
                st_box[0, 3 + c] = max(st_box[0, 3 + c], pts[i, c])
        sp = 1
    while sp > 0:
        sp -= 1
        lo, hi, node = st[sp, 0], st[sp, 1], st[sp, 2]
        m = hi - lo
        if m == 1:
            order[node] = perm[lo]
            continue
        box = st_box[sp].copy()
        ax = 0
        for c in (1, 2):
            if box[3 + c] - box[c] > box[3 + ax] - box[ax]:
                ax = c
        med = lo + _left_size(m)
        _select(pts, perm, lo, hi, med, ax)
        split = np.float64(pts[med, ax])
        order[node] = perm[med]
        axis[node] = ax
        # Left pushed last: popped first (depth first keeps the stack short).
        if hi > med + 1:
            st[sp, 0], st[sp, 1], st[sp, 2] = med + 1, hi, 2 * node + 2
            st_box[sp] = box
            st_box[sp, ax] = split
            sp += 1
        if med > lo:
            st[sp, 0], st[sp, 1], st[sp, 2] = lo, med, 2 * node + 1
            st_box[sp] = box
            st_box[sp, 3 + ax] = split
            sp += 1
    return order, axis


@kernel
def _sift_down(d2, idx, i, count):
    """Max-heap: move entry i down until both children are no larger."""
    while True:
        c = 2 * i + 1
        if c >= count:
            return
        if c + 1 < count and d2[c + 1] > d2[c]:
            c += 1
        if d2[c] <= d2[i]:
            return
        t = d2[c]
        d2[c] = d2[i]
        d2[i] = t
        u = idx[c]
        idx[c] = idx[i]
        idx[i] = u
        i = c


@kernel
def heap_insert(d2, idx, count, kq, dist2, j):
    """Offer point j at squared distance dist2 to the kq nearest so far (count entries).
    Until kq are held they are only appended; the kq-th turns them into a max-heap
    (Jensen's order: no sifting while filling). Returns the new count."""
    if count < kq:
        d2[count] = dist2
        idx[count] = j
        count += 1
        if count == kq:
            for i in range(kq // 2 - 1, -1, -1):
                _sift_down(d2, idx, i, kq)
        return count
    if dist2 < d2[0]:
        d2[0] = dist2
        idx[0] = j
        _sift_down(d2, idx, 0, count)
    return count


@kernel
def heap_sort(d2, idx, count, kq):
    """Turn the kq nearest (a max-heap once count == kq, else unordered) into increasing
    distance order, in place."""
    if count < kq:
        for i in range(count // 2 - 1, -1, -1):
            _sift_down(d2, idx, i, count)
    end = count - 1
    while end > 0:
        t = d2[0]
        d2[0] = d2[end]
        d2[end] = t
        u = idx[0]
        idx[0] = idx[end]
        idx[end] = u
        _sift_down(d2, idx, 0, end)
        end -= 1


@kernel
def knn(pos, axis, qx, qy, qz, kq, r2, d2, idx):
    """The kq nearest points with squared distance < r2 into d2[:count], idx[:count]
    (increasing distance; d2, idx: scratch of at least kq). Returns count.
    A far subtree is skipped by its cell's distance (the query's offsets to the cell
    along each axis, kept incrementally: Arya & Mount 1993), which prunes more than the
    plane distance alone."""
    n = pos.shape[0]
    count = 0
    if n == 0 or kq <= 0:
        return 0
    bound = r2
    st_node = np.empty(STACK, np.int64)
    st_off = np.empty((STACK, 4), np.float64)  # x, y, z offsets to the cell; squared sum
    st_node[0] = 0
    st_off[0, 0] = st_off[0, 1] = st_off[0, 2] = st_off[0, 3] = 0.0
    sp = 1
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        if rd >= bound:
            continue
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        while node < n:
            dx = qx - np.float64(pos[node, 0])
            dy = qy - np.float64(pos[node, 1])
            dz = qz - np.float64(pos[node, 2])
            dist2 = dx * dx + dy * dy + dz * dz
            if dist2 < bound:
                count = heap_insert(d2, idx, count, kq, dist2, node)
                if count == kq:
                    bound = d2[0]
            ax = axis[node]
            if ax == 0:
                diff, old = dx, ox
            elif ax == 1:
                diff, old = dy, oy
            else:
                diff, old = dz, oz
            if diff < 0.0:
                near, far = 2 * node + 1, 2 * node + 2
            else:
                near, far = 2 * node + 2, 2 * node + 1
            if far < n:
                rd_far = rd - old * old + diff * diff
                if rd_far < bound:
                    st_node[sp] = far
                    st_off[sp, 0], st_off[sp, 1], st_off[sp, 2] = ox, oy, oz
                    st_off[sp, ax] = diff
                    st_off[sp, 3] = rd_far
                    sp += 1
            node = near
    heap_sort(d2, idx, count, kq)
    return count


@kernel
def nearest(pos, axis, qx, qy, qz, r2):
    """The nearest point with squared distance < r2: (index, squared distance), or
    (-1, r2) when there is none. The same point as knn(kq=1) (the first met of equally
    near ones), without the heap: the gather map's common lookup."""
    n = pos.shape[0]
    best = -1
    bound = r2
    if n == 0:
        return best, bound
    st_node = np.empty(STACK, np.int64)
    st_off = np.empty((STACK, 4), np.float64)
    st_node[0] = 0
    st_off[0, 0] = st_off[0, 1] = st_off[0, 2] = st_off[0, 3] = 0.0
    sp = 1
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        if rd >= bound:
            continue
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        while node < n:
            dx = qx - np.float64(pos[node, 0])
            dy = qy - np.float64(pos[node, 1])
            dz = qz - np.float64(pos[node, 2])
            dist2 = dx * dx + dy * dy + dz * dz
            if dist2 < bound:
                best = node
                bound = dist2
            ax = axis[node]
            if ax == 0:
                diff, old = dx, ox
            elif ax == 1:
                diff, old = dy, oy
            else:
                diff, old = dz, oz
            if diff < 0.0:
                near, far = 2 * node + 1, 2 * node + 2
            else:
                near, far = 2 * node + 2, 2 * node + 1
            if far < n:
                rd_far = rd - old * old + diff * diff
                if rd_far < bound:
                    st_node[sp] = far
                    st_off[sp, 0], st_off[sp, 1], st_off[sp, 2] = ox, oy, oz
                    st_off[sp, ax] = diff
                    st_off[sp, 3] = rd_far
                    sp += 1
            node = near
    return best, bound


@kernel
def ball(pos, axis, qx, qy, qz, r2, out, cap):
    """Indices of the points with squared distance <= r2 into out[:min(count, cap)], in
    tree order. Stops scanning once more than cap are found and returns cap + 1; else
    returns the count."""
    n = pos.shape[0]
    count = 0
    if n == 0:
        return 0
    st_node = np.empty(STACK, np.int64)
    st_node[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        while node < n:
            dx = qx - np.float64(pos[node, 0])
            dy = qy - np.float64(pos[node, 1])
            dz = qz - np.float64(pos[node, 2])
            if dx * dx + dy * dy + dz * dz <= r2:
                if count == cap:
                    return cap + 1
                out[count] = node
                count += 1
            ax = axis[node]
            diff = dx if ax == 0 else (dy if ax == 1 else dz)
            if diff < 0.0:
                near, far = 2 * node + 1, 2 * node + 2
            else:
                near, far = 2 * node + 2, 2 * node + 1
            if far < n and diff * diff <= r2:
                st_node[sp] = far
                sp += 1
            node = near
    return count


@kernel
def subtree_size(node, n):
    """Nodes in the subtree rooted at node (heap layout, n nodes in all)."""
    size = 0
    first = node
    last = node
    while first < n:
        size += min(last, n - 1) - first + 1
        first = 2 * first + 1
        last = 2 * last + 2
    return size


@kernel
def ball_count(pos, axis, bounds, qx, qy, qz, r2):
    """Number of points with squared distance <= r2. bounds: the points' box (lo x, y, z,
    hi x, y, z). A subtree whose cell lies inside the sphere is counted whole (its size
    follows from the layout), so a focus of a million equal points costs a few nodes."""
    n = pos.shape[0]
    count = 0
    if n == 0:
        return 0
    st_node = np.empty(STACK, np.int64)
    st_box = np.empty((STACK, 6), np.float64)
    st_node[0] = 0
    for c in range(6):
        st_box[0, c] = bounds[c]
    sp = 1
    lo = np.empty(3, np.float64)
    hi = np.empty(3, np.float64)
    q = np.empty(3, np.float64)
    q[0], q[1], q[2] = qx, qy, qz
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        for c in range(3):
            lo[c] = st_box[sp, c]
            hi[c] = st_box[sp, 3 + c]
        while node < n:
            near2 = 0.0  # squared distance to the cell, and to its farthest corner
            far2 = 0.0
            for c in range(3):
                a = q[c] - lo[c]
                b = hi[c] - q[c]
                if a < 0.0:
                    near2 += a * a
                elif b < 0.0:
                    near2 += b * b
                m = max(abs(a), abs(b))
                far2 += m * m
            if near2 > r2:
                break
            if far2 <= r2:
                count += subtree_size(node, n)
                break
            dx = qx - np.float64(pos[node, 0])
            dy = qy - np.float64(pos[node, 1])
            dz = qz - np.float64(pos[node, 2])
            if dx * dx + dy * dy + dz * dz <= r2:
                count += 1
            ax = axis[node]
            split = np.float64(pos[node, ax])
            if q[ax] < split:
                near, far = 2 * node + 1, 2 * node + 2
            else:
                near, far = 2 * node + 2, 2 * node + 1
            if far < n:
                st_node[sp] = far
                for c in range(3):
                    st_box[sp, c] = lo[c]
                    st_box[sp, 3 + c] = hi[c]
                if far == 2 * node + 1:
                    st_box[sp, 3 + ax] = split  # left: coordinates <= split
                else:
                    st_box[sp, ax] = split
                sp += 1
            if near == 2 * node + 1:
                hi[ax] = split
            else:
                lo[ax] = split
            node = near
    return count


@kernel
def knn_batch(pos, axis, queries, kq, radius):
    """k-NN of many queries (M,3) float64 within radius, in scipy's cKDTree.query form:
    (dist (M,kq) float64 with inf where none, idx (M,kq) int64 with N where none)."""
    m = queries.shape[0]
    n = pos.shape[0]
    dist = np.full((m, kq), np.inf)
    out = np.full((m, kq), n, np.int64)
    d2 = np.empty(max(kq, 1), np.float64)
    idx = np.empty(max(kq, 1), np.int64)
    r2 = radius * radius
    for i in range(m):
        c = knn(pos, axis, queries[i, 0], queries[i, 1], queries[i, 2], kq, r2, d2, idx)
        for j in range(c):
            dist[i, j] = np.sqrt(d2[j])
            out[i, j] = idx[j]
    return dist, out


class KdTree:
    """A left-balanced kd-tree over points (N,3); self.order maps node -> input index."""

    def __init__(self, points: np.ndarray):
        pts = np.ascontiguousarray(points, dtype=np.float32)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"KdTree: points must have shape (N, 3), got {pts.shape}")
        self.order, self.axis = build(pts)
        self.position = np.ascontiguousarray(pts[self.order])
        self.bounds = np.zeros(6)  # the points' box: lo x, y, z, hi x, y, z
        if len(pts):
            self.bounds[:3] = pts.min(axis=0)
            self.bounds[3:] = pts.max(axis=0)

    def __len__(self):
        return len(self.position)

    @property
    def nbytes(self) -> int:
        """Bytes of the tree itself (positions + axes; order is dropped by callers)."""
        return self.position.nbytes + self.axis.nbytes + self.bounds.nbytes

    def query(self, queries: np.ndarray, k: int, radius: float):
        """(dist, idx) of the k nearest nodes within radius, like cKDTree.query with
        distance_upper_bound (idx = len(self) where none). idx are node indices."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        return knn_batch(self.position, self.axis, q, int(k), float(radius))


@register_warm_up
def _warm_up():
    pts = np.random.default_rng(0).random((40, 3)).astype(np.float32)
    KdTree(pts).query(pts[:3].astype(np.float64), 4, 0.5)
    tree = KdTree(pts)
    out = np.empty(8, np.int64)
    ball(tree.position, tree.axis, 0.5, 0.5, 0.5, 0.1, out, 8)
    ball_count(tree.position, tree.axis, tree.bounds, 0.5, 0.5, 0.5, 0.1)
    nearest(tree.position, tree.axis, 0.5, 0.5, 0.5, 0.1)
