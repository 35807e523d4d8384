"""photonblur50: what Filter Glossy's split of pre-diffuse photons costs in the photon
pass (photons.SPLIT_GATHER_PHOTONS; docs/accuracy.md "### photonblur50").

At Filter Glossy 1 a photon's first non-diffuse scatter before any diffuse bounce goes
on as two copies (photonkernels._scatter's split_slots): an unblurred one that ends at its
first diffuse choice (the caustic map's) and a blurred one (every other store). Per
scene: the photon pass' wall time (best of --repeat, one thread, kernels warm), the
stored photons per kind, and the stored power per kind, split off against on.

Scenes: the glossy box (tests/test_photon_filter_glossy.py: a closed 2 m cube of
Principled Base Color 0.8, roughness 0.1, a point light) and the metal-patch room (Lambert
walls, a white metal patch that a spot lights alone: every photon splits).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_photon_split.py [--photons 200000] \\
        [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests")]

from engine import RenderSettings  # noqa: E402
from engine import photonkernels as pk  # noqa: E402
from engine import photons as photons_module  # noqa: E402

import test_photon_filter_glossy as t  # noqa: E402
from test_energy import shoot  # noqa: E402

KINDS = (("direct", pk.DIRECT), ("caustic", pk.CAUSTIC), ("indirect", pk.INDIRECT),
         ("caustic_diffuse", pk.CAUSTIC_DIFFUSE))


def run(scene, photons, depth, split, repeat):
    photons_module.SPLIT_GATHER_PHOTONS = split
    best, ph = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        ph = shoot(scene(), RenderSettings(photons=photons, max_photon_depth=depth,
                                           cycles_filter_glossy=1.0, workers=1))
        best = min(best, time.perf_counter() - t0)
    return best, ph


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--photons", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    run(t._glossy_box, 2000, 8, True, 1)  # (kernels loaded)
    print("| scene | split | photon pass s | stored | "
          + " | ".join(f"{n} W" for n, _ in KINDS) + " |")
    print("|---|---|---|---|" + "---|" * len(KINDS))
    for name, scene, depth in (("glossy box", t._glossy_box, 40),
                               ("metal patch", t._metal_patch_room, 12)):
        for split in (False, True):
            s, ph = run(scene, a.photons, depth, split, a.repeat)
            watts = [ph.power[ph.kind == k, 0].astype(np.float64).sum() for _, k in KINDS]
            print(f"| {name} | {'on' if split else 'off'} | {s:.2f} | {len(ph)} | "
                  + " | ".join(f"{w:.2f}" for w in watts) + " |", flush=True)


if __name__ == "__main__":
    main()
