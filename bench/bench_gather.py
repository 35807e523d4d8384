"""The final gather before / after: this checkout against another commit (default: the
`main` branch's head), same machine, one command (issue 13, tenth slice: regathers in one
batch per gather call).

    .venv/bin/python bench/bench_gather.py [--base main] [--blends figure6_box,...]
        [--width 160 --height 120] [--workers 1,2] [--repeat 2]
        [--seeds 4 --stats-width 80 --stats-height 60] [--only time,threads,stats]
        [--before /path/to/a/checkout/of/base]

Prints Markdown tables:
- time: per example blend at default settings, before and after, for each worker count:
  CPU seconds of the camera stage (process clock around integrator.render_camera, all
  threads) and of the final gather in it (summed over the top-level gather_indirect
  calls, regathers included: process clock at 1 worker, thread clock at 2),
  gather_indirect calls by level, and whether the film is bitwise the same as 1 worker's
  (SHA-1 of the five effect passes);
- threads: where the camera stage's and the final gather's time goes on the worker
  threads (twelfth slice), for each worker count: per thread, summed over threads, the
  seconds on a core (run), waiting for a core (run-queue: other processes), and
  *blocked* = wall - run - run-queue (waits for the GIL or a lock), and the minor page
  faults (RUSAGE_THREAD), inside the chunks (_render_chunk) and inside the top-level
  gather_indirect calls; from /proc/self/task/<tid>/schedstat (Linux);
- stats: the image over seeds first..first+N-1, paired by seed (the same seed before and after):
  the mean of the combined image and of the indirect pass, their paired difference with
  its standard error over seeds, and the per-pixel noise (standard deviation over seeds,
  averaged over pixels) before and after.
Every render runs in its own process; before and after alternate; CPU times are the best
of --repeat. The example blends are exported once through the add-on (bench_kernels.py's
pickles, in /tmp/bench_kernels).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

from bench_kernels import ROOT, base_tree, child, exported

RENDER = r"""
import hashlib, json, pickle, sys, threading, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
ensure_compiled()
from engine import integrator
from engine.render import render
from engine.settings import RenderSettings
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
calls, gather_cpu, camera_cpu = {}, [0.0], [0.0]
# One worker: the chunks run on this thread and Embree / lookups may split a call over
# helper threads, so the process clock; two: each worker's queries stay on its thread
# (Context.serial), so the thread clock of the calls (summed over workers).
clock = time.process_time if WORKERS == 1 else time.thread_time
lock = threading.Lock()
local = threading.local()
real_gather, real_camera = integrator.gather_indirect, integrator.render_camera

def gather(ctx, hit, rng, counters, *a, **k):
    level = k.get("level", 0)
    top = not getattr(local, "inside", False)
    local.inside = True
    t = clock()
    try:
        return real_gather(ctx, hit, rng, counters, *a, **k)
    finally:
        if top:
            local.inside = False
        with lock:
            calls[level] = calls.get(level, 0) + 1
            if top:
                gather_cpu[0] += clock() - t

def camera(*a, **k):
    t = time.process_time()
    try:
        return real_camera(*a, **k)
    finally:
        camera_cpu[0] += time.process_time() - t

integrator.gather_indirect, integrator.render_camera = gather, camera
sys.modules["engine.render"].render_camera = camera  # (imported by name there)
film = render(scene, RenderSettings(workers=WORKERS, seed=SEED))
h = hashlib.sha1()
for k in ("direct", "indirect", "caustic", "specular", "emission"):
    h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
if OUT:
    np.savez(OUT, **{k: getattr(film, k) for k in
                     ("direct", "indirect", "caustic", "specular", "emission")})
print(json.dumps(dict(camera=camera_cpu[0], gather=gather_cpu[0], hash=h.hexdigest(),
                      calls={str(k): v for k, v in sorted(calls.items())})))
"""

THREADS = r"""
import json, pickle, resource, sys, threading, time
sys.path.insert(0, ROOT)
from engine.jit import ensure_compiled
ensure_compiled()
from engine import integrator
from engine.render import render
from engine.settings import RenderSettings
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
stats, lock, local = {}, threading.Lock(), threading.local()

def snap():
    with open(f"/proc/self/task/{threading.get_native_id()}/schedstat") as f:
        run, wait = (int(x) * 1e-9 for x in f.read().split()[:2])
    return (time.perf_counter(), run, wait,
            resource.getrusage(resource.RUSAGE_THREAD).ru_minflt)

def timed(fname, key):
    real = getattr(integrator, fname)
    def call(*a, **k):
        if getattr(local, fname, False):  # recursion: counted by the outer call
            return real(*a, **k)
        setattr(local, fname, True)
        s0 = snap()
        try:
            return real(*a, **k)
        finally:
            setattr(local, fname, False)
            d = [y - x for x, y in zip(s0, snap())]
            with lock:
                acc = stats.setdefault(key, [0.0] * 4)
                for i in range(4):
                    acc[i] += d[i]
    setattr(integrator, fname, call)

timed("_render_chunk", "chunk")
timed("gather_indirect", "gather")
render(scene, RenderSettings(workers=WORKERS))
print(json.dumps({k: dict(run=r, runq=q, blocked=w - r - q, faults=int(f))
                  for k, (w, r, q, f) in stats.items()}))
"""

PASSES = ("direct", "indirect", "caustic", "specular", "emission")


def run(root, pkl, w, h, workers, seed=0, out=""):
    return child(RENDER, ROOT=root, PICKLE=pkl, W=w, H=h, WORKERS=workers, SEED=seed,
                 OUT=out)


def timing(roots, blends, args, where):
    print(f"\n### Camera stage and final gather, default settings, {args.width}x"
          f"{args.height} (CPU s, best of {args.repeat})\n")
    print("| blend | workers | camera before | camera after | gain | gather before | "
          "gather after | gain | gather calls by level before / after | image |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|---|")
    for name in blends:
        pkl = exported(name, where)
        first = {}
        for workers in args.workers:
            res = {"before": [], "after": []}
            for _ in range(args.repeat):
                for label in ("before", "after"):
                    res[label].append(run(roots[label], pkl, args.width, args.height,
                                          workers))
            b, a = res["before"], res["after"]
            cb, ca = min(r["camera"] for r in b), min(r["camera"] for r in a)
            gb, ga = min(r["gather"] for r in b), min(r["gather"] for r in a)
            same = []
            for label in ("before", "after"):
                hs = {r["hash"] for r in res[label]}
                first.setdefault(label, hs)
                same.append(label + (" 1 = 2 workers" if hs == first[label] else
                                     " 1 vs 2 workers DIFFER"))
            if len(args.workers) == 1 or workers == args.workers[0]:
                same = ["(first worker count)"]
            calls = (" ".join(f"{v}" for v in b[0]["calls"].values()) + " / "
                     + " ".join(f"{v}" for v in a[0]["calls"].values()))
            print(f"| {name} | {workers} | {cb:.2f} | {ca:.2f} | {cb / max(ca, 1e-9):.2f}x | "
                  f"{gb:.2f} | {ga:.2f} | {gb / max(ga, 1e-9):.2f}x | {calls} | "
                  f"{', '.join(same)} |", flush=True)


def threads(roots, blends, args, where):
    print(f"\n### Worker threads: camera chunks and final gather, default settings, "
          f"{args.width}x{args.height} (s summed over threads; the run with the least chunk "
          f"run time of {args.repeat})\n")
    print("| blend | workers | tree | chunks: run s | run-queue s | blocked s | faults | "
          "gather: run s | run-queue s | blocked s | faults |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in blends:
        pkl = exported(name, where)
        for workers in args.workers:
            res = {"before": [], "after": []}
            for _ in range(args.repeat):
                for label in ("before", "after"):
                    res[label].append(child(THREADS, ROOT=roots[label], PICKLE=pkl,
                                            W=args.width, H=args.height, WORKERS=workers))
            for label in ("before", "after"):
                r = min(res[label], key=lambda x: x["chunk"]["run"])
                c, g = r["chunk"], r["gather"]
                print(f"| {name} | {workers} | {label} | {c['run']:.2f} | {c['runq']:.2f} | "
                      f"{c['blocked']:.2f} | {c['faults']:,} | {g['run']:.2f} | "
                      f"{g['runq']:.2f} | {g['blocked']:.2f} | {g['faults']:,} |", flush=True)


def stats(roots, blends, args, where):
    w, h = args.stats_width, args.stats_height
    print(f"\n### The image over {args.seeds} seeds from {args.first_seed}, paired by seed, "
          f"default settings, "
          f"{w}x{h}, 1 worker\n")
    print("| blend | image | mean before | mean after | paired difference (± s.e.) | "
          "difference / s.e. | per-pixel noise before | after | ratio |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in blends:
        pkl = exported(name, where)
        imgs = {"before": [], "after": []}
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            for label in ("before", "after"):
                out = os.path.join(where, f"gather_{label}_{name}_{seed}.npz")
                run(roots[label], pkl, w, h, 1, seed, out)
                f = np.load(out)
                imgs[label].append({k: f[k].astype(np.float64) for k in PASSES})
        for image in ("combined", "indirect"):
            def pick(film):
                return sum(film[k] for k in PASSES) if image == "combined" else film[image]
            B = np.array([pick(f) for f in imgs["before"]])  # (seeds, H, W, 3)
            A = np.array([pick(f) for f in imgs["after"]])
            mb, ma = B.mean(axis=(1, 2, 3)), A.mean(axis=(1, 2, 3))
            diff = ma - mb
            se = diff.std(ddof=1) / math.sqrt(len(diff))
            nb = B.std(axis=0, ddof=1).mean()
            na = A.std(axis=0, ddof=1).mean()
            print(f"| {name} | {image} | {mb.mean():.5f} | {ma.mean():.5f} | "
                  f"{diff.mean():+.5f} ± {se:.5f} | {diff.mean() / se if se else 0:+.2f} | "
                  f"{nb:.5f} | {na:.5f} | {na / nb:.3f} |", flush=True)


def _short(ref):
    """ref's short commit hash (ref itself outside a git checkout)."""
    out = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", ref],
                         capture_output=True, text=True)
    return out.stdout.strip() if out.returncode == 0 else ref


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="main", help="commit to compare against")
    ap.add_argument("--before", default=None,
                    help="a checkout of --base to use instead of a fresh git archive")
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--stats-width", type=int, default=80)
    ap.add_argument("--stats-height", type=int, default=60)
    ap.add_argument("--only", default="time,stats")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    args = ap.parse_args()
    args.workers = [int(x) for x in args.workers.split(",")]
    os.makedirs(args.work, exist_ok=True)
    commit, head = (_short(ref) for ref in (args.base, "HEAD"))
    roots = {"before": args.before or base_tree(commit, args.work), "after": ROOT}
    load = os.getloadavg()[0]
    print(f"before = {commit}, after = {head} (+ working tree); load average {load:.1f} "
          f"on {os.cpu_count()} cores")
    blends = args.blends.split(",")
    only = args.only.split(",")
    if "time" in only:
        timing(roots, blends, args, args.work)
    if "threads" in only:
        threads(roots, blends, args, args.work)
    if "stats" in only:
        stats(roots, blends, args, args.work)
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
