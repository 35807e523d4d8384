"""Cycles' Clamp Indirect on issue 14's glossy product shot: ours against Cycles, both
clamped alike (engine/sampleclamp.py), by image band, and what the clamp takes off each.

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_clamp_cycles.py \\
        [--clamp 10] [--spp 16] [--seeds 0,1] [--ref 1024] [--size 160x120]

The scene is bench/bench_glossy_product.build (gold text roughness 0.3, glossy-mix balls,
Principled floor, one area light, world colour). Cycles renders it at --ref spp twice,
with Light Paths > Clamping > Indirect at --clamp and at 0 (Direct 0 both: Blender's
defaults), seeds 7 and 8 for the clamped one (their difference says how converged it is);
ours at --spp with RenderSettings.clamp_indirect --clamp and 0 (otherwise the add-on's
export at our defaults). Prints, per band (rows of the text, the balls, the floor, and the
whole image), the mean radiance of each and ours over Cycles', clamped and unclamped; CPU s
is time.process_time of this process (Cycles' threads included).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)

import bench_glossy_product as G  # noqa: E402  (needs the bpy wheel)

A = G.A
BANDS = G.BANDS + (("image", 0.0, 1.0),)


def cycles(spp, seed, width, height, clamp):
    """Cycles' image (H,W,3) at spp with Clamp Indirect `clamp`, cached in $TMPDIR."""
    path = os.path.join(tempfile.gettempdir(),
                        f"clamp_product_{width}x{height}_{spp}_{seed}_{clamp:g}.npy")
    if os.path.isfile(path):
        return np.load(path), 0.0
    scene = G.build(width, height)
    A.set_cycles(scene, spp, seed)
    scene.cycles.sample_clamp_indirect = clamp
    return A.render_rgb_cached(scene, path)


def band_means(img):
    h = img.shape[0]
    lum = np.asarray(img, np.float64).mean(axis=2)
    return [lum[int(a * h):int(b * h)].mean() for _, a, b in BANDS]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clamp", type=float, default=10.0)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--ref", type=int, default=1024)
    ap.add_argument("--size", default="160x120")
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    seeds = [int(s) for s in args.seeds.split(",")]
    ref = {}
    for clamp, seed in ((args.clamp, 7), (args.clamp, 8), (0.0, 7)):
        ref[clamp, seed], cpu = cycles(args.ref, seed, width, height, clamp)
        print(f"Cycles {args.ref} spp, clamp indirect {clamp:g}, seed {seed}: "
              f"{cpu:.1f} CPU s (0: cached)", flush=True)
    pm_scene, kwargs = G.export(width, height)
    names = " / ".join(n for n, _, _ in BANDS)
    print(f"\n| renderer | clamp indirect | spp | seed | CPU s | mean {names} | "
          f"ours / Cycles (same clamp) {names} |")
    print("|---|---:|---:|---:|---:|---|---|")
    for clamp in (args.clamp, 0.0):
        cyc = band_means(ref[clamp, 7])
        print(f"| Cycles | {clamp:g} | {args.ref} | 7 | | "
              + " / ".join(f"{m:.4f}" for m in cyc) + " | |")
        if clamp:
            other = band_means(ref[clamp, 8])
            print(f"| Cycles | {clamp:g} | {args.ref} | 8 | | "
                  + " / ".join(f"{m:.4f}" for m in other) + " | "
                  + " / ".join(f"{o / c:.4f}" for o, c in zip(other, cyc)) + " |")
        for seed in seeds:
            film, cpu = G.ours(pm_scene, {**kwargs, "clamp_direct": 0.0,
                                          "clamp_indirect": clamp}, args.spp, seed)
            m = band_means(film.combined)
            print(f"| ours | {clamp:g} | {args.spp} | {seed} | {cpu:.1f} | "
                  + " / ".join(f"{v:.4f}" for v in m) + " | "
                  + " / ".join(f"{o / c:.4f}" for o, c in zip(m, cyc)) + " |", flush=True)


if __name__ == "__main__":
    main()
