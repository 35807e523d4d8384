"""Morton (Z-order) codes of points, and a bounding-box tree over points sorted by them,
for exact k-th nearest distances at a few queries (the automatic search radius).

morton_order orders query rows so that neighbouring rows search the same part of a tree
(engine/photonmap.py). KthTree answers "how far is the k-th nearest point?" exactly, as
engine/kdtree.py's knn does, but is built in O(N) (a radix sort of 30-bit Morton codes
and one pass of boxes) instead of the kd-tree's O(N log N) median splits: the automatic
radius asks ~4,096 queries of a tree over the whole photon shot that nothing else uses
(measured: its kd-tree build was 0.31 s of a 1.5 s map build at 805k photons,
docs/performance.md). Queries cost about what a kd-tree's do, so it pays only where a
tree serves few queries.

Layout: the points in Morton order, in leaves of LEAF_SIZE consecutive points, and over
the leaves an implicit complete binary tree (node i's children 2i+1 and 2i+2; padding
leaves empty) holding each node's box, float32 (the points' own precision, so exact).
"""
from __future__ import annotations

import numpy as np

from .jit import kernel, register_warm_up
from .kdtree import heap_insert, seed_bound, select_value

LEAF_SIZE = 8
STACK = 64  # DFS stack: at most one pushed sibling per level (2^63 leaves)
STOP_QUERIES = 64  # queries between two looks at the stop flag
POLL = 1 << 14  # points of a build pass between two looks at the stop flag
_NEVER = np.zeros(1, np.uint8)  # a stop flag that never turns 1
SEED_WINDOW = 2  # points read around a query's Morton place for its seed, per kq
# A query's seeded sphere is listed whole (no heap) when it holds at most this many
# times kq points (kth_d2).
LIST_FACTOR = 8


@kernel
def _spread10(x):
    """The low 10 bits of x spread to every third bit (a Morton code's one axis)."""
    x &= 0x3FF
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    x = (x | (x << 2)) & 0x09249249
    return x


@kernel
def morton_codes(p, stop):
    """(code (M,) int64, lo (3,) float64, scale): the 30-bit Morton code of each point of
    p (M,3) over their box (lo, cubic cells of 1 / scale; NaN rows get cell 0). stop:
    (1,) uint8 polled every POLL rows; once nonzero the codes are meaningless."""
    m = p.shape[0]
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(m):
        if i % POLL == 0 and stop[0]:
            break
        for c in range(3):
            v = p[i, c]
            if v < lo[c]:
                lo[c] = v
            if v > hi[c]:
                hi[c] = v
    span = 0.0
    for c in range(3):
        span = max(span, hi[c] - lo[c])
    scale = 1023.0 / span if span > 0.0 and np.isfinite(span) else 0.0
    code = np.zeros(m, np.int64)
    for i in range(m):
        if i % POLL == 0 and stop[0]:
            break
        code[i] = _code(p[i, 0], p[i, 1], p[i, 2], lo, scale)
    return code, lo, scale


@kernel
def _code(x, y, z, lo, scale):
    """The Morton code of one point (morton_codes' cells; outside the box: clamped)."""
    key = 0
    for c in range(3):
        v = ((x if c == 0 else y if c == 1 else z) - lo[c]) * scale
        cell = int(v) if v > 0.0 and v < 1024.0 else (1023 if v >= 1024.0 else 0)
        key |= _spread10(cell) << c
    return key


@kernel
def morton_order(p):
    """Row order of the points p (M,3) along a Morton (Z-order) curve over their box, 10
    bits per axis. Queries taken in this order find the tree's nodes still in cache from
    the previous one: 25 % faster gather lookups, 2x for a whole image's worth
    (bench/bench_kernels.py). Every row's answer is the same in any order."""
    return _radix_argsort30(morton_codes(p, _NEVER)[0], _NEVER)


@kernel
def _radix_argsort30(code, stop):
    """Stable argsort of 30-bit keys (_radix_sort30's order): the same order as
    np.argsort(code, kind="stable") in O(M)."""
    return _radix_sort30(code, stop)[0]


@kernel
def _radix_sort30(code, stop):
    """(order, keys): the stable argsort of 30-bit keys and the keys in that order, by
    three counting-sort passes of 10 bits (LSD radix sort): the same order as
    np.argsort(code, kind="stable") in O(M) instead of a merge sort's O(M log M) (the
    sort was most of morton_order's cost: 1.2 Embree traversals per gather lookup,
    bench/bench_lookup.py). The three histograms are counted in one pass, and each pass
    moves the keys with the indices, so it reads both in order (reading code[order[i]]
    at random cost 3x: docs/performance.md, "Thirteenth slice"). stop: polled every
    POLL keys (a stopped sort's order is meaningless)."""
    m = code.shape[0]
    order = np.arange(m)
    if m < 2:
        return order, code.copy()
    count = np.zeros((3, 1025), np.int64)
    for i in range(m):
        if i % POLL == 0 and stop[0]:
            break
        c = code[i]
        count[0, (c & 0x3FF) + 1] += 1
        count[1, ((c >> 10) & 0x3FF) + 1] += 1
        count[2, ((c >> 20) & 0x3FF) + 1] += 1
    for p in range(3):
        for b in range(1024):
            count[p, b + 1] += count[p, b]
    key = code.copy()
    tmp = np.empty(m, np.int64)
    tmp_key = np.empty(m, np.int64)
    for p in range(3):
        if stop[0]:
            break
        shift = 10 * p
        for i in range(m):
            if i % POLL == 0 and stop[0]:
                break
            c = key[i]
            b = (c >> shift) & 0x3FF
            d = count[p, b]
            tmp[d] = order[i]
            tmp_key[d] = c
            count[p, b] = d + 1
        order, tmp = tmp, order
        key, tmp_key = tmp_key, key
    return order, key


@kernel
def build(points, stop):
    """The tree over points (N,3) float32: (position (N,3) float32, the points in Morton
    order; box (2L-1, 6) float32, node i's box lo x, y, z, hi x, y, z (empty: +inf /
    -inf), L the least power of two with N <= LEAF_SIZE x L; code (N,) their Morton
    codes, increasing; lo, scale: morton_codes' grid). NaN coordinates stay out of
    the boxes (a NaN point is never near anything). stop: (1,) uint8 polled every POLL
    points of each O(N) pass; once nonzero the arrays are meaningless."""
    n = points.shape[0]
    code, lo, scale = morton_codes(points, stop)
    order, sorted_code = _radix_sort30(code, stop)
    if stop[0]:
        return points[:0].copy(), np.empty((0, 6), np.float32), code[:0], lo, scale
    position = np.empty((n, 3), np.float32)
    for i in range(n):
        if i % POLL == 0 and stop[0]:
            break
        j = order[i]
        for c in range(3):
            position[i, c] = points[j, c]
    leaves = 1
    while leaves * LEAF_SIZE < n:
        leaves *= 2
    inner = leaves - 1
    box = np.empty((inner + leaves, 6), np.float32)
    for node in range(inner + leaves):
        for c in range(3):
            box[node, c] = np.inf
            box[node, 3 + c] = -np.inf
    for i in range(n):
        if i % POLL == 0 and stop[0]:
            break
        node = inner + i // LEAF_SIZE
        for c in range(3):
            v = position[i, c]
            if v < box[node, c]:
                box[node, c] = v
            if v > box[node, 3 + c]:
                box[node, 3 + c] = v
    for node in range(inner - 1, -1, -1):
        a = 2 * node + 1
        b = a + 1
        for c in range(3):
            box[node, c] = min(box[a, c], box[b, c])
            box[node, 3 + c] = max(box[a, 3 + c], box[b, 3 + c])
    return position, box, sorted_code, lo, scale


@kernel
def _gap2(lo, hi, q):
    """Squared distance from q to the interval [lo, hi] of one axis (0 inside)."""
    a = np.float64(lo) - q
    if a > 0.0:
        return a * a
    b = q - np.float64(hi)
    return b * b if b > 0.0 else 0.0


@kernel
def _box_d2(box, node, qx, qy, qz):
    """Squared distance from the query to node's box (0 inside; inf for an empty box).
    Rounding is monotonic, so it never exceeds the float64 squared distance knn computes
    to any point in the box: pruning by it loses no point."""
    if box[node, 0] > box[node, 3]:  # empty (padding) leaf or subtree
        return np.inf
    return (_gap2(box[node, 0], box[node, 3], qx) + _gap2(box[node, 1], box[node, 4], qy)
            + _gap2(box[node, 2], box[node, 5], qz))


@kernel
def kth_d2(position, box, code, lo, scale, queries, kq, out, stop):
    """For each query (M,3) float64: the kq-th smallest squared distance (float64, the
    float64 arithmetic of engine/kdtree.py's knn, so the same value bit for bit) to the
    points into out[i]; inf when fewer than kq points are finite. stop: (1,) uint8
    polled every STOP_QUERIES queries; once nonzero the kernel returns (rows left
    unwritten).

    Each query first reads the SEED_WINDOW x kq points around its own place in Morton
    order: their kq-th distance bounds the answer from above (seed_bound's margin), so
    the traversal below prunes from its first box instead of after kq points. Only the
    kq-th value is asked for (never which point), so a sphere of that bound holding at
    most LIST_FACTOR x kq points is listed (_list_d2) and its kq-th value selected
    (kdtree.select_value) without a heap; a fuller one takes the bounded heap search."""
    n = position.shape[0]
    leaves = (box.shape[0] + 1) // 2
    inner = leaves - 1
    d2 = np.empty(max(kq, 1), np.float64)
    idx = np.empty(max(kq, 1), np.int64)
    half = SEED_WINDOW * kq // 2
    cap = max(LIST_FACTOR * kq, 2 * half, 1)
    listed = np.empty(cap, np.float64)
    st_node = np.empty(STACK, np.int64)
    st_d2 = np.empty(STACK, np.float64)
    for i in range(queries.shape[0]):
        if i % STOP_QUERIES == 0 and stop[0]:
            return
        qx, qy, qz = queries[i, 0], queries[i, 1], queries[i, 2]
        # The seed: the kq-th distance among the points nearest in Morton order.
        at = np.searchsorted(code, _code(qx, qy, qz, lo, scale))
        a = min(max(at - half, 0), max(n - 2 * half, 0))
        count = 0
        for j in range(a, min(a + 2 * half, n)):
            dist2 = _d2(position, j, qx, qy, qz)
            if dist2 < np.inf:  # not NaN: it would spoil the selection
                listed[count] = dist2
                count += 1
        bound = np.inf
        if count >= kq:
            seed = select_value(listed, count, kq)
            if seed < np.inf:
                bound = seed_bound(seed)
        if bound < np.inf:
            # Only the kq-th value is asked for: the sphere of the seed's bound listed
            # whole and its kq-th picked, without a heap, unless it holds more than
            # `cap` points (then the heap search below, bounded the same way).
            got = _list_d2(position, box, inner, n, qx, qy, qz, bound, listed, cap,
                           st_node, st_d2)
            if kq <= got <= cap:
                out[i] = select_value(listed, got, kq)
                continue
        count = 0
        sp = _root(box, qx, qy, qz, st_node, st_d2)
        while True:
            node, sp = _next_leaf(box, inner, qx, qy, qz, bound, st_node, st_d2, sp)
            if node < 0:
                break
            first = (node - inner) * LEAF_SIZE
            for j in range(first, min(first + LEAF_SIZE, n)):
                dist2 = _d2(position, j, qx, qy, qz)
                if dist2 < bound:
                    count = heap_insert(d2, idx, count, kq, dist2, j)
                    if count == kq:
                        bound = d2[0]
        out[i] = d2[0] if count == kq else np.inf


@kernel
def _list_d2(position, box, inner, n, qx, qy, qz, bound, listed, cap, st_node, st_d2):
    """The squared distances < bound of the points to the query into listed[:count]
    (any order); returns count, or cap + 1 as soon as more than cap are found."""
    count = 0
    sp = _root(box, qx, qy, qz, st_node, st_d2)
    while True:
        node, sp = _next_leaf(box, inner, qx, qy, qz, bound, st_node, st_d2, sp)
        if node < 0:
            break
        first = (node - inner) * LEAF_SIZE
        for j in range(first, min(first + LEAF_SIZE, n)):
            dist2 = _d2(position, j, qx, qy, qz)
            if dist2 < bound:
                if count == cap:
                    return cap + 1
                listed[count] = dist2
                count += 1
    return count


@kernel
def _root(box, qx, qy, qz, st_node, st_d2):
    """Start a traversal of the box tree: the root on the stack (st_node, st_d2: node and
    its box's squared distance); returns the stack's size."""
    st_node[0] = 0
    st_d2[0] = _box_d2(box, 0, qx, qy, qz)
    return 1


@kernel
def _next_leaf(box, inner, qx, qy, qz, bound, st_node, st_d2, sp):
    """The traversal both searches share (kth_d2's heap search, _list_d2): pop the stack
    (sp entries) and descend, nearer child first, to the next leaf whose box is nearer
    than bound, pushing the farther child where it is nearer than bound too. Returns
    (leaf node, sp), or (-1, 0) when no leaf is left. bound may shrink between calls
    (the heap's): each entry is tested against it again when popped."""
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        if st_d2[sp] >= bound:
            continue
        while node < inner:
            a = 2 * node + 1
            da = _box_d2(box, a, qx, qy, qz)
            db = _box_d2(box, a + 1, qx, qy, qz)
            if db < da:
                near, far, dfar = a + 1, a, da
            else:
                near, far, dfar = a, a + 1, db
            if dfar < bound:
                st_node[sp] = far
                st_d2[sp] = dfar
                sp += 1
            if min(da, db) >= bound:
                node = -1
                break
            node = near
        if node >= 0:
            return node, sp
    return -1, 0


@kernel
def _d2(position, j, qx, qy, qz):
    """kdtree's float64 squared distance of point j to the query."""
    dx = qx - np.float64(position[j, 0])
    dy = qy - np.float64(position[j, 1])
    dz = qz - np.float64(position[j, 2])
    return dx * dx + dy * dy + dz * dz


class KthTree:
    """The Morton box tree over points (N,3); kth(queries, k) is the distance to each
    query's k-th nearest point (exactly kdtree.KdTree.query's dist[:, k - 1])."""

    def __init__(self, points: np.ndarray, stop: np.ndarray | None = None):
        """stop: a (1,) uint8 flag the build polls (parallel.stop_array); once it is set
        the tree is meaningless (the caller checks)."""
        pts = np.ascontiguousarray(points, dtype=np.float32)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"KthTree: points must have shape (N, 3), got {pts.shape}")
        (self.position, self.box, self.code, self.lo,
         self.scale) = build(pts, np.zeros(1, np.uint8) if stop is None else stop)

    def __len__(self):
        return len(self.position)

    def kth(self, queries: np.ndarray, k: int, stop: np.ndarray | None = None) -> np.ndarray:
        """(M,) float64 distances (not squared) from queries (M,3) to their k-th nearest
        point (inf where fewer than k). stop: a (1,) uint8 flag the kernel polls (a
        parallel.stop_array); once it is set the answer is meaningless (the caller
        checks)."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(q), np.inf)
        if len(self.position) and k > 0:
            kth_d2(self.position, self.box, self.code, self.lo, self.scale, q, int(k), out,
                   np.zeros(1, np.uint8) if stop is None else stop)
        return np.sqrt(out)


@register_warm_up
def _warm_up():
    pts = np.random.default_rng(0).random((40, 3)).astype(np.float32)
    tree = KthTree(pts)
    tree.kth(pts[:3].astype(np.float64), 4)
    morton_order(pts[:3].astype(np.float64))
