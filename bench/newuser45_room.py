"""A new user's scene (session 45 trial): an evening living room, built with bpy as a
Blender user builds it (bpy.ops primitives, Shade Smooth, node materials, an Image
Texture loaded from a PNG), rendered with Photon Mapping (Blender's RenderEngine, the
add-on's default settings) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser45_room.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--vase-anisotropic A] [--vase-flat] [--filter-glossy F]

The room: 5 x 4 x 2.6 m, a window (1.6 x 1.1 m hole, no pane) in the back (+Y) wall
onto a dim blue evening world colour (0.02, 0.03, 0.06); a Spot light (150 W, 50 deg,
Blend 0.3, radius 0.05 m) from the ceiling onto a coffee table; a Point light (60 W,
radius 0.1 m) on a side; a floor lamp whose shade is an open cylinder of Emission
(strength 4, warm: a mesh light); a sofa of blocks (Principled, Sheen Weight 1); a
coffee table of car paint (Principled base red, metallic 0, Coat Weight 1, Coat
Roughness 0.05); a brushed-metal vase on it (lathed, Shade Smooth, Principled Metallic
1, roughness 0.25, Anisotropic 0.6); a wooden plank floor from a 64 x 64 PNG written
beside OUT (numpy, saved by Blender, loaded as an Image Texture); white walls. The view
transform is left at Blender's default (AgX); the EXR is linear either way.
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed 0; Cycles' other
settings - Light Paths, clamping, Filter Glossy - at their defaults, which the add-on
reads too).

Prints `RESULT mode cpu_s=... wall_s=...` (this process and its children, from
resource.getrusage; the scene build excluded). --masks writes an (H, W) int array of
object ids (row 0 at the top; -1 the world) and a JSON of the names; compare with
bench/newuser26_compare.py. --save writes the .blend (for `python -m addon.batch`)
before the render.
"""
from __future__ import annotations

import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import (assign, camera, cube, cylinder, new_material,  # noqa: E402
                              principled, world_colour)
from newuser44_table import arguments, lathe, render  # noqa: E402


def wood_png(path, n=64, seed=0):
    """A plank floor's colour map: 8 planks across, each its own brown, a dark seam and
    grain streaks along the plank; written as an 8-bit sRGB PNG by Blender."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n]
    plank = x // (n // 8)
    tone = rng.uniform(0.75, 1.15, 8)[plank]
    grain = 0.9 + 0.1 * np.sin(y * 0.7 + rng.uniform(0, 6, 8)[plank] + 0.3 * x)
    seam = (x % (n // 8)) == 0
    base = np.array([0.45, 0.26, 0.12])  # display (sRGB) values, as a painted texture
    rgb = base * (tone * grain)[..., None]
    rgb[seam] = (0.12, 0.07, 0.04)
    px = np.ones((n, n, 4), np.float32)
    px[..., :3] = np.clip(rgb, 0, 1)
    img = bpy.data.images.new("wood_gen", n, n, alpha=False)
    img.pixels.foreach_set(px[::-1].ravel())  # Blender's rows bottom to top
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    return path


def textured_floor(name, png):
    m = principled(name, (0.5, 0.3, 0.15), 0.6)
    nt = m.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(png)
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.5, 2.5, 1.0)
    coord = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coord.outputs["UV"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def emission(name, color, strength):
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*color, 1.0)
    e.inputs["Strength"].default_value = strength
    nt.links.new(e.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def room_scene(png, vase_anisotropic=0.6, vase_flat=False):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene  # view transform: Blender's default (AgX)
    wall = principled("Wall", (0.8, 0.78, 0.74), 0.8)
    sofa = principled("SofaFabric", (0.12, 0.25, 0.35), 0.9, Sheen_Weight=1.0,
                      Sheen_Roughness=0.5)
    paint = principled("CarPaint", (0.5, 0.03, 0.03), 0.5, Coat_Weight=1.0,
                       Coat_Roughness=0.05)
    brushed = principled("BrushedMetal", (0.9, 0.88, 0.85), 0.25, metallic=1.0,
                         Anisotropic=vase_anisotropic)
    pole = principled("LampPole", (0.05, 0.05, 0.05), 0.4, metallic=1.0)
    shade = emission("LampShade", (1.0, 0.75, 0.45), 4.0)
    # Room, open towards the camera (-Y side missing).
    cube("Floor", (0, 0, -0.05), (5, 4, 0.1), textured_floor("WoodFloor", png))
    cube("Ceiling", (0, 0, 2.65), (5, 4, 0.1), wall)
    cube("LeftWall", (-2.55, 0, 1.3), (0.1, 4.2, 2.6), wall)
    cube("RightWall", (2.55, 0, 1.3), (0.1, 4.2, 2.6), wall)
    # Back wall (+Y) round a window hole x in [-0.3, 1.3], z in [0.9, 2.0].
    cube("BackWall_a", (-1.45, 2.05, 1.3), (2.3, 0.1, 2.6), wall)
    cube("BackWall_b", (1.9, 2.05, 1.3), (1.2, 0.1, 2.6), wall)
    cube("BackWall_c", (0.5, 2.05, 0.45), (1.6, 0.1, 0.9), wall)
    cube("BackWall_d", (0.5, 2.05, 2.3), (1.6, 0.1, 0.6), wall)
    # Sofa against the back wall: seat, back, two arms.
    cube("SofaSeat", (-1.2, 1.4, 0.22), (2.0, 0.8, 0.44), sofa)
    cube("SofaBack", (-1.2, 1.85, 0.55), (2.0, 0.2, 0.9), sofa)
    cube("SofaArmL", (-2.3, 1.4, 0.35), (0.2, 0.8, 0.7), sofa)
    cube("SofaArmR", (-0.1, 1.4, 0.35), (0.2, 0.8, 0.7), sofa)
    # Coffee table in car paint.
    cube("TableTop", (-0.9, 0.3, 0.42), (1.1, 0.6, 0.06), paint)
    for i, (x, y) in enumerate([(-1.4, 0.05), (-0.4, 0.05), (-1.4, 0.55), (-0.4, 0.55)]):
        cube(f"TableLeg{i}", (x, y, 0.195), (0.05, 0.05, 0.39), paint)
    # Brushed-metal vase on the table (radius, height) profile.
    prof = [(0.05, 0.0), (0.08, 0.05), (0.09, 0.12), (0.06, 0.22), (0.04, 0.28),
            (0.05, 0.32)]
    vase = lathe("Vase", prof, brushed, (-0.7, 0.3, 0.45))
    if vase_flat:  # Shade Flat: the geometric normals
        for p in vase.data.polygons:
            p.use_smooth = False
    # Floor lamp at the right: a pole and an open emissive cylinder as the shade.
    cylinder("LampPole", 0.015, 1.4, (1.8, 1.3, 0.7), pole, vertices=16)
    bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.2, depth=0.3,
                                        end_fill_type="NOTHING", location=(1.8, 1.3, 1.5))
    s = bpy.context.active_object
    s.name = "LampShadeMesh"
    bpy.ops.object.shade_smooth()
    assign(s, shade)
    # Lamps: a spot from the ceiling onto the table, a point lamp on the left.
    bpy.ops.object.light_add(type="SPOT", location=(-0.9, 0.0, 2.5))
    spot = bpy.context.active_object
    spot.name = "Spot"
    spot.data.energy = 150.0
    spot.data.spot_size = math.radians(50)
    spot.data.spot_blend = 0.3
    spot.data.shadow_soft_size = 0.05
    spot.rotation_euler = Vector((0.0, 0.3, -2.08)).to_track_quat("-Z", "Y").to_euler()
    bpy.ops.object.light_add(type="POINT", location=(-2.1, -0.5, 1.6))
    pt = bpy.context.active_object
    pt.name = "Point"
    pt.data.energy = 60.0
    pt.data.shadow_soft_size = 0.1
    pt.data.color = (1.0, 0.85, 0.7)
    # Dim evening world, seen through the window.
    world_colour(scene, (0.02, 0.03, 0.06), 1.0)
    camera((0.6, -2.6, 1.35), (-0.5, 1.0, 0.6), lens=24.0)
    return scene


def main():
    ap = arguments()
    ap.add_argument("--vase-anisotropic", type=float, default=0.6,
                    help="the vase's Principled Anisotropic (0: isotropic)")
    ap.add_argument("--vase-flat", action="store_true", help="the vase Shade Flat")
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Caustics > Filter Glossy (Cycles' default 1; read "
                         "by both engines, ours does not blur: docs/accuracy.md vase45)")
    a = ap.parse_args()
    import addon
    addon.register()
    png = os.path.join(os.path.dirname(os.path.abspath(a.out)), "newuser45_wood.png")
    scene = room_scene(wood_png(png), a.vase_anisotropic, a.vase_flat)
    if a.filter_glossy is not None:
        scene.cycles.blur_glossy = a.filter_glossy
    render(scene, a)


if __name__ == "__main__":
    main()
