"""Gather lookups whose counts drop some of their level map's photons read the irradiance
of their usable photons alone at their gather point (gatherlevel44).

- GatherMap.counts_irradiance at a level's own counts is, bit for bit, that level's map
  (the keep map's E at (1, 1, 0, 0), the subset maps' at deeper levels), and at any
  counts the E of a map built to keep those counts' photons alone; asked again (its
  cache) or in another order, the same bits;
- integrator._chain_lookups: where the deep photons gather (a wall in a corner whose
  light is trapped: most of its power from photons of 3 scatters, the floor's from
  direct ones), a lookup past two glass bounces reads the wall's shallow photons alone,
  at the last level and, below the reroute share, at level 0. Before, the last level
  read the map scaled by the whole map's kept share (~1, from the floor's photons): 3x
  the wall's usable light; level 0 read the map whole.
- GatherMap.drop_bounds / chaincounts.may_drop: a point whose bound holds no photon reads
  E exactly at every counts the bound covers (the floor's direct photons: no lookup there
  runs counts_irradiance); the wall's deep photons set the bounds they fall in.
"""
from types import SimpleNamespace

import numpy as np

from engine.chaincounts import DROP_BOUND_EXTRA, DROP_BOUND_LEVELS, GatherCounts
from engine.integrator import MAX_GATHER_LEVEL, _chain_lookups
from engine.photonmap import GatherMap
from engine.photons import Photons
from engine.render import _drop_bound_masks

LIMITS = np.array([6, 1024, 1024, 1024], np.int64)
ARGS = (0.08, 32, 1, "knn_simpson")


def _corner(rng, n_floor=30000, n_wall=3000):
    """A floor (z = 0, 1 x 1 m, up) of direct photons of power 1, and a wall (x = 0,
    facing +x, 1 x 1 m) whose photons are half direct (power 0.02: 30 W/m^2) and half
    of 3 scatters, 2 of them diffuse (power 0.04: 60 W/m^2); the deep ones carry 0.4 % of
    the shot's power and 2/3 of the wall's."""
    pos = np.r_[np.c_[rng.random((n_floor, 2)), np.zeros(n_floor)],
                np.c_[np.zeros(n_wall), rng.random((n_wall, 2))]].astype(np.float32)
    m = len(pos)
    nrm = np.r_[np.tile([0.0, 0.0, 1.0], (n_floor, 1)),
                np.tile([1.0, 0.0, 0.0], (n_wall, 1))].astype(np.float32)
    d = rng.normal(size=(m, 3))
    dn = (d * nrm).sum(1)
    d -= (np.abs(dn) + dn + 0.05)[:, None] * nrm  # arriving from the front: d.n < 0
    d /= np.linalg.norm(d, axis=1)[:, None]
    deep = np.zeros(m, bool)
    deep[n_floor + n_wall // 2:] = True
    power = np.where(np.arange(m) < n_floor, 1.0, np.where(deep, 0.04, 0.02))
    bounces = np.zeros((m, 4), np.uint8)
    bounces[deep] = (3, 2, 0, 0)
    ph = Photons(pos, np.repeat(power[:, None], 3, 1).astype(np.float32),
                 d.astype(np.float32), nrm, np.full(m, 2, np.uint8), bounces=bounces)
    return ph, deep


def _maps(ph):
    """The render's level-0 map (keep) with its deeper levels' subsets and counts."""
    subsets = [ph.usable(LIMITS, camera=(lv + 1, lv + 1, 0, 0))
               for lv in range(1, MAX_GATHER_LEVEL + 1)]
    gathered = ph.usable(LIMITS, camera=(1, 1, 0, 0))
    bounds = _drop_bound_masks(ph, LIMITS, gathered, subsets, list(range(len(subsets))))
    return GatherMap(ph, *ARGS, max_points=4000, keep=gathered, subsets=subsets,
                     bounces=ph.bounces, drop_bounds=bounds)


def test_counts_irradiance_is_the_subset_maps_E():
    ph, _ = _corner(np.random.default_rng(3))
    g = _maps(ph)
    assert len(g.subset_maps) == MAX_GATHER_LEVEL
    every = np.arange(len(g.position))
    assert np.array_equal(g.counts_irradiance(every, LIMITS, (1, 1, 0, 0)), g.E)
    for lv, sub in enumerate(g.subset_maps, start=1):
        got = sub.counts_irradiance(every, LIMITS, (lv + 1, lv + 1, 0, 0))
        assert np.array_equal(got, sub.E)
    key = (5, 3, 1, 1)  # after two glass bounces at level 2: photons of <= 1 scatter
    kept = GatherMap(ph, *ARGS, max_points=4000, keep=ph.usable(LIMITS, camera=key))
    assert np.array_equal(kept.position, g.position)
    some = np.random.default_rng(1).permutation(every)[:500]
    assert np.array_equal(g.subset_maps[1].counts_irradiance(some, LIMITS, key),
                          kept.E[some])  # the views share one cache
    assert np.array_equal(g.counts_irradiance(every[::-1], LIMITS, key), kept.E[::-1])
    assert kept.E.sum() < g.E.sum()


def test_counts_irradiance_sparse_store_is_the_dense_maps_bits():
    """counts_irradiance keeps per count only the points asked (ascending, with their E):
    asked in overlapping, repeated, unordered pieces, and through two views, it answers
    the bits of a map built to keep that count's photons (its E at every point in one
    estimate pass), and holds no more points than were asked (mem45: a dense (P,3) +
    (P,) per count held 52 MB on Figure 6 for 11 k of 34 x 60 k points asked)."""
    ph, _ = _corner(np.random.default_rng(5))
    g = _maps(ph)
    assert getattr(g.estimating, "source", None) is None  # (its rows are not kept)
    key = (4, 2, 1, 1)
    dense = GatherMap(ph, *ARGS, max_points=4000, keep=ph.usable(LIMITS, camera=key)).E
    rng = np.random.default_rng(7)
    P = len(g.position)
    asked = []
    for view in (g, g.subset_maps[0], g, g.subset_maps[1]):
        pts = rng.integers(0, P, 300)
        pts = np.r_[pts, pts[:50], asked[-1][:40] if asked else []].astype(np.int64)
        assert np.array_equal(view.counts_irradiance(pts, LIMITS, key), dense[pts])
        asked.append(pts)
    bits, known, known_E = g.counts_cache[key]
    want = np.unique(np.concatenate(asked))
    assert np.array_equal(known, want) and known_E.shape == (len(want), 3)
    assert len(want) < P
    assert np.array_equal(known_E, dense[want])
    assert g.counts_irradiance(np.zeros(0, np.int64), LIMITS, key).shape == (0, 3)


def test_subset_irradiance_batches_the_counts_with_the_dense_maps_bits():
    """chaincounts.subset_irradiance asks every count of a lookup at once
    (GatherMap.counts_irradiance_many: one search, a mask per count, percost54): rows of
    four counts, some points asked under several counts, some known from an earlier ask,
    read the bits of maps built to keep each count's photons, and each count's store
    holds exactly the points asked under it."""
    from engine.chaincounts import subset_irradiance
    ph, _ = _corner(np.random.default_rng(5))
    g = _maps(ph)
    keys = [(4, 2, 1, 1), (5, 3, 1, 1), (3, 2, 0, 0), (2, 2, 0, 0)]
    dense = {key: GatherMap(ph, *ARGS, max_points=4000,
                            keep=ph.usable(LIMITS, camera=key)).E for key in keys}
    rng = np.random.default_rng(9)
    P = len(g.position)
    g.counts_irradiance(rng.integers(0, P, 100), LIMITS, keys[0])  # (known points)
    asked = {key: [g.counts_cache[keys[0]][1]] if key == keys[0] else [] for key in keys}
    for view in (g, g.subset_maps[0]):
        which = rng.integers(0, len(keys), 800)
        point = rng.integers(0, P, 800)
        point[:200] = point[200:400]  # (the same points under other counts)
        counts = np.array(keys, np.int64)[which]
        got = subset_irradiance(view, LIMITS, counts, point)
        want = np.array([dense[keys[w]][p] for w, p in zip(which, point)], np.float64)
        assert got.dtype == np.float64 and np.array_equal(got, want)
        for j, key in enumerate(keys):
            asked[key].append(point[which == j])
    for key in keys:
        _, known, known_E = g.counts_cache[key]
        assert np.array_equal(known, np.unique(np.concatenate(asked[key])))
        assert np.array_equal(known_E, dense[key][known])


def test_counts_irradiance_from_two_threads_reads_the_dense_maps_bits():
    """The camera pass's workers share a map's counts_cache (engine/parallel.py): two
    threads asking the same count at once, in overlapping pieces, each read the bits of
    the map built for that count; the store they leave holds only points asked, each
    with its own E (a store one thread overwrote loses points, never mixes them)."""
    import threading
    ph, _ = _corner(np.random.default_rng(5))
    g = _maps(ph)
    key = (4, 2, 1, 1)
    dense = GatherMap(ph, *ARGS, max_points=4000, keep=ph.usable(LIMITS, camera=key)).E
    P = len(g.position)
    asks = [np.random.default_rng(s).integers(0, P, (6, 150)) for s in (11, 12)]
    wrong, start = [], threading.Barrier(2)

    def ask(pieces, view):
        start.wait()
        for pts in pieces:
            if not np.array_equal(view.counts_irradiance(pts, LIMITS, key), dense[pts]):
                wrong.append(pts)
    threads = [threading.Thread(target=ask, args=(a, v))
               for a, v in zip(asks, (g, g.subset_maps[0]))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not wrong
    _, known, known_E = g.counts_cache[key]
    assert np.all(np.diff(known) > 0) and np.isin(known, np.concatenate(
        [a.ravel() for a in asks])).all()
    assert np.array_equal(known_E, dense[known])

def _wall_lookups(g, rng, n=400):
    """Lookups in the wall's interior: (Ey, boundary, point) of GatherMap.lookup."""
    p = np.c_[np.zeros(n), 0.25 + 0.5 * rng.random((n, 2))]
    nrm = np.tile([1.0, 0.0, 0.0], (n, 1))
    Ey, boundary, point = g.lookup(p, nrm, points=True)
    return Ey.copy(), boundary.copy(), point.copy()


def test_lookups_after_a_chain_read_their_usable_photons_where_they_lie():
    rng = np.random.default_rng(4)
    ph, deep = _corner(rng)
    g = _maps(ph)
    nc = np.ones(len(ph), bool)
    power = ph.power.astype(np.float64).sum(axis=1)
    counts = GatherCounts(ph.bounces[nc], power[nc], LIMITS, 0.005)
    ctx = SimpleNamespace(settings=SimpleNamespace(bounce_limits=LIMITS),
                          gather_counts=counts)
    assert power[deep].sum() / power.sum() < 0.005  # under the reroute share
    for level, regather, extra in ((MAX_GATHER_LEVEL, False, (2, 0, 1, 1)),
                                   (0, True, (4, 0, 2, 2))):
        gmap = g if level == 0 else g.subset_maps[level - 1]
        Ey, boundary, point = _wall_lookups(gmap, rng)
        found = (point >= 0) & ~boundary
        assert found.mean() > 0.9
        whole = Ey.copy()
        cnt = np.tile(np.array(extra, np.int64), (len(Ey), 1))
        cnt[::2] = 0  # every other row: no chain (the map as it is)
        lt = np.ones(len(Ey))
        _chain_lookups(ctx, level, cnt, Ey, boundary, lt, regather, gmap, point)
        assert not boundary[found].any()  # none sent to gather again
        assert np.array_equal(Ey[::2], whole[::2])
        # (counts total 5: photons of <= 1 scatter, the wall's direct ones)
        key = (level + 1 + extra[0], level + 1 + extra[1], extra[2], extra[3])
        kept = GatherMap(ph, *ARGS, max_points=4000, keep=ph.usable(LIMITS, camera=key))
        rows = np.flatnonzero(found & (np.arange(len(Ey)) % 2 == 1))
        assert len(rows) > 100
        assert np.array_equal(Ey[rows], kept.E[point[rows]])
        # The wall's direct photons alone: 30 W/m^2 (the map whole: 90; the k-NN
        # estimates of a third of a disc's photons read ~4 % low over the wall's points).
        np.testing.assert_allclose(Ey[rows].mean(axis=0), 30.0, rtol=0.15)
        np.testing.assert_allclose(whole[rows].mean(axis=0), 90.0, rtol=0.08)


def test_drop_bounds_skip_exactly_where_no_dropped_photon_lies():
    ph, _ = _corner(np.random.default_rng(5))
    g = _maps(ph)
    every = np.arange(len(g.position))
    wall = g.position[:, 0] < 1e-6
    assert 100 < wall.sum() < len(every) - 100
    assert set(g.drop_bounds) == {(lv, e) for lv in range(DROP_BOUND_LEVELS)
                                  for e in range(1, DROP_BOUND_EXTRA + 1)}
    for level in range(DROP_BOUND_LEVELS):
        gmap = g if level == 0 else g.subset_maps[level - 1]
        for extra in range(1, DROP_BOUND_EXTRA + 1):
            bound = g.drop_bounds[(level, extra)]
            # the deep photons (3 scatters, total limit 6) are dropped once
            # level + 1 + extra + 3 > 6, and lie on the wall alone
            assert not bound[~wall].any()
            assert bound[wall].mean() == (1.0 if level + extra > 2 else 0.0)
            key = (level + 1 + extra, level + 1, extra, extra)
            got = gmap.counts_irradiance(every, LIMITS, key)
            assert np.array_equal(got[~bound], gmap.E[~bound])
            assert (got[bound].sum(1) < gmap.E[bound].sum(1)).all()
    # _chain_lookups at level 0 on the floor, counts that drop the deep photons: E as it
    # is, no estimate run
    g = _maps(ph)
    n = 300
    rng = np.random.default_rng(6)
    p = np.c_[0.2 + 0.6 * rng.random((n, 2)), np.zeros(n)]
    gmap = g
    Ey, boundary, point = gmap.lookup(p, np.tile([0.0, 0.0, 1.0], (n, 1)), points=True)
    Ey, boundary, point = Ey.copy(), boundary.copy(), point.copy()
    assert (point >= 0).all()
    power = ph.power.astype(np.float64).sum(axis=1)
    ctx = SimpleNamespace(settings=SimpleNamespace(bounce_limits=LIMITS),
                          gather_counts=GatherCounts(ph.bounces, power, LIMITS, 0.005))
    whole = Ey.copy()
    cnt = np.tile(np.array((3, 0, 3, 3), np.int64), (n, 1))
    _chain_lookups(ctx, 0, cnt, Ey, boundary, np.ones(n), False, gmap, point)
    assert ctx.gather_counts.partial(0, cnt[:1] + [1, 1, 0, 0])[0]
    assert np.array_equal(Ey, whole)
    assert not gmap.counts_cache  # no lookup ran counts_irradiance
