"""Cycles' Filter Glossy split (engine/glossysplit.py) measured: ours at Filter Glossy 0
and 1 against Cycles at 0 and 1, per object, with the light the maps drop and the light
the gather chains add, each from its own pass.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glossy_split.py [--spp N] [--seed S]
        [--cycles-spp N] [--only glossy_floor,figure6_box]

Ours: the add-on's export (tools/accuracy_scenes.export_ours), only
cycles_filter_glossy changed between the two renders. "dropped" is the caustic pass at
Filter Glossy 0 (the caustic and glow maps' estimates, which the split leaves out at 1);
"chains" is the caustic pass at 1 (the gather chains' light sampling and emission,
which the split puts there).
Cycles: the bpy wheel, tools/accuracy_scenes.set_cycles (bench/bench_filter_glossy.py's
renders). Mean Rec. 709 luminance over the pixels each object covers fully.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, ROOT)
import bench_filter_glossy as bfg  # noqa: E402  (registers glossy_floor; needs bpy)

acc = bfg.acc
LUM = bfg.LUM


def ours(name, fg, spp, seed):
    from engine.render import render
    from engine.settings import RenderSettings
    pm_scene, kwargs = acc.export_ours(name)
    kw = dict(kwargs, seed=seed, spp=spp, cycles_filter_glossy=fg)
    t0 = os.times()
    film = render(pm_scene, RenderSettings(**kw))
    t1 = os.times()
    return film, t1.user + t1.system - t0.user - t0.system


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cycles-spp", type=int, default=512)
    p.add_argument("--only", default="glossy_floor,figure6_box")
    a = p.parse_args(argv)
    print(f"ours {a.spp} spp seed {a.seed}; Cycles {a.cycles_spp} spp; load "
          f"{os.getloadavg()[0]:.1f}")
    print("| scene | region | ours FG0 | ours FG1 | ours 1/0 | Cycles FG0 | Cycles FG1 | "
          "Cycles 1/0 | ours FG1 / Cycles FG1 | dropped / FG0 | chains / FG0 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in a.only.split(","):
        f0, s0 = ours(name, 0.0, a.spp, a.seed)
        f1, s1 = ours(name, 1.0, a.spp, a.seed)
        cyc = {fg: bfg.render(name, a.cycles_spp, fg, 1)[0] for fg in (0.0, 1.0)}
        L = {k: np.asarray(v, np.float64)[..., :3] @ LUM for k, v in (
            ("o0", f0.combined), ("o1", f1.combined), ("c0", cyc[0.0]), ("c1", cyc[1.0]),
            ("drop", f0.caustic), ("chains", f1.caustic))}
        for r, m in bfg.regions(name, f0.combined.shape[:2]).items():
            v = {k: float(x[m].mean()) for k, x in L.items()}
            print(f"| {name} | {r} | {v['o0']:.5g} | {v['o1']:.5g} | {v['o1'] / v['o0']:.4f} | "
                  f"{v['c0']:.5g} | {v['c1']:.5g} | {v['c1'] / v['c0']:.4f} | "
                  f"{v['o1'] / v['c1']:.4f} | {v['drop'] / v['o0']:.4f} | "
                  f"{v['chains'] / v['o0']:.4f} |", flush=True)
        print(f"<!-- {name}: ours FG0 {s0:.0f} CPU s, FG1 {s1:.0f} CPU s -->", flush=True)


if __name__ == "__main__":
    main()
