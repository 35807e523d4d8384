"""Write the mean of several renders (independent seeds: their samples pooled) as one RGB
EXR, for a reference of more samples than one render (bench/studio48_stilllife.py;
docs/accuracy.md "## studio48"). A multilayer EXR (--passes) contributes its Combined
pass, so a passes render also serves as a plain one.

    .venv/bin/python bench/studio48_pool.py OUT.exr A.exr [B.exr ...]
"""
from __future__ import annotations

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests", "blender"))
from newuser26_compare import read_exr  # noqa: E402


def read_rgb(path):
    """(H, W, 3) float64 linear RGB of a plain EXR or a multilayer EXR's Combined pass."""
    import OpenEXR
    names = OpenEXR.InputFile(path).header()["channels"]
    if "R" in names:
        return read_exr(path)
    from blender_helpers import read_layers
    return read_layers(path)["Combined"][..., :3].astype(np.float64)


def write_exr(path, rgb):
    """A 32-bit float RGB EXR of (H, W, 3) linear RGB, row 0 at the top."""
    import Imath
    import OpenEXR
    h, w, _ = rgb.shape
    head = OpenEXR.Header(w, h)
    head["channels"] = {c: Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT)) for c in "RGB"}
    f = OpenEXR.OutputFile(path, head)
    f.writePixels({c: rgb[..., i].astype(np.float32).tobytes() for i, c in enumerate("RGB")})
    f.close()


def main():
    out, *paths = sys.argv[1:]
    write_exr(out, sum(read_rgb(p) for p in paths) / len(paths))


if __name__ == "__main__":
    main()
