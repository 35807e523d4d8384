"""Volume single scattering: exponential distance sampling alone against the mixture with
equiangular sampling towards point / spot lights (engine/volumescatter.py EQUIANGULAR).

Two engine scenes, direct light only (photon mapping off), 40 x 30:
  spot   a fog box (sigma_s 0.4, sigma_a 0.1 /m, g 0.3) lit by a narrow spot from above,
         seen from the side (a god ray: most exponential samples land outside the cone)
  point  the same box with a point light inside it (the 1 / r^2 peak near the lamp)
For each: the reference is the mean of REF_SEEDS renders with the mixture at REF_SPP; each
strategy renders SEEDS seeds at SPP; printed: relMSE (mean over pixels and channels of
(x - ref)^2 / (ref^2 + 0.01)), the mean over seeds, and seconds per render.

    .venv/bin/python bench/bench_volume_equiangular.py [--spp 16] [--seeds 4]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import RenderSettings, volumescatter  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.render import render  # noqa: E402
from engine.scene import Material  # noqa: E402


def scene(kind):
    s = PaperScene(40, 30)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_material(Material("fog", volume_only=True, absorption=(0.1, 0.1, 0.1),
                            scattering=(0.4, 0.4, 0.4), anisotropy=0.3))
    s.add_box((0.0, 0.0, 1.0), (2.4, 2.4, 1.6), "fog", name="fog")
    if kind == "spot":
        s.add_spot_light((0.0, 0.0, 2.6), (0, 0, 0), power=400.0, spot_size_degrees=25.0,
                         blend=0.1)
    else:
        s.add_point_light((0.3, 0.0, 1.1), power=40.0)
    s.set_camera((0.0, -5.0, 1.2), (0.0, 0.0, 0.9), view_angle=45.0)
    return s


def image(kind, spp, seed, equiangular):
    volumescatter.EQUIANGULAR = equiangular
    t = time.perf_counter()
    film = render(scene(kind), RenderSettings(workers=1, spp=spp, photon_mapping=False,
                                              seed=seed))
    return np.asarray(film.combined, np.float64)[..., :3], time.perf_counter() - t


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--ref-spp", type=int, default=256)
    ap.add_argument("--ref-seeds", type=int, default=4)
    a = ap.parse_args()
    print(f"| scene | strategy | spp | relMSE (mean of {a.seeds} seeds) | s / render | "
          "image mean |")
    print("|---|---|---|---|---|---|")
    for kind in ("spot", "point"):
        ref = np.mean([image(kind, a.ref_spp, 100 + k, True)[0]
                       for k in range(a.ref_seeds)], axis=0)
        for name, eq in (("exponential", False), ("mixture with equiangular", True)):
            errs, secs, means = [], [], []
            for k in range(a.seeds):
                img, sec = image(kind, a.spp, k, eq)
                errs.append(rel_mse(img, ref))
                secs.append(sec)
                means.append(img.mean() / ref.mean())
            print(f"| {kind} | {name} | {a.spp} | {np.mean(errs):.5f} | {np.mean(secs):.2f} | "
                  f"{np.mean(means):.4f} of the reference |", flush=True)
    volumescatter.EQUIANGULAR = True


if __name__ == "__main__":
    main()
