"""The gather map's narrow arrays (docs/performance.md "hdri52"):
- its levels (E, the subset maps' E, secondary_levels, counts_irradiance's answers) are
  float32: each the float64 estimate rounded to nearest (photonmap.LEVEL_DTYPE), so
  within 2^-24 of it, relative, and lazy and eager maps hold the same bits;
- its neighbour table (kdtree.neighbour_lists) is uint16 up to NARROW_NEIGHBOURS points
  and int32 above (a real table of 70 k points), the same entries either way; reach is
  float32 rounded down (never beyond the float64 distance, within one float32 step);
- lookups and the walk give the same answers, bit for bit, with either table.
"""
import numpy as np

from engine import kdtree, photonmap
from engine.kdtree import KdTree, nearest, nearest_walk, neighbour_dtype, reach32
from engine.photonmap import GatherMap, morton_order
from engine.photons import CAUSTIC_DIFFUSE, Photons

EPS32 = 2.0 ** -24  # float32's round-to-nearest bound, relative


def _floor_and_wall(rng, n=20000):
    """A floor and a wall meeting at a corner, a third of the photons CAUSTIC_DIFFUSE."""
    pos = np.r_[np.c_[rng.random((n, 2)), np.zeros(n)],
                np.c_[np.zeros(n // 2), rng.random((n // 2, 2))]].astype(np.float32)
    m = len(pos)
    nrm = np.r_[np.tile([0.0, 0.0, 1.0], (n, 1)),
                np.tile([1.0, 0.0, 0.0], (n // 2, 1))].astype(np.float32)
    d = rng.normal(size=(m, 3))
    dn = (d * nrm).sum(1)
    d -= (np.abs(dn) + dn + 0.05)[:, None] * nrm
    d /= np.linalg.norm(d, axis=1)[:, None]
    kind = np.where(rng.random(m) < 1 / 3, CAUSTIC_DIFFUSE, 2).astype(np.uint8)
    # powers over 12 decades: the rounding is relative at any scale
    power = (rng.random((m, 3)) * 10.0 ** rng.uniform(-6, 6, (m, 1))).astype(np.float32)
    return Photons(pos, power, d.astype(np.float32), nrm, kind)


def test_levels_are_the_float64_estimates_rounded_once(monkeypatch):
    rng = np.random.default_rng(52)
    ph = _floor_and_wall(rng)
    sec = ph.kind == CAUSTIC_DIFFUSE
    kw = dict(max_points=3000, subsets=[~sec], secondary=[sec])
    args = (ph, 0.05, 32, 1, "knn_simpson")
    g = GatherMap(*args, **kw)
    lazy = GatherMap(*args, lazy=True, **kw).complete()
    monkeypatch.setattr(photonmap, "LEVEL_DTYPE", np.float64)  # main's float64 levels
    wide = GatherMap(*args, **kw)
    pairs = [(g.E, wide.E), (g.subset_maps[0].E, wide.subset_maps[0].E),
             (g.secondary_levels[0], wide.secondary_levels[0])]
    for a, b in pairs:
        assert a.dtype == np.float32 and b.dtype == np.float64
        assert np.array_equal(a, b.astype(np.float32))  # rounded to nearest, once
        assert (np.abs(a - b) <= EPS32 * np.abs(b)).all()
        assert (b > 0).mean() > 0.5  # not vacuous
    for a, b in ((g.E, lazy.E), (g.subset_maps[0].E, lazy.subset_maps[0].E),
                 (g.secondary_levels[0], lazy.secondary_levels[0]), (g.boundary, lazy.boundary)):
        assert np.array_equal(a, b)  # lazy and eager: the same bits
    assert np.array_equal(g.boundary, wide.boundary)
    # Rounding is monotone: a share never exceeds the level it is part of (every photon's).
    assert (wide.secondary_levels[0] <= wide.E).all() and (g.secondary_levels[0] <= g.E).all()


def test_neighbour_table_is_uint16_to_the_limit_and_int32_above(monkeypatch):
    rng = np.random.default_rng(7)
    pts = np.r_[np.c_[rng.random((6000, 2)), np.zeros(6000)],
                rng.random((2000, 3))].astype(np.float32)
    pts[-100:] = pts[:100]  # exact duplicates: ties the lists must not settle
    t = KdTree(pts)
    nbr, reach = t.neighbour_lists(k=8)
    assert nbr.dtype == np.uint16 and reach.dtype == np.float32
    assert neighbour_dtype(kdtree.NARROW_NEIGHBOURS) == np.uint16
    assert neighbour_dtype(kdtree.NARROW_NEIGHBOURS + 1) == np.int32
    monkeypatch.setattr(kdtree, "NARROW_NEIGHBOURS", 1000)  # the int32 path, same points
    wide, wide_reach = t.neighbour_lists(k=8)
    assert wide.dtype == np.int32
    assert np.array_equal(wide, nbr) and np.array_equal(wide_reach, reach)
    # reach: the kernel's float64 distance rounded down, within one float32 step.
    r64 = np.empty(len(pts))
    kdtree.neighbour_lists(t.position, *t.nodes, 0, len(pts), np.empty((len(pts), 8),
                                                                         np.int32), r64)
    assert (reach.astype(np.float64) <= r64).all()
    assert (np.nextafter(reach, np.float32(np.inf)).astype(np.float64) > r64).all()
    assert np.array_equal(reach32(np.array([np.inf, 0.0])), np.float32([np.inf, 0.0]))
    # The walk with either table: nearest's answer for every query, the same rows settled.
    m = 3000
    pos = t.position.astype(np.float64)
    q = pos[rng.integers(0, len(pos), m)] + rng.normal(0.0, 0.01, (m, 3))
    q = q[morton_order(q)]
    rows = np.arange(m, dtype=np.int64)
    got = []
    for table in (nbr, wide):
        near, walked = np.empty(m, np.int64), np.zeros(m, bool)
        nearest_walk(t.position, *t.nodes, table, reach, q, rows, np.inf, 3, near, walked)
        got.append((near, walked))
    assert np.array_equal(got[0][0], got[1][0]) and np.array_equal(got[0][1], got[1][1])
    want = [nearest(t.position, *t.nodes, x[0], x[1], x[2], np.inf)[0] for x in q]
    assert np.array_equal(got[0][0], want)
    assert got[0][1].mean() > 0.3  # not vacuous: 44 % of the rows settled by the lists


def test_a_table_above_the_limit_indexes_every_point():
    """70 k points: int32 entries past 65535, each row its k nearest (brute force)."""
    rng = np.random.default_rng(11)
    n = kdtree.NARROW_NEIGHBOURS + 4464
    pts = rng.random((n, 3)).astype(np.float32)
    t = KdTree(pts)
    nbr, reach = t.neighbour_lists(k=6)
    assert nbr.dtype == np.int32 and nbr.max() > np.iinfo(np.uint16).max
    pos = t.position.astype(np.float64)
    for j in np.r_[rng.choice(n, 40, replace=False), n - 1]:
        d2 = ((pos - pos[j]) ** 2).sum(axis=1)
        d2[j] = np.inf
        assert np.array_equal(np.sort(d2[nbr[j]]), np.sort(d2)[:6])
        assert reach[j] <= np.sqrt(np.sort(d2)[5])


def test_lookups_read_the_same_with_either_table(monkeypatch):
    rng = np.random.default_rng(5)
    ph = _floor_and_wall(rng, 12000)
    args = (ph, 0.05, 32, 1, "knn_simpson")
    g = GatherMap(*args, max_points=2000)
    monkeypatch.setattr(kdtree, "NARROW_NEIGHBOURS", 100)
    w = GatherMap(*args, max_points=2000)
    assert g.neighbours[0].dtype == np.uint16 and w.neighbours[0].dtype == np.int32
    assert np.array_equal(g.E, w.E)
    m = 2000
    p = np.c_[rng.random((m, 2)), np.zeros(m)]
    n = np.tile([0.0, 0.0, 1.0], (m, 1))
    a, b = g.lookup(p, n, points=True), w.lookup(p, n, points=True)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    assert a[0].dtype == np.float64 and (a[2] >= 0).mean() > 0.9  # not vacuous
    assert np.array_equal(a[0][a[2] >= 0], g.E[a[2][a[2] >= 0]].astype(np.float64))
