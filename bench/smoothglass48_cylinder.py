"""smoothglass48's reproduction of cleanuser47's drinking glass (docs/accuracy.md,
"smoothglass48"): the kitchen's lathed glass (bench/cleanuser47_table.py: one ring of faces
per wall, Glass BSDF at the node's defaults) 10x larger, Shade Smooth or Flat, seen head-on
against a constant World (no other light), optionally standing on a white table top (its
base coincident with the top, as in the kitchen).

    PYTHONPATH=. .venv/bin/python bench/smoothglass48_cylinder.py MODE OUT.exr [--flat]
        [--table] [--solid] [--bounces N] [--elev DEG]
        [--gap M] [--z M] [--res W H] [--set NAME=VALUE] [--spp N]
    PYTHONPATH=. .venv/bin/python bench/smoothglass48_cylinder.py compare CYCLES.exr OURS.exr...

MODE: ours | cycles:SPP (bench/newuser44_table.py render(): no denoise, seed 0). The
World is white (1.0), so a lossless glass that lets every path escape reads 1.0 wherever
it is seen; what a smooth glass loses (paths Cycles refuses) reads as darkness. --bounces
sets every Light Paths limit (default 32: the limits out of the way; 0 leaves Blender's).
--solid: a closed solid cylinder (the same outer wall and caps) instead of the shell.
compare prints the mean over the glass's columns (pixels whose value differs from the
World's in the Cycles image's rows), per column band, for each OURS against CYCLES.
"""
from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import numpy as np  # noqa: E402

PROFILE_SHELL = [(0.3, 0.0), (0.4, 1.1), (0.37, 1.1), (0.27, 0.05)]  # cleanuser47's x 10
PROFILE_SOLID = [(0.3, 0.0), (0.4, 1.1)]


def build(flat=False, table=False, solid=False, bounces=32, world=1.0, elev=0.0, gap=0.0, z=0.0):
    import bpy
    from newuser26_scenes import camera, cube, empty_scene, principled, world_colour
    from newuser44_table import lathe
    from cleanuser47_table import glass_default
    scene = empty_scene()
    cup = glass_default("CupGlass")
    g = lathe("Glass", PROFILE_SOLID if solid else PROFILE_SHELL, cup, (0.0, 0.0, z))
    if flat:
        for p in g.data.polygons:
            p.use_smooth = False
    if table:
        cube("TableTop", (0.0, 0.5, z - gap - 0.02), (3.0, 3.0, 0.04), principled("Top", (0.8, 0.8, 0.8), 0.5))
    world_colour(scene, (world, world, world), 1.0)
    import math
    e = math.radians(elev)  # the camera 4 m away, elev degrees above the glass's middle
    camera((0.0, -4.0 * math.cos(e), z + 0.55 + 4.0 * math.sin(e)), (0.0, 0.0, z + 0.55),
           lens=100.0)
    c = scene.cycles
    if bounces:
        c.max_bounces = c.diffuse_bounces = c.glossy_bounces = bounces
        c.transmission_bounces = c.transparent_max_bounces = bounces
    c.caustics_reflective = c.caustics_refractive = True
    c.blur_glossy = 0.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    return scene


def read_exr(path):
    from newuser26_compare import read_exr as read
    return read(path)


def compare(ref_path, paths):
    ref = read_exr(ref_path)
    lum = ref @ np.array([0.2126, 0.7152, 0.0722])
    rows = slice(int(0.2 * lum.shape[0]), int(0.8 * lum.shape[0]))  # the walls, not rim / base
    glass = np.abs(lum[rows] - np.median(lum[rows][:, :3])) > 1e-3
    cols = np.flatnonzero(glass.any(axis=0))
    if not len(cols):
        return print("no glass columns found")
    c0, c1 = cols[0], cols[-1] + 1
    print(f"glass columns {c0}..{c1 - 1}, rows {rows.start}..{rows.stop - 1}")
    imgs = [read_exr(p) @ np.array([0.2126, 0.7152, 0.0722]) for p in paths]
    bands = np.array_split(np.arange(c0, c1), 8)
    head = "cols".ljust(10) + "Cycles".rjust(8) + "".join(
        os.path.basename(p)[:12].rjust(14) for p in paths)
    print(head)
    for b in bands:
        line = f"{b[0]:>3}-{b[-1]:<5}" + f"{lum[rows][:, b].mean():8.4f}"
        for im in imgs:
            v = im[rows][:, b].mean()
            line += f"  {v:6.4f} {v / max(lum[rows][:, b].mean(), 1e-9):5.3f}"
        print(line)
    whole = lum[rows][:, c0:c1].mean()
    line = "glass".ljust(10) + f"{whole:8.4f}"
    for im in imgs:
        v = im[rows][:, c0:c1].mean()
        line += f"  {v:6.4f} {v / whole:5.3f}"
    print(line)


def main():
    if sys.argv[1] == "compare":
        return compare(sys.argv[2], sys.argv[3:])
    from newuser44_table import arguments, render
    ap = arguments(__doc__)
    ap.add_argument("--flat", action="store_true")
    ap.add_argument("--table", action="store_true")
    ap.add_argument("--solid", action="store_true")
    ap.add_argument("--bounces", type=int, default=32)
    ap.add_argument("--elev", type=float, default=0.0, help="camera elevation, degrees")
    ap.add_argument("--gap", type=float, default=0.0, help="the table top this far under the base (m)")
    ap.add_argument("--z", type=float, default=0.0, help="everything moved up by this (m)")
    ap.add_argument("--spp", type=int, default=0, help="ours' samples (0: the add-on's)")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = build(a.flat, a.table, a.solid, a.bounces, elev=a.elev, gap=a.gap, z=a.z)
    if a.mode == "ours" and a.spp:
        a.set.append(f"spp={a.spp}")
    render(scene, a)


if __name__ == "__main__":
    main()
