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
