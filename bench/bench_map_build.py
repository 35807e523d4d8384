"""Photon map build (render._build_maps: kd-trees, gather map, radii) of a default render,
CPU and wall seconds, one checkout per run.

    .venv/bin/python bench/bench_map_build.py [CHECKOUT] [--blends figure6_box,...]
        [--workers 1,2] [--repeat 3]

CHECKOUT (default: this one) is put first on sys.path, so an older checkout's engine can
be measured by the same script. Each example blend is exported once through the add-on
(the bpy wheel; bench_kernels.exported) and its photon pass run at default
settings (320x240); the map build is then replayed `repeat` times on the same photons
(best CPU time of the process, time.process_time: all threads) and its result hashed:
the SHA-1 of every array and number the maps hold (maps_hash: every attribute, nested,
but the thread count and timings), so the same hash before and after, or at 1 and 2
workers, = the same maps. --trace: the build traced (engine.parallel.Trace) at each worker
count: its work (CPU s of every job) and critical path on idle cores (span), and
predicted = 1-worker work / this span (bench_scaling.py's critical_path, the maps alone).
"""
import argparse
import hashlib
import importlib
import os
import pickle
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))


SKIP = ("accel", "lookup", "workers", "counts_cache", "_lock")  # not the maps' contents
# Not maps: the secondary map's share (smooth_counts' samples a pixel), measured inside
# the build since workers55 and on the calling thread after it before; left out so that
# hashes compare across that change (tests/test_map_build_workers.py checks its value).
NOT_MAPS = ("secondary_share",)


def _digest(value, h, seen, depth=0):
    import numpy as np
    if isinstance(value, np.ndarray):
        h.update(f"{value.dtype}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, (int, float, str, bool, type(None), np.generic)):
        h.update(repr(value).encode())
    elif isinstance(value, dict):
        for key in sorted(value, key=str):
            if not str(key).startswith("time_") and key not in SKIP:
                h.update(str(key).encode())
                _digest(value[key], h, seen, depth + 1)
    elif isinstance(value, (list, tuple)):
        h.update(b"[%d" % len(value))
        for x in value:
            _digest(x, h, seen, depth + 1)
    elif id(value) not in seen and depth <= 6:
        seen.add(id(value))  # (views share arrays: each object once)
        h.update(type(value).__name__.encode())
        if hasattr(value, "__dict__"):
            _digest(vars(value), h, seen, depth + 1)


def maps_hash(out: dict) -> str:
    """SHA-1 (16 hex digits) of a map build's result: every array, number and nested
    attribute of its maps (PhotonMap, GatherMap with its views and guide, GatherCounts,
    radii), but the Embree scene, the thread count, timings and NOT_MAPS; a lazy gather
    map is completed first."""
    import hashlib
    gm = out.get("gather_map")
    if gm is not None and hasattr(gm, "complete"):
        gm.complete()
    h = hashlib.sha1()
    _digest({k: v for k, v in out.items() if k not in NOT_MAPS}, h, set())
    return h.hexdigest()[:16]


def traced_build(build, args, workers):
    """(work, span) CPU s of one map build traced (engine.parallel.Trace) as the photon
    pass runs it: under run_cancellable on the calling thread."""
    import time
    from engine import parallel
    trace = parallel.Trace()
    c0 = time.thread_time()
    with parallel.tracing(trace):
        parallel.run_cancellable(lambda stop: build(*args[:4], stop, *args[5:]))
    trace.root.cpu = time.thread_time() - c0
    return trace.root.work(), trace.root.time_on(workers)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkout", nargs="?", default=os.path.dirname(HERE))
    ap.add_argument("--blends", default="figure6_box,figure7_blocker")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--trace", action="store_true",
                    help="also the build's traced work and critical path (span) per worker count")
    ap.add_argument("--size", default="320x240", help="image size WxH")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    args = ap.parse_args(argv)
    root = os.path.abspath(args.checkout)
    sys.path.insert(0, HERE)
    from bench_kernels import exported  # exports with this checkout's add-on
    os.makedirs(args.work, exist_ok=True)
    pickles = {name: exported(name, args.work) for name in args.blends.split(",")}
    sys.path.insert(0, root)
    from engine.jit import ensure_compiled
    from engine.settings import RenderSettings
    ensure_compiled()
    render = importlib.import_module("engine.render")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; engine "
          f"{os.path.dirname(render.__file__)}")
    trace = ("| work s | span s | predicted |", "|---:|---:|---:|") if args.trace else ("", "")
    print("| blend | workers | global / caustic photons | build CPU s | build wall s | maps SHA-1 "
          + trace[0])
    print("|---|---:|---|---:|---:|---" + trace[1])
    for name, path in pickles.items():
        with open(path, "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = (int(x) for x in args.size.split("x"))
        work1 = None
        for workers in (int(w) for w in args.workers.split(",")):
            ctx = render.prepare_context(scene, RenderSettings(workers=workers))
            captured = {}
            build = render._build_maps

            def capture(*a):
                captured["args"] = a
                return build(*a)
            render._build_maps = capture
            try:
                render._photon_pass(ctx, {}, None, None)
            finally:
                render._build_maps = build
            cpu = wall = float("inf")
            for _ in range(args.repeat):
                t0, c0 = time.perf_counter(), time.process_time()
                a = captured["args"]
                out = build(*a[:4], lambda: False, *a[5:])
                wall = min(wall, time.perf_counter() - t0)
                cpu = min(cpu, time.process_time() - c0)
            cells = ""
            if args.trace:
                work, span = min((traced_build(build, captured["args"], workers)
                                  for _ in range(args.repeat)), key=lambda ws: ws[1])
                work1 = work if workers == 1 else work1
                cells = (f" {work:.3f} | {span:.3f} | "
                         + (f"{work1 / span:.2f}x |" if work1 else "- |"))
            print(f"| {name} | {workers} | {len(captured['args'][1]):,} / "
                  f"{len(captured['args'][2]):,} | {cpu:.2f} | {wall:.2f} | "
                  f"{maps_hash(out)} |" + cells, flush=True)
            ctx.accel.close()


if __name__ == "__main__":
    main()
