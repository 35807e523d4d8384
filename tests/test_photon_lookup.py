"""The compiled photon lookups (engine/kdtree.py, engine/hashgrid.py, engine/photonmap.py)
against scipy's cKDTree and against the numpy estimators they replaced
(tests/reference_photonmap.py):
- k-NN neighbour sets and sphere counts are cKDTree's, on random points, on many identical
  points (a focus) and on tiny sets;
- the kd-tree is left-balanced and ordered (every node splits its subtree);
- every estimator (k-NN Simpson / cone with widening, classic, radius; boundary flags;
  r_floor; min_photons) matches the reference on synthetic maps (corners, a wall lit only
  on its far side, a focus) and on a real scene's global and caustic maps;
- the widening search has a fixed memory budget (issue 16), and results do not depend on
  the number of worker threads.
"""
import ast
import math
import os
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
from scipy.spatial import cKDTree

from engine import RenderSettings
from engine.api import cornell_box
from engine.hashgrid import HashGrid
from engine.hashgrid import ball_count as grid_ball_count
from engine.hashgrid import cells_spanned
from engine.kdtree import (BUCKET_MAX, JUMP_REACH, LEAF_SIZE, KdTree, ball, ball_count,
                           ball_d2, count_closer, count_closer_in, knn, nearest,
                           nearest_facing, nearest_facing_in, nearest_first, nearest_in,
                           nearest_walk, traversal_stack, unique_nearest)
from engine.kdtree import heap_insert, heap_sort
from engine import photonlayout
from engine.photonlayout import powers, vectors
from engine.photonmap import (ESTIMATOR_CODES, MAX_WIDEN_K, SCAN_BUDGET, GatherMap,
                              PhotonMap, _widen_listed)
from engine.photons import Photons
from engine.render import _photon_pass, prepare_context

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from reference_photonmap import ReferencePhotonMap  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _structures(points, cell):
    return {"kdtree": KdTree(points), "hashgrid": HashGrid(points, cell)}


@pytest.mark.parametrize("n", [1, 2, 3, 7, 1000, 30000])
@pytest.mark.parametrize("structure", ["kdtree", "hashgrid"])
def test_knn_and_sphere_counts_match_ckdtree(n, structure):
    rng = np.random.default_rng(n)
    pts = rng.random((n, 3)).astype(np.float32)
    if n >= 1000:
        pts[: n // 4] = pts[0]  # a focus: many identical points
    s = _structures(pts, 0.1)[structure]
    ref = cKDTree(pts.astype(np.float64))
    q = rng.random((400, 3)) * 1.2 - 0.1
    q[:20] = pts[0]
    for k in (1, 8, 64):
        k = min(k, n)
        d, i = s.query(q, k, 0.1)
        dr, ir = ref.query(q, k=k, distance_upper_bound=0.1)
        dr, ir = dr.reshape(len(q), -1), ir.reshape(len(q), -1)
        np.testing.assert_allclose(d, dr, rtol=1e-12)
        found = i < n
        assert (found == (ir < n)).all()
        # Same points (ties at equal distance may come in another order).
        mine = np.where(found, s.order[np.minimum(i, n - 1)], -1)
        theirs = np.where(ir < n, ir, -1)
        assert (np.sort(mine, axis=1) == np.sort(theirs, axis=1)).all() or \
            np.allclose(np.sort(d, axis=1), np.sort(dr, axis=1))
    counts = ref.query_ball_point(q, 0.05, return_length=True)
    if structure == "kdtree":
        mine = [ball_count(s.position, *s.nodes, s.bounds, *x, 0.05 ** 2) for x in q]
        out = np.empty(len(pts) + 1, np.int64)
        listed = [ball(s.position, *s.nodes, *x, 0.05 ** 2, out, len(pts)) for x in q]
        assert listed == list(counts)
        assert ball(s.position, *s.nodes, *q[0], 0.05 ** 2, out, 0) == (1 if counts[0] else 0)
    else:
        buckets = np.empty(cells_spanned(s.grid, 0.05), np.int64)
        mine = [grid_ball_count(s.position, s.start, s.grid, *x, 0.05 ** 2, buckets) for x in q]
    assert list(mine) == list(counts)


def test_kdtree_is_balanced_and_ordered():
    """Every split separates its subtree's points (left <= split <= right), leaves hold
    at most LEAF_SIZE points in contiguous ranges that cover every point once, and
    nearest() finds what knn(k=1) finds."""
    rng = np.random.default_rng(5)
    for n in (0, 1, 2, 5, 8, 9, 100, 1023, 1024, 1025):
        pts = rng.random((n, 3)).astype(np.float32)
        if n > 50:
            pts[: n // 3, 2] = 0.5  # many equal coordinates (a floor)
        t = KdTree(pts)
        assert sorted(t.order) == list(range(n))  # a permutation of the input
        np.testing.assert_array_equal(t.position, pts[t.order])
        inner = len(t.axis)
        assert len(t.leaf) == inner + 2 and t.leaf[0] == 0 and t.leaf[-1] == n
        sizes = np.diff(t.leaf)
        assert (sizes >= 0).all() and sizes.max(initial=0) <= LEAF_SIZE

        def leaf_range(i):
            a = b = i
            while a < inner:
                a, b = 2 * a + 1, 2 * b + 2
            return t.leaf[a - inner], t.leaf[b - inner + 1]

        for i in range(inner):
            ax, split = t.axis[i], t.split[i]
            la, lb = leaf_range(2 * i + 1)
            ra, rb = leaf_range(2 * i + 2)
            assert lb == ra  # the two subtrees' points are adjacent ranges
            assert (t.position[la:lb, ax] <= split).all()
            assert (t.position[ra:rb, ax] >= split).all()
        if n:
            q = rng.random((50, 3))
            for x in q:
                j, d2 = nearest(t.position, *t.nodes, *x, 0.3 ** 2)
                d, i = t.query(x[None], 1, 0.3)
                assert j == (i[0, 0] if i[0, 0] < n else -1)


def _plane(n, rng, z=0.0, nz=1.0):
    pos = np.c_[rng.random((n, 2)), np.full(n, z)].astype(np.float32)
    nrm = np.tile(np.float32([0, 0, nz]), (n, 1))
    d = rng.normal(size=(n, 3))
    d[:, 2] = -np.abs(d[:, 2]) * nz
    d /= np.linalg.norm(d, axis=1)[:, None]
    return Photons(pos, rng.random((n, 3)).astype(np.float32), d.astype(np.float32), nrm,
                   np.zeros(n, np.uint8))


def _join(*parts):
    return Photons(*(np.concatenate([getattr(a, f) for a in parts])
                     for f in ("position", "power", "direction", "normal", "kind")))


def _focus(n, at=(0.5, 0.5, 0.0)):
    z = np.tile(np.float32([0, 0, 1]), (n, 1))
    return Photons(np.tile(np.float32(at), (n, 1)), np.ones((n, 3), np.float32), -z, z,
                   np.zeros(n, np.uint8))


def _held(ph):
    """The photons with the values a map holds of them: the compact layout's
    (engine/photonlayout.py round_trip) unless photonlayout.COMPACT is off."""
    return photonlayout.round_trip(ph) if photonlayout.COMPACT else ph


def _as_float(ph):
    """A map's photons (either layout) as float32 arrays of the values the kernels read."""
    return Photons(ph.position, powers(ph.power, dtype=np.float32),
                   vectors(ph.direction, dtype=np.float32),
                   vectors(ph.normal, dtype=np.float32), ph.kind, ph.emitted,
                   ph.bounces, ph.surface, ph.blur_pdf)


def _assert_same(ref, pm, q, nq, radius, k, min_photons, est, r_floor):
    Er, Br = ref.irradiance(q, nq, radius, k, min_photons, est, return_boundary=True,
                            r_floor=r_floor)
    E, B = pm.irradiance(q, nq, radius, k, min_photons, est, return_boundary=True,
                         r_floor=r_floor)
    scale = max(np.abs(Er).max(), 1e-30)
    np.testing.assert_allclose(E, Er, rtol=1e-6, atol=1e-7 * scale)
    assert (B == Br).all(), f"{est}: {np.count_nonzero(B != Br)} boundary flags differ"
    E_only = pm.irradiance(q, nq, radius, k, min_photons, est, r_floor=r_floor)
    np.testing.assert_array_equal(E_only, E)
    return E


@pytest.mark.parametrize("structure", ["kdtree", "hashgrid"])
def test_estimators_match_the_numpy_reference(structure):
    rng = np.random.default_rng(3)
    floor = _plane(20000, rng)
    wall = _plane(20000, rng, z=0.001, nz=-1.0)  # a thin wall's far side, just above
    maps = {"floor": floor, "corner": _join(floor, wall), "far side only": wall,
            "focus": _join(_focus(3000), floor)}
    q = np.c_[rng.random((600, 2)), np.zeros(600)]
    q[:40, :2] = 0.5 + rng.normal(size=(40, 2)) * 1e-3  # on and around the focus
    nq = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    r_floor = rng.random(len(q)) * 0.01
    for name, ph in maps.items():
        ref = ReferencePhotonMap(_held(ph), 1)
        pm = PhotonMap(ph, 1, structure=structure, cell=0.05)
        for est in ESTIMATOR_CODES:
            for rf in (None, r_floor):
                for k, mp in ((64, 8), (16, 1)) if est == "knn_simpson" else ((64, 8),):
                    E = _assert_same(ref, pm, q, nq, 0.05, k, mp, est, rf)
                    if name == "far side only":
                        assert not E.any()  # light of the other side never leaks


@pytest.mark.parametrize("structure", ["kdtree", "hashgrid"])
def test_fixed_radius_estimators_match_the_reference_beyond_max_classic_k(structure):
    """More than MAX_CLASSIC_K photons in the radius (a dense plane; a focus on it): the
    classic estimate scales the gathered photons by all / gathered, the radius estimate
    narrows its Simpson kernel to their disc; the kernels as the numpy reference."""
    rng = np.random.default_rng(5)
    dense = _plane(200_000, rng)
    maps = {"dense": dense, "focus": _join(_focus(6000), dense)}
    q = np.c_[0.2 + 0.6 * rng.random((200, 2)), np.zeros(200)]
    q[:20, :2] = 0.5 + rng.normal(size=(20, 2)) * 1e-3
    nq = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    for ph in maps.values():
        ref = ReferencePhotonMap(_held(ph), 1)
        pm = PhotonMap(ph, 1, structure=structure, cell=0.05)
        for est in ("classic", "radius"):
            _assert_same(ref, pm, q, nq, 0.1, 64, 8, est, None)


def test_estimators_match_the_reference_on_a_real_scene():
    """The global and caustic maps of the glass-ball Cornell box, queried at photon
    positions (walls, corners, the ball's contact, the caustic) with their normals."""
    st = RenderSettings(photons=20000, caustic_photons=20000, final_gather=False, workers=1)
    ctx = prepare_context(cornell_box(width=32, height=24), st)
    _photon_pass(ctx, {}, None, None)
    rng = np.random.default_rng(0)
    checked = 0
    for pm, radius in ((ctx.global_map, ctx.global_radius),
                       (ctx.caustic_map, ctx.caustic_radius)):
        assert pm is not None and len(pm) > 500
        ph = pm.photons
        sel = rng.choice(len(ph), 800, replace=False)
        q = ph.position[sel].astype(np.float64) + rng.normal(size=(800, 3)) * radius * 0.1
        nq = vectors(ph.normal, sel)
        ref = ReferencePhotonMap(_as_float(ph), 1)
        for est in ESTIMATOR_CODES:
            E = _assert_same(ref, pm, q, nq, radius, st.k_nearest, st.min_photons, est,
                             np.full(len(q), radius * 0.02))
            checked += np.count_nonzero(E[:, 0])
    assert checked > 3000  # most queries found light


def test_gather_map_lookups_match_ckdtree():
    rng = np.random.default_rng(8)
    ph = _join(_plane(30000, rng), _plane(30000, rng, z=0.002, nz=-1.0))
    g = GatherMap(ph, 0.05, 32, 4, "knn_simpson", max_points=5000)
    q = np.c_[rng.random((3000, 2)), np.full(3000, 0.001)]
    up = np.tile([0.0, 0.0, 1.0], (3000, 1))
    E, B = g.lookup(q, up)
    # Reference: the nearest gather point facing the query's way, by cKDTree.
    ref = cKDTree(g.position)
    d, i = ref.query(q, k=64, distance_upper_bound=0.05)
    ok = (i < len(g.position)) & (g.normal[np.minimum(i, len(g.position) - 1)] @ up[0] > 0.7)
    first = np.argmax(ok, axis=1)
    has = ok.any(axis=1)
    chosen = i[np.arange(len(q)), first]
    np.testing.assert_array_equal(E[has], g.E[chosen[has]])
    np.testing.assert_array_equal(B[has], g.boundary[chosen[has]])
    assert not E[~has].any() and B[~has].all()


def test_nearest_facing_and_count_closer_match_brute_force():
    """The gather lookup's two extra queries: the nearest point whose normal agrees, and
    the capped count of nearer points (its rank test), against brute force."""
    rng = np.random.default_rng(12)
    pts = rng.random((5000, 3)).astype(np.float32)
    normal = rng.normal(size=(5000, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    t = KdTree(pts)
    nrm = np.ascontiguousarray(normal[t.order])
    pos = t.position.astype(np.float64)
    for q in rng.random((300, 3)):
        nq = rng.normal(size=3)
        nq /= np.linalg.norm(nq)
        d2 = ((pos - q) ** 2).sum(axis=1)
        facing = nrm @ nq > 0.7
        r2 = 0.15 ** 2
        j, dj = nearest_facing(t.position, *t.nodes, nrm, q[0], q[1], q[2], nq[0], nq[1],
                               nq[2], 0.7, r2)
        ok = facing & (d2 < r2)
        if ok.any():
            assert j == np.flatnonzero(ok)[np.argmin(d2[ok])] and dj == d2[j]
        else:
            assert j == -1
        for cap in (1, 8, 64, 10**6):
            want = min(int((d2 < r2).sum()), cap)
            assert count_closer(t.position, *t.nodes, q[0], q[1], q[2], r2, cap) == want


def test_searches_on_a_reused_stack_give_the_fresh_answers():
    """nearest_in, nearest_facing_in and count_closer_in (the gather lookup's searches on
    one traversal_stack per kernel call) against nearest, nearest_facing and count_closer
    (a fresh stack per search): the same index and squared distance bit for bit, and the
    same count, with one stack reused across all queries and kinds in turn (each search
    starts on what the last one left: deep, shallow or empty stacks). Points: a plane, a
    crease, duplicates (ties) and a sparse cloud; queries near and far, bounds from tiny
    to unbounded."""
    rng = np.random.default_rng(31)
    pts = np.concatenate([np.c_[rng.random((2000, 2)), np.zeros(2000)],
                          np.c_[np.full(800, 1.0), rng.random((800, 2))],
                          rng.random((200, 3)) * 2.0]).astype(np.float32)
    pts[-100:] = pts[:100]  # exact ties
    t = KdTree(pts)
    nrm = rng.normal(size=(len(pts), 3))  # per point in the tree's order
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    st_node, st_off = traversal_stack()
    st_off[:] = np.nan  # stale garbage: every search must start from its own root
    st_node[:] = -7
    q = np.concatenate([t.position[:50].astype(np.float64),
                        t.position[rng.integers(0, len(pts), 300)] + rng.normal(0, 0.02,
                                                                                 (300, 3)),
                        rng.random((100, 3)) * 4.0 - 1.0])
    found = facing = counted = 0
    for x in q:
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        for r2 in (1e-6, 0.01, 0.3, np.inf):
            a = nearest(t.position, *t.nodes, x[0], x[1], x[2], r2)
            b = nearest_in(t.position, *t.nodes, x[0], x[1], x[2], r2, st_node, st_off)
            assert a == b
            found += a[0] >= 0
            a = nearest_facing(t.position, *t.nodes, nrm, x[0], x[1], x[2], *n, 0.7, r2)
            b = nearest_facing_in(t.position, *t.nodes, nrm, x[0], x[1], x[2], *n, 0.7, r2,
                                  st_node, st_off)
            assert a == b
            facing += a[0] >= 0
            for cap in (1, 64):
                a = count_closer(t.position, *t.nodes, x[0], x[1], x[2], r2, cap)
                b = count_closer_in(t.position, *t.nodes, x[0], x[1], x[2], r2, cap,
                                    st_node, st_off)
                assert a == b
                counted += a
    assert found > 900 and facing > 500 and counted > 10000  # not vacuous


def test_neighbour_walk_gives_the_nearest_answer():
    """kdtree.nearest_walk (the gather lookup's search from the previous row's answer and
    neighbour lists, else the seeded tree) against brute force and kdtree.nearest: every
    query gets nearest's index, most are settled by the lists, and no query whose nearest
    distance is shared by two points (a tie: nearest keeps the one its traversal meets
    first) is settled by them. Points: two planes 1 mm apart, a crease (two walls
    meeting), a sparse cloud and exact duplicates (ties); the lists are checked against
    brute force too."""
    from engine.photonmap import morton_order
    rng = np.random.default_rng(21)
    parts = [np.c_[rng.random((3000, 2)), np.zeros(3000)],
             np.c_[rng.random((3000, 2)), np.full(3000, 0.001)],
             np.c_[np.full(1500, 1.0), rng.random((1500, 2))],
             np.c_[rng.random(1500), np.full(1500, 1.0), rng.random(1500)],
             rng.random((300, 3)) * [2.0, 2.0, 2.0] + [0.0, 0.0, 1.2]]
    pts = np.concatenate(parts).astype(np.float32)
    pts[-200:] = pts[:200]  # duplicates: exact ties at any query
    t = KdTree(pts)
    nbr, reach = t.neighbour_lists(k=8)
    pos = t.position.astype(np.float64)
    for j in rng.choice(len(pos), 300, replace=False):
        d2 = ((pos - pos[j]) ** 2).sum(axis=1)
        d2[j] = np.inf
        listed = nbr[j]
        assert j not in listed and len(set(listed)) == 8
        rest = np.setdiff1d(np.arange(len(pos)), np.append(listed, j))
        # (reach: float32 rounded down, within one float32 step: 2^-23 relative)
        assert np.sqrt(d2[rest].min()) > reach[j] >= np.sqrt(d2[listed].max()) * (1 - 2e-7)
        np.testing.assert_array_equal(np.sort(d2[listed]), np.sort(d2)[:8])
    # Queries on and near the surfaces, in Morton order (as lookups take them), plus
    # queries exactly at duplicated points and halfway between a point and its double.
    m = 4000
    q = pos[rng.integers(0, len(pos), m)] + rng.normal(0.0, 0.01, (m, 3))
    q[:100] = pos[:100]
    q = q[morton_order(q)]
    settled_rows = ties = 0
    rows = np.arange(m, dtype=np.int64)
    for r2 in (0.05 ** 2, np.inf):
        near = np.empty(m, np.int64)
        walked = np.zeros(m, bool)
        nearest_walk(t.position, *t.nodes, nbr, reach, q, rows, r2, 3, near, walked)
        for r, x in enumerate(q):
            d2 = ((pos - x) ** 2).sum(axis=1)  # the kernels' own float64 arithmetic
            want, _ = nearest(t.position, *t.nodes, x[0], x[1], x[2], r2)
            tie = (d2 == d2.min()).sum() > 1
            ties += tie
            if not tie:
                best = int(np.argmin(d2))
                assert want == (best if d2[best] < r2 else -1)
            assert near[r] == want  # settled by the lists or not: nearest's answer
            if walked[r]:
                settled_rows += 1
                assert not tie
        # The walk's two shortcuts (from g = the last answer): q within half of g's
        # nearest-neighbour distance is settled by g alone; q beyond JUMP_REACH x g's
        # reach goes to the tree without the lists. Both met here, both exact (above).
        prev = np.r_[-1, np.maximum.accumulate(np.where(near >= 0, np.arange(m), -1))[:-1]]
        has = prev >= 0
        g = near[prev[has]]
        dq = ((q[has] - pos[g]) ** 2).sum(axis=1)
        alone = 4.0 * dq * (1.0 + 1e-8) < ((pos[nbr[g, 0]] - pos[g]) ** 2).sum(axis=1)
        jump = dq > (JUMP_REACH * reach[g].astype(np.float64)) ** 2  # (the kernel's float64)
        assert walked[has][alone].all() and not walked[has][jump].any()
        assert alone.sum() > 20 and jump.sum() > 20  # not vacuous: 47 and 750 here
    assert ties >= 100 and settled_rows > 0.3 * 2 * m  # not vacuous: most settle


def test_listed_sphere_gives_the_knn_answer():
    """The estimators' heap-free k-NN (ball_d2 lists the sphere, nearest_first orders its
    m nearest) against brute force and against the heap search (kdtree.knn): the same
    points in increasing distance, the same float64 distances; on a surface, in a focus
    (many equal points: equal distances), and with clustered distances (a bucket fuller
    than BUCKET_MAX takes the quicksort), capped listings included."""
    rng = np.random.default_rng(14)
    flat = rng.random((6000, 3)).astype(np.float32)
    flat[:, 2] = 0.5
    focus = flat.copy()
    focus[:2000] = focus[0]  # 2000 equal points
    ring = flat.copy()  # points on a thin ring round (0.5, 0.5): clustered distances
    ang = rng.random(3000) * 2 * np.pi
    ring[:3000, 0] = 0.5 + 0.1 * np.cos(ang) * (1 + 1e-4 * rng.random(3000))
    ring[:3000, 1] = 0.5 + 0.1 * np.sin(ang)
    for pts in (flat, focus, ring):
        t = KdTree(pts)
        pos = t.position.astype(np.float64)
        queries = np.vstack([rng.random((150, 3)) * [1, 1, 0] + [0, 0, 0.5],
                             pos[[0, 1, 2]], [[0.5, 0.5, 0.5], [0.5, 0.5, 0.51]]])
        cap = 4096
        src_d2, src_idx = np.empty(cap), np.empty(cap, np.int64)
        d2, idx, hist = np.empty(cap), np.empty(cap, np.int64), np.empty(cap + 1, np.int64)
        kd2, kidx = np.empty(cap), np.empty(cap, np.int64)
        for q in queries:
            for r in (0.02, 0.06, 0.15):
                r2 = r * r
                dd = ((q - pos) ** 2).sum(axis=1)
                inside = np.flatnonzero(dd < r2)
                nb = ball_d2(t.position, *t.nodes, q[0], q[1], q[2], r2, src_d2, src_idx, cap)
                if len(inside) > cap:
                    assert nb == cap + 1
                    continue
                assert nb == len(inside)
                np.testing.assert_array_equal(np.sort(src_idx[:nb]), inside)
                np.testing.assert_array_equal(src_d2[:nb], dd[src_idx[:nb]])
                for m in (1, 8, 64, nb):
                    nearest_first(src_d2, src_idx, nb, m, r2, d2, idx, hist)
                    mm = min(m, nb)
                    want = np.sort(dd[inside])[:mm]
                    np.testing.assert_array_equal(d2[:mm], want)
                    np.testing.assert_array_equal(d2[:mm], dd[idx[:mm]])
                    # every entry kept once: the rest are the farther ones
                    np.testing.assert_array_equal(np.sort(idx[:nb]), inside)
                    assert mm == nb or d2[mm:nb].min() >= d2[mm - 1]
                    c = knn(t.position, *t.nodes, q[0], q[1], q[2], m, r2, kd2, kidx)
                    assert c == mm
                    np.testing.assert_array_equal(kd2[:c], d2[:mm])
                    if mm == nb or d2[mm] > d2[mm - 1]:  # no tie at the k-th: same set
                        np.testing.assert_array_equal(np.sort(kidx[:c]), np.sort(idx[:mm]))
    # The ring's query at its centre took the quicksort: its distances crowd buckets.
    dd = ((ring.astype(np.float64) - [0.5, 0.5, 0.5]) ** 2).sum(axis=1)
    dd = dd[dd < 0.15 ** 2]
    assert np.bincount((dd * len(dd) / 0.15 ** 2).astype(int)).max() > BUCKET_MAX


def test_gather_lookup_needs_the_facing_point_among_the_nearest():
    """A gather point facing the query's way counts only among the 8 x candidates nearest
    (as a k-NN query then a normal test would find it): a crowded opposite surface hides
    a farther facing point."""
    rng = np.random.default_rng(13)
    ph = _join(_plane(2000, rng), _plane(200000, rng, z=0.0005, nz=-1.0))
    g = GatherMap(ph, 0.2, 16, 2, "knn_simpson", max_points=50000)
    q = np.c_[rng.random((2000, 2)), np.full(2000, 0.0004)]
    up = np.tile([0.0, 0.0, 1.0], (2000, 1))
    for candidates in (1, 8):
        E, B = g.lookup(q, up, candidates=candidates)
        kq = 8 * candidates
        ref = cKDTree(g.position)
        d, i = ref.query(q, k=kq, distance_upper_bound=0.2)
        ok = (i < len(g.position)) & \
            (g.normal[np.minimum(i, len(g.position) - 1)] @ up[0] > 0.7)
        has = ok.any(axis=1)
        chosen = i[np.arange(len(q)), np.argmax(ok, axis=1)]
        assert 0.05 < has.mean() < 0.95  # both kinds of rows occur
        np.testing.assert_array_equal(E[has], g.E[chosen[has]])
        assert not E[~has].any() and B[~has].all()


def test_hidden_candidates_take_the_next_visible_one():
    """Rows whose gather point is hidden take the next visible agreeing one in distance
    order (GatherMap._next_visible tests them in batches of rays): the same answer as
    trying the candidates one by one. A floor cut by a comb of thin walls hides most
    candidates of many rows, several in a row."""
    from engine.accel import Accel
    from engine.photonmap import GATHER_AGREEMENT, _query_lift, _ray_ends
    rng = np.random.default_rng(31)
    quads = []
    for x in np.linspace(0.05, 0.95, 31):  # walls x = const, 0.2 m high
        quads.append([[x, -1, -0.1], [x, 2, -0.1], [x, 2, 0.2], [x, -1, 0.2]])
    v = np.array(quads, np.float32).reshape(-1, 3)
    f = np.concatenate([[[4 * i, 4 * i + 1, 4 * i + 2], [4 * i, 4 * i + 2, 4 * i + 3]]
                        for i in range(len(quads))]).astype(np.int32)
    acc = Accel(v, f, 1)
    try:
        g = GatherMap(_plane(60000, rng), 0.08, 32, 4, "knn_simpson", max_points=6000,
                      accel=acc)
        m = 3000
        q = np.c_[rng.random((m, 2)), np.full(m, 0.0005)]
        walls = np.linspace(0.05, 0.95, 31)
        q[::2, 0] = rng.choice(walls, m // 2) + rng.normal(0.0, 0.004, m // 2)  # beside one
        up = np.tile([0.0, 0.0, 1.0], (m, 1))
        E, B = g.lookup(q, up)
        # One by one: the agreeing points among the 64 nearest, the first whose ray
        # (the lookup's own ray writer) is clear.
        ref = cKDTree(g.position)
        d, idx = ref.query(q, k=64, distance_upper_bound=0.08)
        o32, d32, t32 = (np.empty((1, 3), np.float32), np.empty((1, 3), np.float32),
                         np.empty(1, np.float32))
        blocked = np.zeros(1, bool)
        no_lift = np.zeros(0)
        tried = np.zeros(m, int)
        for i in range(m):
            want = (np.zeros(3), True)
            for j in idx[i][idx[i] < len(g.position)]:
                if g.normal[j] @ up[i] <= GATHER_AGREEMENT:
                    continue
                ends = _ray_ends(*q[i], *up[i], _query_lift(no_lift, i, *q[i]), *g.position[j],
                                 *g.normal[j])
                o32[0], d32[0], t32[0] = ends[:3], ends[3:6], ends[6]
                tried[i] += 1
                if not acc.occluded_into(o32, d32, t32, blocked)[0]:
                    want = (g.E[j], g.boundary[j])
                    break
            np.testing.assert_array_equal(E[i], want[0])
            assert B[i] == want[1]
        assert (tried > 2).sum() > 100 and (tried > 5).sum() > 20  # several batches ran
    finally:
        acc.close()


def test_widening_has_a_fixed_memory_budget():
    """Issue 16: caustic queries beside a wall lit only on its far side find only the
    other surface's photons and would widen to MAX_WIDEN_K. Memory must not grow with
    rows x k (the numpy estimator allocated about rows x 4096 x 40 B per block:
    gigabytes), whether the sphere scan settles the row (fewer than SCAN_BUDGET photons in
    the sphere) or the full widening runs (more)."""
    rng = np.random.default_rng(2)
    far = _plane(600_000, rng, z=0.001, nz=-1.0)
    pm = PhotonMap(far, workers=2)
    for m, radius in ((20000, 0.08), (100, 0.2)):  # ~12,000 and ~75,000 in the sphere
        q = np.c_[0.2 + 0.6 * rng.random((m, 2)), np.zeros(m)]
        nq = np.tile([0.0, 0.0, 1.0], (m, 1))
        inside = len(far.position) * np.pi * radius ** 2
        assert (inside > SCAN_BUDGET) == (radius > 0.1)
        pm.irradiance(q[:2], nq[:2], radius, 64, 8, "knn_simpson")  # compiled already
        tracemalloc.start()
        E, B = pm.irradiance(q, nq, radius, 64, 8, "knn_simpson", return_boundary=True)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert not E.any() and B.all()
        # p, n copies and E (float64), boundary, the Morton row order (int64)
        inputs_outputs = m * (3 * 8 * 3 + 1 + 8)
        assert peak < inputs_outputs + (1 << 20), f"peak {peak / 1e6:.1f} MB"
    # The kernel's own scratch is fixed too: MAX_WIDEN_K neighbours, SCAN_BUDGET indices.
    assert MAX_WIDEN_K * 16 + SCAN_BUDGET * 8 <= (1 << 20)


def test_results_do_not_depend_on_workers():
    rng = np.random.default_rng(4)
    ph = _join(_plane(50000, rng), _plane(5000, rng, z=0.001, nz=-1.0), _focus(500))
    q = np.c_[rng.random((30000, 2)), np.zeros(30000)]
    nq = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    one = PhotonMap(ph, workers=1).irradiance(q, nq, 0.03, 64, 8, "knn_simpson",
                                               return_boundary=True)
    two = PhotonMap(ph, workers=2).irradiance(q, nq, 0.03, 64, 8, "knn_simpson",
                                               return_boundary=True)
    np.testing.assert_array_equal(one[0], two[0])
    np.testing.assert_array_equal(one[1], two[1])


def test_bad_structure_and_estimator_are_refused():
    ph = _focus(10)
    with pytest.raises(ValueError, match="structure"):
        PhotonMap(ph, structure="octree")
    with pytest.raises(ValueError, match="cell"):
        PhotonMap(ph, structure="hashgrid")
    with pytest.raises(ValueError, match="estimator"):
        PhotonMap(ph).irradiance(np.zeros((1, 3)), np.ones((1, 3)), 0.1, 8, 1, "gauss")
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        KdTree(np.zeros((4, 2)))


def test_unwritable_cache_dir_falls_back_to_a_writable_one():
    """numba raises at decoration time when it cannot write its cache; the engine must
    still load (a read-only or invalid NUMBA_CACHE_DIR)."""
    env = dict(os.environ, NUMBA_CACHE_DIR="/dev/null/not-a-dir")
    code = "import engine.jit as j, os; print(j.CACHE_DIR); print(os.access(j.CACHE_DIR, os.W_OK))"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    path, writable = out.stdout.split()
    assert not path.startswith("/dev/null") and writable == "True"


@pytest.mark.slow
def test_first_process_compiles_and_says_so_later_ones_load(tmp_path):
    """A fresh cache: needs_compile() is True and the progress callback hears the
    message; a second process finds the cache and compiles nothing."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    code = ("import engine.jit as j; seen = []; need = j.needs_compile(); "
            "j.ensure_compiled(lambda s, f, t: seen.append(t)); print(need, seen)")
    first = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=600)
    assert first.returncode == 0, first.stderr
    need, seen = first.stdout.strip().split(" ", 1)
    seen = ast.literal_eval(seen)  # the printed list of messages
    assert need == "True" and seen[0] == "Compiling render kernels (first render only)"
    # then one message per kernel module, counting up to all of them
    n = len(seen) - 1
    assert n >= 5 and seen[1:] == [f"Compiling kernels {i}/{n}, first render only"
                                   for i in range(1, n + 1)]
    assert max(len(t) for t in seen[1:]) <= 42  # the CLI's bar shows all of it
    second = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env,
                            capture_output=True, text=True, timeout=600)
    assert second.stdout.strip() == "False []", second.stderr


def test_morton_order_changes_no_answer():
    """Rows are visited in Morton order (photonmap.morton_order) for cache locality; each
    row's estimate and gather lookup must not depend on that order or on its neighbours."""
    from engine.photonmap import morton_order
    rng = np.random.default_rng(9)
    p = rng.random((500, 3))
    p[7] = np.nan  # a bad row still gets a place in the order
    order = morton_order(p)
    assert sorted(order) == list(range(len(p)))
    ph = _join(_plane(20000, rng), _plane(3000, rng, z=0.001, nz=-1.0))
    pm = PhotonMap(ph, workers=1)
    g = GatherMap(ph, 0.05, 32, 4, "knn_simpson", max_points=4000)
    q = np.c_[rng.random((2000, 2)), np.full(2000, 0.0005)]
    nq = np.tile([0.0, 0.0, 1.0], (2000, 1))
    shuffle = rng.permutation(len(q))
    for est in ("knn_simpson", "classic"):
        E, B = pm.irradiance(q, nq, 0.05, 32, 4, est, return_boundary=True)
        Es, Bs = pm.irradiance(q[shuffle], nq[shuffle], 0.05, 32, 4, est, return_boundary=True)
        np.testing.assert_array_equal(Es, E[shuffle])
        np.testing.assert_array_equal(Bs, B[shuffle])
    E, B = g.lookup(q, nq)
    Es, Bs = g.lookup(q[shuffle], nq[shuffle])
    np.testing.assert_array_equal(Es, E[shuffle])
    np.testing.assert_array_equal(Bs, B[shuffle])
    assert E.any()


def test_seeded_sphere_gives_the_unseeded_answer():
    """A k-NN row first lists a smaller sphere sized by the previous row's k-th distance
    (photonmap.SEED_GROWTH) and keeps it only when its k nearest are free of ties
    (kdtree.unique_nearest). A row estimated alone (one row a call: never seeded) must
    give the same bits as the same row among others: on a plane (most rows seeded), a
    lattice (equal distances everywhere: ties fall back), a thin wall's far side (rows
    that widen), and a focus (k photons on one point)."""
    rng = np.random.default_rng(21)
    g = np.stack(np.meshgrid(np.arange(120), np.arange(120)), -1).reshape(-1, 2) / 120.0
    lattice = _plane(len(g), rng)
    lattice.position[:, :2] = g
    maps = {"plane": _plane(20000, rng),
            "lattice": lattice,
            "thin wall": _join(_plane(20000, rng), _plane(20000, rng, z=0.001, nz=-1.0)),
            "focus": _join(_focus(3000), _plane(20000, rng))}
    for name, ph in maps.items():
        pm = PhotonMap(ph, workers=1)
        q = np.vstack([np.c_[rng.random((150, 2)), np.full(150, 0.0005)],
                       np.c_[g[::97] + 0.5 / 120.0, np.zeros(len(g[::97]))],  # lattice ties
                       np.c_[g[::89], np.zeros(len(g[::89]))],
                       [[0.5, 0.5, 0.0], [0.5, 0.5, 0.0004]]])
        nq = np.tile([0.0, 0.0, 1.0], (len(q), 1))
        for est, k in (("knn_simpson", 32), ("knn_cone", 16), ("knn_simpson", 64)):
            E, B = pm.irradiance(q, nq, 0.05, k, 4, est, return_boundary=True)
            assert E.any(), name
            for i in range(len(q)):
                Ei, Bi = pm.irradiance(q[i:i + 1], nq[i:i + 1], 0.05, k, 4, est,
                                       return_boundary=True)
                np.testing.assert_array_equal(Ei[0], E[i], err_msg=f"{name} {est} row {i}")
                assert Bi[0] == B[i], f"{name} {est} row {i}"


def test_block_candidates_give_the_tree_answer():
    """Rows in Morton order are taken in blocks (photonmap.CAND_ROWS rows within
    CAND_SPAN x the radius) that list their spheres from one kd-tree search's candidates
    (photonmap._block_candidates); a row estimated alone (one row a call: a block too
    small, the tree) must give the same bits: sparse photons (a caustic's few photons a
    sphere), a lattice (equal distances: the tree's listing decides), a thin wall's far
    side (rows that widen), a focus (k photons on one point), rows beside no photon and a
    dense plane (every block of search spheres overflows: blocks of seeded spheres,
    SEED_REACH, list the seeded rows' spheres). The candidate path is taken (not vacuous)
    and so is its fall-back (a block with more than CAND_CAP candidates), and on the
    dense plane a block of seeded spheres holds candidates where one of search spheres
    overflows."""
    from engine.photonmap import (CAND_CAP, CAND_SPAN, SEED_GROWTH, SEED_REACH, SEED_SPAN,
                                  _block_candidates, morton_order)
    rng = np.random.default_rng(23)
    g = np.stack(np.meshgrid(np.arange(120), np.arange(120)), -1).reshape(-1, 2) / 120.0
    lattice = _plane(len(g), rng)
    lattice.position[:, :2] = g
    sparse = _plane(2000, rng)
    sparse.position[:, 0] *= 0.5  # x > 0.5: no photon
    maps = {"sparse": sparse, "lattice": lattice,
            "thin wall": _join(_plane(20000, rng), _plane(20000, rng, z=0.001, nz=-1.0)),
            "focus": _join(_focus(3000), _plane(20000, rng)),
            "dense": _plane(300000, rng)}
    # Clusters of rows (a pixel's samples: far closer than the radius), one beside the
    # focus, one on lattice points (ties), others anywhere (x > 0.5: no sparse photon).
    centres = np.vstack([rng.random((12, 2)), [[0.5, 0.5]], [[0.25, 0.75]], [[0.8, 0.3]]])
    q = np.vstack([np.c_[c + rng.normal(scale=0.002, size=(24, 2)), np.full(24, 0.0005)]
                   for c in centres] + [np.c_[g[::97][:20], np.zeros(20)]])
    nq = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    radius = 0.05
    taken = {"candidates": 0, "fall-back": 0}
    for name, ph in maps.items():
        pm = PhotonMap(ph, workers=1)
        t = pm.tree
        order = morton_order(q)
        cand = np.empty(CAND_CAP + 1, np.int64)
        xyz = [np.empty(CAND_CAP + 1) for _ in range(3)]
        r = 0
        while r < len(order):
            e, nc = _block_candidates(t.position, t.nodes, q, order, r, radius, CAND_SPAN,
                                      cand, *xyz, True)
            taken["candidates" if nc >= 0 else "fall-back"] += e - r
            r = e
        if name == "dense":
            # A seeded sphere of k = 64 holds ~1.44^1.5 x 64 photons (the plane's density
            # times its area), the search sphere ~2,400: candidates only for the seeds.
            seed_r = SEED_REACH * math.sqrt(SEED_GROWTH * 64 / (300000 * math.pi))
            seeds = 0
            for r in range(len(order)):
                e, nc = _block_candidates(t.position, t.nodes, q, order, r, radius,
                                          CAND_SPAN, cand, *xyz, True)
                assert nc < 0
                es, ns = _block_candidates(t.position, t.nodes, q, order, r, seed_r,
                                           SEED_SPAN, cand, *xyz, True)
                assert ns <= CAND_CAP
                seeds += ns > 0
            assert seeds > len(q) // 4, seeds
        for est, k in (("knn_simpson", 32), ("knn_cone", 16), ("knn_simpson", 64)):
            E, B = pm.irradiance(q, nq, radius, k, 1, est, return_boundary=True,
                                 r_floor=np.full(len(q), 0.002))
            assert E.any(), name
            for i in range(len(q)):
                Ei, Bi = pm.irradiance(q[i:i + 1], nq[i:i + 1], radius, k, 1, est,
                                       return_boundary=True, r_floor=np.full(1, 0.002))
                np.testing.assert_array_equal(Ei[0], E[i], err_msg=f"{name} {est} row {i}")
                assert Bi[0] == B[i], f"{name} {est} row {i}"
    assert taken["candidates"] > len(q) and taken["fall-back"] > 0, taken


def test_unique_nearest_refuses_ties():
    d2 = np.array([1.0, 2.0, 3.0, 5.0, 4.0])
    assert unique_nearest(d2, 5, 3)
    assert not unique_nearest(d2, 5, 6)
    assert not unique_nearest(np.array([1.0, 1.0, 3.0]), 3, 2)  # a tie inside
    assert not unique_nearest(np.array([1.0, 2.0, 2.0]), 3, 2)  # a tie at the k-th
    assert unique_nearest(np.array([1.0, 2.0, 2.0]), 3, 1)


def test_widening_lists_the_heap_answer_bitwise():
    """A widening k-NN row's listed sphere (photonmap._widen_listed: distances listed, then
    nearest_first) gives the bits the heap gave: fed the same ball scan, the same d2 /
    idx in the same order as the heap over the scan (nb <= widest) or as kdtree.knn
    (nb > widest), on a surface with piles of equal points (equal distances, ordered by
    the heap's insertion order: those rows keep the heap, or return -1 for the caller's
    kdtree.knn). Every branch is taken (not vacuous)."""
    rng = np.random.default_rng(19)
    pts = rng.random((5000, 3)).astype(np.float32)
    pts[:, 2] = 0.5
    for c in range(40):  # 40 piles of 12 equal points: ties at any distance
        pts[100 + 12 * c:112 + 12 * c] = pts[100 + 12 * c]
    pts[3000:3300] = pts[2999]  # a focus: 301 equal points
    t = KdTree(pts)
    pos = t.position
    posd = pos.astype(np.float64)
    queries = np.vstack([rng.random((60, 3)) * [1, 1, 0] + [0, 0, 0.5],
                         posd[rng.integers(0, len(pos), 30)]])
    big = 8192
    scan = np.empty(big + 1, np.int64)
    src_d2, hist = np.empty(1024), np.empty(1024 + 1, np.int64)  # >= widest
    d2, idx = np.empty(big), np.empty(big, np.int64)
    hd2, hidx = np.empty(big), np.empty(big, np.int64)
    taken = dict(sorted_small=0, sorted_big=0, heap_ties=0, knn_ties=0)
    for q in queries:
        for r in (0.03, 0.08, 0.2):
            r2 = r * r
            nb = ball(pos, *t.nodes, q[0], q[1], q[2], r2, scan, big)
            assert nb <= big
            order = scan[:nb].copy()
            for widest in (16, 128, 1024):
                dx, dy, dz = q[0] - posd[order, 0], q[1] - posd[order, 1], q[2] - posd[order, 2]
                dd = dx * dx + dy * dy + dz * dz  # as the kernels compute them
                if nb <= widest:  # the estimator's heap over the scan, as before
                    want = 0
                    for ph, e in zip(order, dd):
                        if e < r2:
                            want = heap_insert(hd2, hidx, want, widest, e, ph)
                    heap_sort(hd2, hidx, want, widest)
                else:
                    want = knn(pos, *t.nodes, q[0], q[1], q[2], widest, r2, hd2, hidx)
                scan[:nb] = order
                got = _widen_listed(pos, scan, nb, q[0], q[1], q[2], r2, widest, src_d2, hist,
                                    d2, idx)
                near = np.sort(dd[dd < r2])[:widest + 1]  # the widest nearest and the next
                tie = (np.diff(near) == 0).any()
                if got < 0:  # left to the caller's kdtree.knn: only where distances tie
                    assert nb > widest and tie
                    taken["knn_ties"] += 1
                    continue
                assert got == want
                np.testing.assert_array_equal(d2[:got], hd2[:want])
                np.testing.assert_array_equal(idx[:got], hidx[:want])
                if tie:
                    taken["heap_ties"] += 1
                else:
                    taken["sorted_small" if nb <= widest else "sorted_big"] += 1
    assert min(taken.values()) >= 5, taken


def test_widening_over_a_listed_sphere_sums_the_old_bits(monkeypatch):
    """A widening row whose sphere is listed (at most LIST_FACTOR k photons) orders only
    as far as it reads: the kq nearest of a step, and where the estimate reads the whole
    sphere, its accepted photons alone (docs/performance.md "secondary"). Its estimates,
    boundary flags and masked estimates are bitwise those of the path that orders the
    whole sphere and sums every photon of it (WIDEN_ORDER_AS_READ False: the path before).
    Both run as the kernel's Python function: IEEE arithmetic as written, where the
    compiled kernel may fuse a multiply-add (the same way on both paths; the captured
    renders' estimates and the films keep their bits). Corners (a thin wall's far side
    crowding a sparse floor), a map smaller than MAX_WIDEN_K (widest = P, whole-map
    spheres) and piles of equal points among the accepted ones (ties: the whole sphere
    ordered, as before)."""
    from engine import photonmap
    rng = np.random.default_rng(20)
    floor, wall = _plane(3000, rng), _plane(20000, rng, z=0.001, nz=-1.0)
    piles = _plane(3000, rng)
    for c in range(60):  # 60 piles of 6 equal floor photons: equal accepted distances
        piles.position[6 * c:6 * c + 6] = piles.position[6 * c]
    maps = {"corner": (_join(floor, wall), (0.06, 0.08)),
            "small": (_join(_plane(200, rng), _plane(200, rng, z=0.001, nz=-1.0)), (0.5, 1.5)),
            "piles": (_join(piles, wall), (0.06, 0.08))}
    m = 160
    q = np.c_[0.1 + 0.8 * rng.random((m, 2)), np.zeros(m)]
    nq = np.tile([0.0, 0.0, 1.0], (m, 1))
    r_floor = rng.random(m) * 0.002
    widened = 0
    for name, (ph, radii) in maps.items():
        pm = PhotonMap(ph, 1)
        masks = rng.random((2, len(ph))) < 0.5
        pos = pm.photons.position.astype(np.float64)
        ok = (vectors(pm.photons.normal)[:, 2] > 0.5) & (vectors(pm.photons.direction)[:, 2] < 0)
        for radius in radii:
            d2 = ((q[:, None, :] - pos[None]) ** 2).sum(axis=2)
            for i in range(m):
                near = np.flatnonzero(d2[i] < radius * radius)
                first = near[np.argsort(d2[i, near])][:64]
                widened += len(first) == 64 and ok[first].sum() < 32 and len(near) <= 512
            for est in ("knn_simpson", "knn_cone"):
                for k, mp in ((64, 8), (16, 1)):
                    args = (q, nq, radius, k, mp, est)
                    kw = dict(return_boundary=True, r_floor=r_floor, masks=masks)
                    with monkeypatch.context() as mpatch:
                        mpatch.setattr(photonmap, "_irradiance_rows",
                                       photonmap._irradiance_rows.py_func)
                        got = pm.irradiance(*args, **kw)
                        mpatch.setattr(photonmap, "WIDEN_ORDER_AS_READ", False)
                        want = pm.irradiance(*args, **kw)
                    for a, b in zip(got, want):
                        np.testing.assert_array_equal(a, b, f"{name} {radius} {est} {k}")
    assert widened > 150  # rows that widen over a listed sphere (not vacuous)
