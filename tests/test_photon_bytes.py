"""The bytes a photon pass' maps hold (engine/resources.py held_bytes, the photon pass'
stats["photon_bytes"]; issue 13's "<= 64 bytes per stored photon", docs/performance.md
"perf47"), and two arrays the maps no longer keep:
- held_bytes counts each buffer once (views, subset maps and serial views share them),
  and not Embree's scene;
- the photon pass' photon_bytes is what its maps hold, a lazy gather map's masks, arrays
  to fill and estimating photons included;
- a gather map keeps no (P,3) estimate of its drop bounds' masks (only their (P,) flags),
  eager or lazy;
- GatherCounts keeps its photons' count classes (1 B a photon), not their (N,4) counts,
  with the same masks.
"""
import importlib
import os
import sys

import numpy as np

from engine import RenderSettings
from engine import photonkernels as pk
from engine.api import cornell_box
from engine.chaincounts import GatherCounts
from engine.photonmap import GatherMap, PhotonMap
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
            assert g._lazy.chosen.shape[0] == 5  # the masks' estimates still come whole
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
    # (626 classes here: 2 B a photon; a render's few hundred or fewer: 1-2 B)
    assert g.which.dtype == np.uint16 and len(g.which) == n
    for key in ((1, 1, 0, 0), (3, 2, 1, 0), (5, 1, 2, 2)):
        np.testing.assert_array_equal(g._mask(key), pk.bounce_usable(bounces, lim, key))
    held = held_bytes(g)
    assert held <= power.nbytes + 2 * n + g.rows.nbytes + g.limits.nbytes + 3 * (n // 8 + n)


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
