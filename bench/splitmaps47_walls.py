"""What figure 6's walls keep unblurred under Filter Glossy's split (docs/compatibility.md
"splitmaps47", a): ours at Filter Glossy 0 and 1 (the split on), and the share of each
region's light that (1) the secondary map's estimates carry (integrator._smooth_estimate
of ctx.secondary_map and _secondary_irradiance replaced by zero), and (2) the gather map's
photons carry that scattered off a glossy or glass lobe after their first scatter (kind
INDIRECT / CAUSTIC_DIFFUSE with a glossy or transmission count; their power set to 0
before render._build_maps), at Filter Glossy 1.

    PYTHONPATH=$PWD .venv/bin/python bench/splitmaps47_walls.py [--spp 16]

scenes/figure6.toml at 160 x 120, seed 0, one worker, 200k / 100k photons. Regions by
image rows / columns (no object masks): walls at rows h/4-h/2 (left / right eighth), the
back wall rows h/8-h/3 (middle quarter), the floor the bottom sixth (middle quarter).
"""
from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from engine import RenderSettings, glossysplit  # noqa: E402
from engine import integrator as it  # noqa: E402
from engine.photonkernels import CAUSTIC_DIFFUSE, INDIRECT  # noqa: E402
from engine.scenefile import load_scene  # noqa: E402

rd = sys.modules["engine.render"]


def lum(a):
    a = np.asarray(a, np.float64)
    return a[..., 0] * 0.2126 + a[..., 1] * 0.7152 + a[..., 2] * 0.0722


def regions(L):
    h, w = L.shape
    return {"image": L, "left wall": L[h // 4:h // 2, :w // 8],
            "right wall": L[h // 4:h // 2, -w // 8:],
            "back wall": L[h // 8:h // 3, 3 * w // 8:5 * w // 8],
            "floor": L[-h // 6:, 3 * w // 8:5 * w // 8]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16)
    a = ap.parse_args()
    glossysplit.ENABLED = True
    scene, _ = load_scene(os.path.join(ROOT, "scenes", "figure6.toml"))
    scene.width, scene.height = 160, 120
    base = replace(RenderSettings(), spp=a.spp, seed=0, workers=1, photons=200_000,
                   caustic_photons=100_000)
    orig_se, orig_si, orig_bm = it._smooth_estimate, it._secondary_irradiance, rd._build_maps

    def no_secondary(ctx, pmap, *args, **kw):
        if pmap is not None and pmap is getattr(ctx, "secondary_map", None):
            return kw.get("into")
        return orig_se(ctx, pmap, *args, **kw)

    share = {}

    def no_specular_photons(ctx, shot, *args, **kw):
        b = np.asarray(shot.bounces, np.int64)
        gm = np.isin(shot.kind, (INDIRECT, CAUSTIC_DIFFUSE))
        cut = gm & (b[:, 2] + b[:, 3] > 0)
        p = shot.power.astype(np.float64).sum(axis=1)
        share["power"] = p[cut].sum() / p[gm].sum()
        shot.power[cut] = 0
        return orig_bm(ctx, shot, *args, **kw)

    def run(fg, variant=None):
        it._smooth_estimate = no_secondary if variant == "secondary" else orig_se
        it._secondary_irradiance = ((lambda ctx, hit, *x, **k: np.zeros((len(hit.p), 3)))
                                    if variant == "secondary" else orig_si)
        rd._build_maps = no_specular_photons if variant == "specular" else orig_bm
        f = rd.render(scene, replace(base, cycles_filter_glossy=fg))
        return {k: float(v.mean()) for k, v in regions(lum(f.combined)).items()}

    full = {fg: run(fg) for fg in (0.0, 1.0)}
    sec = {fg: run(fg, "secondary") for fg in (0.0, 1.0)}
    spec = run(1.0, "specular")
    print("| region | ours FG 0 | ours FG 1 | secondary map's share at 0 / 1 "
          "| specular gather photons' share at 1 | ours 1 / 0 |")
    print("|---|---:|---:|---:|---:|---:|")
    for k in full[0.0]:
        s0, s1 = (1 - sec[fg][k] / full[fg][k] for fg in (0.0, 1.0))
        print(f"| {k} | {full[0.0][k]:.4f} | {full[1.0][k]:.4f} | {100 * s0:.2f} % / "
              f"{100 * s1:.2f} % | {100 * (1 - spec[k] / full[1.0][k]):.2f} % | "
              f"{full[1.0][k] / full[0.0][k]:.4f} |")
    print(f"gather map photons' power with a glossy / transmission count: "
          f"{100 * share['power']:.1f} %")


if __name__ == "__main__":
    main()
