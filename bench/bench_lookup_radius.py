"""The global search radius from the photons' spacing (the rule before radius44: auto_radius
over the stored photons) against the radius from the lookups' (render.lookup_radius, the
k-NN distance at the pre-pass' gather-ray ends; x 2 as rendered, and x 1), on the
example scenes of tools/accuracy_scenes.py: per scene and rule the radius (m), the image
mean against the stored Cycles reference's and the HDR-FLIP, one worker, seeds given.
docs/accuracy.md "radius43 (prototype, not merged)" and "radius44" quote its runs.

    .venv/bin/python bench/bench_lookup_radius.py figure6_box,figure3_sphere --seeds 0,1
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import accuracy_scenes as A  # noqa: E402  (needs the bpy wheel)
from bench_accuracy_ab import render_ours  # noqa: E402

RULES = {"photons": {("render", "RADIUS_FROM_LOOKUPS"): False},
         "lookups": {("render", "RADIUS_FROM_LOOKUPS"): True},
         "lookups x 1": {("render", "RADIUS_FROM_LOOKUPS"): True,
                         ("render", "LOOKUP_RADIUS_SCALE"): 1.0}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", help="comma-separated tools/accuracy_scenes.py names")
    ap.add_argument("--seeds", default="0")
    args = ap.parse_args(argv)
    import engine
    engine.jit.ensure_compiled()
    seeds = [int(s) for s in args.seeds.split(",")]
    # The radius' own CPU time: render.global_search_radius wrapped (thread time: the
    # map build may call it on a worker thread).
    R = importlib.import_module("engine.render")  # (engine.render is also a function)
    plain, spent = R.global_search_radius, [0.0]

    def timed(*a):
        t = time.thread_time()
        try:
            return plain(*a)
        finally:
            spent[0] += time.thread_time() - t
    R.global_search_radius = timed
    print("| scene | rule | radius (m) | mean / Cycles | FLIP | CPU s | radius CPU ms |\n"
          "|---|---|---:|---:|---:|---:|---:|")
    for name in args.scenes.split(","):
        ref = A.load_reference(name)
        pm_scene, base = A.export_ours(name)
        for rule, patches in RULES.items():
            r, m, f, c = [], [], [], []
            spent[0] = 0.0
            for seed in seeds:
                img, cpu, _, st = render_ours(pm_scene, dict(base, workers=1, seed=seed),
                                              patches)
                r.append(st["radius_global"])
                m.append(float(img.mean()) / float(ref.mean()))
                f.append(A.flip(img, ref))
                c.append(cpu)
            print(f"| {name} | {rule} | {np.mean(r):.4f} | {np.mean(m):.4f} | "
                  f"{np.mean(f):.4f} | {np.mean(c):.1f} | {1e3 * spent[0] / len(seeds):.0f} |",
                  flush=True)
    print(f"(load average {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
