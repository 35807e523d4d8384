"""Photon pass vs raw Embree on the same rays (Figure 6 box with the glass ball).

    .venv/bin/python bench/bench_photon_pass.py [CHECKOUT] [PHOTONS] [--split] [--small-pages]

CHECKOUT (default: this one) is put first on sys.path, so an older checkout's engine can be
measured by the same script; PHOTONS defaults to 500000. Prints one line per worker count:
photons/s, the traced rays, and the engine's time against raw embreex replaying the
recorded rays (bench_core.raw_embree_time), best of 3, as wall time and as CPU time of the
process (time.process_time: all threads; on a shared machine the CPU-time ratio moves
less with the load than the wall-time one). The engine is timed with the query log off
(the RecordingAccel's copies of every ray are the benchmark's, not the engine's); one
logged trace then records the rays for the replay. "first" is the CPU time of the
process's first trace (cold: what a render's one photon pass costs, page faults of fresh
buffers included), the other columns the best of 3 after it; "faults" and "sys" are the
process's minor page faults and system CPU s of the first trace and the median of the
warm ones (getrusage). --small-pages traces inside render.small_pages() (numpy's
huge-page advice off, as a render runs the pass: 4 KB pages, so several times the faults
of the default run, whose arrays of >= 4 MB may get 2 MB pages).

--split adds, for one worker, where a warm trace's CPU goes (best of 3, thread CPU time):
the Embree calls (Accel.intersect_hits; Accel.intersect in older checkouts), the scatter
kernel, the copies into the shot (_Shot.append) and the rest (emission kernels and Python
glue), against raw embreex on the same rays; the scatter calls per bounce (late bounces
carry few photons); and the Embree calls alone on the recorded rays, raw embreex against
Accel.intersect(_hits), interleaved in this process (the comparison that moves least with
the load).
"""
import contextlib
import os
import resource
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
split = "--split" in sys.argv
small = "--small-pages" in sys.argv
args = [a for a in sys.argv[1:] if a not in ("--split", "--small-pages")]
root = os.path.abspath(args[0]) if args else os.path.dirname(HERE)
photons = int(args[1]) if len(args) > 1 else 500_000
sys.path.insert(0, os.path.join(root, "bench"))
sys.path.insert(0, root)
sys.path.insert(2, HERE)

from engine.jit import ensure_compiled  # noqa: E402
from bench_scaling import box, make_ctx  # noqa: E402
from bench_core import raw_embree_time  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402
from engine.lights import allocate_photons  # noqa: E402
from engine.photons import trace_photons  # noqa: E402


def best_of(n, fn):
    """(best wall s, best CPU s, last result) of n calls."""
    wall = cpu = float("inf")
    out = None
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu, out


def faulted(fn):
    """(minor page faults, system CPU s, result) of fn() for the whole process."""
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    out = fn()
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    return r1.ru_minflt - r0.ru_minflt, r1.ru_stime - r0.ru_stime, out


def print_split(ctx, counts, raw_cpu):
    """Where one warm trace's thread CPU goes (best of 3 per part), and per bounce."""
    import engine.photons as photons_mod
    from engine import photonkernels as pk
    from engine.accel import Accel
    spent, per_bounce = {}, {}
    # (object, attribute, part): Embree's calls through Accel.intersect_hits (the photon
    # pass's own since the tenth slice) or Accel.intersect (before it) count as one part.
    patched = [(pk, "scatter", "scatter"), (Accel, "intersect", "intersect"),
               (photons_mod._Shot, "append", "append")]
    if hasattr(Accel, "intersect_hits"):
        patched.append((Accel, "intersect_hits", "intersect"))
    originals = [getattr(obj, name) for obj, name, _ in patched]
    parts = ("intersect", "scatter", "append")

    def timed(fn, part):
        def call(*a, **k):
            t0 = time.thread_time()
            out = fn(*a, **k)
            dt = time.thread_time() - t0
            spent[part] = spent.get(part, 0.0) + dt
            if part == "scatter":
                row = per_bounce.setdefault(a[1], [0, 0, 0.0])
                row[0] += 1
                row[1] += len(a[2])
                row[2] += dt
            return out
        return call

    best = {}
    try:
        for (obj, name, part), fn in zip(patched, originals):
            setattr(obj, name, timed(fn, part))
        for _ in range(3):
            spent.clear()
            per_bounce.clear()
            t0 = time.thread_time()
            trace_photons(ctx, ctx.lights, counts, False, 1)
            spent["total"] = time.thread_time() - t0
            spent["rest"] = spent["total"] - sum(spent.get(n, 0.0) for n in parts)
            for part, dt in spent.items():
                best[part] = min(best.get(part, float("inf")), dt)
    finally:
        for (obj, name, _), fn in zip(patched, originals):
            setattr(obj, name, fn)
    print("| part (1 worker, warm) | CPU s | share |")
    print("|---|---:|---:|")
    labels = {"intersect": "Embree via Accel.intersect(_hits)", "scatter": "scatter kernel",
              "append": "_Shot.append", "rest": "emission kernels + Python glue",
              "total": "total"}
    for part in ("intersect", "scatter", "append", "rest", "total"):
        print(f"| {labels[part]} | {best[part]:.3f} | {100 * best[part] / best['total']:.0f} % |")
    print(f"| raw embreex, same rays (process CPU) | {raw_cpu:.3f} | |")
    print("| bounce | scatter calls | rays | scatter CPU s (last trace) |")
    print("|---:|---:|---:|---:|")
    for b in sorted(per_bounce):
        calls, rays, dt = per_bounce[b]
        print(f"| {b} | {calls} | {rays:,} | {dt:.4f} |")


def print_embree_calls(rec, log):
    """The Embree calls alone on a trace's recorded rays, interleaved in this process
    (thread CPU, best of 5): raw embreex, Accel.intersect (int64 ids, float64 copies) and,
    where the checkout has them, Accel.intersect_hits (Embree's own arrays, the photon
    pass's call in the tenth slice) and intersect_hits into reused arrays (the trace
    kernel, the photon pass's call since the eleventh slice)."""
    from engine.accel import Accel
    acc = rec.serial()
    scene = acc._scene
    calls = {"raw embreex": lambda o, d, t: scene.run(o, d, dists=t.copy(), output=True),
             "Accel.intersect": lambda o, d, t: Accel.intersect(acc, o, d, t)}
    if hasattr(Accel, "intersect_hits"):
        calls["Accel.intersect_hits"] = lambda o, d, t: Accel.intersect_hits(acc, o, d, t.copy())
    import inspect
    if "out" in inspect.signature(Accel.intersect_hits).parameters:
        # Into reused arrays, traced by the kernel through rtcIntersect8 (the photon
        # pass's call since the eleventh slice).
        n = max((len(e[1]) for e in log), default=0)
        ids, uv = np.empty((2, n), np.int32), np.empty((2, n), np.float32)
        calls["Accel.intersect_hits(out=)"] = lambda o, d, t: Accel.intersect_hits(
            acc, o, d, t.copy(), (ids[0][:len(o)], ids[1][:len(o)], uv[0][:len(o)],
                                  uv[1][:len(o)]))
    best = {}
    for _ in range(5):
        for name, call in calls.items():
            t0 = time.thread_time()
            for query, o, d, t in log:
                call(o, d, t)
            best[name] = min(best.get(name, float("inf")), time.thread_time() - t0)
    print("| Embree call, recorded rays (1 thread, interleaved) | CPU s |")
    print("|---|---:|")
    for name, dt in best.items():
        print(f"| {name} | {dt:.3f} |")


ensure_compiled()
pages = contextlib.nullcontext()
if small:
    import importlib
    pages = importlib.import_module("engine.render").small_pages()
pages.__enter__()
print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
      + (", small pages (render.small_pages)" if small else ""))
for workers in (1, 2):
    st = RenderSettings(photons=photons, workers=workers)
    ctx = make_ctx(box(160, 120), st)
    rec = getattr(ctx.accel, "full", ctx.accel)  # the RecordingAccel
    counts = allocate_photons(ctx.lights, st.photons)
    rec.enabled = False
    f_first, s_first, (_, first, _) = faulted(
        lambda: best_of(1, lambda: trace_photons(ctx, ctx.lights, counts, False, 1)))
    warm = [faulted(lambda: best_of(1, lambda: trace_photons(ctx, ctx.lights, counts, False, 1)))
            for _ in range(3)]
    t = min(w[2][0] for w in warm)
    c = min(w[2][1] for w in warm)
    shot = warm[-1][2][2]
    f_warm = sorted(w[0] for w in warm)[1]
    s_warm = sorted(w[1] for w in warm)[1]
    rec.enabled = True
    rec.log.clear()
    trace_photons(ctx, ctx.lights, counts, False, 1)
    log = list(rec.log)
    rec.log.clear()
    rec.enabled = False  # the split's traces: no logging copies in "rest"
    n = sum(len(e[1]) for e in log)
    raw, raw_c, _ = best_of(3, lambda: raw_embree_time(rec, log))
    print(f"{os.path.basename(root):14s} workers={workers} photons={photons:,} "
          f"stored={len(shot):,} rays={n:,} engine={t:.3f} s raw={raw:.3f} s "
          f"{photons / t / 1e6:.2f} M photons/s, {100 * raw / t:.0f} % of raw Embree; "
          f"CPU engine={c:.3f} s (first {first:.3f} s) raw={raw_c:.3f} s "
          f"{100 * raw_c / c:.0f} % of raw Embree; "
          f"{shot.nbytes / max(len(shot), 1):.0f} B/photon; faults {f_warm} (first {f_first}), "
          f"sys {s_warm:.3f} s (first {s_first:.3f} s)")
    if split and workers == 1:
        print_split(ctx, counts, raw_c)
        print_embree_calls(rec, [e for e in log if e[0] == "INTERSECT"])
    ctx.accel.close()
pages.__exit__(None, None, None)
