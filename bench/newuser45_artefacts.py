"""Artefact counts of renders of bench/newuser45_room.py against a reference, per object
(the --masks file of newuser45_room.py).

    .venv/bin/python bench/newuser45_artefacts.py MASKS.npy REF.exr A.exr [B.exr ...]

Per image: NaN / Inf pixels; fireflies (pixels whose luminance is over 4x - and specks,
over 2x - the median of their 3 x 3 neighbourhood of the same object, and over 0.05,
where the reference's pixel is not); blotches (the 99th percentile and maximum, over an object's pixels, of the ratio
of 5 x 5 box means of the image to the reference's, objects of 400 pixels or more, inner
pixels only: the whole box on that object); the largest luminance; and the mean HDR-FLIP
against the reference (flip_evaluator, docs/design.md, Measuring accuracy). Luminance: Rec. 709
weights of linear RGB.
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_exr, read_masks  # noqa: E402


def windows(a, k):
    """(H-k+1, W-k+1, k*k) views of a's k x k neighbourhoods."""
    from numpy.lib.stride_tricks import sliding_window_view
    v = sliding_window_view(a, (k, k))
    return v.reshape(*v.shape[:2], k * k)


def fireflies(lum, ids, floor=0.05, factor=4.0):
    """Boolean (H, W): over factor x the 3 x 3 median of the same object's neighbours."""
    h, w = lum.shape
    pad = np.pad(lum, 1, mode="edge")
    pid = np.pad(ids, 1, mode="constant", constant_values=-9)
    nb = windows(pad, 3).copy()
    same = windows(pid, 3) == ids[..., None]
    nb[~same] = np.nan
    med = np.nanmedian(nb, axis=-1)
    return (lum > factor * med) & (lum > floor)


def blotches(img_lum, ref_lum, ids, names, k=5, least=400):
    out = {}
    box = windows(img_lum, k).mean(-1)
    rbox = windows(ref_lum, k).mean(-1)
    whole = windows(ids, k)
    for i, n in enumerate(names):
        inner = (whole == i).all(-1)
        if (ids == i).sum() < least or inner.sum() == 0:
            continue
        r = box[inner] / np.maximum(rbox[inner], 1e-9)
        out[n] = (float(np.percentile(r, 99)), float(r.max()), float(np.percentile(r, 1)))
    return out


def main():
    masks_path, ref_path, *others = sys.argv[1:]
    ids, names = read_masks(masks_path)
    ref = read_exr(ref_path)
    rl = ref @ LUM
    ref_ff = fireflies(rl, ids)
    for p in [ref_path] + others:
        im = read_exr(p)
        bad = ~np.isfinite(im).all(-1)
        lum = np.where(bad, 0, im @ LUM)
        ff = fireflies(lum, ids) & (p == ref_path or ~ref_ff)
        specks = int((fireflies(lum, ids, factor=2.0)
                      & (p == ref_path or ~fireflies(rl, ids, factor=2.0))).sum())
        where = [(int(r), int(c), names[ids[r, c]] if ids[r, c] >= 0 else "(world)",
                  round(float(lum[r, c]), 3), round(float(rl[r, c]), 3))
                 for r, c in zip(*np.nonzero(ff))][:8]
        print(f"{os.path.basename(p)}: NaN/Inf {int(bad.sum())}, fireflies {int(ff.sum())} "
              f"{where}, specks (2x) {specks}, max luminance {lum.max():.3f}")
        if p != ref_path:
            import flip_evaluator
            flip = flip_evaluator.evaluate(ref.astype(np.float32), im.astype(np.float32),
                                           "HDR")[1]
            print(f"  HDR-FLIP against {os.path.basename(ref_path)}: {float(flip):.4f}")
            for n, (p99, mx, p1) in blotches(lum, rl, ids, names).items():
                print(f"  blotches {n}: 5x5 ratio 1st pct {p1:.3f}, 99th pct {p99:.3f}, "
                      f"max {mx:.3f}")


if __name__ == "__main__":
    main()
