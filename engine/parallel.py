"""Chunks of a pass run on worker threads; results come back in chunk order.

Embree, scipy's kd-tree and numpy's array kernels release the GIL, so whole chunks
(camera samples, photons) running on two threads keep both cores busy, also through the
numpy shading between the Embree calls. Each chunk owns its random stream (seeded by
its index) and its results are merged in chunk order on the calling thread, so the image
does not depend on the number of threads.

Callbacks (progress, should_cancel) are only ever called on the calling thread: Blender's
RenderEngine API must not be touched from other threads. Worker chunks poll a StopFlag
instead, which compiled kernels poll too (its one-byte array), so a cancel reaches the
middle of a long compiled step (a photon-map estimate of 60k rows, a kd-tree build).
"""
from __future__ import annotations

import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor, wait
from contextlib import contextmanager

import numpy as np

# Pools shut down without waiting for their running chunks (after a cancel), with the
# root StopFlag of the work that made them (None: no flag): drain(owner) joins those of
# one owner when it must leave no thread behind (engine/session.py's stop), while the
# others end on their own in the background.
_draining: list = []  # [(owner, pool)]
_draining_lock = threading.Lock()


def _alive(pool) -> bool:
    return any(t.is_alive() for t in getattr(pool, "_threads", ()))


def _let_drain(pool, owner=None):
    pool.shutdown(wait=False, cancel_futures=True)
    with _draining_lock:
        # Pools whose threads all ended need no join (keeps the list short when a
        # viewport session cancels on every edit).
        _draining[:] = [(o, p) for o, p in _draining if _alive(p)]
        _draining.append((owner, pool))


def drain(owner=None) -> None:
    """Wait for the chunks still running in pools that a cancel left behind (each stops
    at its next check of stop()), so no worker thread outlives the caller's work.
    owner: a StopFlag - only the pools of work polled through it (or through flags
    linked to it, StopFlag.link) are joined; None joins every pool in the process."""
    while True:
        with _draining_lock:
            index = next((i for i, (o, _) in enumerate(_draining)
                          if owner is None or o is owner), None)
            if index is None:
                return
            _, pool = _draining.pop(index)
        pool.shutdown(wait=True)


def pools_left(owner=None) -> int:
    """How many cancelled pools of `owner` (None: of anyone) still have live threads."""
    with _draining_lock:
        return sum(1 for o, p in _draining if (owner is None or o is owner) and _alive(p))


class Cancelled(Exception):
    """Raised inside the passes when the caller asked to stop."""


class StopFlag(threading.Event):
    """A threading.Event that compiled kernels can poll: `array` (1,) uint8 turns 1 when
    the flag is set, and so do the flags linked to it (the flag of an inner ordered_map
    or run_cancellable, set at once instead of at the caller's next poll). Calling it is
    is_set(), so it serves as a job's stop() and as a should_cancel()."""

    def __init__(self):
        super().__init__()
        self.array = np.zeros(1, np.uint8)
        self.root = self  # the flag this one is linked from, transitively (drain's owner)
        self._linked = []
        self._link_lock = threading.Lock()

    def __call__(self) -> bool:
        return self.array[0] != 0

    def set(self):
        self.array[0] = 1
        super().set()
        with self._link_lock:
            linked = list(self._linked)
        for flag in linked:
            flag.set()

    def clear(self):
        self.array[0] = 0
        super().clear()

    def link(self, child: "StopFlag") -> None:
        """Set child whenever this flag is set (now, if it is set already)."""
        child.root = self.root
        with self._link_lock:
            self._linked.append(child)
        if self():
            child.set()

    def unlink(self, child: "StopFlag") -> None:
        with self._link_lock:
            if child in self._linked:
                self._linked.remove(child)


_current = threading.local()


def _never() -> bool:
    return False


def stop_flag_of(should_cancel) -> StopFlag | None:
    """The StopFlag behind should_cancel (the flag itself or its is_set), else the flag of
    the ordered_map / run_cancellable job running on this thread, else None."""
    for f in (should_cancel, getattr(should_cancel, "__self__", None)):
        if isinstance(f, StopFlag):
            return f
    return getattr(_current, "flag", None)


def stop_array(should_cancel=None) -> np.ndarray:
    """The (1,) uint8 array a compiled kernel polls for should_cancel (stop_flag_of), or a
    zero array that never turns 1."""
    flag = stop_flag_of(should_cancel)
    return flag.array if flag is not None else np.zeros(1, np.uint8)


@contextmanager
def polled_by(flag: StopFlag):
    """Within: `flag` is this thread's current stop flag (stop_flag_of), so the chunks
    and compiled steps started here poll it and their pools belong to its root (drain)."""
    before = getattr(_current, "flag", None)
    _current.flag = flag
    try:
        yield flag
    finally:
        _current.flag = before


def _with_flag(job, flag):
    """job(*args) run with flag as this thread's current stop flag (stop_flag_of)."""
    def run(*args):
        before = getattr(_current, "flag", None)
        _current.flag = flag
        try:
            return job(*args)
        finally:
            _current.flag = before
    return run


# ---------------------------------------------------------------------------- the tracer

class Trace:
    """Work and span of the jobs the pools run, for bench/bench_scaling.py's critical path
    (off unless a caller installs one with `tracing`, before the work starts and from the
    calling thread: the workers only read it).

    Each ordered_map / run_cancellable call made while a Trace is on becomes a Group (its
    thread count, inline or not) under the job running on the calling thread (or under
    the trace's root). Each job records its own thread's CPU (time.thread_time), which
    leaves out the threads of the groups it starts; with `inline` groups the children's
    CPU is inside their parent's and is taken out again (Task.own)."""

    def __init__(self):
        self.root = Task()
        self._lock = threading.Lock()

    def group(self, threads: int, inline: bool, name: str = "") -> "Group":
        g = Group(threads, inline, name)
        parent = getattr(_current, "task", None) or self.root
        with self._lock:
            parent.groups.append(g)
        return g


class Group:
    """One ordered_map / run_cancellable call: its jobs (Tasks, in dispatch order) and the
    threads they ran on (1 when inline on the caller's thread)."""

    def __init__(self, threads: int, inline: bool, name: str = ""):
        self.threads = 1 if inline else max(1, threads)
        self.inline = inline
        self.name = name  # the job's qualified name
        self.tasks: list = []
        self._lock = threading.Lock()

    def wrap(self, job):
        """job(*args) run as one of this group's tasks, in submission order."""
        task = Task()
        with self._lock:
            self.tasks.append(task)

        def run(*args):
            before = getattr(_current, "task", None)
            _current.task = task
            task.thread = threading.get_native_id()
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return job(*args)
            finally:
                task.cpu = time.thread_time() - c0
                task.wall = time.perf_counter() - t0
                _current.task = before
        return run


class Task:
    """One job: its thread's CPU and wall seconds while it ran, and the groups it started."""

    def __init__(self):
        self.cpu = 0.0  # its thread's CPU s while it ran (inline children included)
        self.wall = 0.0
        self.thread = None
        self.groups: list = []

    def own(self) -> float:
        """CPU s of this task's own code (inline children taken out). A root task's cpu
        is set by whoever traces (Trace's callers: the calling thread's CPU)."""
        return max(0.0, self.cpu - sum(t.cpu for g in self.groups if g.inline
                                       for t in g.tasks))

    def work(self) -> float:
        """CPU s of this task and everything it started."""
        return self.own() + sum(t.work() for g in self.groups for t in g.tasks)

    def span(self) -> float:
        """CPU s on the critical path: its own code, then each group's jobs (their spans)
        dispatched in order to the group's threads, each to the first thread free (as a
        ThreadPoolExecutor takes them), with no wait for cores, locks or the GIL."""
        total = self.own()
        for g in self.groups:
            free = [0.0] * g.threads
            for t in g.tasks:
                i = free.index(min(free))
                free[i] += t.span()
            total += max(free) if free else 0.0
        return total

    def time_on(self, cores: int) -> float:
        """The least time this task's work can take on `cores` idle cores: its span, or
        its work spread evenly where nested pools hold more threads than cores."""
        return max(self.span(), self.work() / max(1, cores))


_trace: Trace | None = None


@contextmanager
def tracing(trace: Trace):
    """Within: the pools' jobs started on any thread are recorded in `trace`."""
    global _trace
    before, _trace = _trace, trace
    try:
        yield trace
    finally:
        _trace = before


# How often the calling thread asks should_cancel while chunks run: a stop within 0.2 s
# (the viewport, issue 19) needs the poll well under that.
POLL_SECONDS = 0.02

# A pass is cut into at least MIN_CHUNKS chunks, so small jobs use both cores, of at least
# MIN_CHUNK items: two threads running numpy on small arrays spend their time handing the
# GIL back and forth (measured: 8 camera chunks of 5k samples ran slower on 2 threads than
# on 1; 4 chunks of >= 16k gave 1.73x on a 160x120 render).
MIN_CHUNKS = 4
MIN_CHUNK = 16384


_once_lock = threading.Lock()


def once_on(obj, attr: str, make):
    """make()'s result, made once per object and kept on it as obj.<attr> (double-checked
    under a lock: the camera's and the photons' worker threads ask for it alike)."""
    got = getattr(obj, attr, _UNSET)
    if got is not _UNSET:
        return got
    with _once_lock:
        got = getattr(obj, attr, _UNSET)
        if got is _UNSET:
            got = make()
            setattr(obj, attr, got)
    return got


_UNSET = object()


def chunk_length(total: int, limit: int) -> int:
    """Items per chunk for `total` items, at most `limit` (settings.chunk_size: memory).
    It depends on the job and the settings only, never on the number of threads, so each
    chunk's random stream, and so the image, is the same for any thread count."""
    return max(1, min(limit, max(MIN_CHUNK, -(-total // MIN_CHUNKS))))


def ordered_map(job, items, threads: int, should_cancel=None, on_all_started=None):
    """Yield job(item, stop) for each item, in order. on_all_started() is called on the
    calling thread once the last item has been handed to a worker (the pass's tail,
    where workers fall idle one by one; not called inline or when stopped early). stop() tells a running job that the
    caller cancelled (it should raise Cancelled); it is a StopFlag whose array compiled
    kernels poll (stop_array), linked to should_cancel's flag if that is one. At most 2 x threads chunks are in
    flight (one with threads <= 1), which bounds memory. Raises Cancelled when
    should_cancel() returns True. Without should_cancel and with threads <= 1 the jobs
    run inline; with should_cancel they run on worker threads while this thread polls it
    every POLL_SECONDS, so a cancel is seen within that even when a job's step between
    two checks of stop() takes seconds (a camera chunk's first bounce)."""
    items = list(items)
    inline = should_cancel is None and (threads <= 1 or len(items) <= 1)
    if _trace is not None:
        # Each item with its task, made here in the items' order (the dispatch order).
        group = _trace.group(threads, inline, getattr(job, "__qualname__", ""))
        items = [(group.wrap(job), item) for item in items]

        def job(pair, stop):
            return pair[0](pair[1], stop)
    if inline:
        # Inline on this thread: the stop of the job this thread runs, if any.
        stop = stop_flag_of(None) or _never
        for item in items:
            yield job(item, stop)
        return
    threads = max(1, threads)
    in_flight = 2 * threads if threads > 1 else 1
    event = StopFlag()
    parent = stop_flag_of(should_cancel)
    if parent is not None:
        parent.link(event)
    owner = event.root if parent is not None else None
    run = _with_flag(job, event)
    pending = deque()
    todo = iter(items)
    pool = ThreadPoolExecutor(threads)
    try:
        left = len(items)
        for item in todo:
            pending.append(pool.submit(run, item, event))
            left -= 1
            if len(pending) >= in_flight:
                break
        if left == 0 and on_all_started is not None:
            on_all_started()
        while pending:
            # Checked before each chunk is awaited, after the one before it was
            # handed over: a finished chunk is never dropped (as inline).
            if should_cancel is not None and should_cancel():
                raise Cancelled()
            head = pending[0]
            # Without should_cancel nothing needs polling: this thread sleeps until the
            # chunk is done (each poll takes the GIL from a worker: 50 a second).
            while not wait([head], timeout=None if should_cancel is None
                           else POLL_SECONDS).done:
                if should_cancel():
                    raise Cancelled()
            pending.popleft()
            result = head.result()  # re-raises a worker's exception here
            for item in todo:
                pending.append(pool.submit(run, item, event))
                left -= 1
                if left == 0 and on_all_started is not None:
                    on_all_started()
                break
            yield result
    finally:
        # Cancelled, an error, or the consumer stopped early: let running chunks stop
        # at their next check and drop the ones not started. Running chunks are not
        # waited for (a chunk's step between two checks can take seconds): the caller
        # returns within POLL_SECONDS of the cancel and their results are dropped.
        event.set()
        if parent is not None:
            parent.unlink(event)
        for f in pending:
            f.cancel()
        _let_drain(pool, owner)


def run_tasks(tasks, threads: int, should_cancel=None) -> list:
    """[task(stop) for task in tasks]: independent steps (a photon map's build: kd-trees
    over disjoint photon sets, the radius's k-NN, the neighbour lists) run side by side
    on up to `threads` threads, so neither core waits for the other's step. Each task
    computes what it would alone (no shared state), so the results do not depend on the
    thread count. Inline in order with threads <= 1 and no should_cancel; otherwise as
    ordered_map runs its jobs (stop, cancel and errors alike), all of them at once when
    there are at most 2 x threads."""
    return list(ordered_map(lambda task, stop: task(stop), tasks, threads, should_cancel))


def run_cancellable(job, should_cancel=None):
    """Return job(stop), run on a worker thread while the calling thread asks
    should_cancel() every POLL_SECONDS, for one long step that has no chunks of its own
    (a photon map's build). On a cancel, stop() turns True for the job, which should end
    at its next check, and Cancelled is raised at once: the job's result is dropped (it
    must not change shared state). stop is a StopFlag: compiled steps poll its array
    (stop_array). Without should_cancel the job runs inline."""
    if _trace is not None:
        job = _trace.group(1, should_cancel is None,
                           getattr(job, "__qualname__", "")).wrap(job)
    if should_cancel is None:
        return job(lambda: False)
    event = StopFlag()
    parent = stop_flag_of(should_cancel)
    if parent is not None:
        parent.link(event)
    owner = event.root if parent is not None else None
    pool = ThreadPoolExecutor(1)
    try:
        future = pool.submit(_with_flag(job, event), event)
        while not wait([future], timeout=POLL_SECONDS).done:
            if should_cancel():
                event.set()
                raise Cancelled()
        return future.result()
    finally:
        if parent is not None:
            parent.unlink(event)
        _let_drain(pool, owner)
