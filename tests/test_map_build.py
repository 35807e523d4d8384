"""The photon map build (engine/kdtree.py build, engine/photonmap.py construction): the
tree built on several threads is the one built on one, and a map's arrays are its
photons permuted into the tree's order."""
import numpy as np
import pytest

from engine import kdtree
from engine import photonlayout
from engine.parallel import StopFlag, Cancelled
from engine.photonmap import PhotonMap, auto_radius
from engine.photons import Photons


def _points(n, seed=0):
    rng = np.random.default_rng(seed)
    p = rng.random((n, 3)).astype(np.float32)
    # A focused caustic: many equal coordinates (the three-way partition's case).
    p[: n // 8] = np.float32([0.25, 0.5, 0.75])
    return p


@pytest.mark.parametrize("n", [kdtree.PARALLEL_POINTS, kdtree.PARALLEL_POINTS * 3 + 7])
def test_threaded_build_is_the_serial_build(n):
    pts = _points(n)
    one = kdtree.KdTree(pts)
    for workers in (2, 3):
        many = kdtree.KdTree(pts, workers=workers)
        for name in ("order", "position", "axis", "split", "leaf", "bounds"):
            assert np.array_equal(getattr(one, name), getattr(many, name)), (workers, name)
    # The tree's order is a permutation and its positions are the points in it.
    assert np.array_equal(np.sort(one.order), np.arange(n))
    assert np.array_equal(one.position, pts[one.order])
    assert np.array_equal(one.bounds, np.concatenate([pts.min(0), pts.max(0)]).astype(float))


def test_threaded_build_answers_queries_like_a_brute_force_search():
    pts = _points(kdtree.PARALLEL_POINTS + 100, seed=1)
    tree = kdtree.KdTree(pts, workers=2)
    q = np.random.default_rng(2).random((50, 3))
    dist, idx = tree.query(q, 8, np.inf)
    brute = np.sort(np.linalg.norm(q[:, None, :] - pts[None, :, :].astype(float), axis=2), 1)
    assert np.allclose(dist, brute[:, :8], rtol=0, atol=1e-12)
    assert np.allclose(np.linalg.norm(tree.position[idx].astype(float) - q[:, None], axis=2),
                       dist, atol=1e-12)


def test_cancelled_threaded_build_raises():
    flag = StopFlag()
    flag.set()
    with pytest.raises(Cancelled):
        kdtree.KdTree(_points(kdtree.PARALLEL_POINTS), should_cancel=flag, workers=2)


def test_photon_map_holds_its_photons_in_tree_order():
    n = kdtree.PARALLEL_POINTS + 5
    rng = np.random.default_rng(3)
    ph = Photons(_points(n, 3), rng.random((n, 3)).astype(np.float32),
                 rng.random((n, 3)).astype(np.float32), rng.random((n, 3)).astype(np.float32),
                 rng.integers(0, 4, n).astype(np.uint8), emitted=n)
    for workers in (1, 2):
        pm = PhotonMap(ph, workers)
        order = kdtree.KdTree(ph.position).order
        # (in the map's layout: photonlayout.COMPACT's)
        held = ph.take(order)
        if photonlayout.COMPACT:
            photonlayout.compact(held)
        for name in ("position", "power", "direction", "normal", "kind"):
            assert np.array_equal(getattr(pm.photons, name), getattr(held, name)), name
        assert pm.photons.emitted == n
    # Photons.select: a mask and its rows give the same photons.
    mask = ph.kind == 2
    a, b = ph.select(mask), ph.select(np.flatnonzero(mask))
    for name in ("position", "power", "direction", "normal", "kind"):
        assert np.array_equal(getattr(a, name), getattr(ph, name)[mask])
        assert np.array_equal(getattr(a, name), getattr(b, name))


def test_auto_radius_with_a_maps_tree_is_the_radius_without():
    pts = _points(20_000, seed=4)
    pm = PhotonMap(Photons(pts, *(np.zeros((len(pts), 3), np.float32),) * 3,
                           np.zeros(len(pts), np.uint8)))
    own = auto_radius(4.0, len(pts), 32, 10.0, pts)
    assert auto_radius(4.0, len(pts), 32, 10.0, pts, pm.tree) == own
    assert auto_radius(4.0, len(pts), 32, 10.0, pts, workers=2) == own
    assert 0 < own < 1.0


def test_kdtree_build_polls_its_stop_flag_in_the_compiled_call():
    """One thread (no pool between the steps): the compiled build itself sees the flag."""
    flag = StopFlag()
    flag.set()
    with pytest.raises(Cancelled):
        kdtree.KdTree(_points(5000), should_cancel=flag)


def test_map_of_rows_with_power_scale_is_the_numpy_gather():
    """PhotonMap(rows=, power_scale=) holds photons.take(rows) in its tree's order, each
    power times its float32 scale (the GatherMap's estimating photons)."""
    n = 20_000
    rng = np.random.default_rng(7)
    ph = Photons(_points(n, 8), rng.random((n, 3)).astype(np.float32),
                 rng.random((n, 3)).astype(np.float32), rng.random((n, 3)).astype(np.float32),
                 rng.integers(0, 4, n).astype(np.uint8), emitted=n)
    rows = np.flatnonzero(rng.random(n) < 0.7)
    scale = (1.0 / (1.0 - rng.random(len(rows)) * 0.5)).astype(np.float32)
    pm = PhotonMap(ph, 1, rows=rows, power_scale=scale)
    order = kdtree.KdTree(ph.position[rows]).order
    source = rows[order]
    power = ph.power[source]
    power *= scale[order][:, None]
    # (the map's layout: photonlayout.COMPACT's, of the same float32 products)
    held = photonlayout.compact if photonlayout.COMPACT else (lambda x: x)
    assert np.array_equal(pm.photons.power, held(Photons(ph.position, power, ph.direction,
                                                         ph.normal, ph.kind)).power)
    for name in ("position", "direction", "normal", "kind"):
        want = getattr(ph, name)[source]
        if name in ("direction", "normal") and photonlayout.COMPACT:
            want = photonlayout.encode_vectors(want)
        assert np.array_equal(getattr(pm.photons, name), want), name
    assert pm.photons.emitted == n
