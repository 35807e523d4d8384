"""The garden's tree crown (bench/newuser48_garden.py) by the leaf cards a camera ray
crosses before what it sees: Cycles' transparent bounces, against renders.

    .venv/bin/python bench/newuser48_crown.py MASKS.npy REF.exr A.exr [B.exr ...]

MASKS.npy and MASKS_passed.npy are newuser48_garden.py --masks' files: per pixel the
object its centre's camera ray sees ('Leaves' a leaf card's opaque texel, -1 the sky)
and the cards it passed on the way (texel alpha below 0.5). Prints, per band of cards
passed and what the ray sees there (a leaf, the sky, another object), the pixels, the
reference's mean luminance and each image's mean luminance over it. Luminance: Rec. 709
weights of linear RGB. Cycles ends a path after Light Paths > Max Bounces > Transparent
(8) transparent bounces; a pixel past 8 cards is black there.
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_exr, read_masks  # noqa: E402

BANDS = ((0, 0), (1, 3), (4, 7), (8, 8), (9, 999))


def main():
    masks_path, ref_path, *others = sys.argv[1:]
    ids, names = read_masks(masks_path)
    passed = np.load(masks_path[:-4] + "_passed.npy")
    ref = read_exr(ref_path) @ LUM
    imgs = [read_exr(p) @ LUM for p in others]
    leaf = ids == names.index("Leaves")
    crown = leaf | (passed > 0)
    kinds = (("leaf", leaf), ("sky", ids < 0), ("other", (ids >= 0) & ~leaf))
    head = " | ".join(f"{os.path.basename(p)} / ref" for p in others)
    print(f"| cards passed | sees | pixels | ref luminance | {head} |")
    print("|---|---|---|---|" + "---|" * len(others))
    for lo, hi in BANDS:
        for what, m0 in kinds:
            m = m0 & crown & (passed >= lo) & (passed <= hi)
            if m.sum() == 0:
                continue
            lr = float(ref[m].mean())
            cells = " | ".join(f"{float(im[m].mean()) / max(lr, 1e-12):.3f}" for im in imgs)
            band = f"{lo}" if lo == hi else f"{lo}-{hi}" if hi < 999 else f"{lo}+"
            print(f"| {band} | {what} | {int(m.sum())} | {lr:.4f} | {cells} |")


if __name__ == "__main__":
    main()
