"""The bytes a photon pass' maps hold (engine/resources.py held_bytes, the photon pass'
stats["photon_bytes"]; issue 13's "<= 64 bytes per stored photon", docs/performance.md
"perf47"), and two arrays the maps no longer keep:
- held_bytes counts each buffer once (views, subset maps and serial views share them),
  and not Embree's scene;
- the photon pass' photon_bytes is what its maps hold, a lazy gather map's masks, arrays
  to fill and estimating photons included;
- a gather map keeps no (P,3) estimate of its drop bounds' masks (only their (P,) flags),
  eager or lazy;
- GatherCounts keeps its photons' count classes and their power's sums, no array a
  photon (review53; 1 B a photon of class indices and 1-8 B of power before);
and the lossless cuts of docs/performance.md "mem48":
- masks as bits (pack_masks: 1/8 B a photon and mask) give the estimates of the bool
  masks, bit for bit; a lazy gather map keeps its masks so, and counts_irradiance's
  bits are bounce_usable's rows;
- the gather points' position (the tree's) and normal are float32, and the rays to them
  the float64 copies' bits;
- a kept mask without an estimating photon of nonzero power keeps no level of its own
  (one shared zero array: the zeros the estimate gives);
- a map's per-key usable masks (chaincounts) are kept as bits.
"""
import importlib
import os
import sys

import numpy as np
import pytest

from engine import RenderSettings
from engine import photonkernels as pk
from engine.api import cornell_box
from engine.chaincounts import GatherCounts
from engine.photonmap import GatherMap, PhotonMap, _list_rays, pack_masks, unpack_masks
from engine.render import prepare_context, shoot_photons
from engine.resources import held_bytes

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_photon_lookup import _join, _plane  # noqa: E402

render_mod = importlib.import_module("engine.render")  # (engine.render is also a function)


def _base(a):
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a


def test_held_bytes_counts_each_buffer_once():
    rng = np.random.default_rng(3)
    ph = _plane(5000, rng)
    pm = PhotonMap(ph)
    own = held_bytes(pm)
    t = pm.tree
    arrays = [pm.photons.position, pm.photons.power, pm.photons.direction, pm.photons.normal,
              pm.photons.kind, t.axis, t.split, t.leaf, t.bounds]
    assert pm.photons.position is t.position  # (one buffer, counted once)
    assert own == sum(a.nbytes for a in arrays)
    # Views, a serial view, a tuple and a dict of the same map add nothing.
    assert held_bytes(pm, pm.serial(), (pm, [pm.photons.power[:10]]),
                      {"a": pm.photons.position[::2]}) == own
    # A view keeps its whole base alive: counted whole.
    big = np.zeros((1000, 3))
    assert held_bytes(big[:1]) == big.nbytes
    # Embree's scene (a gather map's accel) is not the map's memory.
    g = GatherMap(ph, 0.05, 16, 1, "knn_simpson", max_points=1000, accel=object())
    assert held_bytes(g) == held_bytes(g.__dict__ | {"accel": None})


def _gather_map(lazy, rng):
    ph = _join(_plane(20000, rng), _plane(4000, rng, z=0.001, nz=-1.0))
    n = len(ph)
    keep = rng.random(n) < 0.9
    deeper = keep & (rng.random(n) < 0.7)
    second = rng.random(n) < 0.2
    bounds = {(0, 1): keep & ~deeper, (0, 2): keep & ~second, (1, 1): np.zeros(n, bool)}
    return GatherMap(ph, 0.05, 32, 1, "knn_simpson", keep=keep, subsets=[deeper],
                     secondary=[second], drop_bounds=bounds, max_points=4000, lazy=lazy)


def test_gather_maps_keep_no_estimate_of_their_drop_bounds():
    """keep, one subset and one secondary mask: three (P,3) levels kept; the two drop
    bounds with photons add their (P,) flags alone (tests/test_map_stage.py checks their
    bits against the eager map's)."""
    for lazy in (False, True):
        g = _gather_map(lazy, np.random.default_rng(5))
        P = len(g.position)
        if lazy:
            assert g._lazy.levels.shape == (3, P, 3)
            assert g._lazy.E is None  # (every photon's estimate: no view reads it, keep's)
            assert getattr(g._lazy.estimating, "source", None) is None  # (its rows: used)
            # the masks' estimates still come whole, kept as bits
            assert g._lazy.chosen.shape == (5, (len(g._lazy.estimating) + 7) // 8)
            assert g._lazy.chosen.dtype == np.uint8
            g.complete()
        for level in (g.E, g.subset_maps[0].E, g.secondary_levels[0]):
            assert _base(level).shape[0] * _base(level).shape[1] <= 3 * P
        assert g.drop_bounds[(0, 1)].any() and g.drop_bounds[(0, 2)].any()
        assert not g.drop_bounds[(1, 1)].any()


def test_gather_counts_keep_classes_not_counts():
    rng = np.random.default_rng(4)
    n = 20000
    bounces = rng.integers(0, 5, (n, 4)).astype(np.uint8)
    bounces[::97] = pk.BOUNCE_SATURATED
    power = rng.random(n)
    lim = np.array([6, 4, 4, 4])
    g = GatherCounts(bounces, power, lim, 0.005)
    # (626 classes here, each its count row and its power's exact partial sums; no
    # array a photon: review53)
    assert len(g.rows) == len(g.sums) == len(np.unique(bounces, axis=0))
    held = held_bytes(g)
    assert held <= g.rows.nbytes + g.sums.nbytes + g.limits.nbytes + 4096


def test_the_photon_pass_reports_what_its_maps_hold(monkeypatch):
    """stats["photon_bytes"]: the maps' bytes, a lazy gather map's estimating photons,
    masks and arrays to fill among them (they were not counted: the shots' arrays were,
    shot_bytes now)."""
    monkeypatch.setattr(render_mod, "gather_points_lazy", lambda *a: True)
    ctx = prepare_context(cornell_box(16, 12), RenderSettings(
        photons=20_000, caustic_photons=5_000, seed=1, workers=1))
    try:
        stats = {}
        shots = shoot_photons(ctx, stats)
    finally:
        ctx.accel.close()
    g = ctx.gather_map
    assert g._lazy is not None and g.estimating is not None
    maps = [getattr(ctx, f) for f in render_mod.MAP_FIELDS]
    assert stats["photon_bytes"] == held_bytes(*maps)
    assert stats["shot_bytes"] == sum(ph.nbytes for ph in shots)
    lz = g._lazy
    parts = (g.estimating.nbytes + (0 if lz.E is None else lz.E.nbytes) + lz.boundary.nbytes
             + lz.known.nbytes
             + (0 if lz.chosen is None else lz.chosen.nbytes)
             + (0 if lz.levels is None else lz.levels.nbytes) + g.position.nbytes
             + g.normal.nbytes + sum(a.nbytes for a in g.neighbours) + ctx.caustic_map.nbytes)
    assert lz.chosen is not None
    assert stats["photon_bytes"] >= parts


def test_the_photon_hit_view_keeps_only_its_dots():
    """A render picks the photon-hit view's dots before its camera pass (the shots' arrays
    are let go): at most photon_hit_budget of the photons, and the view drawn from them is
    the view of the whole shots."""
    ctx = prepare_context(cornell_box(32, 24), RenderSettings(
        photons=20_000, caustic_photons=5_000, seed=1, workers=1))
    try:
        shots = [(ph.position, ph.kind) for ph in shoot_photons(ctx, {})]
        n = sum(len(p) for p, _ in shots)
        region = (0, 0, 32, 24)
        fraction, dots = render_mod._photon_hit_dots(ctx, shots, region)
        assert dots is not None and 0.0 < fraction < 1.0
        assert len(dots[0]) <= render_mod.photon_hit_budget(n, 32, 24) < n / 10
        assert all(len(a) == len(dots[0]) for a in dots)
        view = render_mod._photon_hit_draw(ctx, fraction, dots, region, 32, 24)
        whole = render_mod._photon_hit_view(ctx, shots, region, 32, 24)
        np.testing.assert_array_equal(view[0], whole[0])
        assert view[1:] == whole[1:] and view[1] > 0
    finally:
        ctx.accel.close()


def test_masks_as_bits_give_the_estimates_of_bool_masks():
    rng = np.random.default_rng(6)
    ph = _plane(3001, rng)  # (not a multiple of 8 photons)
    n = len(ph)
    pm = PhotonMap(ph)
    masks = np.stack([rng.random(n) < 0.5, np.zeros(n, bool), np.ones(n, bool),
                      rng.random(n) < 0.01])
    bits = pack_masks(masks)
    assert bits.dtype == np.uint8 and bits.shape == (4, (n + 7) // 8)
    np.testing.assert_array_equal(unpack_masks(bits, n), masks)
    q = np.c_[rng.random((500, 2)), np.zeros(500)]
    nq = np.tile([0.0, 0.0, 1.0], (500, 1))
    a = pm.irradiance(q, nq, 0.05, 16, 1, "knn_simpson", return_boundary=True, masks=masks)
    b = pm.irradiance(q, nq, 0.05, 16, 1, "knn_simpson", return_boundary=True, masks=bits)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert a[2][0].any() and not a[2][1].any()
    np.testing.assert_array_equal(a[2][2], a[0])  # (every photon: the estimate itself)
    with pytest.raises(ValueError, match="masks"):
        pm.irradiance(q, nq, 0.05, 16, 1, "knn_simpson", masks=bits[:, :-1])


def test_counts_irradiance_bits_are_bounce_usable_rows():
    rng = np.random.default_rng(8)
    ph = _plane(12000, rng)
    n = len(ph)
    bounces = rng.integers(0, 4, (n, 4)).astype(np.uint8)
    lim = np.array([3, 2, 2, 2])
    g = GatherMap(ph, 0.05, 16, 1, "knn_simpson", max_points=2000, bounces=bounces)
    key = (2, 1, 1, 0)
    g.counts_irradiance(np.arange(5), lim, key)
    bits = g.counts_cache[key][0]
    rows, which = g.estimating_classes
    assert bits.shape == (1, (len(g.estimating) + 7) // 8)
    np.testing.assert_array_equal(unpack_masks(bits, len(g.estimating))[0],
                                  pk.bounce_usable(rows, lim, key)[which])


def test_gather_points_are_float32_and_their_rays_the_float64_bits():
    rng = np.random.default_rng(9)
    g = GatherMap(_plane(8000, rng), 0.05, 16, 1, "knn_simpson", max_points=2000)
    assert g.position is g.tree.position and g.position.dtype == np.float32
    assert g.normal.dtype == np.float32
    P = len(g.position)
    rows = np.arange(40)
    q = np.c_[rng.random((40, 2)), np.full(40, 1e-4)]
    nq = np.tile([0.0, 0.0, 1.0], (40, 1))
    lists = rng.integers(0, P, (40, 4)).astype(np.int64)
    counts = np.full(40, 4, np.int64)
    out = []
    for pos, nrm in ((g.position, g.normal),
                     (g.position.astype(np.float64), g.normal.astype(np.float64))):
        o32, d32 = np.empty((160, 3), np.float32), np.empty((160, 3), np.float32)
        t32, slot = np.empty(160, np.float32), np.empty(160, np.int64)
        k = _list_rays(pos, nrm, q, nq, np.zeros(0), rows, lists, counts, rows,
                       np.zeros(40, np.int64), 4, o32, d32, t32, slot)
        out.append((k, o32[:k], d32[:k], t32[:k], slot[:k]))
    assert out[0][0] == 160
    for x, y in zip(*out):
        np.testing.assert_array_equal(x, y)


def test_a_mask_without_power_keeps_no_level():
    """A secondary mask and a subset without an estimating photon of power: their levels
    are zeros (what the estimate gives them), one shared array each kind, eager and lazy,
    and the map holds 2 x 24 B a point less than with a photon in each."""
    for lazy in (False, True):
        rng = np.random.default_rng(10)
        ph = _plane(20000, rng)
        n = len(ph)
        none = np.zeros(n, bool)
        g = GatherMap(ph, 0.05, 16, 1, "knn_simpson", max_points=3000, subsets=[none, none],
                      secondary=[none], lazy=lazy)
        P = len(g.position)
        g.complete()
        assert g.E.any()
        for level in (g.subset_maps[0].E, g.subset_maps[1].E, g.secondary_levels[0]):
            assert level.shape == (P, 3) and not level.any()
        assert g.subset_maps[0].E is g.subset_maps[1].E
        assert g.subset_maps[0].E.flags.c_contiguous  # (the lookup kernels read it)
        one = np.zeros(n, bool)
        one[rng.integers(0, n, 50)] = True
        h = GatherMap(ph, 0.05, 16, 1, "knn_simpson", max_points=3000, subsets=[one, one],
                      secondary=[one], lazy=lazy).complete()
        assert held_bytes(h) - held_bytes(g) >= 2 * 12 * P - 64  # (two float32 (P,3) levels)
        for a, b in zip(g.subset_maps[0].lookup(np.c_[rng.random((50, 2)), np.zeros(50)],
                                                np.tile([0.0, 0.0, 1.0], (50, 1))),
                        (np.zeros((50, 3)),)):
            np.testing.assert_array_equal(a, b)


def test_a_maps_usable_masks_are_kept_as_bits():
    """chaincounts' per-key usable masks (a caustic map's, read after specular chains):
    bits (1/8 B a photon and key), the same mask, and the masked estimate of
    chaincounts.irradiance that of the bool masks."""
    from engine import chaincounts
    rng = np.random.default_rng(12)
    pm = PhotonMap(_plane(5003, rng))  # (not a multiple of 8 photons)
    pm.photons.bounces = rng.integers(0, 4, (len(pm.photons), 4)).astype(np.uint8)
    lim = np.array([3, 2, 2, 2])
    counts = np.array([[1, 1, 0, 0], [2, 1, 1, 0], [3, 2, 1, 1]] * 30, np.int64)
    q = np.c_[rng.random((90, 2)), np.zeros(90)]
    nq = np.tile([0.0, 0.0, 1.0], (90, 1))
    got = chaincounts.irradiance(pm, lim, counts, q, nq, 0.08, 16, 1, "knn_simpson")
    cache = chaincounts.map_cache(pm)
    assert cache
    for key, (bits, every, some) in cache.items():
        usable = pm.photons.usable(lim, key)
        assert bits.dtype == np.uint8 and bits.shape == (1, (len(pm.photons) + 7) // 8)
        np.testing.assert_array_equal(chaincounts._usable(pm.photons, lim, key, cache),
                                      usable)
        assert (every, some) == (usable.all(), usable.any())
    for j, key in enumerate(map(tuple, counts[:3])):
        want = pm.irradiance(q[j::3], nq[j::3], 0.08, 16, 1, "knn_simpson",
                             masks=pm.photons.usable(lim, key)[None])[1][0]
        if not pm.photons.usable(lim, key).all():
            np.testing.assert_array_equal(got[j::3], want)
