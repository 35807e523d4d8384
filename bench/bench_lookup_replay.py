"""Where a render's gather-map lookups spend their time: one render of an example blend
(exported by bench/bench_kernels.py into --work) with every GatherMap.lookup call
captured, then each call replayed piece by piece in the same process (CPU seconds,
best of --repeat a call, summed over the calls):

    PYTHONPATH=$PWD .venv/bin/python bench/bench_lookup_replay.py [--blend figure7_blocker]
        [--width 320 --height 240] [--repeat 2]

Prints a Markdown table: the whole lookup, morton_order, the kernel _gather_candidates,
the nearest-point walk alone (kdtree.nearest_walk), Embree's visibility rays, the
hidden-candidate path (_next_visible), and counts (calls, rows, rays, rays blocked, rows
without a candidate). docs/performance.md, "speed31"."""
from __future__ import annotations

import argparse
import os
import pickle
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402


def best_cpu(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blend", default="figure7_blocker")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--work", default="/tmp/bench_kernels",
                    help="bench_kernels.py's exports (run it once to make them)")
    args = ap.parse_args()
    from engine import kdtree, photonmap
    from engine.jit import ensure_compiled
    from engine.mortontree import morton_order
    from engine.photonmap import _NO_LIFT, GatherMap, _gather_candidates
    from engine.render import render
    from engine.settings import RenderSettings
    ensure_compiled()
    with open(os.path.join(args.work, args.blend + ".pkl"), "rb") as f:
        scene = pickle.load(f)
    scene.width, scene.height = args.width, args.height
    calls = []
    lookup = GatherMap.lookup

    def capture(self, p, n, candidates=8, offset=None, scratch=None, points=False,
                surface=None):
        calls.append((self, np.array(p), np.array(n), candidates,
                      None if offset is None else np.array(offset),
                      None if surface is None else np.array(surface)))
        return lookup(self, p, n, candidates, offset, scratch, points, surface)
    GatherMap.lookup = capture
    try:
        render(scene, RenderSettings(workers=1))
    finally:
        GatherMap.lookup = lookup
    cpu = dict.fromkeys(("lookup", "morton", "kernel", "walk", "embree", "next_visible"), 0.0)
    count = dict.fromkeys(("rays", "blocked", "no candidate"), 0)
    rows_total = 0
    for g, p, n, candidates, off, qs in calls:
        g = g.serial()
        m = len(p)
        rows_total += m
        cpu["lookup"] += best_cpu(lambda: g.lookup(p, n, candidates, off, surface=qs),
                                  args.repeat)
        surf, qsurf = g._surfaces(qs, m)
        rows = morton_order(p)
        cpu["morton"] += best_cpu(lambda: morton_order(p), args.repeat)
        out, boundary = np.empty((m, 3)), np.empty(m, bool)
        o32, d32 = np.empty((m, 3), np.float32), np.empty((m, 3), np.float32)
        t32, ray_row = np.empty(m, np.float32), np.empty(m, np.int64)
        point, blocked = np.empty(m, np.int64), np.zeros(m, bool)
        kmax = min(8 * candidates, len(g.position))
        r2 = g.radius * g.radius
        lift = _NO_LIFT if off is None else np.ascontiguousarray(off, np.float64)
        want = g.accel is not None

        def kernel():
            return _gather_candidates(g.tree.position, g.tree.nodes, *g.neighbours,
                                      g.position, g.normal, surf, g.E, g.boundary, p, n,
                                      qsurf, lift, rows, r2, kmax, want, out, boundary, o32,
                                      d32, t32, ray_row, point)
        cpu["kernel"] += best_cpu(kernel, args.repeat)
        nr = kernel()
        q = np.ascontiguousarray(p[rows])
        near = np.empty(m, np.int64)
        cpu["walk"] += best_cpu(lambda: kdtree.nearest_walk(
            g.tree.position, *g.tree.nodes, *g.neighbours, q, np.arange(m), r2,
            photonmap.WALK_STEPS, near, np.zeros(0, np.bool_)), args.repeat)
        count["no candidate"] += int((point < 0).sum())
        if not nr:
            continue
        # Embree overwrites tmax: a fresh copy each time.
        cpu["embree"] += best_cpu(lambda: g.accel.occluded_into(
            o32[:nr], d32[:nr], t32[:nr].copy(), blocked[:nr]), args.repeat)
        hidden = rows[ray_row[:nr][blocked[:nr]]]
        count["rays"] += nr
        count["blocked"] += len(hidden)
        if len(hidden):
            cpu["next_visible"] += best_cpu(lambda: g._next_visible(
                p, n, lift, hidden, kmax, out.copy(), boundary.copy(), point.copy(), qsurf),
                args.repeat)
    print(f"{args.blend} {args.width}x{args.height}, 1 worker: {len(calls)} lookup calls, "
          f"{rows_total} rows ({rows_total / max(len(calls), 1):.0f} a call), "
          f"{count['rays']} visibility rays, {count['blocked']} blocked, "
          f"{count['no candidate']} rows without a candidate; load "
          f"{os.getloadavg()[0]:.1f}\n")
    print("| piece | CPU s | ns a row |\n|---|---:|---:|")
    for key, label in (("lookup", "GatherMap.lookup"), ("morton", "morton_order"),
                       ("kernel", "_gather_candidates"),
                       ("walk", "  the walk alone (nearest_walk)"),
                       ("embree", "Embree occluded_into"),
                       ("next_visible", "_next_visible")):
        print(f"| {label} | {cpu[key]:.3f} | {cpu[key] / max(rows_total, 1) * 1e9:.1f} |")


if __name__ == "__main__":
    main()
