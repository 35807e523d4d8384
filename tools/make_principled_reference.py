"""Render the Cycles reference of issue 14's Principled scene (tests/test_principled_cycles.py).

    .venv/bin/python tools/make_principled_reference.py [--samples 2048] [--low-samples 256]
    .venv/bin/python tools/make_principled_reference.py --equal-time-only [--equal-time-samples 192]

Scene "principled_spheres" of tools/accuracy_scenes.py (a row of Principled balls on a rough
Principled floor, one area light, a dim grey world, 160x120), Cycles from the bpy wheel with
the comparison settings of tools/make_references.py. Writes

    tests/references/principled_spheres.npz    image: (H, W, 3) float16 linear radiance,
                                                rows top to bottom; labels: (H, W) uint8
                                                object labels (accuracy_scenes.object_labels)
    tests/references/principled_spheres.json   samples, seconds, object names, per-object
                                                mean RGB, and a second Cycles render at
                                                --low-samples (another seed) scored per
                                                object: the reference's own noise floor,
                                                and Cycles' HDR-FLIP at
                                                --equal-time-samples (seeds 1, 2) against
                                                the reference (cycles_equal_time)

--equal-time-only renders only that last part into the existing .json (the test of equal
time, tests/test_principled_cycles.py, compares our default render's FLIP with it). Its
sample count is Cycles' samples in the CPU time of our default render of the scene, from
bench/bench_accuracy_ab.py on one machine (docs/accuracy_time.md: Cycles 256 spp 11.0 CPU
s, ours 7.6 CPU s -> 177), rounded up to 192 so that Cycles gets a little more than equal
time.
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

NAME = "principled_spheres"
EQUAL_TIME_SAMPLES = 192
# Seeds other than the reference's 0: a render at seed 0 shares the reference's first samples.
EQUAL_TIME_SEEDS = (1, 2)


def equal_time(ref, samples):
    """Cycles at `samples` spp, seeds EQUAL_TIME_SEEDS: {samples, seeds, flip (mean HDR-FLIP
    against ref, per seed), seconds (wall, per seed)}."""
    flips, seconds = [], []
    for seed in EQUAL_TIME_SEEDS:
        img, t = acc.render_cycles(NAME, samples, seed=seed)
        flips.append(round(acc.flip(img, ref), 5))
        seconds.append(round(t, 2))
    return {"samples": samples, "seeds": list(EQUAL_TIME_SEEDS), "flip": flips,
            "seconds": seconds}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, default=2048)
    p.add_argument("--low-samples", type=int, default=256)
    p.add_argument("--equal-time-samples", type=int, default=EQUAL_TIME_SAMPLES)
    p.add_argument("--equal-time-only", action="store_true",
                   help="only (re)compute cycles_equal_time in the existing .json")
    args = p.parse_args(argv)
    json_path = os.path.join(acc.REF_DIR, NAME + ".json")
    if args.equal_time_only:
        with open(json_path) as f:
            meta = json.load(f)
        meta["cycles_equal_time"] = equal_time(acc.load_reference(NAME),
                                               args.equal_time_samples)
        with open(json_path, "w") as f:
            json.dump(meta, f, indent=1, sort_keys=True)
        print(f"{NAME}: equal time {meta['cycles_equal_time']}")
        return 0
    ref, t_ref = acc.render_cycles(NAME, args.samples, seed=0)
    if not np.isfinite(ref).all():
        raise SystemExit(f"{NAME}: Cycles reference has NaN/Inf")
    labels, names = acc.object_labels(NAME)
    low, t_low = acc.render_cycles(NAME, args.low_samples, seed=1)
    ref16 = ref.astype(np.float16)
    means = acc.object_means(ref16.astype(np.float32), labels, names)
    low_means = acc.object_means(low, labels, names)
    meta = {
        "width": int(ref.shape[1]), "height": int(ref.shape[0]),
        "cycles_samples": args.samples, "cycles_time_s": round(t_ref, 2),
        "objects": names,
        "pixels": {n: int((labels == i + 1).sum()) for i, n in enumerate(names)},
        "means": {n: [round(float(c), 6) for c in v] for n, v in means.items()},
        "cycles_low_samples": args.low_samples, "cycles_low_time_s": round(t_low, 2),
        # mean(low) / mean(ref) per object: how far a Cycles render at low samples strays
        "cycles_low_ratio": {n: round(float(low_means[n].mean() / means[n].mean()), 5)
                             for n in means},
        "cycles_low_relmse": round(acc.relmse(low, ref16.astype(np.float32)), 6),
        "cycles_low_flip": round(acc.flip(low, ref16.astype(np.float32)), 5),
        "date": time.strftime("%Y-%m-%d"),
        "cycles_equal_time": equal_time(ref16.astype(np.float32), args.equal_time_samples),
    }
    path = os.path.join(acc.REF_DIR, NAME + ".npz")
    with replacing(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, image=ref16, labels=labels)
    with open(json_path, "w") as f:
        json.dump(meta, f, indent=1, sort_keys=True)
    print(f"{NAME}: {args.samples} spp in {t_ref:.0f} s; {args.low_samples} spp per-object "
          f"ratios {meta['cycles_low_ratio']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
