"""Render the Cycles reference images for the accuracy comparison (issue 4).

    .venv/bin/python tools/make_references.py [--only NAME[,NAME]] [--samples N]
                                              [--samples-256 N] [--list]

For each scene of tools/accuracy_scenes.py (the four example blends at low resolution plus
scenes built with bpy) renders Cycles from the bpy wheel with comparable settings (CPU, no
denoising, no clamping, filter glossy 0, 32 bounces, 1 px box pixel filter, no adaptive
sampling) and writes

    tests/references/NAME.npy          (H, W, 3) float16 linear radiance, rows top to bottom
    tests/references/references.json   per scene: samples, Cycles time, resolution, kind,
                                       and Cycles at 256 spp scored against the reference
                                       (relMSE, FLIP, brightness ratio, time)

The 256-spp render uses another seed, so its score is an honest "Cycles-256" error.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import accuracy_scenes as acc  # noqa: E402
from engine.imageio import replacing  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", help="comma-separated scene names (default: all)")
    p.add_argument("--samples", type=int, default=4096, help="reference samples per pixel")
    p.add_argument("--samples-256", type=int, default=256,
                   help="samples of the 'Cycles at low samples' comparison render")
    p.add_argument("--list", action="store_true", help="list scene names and exit")
    args = p.parse_args(argv)
    if args.list:
        for name, (_, kind) in acc.SCENES.items():
            print(f"{name:20s} {kind}")
        return 0
    names = list(acc.SCENES) if not args.only else args.only.split(",")
    for n in names:
        if n not in acc.SCENES:
            p.error(f"unknown scene {n!r}; known: {', '.join(acc.SCENES)}")
    os.makedirs(acc.REF_DIR, exist_ok=True)
    meta = acc.load_meta()
    t_all = time.perf_counter()
    for name in names:
        samples = max(args.samples, acc.REFERENCE_SAMPLES.get(name, 0))
        ref, t_ref = acc.render_cycles(name, samples, seed=0)
        if not np.isfinite(ref).all():
            raise SystemExit(f"{name}: Cycles reference has NaN/Inf")
        low, t_low = acc.render_cycles(name, args.samples_256, seed=1)
        with replacing(os.path.join(acc.REF_DIR, name + ".npy")) as tmp:
            np.save(tmp, ref.astype(np.float16))
        ref16 = ref.astype(np.float16).astype(np.float32)
        meta[name] = {
            "kind": acc.SCENES[name][1],
            "width": int(ref.shape[1]), "height": int(ref.shape[0]),
            "cycles_samples": samples, "cycles_time_s": round(t_ref, 2),
            "cycles_low_samples": args.samples_256, "cycles_low_time_s": round(t_low, 2),
            "cycles_low_relmse": round(acc.relmse(low, ref16), 6),
            "cycles_low_flip": round(acc.flip(low, ref16), 5),
            "cycles_low_brightness": round(acc.brightness(low, ref16), 5),
            "mean": round(float(ref.mean()), 6),
            "date": time.strftime("%Y-%m-%d"),
        }
        print(f"{name:18s} ref {samples} spp {t_ref:6.1f} s | "
              f"{args.samples_256} spp {t_low:5.1f} s: relMSE {meta[name]['cycles_low_relmse']:.4f}"
              f" FLIP {meta[name]['cycles_low_flip']:.4f}", flush=True)
        with open(os.path.join(acc.REF_DIR, "references.json"), "w") as f:
            json.dump(meta, f, indent=1, sort_keys=True)
    print(f"done in {time.perf_counter() - t_all:.0f} s -> {acc.REF_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
