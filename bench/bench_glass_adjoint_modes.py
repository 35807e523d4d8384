"""Photons at smooth-shaded glass by photonkernels.GLASS_ADJOINT_MODE (smoothglass44).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glass_adjoint_modes.py
        [--glossy 4] [--spp 4] [--photons 20000] [--caustic-photons 100000] [--seed 0]
        [--min-bend 6]

1. The share of photon arrivals (cosine-distributed about Ng, 20,000 each) for which
   glassadjoint.turn_possible asks for the root search, by the shading normal's bend,
   arriving from air (IOR 1.5 glass) and from inside the glass.
2. tests/blender/test_glass_of_water_cycles.py's scene with smooth sides (the glass of
   water and the empty glass) rendered with each rule in one process: the image mean,
   ours / Cycles' stored mean (the glass of water only: tests/references/
   glass_of_water.json), and the render's CPU seconds. Rules: never (main's sample about
   the shading normal everywhere), every (the adjoint with its root search at every hit
   bent > ~0.1 degree: smoothglass43), where (the default: the adjoint above --min-bend
   degrees, its root search only where turn_possible).

docs/accuracy.md, smoothglass44, gives the numbers measured.
"""
import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy  # noqa: E402
import addon  # noqa: E402
addon.register()
import engine.photonkernels as pk  # noqa: E402
from engine import glassadjoint as ga  # noqa: E402
from blender_helpers import cheap  # noqa: E402
from test_glass_of_water_cycles import _mean, _scene, _stored_means  # noqa: E402

RULES = (("never", pk.GLASS_ADJOINT_NEVER), ("every", pk.GLASS_ADJOINT_EVERY_BENT),
         ("where", pk.GLASS_ADJOINT_WHERE_TURNED))


def bound_shares(n=20_000, seed=0):
    """Markdown rows: bend (deg), share asked from air, from glass."""
    rng = np.random.default_rng(seed)
    g = np.array([0.0, 0.0, 1.0])
    rows = []
    for bend in (0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 45.0):
        t = math.radians(bend)
        share = []
        for eta in (1.5, 1.0 / 1.5):
            asked = 0
            for _ in range(n):
                az = rng.uniform(0.0, 2.0 * math.pi)
                nn = np.array([math.sin(t) * math.cos(az), math.sin(t) * math.sin(az),
                               math.cos(t)])
                u, a = rng.random(), rng.uniform(0.0, 2.0 * math.pi)
                r = math.sqrt(u)
                d = np.array([-r * math.cos(a), -r * math.sin(a), -math.sqrt(1.0 - u)])
                asked += ga.turn_possible(*d, *nn, *g, eta)
            share.append(asked / n)
        rows.append(f"| {bend:g} | {share[0]:.4f} | {share[1]:.4f} |")
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--glossy", type=int, default=4)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--photons", type=int, default=20_000)
    ap.add_argument("--caustic-photons", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--min-bend", type=float, default=pk.GLASS_ADJOINT_MIN_BEND_DEG)
    args = ap.parse_args()
    print("| bend (deg) | asked, from air | asked, from glass |\n|---:|---:|---:|")
    print("\n".join(bound_shares()))
    want = _stored_means()["smooth"]
    print(f"\nsmooth sides, Glossy {args.glossy}, {args.spp} spp, {args.photons} / "
          f"{args.caustic_photons} photons, seed {args.seed}, min bend {args.min_bend:g} deg; "
          f"load {os.getloadavg()[0]:.1f}\n")
    print("| content | rule | mean | ours / Cycles | CPU s |\n|---|---|---:|---:|---:|")
    saved = pk.GLASS_ADJOINT_MODE, pk.GLASS_ADJOINT_MIN_BEND_DEG
    try:
        pk.GLASS_ADJOINT_MIN_BEND_DEG = args.min_bend
        warm_up = True
        # The first render loads the kernels (seconds of CPU): run it once, unreported.
        for water, (name, mode) in [(True, RULES[0])] + [(w, r) for w in (True, False)
                                                         for r in RULES]:
            pk.GLASS_ADJOINT_MODE = mode
            bpy.ops.wm.read_homefile(use_empty=True)
            scene = bpy.context.scene
            _scene(bpy, scene, "smooth", water=water)
            cheap(scene, spp=args.spp, photons=args.photons,
                  caustic_photons=args.caustic_photons)
            scene.cycles.glossy_bounces = args.glossy
            scene.photonmap.seed = args.seed
            scene.photonmap.threads = 1
            with tempfile.TemporaryDirectory() as tmp:
                c0 = time.process_time()
                m = _mean(bpy, scene, os.path.join(tmp, "o.exr"), "PHOTONMAP")
                cpu = time.process_time() - c0
            ratio = f"{m / want:.4f}" if water else "-"
            if warm_up:
                warm_up = False
                continue
            print(f"| {'glass of water' if water else 'empty glass'} | {name} | "
                  f"{m:.4f} | {ratio} | {cpu:.1f} |", flush=True)
    finally:
        pk.GLASS_ADJOINT_MODE, pk.GLASS_ADJOINT_MIN_BEND_DEG = saved


if __name__ == "__main__":
    main()
