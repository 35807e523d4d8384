"""Photon visibility's re-estimates, before / after (issue 13, gatherspeed): end-to-end CPU s
of 1-worker renders (default settings) of this tree and a base checkout, alternated, and
each film's hash (the same bits expected), then, per version, the CPU s of
photonvisibility.visible_irradiance and its parts (the masked second search
_reestimate on the base, the read-list sums _visible_sums here) in one profiled render.

    .venv/bin/python bench/bench_gatherspeed.py --base-root BASE
        [--blends figure7_blocker,figure3_sphere] [--repeat 3]

--base-root: a checkout of the base, e.g. `git worktree add /tmp/base main` (its warm
kernel cache saves a compile); blends are exported as bench_kernels.py exports them (bpy),
into --work."""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_kernels as bk  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# One render with visible_irradiance's parts timed (process CPU s).
SPLIT = r"""
import json, pickle, sys, time
sys.path.insert(0, ROOT)
from engine.jit import ensure_compiled
ensure_compiled()
from engine import photonvisibility as pv
from engine.render import render
from engine.settings import RenderSettings
t = {}
def timed(name):
    f = getattr(pv, name, None)
    if f is None:
        return
    def g(*a, **kw):
        t0 = time.process_time()
        try:
            return f(*a, **kw)
        finally:
            t[name] = t.get(name, 0.0) + time.process_time() - t0
    setattr(pv, name, g)
for name in ("visible_irradiance", "_estimate_read", "_hidden_pairs", "_reestimate",
             "_visible_sums"):
    timed(name)
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
t0 = time.process_time()
render(scene, RenderSettings(workers=1))
t["render"] = time.process_time() - t0
print(json.dumps(t))
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base-root", required=True, help="a checkout of the base commit")
    ap.add_argument("--blends", default="figure7_blocker,figure3_sphere")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    args = ap.parse_args(argv)
    os.makedirs(args.work, exist_ok=True)
    roots = {"base": args.base_root, "this": ROOT}
    print(f"base = {args.base_root}, this = {ROOT}; 1 worker, {args.width}x{args.height}, "
          f"min of {args.repeat}\n")
    print("| blend | base CPU s | this CPU s | gain | film |")
    print("|---|---:|---:|---:|---|")
    for name in args.blends.split(","):
        pkl = bk.exported(name, args.work)
        res = {"base": [], "this": []}
        for _ in range(args.repeat):
            for label in ("base", "this"):
                res[label].append(bk.child(bk.RENDER, ROOT=roots[label], PICKLE=pkl,
                                           W=args.width, H=args.height, WORKERS=1,
                                           SETTINGS={}))
        b = min(r["cpu"] for r in res["base"])
        a = min(r["cpu"] for r in res["this"])
        same = {r["hash"] for r in res["base"] + res["this"]}
        print(f"| {name} | {b:.2f} | {a:.2f} | {b / a:.3f}x | "
              f"{'same bits' if len(same) == 1 else 'DIFFERS'} |", flush=True)
    print("\n| blend | version | render CPU s | visible_irradiance | _estimate_read | "
          "_hidden_pairs | _reestimate | _visible_sums |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name in args.blends.split(","):
        pkl = bk.exported(name, args.work)
        for label in ("base", "this"):
            t = bk.child(SPLIT, ROOT=roots[label], PICKLE=pkl, W=args.width, H=args.height)
            cols = " | ".join(f"{t[k]:.2f}" if k in t else "-" for k in (
                "visible_irradiance", "_estimate_read", "_hidden_pairs", "_reestimate",
                "_visible_sums"))
            print(f"| {name} | {label} | {t['render']:.2f} | {cols} |", flush=True)


if __name__ == "__main__":
    main()
