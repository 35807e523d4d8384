"""The caustic map's search radius and k: accuracy against an analytic ball-lens profile,
and what it costs in CPU time (issue 14: the caustic under a glass ball).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_caustic_radius.py [--photons 100000,400000]
        [--k 16,32,64,128] [--seed 1]

The scene of the new-user trial (s16, case 3): a smooth glass ball (IOR 1.5, radius 0.6 m)
resting on a diffuse floor under a sun (angle 0) from 35 degrees above the horizon. Its
caustic lands past the ball's paraxial focus: a bright spot and a halo of spherical
aberration. The reference is tests/ball_lens.py (rays traced through a perfect sphere in
numpy, Fresnel at both interfaces, 4M rays binned in 2 cm cells; no engine code). Each
row: one caustic photon count and one rule for the estimate's cap (max radius) and k;
the caustic map's knn_simpson estimate at the centres of the same 2 cm cells (a 1 x 2 m
window around the spot) against the reference:
  L1     sum |E - ref| / sum ref over the window (noise and blur; the photons' own 2 cm
         bins score this at the photon count's noise floor, row "photon bins")
  peak   the brightest cell / the reference's brightest cell
  width  radius about the peak holding 50 % of the window's power / the reference's
  total  the window's integrated irradiance (W) / the reference's (conservation)
  cpu    CPU ms of the estimates (5,151 points, one thread) and of the photon pass
Rules: "global" (render's: the global photons' spacing, photonmap.caustic_radius),
"own" (auto_radius over the caustic photons themselves: 2 x their median k-NN distance),
"min" (the smaller of both), "5 cm" (fixed). Prints one Markdown table, and the load.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

from ball_lens import (CENTRE, IOR, R, SUN, SUN_DIR, CELL, XS, YS,  # noqa: E402
                       ball_scene, bin_irradiance, encircled_radius, floor_hits)
from engine import RenderSettings  # noqa: E402
from engine.photonlayout import powers  # noqa: E402
from engine.photonmap import auto_radius  # noqa: E402
from engine.render import prepare_context, shoot_photons  # noqa: E402


def reference(rays=4_000_000):
    pts, power = floor_hits(CENTRE, R, IOR, SUN_DIR, SUN, rays=rays, seed=7)
    return bin_irradiance(pts, power, XS, YS, CELL)


def scores(img, ref):
    return (float(np.abs(img - ref).sum() / ref.sum()), float(img.max() / ref.max()),
            encircled_radius(img, XS, YS) / encircled_radius(ref, XS, YS),
            float(img.sum() / ref.sum()))


def shoot(caustic_photons, seed, photons=400_000):
    settings = RenderSettings(spp=1, photons=photons, caustic_photons=caustic_photons,
                              seed=seed, workers=1)
    ctx = prepare_context(ball_scene(), settings)
    t = time.process_time()
    shoot_photons(ctx, {})
    return ctx, time.process_time() - t


def estimate(ctx, radius, k):
    X, Y = np.meshgrid(XS, YS)
    q = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)]) - ctx.geo.offset
    n = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    cm = ctx.caustic_map.serial()
    best = math.inf
    for _ in range(2):
        t = time.process_time()
        E = cm.irradiance(q, n, radius, k, 1, "knn_simpson")[:, 1]
        best = min(best, time.process_time() - t)
    return E.reshape(X.shape), best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--photons", default="100000,400000")
    ap.add_argument("--k", default="16,32,64,128")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    ref = reference()
    print(f"load: {os.getloadavg()[0]:.2f} (1-min), {os.cpu_count()} cores")
    print("| caustic photons | rule | max radius (m) | k | L1 | peak | width | total | "
          "cpu estimates (ms) | cpu photon pass (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for count in (int(c) for c in a.photons.split(",")):
        ctx, t_shoot = shoot(count, a.seed)
        cm = ctx.caustic_map
        pos = cm.photons.position.astype(np.float64) + ctx.geo.offset
        on = np.abs(pos[:, 2]) < 1e-3
        bins = bin_irradiance(pos[on, :2], powers(cm.photons.power)[on, 1],
                              XS, YS, CELL)
        l1, pk, wd, tot = scores(bins, ref)
        print(f"| {len(cm):,} | photon bins (2 cm) | - | - | {l1:.3f} | {pk:.3f} | {wd:.3f} | "
              f"{tot:.3f} | - | {t_shoot:.2f} |")
        own = auto_radius(1.0, len(cm), 64, ctx.geo.extent, cm.photons.position, cm.tree)
        rules = (("global", ctx.caustic_radius), ("own", own),
                 ("min", min(own, ctx.caustic_radius)), ("5 cm", 0.05))
        for k in (int(x) for x in a.k.split(",")):
            for name, radius in rules:
                if name == "min" and radius == ctx.caustic_radius:
                    continue
                E, t = estimate(ctx, radius, k)
                l1, pk, wd, tot = scores(E, ref)
                print(f"| {len(cm):,} | {name} | {radius:.4f} | {k} | {l1:.3f} | {pk:.3f} | "
                      f"{wd:.3f} | {tot:.3f} | {1e3 * t:.1f} | {t_shoot:.2f} |")
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
