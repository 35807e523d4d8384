"""A furnace for rough glass seen at an angle (session 47 trial): a 2 x 2 m slab, 8 mm
thick, of Glass BSDF (the node's IOR, roughness ROUGH) in a uniform white World of
strength 1, seen from 3 m at ANGLE degrees from its normal (120 mm lens, 48 x 36), by
Photon Mapping (the add-on's defaults) or by Cycles (SPP samples, no denoising, no
adaptive sampling, Clamp Indirect 0); both engines at Filter Glossy FG (--filter-glossy,
default 0: ours reads the scene's Filter Glossy as Cycles does, and an unequal pair
compares the blur, not the glass: docs/accuracy.md, newuser47, "Correction (lead)").

    PYTHONPATH=. .venv/bin/python bench/newuser47_furnace.py MODE ANGLE ROUGH [--out DIR]
        [--distribution MULTI_GGX|GGX|BECKMANN] [--bounces N] [--filter-glossy FG]

MODE: ours | cycles:SPP. Prints `FURNACE mode angle rough: slab mean RGB ...`, the mean
linear RGB over the pixels whose camera ray hits the slab first (Blender's
scene.ray_cast), and the World's where it shows. The light leaving the slab is what
its two rough interfaces (and the bounce limits) pass of the World's 1.0; the two
engines' ratio is the glass closures' difference at that angle (docs/accuracy.md,
newuser47: the bathroom's frosted shower screen).
"""
from __future__ import annotations

import argparse
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import bpy  # noqa: E402

from newuser26_compare import read_exr  # noqa: E402
from newuser26_scenes import camera, cube, object_masks, world_colour  # noqa: E402
from newuser47_bathroom import frosted_glass  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode")
    ap.add_argument("angle", type=float)
    ap.add_argument("rough", type=float)
    ap.add_argument("--out", default="/tmp", help="folder of the EXR (default /tmp)")
    ap.add_argument("--distribution", default="MULTI_GGX",
                    help="the Glass BSDF's distribution (default MULTI_GGX, the node's)")
    ap.add_argument("--bounces", type=int,
                    help="Light Paths Total, Glossy and Transmission bounces (read by both; "
                         "default Blender's 12, 4, 12)")
    ap.add_argument("--filter-glossy", type=float, default=0.0,
                    help="Light Paths Filter Glossy, read by both engines (default 0)")
    a = ap.parse_args()
    import addon
    addon.register()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    mat = frosted_glass("Frosted", a.rough)
    mat.node_tree.nodes["Glass BSDF"].distribution = a.distribution
    cube("Slab", (0, 0, 0), (2.0, 2.0, 0.008), mat)
    world_colour(scene, (1, 1, 1), 1.0)
    t = math.radians(a.angle)
    camera((0, -3 * math.sin(t), 3 * math.cos(t)), (0, 0, 0), lens=120)
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 48, 36, 100
    ids, names = object_masks(scene, 48, 36)
    if a.bounces:
        c = scene.cycles
        c.max_bounces = c.glossy_bounces = c.transmission_bounces = a.bounces
    scene.cycles.blur_glossy = a.filter_glossy  # (both engines read it)
    r.engine = "PHOTONMAP" if a.mode == "ours" else "CYCLES"
    if r.engine == "CYCLES":
        c = scene.cycles
        c.device, c.samples = "CPU", int(a.mode.split(":")[1])
        c.use_denoising = c.use_adaptive_sampling = False
        c.sample_clamp_indirect = 0.0
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    out = os.path.join(os.path.abspath(a.out), f"newuser47_furnace_"
                       f"{a.mode.replace(':', '')}_{a.angle:g}_{a.rough:g}_{a.distribution}_{a.bounces or 0}"
                       f"_fg{a.filter_glossy:g}.exr")
    r.filepath, r.use_file_extension = out, False
    bpy.ops.render.render(write_still=True)
    img = read_exr(out)
    slab = ids == names.index("Slab")
    world = img[ids < 0].mean(0).round(4) if (ids < 0).any() else "-"
    print(f"FURNACE {a.mode} {a.distribution} FG {a.filter_glossy:g} bounces {a.bounces or 'default'} angle {a.angle:g} rough {a.rough:g}: slab mean RGB "
          f"{img[slab].mean(0).round(4)} over {int(slab.sum())} px; world {world}")


if __name__ == "__main__":
    main()
