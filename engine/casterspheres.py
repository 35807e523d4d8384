"""Bounding spheres that caustic photons are aimed at: one per caster, or, where the caster
fills its bounding sphere poorly (a thin ring, a long strip of many triangles), a few smaller
spheres around clusters of its triangles.

The aimed shot (engine/lights/emission.py, aim_direction / aim_origin) picks a sphere by
the solid angle (or, from infinity, the shadow disk) it subtends and weighs each photon
by natural pdf / aimed pdf, the aimed pdf summed over every sphere whose cone holds the
direction, so overlapping spheres stay unbiased: only the photons' spread changes. A
photon aimed at a sphere that the caster barely fills misses it, and a missed caustic
photon is a wasted trace (newuser42's half ring, 1 m radius, 0.35 m high: 3.5 % of the
caustic photons were stored).

The rule is geometric and light-free: the cost of a set of spheres is the sum of their
squared radii (each sphere's share of aimed photons is its solid angle, ~ r^2 from afar),
and a caster is split only where that sum drops by at least MIN_GAIN. A ball, a cube or a
square mirror never gains (a half-ball's sphere is 1.12 x the ball's: two of them cost
2.5 x one; a plane's pieces cost the same as the whole), so it keeps the one sphere it had,
bit for bit (docs/design.md, Photon mapping model)."""
from __future__ import annotations

import numpy as np

from .geometry import PIECE_TRIANGLES, Geometry
from .rayoffset import ulp32

# Off: one bounding sphere per caster, as before (the benchmark's "before").
CLUSTER_CASTERS = True
# Spheres one caster may be split into, and all casters together: the aimed kernels test
# every sphere per photon (at worst, 64 spheres each holding every photon's direction,
# +43 % of a glass ball's caustic shot, 8 +6 %: docs/accuracy.md "ring43").
MAX_PER_CASTER = 16
MAX_SPHERES = 64
# A split must cut the summed r^2 by at least this share (else one sphere, as before);
# each extra sphere is charged SPHERE_COST of the set's cost when choosing the count.
MIN_GAIN = 0.25
SPHERE_COST = 0.02
# Depth of the tree of triangle clusters (2^5 = 32 leaves to choose from),
# built on at most SAMPLE_TRIANGLES of a caster's triangles.
TREE_DEPTH = 5
SAMPLE_TRIANGLES = 8192


def triangle_pieces(sel: np.ndarray):
    """Indices of triangles sel (indices, or a (T,) bool mask), PIECE_TRIANGLES rows of
    the list or of the mask at a time (no index list of every masked triangle)."""
    for a in range(0, len(sel), PIECE_TRIANGLES):
        piece = sel[a:a + PIECE_TRIANGLES]
        yield a + np.nonzero(piece)[0] if piece.dtype == np.bool_ else piece


def corner_pieces(geo: Geometry, sel: np.ndarray):
    """The corners (3n,3) of triangles sel (indices or a bool mask), a piece at a time."""
    for idx in triangle_pieces(sel):
        if not len(idx):
            continue
        v0 = np.take(geo.v0, idx, axis=0)
        yield np.concatenate([v0, v0 + np.take(geo.e1, idx, axis=0),
                              v0 + np.take(geo.e2, idx, axis=0)])


def bounding_sphere(geo: Geometry, sel: np.ndarray) -> tuple:
    """(centre (3,), radius) around the corners of triangles sel (indices or a bool mask):
    centred on their bounding box, 0.1 % margin, and at least the float32 resolution at
    the sphere's coordinates. Corners are read a piece at a time: all of a large
    object's would cost 72 B a triangle at the peak of the preparation."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for pts in corner_pieces(geo, sel):
        lo, hi = np.minimum(lo, pts.min(axis=0)), np.maximum(hi, pts.max(axis=0))
    c = (lo + hi) / 2.0
    far = big = 0.0
    for pts in corner_pieces(geo, sel):
        far = max(far, float(np.linalg.norm(pts - c, axis=1).max()))
        big = max(big, float(np.abs(pts).max()))
    return c, far * 1.001 + 16.0 * float(ulp32(big))


def per_caster(casters: int) -> int:
    """Spheres each of `casters` casters may take: MAX_PER_CASTER within MAX_SPHERES in
    all (at least one each: many casters keep one sphere apiece, as before)."""
    if not CLUSTER_CASTERS or casters <= 0:
        return 1
    return int(max(1, min(MAX_PER_CASTER, MAX_SPHERES // casters)))


class _Node:
    __slots__ = ("radius", "axis", "split", "children")

    def __init__(self, radius):
        self.radius, self.axis, self.split, self.children = radius, 0, 0.0, ()


def _centroids(geo: Geometry, rows: np.ndarray) -> np.ndarray:
    """(n,3) centroids of triangles rows, a piece at a time."""
    cent = np.empty((len(rows), 3))
    for a in range(0, len(rows), PIECE_TRIANGLES):
        idx = rows[a:a + PIECE_TRIANGLES]
        cent[a:a + len(idx)] = (np.take(geo.v0, idx, axis=0)
                                + (np.take(geo.e1, idx, axis=0)
                                   + np.take(geo.e2, idx, axis=0)) / 3.0)
    return cent


def _boxes(geo: Geometry, rows: np.ndarray) -> tuple:
    """(lo, hi) (n,3): each triangle's bounding box (the sample's only: small)."""
    v0 = np.take(geo.v0, rows, axis=0)
    v1, v2 = v0 + np.take(geo.e1, rows, axis=0), v0 + np.take(geo.e2, rows, axis=0)
    return np.minimum(np.minimum(v0, v1), v2), np.maximum(np.maximum(v0, v1), v2)


def _sweep(lo, hi, cent) -> tuple:
    """The split of triangles (boxes lo, hi, centroids cent (n,3)) by centroid along one
    axis into two runs whose boxes' squared diagonals sum least (a surface-area
    heuristic's sweep, with the box's circumscribed sphere as the cost: r^2 of each
    side); (cost, axis, order, k): order[:k] go left."""
    best = (np.inf, 0, None, 0)
    n = len(cent)
    for axis in range(3):
        order = np.argsort(cent[:, axis], kind="stable")
        l, h = lo[order], hi[order]
        # left run 0..i and right run i+1..n-1 boxes, all i at once
        pl = np.maximum.accumulate(h, axis=0) - np.minimum.accumulate(l, axis=0)
        sr = (np.maximum.accumulate(h[::-1], axis=0)
              - np.minimum.accumulate(l[::-1], axis=0))[::-1]
        cost = (pl[:-1] ** 2).sum(axis=1) + (sr[1:] ** 2).sum(axis=1)
        # a split between equal centroids cannot be kept by _assign's test
        cost[cent[order[1:], axis] <= cent[order[:-1], axis]] = np.inf
        i = int(np.argmin(cost)) if n > 1 else 0
        if n > 1 and cost[i] < best[0]:
            best = (float(cost[i]), axis, order, i + 1)
    return best


def _tree(geo: Geometry, rows: np.ndarray, cent: np.ndarray, lo, hi, depth: int,
          radius=None) -> _Node:
    """Tree of triangles rows (centroids cent, boxes lo, hi) split by _sweep, each node
    with the radius of its triangles' bounding sphere and its split (axis, coordinate:
    centroids below it go left)."""
    node = _Node(radius if radius is not None else bounding_sphere(geo, rows)[1])
    if depth <= 0 or len(rows) < 2:
        return node
    cost, axis, order, k = _sweep(lo, hi, cent)
    if order is None:
        return node  # every centroid at one point: nothing to split
    left, right = order[:k], order[k:]
    node.axis, node.split = axis, float(cent[right[0], axis])
    node.children = tuple(_tree(geo, rows[part], cent[part], lo[part], hi[part], depth - 1)
                          for part in (left, right))
    return node


def _best(node: _Node, most: int) -> list:
    """best[b] for b = 0 .. most: (summed r^2, nodes) of the cheapest cut of node's
    subtree into at most b spheres (b = 0: none, infinite cost)."""
    own = node.radius * node.radius
    best = [(np.inf, [])] + [(own, [node])] * most
    if node.children:
        left, right = (_best(child, most) for child in node.children)
        for b in range(2, most + 1):
            for b1 in range(1, b):
                cost = left[b1][0] + right[b - b1][0]
                if cost < best[b][0]:
                    best[b] = (cost, left[b1][1] + right[b - b1][1])
    return best


def _assign(node: _Node, cut: set, rows: np.ndarray, cent: np.ndarray, out: list):
    """Split triangles rows (centroids cent) down the tree by its splits into the cut's
    clusters (out: one index array per cut node reached)."""
    if id(node) in cut:
        if len(rows):
            out.append(rows)
        return
    below = cent[:, node.axis] < node.split
    _assign(node.children[0], cut, rows[below], cent[below], out)
    _assign(node.children[1], cut, rows[~below], cent[~below], out)


def caster_spheres(geo: Geometry, sel: np.ndarray, most: int = MAX_PER_CASTER,
                   root=None) -> tuple:
    """Bounding spheres (centers (m,3), radii (m,)) covering every corner of one caster's
    triangles sel (indices or a bool mask), 1 <= m <= most: the cheapest cut of a
    cluster tree (_sweep's splits) by summed r^2, each extra sphere charged SPHERE_COST; one
    sphere (bounding_sphere's, or root = (centre, radius) already computed from it)
    unless the cut saves MIN_GAIN of its cost. The cut is chosen on at most
    SAMPLE_TRIANGLES of the triangles (a stride through them: a million-triangle ball
    costs ~0.05 CPU s more than its one sphere); every triangle then goes down the tree's
    splits into its cluster, whose sphere bounds all of its corners."""
    root = bounding_sphere(geo, sel) if root is None else root
    one = (np.asarray(root[0], np.float64)[None, :], np.array([root[1]], np.float64))
    rows = sel if sel.dtype != np.bool_ else np.nonzero(sel)[0]
    if most <= 1 or len(rows) < 2 or not CLUSTER_CASTERS:
        return one
    step = -(-len(rows) // SAMPLE_TRIANGLES)
    sample = rows[::step]
    tree = _tree(geo, sample, _centroids(geo, sample), *_boxes(geo, sample), TREE_DEPTH,
                 root[1])
    best = _best(tree, most)
    score = [best[b][0] * (1.0 + SPHERE_COST * (b - 1)) for b in range(1, most + 1)]
    b = 1 + int(np.argmin(score))
    if b == 1 or not best[b][0] <= (1.0 - MIN_GAIN) * best[1][0]:
        return one
    clusters = []
    _assign(tree, {id(n) for n in best[b][1]}, rows, _centroids(geo, rows), clusters)
    spheres = [bounding_sphere(geo, c) for c in clusters]
    return (np.array([c for c, _ in spheres]).reshape(-1, 3),
            np.array([r for _, r in spheres], np.float64))
