"""engine.parallel.Trace (bench/bench_scaling.py's critical path): the jobs' tree, their
work and span, and that tracing changes no result (1 and 2 workers bitwise)."""
import time

import numpy as np
import pytest

from engine import RenderSettings, parallel
from engine.api import cornell_box
from engine.parallel import Group, Task, Trace, ordered_map, run_cancellable, run_tasks
from engine.render import render


def _busy(seconds):
    """Spin for `seconds` of this thread's CPU (thread_time: what the trace records)."""
    t0 = time.thread_time()
    x = 0
    while time.thread_time() - t0 < seconds:
        x += 1
    return x


def test_span_schedules_each_group_in_order_on_its_threads():
    # Hand-made tree: the root's own 1 s, then a group of 2 threads running jobs of
    # 3, 1, 1, 2 s (in-order dispatch to the first free thread: [3] and [1, 1, 2] -> 4),
    # then an inline group (its CPU inside the root's) of 0.5 s.
    root = Task()
    g = Group(2, inline=False)
    for c in (3.0, 1.0, 1.0, 2.0):
        t = Task()
        t.cpu = c
        g.tasks.append(t)
    inline = Group(2, inline=True)
    t = Task()
    t.cpu = 0.5
    inline.tasks.append(t)
    root.groups += [g, inline]
    root.cpu = 1.5  # its own 1 s + the inline job's 0.5 s
    assert root.own() == pytest.approx(1.0)
    assert root.work() == pytest.approx(1.0 + 7.0 + 0.5)
    assert root.span() == pytest.approx(1.0 + 4.0 + 0.5)
    assert g.threads == 2 and inline.threads == 1


@pytest.mark.parametrize("threads", [1, 2])
def test_trace_records_nested_pools_and_their_cpu(threads):
    def inner(x, stop):
        _busy(0.01)
        return x

    def outer(x, stop):
        return sum(ordered_map(inner, range(3), threads))

    trace = Trace()
    c0 = time.thread_time()
    with parallel.tracing(trace):
        out = list(ordered_map(outer, range(4), threads))
    trace.root.cpu = time.thread_time() - c0  # the caller's own CPU (inline jobs' inside)
    assert out == [3] * 4
    (g,) = trace.root.groups
    assert len(g.tasks) == 4 and g.inline == (threads <= 1) and "outer" in g.name
    for t in g.tasks:
        (h,) = t.groups
        assert len(h.tasks) == 3 and "inner" in h.name
        assert all(c.cpu >= 0.009 for c in h.tasks)
        assert t.work() >= 0.027
    work = trace.root.work()
    assert work >= 12 * 0.009
    # One thread: the span is the work. Two: nested pools overlap in the span (it counts
    # no contention between them), so span <= work, and the time on 2 cores is at
    # least half the work.
    span = trace.root.span()
    if threads == 1:
        assert span == pytest.approx(work)
    else:
        assert max(c.cpu for t in g.tasks for c in t.groups[0].tasks) <= span <= work + 1e-9
    assert trace.root.time_on(2) == pytest.approx(max(span, work / 2))
    assert parallel._trace is None  # tracing ends with the block


def test_run_cancellable_and_run_tasks_are_traced():
    trace = Trace()
    with parallel.tracing(trace):
        a = run_cancellable(lambda stop: run_tasks([lambda s: _busy(0.01) * 0 + 1,
                                                    lambda s: 2], 2), lambda: False)
    assert a == [1, 2]
    (g,) = trace.root.groups
    assert not g.inline and g.threads == 1
    (h,) = g.tasks[0].groups
    assert len(h.tasks) == 2 and h.tasks[0].cpu >= 0.009


def test_tracing_changes_no_image_and_one_equals_two_workers():
    s = cornell_box(32, 24)
    films = {}
    for traced in (False, True):
        for w in (1, 2):
            settings = RenderSettings(spp=4, photons=20_000, workers=w, chunk_size=2048)
            if traced:
                with parallel.tracing(Trace()) as trace:
                    f = render(s, settings)
                assert trace.root.groups, "the render's pools were not traced"
            else:
                f = render(s, settings)
            films[traced, w] = np.concatenate([f.direct, f.indirect, f.caustic, f.specular])
    ref = films[False, 1]
    for key, f in films.items():
        assert np.array_equal(f, ref), key


def test_without_should_cancel_the_caller_waits_once_per_chunk(monkeypatch):
    # ordered_map's calling thread sleeps on the head chunk (no 20 ms polls, each of
    # which took the GIL from a worker); with should_cancel it polls.
    calls = []
    real_wait = parallel.wait

    def counting_wait(fs, timeout=None):
        calls.append(timeout)
        return real_wait(fs, timeout=timeout)

    monkeypatch.setattr(parallel, "wait", counting_wait)  # the calling thread's only

    def job(x, stop):
        time.sleep(0.15)
        return x

    assert list(ordered_map(job, range(4), 2)) == [0, 1, 2, 3]
    assert calls == [None] * 4
    calls.clear()
    assert list(ordered_map(job, range(4), 2, lambda: False)) == [0, 1, 2, 3]
    assert len(calls) > 4 and set(calls) == {parallel.POLL_SECONDS}
