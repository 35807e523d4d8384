"""Per-object brightness and error of renders of a bench/newuser26_scenes.py scene against
a reference, over the pixels whose camera ray hits that object first (the --masks file of
newuser26_scenes.py).

    .venv/bin/python bench/newuser26_compare.py MASKS.npy REF.exr A.exr [B.exr ...]

Prints a table: per object its pixel count, the reference's mean luminance, and for each
image the ratio of its mean luminance to the reference's and its relMSE
(mean of (x - ref)^2 / (ref^2 + 0.01), per channel; pbrt/Mitsuba's relative MSE), then
the same for the whole image. Luminance: Rec. 709 weights of linear RGB.
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np

LUM = np.array([0.2126, 0.7152, 0.0722])


def read_exr(path):
    """(H, W, 3) float32 linear RGB, row 0 at the top."""
    import Imath
    import OpenEXR
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, pt), np.float32).reshape(h, w)
                     for c in "RGB"], -1).astype(np.float64)


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def read_masks(path):
    """(ids (H, W) int, names) of a --masks file and its JSON of object names."""
    with open(path + ".json") as f:
        return np.load(path), json.load(f)


def main():
    masks_path, ref_path, *others = sys.argv[1:]
    ids, names = read_masks(masks_path)
    ref = read_exr(ref_path)
    imgs = [read_exr(p) for p in others]
    head = " | ".join(f"{os.path.basename(p)} ratio / relMSE" for p in others)
    print(f"| object | pixels | ref luminance | {head} |")
    print("|---|---|---|" + "---|" * len(others))
    rows = [(n, ids == i) for i, n in enumerate(names)] + [("(background)", ids < 0),
                                                           ("whole image", ids > -9)]
    for name, m in rows:
        if m.sum() == 0:
            continue
        lr = float((ref[m] @ LUM).mean())
        cells = []
        for im in imgs:
            li = float((im[m] @ LUM).mean())
            cells.append(f"{li / max(lr, 1e-12):.3f} / {rel_mse(im[m], ref[m]):.4f}")
        print(f"| {name} | {int(m.sum())} | {lr:.4f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
