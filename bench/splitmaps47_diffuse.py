"""Where figure6_box's walls keep light the Filter Glossy split leaves unblurred
(docs/compatibility.md "splitmaps47", a): ours (the split on, glossysplit.ENABLED) and
Cycles at Filter Glossy 0 and 1, both at Light Paths > Diffuse --diffuse. At Diffuse 1
a camera path D -> X -> S ... is not shaded at X, so light through a specular surface
after two diffuse bounces (the gather map's photons through the glass, read at the
gather rays' ends) is gone in both: if ours' 1 / 0 ratio on the walls meets Cycles' there
and not at the scene's own limit, that light is the gap.

    PYTHONPATH=$PWD .venv/bin/python bench/splitmaps47_diffuse.py [--spp 32]
        [--cycles-spp 256] [--diffuse 1,4] [--only figure6_box]

Ours: the add-on's export (tools/accuracy_scenes.export_ours), only
cycles_filter_glossy and diffuse_bounces changed; Cycles: bench/bench_filter_glossy's
renders (tools/accuracy_scenes.set_cycles) with scene.cycles.diffuse_bounces set.
Mean Rec. 709 luminance over the pixels each object covers fully.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, ROOT)
import bench_filter_glossy as bfg  # noqa: E402  (needs bpy)

acc = bfg.acc
LUM = bfg.LUM


def ours(name, fg, spp, diffuse):
    from engine import glossysplit
    from engine.render import render
    from engine.settings import RenderSettings
    glossysplit.ENABLED = True
    pm_scene, kwargs = acc.export_ours(name)
    kw = dict(kwargs, seed=0, spp=spp, cycles_filter_glossy=fg, diffuse_bounces=diffuse)
    return render(pm_scene, RenderSettings(**kw)).combined


def cycles(name, samples, fg, diffuse):
    scene = acc.setup(name)
    acc.set_cycles(scene, samples, 1)
    scene.cycles.blur_glossy = fg
    scene.cycles.diffuse_bounces = diffuse
    return acc.render_rgb(scene)[0]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=32)
    p.add_argument("--cycles-spp", type=int, default=256)
    p.add_argument("--diffuse", default="1,4")
    p.add_argument("--only", default="figure6_box")
    a = p.parse_args(argv)
    print(f"ours {a.spp} spp seed 0, Cycles {a.cycles_spp} spp seed 1; load "
          f"{os.getloadavg()[0]:.1f}")
    print("| scene | Diffuse | region | ours 1 / 0 | Cycles 1 / 0 | ours 1 / Cycles 1 |")
    print("|---|---:|---|---:|---:|---:|")
    for name in a.only.split(","):
        for diffuse in (int(x) for x in a.diffuse.split(",")):
            L = {}
            for fg in (0.0, 1.0):
                L[("o", fg)] = np.asarray(ours(name, fg, a.spp, diffuse),
                                          np.float64)[..., :3] @ LUM
                L[("c", fg)] = np.asarray(cycles(name, a.cycles_spp, fg, diffuse),
                                          np.float64)[..., :3] @ LUM
            for r, m in bfg.regions(name, L[("o", 0.0)].shape).items():
                v = {k: float(x[m].mean()) for k, x in L.items()}
                print(f"| {name} | {diffuse} | {r} | {v[('o', 1.0)] / v[('o', 0.0)]:.4f} | "
                      f"{v[('c', 1.0)] / v[('c', 0.0)]:.4f} | "
                      f"{v[('o', 1.0)] / v[('c', 1.0)]:.4f} |", flush=True)


if __name__ == "__main__":
    main()
