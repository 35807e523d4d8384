"""Whole-image HDR-FLIP and relMSE of renders against a reference, where an image may be
the mean of several renders (independent seeds: their samples pooled), for equal-time
comparisons (bench/newuser48_garden.py; docs/accuracy.md "## newuser48").

    .venv/bin/python bench/newuser48_flip.py REF.exr A.exr [B.exr+C.exr ...]

An argument "B.exr+C.exr" is the mean of B and C. Prints per image its mean luminance
ratio to the reference, relMSE (newuser26_compare.rel_mse) and mean HDR-FLIP
(flip_evaluator; docs/design.md, Measuring accuracy). Luminance: Rec. 709 weights.
"""
from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from newuser26_compare import LUM, read_exr, rel_mse  # noqa: E402


def image(arg):
    """(H, W, 3) float64: one EXR or the mean of '+'-joined EXRs."""
    parts = arg.split("+")
    return sum(read_exr(p) for p in parts) / len(parts)


def main():
    import flip_evaluator
    ref_path, *others = sys.argv[1:]
    ref = read_exr(ref_path)
    print(f"| image | luminance / {os.path.basename(ref_path)} | relMSE | HDR-FLIP |")
    print("|---|---|---|---|")
    for arg in others:
        im = image(arg)
        flip = flip_evaluator.evaluate(ref.astype(np.float32), im.astype(np.float32),
                                       "HDR")[1]
        ratio = float((im @ LUM).mean() / (ref @ LUM).mean())
        name = "+".join(os.path.basename(p) for p in arg.split("+"))
        print(f"| {name} | {ratio:.4f} | {rel_mse(im, ref):.4f} | {float(flip):.4f} |")


if __name__ == "__main__":
    main()
