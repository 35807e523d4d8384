"""The noise of one object's pixels from two renders that differ only in their seed
(subsurf49: the studio48 candle's random walk against Cycles' at equal samples).

    .venv/bin/python bench/subsurf49_noise.py MASKS.npy REF.exr OBJECT A.exr:B.exr ...

MASKS.npy an object-id mask (bench/newuser26_scenes.py --masks, with its .json names),
REF.exr a converged reference (only its mean and its per-pixel luminance scale are used),
OBJECT the object's name. Per pair of same-setting renders A, B (seeds apart) over the
object's pixels: the mean luminance of (A + B) / 2 over REF's; the noise of ONE image as
relMSE, mean over pixels and channels of (A - B)^2 / 2 / (ref^2 + 0.01) (the expected
relMSE of A against the exact image, Var(A - B) = 2 Var(A); newuser26_compare.py's
relMSE without the bias part); the same of the luminance alone; and the colour speckle:
the standard deviation over pixels of each channel's share of the pixel's R + G + B,
mean of A and B's.
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_exr, read_masks  # noqa: E402


def noise(a, b, ref):
    """(mean ratio, relMSE of one image per channel, of its luminance, (3,) share std)."""
    ratio = float(((a + b) / 2 @ LUM).mean() / (ref @ LUM).mean())
    rel = float(np.mean((a - b) ** 2 / 2 / (ref ** 2 + 0.01)))
    la, lb, lr = a @ LUM, b @ LUM, ref @ LUM
    rel_l = float(np.mean((la - lb) ** 2 / 2 / (lr ** 2 + 0.01)))
    share = []
    for x in (a, b):
        s = x.sum(axis=1, keepdims=True)
        share.append((x / np.where(s > 0, s, 1.0)).std(axis=0))
    return ratio, rel, rel_l, (share[0] + share[1]) / 2


def main():
    masks, ref_path, name, pairs = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    ids, names = read_masks(masks)
    m = ids == names.index(name)
    ref = read_exr(ref_path)[m].astype(np.float64)
    print(f"{name}: {int(m.sum())} pixels; reference {os.path.basename(ref_path)}")
    print("| renders A : B | mean / reference | relMSE (one image) | luminance relMSE "
          "| R / G / B share std |")
    print("|---|---|---|---|---|")
    for pair in pairs:
        a, b = (read_exr(p)[m].astype(np.float64) for p in pair.split(":"))
        ratio, rel, rel_l, share = noise(a, b, ref)
        print(f"| {' : '.join(os.path.basename(p) for p in pair.split(':'))} | {ratio:.3f} "
              f"| {rel:.4f} | {rel_l:.4f} | " + " / ".join(f"{x:.3f}" for x in share) + " |")


if __name__ == "__main__":
    main()
