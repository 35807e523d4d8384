"""engine/mortontree.py: the Morton box tree's k-th nearest distances are the kd-tree's
(engine/kdtree.py knn) bit for bit, and a brute-force search's; morton_order sorts rows
by their Morton codes (stable)."""
import numpy as np
import pytest

from engine import kdtree, mortontree


def _points(n, seed):
    rng = np.random.default_rng(seed)
    p = rng.random((n, 3)).astype(np.float32)
    p[:, 2] *= np.float32(0.02)  # photons lie on surfaces: a thin slab
    p[: n // 8] = np.float32([0.25, 0.5, 0.75])  # a focused caustic: equal points
    if n > 50:
        p[7] = np.nan  # never near anything
        p[9] = np.float32([5.0, -3.0, 1e4])  # far outlier: the box's corner
    return p


@pytest.mark.parametrize("n", [1, 3, 9, 17, 200, 5000, 40_000])
def test_kth_distance_is_the_kd_trees(n):
    p = _points(n, n)
    rng = np.random.default_rng(1)
    # Every third point as a query, at most ~2,000 of them: the far outlier squeezes the
    # slab into a few Morton cells, so each query visits most points; the 40,000-point
    # tree (its build's stop polls every 16,384 points) with 13,334 queries took 8 CPU s.
    step = max(3, n // 2000)
    q = np.concatenate([p[::step].astype(np.float64), rng.random((30, 3)) * 3 - 1,
                        np.array([[np.nan, 0.0, 0.0], [1e30, 0.0, 0.0]])])
    kd = kdtree.KdTree(p)
    mt = mortontree.KthTree(p)
    for k in (1, 2, 8, 65):
        if k > n:
            continue
        want = kd.query(q, k, np.inf)[0][:, -1]
        got = mt.kth(q, k)
        assert np.array_equal(want, got, equal_nan=True), (n, k)


def test_kth_distance_against_brute_force():
    p = _points(3000, 5)
    q = np.random.default_rng(6).random((60, 3))
    d = np.sort(np.sqrt(((q[:, None, :] - p[None, :, :].astype(np.float64)) ** 2).sum(2)), 1)
    got = mortontree.KthTree(p).kth(q, 33)
    assert np.allclose(got, d[:, 32], rtol=1e-12, atol=0)
    # Fewer finite points than k: inf.
    assert np.all(np.isinf(mortontree.KthTree(p[:20]).kth(q, 21)))


def test_stopped_query_leaves_rows_unwritten():
    p = _points(1000, 2)
    stop = np.ones(1, np.uint8)
    assert np.all(np.isinf(mortontree.KthTree(p).kth(p[:5].astype(np.float64), 4, stop)))
    # A stopped build returns at once (the caller, photonmap.auto_radius, raises).
    assert len(mortontree.KthTree(p, stop)) == 0


def test_morton_order_is_a_stable_sort_of_the_codes():
    p = np.random.default_rng(3).random((5000, 3))
    p[::7] = p[3]  # equal codes keep their order
    p[11] = np.nan
    code = mortontree.morton_codes(p, np.zeros(1, np.uint8))[0]
    assert np.array_equal(mortontree.morton_order(p), np.argsort(code, kind="stable"))
    assert code[11] == 0 and code.max() < 1 << 30


@pytest.mark.parametrize("m", [0, 1, 2, 5000])
def test_radix_sort_returns_the_codes_in_their_stable_order(m):
    rng = np.random.default_rng(m)
    code = rng.integers(0, 1 << 30, m).astype(np.int64)
    code[::5] = code[:1] if m else code[::5]  # equal keys keep their order
    if m > 2:
        code[1] = (1 << 30) - 1  # every bit of all three passes
    order, keys = mortontree._radix_sort30(code, np.zeros(1, np.uint8))
    assert np.array_equal(order, np.argsort(code, kind="stable"))
    assert np.array_equal(keys, code[order])
    assert np.array_equal(mortontree._radix_argsort30(code, np.zeros(1, np.uint8)), order)


@pytest.mark.parametrize("count", [1, 2, 7, 100, 3000])
def test_select_value_is_the_sorted_arrays_entry(count):
    rng = np.random.default_rng(count)
    a = rng.random(count)
    a[::3] = a[0]  # many equal values (a focus)
    a[1::7] = np.inf
    want = np.sort(a)
    for m in sorted({1, min(2, count), count // 2 + 1, count}):
        b = a.copy()
        assert kdtree.select_value(b, count, m) == want[m - 1], (count, m)
        assert np.array_equal(np.sort(b), want)  # only reordered


@pytest.mark.parametrize("n", [1, 9, 200, 5000, 40_000])
def test_kd_trees_kth_is_its_query(n):
    """KdTree.kth (kth_d2_rows: the previous row's sphere listed, else knn) gives the
    k-NN query's last distance bit for bit, for queries on points, between them, on a
    pile of equal points, NaN and far away."""
    p = _points(n, n + 1)
    rng = np.random.default_rng(2)
    q = np.concatenate([p[::2].astype(np.float64), rng.random((40, 3)) * 3 - 1,
                        np.array([[np.nan, 0.0, 0.0], [1e30, 0.0, 0.0]]),
                        np.repeat(p[:1].astype(np.float64), 3, axis=0)])
    kd = kdtree.KdTree(p)
    for k in (1, 2, 8, 65, n + 1):
        if k > 65 and n > 200:
            continue  # query's (M, k) answer would not fit
        want = kd.query(q, k, np.inf)[0][:, -1]
        assert np.array_equal(kd.kth(q, k), want, equal_nan=True), (n, k)
