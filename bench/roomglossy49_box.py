"""roomglossy49 (issue 14): a closed box of one material, ours against Cycles, and a white
furnace of the same material - the minimal case of bathroom49's +5 % (docs/accuracy.md,
"### roomglossy49").

    PYTHONPATH=. .venv/bin/python bench/roomglossy49_box.py MODE OUT.exr
        [--mat principled:ROUGH | diffuse] [--bounces N] [--furnace]
        [--res W H] [--set NAME=VALUE] [--filter-glossy F] [--clamp]
        [--light point|area] [--walls flipped|slabs] [--grey G] [--brick [--bump]]
        [--seeds N]

The box: a 2 m cube (x, y, z in -1..1), its normals flipped inwards, every face the one
material: a Principled BSDF (Base Color 0.8 grey, roughness ROUGH, the node's other
inputs at their defaults: IOR 1.5 (Blender 5.0), multiscatter GGX) or a Diffuse BSDF
(Color 0.8); lit by one Point light (100 W, radius 0.05 m) at (0.3, 0.2, 0.5); the
camera inside at (-0.6, -0.7, -0.3) looking at the far top corner (16 mm lens). World
black. Variants: --light area (bathroom49's 0.5 m, 60 W Area light under the ceiling),
--walls slabs (six 0.1 m cubes outside the room, normals outwards, as bathroom49's walls),
--grey G (the base colour), --brick (bathroom49's white tiles' Brick Texture as Base
Color; --bump with its Bump node). --bounces N sets Light Paths Max Bounces Total,
Diffuse, Glossy, Transmission and Transparent to N (both engines read them; default
Blender's 12 / 4 / 4 / 12 / 8).
Filter Glossy 0 and clamping off in both unless asked for (--filter-glossy F; --clamp
keeps Blender's Clamp Direct 0 / Indirect 10).

--furnace: instead a unit sphere (UV sphere, 64 x 32, Shade Smooth) of the material in a
uniform white World of strength 1, seen from 4 m (50 mm lens): the light leaving the
sphere is the material's directional albedo over the view angles the disc shows (a convex
body: no interreflection), ours against Cycles.

MODE: ours | cycles:SPP (CPU, no denoising, no adaptive sampling, seed 0). Prints
`BOX mode mat box|furnace bounces=N variant...: mean RGB r g b lum L` over the whole image (the furnace: over the
sphere's pixels) and `RESULT mode cpu_s=...`.

--seeds N: render seeds 0 .. N-1 (ours' Seed, Cycles' Seed; a --set seed=... would
override ours'), each to OUT with `_sN` before its extension, and print each seed's
`SEED s lum L`, then BOX over their mean and `SEEDS n mean M sd S se E` of the
luminances. The lamp's glossy highlight makes one seed's mean scatter: at roughness 0.1,
direct light only, ours' 128 spp read 0.9946-1.0031 of Cycles over seeds 0-7, Cycles' own
128 spp as wide (docs/accuracy.md, "### direct51").
"""
from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from newuser26_compare import read_exr  # noqa: E402
from newuser26_scenes import (assign, camera, cube, new_material, object_masks,  # noqa: E402
                              principled, world_colour)
from newuser44_table import arguments, render  # noqa: E402
from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402

LUM = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of linear RGB


def material(spec, grey=0.8, brick=False, bump=False):
    """'principled:ROUGH' (Base Color GREY, or bathroom49's white tiles' Brick Texture with
    brick, its Bump with bump) or 'diffuse' (Diffuse BSDF, Color GREY)."""
    if spec.startswith("principled"):
        if brick:
            from bathroom49_scene import tiles
            m = tiles("Walls", (0.86, 0.87, 0.88), (0.74, 0.76, 0.78), bump=bump)
            m.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = float(
                spec.split(":")[1])
            return m
        return principled("Walls", (grey,) * 3, float(spec.split(":")[1]))
    m = new_material("Walls")
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (grey, grey, grey, 1.0)
    nt.links.new(d.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def box_scene(scene, mat, light="point", walls="flipped"):
    if walls == "flipped":
        o = cube("Box", (0, 0, 0), (2.0, 2.0, 2.0), mat)
        o.data.flip_normals()  # the walls face the inside, where camera and light are
    else:  # six 0.1 m slabs outside the room, overlapping at the edges (bathroom49's)
        for i, (loc, sc) in enumerate((((0, 0, -1.05), (2.2, 2.2, 0.1)),
                                       ((0, 0, 1.05), (2.2, 2.2, 0.1)),
                                       ((0, -1.05, 0), (2.2, 0.1, 2.2)),
                                       ((0, 1.05, 0), (2.2, 0.1, 2.2)),
                                       ((-1.05, 0, 0), (0.1, 2.0, 2.0)),
                                       ((1.05, 0, 0), (0.1, 2.0, 2.0)))):
            cube(f"Wall{i}", loc, sc, mat)
    if light == "point":
        bpy.ops.object.light_add(type="POINT", location=(0.3, 0.2, 0.5))
        lamp = bpy.context.active_object
        lamp.data.energy = 100.0
        lamp.data.shadow_soft_size = 0.05
    else:  # bathroom49's: a 0.5 m square Area light, 60 W, 2 cm under the ceiling
        bpy.ops.object.light_add(type="AREA", location=(0.1, 0.1, 0.98))
        lamp = bpy.context.active_object
        lamp.data.size = 0.5
        lamp.data.energy = 60.0
    world_colour(scene, (0, 0, 0), 0.0)
    camera((-0.6, -0.7, -0.3), (1.0, 1.0, 1.0), lens=16.0)


def furnace_scene(scene, mat):
    primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    o = bpy.context.active_object
    o.name = "Sphere"
    bpy.ops.object.shade_smooth()
    assign(o, mat)
    world_colour(scene, (1, 1, 1), 1.0)
    camera((0.0, -4.0, 0.0), (0.0, 0.0, 0.0), lens=50.0)


def main():
    ap = arguments(__doc__.splitlines()[0])
    ap.set_defaults(res=(48, 36))
    ap.add_argument("--mat", default="principled:0.1")
    ap.add_argument("--bounces", type=int)
    ap.add_argument("--furnace", action="store_true")
    ap.add_argument("--filter-glossy", type=float, default=0.0)
    ap.add_argument("--light", default="point", choices=("point", "area"))
    ap.add_argument("--walls", default="flipped", choices=("flipped", "slabs"))
    ap.add_argument("--grey", type=float, default=0.8, help="the base colour (default 0.8)")
    ap.add_argument("--brick", action="store_true", help="bathroom49's white Brick tiles")
    ap.add_argument("--bump", action="store_true", help="with --brick: the tiles' Bump")
    ap.add_argument("--clamp", action="store_true", help="Blender's default clamps")
    ap.add_argument("--seeds", type=int, default=1, help="average seeds 0 .. N-1")
    a = ap.parse_args()
    a.no_clamp = not a.clamp
    import addon
    addon.register()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    mat = material(a.mat, a.grey, a.brick, a.bump)
    if a.furnace:
        furnace_scene(scene, mat)
    else:
        box_scene(scene, mat, a.light, a.walls)
    c = scene.cycles
    c.blur_glossy = a.filter_glossy
    if a.bounces is not None:
        c.max_bounces = c.diffuse_bounces = c.glossy_bounces = a.bounces
        c.transmission_bounces = c.transparent_max_bounces = a.bounces
    out, sels = a.out, []
    for s in range(a.seeds):
        if a.seeds > 1:
            stem, ext = os.path.splitext(out)
            a.out = f"{stem}_s{s}{ext}"
            a.cycles_seed = scene.photonmap.seed = s
        render(scene, a)
        img = read_exr(os.path.abspath(a.out))
        if a.furnace:
            ids, names = object_masks(scene, *a.res)
            sels.append(img[ids == names.index("Sphere")])
        else:
            sels.append(img.reshape(-1, 3))
        if a.seeds > 1:
            print(f"SEED {s} lum {sels[-1].mean(0) @ LUM:.5f}", flush=True)
    sel = np.mean(sels, axis=0)
    rgb = sel.mean(0)
    tag = " ".join(f"{k}={getattr(a, k)}" for k in ("light", "walls", "grey", "brick", "bump")
                   + ("filter_glossy", "clamp"))
    print(f"BOX {a.mode} {a.mat} {'furnace' if a.furnace else 'box'} bounces={a.bounces} {tag}: "
          f"mean RGB {rgb[0]:.5f} {rgb[1]:.5f} {rgb[2]:.5f} lum {rgb @ LUM:.5f} "
          f"({len(sel)} pixels)", flush=True)
    if a.seeds > 1:
        lums = np.array([x.mean(0) @ LUM for x in sels])
        sd = lums.std(ddof=1)
        print(f"SEEDS {a.seeds} mean {lums.mean():.5f} sd {sd:.5f} se {sd / np.sqrt(a.seeds):.5f}",
              flush=True)


if __name__ == "__main__":
    main()
