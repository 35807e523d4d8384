"""A Shade Smooth subsurface candle alone under a sun (subsurf49): the studio48 candle's
top cap, whose flat face shares the rim's leaning vertex normals, against Cycles.

    PYTHONPATH=. .venv/bin/python bench/subsurf49_cap.py MODE OUT.exr [--res W H]
        [--set NAME=VALUE] [--cycles-seed S] [--flat-caps] [--sun-tilt DEG]
    PYTHONPATH=. .venv/bin/python bench/subsurf49_cap.py compare A.exr[+B.exr]:REF.exr ...
        [--flat-caps]

The candle of bench/studio48_stilllife.py (a 48-sided cylinder 3.5 cm in radius, 14 cm
tall, Principled (0.9, 0.82, 0.65), Roughness 0.4, Subsurface Weight 1 at the node's
Radius (1, 0.2, 0.1) and Scale 0.05; Shade Smooth, or its caps flat-shaded with
--flat-caps) under a black world and one Sun of strength 3, tilted --sun-tilt degrees
(default 30) from straight down towards the camera's side; an orthographic camera 45
degrees above the horizon. No clamping, Light Paths at Blender's defaults otherwise.
MODE: ours | cycles:SPP (seed --cycles-seed, no denoising, no adaptive sampling).
compare: per image pair, the mean luminance ratio over the cap's pixels (the camera ray
through the pixel centre meets a face of normal z > 0.9), the side's and the whole
candle's, each pixel's relMSE (mean of (img - ref)^2 / (ref^2 + 0.01)) and the mean
ratio per channel over the candle. "A.exr+B.exr": the mean of both.
"""
from __future__ import annotations

import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402
import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

from newuser26_scenes import cylinder, empty_scene, principled, world_colour  # noqa: E402
from newuser44_table import arguments, render  # noqa: E402

LUM = np.array([0.2126, 0.7152, 0.0722])


def candle_scene(flat_caps=False, sun_tilt=30.0, cam_elev=45.0):
    """The candle, the sun and the camera (docs above); returns the scene."""
    scene = empty_scene()
    world_colour(scene, (0.0, 0.0, 0.0), 0.0)
    candle = cylinder("Candle", 0.035, 0.14, (0.0, 0.0, 0.07),
                      principled("Wax", (0.9, 0.82, 0.65), 0.4, Subsurface_Weight=1.0),
                      vertices=48)
    if flat_caps:
        for poly in candle.data.polygons:
            if abs(poly.normal.z) > 0.9:
                poly.use_smooth = False
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.data.angle = 0.0
    sun.rotation_euler = (math.radians(sun_tilt), 0.0, math.radians(20.0))
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 0.2
    e = math.radians(cam_elev)
    loc = Vector((0.0, -0.7 * math.cos(e), 0.7 * math.sin(e) + 0.09))
    cam.location = loc
    cam.rotation_euler = (Vector((0.0, 0.0, 0.09)) - loc).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    c = scene.cycles
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    return scene


def regions(scene, w, h):
    """(cap, side) (H, W) bool masks, row 0 at the top: pixels whose centre ray (along
    the orthographic camera's view) meets the candle on a face of normal z > 0.9 / on
    another face."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    back = cam.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    cap, side = np.zeros((h, w), bool), np.zeros((h, w), bool)
    for j in range(h):
        for i in range(w):
            p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
            hit, _, nrm, _, ob, _ = scene.ray_cast(dg, p + back * 2.0, -back)
            if hit and ob.name == "Candle":
                (cap if nrm.z > 0.9 else side)[j, i] = True
    return cap, side


def image(spec):
    """(H, W, 3) float64 of an EXR, or the mean of "A.exr+B.exr"."""
    parts = spec.split("+")
    out = 0.0
    for p in parts:
        img = bpy.data.images.load(os.path.abspath(p))
        w, h = img.size
        px = np.array(img.pixels[:], np.float64).reshape(h, w, 4)[::-1, :, :3]
        bpy.data.images.remove(img)
        out = out + px
    return out / len(parts)


def compare(pairs, flat_caps, sun_tilt, cam_elev):
    first = image(pairs[0].split(":")[1])
    h, w = first.shape[:2]
    scene = candle_scene(flat_caps, sun_tilt, cam_elev)
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    cap, side = regions(scene, w, h)
    print("| image / reference | cap (px) | side (px) | candle | candle relMSE | "
          "candle R / G / B |")
    print("|---|---|---|---|---|---|")
    for pair in pairs:
        img, ref = (image(p) for p in pair.split(":"))
        cells = []
        for m in (cap, side, cap | side):
            cells.append(f"{(img[m] @ LUM).mean() / (ref[m] @ LUM).mean():.3f} "
                         f"({int(m.sum())})")
        m = cap | side
        rel = ((img[m] - ref[m]) ** 2 / (ref[m] ** 2 + 0.01)).mean()
        rgb = img[m].mean(axis=0) / ref[m].mean(axis=0)
        print(f"| {pair} | " + " | ".join(cells) + f" | {rel:.4f} | "
              + " / ".join(f"{x:.3f}" for x in rgb) + " |")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "compare":
        import argparse
        ap = argparse.ArgumentParser()
        ap.add_argument("cmd")
        ap.add_argument("pairs", nargs="+")
        ap.add_argument("--flat-caps", action="store_true")
        ap.add_argument("--sun-tilt", type=float, default=30.0)
        ap.add_argument("--cam-elev", type=float, default=45.0)
        a = ap.parse_args()
        return compare(a.pairs, a.flat_caps, a.sun_tilt, a.cam_elev)
    ap = arguments(__doc__)
    ap.set_defaults(res=(96, 96))
    ap.add_argument("--cycles-seed", type=int, default=0)
    ap.add_argument("--flat-caps", action="store_true")
    ap.add_argument("--sun-tilt", type=float, default=30.0)
    ap.add_argument("--cam-elev", type=float, default=45.0)
    a = ap.parse_args()
    import addon
    addon.register()
    render(candle_scene(a.flat_caps, a.sun_tilt, a.cam_elev), a)


if __name__ == "__main__":
    main()
