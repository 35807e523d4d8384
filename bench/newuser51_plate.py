"""Contact bands of bench/newuser51_donut.py renders against a reference: the pixels of
object A within D pixels of object B in the --masks image (where a light leak under the
plate, a missing contact shadow or self-intersection acne would show), and the pixels of
A farther than that, as a control.

    .venv/bin/python bench/newuser51_plate.py MASKS.npy REF.exr A.exr [B.exr ...]
        [--pairs Table:Plate,Plate:Donut,...] [--d 3]

An image argument "B.exr+C.exr" is the mean of B and C. Prints, per band, its pixel
count, the reference's mean luminance and per image the ratio of its mean luminance to
the reference's and its relMSE (newuser26_compare.rel_mse). Luminance: Rec. 709 weights.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_exr, read_masks, rel_mse  # noqa: E402

PAIRS = ("Table:Plate,Table:Mug,Plate:Donut,Plate:Icing,Icing:Sprinkles,Donut:Icing,"
         "Sprinkles:Icing")


def read(arg):
    return np.mean([read_exr(p) for p in arg.split("+")], axis=0)


def near(mask, d):
    """Pixels within Chebyshev distance d of mask (a square dilation)."""
    out = mask.copy()
    h, w = mask.shape
    for dy in range(-d, d + 1):
        for dx in range(-d, d + 1):
            s = np.zeros_like(mask)
            s[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] = \
                mask[max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)]
            out |= s
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("masks")
    ap.add_argument("ref")
    ap.add_argument("images", nargs="+")
    ap.add_argument("--pairs", default=PAIRS)
    ap.add_argument("--d", type=int, default=3)
    a = ap.parse_args()
    ids, names = read_masks(a.masks)
    ref = read(a.ref)
    imgs = [read(p) for p in a.images]
    head = " | ".join(f"{os.path.basename(p)} ratio / relMSE" for p in a.images)
    print(f"| band (d = {a.d} px) | pixels | ref luminance | {head} |")
    print("|---|---|---|" + "---|" * len(imgs))
    for pair in a.pairs.split(","):
        na, nb = pair.split(":")
        if na not in names or nb not in names:
            continue
        ma, mb = ids == names.index(na), ids == names.index(nb)
        band = ma & near(mb, a.d)
        for label, m in ((f"{na} near {nb}", band), (f"{na} farther from {nb}", ma & ~band)):
            if m.sum() == 0:
                continue
            lr = float((ref[m] @ LUM).mean())
            cells = [f"{float((im[m] @ LUM).mean()) / max(lr, 1e-12):.3f} / "
                     f"{rel_mse(im[m], ref[m]):.4f}" for im in imgs]
            print(f"| {label} | {int(m.sum())} | {lr:.4f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
