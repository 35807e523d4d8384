"""Cycles' sample weights against ours in the MIS pdf that a camera path's min_ray_pdf takes
(engine/filterglossy.py mis_pdf; fgcamera46): principled_spheres' materials, directions
continued by our continuation (integrator.continue_specular) from hits of random rays
around the balls; the blur alpha at Filter Glossy 1 each way.

    PYTHONPATH=$PWD .venv/bin/python bench/fgcamera46_weights.py [--rays 200000]

Cycles' weights: every lobe's estimated albedo's mean channel (its sample_weight); ours:
the non-diffuse lobes' max channel (choose_lobes' p) with the diffuse lobe's mean channel
(what _trace_paths passes), and, for comparison, its max channel too. Each lobe's own pdf
from principled.bsdf_pdf with that lobe alone selected. Prints a Markdown table.
"""
import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import accuracy_scenes as acc  # noqa: E402  (needs the bpy wheel)
from engine.bsdf import closures, surface_hit  # noqa: E402
from engine.closures import principled as pr  # noqa: E402
from engine.filterglossy import blur_alphas, mis_pdf  # noqa: E402
from engine.integrator import continue_specular, lobe_choice  # noqa: E402
from engine.render import prepare_context  # noqa: E402
from engine.sampling import uniform_sphere  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rays", type=int, default=200_000)
    a = ap.parse_args(argv)
    scene, kw = acc.export_ours("principled_spheres")
    ctx = prepare_context(scene, RenderSettings(**dict(kw, workers=1)))
    rng = np.random.default_rng(0)
    n = a.rays
    o = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-1.5, 1.5, n),
                         rng.uniform(0.05, 1.5, n)])
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    hit = surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[k])
    prm, alb = closures(ctx.table, hit, ctx.geo)
    tp = np.ones((len(hit.mat), 3))
    choice = lobe_choice(alb, tp)
    sel, q, p, psum = choice
    keep, _, d2, _, _, pdf = continue_specular(ctx, hit, tp, rng, choice=choice,
                                               want_pdf=True)
    fin = np.isfinite(pdf)
    r, wi = keep[fin], d2[fin]
    ns, wo = hit.ns[r], hit.wo[r]
    cos_i = np.sum(ns * wi, axis=1)
    ours = mis_pdf(pdf[fin], q[r], psum[r], alb[r, 0].mean(axis=1), cos_i)
    ours_max = mis_pdf(pdf[fin], q[r], psum[r], alb[r, 0].max(axis=1), cos_i)
    num, den = np.zeros(len(r)), np.zeros(len(r))
    c = np.ascontiguousarray
    for lobe in range(1, pr.N_LOBES):
        if lobe == pr.L_GLASS_T:  # (one closure with the reflection: bsdf_pdf's glass)
            continue
        one = np.zeros((len(r), pr.N_LOBES))
        one[:, lobe] = 1.0
        pl = np.empty(len(r))
        pr.bsdf_pdf_many(c(prm[r]), one, c(ns), c(wo), c(wi), pl)
        w = alb[r, lobe].mean(axis=1)
        if lobe == pr.L_GLASS_R:
            w = w + alb[r, pr.L_GLASS_T].mean(axis=1)
        num += w * pl
        den += w
    wd = alb[r, 0].mean(axis=1)
    cyc = (num + wd * np.maximum(cos_i, 0) / np.pi) / (den + wd)
    bo, bm, bc = (blur_alphas(1.0, x) for x in (ours, ours_max, cyc))
    print(f"{len(r)} continued rough samples from {len(hit.mat)} hits")
    print("| material | samples | pdf ours / Cycles (median) | blurs: Cycles | ours | "
          "decisions differ | diffuse max channel: pdf ratio | decisions differ |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    mats = hit.mat[r]
    for mt in np.unique(mats):
        s = mats == mt
        print(f"| {ctx.table.names[mt]} | {s.sum()} | {np.median(ours[s] / cyc[s]):.3f} | "
              f"{np.mean(bc[s] > 0):.3f} | {np.mean(bo[s] > 0):.3f} | "
              f"{np.mean((bo[s] > 0) != (bc[s] > 0)):.4f} | "
              f"{np.median(ours_max[s] / cyc[s]):.3f} | "
              f"{np.mean((bm[s] > 0) != (bc[s] > 0)):.4f} |")


if __name__ == "__main__":
    main()
