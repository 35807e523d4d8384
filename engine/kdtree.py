"""The photon map's kd-tree in flat arrays: Jensen's balanced, pointer-free layout with
leaf buckets.

Layout: a complete binary tree stored like a heap (node i's children are 2i+1 and 2i+2;
Jensen, "Realistic Image Synthesis Using Photon Mapping", 2001, sect. 6.3), all leaves on
one level. Inner node i splits its cell along `axis[i]` at `split[i]`; leaf l holds the
points [leaf[l], leaf[l+1]) of the tree's point order, at most LEAF_SIZE of them, stored
contiguously (the leaf buckets of scipy's cKDTree: a query computes distances only in
leaves, reading neighbouring points from one cache line, instead of at every node as in
Jensen's one-point-per-node tree). Building permutes the points so that every split is
the median of its range along the longest side of its cell (the points' box cut by the
splits above); the caller reorders its per-point data by `order` once, so a point's index
in the tree is also its data index. Any node's subtree is a contiguous range of points.

Memory: the points (float32, 12 B) plus, per LEAF_SIZE / 2 .. LEAF_SIZE points, one axis
byte, one float32 split and one int64 leaf start (under 2 B per point).

Queries run inside compiled kernels (engine/jit.py) with fixed scratch memory:
  knn         the k nearest points with squared distance < r2 (a bounded max-heap filled
              unsorted and heapified at the k-th point, as Jensen does), returned in
              increasing distance
  nearest     the one nearest point with squared distance < r2 (knn with k = 1, no heap)
              (nearest, nearest_facing and count_closer have `_in` forms that take a
              traversal_stack as scratch, for callers making many searches)
  nearest_facing  the nearest point whose normal agrees with the query's
  count_closer    how many points have squared distance < r2, up to a cap (a rank test)
  ball        the points with squared distance <= r2, up to a caller's capacity
  ball_count  how many points have squared distance <= r2 (whole subtrees inside the
              sphere are counted by their range: the points' box is kept for that)
  ball_d2     the points with squared distance < r2 and their distances, up to a cap;
              nearest_first then orders the m nearest of them (knn's answer, no heap);
              unique_nearest tells whether those m are free of ties
  nearest_walk  nearest's answers for a block of queries in Morton order, each from
              the previous answer's list of its k nearest (neighbour_lists, built
              once: 2 B x k + 4 B per point, 4 B x k + 4 B above NARROW_NEIGHBOURS
              points) without the tree when the lists prove it;
              else nearest, seeded
Far subtrees are skipped by the query's squared distance to their cell (Arya & Mount
1993, kept incrementally per axis). Distances are computed in float64 from the float32
positions (as scipy's cKDTree does on a float64 copy), so neighbour sets match it except
for exact ties.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel, register_warm_up
from .parallel import Cancelled, ordered_map, stop_array
from .photonlayout import read_vector
from .samesurface import continues_plane

STACK = 64  # traversal stack: one entry per tree level (a tree of 2^63 points at most)
LEAF_SIZE = 8  # points per leaf at most (measured: 8 and 16 within 5 %, 4 slower)
# Fewer points are built on one thread (a pool's start-up would cost more than it saves).
PARALLEL_POINTS = 1 << 16
# neighbour_lists: points listed per point (measured on Figures 6 and 7's gather lookups:
# 8 settles 75-80 % of them without the tree, 12 85-90 %, 16 the same speed as 12) and
# points per job of a threaded build.
NEIGHBOURS = 12
NEIGHBOUR_CHUNK = 8192
# neighbour_lists: a table of at most this many points lists them as uint16 (2 B an entry:
# a gather map's ~60 k points, 24 B a point instead of 48; docs/performance.md "hdri52"),
# a larger one as int32.
NARROW_NEIGHBOURS = 1 << 16
# kth_d2_rows and neighbour_lists list a seeded sphere of up to this many times the
# points they need before they fall back to the heap search (knn).
KTH_LIST_FACTOR = 8
# nearest_walk: a row whose previous answer g lies farther than this many times g's
# reach searches the tree at once (measured on Figures 6 and 7's lookups: 2.5 saves the
# most; at 1.5 0.7 % of rows that the lists would have settled go to the tree instead).
JUMP_REACH = 2.5


@kernel
def _select(pts, perm, lo, hi, kth, ax):
    """Reorder pts[lo:hi] (and perm with it) so that pts[kth] holds the point of that rank
    along ax, the ones before it no greater, the ones after no smaller. The points move
    with their indices, so every pass reads memory in order. A three-way partition keeps
    many equal coordinates (a focused caustic) linear instead of quadratic: Hoare's FIND
    with a median-of-three pivot. pts (N,3) points and perm (N,) their indices, or pts
    (N,) values (perm and ax unused: select_value): numba compiles each form alone."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        a, b, c = _coord(pts, lo, ax), _coord(pts, mid, ax), _coord(pts, hi - 1, ax)
        pivot = max(min(a, b), min(max(a, b), c))  # median of three
        lt = lo
        i = lo
        gt = hi
        while i < gt:
            v = _coord(pts, i, ax)
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
def _coord(pts, i, ax):
    """Point i's coordinate along ax, or value i (pts (N,): a compile-time branch)."""
    if pts.ndim == 2:
        return pts[i, ax]
    return pts[i]


@kernel
def _swap(pts, perm, i, j):
    if pts.ndim == 1:
        t = pts[i]
        pts[i] = pts[j]
        pts[j] = t
        return
    for c in range(3):
        t = pts[i, c]
        pts[i, c] = pts[j, c]
        pts[j, c] = t
    u = perm[i]
    perm[i] = perm[j]
    perm[j] = u


@kernel
def leaf_count(n):
    """Leaves of the tree over n points: the least power of two with n <= LEAF_SIZE x it."""
    leaves = 1
    while leaves * LEAF_SIZE < n:
        leaves *= 2
    return leaves


@kernel
def build(points, stop, levels):
    """kd-tree over points (N,3) float32. Returns (order (N,) int64: the tree's point i is
    points[order[i]], position (N,3) float32: the points in that order, axis (L-1,) uint8
    and split (L-1,) float32 of the inner nodes, leaf (L+1,) int64 leaf starts, bounds (6,)
    float64: the points' box, lo x, y, z, hi x, y, z, tasks (K,3) int64 and task_box
    (K,6)), L = leaf_count(N). Each split is the median of its range (ranges halve, so
    leaves differ by at most one point) along its cell's longest side. O(N log N), no
    recursion. levels > 0: the subtrees rooted `levels` levels below the root are left
    for build_subtree, one per row of tasks (point range lo, hi and node; task_box its
    cell), which may run on several threads at once (disjoint points and nodes: the tree
    is the same as a whole build's); levels = 0 builds everything (K = 0). stop: (1,)
    uint8 polled at every node; once it is nonzero the build ends early and its arrays
    are meaningless (the caller checks)."""
    n = points.shape[0]
    leaves = leaf_count(n)
    inner = leaves - 1
    perm = np.arange(n)
    pts = points.copy()
    axis = np.zeros(inner, np.uint8)
    split = np.zeros(inner, np.float32)
    leaf = np.zeros(leaves + 1, np.int64)
    leaf[leaves] = n
    bounds = np.empty(6)
    for c in range(3):
        bounds[c] = np.inf
        bounds[3 + c] = -np.inf
    for i in range(n):
        for c in range(3):
            bounds[c] = min(bounds[c], pts[i, c])
            bounds[3 + c] = max(bounds[3 + c], pts[i, c])
    first = (1 << levels) - 1  # the first node `levels` levels below the root
    if first >= inner:
        first = inner
    tasks = np.zeros((first + 1, 3), np.int64)
    task_box = np.zeros((first + 1, 6))
    k = _build_nodes(pts, perm, axis, split, leaf, inner, 0, n, 0, bounds, stop, first,
                     tasks, task_box)
    return perm, pts, axis, split, leaf, bounds, tasks[:k], task_box[:k]


@kernel
def build_subtree(pts, perm, axis, split, leaf, lo, hi, node, box, stop):
    """The subtree of one of build's tasks, in place (pts, perm: build's position and
    order)."""
    inner = axis.shape[0]
    _build_nodes(pts, perm, axis, split, leaf, inner, lo, hi, node, box, stop, inner + 1,
                 np.zeros((1, 3), np.int64), np.zeros((1, 6)))


@kernel
def _build_nodes(pts, perm, axis, split, leaf, inner, lo0, hi0, node0, box0, stop, defer,
                 tasks, task_box):
    """Split the nodes of the subtree at node0 over points [lo0, hi0) with cell box0,
    depth first; inner nodes with index >= defer are written to tasks / task_box
    instead (returns their count)."""
    st = np.empty((2 * STACK, 3), np.int64)  # lo, hi, node
    st_box = np.empty((2 * STACK, 6), np.float64)
    st[0, 0], st[0, 1], st[0, 2] = lo0, hi0, node0
    st_box[0] = box0
    box = np.empty(6, np.float64)  # the popped node's cell (scratch: no allocation a node)
    nt = 0
    sp = 1
    while sp > 0:
        if stop[0]:
            break
        sp -= 1
        lo, hi, node = st[sp, 0], st[sp, 1], st[sp, 2]
        if node >= inner:
            leaf[node - inner] = lo
            continue
        if node >= defer:
            tasks[nt, 0], tasks[nt, 1], tasks[nt, 2] = lo, hi, node
            task_box[nt] = st_box[sp]
            nt += 1
            continue
        box[:] = st_box[sp]
        ax = 0
        for c in (1, 2):
            if box[3 + c] - box[c] > box[3 + ax] - box[ax]:
                ax = c
        med = lo + (hi - lo) // 2
        if hi > lo:
            _select(pts, perm, lo, hi, med, ax)
            value = pts[med, ax]
        else:
            value = np.float32(box[ax]) if np.isfinite(box[ax]) else np.float32(0.0)
        axis[node] = ax
        split[node] = value
        # Left: points [lo, med), coordinates <= split; right: [med, hi), >= split.
        # Left pushed last: popped first (depth first keeps the stack short).
        st[sp, 0], st[sp, 1], st[sp, 2] = med, hi, 2 * node + 2
        st_box[sp] = box
        st_box[sp, ax] = value
        sp += 1
        st[sp, 0], st[sp, 1], st[sp, 2] = lo, med, 2 * node + 1
        st_box[sp] = box
        st_box[sp, 3 + ax] = value
        sp += 1
    return nt


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
def traversal_stack():
    """A traversal stack: node indices (STACK,) int64 and, per entry, the query's x, y, z
    offsets to the node's cell and their squared sum (STACK, 4) float64. The searches'
    `_in` forms take one as scratch: a caller making many searches on one thread makes it
    once (two allocations per search cost ~20 % of a seeded nearest search: 0.58-0.71
    against 0.45-0.51 us, docs/performance.md, "Fourteenth slice")."""
    return np.empty(STACK, np.int64), np.empty((STACK, 4), np.float64)


@kernel
def _push_root(st_node, st_off):
    """Empty the stack but for the root (no offsets). Returns the stack size, 1."""
    st_node[0] = 0
    st_off[0, 0] = st_off[0, 1] = st_off[0, 2] = st_off[0, 3] = 0.0
    return 1


@kernel
def _root_stack():
    """A fresh traversal_stack holding the root: (st_node, st_off, size 1)."""
    st_node, st_off = traversal_stack()
    return st_node, st_off, _push_root(st_node, st_off)


@kernel
def _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, bound, inclusive, st_node,
             st_off, sp):
    """From `node` (its cell rd squared away from the query, per-axis offsets ox, oy, oz)
    down to the leaf on the query's side, pushing each far child whose cell is within
    bound (<= with inclusive, else <) onto the stack with its offsets (the incremental
    distance of Arya and Mount). Returns (leaf node, stack size). Every query's walk."""
    inner = axis.shape[0]
    while node < inner:
        ax = axis[node]
        if ax == 0:
            diff, old = qx - np.float64(split[node]), ox
        elif ax == 1:
            diff, old = qy - np.float64(split[node]), oy
        else:
            diff, old = qz - np.float64(split[node]), oz
        if diff < 0.0:
            near, far = 2 * node + 1, 2 * node + 2
        else:
            near, far = 2 * node + 2, 2 * node + 1
        rd_far = rd - old * old + diff * diff
        if rd_far <= bound if inclusive else rd_far < bound:
            st_node[sp] = far
            st_off[sp, 0], st_off[sp, 1], st_off[sp, 2] = ox, oy, oz
            st_off[sp, ax] = diff
            st_off[sp, 3] = rd_far
            sp += 1
        node = near
    return node, sp


@kernel
def knn(pos, axis, split, leaf, qx, qy, qz, kq, r2, d2, idx):
    """The kq nearest points with squared distance < r2 into d2[:count], idx[:count]
    (increasing distance; d2, idx: scratch of at least kq). Returns count."""
    n = pos.shape[0]
    count = 0
    if n == 0 or kq <= 0:
        return 0
    inner = axis.shape[0]
    bound = r2
    st_node, st_off, sp = _root_stack()
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        if rd >= bound:
            continue
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        node, sp = _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, bound, False,
                            st_node, st_off, sp)
        for j in range(leaf[node - inner], leaf[node - inner + 1]):
            dx = qx - np.float64(pos[j, 0])
            dy = qy - np.float64(pos[j, 1])
            dz = qz - np.float64(pos[j, 2])
            dist2 = dx * dx + dy * dy + dz * dz
            if dist2 < bound:
                count = heap_insert(d2, idx, count, kq, dist2, j)
                if count == kq:
                    bound = d2[0]
    heap_sort(d2, idx, count, kq)
    return count


@kernel
def nearest(pos, axis, split, leaf, qx, qy, qz, r2):
    """The nearest point with squared distance < r2: (index, squared distance), or
    (-1, r2) when there is none. The same point as knn(kq=1) (the first met of equally
    near ones), without the heap: the gather map's common lookup."""
    st_node, st_off = traversal_stack()
    return nearest_in(pos, axis, split, leaf, qx, qy, qz, r2, st_node, st_off)


@kernel
def nearest_in(pos, axis, split, leaf, qx, qy, qz, r2, st_node, st_off):
    """nearest with a caller's traversal_stack (st_node, st_off) as scratch."""
    n = pos.shape[0]
    best = -1
    bound = r2
    if n == 0:
        return best, bound
    inner = axis.shape[0]
    sp = _push_root(st_node, st_off)
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        if rd >= bound:
            continue
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        node, sp = _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, bound, False,
                            st_node, st_off, sp)
        for j in range(leaf[node - inner], leaf[node - inner + 1]):
            dx = qx - np.float64(pos[j, 0])
            dy = qy - np.float64(pos[j, 1])
            dz = qz - np.float64(pos[j, 2])
            dist2 = dx * dx + dy * dy + dz * dz
            if dist2 < bound:
                best = j
                bound = dist2
    return best, bound


@kernel
def nearest_facing(pos, axis, split, leaf, normal, qx, qy, qz, nx, ny, nz, agreement, r2):
    """The nearest point j with squared distance < r2 whose normal faces the query's way
    (normal[j] . (nx, ny, nz) > agreement): (index, squared distance), or (-1, r2). Only
    facing points shrink the search bound, so one traversal replaces a k-NN query
    followed by a normal test over its result (normal: (N,3), in the tree's order)."""
    st_node, st_off = traversal_stack()
    return nearest_facing_in(pos, axis, split, leaf, normal, qx, qy, qz, nx, ny, nz,
                             agreement, r2, st_node, st_off)


@kernel
def nearest_facing_in(pos, axis, split, leaf, normal, qx, qy, qz, nx, ny, nz, agreement, r2,
                      st_node, st_off):
    """nearest_facing with a caller's traversal_stack (st_node, st_off) as scratch."""
    return nearest_facing_on_in(pos, axis, split, leaf, normal, _ANY_SURFACE, -1, qx, qy, qz,
                                nx, ny, nz, agreement, r2, st_node, st_off)


_ANY_SURFACE = np.zeros(0, np.int32)  # nearest_facing_on_in without the surface test


@kernel
def nearest_facing_on_in(pos, axis, split, leaf, normal, surface, qs, qx, qy, qz, nx, ny, nz,
                         agreement, r2, st_node, st_off):
    """nearest_facing_in's answer among the points on the query's surface qs as well
    (samesurface.same_surface over surface (N,) int32, the points' object ids in the
    tree's order; qs < 0: every facing point, nearest_facing_in's; surface may be empty
    only then)."""
    n = pos.shape[0]
    best = -1
    bound = r2
    if n == 0:
        return best, bound
    inner = axis.shape[0]
    sp = _push_root(st_node, st_off)
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        if rd >= bound:
            continue
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        node, sp = _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, bound, False,
                            st_node, st_off, sp)
        for j in range(leaf[node - inner], leaf[node - inner + 1]):
            dx = qx - np.float64(pos[j, 0])
            dy = qy - np.float64(pos[j, 1])
            dz = qz - np.float64(pos[j, 2])
            dist2 = dx * dx + dy * dy + dz * dz
            if not dist2 < bound:
                continue
            m0, m1, m2 = read_vector(normal, j)  # (photonlayout: float32 or octahedral)
            if m0 * nx + m1 * ny + m2 * nz > agreement \
                    and (qs < 0 or surface[j] == qs or surface[j] < 0
                         or continues_plane(pos, normal, j, qx, qy, qz, nx, ny, nz)):
                best = j
                bound = dist2
    return best, bound


@kernel
def count_closer(pos, axis, split, leaf, qx, qy, qz, r2, cap):
    """How many points have squared distance < r2, counting up to cap (returns cap as
    soon as cap are found): the rank test "is this point among the cap nearest?"."""
    st_node, st_off = traversal_stack()
    return count_closer_in(pos, axis, split, leaf, qx, qy, qz, r2, cap, st_node, st_off)


@kernel
def count_closer_in(pos, axis, split, leaf, qx, qy, qz, r2, cap, st_node, st_off):
    """count_closer with a caller's traversal_stack (st_node, st_off) as scratch."""
    n = pos.shape[0]
    count = 0
    if n == 0 or cap <= 0:
        return 0
    inner = axis.shape[0]
    sp = _push_root(st_node, st_off)
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        node, sp = _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, r2, False,
                            st_node, st_off, sp)
        for j in range(leaf[node - inner], leaf[node - inner + 1]):
            dx = qx - np.float64(pos[j, 0])
            dy = qy - np.float64(pos[j, 1])
            dz = qz - np.float64(pos[j, 2])
            if dx * dx + dy * dy + dz * dz < r2:
                count += 1
                if count == cap:
                    return cap
    return count


@kernel
def ball(pos, axis, split, leaf, qx, qy, qz, r2, out, cap):
    """Indices of the points with squared distance <= r2 into out[:min(count, cap)], in
    tree order. Stops scanning once more than cap are found and returns cap + 1; else
    returns the count. out[count:cap] may be overwritten (scratch)."""
    n = pos.shape[0]
    count = 0
    if n == 0:
        return 0
    inner = axis.shape[0]
    st_node, st_off, sp = _root_stack()
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        node, sp = _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, r2, True,
                            st_node, st_off, sp)
        lo, hi = leaf[node - inner], leaf[node - inner + 1]
        if count + (hi - lo) <= cap:
            # Room for the whole leaf: written without a branch, the count advanced by
            # the test (a point inside is a coin flip at a sphere's rim: mispredicted
            # branches cost more than the writes; docs/performance.md "caustickernel").
            for j in range(lo, hi):
                dx = qx - np.float64(pos[j, 0])
                dy = qy - np.float64(pos[j, 1])
                dz = qz - np.float64(pos[j, 2])
                out[count] = j
                count += dx * dx + dy * dy + dz * dz <= r2
            continue
        for j in range(lo, hi):
            dx = qx - np.float64(pos[j, 0])
            dy = qy - np.float64(pos[j, 1])
            dz = qz - np.float64(pos[j, 2])
            if dx * dx + dy * dy + dz * dz <= r2:
                if count == cap:
                    return cap + 1
                out[count] = j
                count += 1
    return count


@kernel
def ball_d2(pos, axis, split, leaf, qx, qy, qz, r2, d2, idx, cap):
    """The points with squared distance < r2 (knn's strict bound) and those distances
    into idx[:count], d2[:count], in tree order (the same float64 distances knn
    computes). Stops scanning once more than cap are found and returns cap + 1; else
    returns the count. With nearest_first, the k-NN answer of a sphere that holds few
    points, without a heap (estimates of a sparse map: engine/photonmap.py). d2 / idx
    beyond count (up to cap) may be overwritten (scratch)."""
    n = pos.shape[0]
    count = 0
    if n == 0:
        return 0
    inner = axis.shape[0]
    st_node, st_off, sp = _root_stack()
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        rd = st_off[sp, 3]
        ox, oy, oz = st_off[sp, 0], st_off[sp, 1], st_off[sp, 2]
        node, sp = _descend(axis, split, node, rd, ox, oy, oz, qx, qy, qz, r2, False,
                            st_node, st_off, sp)
        lo, hi = leaf[node - inner], leaf[node - inner + 1]
        if count + (hi - lo) <= cap:
            for j in range(lo, hi):  # without a branch, as in ball
                dx = qx - np.float64(pos[j, 0])
                dy = qy - np.float64(pos[j, 1])
                dz = qz - np.float64(pos[j, 2])
                dist2 = dx * dx + dy * dy + dz * dz
                d2[count] = dist2
                idx[count] = j
                count += dist2 < r2
            continue
        for j in range(lo, hi):
            dx = qx - np.float64(pos[j, 0])
            dy = qy - np.float64(pos[j, 1])
            dz = qz - np.float64(pos[j, 2])
            dist2 = dx * dx + dy * dy + dz * dz
            if dist2 < r2:
                if count == cap:
                    return cap + 1
                d2[count] = dist2
                idx[count] = j
                count += 1
    return count


INSERTION_SORT = 16  # ranges this short are finished by insertion sort
BUCKET_MAX = 32  # a distance bucket fuller than this is ordered by quicksort instead


@kernel
def nearest_first(src_d2, src_idx, count, m, r2, d2, idx, hist):
    """The count entries of src_d2 / src_idx (squared distances < r2 and their points)
    into d2 / idx (same entries) with the m smallest first in increasing distance, the
    rest after them. A counting sort into `count` buckets of equal squared-distance width
    (photons on a surface fill them evenly: a disc's area grows with d^2), then insertion
    sort of the buckets up to the m-th entry: about two branch-free passes, where a
    comparison sort's unpredictable branches cost 3-4x more (bench/bench_lookup.py).
    Buckets fuller than BUCKET_MAX (clustered distances) fall back to a partial quicksort
    (_partial_sort). hist: scratch of count + 1 entries. Equal distances keep src's order."""
    m = min(m, count)
    if m <= 0:
        return
    if count <= INSERTION_SORT or not r2 > 0.0:
        for j in range(count):
            d2[j] = src_d2[j]
            idx[j] = src_idx[j]
        if count <= INSERTION_SORT:
            # _partial_sort's own answer for so few (it insertion-sorts them whole),
            # without its stack's allocation (~40 ns: 12 % of Figure 7's caustic rows).
            _insertion_sort(d2, idx, 0, count)
        else:
            _partial_sort(d2, idx, count, m)
        return
    scale = count / r2
    top = count - 1
    hist[:count + 1] = 0
    for j in range(count):
        b = min(int(src_d2[j] * scale), top)
        hist[b + 1] += 1
    # Bucket starts; the buckets up to the one holding entry m - 1 must be short.
    full = False
    last = 0
    for b in range(count):
        size = hist[b + 1]
        hist[b + 1] += hist[b]
        if hist[b] < m:
            last = b
            if size > BUCKET_MAX:
                full = True
    if full:
        for j in range(count):
            d2[j] = src_d2[j]
            idx[j] = src_idx[j]
        _partial_sort(d2, idx, count, m)
        return
    for j in range(count):
        b = min(int(src_d2[j] * scale), top)
        slot = hist[b]
        d2[slot] = src_d2[j]
        idx[slot] = src_idx[j]
        hist[b] = slot + 1
    # hist[b] is now bucket b's end; entries beyond bucket `last` stay bucket-ordered.
    _insertion_sort(d2, idx, 0, hist[last])


@kernel
def unique_nearest(d2, count, m):
    """After nearest_first(..., count, m, ...): True when the m first distances are
    strictly increasing and strictly below every other of the count entries, i.e. the m
    nearest are one set in one order whatever the search or sort that finds them."""
    if m > count or m <= 0:
        return False
    for j in range(m - 1):
        if not d2[j] < d2[j + 1]:
            return False
    last = d2[m - 1]
    for j in range(m, count):
        if not last < d2[j]:
            return False
    return True


@kernel
def _insertion_sort(d2, idx, lo, hi):
    """Sort d2[lo:hi] (idx with it) by insertion: stable, fast on nearly sorted ranges."""
    for i in range(lo + 1, hi):
        v = d2[i]
        u = idx[i]
        j = i - 1
        while j >= lo and d2[j] > v:
            d2[j + 1] = d2[j]
            idx[j + 1] = idx[j]
            j -= 1
        d2[j + 1] = v
        idx[j + 1] = u


@kernel
def _partial_sort(d2, idx, count, m):
    """Reorder the count entries of d2 / idx in place so that the m smallest come first
    in increasing distance: a partial quicksort (Hoare's FIND and quicksort, recursing
    only into ranges that start below m; three-way partitions, so many equal distances
    (a focus) stay linear). O(count + m log m) expected, a fixed stack."""
    m = min(m, count)
    st = np.empty((2 * STACK, 2), np.int64)
    st[0, 0], st[0, 1] = 0, count
    sp = 1
    while sp > 0:
        sp -= 1
        lo, hi = st[sp, 0], st[sp, 1]
        while hi - lo > INSERTION_SORT and lo < m:
            mid = (lo + hi) // 2
            a, b, c = d2[lo], d2[mid], d2[hi - 1]
            pivot = max(min(a, b), min(max(a, b), c))  # median of three
            lt = lo
            i = lo
            gt = hi
            while i < gt:
                v = d2[i]
                if v < pivot:
                    _swap_entry(d2, idx, i, lt)
                    lt += 1
                    i += 1
                elif v > pivot:
                    gt -= 1
                    _swap_entry(d2, idx, i, gt)
                else:
                    i += 1
            # [lo, lt) < pivot, [lt, gt) == pivot (done), [gt, hi) > pivot. Only ranges
            # starting below m matter; the longer one goes on the stack, the shorter
            # is taken next, so the stack stays under log2(count) < 2 x STACK deep.
            if gt < m:
                if lt - lo > hi - gt:
                    st[sp, 0], st[sp, 1] = lo, lt
                    sp += 1
                    lo = gt
                else:
                    st[sp, 0], st[sp, 1] = gt, hi
                    sp += 1
                    hi = lt
            else:
                hi = lt
        if lo < m:
            _insertion_sort(d2, idx, lo, hi)


@kernel
def _swap_entry(d2, idx, i, j):
    t = d2[i]
    d2[i] = d2[j]
    d2[j] = t
    u = idx[i]
    idx[i] = idx[j]
    idx[j] = u


@kernel
def subtree_range(node, inner, leaf):
    """(first, end) of the points under node: its leftmost and rightmost leaves' range."""
    a = node
    b = node
    while a < inner:
        a = 2 * a + 1
        b = 2 * b + 2
    return leaf[a - inner], leaf[b - inner + 1]


@kernel
def ball_count(pos, axis, split, leaf, bounds, qx, qy, qz, r2):
    """Number of points with squared distance <= r2. bounds: the points' box (lo x, y, z,
    hi x, y, z). A subtree whose cell lies inside the sphere is counted whole (its points
    are one range), so a focus of a million equal points costs a few nodes."""
    n = pos.shape[0]
    count = 0
    if n == 0:
        return 0
    inner = axis.shape[0]
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
        while True:
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
                first, end = subtree_range(node, inner, leaf)
                count += end - first
                break
            if node >= inner:
                for j in range(leaf[node - inner], leaf[node - inner + 1]):
                    dx = qx - np.float64(pos[j, 0])
                    dy = qy - np.float64(pos[j, 1])
                    dz = qz - np.float64(pos[j, 2])
                    if dx * dx + dy * dy + dz * dz <= r2:
                        count += 1
                break
            ax = axis[node]
            value = np.float64(split[node])
            if q[ax] < value:
                near, far = 2 * node + 1, 2 * node + 2
            else:
                near, far = 2 * node + 2, 2 * node + 1
            st_node[sp] = far
            for c in range(3):
                st_box[sp, c] = lo[c]
                st_box[sp, 3 + c] = hi[c]
            if far == 2 * node + 1:
                st_box[sp, 3 + ax] = value  # left: coordinates <= split
            else:
                st_box[sp, ax] = value
            sp += 1
            if near == 2 * node + 1:
                hi[ax] = value
            else:
                lo[ax] = value
            node = near
    return count


@kernel
def neighbour_lists(pos, axis, split, leaf, lo, hi, nbr, reach):
    """For the points j in [lo, hi): their k = nbr.shape[1] nearest other points (knn's
    order) into nbr[j] (uint16 or int32, neighbour_dtype; padded with j itself when there
    are fewer), and into reach[j] (float64) the distance (not squared) within which no
    unlisted point lies: the k-th listed one's, shrunk by 1e-9 relative (far above the
    float64 rounding of the distances), inf when every other point is listed.
    nearest_walk's table (KdTree.neighbour_lists keeps reach as float32, rounded down).

    Each point's k + 1 nearest (itself among them) lie within the previous point's
    (k + 1)-th distance + the distance between the two (triangle inequality; points come
    in tree order, so neighbours): that sphere is listed (ball_d2) and ordered
    (nearest_first), and taken when its k + 1 nearest are free of ties (unique_nearest:
    then any search gives them in that order, knn's answer bit for bit). Else, and for
    spheres of more than KTH_LIST_FACTOR x (k + 1) points, knn."""
    k = nbr.shape[1]
    kq = k + 1
    cap = KTH_LIST_FACTOR * kq
    d2 = np.empty(cap, np.float64)
    idx = np.empty(cap, np.int64)
    list_d2 = np.empty(cap, np.float64)
    list_idx = np.empty(cap, np.int64)
    hist = np.empty(cap + 1, np.int64)
    prev = -1
    prev_d = np.inf  # the previous point's kq-th distance (inf: none)
    for j in range(lo, hi):
        qx, qy, qz = np.float64(pos[j, 0]), np.float64(pos[j, 1]), np.float64(pos[j, 2])
        c = -1
        if prev >= 0 and prev_d < np.inf:
            b = prev_d + np.sqrt(_dist2(pos, prev, qx, qy, qz))
            b2 = seed_bound(b * b)
            if b2 < np.inf:
                got = ball_d2(pos, axis, split, leaf, qx, qy, qz, b2, list_d2, list_idx, cap)
                if kq <= got <= cap:
                    nearest_first(list_d2, list_idx, got, kq, b2, d2, idx, hist)
                    if unique_nearest(d2, got, kq):
                        c = kq
        if c < 0:
            c = knn(pos, axis, split, leaf, qx, qy, qz, kq, np.inf, d2, idx)
        prev = j
        prev_d = np.sqrt(d2[kq - 1]) if c == kq else np.inf
        m = 0
        last = np.inf
        for t in range(c):
            if idx[t] != j and m < k:  # j itself (or an equal point first: then j later)
                nbr[j, m] = idx[t]
                last = d2[t]
                m += 1
        for t in range(m, k):
            nbr[j, t] = j
        reach[j] = np.inf if c < k + 1 else np.sqrt(last) * (1.0 - 1e-9)


@kernel
def _dist2(pos, j, qx, qy, qz):
    """Squared distance of point j to the query: the same float64 arithmetic as every
    query here, so the values compare bit for bit."""
    dx = qx - np.float64(pos[j, 0])
    dy = qy - np.float64(pos[j, 1])
    dz = qz - np.float64(pos[j, 2])
    return dx * dx + dy * dy + dz * dz


@kernel
def seed_bound(d2):
    """A search bound that a point at squared distance d2 certainly passes: d2 plus a
    margin (1e-9 relative) far above the rounding error of the traversal's incremental
    distances to cells (a few ulps), so no cell holding a point as near is pruned and
    the search still meets every such point in its usual order."""
    return d2 * (1.0 + 1e-9) + 1e-300


@kernel
def nearest_walk(pos, axis, split, leaf, nbr, reach, p, rows, r2, steps, near, walked):
    """nearest(r2)'s answer for the queries p[rows[r]] (p (M,3) float64, or wider rows of
    which the first three columns are read; rows (R,) in Morton order) into near[r] (-1:
    no point nearer than sqrt(r2)), most of them without the tree: from g = the previous
    row's answer, the nearest of g and its neighbour list (neighbour_lists' table nbr,
    reach) is q's nearest among all points when
    sqrt(d2(q, best)) + |q - g| < reach[g] (an unlisted point p is at least
    reach[g] - |q - g| from q: triangle inequality). Else the walk moves to the best
    point met and tries again, up to `steps` lists, then searches the tree bounded by
    the nearest point met (seed_bound). Equally near points are never settled by the
    lists (nearest keeps the one its traversal meets first), so every answer is
    nearest's. walked (R,) bool or (0,): which rows the lists settled (tests, benches).

    Two shortcuts, each exact:
    - g alone: when |q - g| < |g - h| / 2 for g's nearest other point h (its list's
      first entry), every other point p is farther from q than g is
      (|q - p| >= |p - g| - |q - g| > |q - g|), so g is the answer (or none beyond
      sqrt(r2)) without its list; squared, 4 |q - g|^2 (1 + 1e-8) < |g - h|^2 (a margin
      far above the float64 rounding, as reach's). 10 % of Figure 6's rows.
    - A jump: when |q - g| > JUMP_REACH x reach[g] (rows in Morton order jumping to
      another surface or region), the lists would not settle the row (under 0.01 % of
      such rows did on Figure 6) and the tree is searched at once, bounded by g
      (seed_bound); 4.3 % of Figure 6's rows, ~2.6 lists each saved.
    With the two-pass list scan below, the walk 12-17 % cheaper on Figures 6 and 7's
    lookups (docs/performance.md, "gathercand2").

    One kernel for all rows, the walk inline: a per-row call of a kernel with array
    arguments cost ~0.08 us a row in reference counting (docs/performance.md, "Eighth
    slice")."""
    k = nbr.shape[1]
    record = walked.shape[0] > 0
    st_node, st_off = traversal_stack()  # one for all rows' tree searches
    dd = np.empty(k)  # a list's squared distances
    prev = -1
    for r in range(rows.shape[0]):
        i = rows[r]
        qx, qy, qz = p[i, 0], p[i, 1], p[i, 2]
        settled = False
        bound = r2
        j = -1
        if prev >= 0:
            g = prev
            best = g
            bd = _dist2(pos, g, qx, qy, qz)
            h = nbr[g, 0] if k > 0 else g  # g itself: no other point, never passes
            ex = np.float64(pos[h, 0]) - np.float64(pos[g, 0])
            ey = np.float64(pos[h, 1]) - np.float64(pos[g, 1])
            ez = np.float64(pos[h, 2]) - np.float64(pos[g, 2])
            if 4.0 * bd * (1.0 + 1e-8) < ex * ex + ey * ey + ez * ez:
                if record:
                    walked[r] = True
                j = g if bd < r2 else -1
                near[r] = j
                if j >= 0:
                    prev = j
                continue
            rg = np.float64(reach[g])
            jump = bd > JUMP_REACH * JUMP_REACH * rg * rg
            for _ in range(0 if jump else steps):
                dg = bd  # best == g here
                # The list's distances first, then their least m and its first entry: the
                # best and tie a scan in list order finds (strictly nearer replaces, an
                # equal distance of another point is a tie), without a branch a point
                # between the loads (-6 to -8 % on the walk, docs/performance.md,
                # "gathercand2").
                for t in range(k):
                    dd[t] = _dist2(pos, nbr[g, t], qx, qy, qz)
                m = bd
                for t in range(k):
                    m = dd[t] if dd[t] < m else m
                tie = False
                if m < bd:
                    first = -1
                    for t in range(k):
                        if dd[t] == m:
                            if first < 0:
                                first = t
                            elif nbr[g, t] != nbr[g, first]:
                                tie = True
                    best = nbr[g, first]
                    bd = m
                else:
                    for t in range(k):
                        if dd[t] == bd and nbr[g, t] != best:
                            tie = True
                if not tie and np.sqrt(bd) + np.sqrt(dg) < np.float64(reach[g]):
                    settled = True
                    j = best if bd < r2 else -1
                    break
                if best == g:
                    break
                g = best
            if not settled:
                bound = min(bound, seed_bound(bd))
        if not settled:
            j, _ = nearest_in(pos, axis, split, leaf, qx, qy, qz, bound, st_node, st_off)
        if record:
            walked[r] = settled
        near[r] = j
        if j >= 0:
            prev = j


@kernel
def knn_batch(pos, axis, split, leaf, queries, kq, radius):
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
        c = knn(pos, axis, split, leaf, queries[i, 0], queries[i, 1], queries[i, 2], kq, r2,
                d2, idx)
        for j in range(c):
            dist[i, j] = np.sqrt(d2[j])
            out[i, j] = idx[j]
    return dist, out


@kernel
def select_value(a, count, m):
    """The m-th smallest (1-based) of a[:count] (float64, no NaN), reordering a[:count]
    in place: the kd-tree build's _select on values. Only the value: which entry holds
    it is not kept."""
    _select(a, a, 0, count, m - 1, 0)  # perm unused for values
    return a[m - 1]


@kernel
def kth_d2_rows(pos, axis, split, leaf, queries, rows, kq, out):
    """For each query i = rows[r] (queries (M,3) float64, rows in Morton order): the
    kq-th smallest squared distance to the points into out[i] (knn's float64 distances
    and strict bound, so knn's d2[kq - 1] bit for bit; out[i] untouched where fewer than
    kq points are finite).

    Only the value is asked for, never which point holds it, so ties do not matter and
    no heap is needed where a bound is known: the kq nearest of the previous row lie
    within its kq-th distance + the distance between the two queries of this one
    (triangle inequality; seed_bound's margin covers the rounding), so the sphere of that
    radius is listed (ball_d2) and its kq-th distance picked (select_value). Rows whose
    sphere holds fewer than kq or more than KTH_LIST_FACTOR x kq points (the first row,
    a jump between Morton cells) take knn. Measured on the secondary map's radius
    (5,113 queries of k = 65): docs/performance.md, "Thirteenth slice"."""
    cap = max(KTH_LIST_FACTOR * kq, 1)
    d2 = np.empty(max(kq, 1), np.float64)
    idx = np.empty(max(kq, 1), np.int64)
    list_d2 = np.empty(cap, np.float64)
    list_idx = np.empty(cap, np.int64)
    prev = -1
    prev_kth = np.inf
    for r in range(rows.shape[0]):
        i = rows[r]
        qx, qy, qz = queries[i, 0], queries[i, 1], queries[i, 2]
        found = False
        kth = np.inf
        if prev >= 0 and prev_kth < np.inf:
            gap = np.sqrt(_dist2q(queries, prev, qx, qy, qz))
            b = np.sqrt(prev_kth) + gap
            b2 = seed_bound(b * b)
            if b2 < np.inf:  # not NaN or inf: a NaN query lists nothing
                got = ball_d2(pos, axis, split, leaf, qx, qy, qz, b2, list_d2, list_idx,
                              cap)
                if kq <= got <= cap:
                    kth = select_value(list_d2, got, kq)
                    found = True
        if not found:
            c = knn(pos, axis, split, leaf, qx, qy, qz, kq, np.inf, d2, idx)
            if c == kq:
                kth = d2[kq - 1]
        if kth < np.inf:
            out[i] = kth
        prev = i
        prev_kth = kth


@kernel
def _dist2q(queries, j, qx, qy, qz):
    """Squared distance between query j and (qx, qy, qz), float64."""
    dx = qx - queries[j, 0]
    dy = qy - queries[j, 1]
    dz = qz - queries[j, 2]
    return dx * dx + dy * dy + dz * dz


def neighbour_dtype(n: int):
    """The index type of a neighbour table over n points: uint16 up to NARROW_NEIGHBOURS
    points (every index 0..n-1 fits), int32 above (docs/performance.md "hdri52")."""
    return np.uint16 if n <= NARROW_NEIGHBOURS else np.int32


def reach32(reach: np.ndarray) -> np.ndarray:
    """(N,) float32: reach (N,) float64 rounded toward zero (a value rounded up to nearest
    steps one float32 ulp down; inf stays inf): reach32(r) <= r, so a reach stays a
    distance within which no unlisted point lies."""
    out = reach.astype(np.float32)
    up = out.astype(np.float64) > reach
    out[up] = np.nextafter(out[up], np.float32(0.0))
    return out


class KdTree:
    """The kd-tree over points (N,3); self.order maps the tree's point index -> input
    index, self.position are the points in the tree's order."""

    def __init__(self, points: np.ndarray, should_cancel=None, workers: int = 1):
        """should_cancel: a parallel.StopFlag (or the flag of the job running on this
        thread, parallel.stop_flag_of) that the compiled build polls; raises
        parallel.Cancelled when it is set. workers > 1: the subtrees below the top
        levels are built on that many threads (the same tree)."""
        pts = np.ascontiguousarray(points, dtype=np.float32)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"KdTree: points must have shape (N, 3), got {pts.shape}")
        stop = stop_array(should_cancel)
        levels = 0
        if workers > 1 and len(pts) >= PARALLEL_POINTS:
            while (1 << levels) < 2 * workers:  # two subtrees a thread: a short tail
                levels += 1
        # The build permutes its own copy of the points: that copy is the tree's order.
        (self.order, self.position, self.axis, self.split, self.leaf, bounds, tasks,
         task_box) = build(pts, stop, levels)
        if stop[0]:
            raise Cancelled()
        if len(tasks):
            def job(i, job_stop):
                flag = stop_array(job_stop)
                build_subtree(self.position, self.order, self.axis, self.split, self.leaf,
                              tasks[i, 0], tasks[i, 1], tasks[i, 2], task_box[i], flag)
                if flag[0]:
                    raise Cancelled()
            for _ in ordered_map(job, range(len(tasks)), workers):
                pass
            if stop[0]:
                raise Cancelled()
        self.bounds = bounds if len(pts) else np.zeros(6)  # lo x, y, z, hi x, y, z

    def __len__(self):
        return len(self.position)

    @property
    def nodes(self):
        """(axis, split, leaf): the arrays every query kernel takes after the positions."""
        return self.axis, self.split, self.leaf

    @property
    def nbytes(self) -> int:
        """Bytes of the tree itself (positions + nodes; order is dropped by callers)."""
        return (self.position.nbytes + self.axis.nbytes + self.split.nbytes
                + self.leaf.nbytes + self.bounds.nbytes)

    def neighbour_lists(self, k: int = NEIGHBOURS, workers: int = 1, should_cancel=None):
        """(nbr (N,k) uint16 or int32 (neighbour_dtype), reach (N,) float32): each point's
        k nearest other points and the distance within which no other point lies
        (neighbour_lists), for nearest_walk. reach is the kernel's float64 distance
        rounded down to float32 (reach32): never beyond it, so every row the lists settle
        is still nearest's answer; a row whose float64 reach would have settled it by less
        than a float32 step searches the tree (the same answer). Built on `workers`
        threads (the same table); raises parallel.Cancelled when should_cancel is set."""
        n = len(self.position)
        nbr = np.empty((n, k), neighbour_dtype(n))
        reach = np.empty(n)
        chunks = [(a, min(a + NEIGHBOUR_CHUNK, n)) for a in range(0, n, NEIGHBOUR_CHUNK)]

        def job(chunk, job_stop):
            if job_stop():
                raise Cancelled()
            neighbour_lists(self.position, self.axis, self.split, self.leaf, chunk[0],
                            chunk[1], nbr, reach)
        for _ in ordered_map(job, chunks, workers if n >= PARALLEL_POINTS // 4 else 1,
                             should_cancel):
            pass
        return nbr, reach32(reach)

    def kth(self, queries: np.ndarray, k: int) -> np.ndarray:
        """(M,) float64 distances (not squared) from queries (M,3) to their k-th nearest
        point (inf where fewer than k): query(queries, k, inf)[0][:, k - 1] bit for bit
        (kth_d2_rows, rows in Morton order), as mortontree.KthTree.kth."""
        from .mortontree import morton_order
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(q), np.inf)
        if len(self.position) and k > 0 and len(q):
            kth_d2_rows(self.position, *self.nodes, q, morton_order(q), int(k), out)
        return np.sqrt(out)

    def query(self, queries: np.ndarray, k: int, radius: float):
        """(dist, idx) of the k nearest points within radius, like cKDTree.query with
        distance_upper_bound (idx = len(self) where none). idx index self.position."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        return knn_batch(self.position, *self.nodes, q, int(k), float(radius))


@register_warm_up
def _warm_up():
    pts = np.random.default_rng(0).random((40, 3)).astype(np.float32)
    tree = KdTree(pts)
    order, position, axis, split, leaf, _, tasks, task_box = build(pts, np.zeros(1, np.uint8),
                                                                   1)
    for i in range(len(tasks)):
        build_subtree(position, order, axis, split, leaf, tasks[i, 0], tasks[i, 1],
                      tasks[i, 2], task_box[i], np.zeros(1, np.uint8))
    tree.query(pts[:3].astype(np.float64), 4, 0.5)
    tree.kth(pts[:6].astype(np.float64), 4)
    out = np.empty(8, np.int64)
    ball(tree.position, *tree.nodes, 0.5, 0.5, 0.5, 0.1, out, 8)
    ball_count(tree.position, *tree.nodes, tree.bounds, 0.5, 0.5, 0.5, 0.1)
    nearest(tree.position, *tree.nodes, 0.5, 0.5, 0.5, 0.1)
    nrm = np.zeros((40, 3)); nrm[:, 2] = 1.0
    nearest_facing(tree.position, *tree.nodes, nrm, 0.5, 0.5, 0.5, 0.0, 0.0, 1.0, 0.7, 0.1)
    count_closer(tree.position, *tree.nodes, 0.5, 0.5, 0.5, 0.1, 8)
    nbr, reach = tree.neighbour_lists(4)
    # The int32 table of more than NARROW_NEIGHBOURS points (the same kernels).
    wide = np.empty(nbr.shape, np.int32)
    neighbour_lists(tree.position, *tree.nodes, 0, len(pts), wide, np.empty(len(pts)))
    q = np.full((2, 3), 0.5)
    rows = np.arange(2, dtype=np.int64)
    near = np.empty(2, np.int64)
    for table in (nbr, wide):
        for walked in (np.empty(2, np.bool_), np.zeros(0, np.bool_)):
            nearest_walk(tree.position, *tree.nodes, table, reach, q, rows, 0.1, 3, near,
                         walked)
