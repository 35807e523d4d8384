"""The first render's kernel compile: cold (an empty numba cache) with 1, 2, ... processes
sharing it (engine/compilepool.py), and the cached start after it; each in a fresh process
and a fresh cache folder. Prints a table: wall seconds, CPU seconds of the process and its
helpers, and the warm-ups each share ran.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_compile.py [--processes 1,2] [--repeat 1]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = r"""
import json, os, resource, time
t0 = time.perf_counter()
from engine import jit, compilepool
t1 = time.perf_counter()
cold = jit.needs_compile()
jit.ensure_compiled()
t2 = time.perf_counter()
me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps(dict(cold=cold, import_s=t1 - t0, compile_s=t2 - t1,
                      cpu_s=me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime,
                      run=compilepool.LAST_RUN)))
"""


def child(cache, processes):
    env = dict(os.environ, PYTHONPATH=ROOT, NUMBA_CACHE_DIR=cache)
    env["PHOTONMAP_COMPILE_PROCESSES"] = str(processes)
    t = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", CHILD], cwd=ROOT, env=env,
                         capture_output=True, text=True, check=True)
    out = json.loads(res.stdout.strip().splitlines()[-1])
    out["wall_s"] = time.perf_counter() - t
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--processes", default="1,2",
                    help="comma-separated process counts (default 1,2)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per count (best wall kept)")
    args = ap.parse_args()
    counts = [int(x) for x in args.processes.split(",")]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{os.cpu_count()} CPUs, load average {load:.1f} at start")
    print("| processes | cold wall s | cold CPU s (all processes) | warm-ups here / all "
          "| cached start wall s |")
    print("|---:|---:|---:|---|---:|")
    for n in counts:
        best = None
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory(prefix="bench-compile-") as cache:
                cold = child(cache, n)
                assert cold["cold"], "the fresh cache folder was not empty"
                warm = child(cache, n)
            if best is None or cold["wall_s"] < best[0]["wall_s"]:
                best = (cold, warm)
        cold, warm = best
        run = cold["run"] or {}
        share = (f"{run['run_here']} / {run['jobs']}" if run else "all (one process)")
        print(f"| {n} | {cold['wall_s']:.1f} | {cold['cpu_s']:.1f} | {share} | "
              f"{warm['wall_s']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
