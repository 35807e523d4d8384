"""Photon-guided final-gather directions (engine/guiding.py, settings gather_guiding,
gather_guide_source) against the cosine gather: per scene and setting the CPU seconds, the
error against the Cycles reference (relMSE, HDR-FLIP; mean over the seeds), the noise part
of relMSE (from two seeds: mean (a - b)^2 / 2 / (ref^2 + 0.01)) and noise x CPU (equal-time
efficiency: lower is better; the ratio of two rows' noise x CPU is the time one needs for
the other's noise). Prints a table.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_gather_guiding.py \
        [--scenes figure6_box,principled_spheres] [--seeds 0 1] [--workers 2]
        [--rows cosine,indirect,flux,flux+regathers]

Scenes of tools/accuracy_scenes.py at our defaults against their stored Cycles
references. (The new user's daylit room of docs/accuracy.md "guide33" is rendered through
the add-on by its own script, not this bench.)
"""
from __future__ import annotations

import argparse
import os
import resource
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

import accuracy_scenes as A  # noqa: E402  (needs the bpy wheel)
from engine import integrator  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

ROWS = {"cosine": dict(gather_guiding=False),
        "indirect": dict(gather_guiding=True, gather_guide_source="indirect"),
        "flux": dict(gather_guiding=True, gather_guide_source="flux"),
        "flux+regathers": dict(gather_guiding=True, gather_guide_source="flux"),
        "indirect+regathers": dict(gather_guiding=True, gather_guide_source="indirect")}


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="figure6_box,principled_spheres")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rows", default="cosine,indirect,flux")
    args = ap.parse_args(argv)
    ensure_compiled()
    jobs = []
    for name in filter(None, args.scenes.split(",")):
        scene, kw = A.export_ours(name)
        jobs.append((name, scene, kw, A.load_reference(name)))
    print("| scene | gather | CPU s | relMSE | HDR-FLIP | noise relMSE | noise x CPU |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name, scene, base, ref in jobs:
        for label in args.rows.split(","):
            integrator.GUIDE_REGATHERS = label.endswith("+regathers")
            cpu, imgs = [], []
            for seed in args.seeds:
                t = cpu_seconds()
                film = render(scene, RenderSettings(**dict(base, **ROWS[label], seed=seed,
                                                           workers=args.workers)))
                cpu.append(cpu_seconds() - t)
                imgs.append(np.asarray(film.combined, np.float64)[..., :3])
            integrator.GUIDE_REGATHERS = False
            rel = np.mean([A.relmse(x, ref) for x in imgs])
            fl = np.mean([A.flip(x.astype(np.float32), ref) for x in imgs])
            noise = (float(np.mean((imgs[0] - imgs[1]) ** 2 / 2 / (ref.astype(np.float64) ** 2
                                                                   + 0.01)))
                     if len(imgs) > 1 else float("nan"))
            print(f"| {name} | {label} | {np.mean(cpu):.1f} | {rel:.5f} | {fl:.4f} | "
                  f"{noise:.2e} | {noise * np.mean(cpu):.2e} |", flush=True)


if __name__ == "__main__":
    main()
