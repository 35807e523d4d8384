"""The garden's tree crown (bench/newuser48_garden.py) by the leaf cards a camera ray
crosses before what it sees: Cycles' transparent bounces, against renders.

    .venv/bin/python bench/newuser48_crown.py MASKS.npy REF.exr A.exr [B.exr ...]
    .venv/bin/python bench/newuser48_crown.py --passes MASKS.npy REF.exr OTHER.exr

MASKS.npy and MASKS_passed.npy are newuser48_garden.py --masks' files: per pixel the
object its centre's camera ray sees ('Leaves' a leaf card's opaque texel, -1 the sky)
and the cards it passed on the way (texel alpha below 0.5). Prints, per band of cards
passed and what the ray sees there (a leaf, the sky, another object), the pixels, the
reference's mean luminance and each image's mean luminance over it. Luminance: Rec. 709
weights of linear RGB. Cycles ends a path after Light Paths > Max Bounces > Transparent
(8) transparent bounces; a pixel past 8 cards is black there.

--passes: two multilayer renders (newuser48_garden.py --passes): per band, the
reference's mean luminance of each light pass (x its Color pass, as
bench/newuser46_passes.py) and OTHER's ratio to it, so the light a leaf reflects
(Diffuse / Glossy, Direct / Indirect) is told from the sky seen past the cards
(Environment).
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_exr, read_masks  # noqa: E402

BANDS = ((0, 0), (1, 3), (4, 7), (8, 8), (9, 999))


def bands(ids, names, passed):
    """[(band label, what, (H, W) bool)] over the crown's pixels."""
    leaf = ids == names.index("Leaves")
    crown = leaf | (passed > 0)
    kinds = (("leaf", leaf), ("sky", ids < 0), ("other", (ids >= 0) & ~leaf))
    out = []
    for lo, hi in BANDS:
        for what, m0 in kinds:
            m = m0 & crown & (passed >= lo) & (passed <= hi)
            if m.sum():
                band = f"{lo}" if lo == hi else f"{lo}-{hi}" if hi < 999 else f"{lo}+"
                out.append((band, what, m))
    return out


def passes_main(masks_path, ref_path, other_path):
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(
        os.path.abspath(__file__))), "tests", "blender"))
    from blender_helpers import read_layers
    from newuser46_passes import light
    ids, names = read_masks(masks_path)
    passed = np.load(masks_path[:-4] + "_passed.npy")
    ref, oth = light(read_layers(ref_path)), light(read_layers(other_path))
    names_p = [p for p in ref if p in oth and p != "Combined"]
    print("| cards passed | sees | pixels | Combined | " + " | ".join(names_p) + " |")
    print("|---|---|---|---|" + "---|" * len(names_p))
    for band, what, m in bands(ids, names, passed):
        cells = []
        for p in ["Combined"] + names_p:
            r = float((ref[p][m] @ LUM).mean())
            o = float((oth[p][m] @ LUM).mean())
            cells.append(f"{r:.3f} x {o / r:.3f}" if r > 1e-4 else "-")
        print(f"| {band} | {what} | {int(m.sum())} | " + " | ".join(cells) + " |")


def main():
    if sys.argv[1] == "--passes":
        return passes_main(*sys.argv[2:5])
    masks_path, ref_path, *others = sys.argv[1:]
    ids, names = read_masks(masks_path)
    passed = np.load(masks_path[:-4] + "_passed.npy")
    ref = read_exr(ref_path) @ LUM
    imgs = [read_exr(p) @ LUM for p in others]
    head = " | ".join(f"{os.path.basename(p)} / ref" for p in others)
    print(f"| cards passed | sees | pixels | ref luminance | {head} |")
    print("|---|---|---|---|" + "---|" * len(others))
    for band, what, m in bands(ids, names, passed):
        lr = float(ref[m].mean())
        cells = " | ".join(f"{float(im[m].mean()) / max(lr, 1e-12):.3f}" for im in imgs)
        print(f"| {band} | {what} | {int(m.sum())} | {lr:.4f} | {cells} |")


if __name__ == "__main__":
    main()
