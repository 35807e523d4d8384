"""Cycles' Filter Glossy on our camera paths (fgcamera46, engine/filterglossy.py): ours at
Filter Glossy 1 against 0, and against Cycles at 1 and 0, per region.

    PYTHONPATH=$PWD .venv/bin/python bench/fgcamera46.py [--spp 64] [--seeds 0,1]
        [--cycles-spp 1024] [--only principled_spheres,glass_on_metal] [--fg 1.0] [--json OUT]

Scenes: principled_spheres (issue 14's row of Principled balls, 160 x 120: the metals
reflect their neighbours' lobes after their own rough bounce, Cycles FG 1 / FG 0 0.978 /
0.981 on Steel / Gold, docs/compatibility.md "filterglossy45"), glass_on_metal (built
here: a smooth glass ball on a rough metal floor, roughness 0.5, under a small area lamp,
a white wall behind; the camera sees the ball in the floor's reflection: the
rough-then-smooth chain of docs/accuracy.md "turnedcamera45", where Cycles at Filter
Glossy 1 samples the ball as rough glass and finds the lamp through it) and glossy_floor
(bench/bench_filter_glossy.py's). Ours: our engine on the scene as the add-on exports it
(tools/accuracy_scenes.export_ours), `cycles_filter_glossy` 0 and 1, the same seeds;
Cycles (the bpy wheel, CPU, tools/accuracy_scenes.set_cycles' comparison settings, only
blur_glossy changed) at --cycles-spp (0: skipped). Regions: the whole image and the
pixels each object covers fully (the stored labels, else Cycles coverage renders).
--fg: the Filter Glossy compared with 0 (0.3: only bounces of pdf below 0.3, a Lambert
bounce within 18 degrees of grazing, blur). Prints a Markdown table; --json writes the
region means.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import accuracy_scenes as acc  # noqa: E402  (needs the bpy wheel)
import bench_filter_glossy as bfg  # noqa: E402  (registers glossy_floor)
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

mb = acc.mb


def _glass_on_metal():
    """A smooth glass ball (IOR 1.5) on a rough metal floor (Principled, metallic 1,
    roughness 0.5: alpha 0.25, its GGX pdf at most ~1.3 /sr, so most of its reflections
    blur what they meet at Filter Glossy 1), a white diffuse wall behind, a 0.3 m square
    area lamp above and behind the ball; the camera low, seeing the ball and its mirror
    image in the floor."""
    mb.reset()
    metal = mb.material("Metal", "principled", (0.9, 0.9, 0.9), roughness=0.5, metallic=1.0)
    white = mb.material("White", "diffuse", (0.8, 0.8, 0.8))
    glass = mb.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    mb.plane("Floor", 8, 8, metal)
    mb.plane("Wall", 8, 4, white, (0, 2.5, 2.0), (np.pi / 2, 0, 0))
    mb.sphere("Ball", 0.5, glass, (0.0, 0.3, 0.5))
    mb.light("Lamp", "AREA", (0.3, 1.2, 2.2), 200.0, look_at=(0.0, 0.3, 0.5), shape="SQUARE",
             size=0.3)
    mb.camera((0.0, -4.0, 0.9), (0.0, 0.3, 0.4), 40.0)


acc.SCENES["glass_on_metal"] = (_glass_on_metal, "specular")
SCENES = ("principled_spheres", "glass_on_metal")


def cpu_seconds():
    t = os.times()
    return t.user + t.system


def ours(name, spp, seeds, fg):
    """(H, W, 3) float64 mean of our renders over seeds at Filter Glossy fg, CPU s."""
    scene, kw = acc.export_ours(name)
    imgs, t = [], cpu_seconds()
    for seed in seeds:
        film = render(scene, RenderSettings(**dict(kw, spp=spp, seed=seed, workers=1,
                                                   cycles_filter_glossy=fg)))
        imgs.append(np.asarray(film.combined, np.float64)[..., :3])
    return np.mean(imgs, axis=0), cpu_seconds() - t


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seeds", default="0,1")
    p.add_argument("--cycles-spp", type=int, default=1024)
    p.add_argument("--only", default=",".join(SCENES))
    p.add_argument("--fg", type=float, default=1.0)
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    ensure_compiled()
    print(f"ours {a.spp} spp x seeds {seeds}, one thread; Cycles {a.cycles_spp} spp seed 0; "
          f"load {os.getloadavg()[0]:.1f}")
    f = f"FG {a.fg:g}"
    print(f"| scene | region | pixels | ours {f} / FG 0 | Cycles {f} / FG 0 | ours / Cycles FG 0 "
          f"| ours / Cycles {f} |")
    print("|---|---|---:|---:|---:|---:|---:|")
    record = {}
    for name in a.only.split(","):
        fgs = (0.0, a.fg)
        img = {fg: ours(name, a.spp, seeds, fg) for fg in fgs}
        cyc = {}
        w0 = time.perf_counter()
        if a.cycles_spp > 0:
            cyc = {fg: bfg.render(name, a.cycles_spp, fg, 0)[0].astype(np.float64)
                   for fg in fgs}
        regs = bfg.regions(name, img[0.0][0].shape[:2])
        rec = record[name] = {}
        for r, m in regs.items():
            o0, o1 = (float(bfg.lum(img[fg][0])[m].mean()) for fg in fgs)
            rec[r] = {"pixels": int(m.sum()), "ours_fg0": o0, "ours_fg1": o1}
            cells = [f"{o1 / o0:.4f}"]
            if cyc:
                c0, c1 = (float(bfg.lum(cyc[fg])[m].mean()) for fg in fgs)
                rec[r].update(cycles_fg0=c0, cycles_fg1=c1)
                cells += [f"{c1 / c0:.4f}", f"{o0 / c0:.4f}", f"{o1 / c1:.4f}"]
            else:
                cells += ["-", "-", "-"]
            print(f"| {name} | {r} | {int(m.sum())} | " + " | ".join(cells) + " |", flush=True)
        print(f"<!-- {name}: ours CPU s FG 0 {img[0.0][1]:.0f}, {f} {img[a.fg][1]:.0f}; Cycles "
              f"{time.perf_counter() - w0:.0f} s wall -->", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
