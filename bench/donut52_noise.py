"""Where an image's error sits, per region of bench/newuser51_donut.py's masks: the table
split by its distance to the plate in the image (the plate's defocused rim and its
penumbra lie within 3 pixels), then every other object (docs/accuracy.md "donut52").

    .venv/bin/python bench/donut52_noise.py flip MASKS.npy REF.exr A.exr [B.exr ...]
    .venv/bin/python bench/donut52_noise.py noise MASKS.npy REF.exr A.exr+B.exr [...]
    .venv/bin/python bench/donut52_noise.py passes MASKS.npy REF.exr A.exr+B.exr [...]

flip: per region the mean HDR-FLIP of each image against REF (flip_evaluator, as
bench/newuser48_flip.py) and the region's share of the image's summed FLIP.
noise: per region the pixel variance of ONE render, from two renders of independent
seeds A and B: mean over the region of (A - B)^2 / 2 / (REF^2 + 0.01) (relMSE's
denominator, newuser26_compare.rel_mse; so a render's relMSE is this plus its bias^2
and REF's own noise), x 1e5.
passes: the same for each light pass of two multilayer renders (--passes: the light each
pass adds to Combined, bench/newuser46_passes.py), x 1e5; the passes' variances need not
add up to Combined's (they covary).
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import read_exr, read_masks  # noqa: E402
from newuser51_plate import near  # noqa: E402


def regions(ids, names):
    """[(label, (H, W) bool)]: the table within 3 pixels of the plate, 4-10 pixels, farther;
    the other objects; the whole image."""
    table, plate = ids == names.index("Table"), ids == names.index("Plate")
    n3, n10 = near(plate, 3), near(plate, 10)
    out = [("Table <= 3 px from the Plate", table & n3), ("Table 4-10 px", table & n10 & ~n3),
           ("Table farther", table & ~n10)]
    out += [(n, ids == i) for i, n in enumerate(names) if n != "Table"]
    return out + [("whole image", ids > -9)]


def flip(regs, ref, paths):
    import flip_evaluator
    maps = []
    for p in paths:
        f = flip_evaluator.evaluate(ref.astype(np.float32), read_exr(p).astype(np.float32),
                                    "HDR", applyMagma=False)[0]
        maps.append(np.asarray(f, np.float64).reshape(ref.shape[0], ref.shape[1], -1)[..., 0])
    print("| region (pixels) | " + " | ".join(f"{os.path.basename(p)} FLIP (share)"
                                             for p in paths) + " |")
    print("|---|" + "---|" * len(paths))
    for label, m in regs:
        print(f"| {label} ({int(m.sum())}) | " + " | ".join(
            f"{f[m].mean():.4f} ({f[m].sum() / f.sum():.2f})" for f in maps) + " |")


def variance(a, b, den):
    """(H, W): one render's pixel variance from two seeds, over den, channel mean."""
    return ((a - b) ** 2 / 2.0 / den).mean(-1)


def noise(regs, ref, pairs):
    den = ref ** 2 + 0.01
    cols = [variance(*(read_exr(p) for p in pair.split("+")), den) for pair in pairs]
    print("| region (pixels) | " + " | ".join(
        "+".join(os.path.basename(p) for p in pair.split("+")) for pair in pairs) + " |")
    print("|---|" + "---|" * len(pairs))
    for label, m in regs:
        print(f"| {label} ({int(m.sum())}) | " + " | ".join(f"{v[m].mean() * 1e5:.2f}"
                                                          for v in cols) + " |")


def passes(regs, ref, pairs):
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(
        __file__))), "tests", "blender"))
    from blender_helpers import read_layers
    from newuser46_passes import light
    den = ref ** 2 + 0.01
    for pair in pairs:
        a, b = (light(read_layers(p)) for p in pair.split("+"))
        names = [p for p in a if p in b and np.any(a[p]) or p == "Combined"]
        print(f"{pair}: one render's variance x 1e5 per light pass")
        print("| region (pixels) | " + " | ".join(names) + " |")
        print("|---|" + "---|" * len(names))
        v = {p: variance(a[p], b[p], den) for p in names}
        for label, m in regs:
            print(f"| {label} ({int(m.sum())}) | " + " | ".join(
                f"{v[p][m].mean() * 1e5:.2f}" for p in names) + " |")


def main():
    mode, masks, ref, *images = sys.argv[1:]
    ids, names = read_masks(masks)
    regs = regions(ids, names)
    {"flip": flip, "noise": noise, "passes": passes}[mode](regs, read_exr(ref), images)


if __name__ == "__main__":
    main()
