"""Cycles' Clamp Indirect per photon (clampphoton54, engine/photonclamp.py): ours against
Cycles at the same Clamp Indirect, per region, on bench/clampray53_cycles.py's scenes,
before (engine.photonclamp.PER_PHOTON False: the estimates clamped as a whole, main's
clamp) and after (each photon weighed as the Cycles path it ends).

    PYTHONPATH=$PWD .venv/bin/python bench/clampphoton54_cycles.py SCENE [--out DIR]
        [--cycles-spp N] [--seeds 0] [--clamps 10,1]

SCENE: ball, room, jewel1, jewel0 (bench/clampray53_cycles.py's docstring: the scenes,
their regions, the settings). Cycles at --cycles-spp, seed 0, and ours' renders are
cached in --out (.npy; clampray53_cycles.py's names: its "o0" files are the before
renders, integrator.CLAMP_PER_GATHER_RAY False; the after renders are "p1"), so that
script's caches serve as both Cycles' and the before images. Prints a table per scene:
each region's mean luminance, Cycles' own, and ours' before / after over Cycles' at the
same clamp.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (ROOT, os.path.join(ROOT, "bench"), os.path.join(ROOT, "tools")):
    if p not in sys.path:
        sys.path.insert(0, p)

import accuracy_scenes as A  # noqa: E402
import clampray53_cycles as R  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", choices=("ball", "room", "jewel1", "jewel0"))
    ap.add_argument("--out", default="/tmp/clampphoton54")
    ap.add_argument("--cycles-spp", type=int, default=1024)
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--clamps", default="10,1")
    a = ap.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
    os.makedirs(a.out, exist_ok=True)
    import engine.integrator as I
    import engine.photonclamp as P
    I.CLAMP_PER_GATHER_RAY = False
    seeds = [int(s) for s in a.seeds.split(",")]
    clamps = [float(c) for c in a.clamps.split(",")]
    if a.scene.startswith("jewel"):
        scene, w, h = R.jewel_scene()
        scene.cycles.blur_glossy = float(a.scene[-1])
        regions, _ = R.jewel_masks(w, h)
    else:
        scene, w, h = (R.ball_scene if a.scene == "ball" else R.room_scene)()
        r = scene.render
        r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
        regions = R.masks(scene, a.scene, w, h)
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    print("pixels:", {k: int(v.sum()) for k, v in regions.items()}, flush=True)
    c = scene.cycles
    c.sample_clamp_direct = 0.0
    names = list(regions)
    print(f"\n| {a.scene} | clamp | seed | " + " | ".join(names) + " |")
    print("|---|---:|---:|" + "---:|" * len(names))
    for clamp in clamps:
        c.sample_clamp_indirect = clamp
        r.engine = "CYCLES"
        c.device, c.samples, c.seed = "CPU", a.cycles_spp, 0
        c.use_denoising = c.use_adaptive_sampling = False
        ref, cpu = A.render_rgb_cached(
            scene, os.path.join(a.out, f"{a.scene}_c{a.cycles_spp}_clamp{clamp:g}.npy"))
        ref_m = [R.lum(ref)[m].mean() for m in regions.values()]
        print(f"| Cycles {a.cycles_spp} spp | {clamp:g} | 0 | "
              + " | ".join(f"{v:.4f}" for v in ref_m) + " |", flush=True)
        r.engine = "PHOTONMAP"
        for seed in seeds:
            scene.photonmap.seed = seed
            row, cpus = [], []
            for per_photon, tag in ((False, "o0"), (True, "p1")):
                P.PER_PHOTON = per_photon
                img, cpu = A.render_rgb_cached(scene, os.path.join(
                    a.out, f"{a.scene}_{tag}_s{seed}_clamp{clamp:g}.npy"))
                row.append([R.lum(img)[m].mean() for m in regions.values()])
                cpus.append(cpu)
            print(f"| ours before / after ({cpus[1]:.0f} CPU s) | {clamp:g} | {seed} | "
                  + " | ".join(f"{b / x:.3f} / {p / x:.3f}"
                               for b, p, x in zip(*row, ref_m)) + " |", flush=True)


if __name__ == "__main__":
    main()
