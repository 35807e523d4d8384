"""Render the Cycles reference of issue 14's Principled scene (tests/test_principled_cycles.py).

    .venv/bin/python tools/make_principled_reference.py [--samples 2048] [--low-samples 256]

Scene "principled_spheres" of tools/accuracy_scenes.py (a row of Principled balls on a rough
Principled floor, one area light, a dim grey world, 160x120), Cycles from the bpy wheel with
the comparison settings of tools/make_references.py. Writes

    tests/references/principled_spheres.npz    image: (H, W, 3) float16 linear radiance,
                                                rows top to bottom; labels: (H, W) uint8
                                                object labels (accuracy_scenes.object_labels)
    tests/references/principled_spheres.json   samples, seconds, object names, per-object
                                                mean RGB, and a second Cycles render at
                                                --low-samples (another seed) scored per
                                                object: the reference's own noise floor
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


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, default=2048)
    p.add_argument("--low-samples", type=int, default=256)
    args = p.parse_args(argv)
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
    }
    path = os.path.join(acc.REF_DIR, NAME + ".npz")
    with replacing(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, image=ref16, labels=labels)
    with open(os.path.join(acc.REF_DIR, NAME + ".json"), "w") as f:
        json.dump(meta, f, indent=1, sort_keys=True)
    print(f"{NAME}: {args.samples} spp in {t_ref:.0f} s; {args.low_samples} spp per-object "
          f"ratios {meta['cycles_low_ratio']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
