"""Per-object light passes of two multilayer renders of bench/newuser46_kitchen.py
(--passes) against each other: for each object of the --masks file (100 pixels or more)
and each light pass, the mean luminance of pass x its Color pass (the light that pass
adds to Combined; Emission and Environment as they are) in the reference and the ratio
of the other's to it.

    .venv/bin/python bench/newuser46_passes.py MASKS.npy REF.exr OTHER.exr [--least N]

Luminance: Rec. 709 weights of linear RGB. A pass whose reference mean is below 0.5 % of
the object's Combined is printed as "-" (its ratio is noise).
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "tests", "blender"))
from newuser26_compare import LUM, read_masks  # noqa: E402
from blender_helpers import read_layers  # noqa: E402

KINDS = ("Diffuse", "Glossy", "Transmission")


def light(layers):
    """{pass: (H, W, 3)} of the light each pass adds to Combined, and Combined."""
    out = {"Combined": layers["Combined"][..., :3].astype(np.float64)}
    for k in KINDS:
        col = layers[f"{k} Color"][..., :3].astype(np.float64)
        for t in ("Direct", "Indirect"):
            out[f"{k} {t}"] = layers[f"{k} {t}"][..., :3] * col
    for n in ("Emit", "Emission", "Env", "Environment"):
        if n in layers:
            out[n] = layers[n][..., :3].astype(np.float64)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("masks")
    ap.add_argument("ref")
    ap.add_argument("other")
    ap.add_argument("--least", type=int, default=100)
    a = ap.parse_args()
    ids, names = read_masks(a.masks)
    ref, oth = light(read_layers(a.ref)), light(read_layers(a.other))
    passes = [p for p in ref if p in oth]
    print("| object (pixels) | " + " | ".join(passes) + " |")
    print("|---|" + "---|" * len(passes))
    rows = [(n, ids == i) for i, n in enumerate(names)] + [("whole image", ids > -9)]
    for name, m in rows:
        if m.sum() < a.least:
            continue
        comb = float((ref["Combined"][m] @ LUM).mean())
        cells = []
        for p in passes:
            r, o = float((ref[p][m] @ LUM).mean()), float((oth[p][m] @ LUM).mean())
            cells.append("-" if r < 0.005 * comb else f"{r:.3f} x {o / r:.3f}")
        print(f"| {name} ({int(m.sum())}) | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
