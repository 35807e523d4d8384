"""Serial work of a render: what the calling thread runs outside the jobs that spread over
the workers, one checkout per run.

    .venv/bin/python bench/bench_serial_work.py [CHECKOUT] [--blends figure6_box,...]
        [--width 160 --height 120]

CHECKOUT (default: this one) is put first on sys.path, so an older checkout's engine can be
measured by the same script. Each example blend (exported once through the add-on,
bench_kernels.exported) renders at default settings with ONE worker, in this process;
every job handed to parallel.ordered_map or parallel.run_tasks (camera and photon chunks,
kd-subtree builds, estimate blocks, neighbour lists, the map build's concurrent steps) is
timed on its own thread's clock (time.thread_time; nested jobs count once, in the
outermost). What is left of the process's CPU time (time.process_time) ran on the
calling thread alone: with two workers it stays serial, so it bounds the speed-up
(Amdahl: 1 / (serial + (1 - serial) / 2)). The bound ignores the GIL-holding glue inside
the jobs and the last chunk's tail. cProfile (process clock) lists the largest serial
functions: it is switched off inside the jobs, so only the calling thread's own work is
in it (waits for jobs run elsewhere are left out of the list).
"""
import argparse
import cProfile
import importlib
import io
import os
import pickle
import pstats
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
WAITS = ("acquire", "wait", "_wait_for_tstate_lock", "join", "result", "get")


STATE = {}  # the blend being measured: its "acc" (label -> CPU s) and "prof"


def _timed(fn, label, depth):
    """fn with its thread's CPU time added to STATE's acc[label] when it is the outermost
    job."""
    def run(*args):
        acc, prof = STATE["acc"], STATE["prof"]
        d = getattr(depth, "d", 0)
        # cProfile follows the thread that enabled it: jobs on other threads are not in it.
        main = threading.current_thread() is threading.main_thread()
        if d == 0:
            if main:
                prof.disable()
            t0 = time.thread_time()
        depth.d = d + 1
        try:
            return fn(*args)
        finally:
            depth.d = d
            if d == 0:
                acc[label] = acc.get(label, 0.0) + time.thread_time() - t0
                if main:
                    prof.enable()
    return run


def instrument():
    """Wrap the ordered_map / run_tasks every engine module imported (once)."""
    from engine import parallel
    depth = threading.local()
    ordered_map = parallel.ordered_map
    run_tasks = getattr(parallel, "run_tasks", None)

    def timed_map(job, items, threads, *args, **kwargs):
        return ordered_map(_timed(job, job.__qualname__, depth), items, threads,
                           *args, **kwargs)

    def timed_tasks(tasks, threads, should_cancel=None):
        return run_tasks([_timed(t, "task " + t.__qualname__, depth)
                          for t in tasks], threads, should_cancel)
    for name in list(sys.modules):
        mod = sys.modules[name]
        # (engine.parallel's own ordered_map, behind run_tasks, stays: its tasks are timed
        # by their names.)
        if name.startswith("engine") and name != "engine.parallel" and mod is not None:
            if getattr(mod, "ordered_map", None) is ordered_map:
                mod.ordered_map = timed_map
            if run_tasks is not None and getattr(mod, "run_tasks", None) is run_tasks:
                mod.run_tasks = timed_tasks


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkout", nargs="?", default=os.path.dirname(HERE))
    ap.add_argument("--blends", default="figure6_box,figure7_blocker")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--top", type=int, default=6)
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
    instrument()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; engine "
          f"{os.path.dirname(render.__file__)}")
    print("| blend | CPU s | in jobs s | calling thread alone s | serial share "
          "| 2-worker bound | largest serial items (s) |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for name, path in pickles.items():
        with open(path, "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = args.width, args.height
        acc = STATE["acc"] = {}
        prof = STATE["prof"] = cProfile.Profile(time.process_time)
        c0 = time.process_time()
        prof.enable()
        render.render(scene, RenderSettings(workers=1))
        prof.disable()
        cpu = time.process_time() - c0
        jobs = sum(acc.values())
        serial = (cpu - jobs) / cpu
        stats = pstats.Stats(prof, stream=io.StringIO())
        items = sorted(((tt, fn) for fn, (_, _, tt, _, _) in stats.stats.items()
                        if fn[2] not in WAITS and "acquire" not in fn[2]
                        and "_lsprof" not in fn[2]), reverse=True)[:args.top]
        top = ", ".join(f"{fn[2]} {tt:.2f}" for tt, fn in items)
        print(f"| {name} | {cpu:.2f} | {jobs:.2f} | {cpu - jobs:.2f} | {100 * serial:.1f} % "
              f"| {1 / (serial + (1 - serial) / 2):.2f}x | {top} |", flush=True)
        for label, value in sorted(acc.items(), key=lambda x: -x[1]):
            print(f"|  | | {value:.2f} | {label} | | | |")


if __name__ == "__main__":
    main()
