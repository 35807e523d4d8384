"""The final gather's bookkeeping kernels (engine/gatherkernels.py) against the numpy
gather_indirect they replaced, kept here as the oracle: the same irradiance, bit for bit,
with the recursion (regathers at boundaries and short rays) and specular continuations
(per-ray classes) exercised; and each kernel against its numpy expression. The lean
hits (plain diffuse materials: no closures' set-up, no continuation) against the full
set-up of the same materials."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.bsdf import SurfaceHit, lobe_weights, surface_hit
from engine.camerakernels import choose_lobes, hit_closures
from engine.closures import principled as pr
from engine.gatherkernels import (add_gathered, diffuse_lookups, keep_embree_hits, keep_hits,
                                  lean_diffuse, lean_materials, rays_f32)
from engine.geometry import MaterialTable
from engine.scene import Material
from engine.integrator import (MAX_GATHER_LEVEL, Counters, GatherBuffers, _closest_bvh, _deeper,
                               _secondary_irradiance, continue_specular, direct_irradiance,
                               gather_indirect)
from engine.camerakernels import gather_rays
from engine.normalmap import bump_shadowing
from engine.render import _photon_pass, prepare_context
from engine.sampling import max3, uniform_sphere
from helpers import hits_from_inside
from engine.visibility import DIFFUSE


def _concat_hits(hits):
    """One SurfaceHit of the rows of several (fields concatenated; None where all are)."""
    fields = {}
    for name in SurfaceHit.__dataclass_fields__:
        parts = [getattr(h, name) for h in hits]
        if all(a is None for a in parts):
            fields[name] = None
        else:
            assert not any(a is None for a in parts), name
            fields[name] = np.concatenate(parts)
    return SurfaceHit(**fields)


def _gather_indirect_numpy(ctx, hit, rng, counters, rays=None, level=0, log=None,
                           batched=True):
    """gather_indirect as it was before gatherkernels (numpy compaction, selection and
    accumulation), with the regathers of all rays and depths in one batch at the end
    (their own stream, rng.spawn) as gather_indirect makes them since issue 13's tenth
    slice; log counts the regathered rows, the regather batches and the per-ray-class
    steps. batched=False: each step's regathers at once, from rng (before the tenth
    slice; the statistical reference of the batch). The regathered ends' secondary
    caustic: their lookups' points' share (GatherMap.secondary_E; the limits here keep
    every photon at any counts), else estimated."""
    n = len(hit.p)
    E = np.zeros((n, 3))
    pending = []
    G = rays or ctx.settings.gather_rays
    c = np.ascontiguousarray
    for g in range(G):
        u1, u2 = rng.random(n), rng.random(n)
        idx = np.empty(n, np.int64)
        o, d = np.empty((n, 3)), np.empty((n, 3))
        k = gather_rays(c(u1, np.float64), c(u2, np.float64), c(hit.ns, np.float64),
                        c(hit.ng, np.float64), c(hit.p, np.float64), c(hit.offset, np.float64),
                        idx, o, d)
        idx, o, d = idx[:k], o[:k], d[:k]
        tp = np.ones((len(idx), 3))
        if getattr(hit, "n_smooth", None) is not None:
            tp *= bump_shadowing(hit.n_smooth[idx], hit.ns[idx], d)[:, None]
        ray_cls = DIFFUSE
        for depth in range(ctx.settings.gather_depth + 1):
            if len(idx) == 0:
                break
            t, prim, u, v = ctx.accel.intersect(o, d, cls=ray_cls)
            counters.gather_rays += len(idx)
            got = prim >= 0
            if not got.all():
                o, d, tp, idx, prim, u, v, t = (a[got] for a in (o, d, tp, idx, prim, u, v, t))
                if np.ndim(ray_cls):
                    ray_cls = ray_cls[got]
                    log["per_ray_steps"] += 1
            if len(idx) == 0:
                break
            y = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
            if level > 0 and depth == 0:
                Le = y.emission
                if np.any(Le > 0):
                    E[idx] += tp * math.pi * Le / G
            wd = lobe_weights(ctx.table, y)["diffuse"]
            dsel = np.nonzero(max3(wd) > 0)[0]
            if len(dsel):
                # (the map of this level's depth under the bounce limits, as the kernel)
                gmap = _deeper(ctx.gather_map, ctx.regather_maps, level)
                sec = gmap.secondary_E if level < MAX_GATHER_LEVEL else None
                got = gmap.lookup(y.p[dsel], y.ng[dsel], offset=y.offset[dsel],
                                  points=sec is not None)
                Ey, boundary = got[:2]
                if level < MAX_GATHER_LEVEL:
                    redo = boundary | (t[dsel] < ctx.gather_short)
                    # The regathered ends' secondary caustic: their points' share (NaN:
                    # no point, estimated from the secondary map).
                    known = None
                    if sec is not None:
                        pt = got[2][redo]
                        known = np.where((pt >= 0)[:, None], sec[np.maximum(pt, 0)], np.nan)
                    if redo.any() and not batched:
                        ysub = y.take(dsel[redo])
                        Ey[redo] = (direct_irradiance(ctx, ysub, rng, counters,
                                                      skip_mesh_lights=True)
                                    + _gather_indirect_numpy(ctx, ysub, rng, counters, 1,
                                                             level + 1, log, False)
                                    + _secondary_irradiance(ctx, ysub, rng, level + 1,
                                                            known=known))
                    elif redo.any():
                        log["regathered"] += int(redo.sum())
                        rows = dsel[redo]
                        pending.append((idx[rows], tp[rows], wd[rows], y.take(rows), known))
                        dsel, Ey = dsel[~redo], Ey[~redo]  # added by the batch below
                E[idx[dsel]] += tp[dsel] * wd[dsel] * Ey / G
            if depth == ctx.settings.gather_depth:
                break
            keep, o, d, tp, ray_cls = continue_specular(ctx, y, tp, rng, ray_cls)
            idx = idx[keep]
    if pending:
        log["batches"] = log.get("batches", 0) + 1
        target, tps, wds = (np.concatenate([q[i] for q in pending]) for i in range(3))
        ysub = _concat_hits([q[3] for q in pending])
        known = (None if all(q[4] is None for q in pending) else np.concatenate(
            [np.full((len(q[0]), 3), np.nan) if q[4] is None else q[4] for q in pending]))
        sub_rng = rng.spawn(1)[0]
        Esub = (direct_irradiance(ctx, ysub, sub_rng, counters, skip_mesh_lights=True)
                + _gather_indirect_numpy(ctx, ysub, sub_rng, counters, 1, level + 1, log)
                + _secondary_irradiance(ctx, ysub, sub_rng, level + 1, known=known))
        np.add.at(E, target, tps * wds * Esub / G)  # in order, as the kernel adds
    return E


@pytest.fixture(scope="module")
def box():
    # Limits no path reaches: the numpy stage below predates the bounce counts of the
    # gather rays' continuations (engine/chaincounts.py, tests/test_bounce_limits.py).
    ctx = prepare_context(cornell_box(32, 24, glass_sphere=True),
                          RenderSettings(workers=1, photons=30_000, caustic_photons=10_000,
                                         seed=2, max_bounces=1024, diffuse_bounces=1024,
                                         glossy_bounces=1024, transmission_bounces=1024))
    _photon_pass(ctx, {}, None, None)
    yield ctx
    ctx.accel.close()


_hits = hits_from_inside


def test_gather_indirect_is_bitwise_the_numpy_stage(box):
    ctx = box
    assert ctx.gather_map is not None
    hit = _hits(ctx, 6000, seed=11)
    log = {"regathered": 0, "per_ray_steps": 0}
    want = _gather_indirect_numpy(ctx, hit, np.random.default_rng(5), Counters(), log=log)
    c_new = Counters()
    got = gather_indirect(ctx, hit, np.random.default_rng(5), c_new)
    assert log["regathered"] > 50 and log["per_ray_steps"] > 0  # recursion, classes exercised
    assert log["batches"] == MAX_GATHER_LEVEL  # one regather batch per level
    assert got.shape == want.shape and np.array_equal(got, want)
    assert (want > 0).mean() > 0.5


def test_keep_hits_compacts_like_boolean_indexing():
    rng = np.random.default_rng(1)
    n = 1000
    prim = np.where(rng.random(n) < 0.3, -1, rng.integers(0, 50, n)).astype(np.int64)
    arrays = dict(o=rng.random((n, 3)), d=rng.random((n, 3)), tp=rng.random((n, 3)),
                  idx=rng.permutation(n).astype(np.int64), u=rng.random(n), v=rng.random(n),
                  t=rng.random(n))
    cls = rng.integers(0, 8, n).astype(np.int64)
    got = prim >= 0
    want = {k: a[got] for k, a in arrays.items()}
    work = {k: a.copy() for k, a in arrays.items()}
    pc, cc = prim.copy(), cls.copy()
    m = keep_hits(pc, work["o"], work["d"], work["tp"], work["idx"], work["u"], work["v"],
                  work["t"], cc)
    assert m == got.sum()
    assert np.array_equal(pc[:m], prim[got]) and np.array_equal(cc[:m], cls[got])
    for k in arrays:
        assert np.array_equal(work[k][:m], want[k]), k
    # A scalar class: an empty cls array, untouched.
    m2 = keep_hits(prim.copy(), *(a.copy() for a in arrays.values()), np.zeros(0, np.int64))
    assert m2 == m


def test_diffuse_rows_and_accumulation_match_numpy():
    rng = np.random.default_rng(3)
    n = 500
    wd = rng.random((n, 3)) * (rng.random((n, 1)) < 0.6)
    wd[7] = [np.nan, 0.5, 0.5]  # max3 propagates NaN: not a diffuse row
    wd[8] = [0.0, 0.0, 1e-300]
    p, ng, t = rng.random((n, 3)), rng.random((n, 3)), rng.random(n)
    off = rng.random(n)
    dsel = np.nonzero(max3(wd) > 0)[0]
    rows = np.empty(n, np.int64)
    lp, ln, lo, lt = np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n)
    k = diffuse_lookups(wd, p, ng, off, t, rows, lp, ln, lo, lt)
    assert np.array_equal(rows[:k], dsel) and 7 not in dsel and 8 in dsel
    assert np.array_equal(lp[:k], p[dsel]) and np.array_equal(ln[:k], ng[dsel])
    assert np.array_equal(lo[:k], off[dsel]) and np.array_equal(lt[:k], t[dsel])
    # Accumulation, with and without the regather list.
    idx = rng.permutation(2 * n)[:n].astype(np.int64)
    tp = rng.random((n, 3))
    Ey = rng.random((k, 3))
    boundary = rng.random(k) < 0.2
    E0 = rng.random((2 * n, 3))
    want = E0.copy()
    want[idx[dsel]] += tp[dsel] * wd[dsel] * Ey / 3
    got = E0.copy()
    again = np.empty(k, np.int64)
    assert add_gathered(got, idx, dsel, tp, wd, Ey, 3, boundary, lt[:k], 0.4, False,
                        again) == 0
    assert np.array_equal(got, want)
    got = E0.copy()
    na = add_gathered(got, idx, dsel, tp, wd, Ey, 3, boundary, lt[:k], 0.4, True, again)
    expect = np.nonzero(boundary | (t[dsel] < 0.4))[0]
    assert np.array_equal(again[:na], expect)
    keep = np.setdiff1d(np.arange(k), expect)
    want = E0.copy()
    want[idx[dsel[keep]]] += tp[dsel[keep]] * wd[dsel[keep]] * Ey[keep] / 3
    assert np.array_equal(got, want)


def _lean_cases():
    """Materials (name, Material, lean?) covering each feature that makes a hit need the
    full closures."""
    grey = (0.6, 0.5, 0.4)
    return [
        ("lambert", Material("lambert", base_color=grey), True),
        ("lambert_dark", Material("lambert_dark", base_color=(0.0, 0.0, 0.0)), True),
        ("bright", Material("bright", base_color=(1.5, 0.2, 0.7), roughness=0.7), True),
        ("metal", Material("metal", base_color=grey, metallic=0.5), False),
        ("glass", Material("glass", transmission=1.0), False),
        ("spec", Material("spec", base_color=grey, specular=1.0), False),
        ("coat", Material("coat", base_color=grey, coat_weight=0.3), False),
        ("sheen", Material("sheen", base_color=grey, sheen_weight=0.3), False),
        ("alpha", Material("alpha", base_color=grey, alpha=0.5), False),
        ("emitter", Material("emitter", base_color=grey, emission=(1.0, 1.0, 1.0)), False),
        ("textured", Material("textured", base_color=grey,
                              texture=np.full((2, 2, 3), 0.5)), False),
    ]


def test_lean_materials_are_one_lambert_lobe():
    """Every material lean_materials calls lean has, from any view and side, the full
    set-up's (camerakernels.hit_closures) diffuse weight bit for bit and no other lobe to
    continue through (choose_lobes' psum 0); every other case is not lean."""
    cases = _lean_cases()
    table = MaterialTable.build([m for _, m, _ in cases])
    lean = lean_materials(table)
    assert lean.tolist() == [want for _, _, want in cases]
    rng = np.random.default_rng(4)
    n = 4000
    mat = rng.integers(0, len(cases), n).astype(np.int32)
    ng = uniform_sphere(rng.random(n), rng.random(n))
    ns = ng + 0.3 * uniform_sphere(rng.random(n), rng.random(n))
    ns /= np.linalg.norm(ns, axis=1)[:, None]
    wo = uniform_sphere(rng.random(n), rng.random(n))
    front = rng.random(n) < 0.7
    base = np.take(table.base_color, mat, axis=0)
    prm, albedo = np.empty((n, pr.N_PACK)), np.empty((n, pr.N_LOBES, 3))
    hit_closures(ns, ng, wo, mat, table.closure_params, False, base, front,
                 np.ascontiguousarray(table.alpha, np.float64), np.zeros(0), prm, albedo,
                 np.zeros(0))
    sel, q, p, psum = np.empty((n, pr.N_LOBES)), np.empty(n), np.empty((n, pr.N_LOBES - 1)), \
        np.empty(n)
    choose_lobes(albedo, np.ones((n, 3)), sel, q, p, psum)
    wd = np.full((n, 3), -1.0)
    full = np.empty(n, np.int64)
    k = lean_diffuse(mat, base, lean, np.ascontiguousarray(table.alpha, np.float64), wd, full)
    is_lean = lean[mat]
    assert np.array_equal(full[:k], np.nonzero(~is_lean)[0])
    assert np.array_equal(wd[is_lean], albedo[is_lean, pr.L_DIFFUSE])
    assert not (albedo[is_lean, 1:] != 0).any() and not (psum[is_lean] > 0).any()
    assert (wd[~is_lean] == -1.0).all()  # left for the full set-up
    # The layered cases do have another lobe to continue through, from most views.
    for case in range(3, 9):
        assert (psum[mat == case] > 0).mean() > 0.5, cases[case][0]
    # No lean material: the general path.
    assert lean_materials(MaterialTable.build([cases[3][1], cases[4][1]])) is None


def test_gather_indirect_with_only_lean_or_no_lean_hits(box, monkeypatch):
    """The lean split at its ends: hits on lean surfaces only (the box's walls; their gather
    rays still meet the glass ball), and the same gather with the split switched off
    (every hit takes the full set-up, as before it): the numpy oracle's irradiance, bit
    for bit."""
    ctx = box
    hit = _hits(ctx, 3000, seed=12)
    walls = np.nonzero(lean_materials(ctx.table)[hit.mat])[0]
    assert 0 < len(walls) < len(hit.p)
    want = _gather_indirect_numpy(ctx, hit.take(walls), np.random.default_rng(6), Counters(),
                                  log={"regathered": 0, "per_ray_steps": 0})
    got = gather_indirect(ctx, hit.take(walls), np.random.default_rng(6), Counters())
    assert np.array_equal(got, want)
    want = _gather_indirect_numpy(ctx, hit, np.random.default_rng(7), Counters(),
                                  log={"regathered": 0, "per_ray_steps": 0})
    monkeypatch.setattr("engine.integrator.lean_materials", lambda table: None)
    got = gather_indirect(ctx, hit, np.random.default_rng(7), Counters())
    assert np.array_equal(got, want)


def test_regathers_run_in_one_batch_per_level(box, monkeypatch):
    """gather_indirect regathers all its rays' untrusted ends in one call of the next
    level (issue 13, tenth slice: before, one call per gather step that had any)."""
    import engine.integrator as integrator
    ctx = box
    hit = _hits(ctx, 4000, seed=13)
    calls = {}
    real = integrator.gather_indirect

    def counting(ctx, hit, rng, counters, *a, level=0, **k):
        calls[level] = calls.get(level, 0) + 1
        return real(ctx, hit, rng, counters, *a, level=level, **k)

    monkeypatch.setattr(integrator, "gather_indirect", counting)
    counters = Counters()
    E = integrator.gather_indirect(ctx, hit, np.random.default_rng(8), counters)
    assert calls == {level: 1 for level in range(MAX_GATHER_LEVEL + 1)}
    assert np.isfinite(E).all() and (E > 0).mean() > 0.5


def test_batched_regathers_are_statistically_the_per_step_ones(box):
    """The batch changes only which random numbers the regathers draw (the level's own
    rays draw the same): over 6,000 hits and 4 seeds the irradiance's mean equals the
    per-step regathers' (paired: the difference within 4 standard errors of the paired
    per-hit differences, and within 1 % of the mean)."""
    ctx = box
    hit = _hits(ctx, 6000, seed=14)
    diffs, means = [], []
    for seed in range(4):
        log = {"regathered": 0, "per_ray_steps": 0}
        old = _gather_indirect_numpy(ctx, hit, np.random.default_rng(20 + seed), Counters(),
                                     log=log, batched=False)
        new = gather_indirect(ctx, hit, np.random.default_rng(20 + seed), Counters())
        assert not np.array_equal(old, new)  # the regathers did draw other numbers
        diffs.append((new - old).sum(axis=1))
        means.append(old.sum(axis=1).mean())
    diff = np.concatenate(diffs)
    se = diff.std() / math.sqrt(len(diff))
    assert abs(diff.mean()) < 4 * se
    assert abs(diff.mean()) < 0.01 * np.mean(means)


def test_regather_stream_is_generator_spawn_and_draws_nothing():
    """integrator._spawn (the regathers' stream) gives Generator.spawn's numbers without
    calling it (absent before numpy 1.25), child after child, and leaves the parent's
    stream where it was."""
    from engine.integrator import _spawn
    a, b = np.random.default_rng(11), np.random.default_rng(11)
    a.random(3), b.random(3)
    for _ in range(2):
        np.testing.assert_array_equal(_spawn(a).random(8), b.spawn(1)[0].random(8))
    np.testing.assert_array_equal(a.random(8), b.random(8))


def _hits_through_glass(ctx, n, seed, max_bounces=6):
    """Diffuse hits reached through the box's glass ball: rays from around the ball aimed
    into it, continued through its specular lobes (continue_specular) until they meet a
    surface with a diffuse lobe (the floor and walls seen through the ball)."""
    rng = np.random.default_rng(seed)
    centre = np.array([-0.7, -0.4, 0.7]) - ctx.geo.offset
    o = centre + 1.6 * uniform_sphere(rng.random(n), rng.random(n))
    target = centre + 0.5 * uniform_sphere(rng.random(n), rng.random(n))
    d = target - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    tp, cls, found = np.ones((n, 3)), DIFFUSE, []
    for depth in range(max_bounces):
        t, prim, u, v = ctx.accel.intersect(o, d, cls=cls)
        k = prim >= 0
        o, d, tp, prim, u, v = o[k], d[k], tp[k], prim[k], u[k], v[k]
        cls = cls[k] if np.ndim(cls) else cls
        if not len(prim):
            break
        y = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
        diffuse = max3(lobe_weights(ctx.table, y)["diffuse"]) > 0
        if depth > 0 and diffuse.any():
            found.append(y.take(np.nonzero(diffuse)[0]))
        keep, o, d, tp, cls = continue_specular(ctx, y, tp, rng, cls)
    return _concat_hits(found)


def test_regathers_seen_through_glass_are_statistically_the_per_step_ones(box):
    """Issue 14's Glass ball read 2-4 % darker with the regathers in one batch at some
    seeds (docs/performance.md, "the regathers' batch reverted"). At the points the ball
    shows (diffuse hits reached through glass, where gather rays end on the ball's own
    contact and regather most), the batch's irradiance equals the per-step regathers'
    over 8 seeds, paired: the mean difference within 4 standard errors and 2 % of the mean."""
    ctx = box
    hit = _hits_through_glass(ctx, 12000, seed=15)
    assert len(hit.p) > 2000
    diffs, means, regathered = [], [], 0
    for seed in range(8):
        log = {"regathered": 0, "per_ray_steps": 0}
        old = _gather_indirect_numpy(ctx, hit, np.random.default_rng(40 + seed), Counters(),
                                     log=log, batched=False)
        new = gather_indirect(ctx, hit, np.random.default_rng(40 + seed), Counters())
        diffs.append((new - old).sum(axis=1))
        means.append(old.sum(axis=1).mean())
        regathered += log["regathered"]
    diff = np.concatenate(diffs)
    se = diff.std() / math.sqrt(len(diff))
    assert abs(diff.mean()) < 4 * se
    assert abs(diff.mean()) < 0.02 * np.mean(means)


def test_regather_surface_data_are_the_steps(box):
    """_regather recomputes the ends' surface data from (prim, u, v, d) instead of keeping
    the step's SurfaceHit: surface_hit is row by row, so every field of a subset of rows
    equals the same rows taken from the whole batch, bit for bit (glass, mirror and
    diffuse materials, rays from both sides)."""
    ctx = box
    rng = np.random.default_rng(16)
    lo, hi = ctx.geo.bounds
    n = 5000
    o = lo + (hi - lo) * (0.1 + 0.8 * rng.random((n, 3)))
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    prim, u, v, d = prim[k], u[k], v[k], d[k]
    whole = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
    rows = np.sort(rng.choice(len(prim), len(prim) // 5, replace=False))
    part = surface_hit(ctx.geo, ctx.table, prim[rows], u[rows], v[rows], d[rows])
    taken = whole.take(rows)
    assert len(np.unique(whole.mat)) >= 3
    for name in SurfaceHit.__dataclass_fields__:
        a, b = getattr(part, name), getattr(taken, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert np.array_equal(np.asarray(a), np.asarray(b)), name


def _random_rays(ctx, n, seed):
    """n float64 rays in random directions, two thirds from inside the scene's bounds, a
    third from outside a corner of them (about half of these miss)."""
    rng = np.random.default_rng(seed)
    lo, hi = ctx.geo.bounds  # (as tests/helpers.rays_from_inside)
    o = lo + (hi - lo) * (0.05 + 0.9 * rng.random((n, 3)))
    o[: n // 3] = hi + 1.0  # outside: about half of these miss everything
    d = uniform_sphere(rng.random(n), rng.random(n))
    return np.ascontiguousarray(o), np.ascontiguousarray(d)


def test_rays_f32_is_numpys_float32_layout():
    rng = np.random.default_rng(4)
    o = rng.normal(size=(700, 3)) * 10.0 ** rng.integers(-8, 8, (700, 1))
    d = rng.normal(size=(700, 3))
    o32, d32 = np.empty((700, 3), np.float32), np.empty((700, 3), np.float32)
    tf32 = np.zeros(700, np.float32)
    rays_f32(o, d, o32, d32, tf32)
    assert np.array_equal(o32, np.ascontiguousarray(o, np.float32))
    assert np.array_equal(d32, np.ascontiguousarray(d, np.float32))
    assert (tf32 == np.finfo(np.float32).max).all()


@pytest.mark.parametrize("per_ray", [False, True])
def test_embree_hits_kept_as_intersect_and_keep_hits_keep_them(box, per_ray):
    """The gather step's Embree path (rays_f32, Accel.intersect_hits(out=),
    keep_embree_hits) against Accel.intersect and keep_hits, bit for bit: the kept rays,
    their triangles, barycentrics and distances."""
    ctx = box
    n = 5000
    o, d = _random_rays(ctx, n, seed=8)
    rng = np.random.default_rng(9)
    tp = rng.random((n, 3))
    idx = rng.permutation(n).astype(np.int64)
    cls = rng.integers(0, 8, n).astype(np.int64) if per_ray else np.zeros(0, np.int64)
    ray_cls = cls if per_ray else DIFFUSE
    # numpy's way
    t, prim, u, v = ctx.accel.intersect(o, d, cls=ray_cls)
    want = [a.copy() for a in (o, d, tp, idx)]
    want_cls = cls.copy()
    k_want = keep_hits(prim, *want, u, v, t, want_cls)
    assert 0 < k_want < n  # hits and misses
    # the kernel path, into a thread's buffers used before for more rays
    buf = GatherBuffers()
    buf.rays(n + 100)
    bvh = _closest_bvh(ctx.accel, ray_cls)
    assert bvh is not None
    o32, d32, tf32 = buf.o32[:n], buf.d32[:n], buf.tf32[:n]
    buf.o32[:], buf.tf32[:] = 7.0, 3.0  # stale values from an earlier step
    got = [a.copy() for a in (o, d, tp, idx)]
    got_cls = cls.copy()
    rays_f32(got[0], got[1], o32, d32, tf32)
    out = buf.geom[:n], buf.prim32[:n], buf.u32[:n], buf.v32[:n]
    starts = bvh.intersect_hits(o32, d32, tf32, out=out)[4]
    gp, gu, gv, gt = buf.prim[:n], buf.u[:n], buf.v[:n], buf.t[:n]
    k = keep_embree_hits(*out, tf32, starts, *got, got_cls, gp, gu, gv, gt)
    assert k == k_want
    for g, w in zip(got, want):
        assert np.array_equal(g[:k], w[:k])
    for g, w in ((gp, prim), (gu, u), (gv, v), (gt, t)):
        assert g.dtype == w.dtype and np.array_equal(g[:k], w[:k])
    if per_ray:
        assert np.array_equal(got_cls[:k], want_cls[:k])


def test_keep_embree_hits_adds_the_pieces_first_triangles():
    """Several Embree geometries in one BVH: the hit triangle's row is starts[geom] +
    prim, as Accel.intersect answers (and the misses, geom -1, are dropped)."""
    geom = np.array([0, -1, 2, 1, -1, 2], np.int32)
    prim32 = np.array([5, 9, 0, 3, 9, 7], np.int32)
    starts = np.array([0, 100, 1000], np.int64)
    u32 = np.linspace(0, 1, 6).astype(np.float32)
    tf32 = np.linspace(1, 2, 6).astype(np.float32)
    o, d, tp = (np.arange(18.0).reshape(6, 3) + s for s in (0, 100, 200))
    idx = np.arange(6, dtype=np.int64)
    prim, u, v, t = np.empty(6, np.int64), np.empty(6), np.empty(6), np.empty(6)
    k = keep_embree_hits(geom, prim32, u32, u32, tf32, starts, o, d, tp, idx,
                         np.zeros(0, np.int64), prim, u, v, t)
    hit = geom >= 0
    assert k == 4
    assert prim[:k].tolist() == [5, 1000, 103, 1007]
    assert np.array_equal(u[:k], u32[hit].astype(np.float64))
    assert np.array_equal(t[:k], tf32[hit].astype(np.float64))
    assert idx[:k].tolist() == [0, 2, 3, 5] and np.array_equal(o[1], [6.0, 7.0, 8.0])


def test_gather_lookup_into_scratch_is_the_fresh_lookup(box):
    """GatherMap.lookup writing into a thread's GatherBuffers answers as with fresh arrays,
    also after a larger call left other values in them (hidden candidates included)."""
    ctx = box
    hit = _hits(ctx, 4000, seed=13)
    buf = GatherBuffers()
    buf.rays(len(hit.p))
    g = ctx.gather_map
    big = g.lookup(hit.p, hit.ng, offset=hit.offset, scratch=buf)
    assert np.array_equal(big[0], g.lookup(hit.p, hit.ng, offset=hit.offset)[0])
    rows = np.arange(0, len(hit.p), 3)
    want = g.lookup(hit.p[rows], hit.ng[rows], offset=hit.offset[rows])
    got = g.lookup(hit.p[rows], hit.ng[rows], offset=hit.offset[rows], scratch=buf)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert want[1].any() and not want[1].all() and (want[0] > 0).any()


def test_closest_bvh_only_where_one_bvh_answers_as_intersect():
    scene = cornell_box(16, 12, glass_sphere=True)
    ctx = prepare_context(scene, RenderSettings(workers=1, photon_mapping=False))
    try:
        assert not ctx.accel.has_invisible
        assert _closest_bvh(ctx.accel, DIFFUSE) is ctx.accel.full
        assert _closest_bvh(ctx.accel, np.array([DIFFUSE, 4])) is ctx.accel.full
    finally:
        ctx.accel.close()
    scene = cornell_box(16, 12, glass_sphere=True)
    next(m for m in scene.meshes if m.name == "block").visible_diffuse = False
    ctx = prepare_context(scene, RenderSettings(workers=1, photon_mapping=False))
    try:
        assert ctx.accel.has_invisible
        assert _closest_bvh(ctx.accel, DIFFUSE) is None  # a subset: its own triangle rows
        assert _closest_bvh(ctx.accel, np.array([DIFFUSE, 4])) is None  # split by class
        assert _closest_bvh(ctx.accel, 4) is ctx.accel.for_class(4)  # glossy sees all
    finally:
        ctx.accel.close()


def test_gather_indirect_with_invisible_objects_is_the_numpy_stage(monkeypatch):
    """A glass ball invisible to glossy rays: the gather's diffuse steps go through the
    kernel path (every triangle answers diffuse rays), the steps with per-ray classes
    after a specular bounce through Accel.intersect (a class subset); the oracle's
    numbers either way."""
    from engine import integrator
    scene = cornell_box(32, 24, glass_sphere=True)
    next(m for m in scene.meshes if m.name == "glass_sphere").visible_glossy = False
    ctx = prepare_context(scene, RenderSettings(workers=1, photons=20_000,
                                                caustic_photons=5_000, seed=3))
    used = {"kernel": 0, "intersect": 0}

    def counted(name, f):
        def call(*a):
            used[name] += 1
            return f(*a)
        return call

    monkeypatch.setattr(integrator, "keep_embree_hits",
                        counted("kernel", integrator.keep_embree_hits))
    monkeypatch.setattr(integrator, "keep_hits", counted("intersect", integrator.keep_hits))
    try:
        assert ctx.accel.has_invisible
        _photon_pass(ctx, {}, None, None)
        hit = _hits(ctx, 3000, seed=21)
        log = {"regathered": 0, "per_ray_steps": 0}
        want = _gather_indirect_numpy(ctx, hit, np.random.default_rng(6), Counters(), log=log)
        got = gather_indirect(ctx, hit, np.random.default_rng(6), Counters())
        assert log["regathered"] > 0 and log["per_ray_steps"] > 0
        assert used["kernel"] > 0 and used["intersect"] > 0
        assert np.array_equal(got, want) and (want > 0).mean() > 0.3
    finally:
        ctx.accel.close()


def _count_continuations_numpy(cnt, n, idx, passed, ray_cls):
    """integrator._count_continuations in numpy: the oracle of gatherkernels.count_bounces
    (every continuation but the pass lobe's is a bounce of its class, bent or not)."""
    from engine.visibility import GLOSSY, TRANSMISSION
    if len(idx) == 0:
        return cnt
    bounce = ~np.asarray(passed, bool)
    if cnt is None:
        if not bounce.any():
            return None
        cnt = np.zeros((n, 4), np.int64)
    cls = np.broadcast_to(ray_cls, (len(idx),))
    cnt[idx, 0] += bounce
    cnt[idx, 1] += bounce & (cls == DIFFUSE)
    cnt[idx, 2] += bounce & (cls == GLOSSY)
    cnt[idx, 3] += bounce & (cls == TRANSMISSION)
    return cnt


def test_continuation_counts_are_the_numpy_stage_counts():
    """integrator._count_continuations (gatherkernels.count_bounces) counts what numpy
    counts: every continuation but a transparent pass per class, per-ray and scalar
    classes, counts made on the first bounce and None while every ray passes, counts
    carried in and added to."""
    from engine.integrator import _count_continuations
    from engine.visibility import GLOSSY, TRANSMISSION
    rng = np.random.default_rng(13)
    n = 500
    classes = np.array([DIFFUSE, GLOSSY, TRANSMISSION, 16], np.int64)
    for trial in range(40):
        K = int(rng.integers(0, 400))
        idx = rng.choice(n, K, replace=False).astype(np.int64)  # one ray a hit
        passed = (np.ones(K, bool) if trial % 4 == 0 else rng.random(K) < 0.7)
        ray_cls = (classes[rng.integers(0, 4, K)] if trial % 2 else
                   int(classes[trial % 4]))
        start = None if trial % 3 == 0 else rng.integers(0, 5, (n, 4)).astype(np.int64)
        got = _count_continuations(None if start is None else start.copy(), n, idx, passed,
                                   ray_cls)
        want = _count_continuations_numpy(None if start is None else start.copy(), n, idx,
                                          passed, ray_cls)
        if want is None:
            assert got is None
        else:
            np.testing.assert_array_equal(got, want)
