"""Chunks of a pass run on worker threads; results come back in chunk order.

Embree, scipy's kd-tree and numpy's array kernels release the GIL, so whole chunks
(camera samples, photons) running on two threads keep both cores busy, also through the
numpy shading between the Embree calls. Each chunk owns its random stream (seeded by
its index) and its results are merged in chunk order on the calling thread, so the image
does not depend on the number of threads.

Callbacks (progress, should_cancel) are only ever called on the calling thread: Blender's
RenderEngine API must not be touched from other threads. Worker chunks poll a
threading.Event instead.
"""
from __future__ import annotations

import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor, wait

# Pools shut down without waiting for their running chunks (after a cancel): drain()
# joins them when a caller must leave no thread behind (engine/session.py's stop).
_draining: list = []
_draining_lock = threading.Lock()


def _let_drain(pool):
    pool.shutdown(wait=False, cancel_futures=True)
    with _draining_lock:
        # Pools whose threads all ended need no join (keeps the list short when a
        # viewport session cancels on every edit).
        _draining[:] = [p for p in _draining
                        if any(t.is_alive() for t in getattr(p, "_threads", ()))]
        _draining.append(pool)


def drain() -> None:
    """Wait for the chunks still running in pools that a cancel left behind (each stops
    at its next check of stop()), so no worker thread outlives the caller's work."""
    while True:
        with _draining_lock:
            if not _draining:
                return
            pool = _draining.pop()
        pool.shutdown(wait=True)


class Cancelled(Exception):
    """Raised inside the passes when the caller asked to stop."""


POLL_SECONDS = 0.1  # how often the calling thread asks should_cancel while chunks run

# A pass is cut into at least MIN_CHUNKS chunks, so small jobs use both cores, of at least
# MIN_CHUNK items: two threads running numpy on small arrays spend their time handing the
# GIL back and forth (measured: 8 camera chunks of 5k samples ran slower on 2 threads than
# on 1; 4 chunks of >= 16k gave 1.73x on a 160x120 render).
MIN_CHUNKS = 4
MIN_CHUNK = 16384


def chunk_length(total: int, limit: int) -> int:
    """Items per chunk for `total` items, at most `limit` (settings.chunk_size: memory).
    It depends on the job and the settings only, never on the number of threads, so each
    chunk's random stream, and so the image, is the same for any thread count."""
    return max(1, min(limit, max(MIN_CHUNK, -(-total // MIN_CHUNKS))))


def ordered_map(job, items, threads: int, should_cancel=None):
    """Yield job(item, stop) for each item, in order. stop() tells a running job that the
    caller cancelled (it should raise Cancelled). At most 2 x threads chunks are in
    flight (one with threads <= 1), which bounds memory. Raises Cancelled when
    should_cancel() returns True. Without should_cancel and with threads <= 1 the jobs
    run inline; with should_cancel they run on worker threads while this thread polls it
    every POLL_SECONDS, so a cancel is seen within that even when a job's step between
    two checks of stop() takes seconds (a camera chunk's first bounce)."""
    items = list(items)
    if should_cancel is None and (threads <= 1 or len(items) <= 1):
        for item in items:
            yield job(item, lambda: False)
        return
    threads = max(1, threads)
    in_flight = 2 * threads if threads > 1 else 1
    event = threading.Event()
    pending = deque()
    todo = iter(items)
    pool = ThreadPoolExecutor(threads)
    try:
        for item in todo:
            pending.append(pool.submit(job, item, event.is_set))
            if len(pending) >= in_flight:
                break
        while pending:
            # Checked before each chunk is awaited, after the one before it was
            # handed over: a finished chunk is never dropped (as inline).
            if should_cancel is not None and should_cancel():
                raise Cancelled()
            head = pending[0]
            while not wait([head], timeout=POLL_SECONDS).done:
                if should_cancel is not None and should_cancel():
                    raise Cancelled()
            pending.popleft()
            result = head.result()  # re-raises a worker's exception here
            for item in todo:
                pending.append(pool.submit(job, item, event.is_set))
                break
            yield result
    finally:
        # Cancelled, an error, or the consumer stopped early: let running chunks stop
        # at their next check and drop the ones not started. Running chunks are not
        # waited for (a chunk's step between two checks can take seconds): the caller
        # returns within POLL_SECONDS of the cancel and their results are dropped.
        event.set()
        for f in pending:
            f.cancel()
        _let_drain(pool)


def run_cancellable(job, should_cancel=None):
    """Return job(stop), run on a worker thread while the calling thread asks
    should_cancel() every POLL_SECONDS, for one long step that has no chunks of its own
    (a photon map's build). On a cancel, stop() turns True for the job, which should end
    at its next check, and Cancelled is raised at once: the job's result is dropped (it
    must not change shared state; a compiled step without checks may run on for a while
    in the background). Without should_cancel the job runs inline."""
    if should_cancel is None:
        return job(lambda: False)
    event = threading.Event()
    pool = ThreadPoolExecutor(1)
    try:
        future = pool.submit(job, event.is_set)
        while not wait([future], timeout=POLL_SECONDS).done:
            if should_cancel():
                event.set()
                raise Cancelled()
        return future.result()
    finally:
        _let_drain(pool)

