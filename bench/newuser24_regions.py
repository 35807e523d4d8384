"""Region means of two renders of a bench/newuser24_scenes.py scene, per object: the
middle half (each way) of the pixel box the object's vertices project to, so each region
sees mostly that object.

    NUMBA_CACHE_DIR=... PYTHONPATH=. .venv/bin/python bench/newuser24_regions.py \
        SCENE A.exr B.exr OBJECT [OBJECT ...] [--res 160 120]

Prints per object the mean linear RGB of A, of B and A / B.
"""
from __future__ import annotations

import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (ROOT, os.path.join(ROOT, "bench")):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402
import bpy  # noqa: E402


def read(path, w, h):
    img = bpy.data.images.load(os.path.abspath(path))
    px = np.array(img.pixels[:], np.float64).reshape(h, w, 4)[::-1, :, :3]  # top row first
    return px


def box(scene, obj, w, h):
    from bpy_extras.object_utils import world_to_camera_view
    dg = bpy.context.evaluated_depsgraph_get()
    ob = obj.evaluated_get(dg)
    pts = [world_to_camera_view(scene, scene.camera, ob.matrix_world @ v.co)
           for v in ob.data.vertices]
    xs = np.array([p.x for p in pts]) * w
    ys = (1.0 - np.array([p.y for p in pts])) * h
    x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
    cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 4, (y1 - y0) / 4
    return (int(max(cy - hy, 0)), int(min(cy + hy, h)), int(max(cx - hx, 0)),
            int(min(cx + hx, w)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("objects", nargs="+")
    ap.add_argument("--res", type=int, nargs=2, default=(160, 120))
    args = ap.parse_args()
    import newuser24_scenes as nu
    scene = nu.SCENES[args.scene]()
    w, h = args.res
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    a, b = read(args.a, w, h), read(args.b, w, h)
    print("| object | A | B | A / B |")
    print("|---|---|---|---|")
    for name in args.objects:
        r0, r1, c0, c1 = box(scene, bpy.data.objects[name], w, h)
        ma = a[r0:r1, c0:c1].reshape(-1, 3).mean(axis=0)
        mb = b[r0:r1, c0:c1].reshape(-1, 3).mean(axis=0)
        print(f"| {name} | {ma[0]:.3f} {ma[1]:.3f} {ma[2]:.3f} | {mb[0]:.3f} {mb[1]:.3f} "
              f"{mb[2]:.3f} | {ma[0] / mb[0]:.3f} {ma[1] / mb[1]:.3f} {ma[2] / mb[2]:.3f} |")


if __name__ == "__main__":
    main()
