"""Per-region brightness, contrast and grain of renders of bench/newuser54_plant.py against
a reference (its --masks file): the leaf shadows' sharpness and grain.

    .venv/bin/python bench/newuser54_regions.py MASKS.npy REF.exr A.exr [B.exr ...]

An argument "B.exr+C.exr" is the mean of B and C (bench/newuser48_flip.py). Per region and
image: the ratio of its mean luminance to the reference's; "std" the ratio of its pixels'
luminance standard deviation to the reference's (the shadows' contrast plus the grain);
"grain" the standard deviation of (image - reference) luminance over the region, relative
to the reference's mean (the noise; the reference's own counts in it); "edge" the ratio of
the mean absolute luminance step to the next pixel (right and down, both pixels in the
region) to the reference's (below 1: blurred outlines, above: sharper or grainier).
Luminance: Rec. 709 weights of linear RGB.
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_masks  # noqa: E402
from newuser48_flip import image  # noqa: E402


def steps(lum, m):
    """Mean |luminance step| between neighbours (right, down) both inside mask m."""
    down = np.abs(np.diff(lum, axis=0))[m[1:] & m[:-1]]
    right = np.abs(np.diff(lum, axis=1))[m[:, 1:] & m[:, :-1]]
    s = np.concatenate([down, right])
    return float(s.mean()) if s.size else float("nan")


def main():
    masks_path, ref_path, *others = sys.argv[1:]
    ids, names = read_masks(masks_path)
    rl = image(ref_path) @ LUM
    ims = [image(p) @ LUM for p in others]
    head = " | ".join(f"{os.path.basename(p)} ratio / std / grain / edge" for p in others)
    print(f"| region | pixels | ref luminance | ref std | {head} |")
    print("|---|---|---|---|" + "---|" * len(others))
    for i, name in sorted(enumerate(names), key=lambda t: t[1]):
        m = ids == i
        if m.sum() < 20:
            continue
        ref_mean, ref_std, ref_step = rl[m].mean(), rl[m].std(), steps(rl, m)
        cells = []
        for lum in ims:
            cells.append(f"{lum[m].mean() / ref_mean:.3f} / {lum[m].std() / ref_std:.2f} / "
                         f"{(lum - rl)[m].std() / ref_mean:.3f} / "
                         f"{steps(lum, m) / ref_step:.2f}")
        print(f"| {name} | {int(m.sum())} | {ref_mean:.4f} | {ref_std:.4f} | "
              + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
