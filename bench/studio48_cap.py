"""The studio48 candle split into its top cap and its side (docs/accuracy.md "## studio48"):
the candle pixels whose camera ray (through the pixel centre, Blender's scene.ray_cast)
meets a face of geometric normal z > 0.9, and the rest; per region the mean luminance
ratio of each image pair IMG:REF. The scene is bench/studio48_stilllife.py's with the
same --drop list as the renders (the pixel grid 160 x 120).

    .venv/bin/python bench/studio48_cap.py MASKS.npy A.exr[+B.exr]:REF.exr ... \
        [--candle-flat-caps] [--drop NAME ...]      (--drop last: it takes the rest)

An image "A.exr+B.exr" is the mean of both (seeds pooled). Luminance: Rec. 709 weights.
"""
from __future__ import annotations

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402
import bpy  # noqa: E402

import studio48_stilllife as still  # noqa: E402
from newuser26_compare import LUM, read_masks  # noqa: E402
from newuser48_flip import image  # noqa: E402


def cap_mask(scene, candle, w, h):
    """(H, W) bool: candle pixels whose centre ray meets a face of normal z > 0.9."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    o = cam.matrix_world.translation
    cap = np.zeros((h, w), bool)
    for j, i in zip(*np.nonzero(candle)):
        p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
        hit, _, nrm, _, _, _ = scene.ray_cast(dg, o, (p - o).normalized())
        cap[j, i] = hit and nrm.z > 0.9
    return cap


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("masks")
    ap.add_argument("pairs", nargs="+")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--candle-flat-caps", action="store_true")
    ap.add_argument("--hdr", default="/tmp/studio48/studio.hdr")
    a = ap.parse_args()
    still.write_hdr(a.hdr, still.studio_pixels())
    scene = still.studio_scene(a.hdr, a.drop, None, a.candle_flat_caps)
    ids, names = read_masks(a.masks)
    h, w = ids.shape
    scene.render.resolution_x, scene.render.resolution_y = w, h
    candle = ids == names.index("Candle")
    cap = cap_mask(scene, candle, w, h)
    print("| image / reference | cap (pixels) | side (pixels) | whole candle |")
    print("|---|---|---|---|")
    for pair in a.pairs:
        img, ref = (image(p) for p in pair.split(":"))
        cells = []
        for m in (cap, candle & ~cap, candle):
            cells.append(f"{(img[m] @ LUM).mean() / (ref[m] @ LUM).mean():.3f} ({int(m.sum())})")
        print(f"| {pair} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
