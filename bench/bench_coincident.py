"""What the touching-glass probe (engine/coincident.py) costs in a render: per scene, whether
the scene has a touching pair (CoincidentSurfaces built), its triangles, the build's
milliseconds, and in one 1-worker render the calls and rows of CoincidentSurfaces.meet /
meet_hits and the rows they changed, the rows `near` read and those it found near a
partner (a final-gather step with one traces its rays by Accel.intersect), the probe's CPU
seconds (meet, meet_hits, near, each outermost call) and that share of the render's CPU.
A scene whose glass touches nothing must show no instance and no calls.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_coincident.py \\
        [--blends figure3_sphere,figure6_box,figure7_blocker,figure8_caustic] \\
        [--accuracy mirror_glass] [--size 160x120] [--spp 16]

--blends: example blends (exported through the add-on as bench/bench_kernels.py does);
--accuracy: scenes of tools/accuracy_scenes.py at their own resolution and our default
settings (spp as given). Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import os
import pickle
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, os.path.join(ROOT, "tools"))


def measured(scene, settings):
    """(CoincidentSurfaces or None, build ms, {method: [calls, rows, changed, cpu s]},
    render CPU s) of one render with the probe's methods timed (process CPU)."""
    from engine import coincident as C
    from engine.render import render
    stats = {"meet": [0, 0, 0, 0.0], "meet_hits": [0, 0, 0, 0.0], "near": [0, 0, 0, 0.0]}
    saved = {k: getattr(C.CoincidentSurfaces, k) for k in stats}
    built = {}
    saved_for = C.CoincidentSurfaces.for_context.__func__

    def for_context(cls, ctx):
        first = "_coincident" not in ctx.geo.__dict__
        c0 = time.process_time()
        out = saved_for(cls, ctx)
        if first:
            built["ms"] = 1e3 * (time.process_time() - c0)
            built["made"] = out
        return out

    depth = [0]  # calls under way: a nested call's time is its caller's

    def timed(name):
        f = saved[name]

        def call(self, o, *a, **kw):
            c0 = time.process_time()
            depth[0] += 1
            try:
                n = f(self, o, *a, **kw)
            finally:
                depth[0] -= 1
            s = stats[name]
            s[0] += 1
            s[1] += len(o)
            s[2] += int(n.sum()) if name == "near" else n  # near: rows that may meet
            if depth[0] == 0:
                s[3] += time.process_time() - c0
            return n
        return call

    try:
        C.CoincidentSurfaces.for_context = classmethod(for_context)
        for k in stats:
            setattr(C.CoincidentSurfaces, k, timed(k))
        c0 = time.process_time()
        render(scene, settings)
        cpu = time.process_time() - c0
    finally:
        C.CoincidentSurfaces.for_context = classmethod(saved_for)
        for k, f in saved.items():
            setattr(C.CoincidentSurfaces, k, f)
    return built.get("made"), built.get("ms", 0.0), stats, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blends", default="figure3_sphere,figure6_box,figure7_blocker,"
                                        "figure8_caustic")
    ap.add_argument("--accuracy", default="", help="tools/accuracy_scenes.py names")
    ap.add_argument("--size", default="160x120", help="the blends' resolution")
    ap.add_argument("--spp", type=int, default=16)
    args = ap.parse_args(argv)
    from engine.jit import ensure_compiled
    from engine.settings import RenderSettings
    ensure_compiled()
    w, h = (int(v) for v in args.size.lower().split("x"))
    jobs = []
    if args.blends:
        from bench_kernels import exported
        where = os.path.join(tempfile.gettempdir(), "film_hashes")
        os.makedirs(where, exist_ok=True)
        for name in args.blends.split(","):
            with open(exported(name, where), "rb") as f:
                scene = pickle.load(f)
            scene.width, scene.height = w, h
            jobs.append((name, scene, dict(workers=1, spp=args.spp)))
    for name in filter(None, args.accuracy.split(",")):
        import accuracy_scenes as A
        scene, kwargs = A.export_ours(name)
        jobs.append((name, scene, dict(kwargs, workers=1, spp=args.spp)))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; 1 worker, "
          f"{args.spp} spp")
    print("| scene | pairs (glass / other triangles) | build ms | meet calls / rows / changed "
          "| meet_hits calls / rows / changed | near rows / may meet | probe CPU s "
          "| render CPU s | share |")
    print("|---|---|---:|---|---|---|---:|---:|---:|")
    for name, scene, kw in jobs:
        made, ms, st, cpu = measured(scene, RenderSettings(**kw))
        pairs = ("none" if made is None else
                 f"{len(made.glass.tri)} / {len(made.others.tri)}")
        probe = st["meet"][3] + st["meet_hits"][3] + st["near"][3]
        print(f"| {name} | {pairs} | {ms:.1f} | {st['meet'][0]} / {st['meet'][1]} / "
              f"{st['meet'][2]} | {st['meet_hits'][0]} / {st['meet_hits'][1]} / "
              f"{st['meet_hits'][2]} | {st['near'][1]} / {st['near'][2]} | "
              f"{probe:.2f} | {cpu:.1f} | {probe / cpu:.1%} |", flush=True)


if __name__ == "__main__":
    main()
