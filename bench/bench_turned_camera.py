"""Camera paths through smooth-sided glass seen from the side (turnedcamera45): ours with
the camera paths' guard at bent smooth glass (turnedlight.CAMERA off, as before) and
without it (Cycles' turned normal, the default), against Cycles.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_turned_camera.py [--spp 16]
        [--photons 20000] [--caustic-photons 100000] [--seed 0] [--cycles-spp 1024]
        [--glossy 4] [--shadings smooth,flat] [--contents water,empty,bottle] [--save DIR]

The scene is tests/blender/test_glass_of_water_cycles.py's (a glass, with or without
water, on a diffuse table; a 30-degree sun 20 degrees off the vertical; black world) seen
by a perspective camera from the side and a little above (tests/blender/
test_turned_camera_cycles.py's _side_scene): the camera meets the smooth sides at every
angle up to grazing at the silhouettes and the rims (vertex normals up to 47 degrees off
their faces). Image means and the means over the glass's box in the image; ours' CPU
seconds (one thread) per render. --contents bottle: the glass replaced by a lathed wine
bottle (BOTTLE) standing on the table, smooth or flat. Prints a Markdown table (docs/accuracy.md,
turnedcamera45).
"""
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy  # noqa: E402
# (registers the add-on in this Blender)
from bench_turned_light import glass_arguments, glass_cases  # noqa: E402
from engine import turnedlight  # noqa: E402
from blender_helpers import cheap, cycles_plain, read_rgba, render_exr  # noqa: E402
from test_turned_camera_cycles import _glass_box, _side_scene  # noqa: E402

MODES = {"guard (before)": False, "turned (now)": True}


# newuser44's wine bottle (bench/newuser44_table.py: radius, height from its base), 6x as
# wide and 3x as tall: a lathed solid ~1 m tall, 0.25 m in radius, bent at its base,
# shoulder and lip.
BOTTLE = [(6 * r, 3 * z) for r, z in ((0.04, 0.0), (0.042, 0.01), (0.042, 0.2),
                                      (0.035, 0.24), (0.018, 0.27), (0.014, 0.30),
                                      (0.014, 0.33))]


def _bottle(shading):
    """The side scene's glass replaced by BOTTLE (Shade Smooth, or flat), named "Glass"
    (the glass box is its bounding box), in the glass's material."""
    from newuser44_table import lathe
    old = bpy.data.objects["Glass"]
    mat = old.data.materials[0]
    bpy.data.objects.remove(old)
    ob = lathe("Glass", BOTTLE, mat, (0.0, 0.0, 0.001))
    for p in ob.data.polygons:
        p.use_smooth = shading == "smooth"


def _render(engine, shading, content, args, tmp, name):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    _side_scene(bpy, scene, shading, water=content == "water")
    if content == "bottle":
        _bottle(shading)
    # Light Paths as Cycles is compared (no clamp, no glossy blur, 12 bounces): the
    # add-on reads them too.
    cycles_plain(scene, args.cycles_spp, 12)
    if engine != "CYCLES":
        cheap(scene, spp=args.spp, photons=args.photons,
              caustic_photons=args.caustic_photons)
        scene.photonmap.seed = args.seed
        scene.photonmap.threads = 1
    scene.cycles.glossy_bounces = args.glossy
    scene.render.engine = engine
    box = _glass_box(bpy, scene)
    c0 = time.process_time()
    img = read_rgba(bpy, render_exr(bpy, scene, os.path.join(tmp, name + ".exr")))[..., :3]
    cpu = time.process_time() - c0
    if args.save:
        np.save(os.path.join(args.save, name + ".npy"), img)
    return float(img.mean()), float(img[box].mean()), cpu


def main():
    ap = glass_arguments(16)
    ap.add_argument("--save", default="", help="folder for each render's (H,W,3) .npy")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        _render("PHOTONMAP", "flat", "water", args, tmp, "warm")  # loads the kernels
        for content, _, shading in glass_cases(args):
            got = {}
            for mode, on in MODES.items():
                turnedlight.CAMERA = on
                try:
                    got[mode] = _render("PHOTONMAP", shading, content, args, tmp,
                                        f"{content}_{shading}_{on}")
                finally:
                    turnedlight.CAMERA = True
            cyc = _render("CYCLES", shading, content, args, tmp,
                          f"cycles_{content}_{shading}_g{args.glossy}")
            rows.append((content, shading, got, cyc))
    print(f"\nours {args.spp} spp, {args.photons} / {args.caustic_photons} photons, seed "
          f"{args.seed}, one thread; Cycles {args.cycles_spp} spp, Glossy {args.glossy}; "
          f"load {os.getloadavg()[0]:.1f}\n")
    print("| content | shading | Cycles: image / glass box | "
          + " | ".join(f"{m}: image / glass box (ratio)" for m in MODES) + " | CPU s |")
    print("|---|---|---|" + "---|" * (len(MODES) + 1))
    for content, shading, got, cyc in rows:
        cells = [f"{got[m][0]:.4f} / {got[m][1]:.4f} ({got[m][0] / cyc[0]:.3f} / "
                 f"{got[m][1] / cyc[1]:.3f})" for m in MODES]
        label = {"water": "glass of water", "empty": "empty glass"}.get(content, content)
        print(f"| {label} | {shading} | "
              f"{cyc[0]:.4f} / {cyc[1]:.4f} | " + " | ".join(cells) + " | "
              + " / ".join(f"{got[m][2]:.1f}" for m in MODES) + " |")


if __name__ == "__main__":
    main()
