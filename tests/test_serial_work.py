"""Work moved off the calling thread (docs/performance.md, "Eighth slice: serial work"):
the map build's steps side by side (parallel.run_tasks), the gather points' share and
choice in one compiled pass, maps gathered once into tree order, the photon pass's lent
buffers and the photon-hit view beside the camera pass. Each must give bitwise what the
code it replaced gave, and the same for 1 and 2 workers."""
import math
import threading
import time

import numpy as np
import pytest

from engine import RenderSettings, hashgrid
from engine.api import cornell_box
from engine.parallel import Cancelled, run_tasks
from engine.photonmap import (DENSITY_CELL, GATHER_POINTS_PER_DISC, MAX_POINT_SHARE, SHARE_ROWS,
                              GatherMap, PhotonMap, _point_shares)
from engine.photons import Photons, _Buffers, _Shot, _Stored, trace_photons
from engine.render import prepare_context, render, shoot_photons
from engine.lights import allocate_photons
from engine.photonkernels import store_arrays


# ---------------------------------------------------------------- the replaced numpy code
def numpy_point_share(position, base, radius):
    """gather_point_share as it was (a8e906b), the reference for _point_shares."""
    n = len(position)
    step_share = base.sum() / max(n, 1)
    share = np.full(n, step_share)
    if n == 0 or not radius > 0 or not base.any():
        return share
    size = DENSITY_CELL * radius
    cell = np.floor(np.asarray(position, np.float64) / size)
    cell = np.clip(np.nan_to_num(cell), -2.0 ** 40, 2.0 ** 40).astype(np.int64)
    key = (cell[:, 0] * np.int64(hashgrid.P1)) ^ (cell[:, 1] * np.int64(hashgrid.P2)) \
        ^ (cell[:, 2] * np.int64(hashgrid.P3))
    base_keys, counts = np.unique(key[base], return_counts=True)
    at = np.minimum(np.searchsorted(base_keys, key), len(base_keys) - 1)
    found = np.where(base_keys[at] == key, counts[at], 0)
    per_disc = found / step_share * math.pi / (DENSITY_CELL * DENSITY_CELL)
    with np.errstate(divide="ignore"):
        want = GATHER_POINTS_PER_DISC / per_disc
    return np.clip(want, step_share, max(MAX_POINT_SHARE, step_share))


def numpy_pick_points(base, share):
    """_pick_points as it was (a8e906b)."""
    s = base.sum() / max(len(base), 1)
    extra = (share - s) / max(1.0 - s, 1e-300)
    u = np.modf((np.arange(len(share), dtype=np.float64) + 1.0) * 0.6180339887498949)[0]
    return base | (u < extra)


def _clustered(n, seed=0):
    """Photons on a few dense and sparse patches, with a caustic pile of equal points,
    far coordinates (their cell keys overflow int64 products) and non-finite ones."""
    rng = np.random.default_rng(seed)
    p = rng.random((n, 3)) * [4.0, 4.0, 0.0]
    p[: n // 3] *= 0.05  # dense patch
    p[n // 3: n // 3 + 50] = [1.25, 2.5, 0.0]  # a pile on one point
    p[-40:-20] = rng.random((20, 3)) * 1e12 - 5e11
    p[-20:-17] = [np.nan, 0.0, 1.0]
    p[-17:-14] = [np.inf, -np.inf, 0.0]
    return p.astype(np.float32)


@pytest.mark.parametrize("n, step, radius", [(1000, 4, 0.05), (SHARE_ROWS + 4321, 14, 0.02),
                                             (5000, 7, 0.0), (5000, 7, float("nan"))])
@pytest.mark.parametrize("workers", [1, 2])
def test_point_shares_are_the_numpy_shares_and_choice(n, step, radius, workers):
    pos = _clustered(n)
    base = np.zeros(n, bool)
    base[::step] = True
    with np.errstate(invalid="ignore", over="ignore"):
        want_share = numpy_point_share(pos, base, radius)
    want_points = numpy_pick_points(base, want_share)
    share, is_point = np.empty(n), np.empty(n, bool)
    _point_shares(pos, step, radius, share, is_point, workers)
    assert np.array_equal(share, want_share)  # bit for bit (no NaN among them)
    assert np.array_equal(is_point, want_points)
    assert want_points.sum() > base.sum() or not radius > 0  # sparse patches add points


def _photons(n, seed=1):
    rng = np.random.default_rng(seed)
    pos = _clustered(n, seed)
    pos[~np.isfinite(pos).all(axis=1)] = 0.5
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    return Photons(pos, rng.random((n, 3)).astype(np.float32), -up, up.copy(),
                   rng.integers(0, 4, n).astype(np.uint8), emitted=3 * n)


@pytest.mark.parametrize("structure", ["kdtree", "hashgrid"])
def test_a_map_over_rows_is_the_map_over_the_taken_photons(structure):
    ph = _photons(70_000)
    rows = np.flatnonzero(ph.kind != 1)
    scale = np.random.default_rng(2).random(len(rows)).astype(np.float32) + 1.0
    taken = ph.take(rows)
    taken.power = taken.power * scale[:, None]
    cell = 0.05 if structure == "hashgrid" else None
    for workers in (1, 2):
        a = PhotonMap(taken, workers, structure, cell)
        b = PhotonMap(ph, workers, structure, cell, rows=rows, power_scale=scale)
        for name in ("position", "power", "direction", "normal", "kind"):
            assert np.array_equal(getattr(a.photons, name), getattr(b.photons, name)), name
        assert b.photons.emitted == ph.emitted
    assert len(PhotonMap(ph, rows=np.zeros(0, np.int64))) == 0


def _gather_arrays(g):
    return [g.E, g.boundary, g.position, g.normal, g.tree.position, *g.tree.nodes,
            *g.neighbours]


def test_gather_map_over_rows_is_the_same_for_any_thread_count():
    ph = _photons(90_000)
    rows = np.flatnonzero(ph.kind != 1)
    one = GatherMap(ph.take(rows), 0.05, 16, 1, "knn_simpson", max_points=20_000)
    for workers in (1, 2):
        for flag in (None, lambda: False):
            g = GatherMap(ph, 0.05, 16, 1, "knn_simpson", max_points=20_000, rows=rows,
                          workers=workers, should_cancel=flag)
            for x, y in zip(_gather_arrays(one), _gather_arrays(g)):
                assert np.array_equal(x, y)


def test_run_tasks_returns_results_in_order_and_runs_side_by_side():
    seen = []

    def task(i):
        def run(stop):
            seen.append(threading.current_thread())
            time.sleep(0.01 * (3 - i))
            return i * i
        return run
    assert run_tasks([task(i) for i in range(3)], 1) == [0, 1, 4]
    assert set(seen) == {threading.current_thread()}  # inline
    seen.clear()
    assert run_tasks([task(i) for i in range(3)], 2) == [0, 1, 4]
    assert threading.current_thread() not in seen

    def broken(stop):
        raise ValueError("task broke")
    with pytest.raises(ValueError, match="task broke"):
        run_tasks([task(0), broken], 2)
    with pytest.raises(Cancelled):
        run_tasks([task(0), task(1)], 1, lambda: True)


def _map_arrays(ctx):
    out = [ctx.global_radius, ctx.secondary_radius, ctx.caustic_radius, ctx.gather_short]
    for m in (ctx.caustic_map, ctx.secondary_map, ctx.global_map):
        if m is not None:
            ph = m.photons
            out += [ph.position, ph.power, ph.direction, ph.normal, ph.kind, *m.tree.nodes]
    if ctx.gather_map is not None:
        out += _gather_arrays(ctx.gather_map.complete())  # (read whole)
    return out


@pytest.mark.parametrize("final_gather", [True, False])
def test_map_build_is_the_same_for_one_and_two_workers(final_gather):
    scene = cornell_box(32, 24)
    maps = []
    for workers in (1, 2):
        st = RenderSettings(photons=120_000, caustic_photons=40_000, workers=workers,
                            final_gather=final_gather)
        ctx = prepare_context(scene, st)
        try:
            shots = shoot_photons(ctx, {})
            maps.append(_map_arrays(ctx))
        finally:
            ctx.accel.close()
    assert len(shots) == 2 and sum(len(s) for s in shots) > 0
    assert len(maps[0]) == len(maps[1])
    for a, b in zip(*maps):
        assert np.array_equal(a, b)


def test_stored_blocks_hold_what_one_block_holds():
    rng = np.random.default_rng(3)
    pool = _Buffers()
    stored = _Stored(100, pool)
    want = [np.empty((0, 3), np.float32)] * 4 + [np.empty(0, np.uint8)]
    for m in (60, 30, 90, 250, 5):  # the 3rd and 4th overflow their block
        rows = rng.integers(1, m + 1)
        arrays = store_arrays(rows)
        for a in arrays:
            a[...] = rng.random(a.shape) * 200
        room = stored.room(m)
        # (the radiance array, Clamp Indirect's (photonclamp), has no rows without it)
        assert all(len(r) >= m for r in room[:8]) and len(room[8]) == 0
        for r, a in zip(room, arrays):
            r[:rows] = a
        stored.count += rows
        want = [np.concatenate([w, a]) for w, a in zip(want, arrays)]
    assert len(stored.blocks) >= 2
    shot = _Shot(10)
    shot.append(stored, 10)
    stored.release()
    got = shot.photons()
    for w, name in zip(want, ("position", "power", "direction", "normal", "kind")):
        assert np.array_equal(getattr(got, name), w)
    # Released blocks are lent again: the smallest that fits.
    sizes = sorted(len(a[0]) for _, a in pool._free)
    assert len(pool.take(store_arrays, sizes[0])[0]) == sizes[0]


def test_a_direct_shot_grows_and_trims_and_holds_what_one_block_holds():
    """A shot stored into directly (one thread, photons._Shot direct) by chunks whose
    photons outgrow its first reserve (DIRECT_ROWS per photon) holds the chunks' rows in
    order, and photons() cuts the spare rows off (in place) to C-contiguous arrays."""
    rng = np.random.default_rng(5)
    pool = _Buffers()
    shot = _Shot(10, direct=True)
    want = [np.empty((0, 3), np.float32)] * 4 + [np.empty(0, np.uint8)]
    for chunk in range(2):
        shot.begin(5)
        stored = _Stored(0, pool, shot)
        for m in (400, 900, 30):  # past 2 x 10 + 1024 rows in the first chunk
            rows = int(rng.integers(m // 2, m + 1))
            arrays = store_arrays(rows)
            for a in arrays:
                a[...] = rng.random(a.shape) * 200
            room = stored.room(m)
            assert all(len(r) >= m for r in room[:8]) and len(room[8]) == 0
            for r, a in zip(room, arrays):
                r[:rows] = a
            stored.count += rows
            want = [np.concatenate([w, a]) for w, a in zip(want, arrays)]
        shot.commit(stored, 5)
        shot.append(stored, 5 * (chunk + 1))  # copies nothing: already there
        stored.release()
    assert not pool._free  # nothing was borrowed
    got = shot.photons()
    for w, name in zip(want, ("position", "power", "direction", "normal", "kind")):
        assert np.array_equal(getattr(got, name), w)
        assert getattr(got, name).flags.c_contiguous


def test_lent_buffers_give_the_photons_of_fresh_ones(monkeypatch):
    """Many chunks on one and two threads reuse each other's buffers; the photons are
    those of a trace that allocates every buffer afresh (the code before the pool)."""
    scene = cornell_box(16, 12)
    shots = []
    for workers, fresh in ((1, True), (1, False), (2, False)):
        st = RenderSettings(photons=60_000, workers=workers, chunk_size=8192)
        ctx = prepare_context(scene, st)
        with monkeypatch.context() as mp:
            if fresh:
                mp.setattr(_Buffers, "take", lambda self, make, rows: make(rows))
            counts = allocate_photons(ctx.lights, st.photons)
            shots.append(trace_photons(ctx, ctx.lights, counts, False, 1))
        ctx.accel.close()
    for other in shots[1:]:
        for name in ("position", "power", "direction", "normal", "kind"):
            assert np.array_equal(getattr(shots[0], name), getattr(other, name)), name


def test_photon_hit_view_beside_the_camera_pass_is_the_view_after_it():
    scene = cornell_box(48, 36)
    films = [render(scene, RenderSettings(photons=20_000, caustic_photons=5_000, spp=4,
                                          workers=w, show_photons=True)) for w in (1, 2)]
    assert films[0].stats["photon_hits_shown"] > 0
    assert films[0].stats["photon_hits_shown"] == films[1].stats["photon_hits_shown"]
    assert films[0].stats["photon_hits_fraction"] == films[1].stats["photon_hits_fraction"]
    assert np.array_equal(films[0].photon_hits, films[1].photon_hits)
    assert np.array_equal(films[0].combined, films[1].combined)
