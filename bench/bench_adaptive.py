"""Adaptive sampling (engine/adaptive.py, Cycles' Noise Threshold) on the example blends:
CPU time, mean samples per pixel and error against the stored Cycles references, at fixed
spp and at a few thresholds; which threshold keeps the fixed-spp default's error.

Each blend is exported once through the add-on at its reference's resolution and at our
default settings (tools/accuracy_scenes.export_ours: the pixel filter and bounce limits
the references were rendered with), then rendered with engine.render in this process for
each setting and seed, the settings interleaved per seed. CPU s: process CPU time of the
whole render (photon pass included; resource.getrusage, all threads), camera s: the
camera pass's own wall seconds (film.stats["time_camera"]). relMSE and HDR-FLIP as
bench/bench_accuracy.py scores them (tools/accuracy_scenes.relmse / flip), averaged over
the seeds.

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_adaptive.py \
        [--blends figure6_box,figure7_blocker] [--seeds 0 1] [--workers 1]
        [--thresholds 0.1 0.05 0.02 0.01] [--fixed 128 64 32] [--min-samples 0]

--passes: what rounds cost in stratification: fixed 128 spp against every pixel taking its
128 samples in 8 adaptive rounds of 16 (threshold 1e-6, Min Samples 4: no pixel converges
but those of exactly constant colour), per pass (direct, indirect, caustic, specular) its
image mean over the seeds and its per-pixel noise (std over the seeds, averaged over the
image).
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
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

BLENDS = ("figure3_sphere", "figure6_box", "figure7_blocker", "figure8_caustic")


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def one(scene, kwargs, ref):
    t = cpu_seconds()
    film = render(scene, RenderSettings(**kwargs))
    cpu = cpu_seconds() - t
    img = film.combined
    spp = film.stats.get("adaptive_mean_spp", kwargs["spp"])
    return dict(cpu=cpu, camera=film.stats.get("time_camera", float("nan")), spp=spp,
                relmse=A.relmse(img, ref), flip=A.flip(img, ref))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default=",".join(BLENDS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--thresholds", type=float, nargs="+", default=[0.1, 0.05, 0.02, 0.01])
    ap.add_argument("--fixed", type=int, nargs="+", default=[128, 64, 32],
                    help="fixed spp rows (the first: the default)")
    ap.add_argument("--min-samples", type=int, default=0,
                    help="Min Samples of the threshold rows (0: auto, as Cycles)")
    ap.add_argument("--passes", action="store_true",
                    help="per-pass mean and noise: fixed 128 spp vs 8 rounds of 16")
    args = ap.parse_args(argv)
    ensure_compiled()
    if args.passes:
        return passes(args)
    print("| blend | setting | mean spp | CPU s | camera s | relMSE | HDR-FLIP |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name in args.blends.split(","):
        ref = A.load_reference(name)
        scene, base = A.export_ours(name)
        base = dict(base, workers=args.workers)
        rows = {f"fixed {n} spp": dict(base, spp=n) for n in args.fixed}
        for t in args.thresholds:
            label = f"threshold {t:g}" + (f", min {args.min_samples}" if args.min_samples else "")
            rows[label] = dict(base, spp=args.fixed[0], adaptive_threshold=t,
                               adaptive_min_samples=args.min_samples)
        res = {k: [] for k in rows}
        for seed in args.seeds:  # interleaved: each seed renders every setting in turn
            for label, kw in rows.items():
                res[label].append(one(scene, dict(kw, seed=seed), ref))
        for label, rs in res.items():
            m = {k: float(np.mean([r[k] for r in rs])) for k in rs[0]}
            print(f"| {name} | {label} | {m['spp']:.1f} | {m['cpu']:.2f} | "
                  f"{m['camera']:.2f} | {m['relmse']:.5f} | {m['flip']:.4f} |", flush=True)


def passes(args):
    names = ("direct", "indirect", "caustic", "specular")
    print("| blend | camera pass | " + " | ".join(f"{n} mean / noise" for n in names) + " |")
    print("|---|---|" + "---:|" * len(names))
    for name in args.blends.split(","):
        scene, base = A.export_ours(name)
        rows = {"fixed 128 spp": dict(base, workers=args.workers, spp=128),
                "8 rounds of 16": dict(base, workers=args.workers, spp=128,
                                       adaptive_threshold=1e-6, adaptive_min_samples=4)}
        out = {k: [] for k in rows}
        for seed in args.seeds:
            for label, kw in rows.items():
                film = render(scene, RenderSettings(**dict(kw, seed=seed)))
                out[label].append({n: getattr(film, n).astype(np.float64) for n in names})
        for label, films in out.items():
            cells = []
            for n in names:
                a = np.array([f[n] for f in films])
                cells.append(f"{a.mean():.5f} / {a.std(axis=0, ddof=1).mean():.5f}")
            print(f"| {name} | {label} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
