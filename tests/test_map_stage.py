"""The map stage's shared work (engine/photonmap.py, engine/kdtree.py, engine/mortontree.py),
bit for bit against the code it replaced:
- one estimate pass with power masks (PhotonMap.irradiance masks=) gives each mask the
  bits of a separate pass over a map whose power array zeroes the other photons (the
  GatherMap subsets' former estimate per level), for every estimator, both structures,
  boundary flags, r_floor, a focus (the floored disc) and 1 / 2 workers;
- a GatherMap with keep and subsets holds, per level, the bits of a GatherMap built with
  that level's mask as its keep, and one boundary array for all of them.
"""
import os
import sys

import numpy as np
import pytest

from engine.photonmap import ESTIMATOR_CODES, GatherMap, PhotonMap
from engine.photons import Photons

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_photon_lookup import _focus, _join, _plane  # noqa: E402


def _scene(rng):
    # A lit floor, a thin wall's far side just above it (other-surface photons) and a
    # focus (k photons on a point: the floored disc).
    return _join(_plane(20000, rng), _plane(4000, rng, z=0.001, nz=-1.0), _focus(300))


def _zeroed(pm, mask):
    """The former subset estimate's map: pm with the photons outside mask at power 0."""
    view = PhotonMap.__new__(PhotonMap)
    view.__dict__.update(pm.__dict__)
    ph = pm.photons
    # (either layout: a compact map's RGBE row of zeros is a power of 0)
    power = (ph.power * mask[:, None]).astype(ph.power.dtype)
    view.photons = Photons(ph.position, power, ph.direction, ph.normal, ph.kind, ph.emitted)
    return view


@pytest.mark.parametrize("structure", ["kdtree", "hashgrid"])
@pytest.mark.parametrize("estimator", list(ESTIMATOR_CODES))
def test_masked_estimates_are_the_bits_of_separate_passes(structure, estimator):
    rng = np.random.default_rng(11)
    ph = _scene(rng)
    q = np.c_[rng.random((12000, 2)), np.zeros(12000)]
    q[:40] = (0.5, 0.5, 0.0)  # on the focus
    nq = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    r_floor = np.full(len(q), 2e-3)
    n = len(ph)
    masks = np.stack([rng.random(n) < 0.5, np.ones(n, bool), np.zeros(n, bool),
                      rng.random(n) < 0.05])
    for workers in (1, 2):
        pm = PhotonMap(ph, workers=workers, structure=structure, cell=0.03)
        E, B, masked = pm.irradiance(q, nq, 0.03, 32, 4, estimator, return_boundary=True,
                                     r_floor=r_floor, masks=masks)
        E0, B0 = pm.irradiance(q, nq, 0.03, 32, 4, estimator, return_boundary=True,
                               r_floor=r_floor)
        np.testing.assert_array_equal(E, E0)
        np.testing.assert_array_equal(B, B0)
        assert masked.shape == (len(masks), len(q), 3)
        for mask, got in zip(masks, masked):
            Em, Bm = _zeroed(pm, mask).irradiance(q, nq, 0.03, 32, 4, estimator,
                                                  return_boundary=True, r_floor=r_floor)
            assert Em.any() or not mask.any()
            np.testing.assert_array_equal(got, Em)
            np.testing.assert_array_equal(B, Bm)
        # Without boundary flags: (E, masked), the same bits.
        E1, masked1 = pm.irradiance(q, nq, 0.03, 32, 4, estimator, r_floor=r_floor,
                                    masks=masks)
        np.testing.assert_array_equal(E1, E)
        np.testing.assert_array_equal(masked1, masked)


def test_masks_of_the_wrong_shape_are_refused():
    pm = PhotonMap(_focus(10))
    with pytest.raises(ValueError, match="masks"):
        pm.irradiance(np.zeros((1, 3)), np.ones((1, 3)), 0.1, 8, 1, "knn_simpson",
                      masks=np.ones((2, 9), bool))
    # An empty query or map still returns the masked estimates (zero).
    E, masked = pm.irradiance(np.zeros((0, 3)), np.ones((0, 3)), 0.1, 8, 1, "knn_simpson",
                              masks=np.ones((2, 10), bool))
    assert E.shape == (0, 3) and masked.shape == (2, 0, 3)


@pytest.mark.parametrize("workers", [1, 2])
def test_gather_map_levels_are_the_bits_of_maps_keeping_their_mask(workers):
    """One pass for keep and every subset: each level's E is that of a GatherMap built
    with its mask as keep (the former estimate per level); keep=None reads the unmasked
    pass, and a mask keeping every photon gives its bits."""
    rng = np.random.default_rng(12)
    ph = _join(_plane(30000, rng), _plane(6000, rng, z=0.001, nz=-1.0))
    n = len(ph)
    keep = rng.random(n) < 0.9
    deeper = keep & (rng.random(n) < 0.7)
    deepest = deeper & (rng.random(n) < 0.5)
    args = (ph, 0.05, 32, 1, "knn_simpson")
    g = GatherMap(*args, workers=workers, keep=keep, subsets=[deeper, deepest],
                  max_points=5000)
    assert len(g.subset_maps) == 2
    for mask, got in zip([keep, deeper, deepest], [g] + g.subset_maps):
        alone = GatherMap(*args, workers=workers, keep=mask, max_points=5000)
        np.testing.assert_array_equal(got.E, alone.E)
        np.testing.assert_array_equal(got.boundary, alone.boundary)
        np.testing.assert_array_equal(got.position, alone.position)
        assert got.boundary is g.boundary and got.tree is g.tree
    whole = GatherMap(*args, workers=workers, max_points=5000)
    ones = GatherMap(*args, workers=workers, keep=np.ones(n, bool), max_points=5000)
    sub = GatherMap(*args, workers=workers, subsets=[keep], max_points=5000)
    np.testing.assert_array_equal(whole.E, ones.E)
    np.testing.assert_array_equal(sub.E, whole.E)
    np.testing.assert_array_equal(sub.subset_maps[0].E, g.E)


def _old_select(pts, perm, lo, hi, kth, ax):
    """kdtree._select before it served select_value too (the code it replaces)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        a, b, c = pts[lo, ax], pts[mid, ax], pts[hi - 1, ax]
        pivot = max(min(a, b), min(max(a, b), c))
        lt = lo
        i = lo
        gt = hi
        while i < gt:
            v = pts[i, ax]
            if v < pivot:
                pts[[i, lt]] = pts[[lt, i]]
                perm[[i, lt]] = perm[[lt, i]]
                lt += 1
                i += 1
            elif v > pivot:
                gt -= 1
                pts[[i, gt]] = pts[[gt, i]]
                perm[[i, gt]] = perm[[gt, i]]
            else:
                i += 1
        if kth < lt:
            hi = lt
        elif kth >= gt:
            lo = gt
        else:
            return


@pytest.mark.parametrize("n", [1, 2, 5, 64, 777])
def test_select_on_points_is_the_former_partition(n):
    """kdtree._select (one implementation for the build's points and select_value's
    values): the points and indices in the former order, bit for bit, with many ties."""
    from engine.kdtree import _select, select_value
    rng = np.random.default_rng(n)
    pts = rng.random((n, 3)).astype(np.float32)
    pts[: n // 3, 1] = np.float32(0.5)  # a focus's equal coordinates
    for kth, ax in ((n // 2, 0), (n - 1, 1), (0, 2), (n // 3, 1)):
        got, want = pts.copy(), pts.copy()
        gp, wp = np.arange(n), np.arange(n)
        _select(got, gp, 0, n, kth, ax)
        _old_select(want, wp, 0, n, kth, ax)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(gp, wp)
        # The values' form: the same pass on one coordinate, the same rank's value.
        vals = pts[:, ax].astype(np.float64)
        assert select_value(vals.copy(), n, kth + 1) == np.sort(vals)[kth] == want[kth, ax]


def test_box_tree_listing_is_the_brute_force_set():
    """mortontree._list_d2 (sharing the heap search's traversal, _next_leaf): the squared
    distances below the bound, as a set, or cap + 1 when more lie there."""
    from engine import mortontree
    rng = np.random.default_rng(3)
    p = rng.random((5000, 3)).astype(np.float32)
    p[:300] = np.float32([0.5, 0.5, 0.5])
    t = mortontree.KthTree(p)
    inner = (len(t.box) + 1) // 2 - 1
    st_node = np.empty(mortontree.STACK, np.int64)
    st_d2 = np.empty(mortontree.STACK)
    for q in [(0.5, 0.5, 0.5), (0.1, 0.9, 0.3), (2.0, 2.0, 2.0)]:
        d2 = ((p.astype(np.float64) - np.array(q)) ** 2).sum(1)
        for bound in (1e-3, 0.01, 0.05):
            want = np.sort(d2[d2 < bound])
            listed = np.empty(len(p) + 1)
            got = mortontree._list_d2(t.position, t.box, inner, len(p), *q, bound, listed,
                                      len(p), st_node, st_d2)
            np.testing.assert_array_equal(np.sort(listed[:got]), want)
            if len(want) > 1:
                assert mortontree._list_d2(t.position, t.box, inner, len(p), *q, bound,
                                           listed, len(want) - 1, st_node,
                                           st_d2) == len(want)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_lazy_gather_map_estimates_only_the_points_its_lookups_take(workers):
    """GatherMap(lazy=True) (the render's, fast46): lookups over a corner of the floor
    answer with the bits of the map that estimated every point at its build (E, boundary,
    the point, a subset level's E, the secondary share and the drop bounds at the points
    taken), having estimated only the points they took; complete() then holds every
    array of the eager map."""
    rng = np.random.default_rng(12)
    ph = _join(_plane(30000, rng), _plane(6000, rng, z=0.001, nz=-1.0))
    n = len(ph)
    keep = rng.random(n) < 0.9
    deeper = keep & (rng.random(n) < 0.7)
    second = rng.random(n) < 0.2
    bounds = {(0, 1): keep & ~deeper, (1, 1): np.zeros(n, bool)}
    args = (ph, 0.05, 32, 1, "knn_simpson")
    kw = dict(workers=workers, keep=keep, subsets=[deeper], secondary=[second],
              drop_bounds=bounds, max_points=5000)
    eager = GatherMap(*args, **kw)
    lazy = GatherMap(*args, lazy=True, **kw)
    assert eager._lazy is None and not lazy._lazy.known.any()
    q = np.c_[0.2 * rng.random((400, 2)), np.zeros(400)]
    nq = np.tile([0.0, 0.0, 1.0], (400, 1))
    want = eager.lookup(q, nq, points=True)
    got = lazy.lookup(q, nq, points=True)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    taken = np.unique(got[2][got[2] >= 0])
    assert len(taken) > 10
    assert np.array_equal(np.flatnonzero(lazy._lazy.known), taken)  # those alone
    assert len(taken) < 0.2 * len(lazy.position)
    # A level's view reads the shared arrays: its lookups' bits too (no point new here).
    for a, b in zip(lazy.subset_maps[0].lookup(q, nq), eager.subset_maps[0].lookup(q, nq)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(lazy.secondary_levels[0][taken],
                                  eager.secondary_levels[0][taken])
    for key in bounds:
        np.testing.assert_array_equal(lazy.drop_bounds[key][taken], eager.drop_bounds[key][taken])
    assert lazy.complete() is lazy and lazy._lazy.known.all()
    for a, b in ((lazy.E, eager.E), (lazy.boundary, eager.boundary),
                 (lazy.subset_maps[0].E, eager.subset_maps[0].E),
                 (lazy.secondary_levels[0], eager.secondary_levels[0])):
        np.testing.assert_array_equal(a, b)
    for key in bounds:
        np.testing.assert_array_equal(lazy.drop_bounds[key], eager.drop_bounds[key])
    assert eager.drop_bounds[(0, 1)].any() and lazy.subset_maps[0].boundary is lazy.boundary
