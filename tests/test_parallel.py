"""Chunks on worker threads (engine/parallel.py): order, cancellation, errors, and the
image does not depend on the number of threads."""
import threading
import time

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.parallel import Cancelled, ordered_map
from engine.render import render


def _slow_square(x, stop):
    time.sleep(0.002 * ((7 * x) % 5))  # finish out of order
    return x * x


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_results_come_back_in_order(threads):
    assert list(ordered_map(_slow_square, range(20), threads)) == [x * x for x in range(20)]


def test_callbacks_stay_on_the_calling_thread_and_cancel_stops_the_workers():
    caller = threading.current_thread()
    asked_from = set()
    seen_stop = []
    started = threading.Event()

    def job(x, stop):
        started.set()
        t0 = time.perf_counter()
        while not stop() and time.perf_counter() - t0 < 10:
            time.sleep(0.005)
        seen_stop.append(stop())
        raise Cancelled()

    def should_cancel():
        asked_from.add(threading.current_thread())
        return started.is_set()

    t0 = time.perf_counter()
    with pytest.raises(Cancelled):
        list(ordered_map(job, range(8), 2, should_cancel))
    assert time.perf_counter() - t0 < 5, "workers did not see the stop flag"
    assert asked_from == {caller}
    # ordered_map does not wait for running chunks (cancel returns at once): they see
    # the flag and end on their own.
    while len(seen_stop) < 2 and time.perf_counter() - t0 < 5:
        time.sleep(0.01)
    assert seen_stop and all(seen_stop)


def test_a_worker_error_reaches_the_caller():
    def job(x, stop):
        if x == 3:
            raise ValueError("chunk 3 broke")
        return x

    with pytest.raises(ValueError, match="chunk 3 broke"):
        list(ordered_map(job, range(6), 2))


def test_thread_count_does_not_change_the_image_over_many_chunks():
    # 96x72 x 16 spp = 110,592 samples: 4 camera chunks; 80k photons: 4 photon chunks.
    s = cornell_box(96, 72)
    st = dict(photons=80000, caustic_photons=40000, spp=16, seed=3)
    images = [s.render(RenderSettings(workers=w, **st)).combined for w in (1, 2, 3)]
    np.testing.assert_array_equal(images[0], images[1])
    np.testing.assert_array_equal(images[0], images[2])


def test_cancel_during_the_camera_pass_returns_the_finished_part():
    scene = cornell_box(96, 72)  # x 16 spp: 4 camera chunks
    calls = {"render": 0}

    def progress(stage, fraction, text):
        if stage == "render":
            calls["render"] += 1

    def should_cancel():
        return calls["render"] >= 2  # after two camera chunks

    film = render(scene, RenderSettings(photons=5000, caustic_photons=0, spp=16, workers=2),
                  progress=progress, should_cancel=should_cancel)
    assert film.stats["cancelled"]
    img = film.combined
    assert np.isfinite(img).all()
    rows_done = (img.sum(axis=(1, 2)) > 0).sum()
    assert 0 < rows_done < img.shape[0]  # top rows rendered, the rest left black


@pytest.mark.parametrize("threads", [1, 2])
def test_cancel_keeps_every_chunk_handed_over_before_it(threads):
    """The caller cancels after taking three results: it has exactly those three, on one
    thread or two (a finished chunk is never dropped)."""
    got = []

    def should_cancel():
        return len(got) >= 3

    with pytest.raises(Cancelled):
        for r in ordered_map(_slow_square, range(10), threads, should_cancel):
            got.append(r)
    assert got == [0, 1, 4]


@pytest.mark.parametrize("workers", [1, 2])
def test_cancel_is_noticed_inside_a_chunk(workers):
    """One camera chunk of a final-gather render holds seconds of work; the stop flag is
    polled inside final gathering, so a cancel does not wait for whole chunks (no hang)."""
    scene = cornell_box(120, 90)
    t_cancel = []

    def should_cancel():
        if not t_cancel:
            t_cancel.append(time.perf_counter() + 1.0)  # cancel 1 s into the render
        return time.perf_counter() > t_cancel[0]

    film = render(scene, RenderSettings(photons=20000, caustic_photons=0, spp=128,
                                        workers=workers), should_cancel=should_cancel)
    late = time.perf_counter() - t_cancel[0]
    assert film.stats["cancelled"]
    assert late < 3.0, late  # a full render takes far longer (~10 s)


@pytest.mark.parametrize("total,limit", [(160 * 120 * 128, 1 << 17), (320 * 240 * 128, 1 << 17),
                                         (64 * 48 * 64, 1 << 15), (96 * 72 * 16, 1 << 17),
                                         (100, 1 << 17), (1, 256), (0, 1 << 17)])
def test_chunk_bounds_cover_the_pass_and_end_in_pieces(total, limit, monkeypatch):
    from engine import parallel
    from engine.parallel import MIN_CHUNK, MIN_CHUNKS, TAIL_CHUNKS, chunk_bounds, chunk_length
    chunk = chunk_length(total, limit)
    plain = [(a, min(total, a + chunk)) for a in range(0, total, chunk)]
    # Off by default: the chunks of chunk_length (the images of whole chunks).
    assert chunk_bounds(total, limit) == plain
    monkeypatch.setattr(parallel, "TAIL_SPLIT", 4)
    bounds = chunk_bounds(total, limit)
    assert [a for a, _ in bounds[1:]] == [b for _, b in bounds[:-1]]  # contiguous
    assert (bounds[0][0], bounds[-1][1]) == (0, total) if total else bounds == []
    sizes = [b - a for a, b in bounds]
    assert all(0 < n <= min(limit, chunk) for n in sizes)
    if len(plain) <= MIN_CHUNKS or chunk < 2 * MIN_CHUNK:
        assert bounds == plain  # short passes and small chunks: as chunk_length cuts them
        return
    # Whole chunks as chunk_length cuts them, then pieces over the last 2-3 chunk lengths.
    whole = [ab for ab in bounds if ab[1] - ab[0] == chunk]
    assert whole == plain[:len(whole)]
    tail = total - whole[-1][1]
    assert TAIL_CHUNKS * chunk <= tail < (TAIL_CHUNKS + 1) * chunk
    piece = max(MIN_CHUNK, chunk // 4)
    assert all(n == piece for n in sizes[len(whole):-1]) and sizes[-1] <= piece


def test_pieces_at_the_end_change_only_the_tail_and_not_with_the_thread_count(monkeypatch):
    """parallel.TAIL_SPLIT = 4, 64x48 x 64 spp with chunk_size 32768: 4 chunks, then 4
    pieces of 16384 samples. The image is the same bits for 1, 2 and 3 threads, and the
    rows rendered by the whole chunks are the same bits as with whole chunks only (the
    default; the pieces own new streams)."""
    from engine import parallel
    from engine.parallel import chunk_bounds
    s = cornell_box(64, 48)
    st = dict(photons=20000, caustic_photons=10000, spp=64, seed=5, chunk_size=1 << 15)
    whole = s.render(RenderSettings(workers=2, **st)).combined
    monkeypatch.setattr(parallel, "TAIL_SPLIT", 4)
    bounds = chunk_bounds(64 * 48 * 64, 1 << 15)
    assert len(bounds) == 8 and bounds[4] == (4 << 15, (4 << 15) + 16384)
    images = [s.render(RenderSettings(workers=w, **st)).combined for w in (1, 2, 3)]
    np.testing.assert_array_equal(images[0], images[1])
    np.testing.assert_array_equal(images[0], images[2])
    rows = (4 << 15) // 64 // 64  # rows whose samples all lie in the first 4 chunks
    assert rows == 32
    np.testing.assert_array_equal(images[0][:rows], whole[:rows])
    assert not np.array_equal(images[0][rows:], whole[rows:])  # the pieces' new streams


def test_light_items_run_ahead_of_a_slow_head_chunk():
    """Items weighing a quarter of a chunk (the camera pass's tail pieces): with 2 threads
    up to 4 chunks' weight is in flight, so a worker goes on to item 6 while item 0 still
    runs (with every item weighing 1 it would wait for item 0 after item 3); results still
    come back in order."""
    reached = threading.Event()

    def job(x, stop):
        if x == 0:
            return reached.wait(10)  # True once item 6 has started beside it
        if x == 6:
            reached.set()
        return x

    out = list(ordered_map(job, range(10), 2, weight=lambda x: 1 if x == 0 else 0.25))
    assert out == [True] + list(range(1, 10))
