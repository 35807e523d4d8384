"""A new user's scene (session 53 trial): three candles on a wooden table at night - wax
that glows by subsurface scattering, flames that are emissive meshes, a brass candle
holder and a glass tumbler throwing a caustic - built with bpy as a Blender user builds
it (Principled BSDF, an Emission shader, Blender's defaults where a user leaves them), at
both engines' default render settings, rendered with Photon Mapping (the add-on's
defaults) and Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser53_candles.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--cycles-seed S] [--drop NAME ...] [--only flames|moon] [--strength S]
        [--plain-wood] [--border X0 X1 Y0 Y1]

The set (metres; the table's top at z = 0): the table (a cube 0.9 x 0.6 x 0.04; Principled
roughness 0.4, its Base Color a Wave Texture (Bands, Scale 3, Distortion 6, Detail 2, the
rest the node's defaults, Generated coordinates) through a Color Ramp from dark to light
brown: wood grain); a back wall (a plane 1.6 x 1.0 m, 0.3 m behind; Principled (0.6,
0.55, 0.5), roughness 0.5). Three candles (cylinders of 48 sides, Shade Smooth; Principled
Base Color (0.9, 0.75, 0.5), Subsurface Weight 1, the node's Subsurface Radius (1, 0.2,
0.1) and Scale 0.05 m): "CandleTall" (radius 22 mm, 140 mm) in a brass holder (a lathed
dish and stem, Shade Smooth; Principled Metallic 1, (0.9, 0.7, 0.35), roughness 0.25),
"CandleMid" (radius 28 mm, 90 mm) and "CandleShort" (radius 25 mm, 60 mm) on the table;
each with a wick (a black cylinder of radius 1 mm) and a flame: a UV sphere of radius
6 mm scaled 2.2 x in z (its faces in a fixed order, tools/canonical_mesh.py), Shade
Smooth, an Emission shader (Color (1.0, 0.45, 0.1), Strength 40; --strength) in place of
the Principled. A glass tumbler (a lathed closed shell, wall 3 mm, bottom 6 mm, radius 35
mm, 80 mm tall, Shade Smooth by Angle 30 degrees; Principled Transmission Weight 1,
roughness 0, the node's IOR) in front of the candles, so CandleMid's flame throws its
caustic onto the table towards the camera. Light besides the flames: the World a dark
blue Background ((0.05, 0.08, 0.2), Strength 0.1: moonlight) and one weak Area light in
a "window" to the left (0.4 m square, 3 W, colour (0.6, 0.7, 1.0)). Camera 50 mm; AgX.
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed; Cycles'
Light Paths at their defaults, read by the add-on).

--drop NAME removes objects whose names start with NAME; --plain-wood gives the table a
constant Base Color (0.28, 0.14, 0.06) in place of the Wave Texture; --only flames keeps
the flames (the World black, the area light removed), --only moon the World and the area
light;
--border renders only that Render Region (fractions, y from the bottom; the EXR keeps the
full frame, black outside). Prints `RESULT mode cpu_s=... wall_s=...`
(bench/newuser44_table.py render) and, for ours, the add-on's warnings, export and stats.
--masks writes an (H, W) int array of object ids (row 0 at the top; -1 the world) and a
JSON of names, the table's top split into "Table:Caustic" (its ray to CandleMid's flame
centre passes through the Glass: the tumbler's caustic and shadow), "Table:NearCandles"
(within 0.12 m of a candle's axis) and "Table" (the rest); compare with
bench/newuser26_compare.py, bench/newuser45_artefacts.py and bench/newuser48_flip.py.
"""
from __future__ import annotations

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
                              principled, top_masks, world_colour)
from newuser44_table import arguments, finish, region_arguments  # noqa: E402
from studio48_stilllife import revolve  # noqa: E402
from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402

HOLDER_TOP = 0.03  # the brass holder's dish (m), where CandleTall stands
# name: (x, y, radius, height, base z)
CANDLES = {"CandleTall": (-0.09, 0.06, 0.022, 0.14, HOLDER_TOP),
           "CandleMid": (0.03, 0.09, 0.028, 0.09, 0.0),
           "CandleShort": (0.14, 0.02, 0.025, 0.06, 0.0)}
GLASS_AT = (0.06, -0.07)
FLAME_R, FLAME_STRETCH = 0.006, 2.2


def flame_centre(name):
    x, y, _, h, z0 = CANDLES[name]
    return Vector((x, y, z0 + h + 0.004 + FLAME_R * FLAME_STRETCH))


def wood_material(name):
    """Principled whose Base Color is a Wave Texture (bands) through a Color Ramp."""
    m = principled(name, (0.3, 0.15, 0.06), 0.4)
    nt = m.node_tree
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = 3.0
    wave.inputs["Distortion"].default_value = 6.0
    wave.inputs["Detail"].default_value = 2.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    e = ramp.color_ramp.elements
    e[0].color = (0.12, 0.05, 0.02, 1.0)
    e[1].color = (0.45, 0.25, 0.11, 1.0)
    nt.links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def emission_material(name, color, strength):
    """An Emission shader in the Principled's place (Material Output > Surface)."""
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*color, 1.0)
    em.inputs["Strength"].default_value = strength
    nt.links.new(em.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def candles_scene(strength=40.0, drop=(), only=None, plain_wood=False):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    wood = (principled("Wood", (0.28, 0.14, 0.06), 0.4) if plain_wood
            else wood_material("Wood"))
    cube("Table", (0, 0.05, -0.02), (0.9, 0.6, 0.04), wood)
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 0.35, 0.3),
                                     rotation=(1.5707963, 0, 0), scale=(1.6, 1.0, 1))
    wall = bpy.context.active_object
    wall.name = "Wall"
    assign(wall, principled("WallPaint", (0.6, 0.55, 0.5), 0.5))
    wax = principled("Wax", (0.9, 0.75, 0.5), 0.5, Subsurface_Weight=1.0)
    wick = principled("Wick", (0.02, 0.02, 0.02), 0.8)
    flame = emission_material("Flame", (1.0, 0.45, 0.1), strength)
    brass = principled("Brass", (0.9, 0.7, 0.35), 0.25, metallic=1.0)
    x, y = CANDLES["CandleTall"][:2]
    revolve("Holder", [(0, 0), (0.05, 0), (0.05, 0.006), (0.012, 0.01), (0.012, 0.024),
                       (0.03, 0.026), (0.03, HOLDER_TOP), (0, HOLDER_TOP)],
            brass, (x, y, 0.0))
    for name, (x, y, r, h, z0) in CANDLES.items():
        cylinder(name, r, h, (x, y, z0 + h / 2), wax)
        cylinder(name + "Wick", 0.001, 0.008, (x, y, z0 + h + 0.004), wick, vertices=8)
        o = primitive_uv_sphere_add(segments=24, ring_count=12, radius=FLAME_R,
                                    location=flame_centre(name))
        o.name = name + "Flame"
        o.scale.z = FLAME_STRETCH
        bpy.ops.object.shade_smooth()
        assign(o, flame)
    glass = principled("Glass", (1, 1, 1), 0.0, Transmission_Weight=1.0)
    R, H, t, b = 0.035, 0.08, 0.003, 0.006
    g = revolve("Glass", [(0, 0), (R, 0), (R, H), (R - t, H), (R - t, b), (0, b)], glass,
                (*GLASS_AT, 0.0))
    # Shade Auto Smooth (30 degrees), as a user fixes a smooth glass's dark rim and base.
    bpy.context.view_layer.objects.active = g
    for o in bpy.context.selected_objects:
        o.select_set(False)
    g.select_set(True)
    bpy.ops.object.shade_smooth_by_angle(angle=0.5235988)
    world_colour(scene, (0.05, 0.08, 0.2), 0.1)
    bpy.ops.object.light_add(type="AREA", location=(-0.7, -0.1, 0.5))
    area = bpy.context.active_object
    area.name = "WindowLight"
    area.data.energy = 3.0
    area.data.size = 0.4
    area.data.color = (0.6, 0.7, 1.0)
    area.rotation_euler = (Vector((0, 0.05, 0.05)) - area.location).to_track_quat(
        "-Z", "Y").to_euler()
    if only == "flames":
        scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
        bpy.data.objects.remove(area)
    elif only == "moon":
        for o in [o for o in bpy.data.objects if o.name.endswith("Flame")]:
            bpy.data.objects.remove(o)
    for name in drop:
        for o in [o for o in bpy.data.objects if o.name.startswith(name)]:
            bpy.data.objects.remove(o)
    camera((0.0, -0.55, 0.26), (0.02, 0.03, 0.07), lens=50.0)
    return scene


def table_masks(scene, w, h, path):
    """object_masks with the table's top split: Table:Caustic (the mid flame seen through
    the glass) / Table:NearCandles (within 12 cm of a candle's axis)."""
    light = flame_centre("CandleMid")

    def classify(x, n, dg):
        x1 = x + n * 1e-5
        d = light - x1
        hit2, _, _, _, ob2, _ = scene.ray_cast(dg, x1, d.normalized(), distance=d.length)
        if hit2 and ob2.name == "Glass":
            return "Table:Caustic"
        if min((x.xy - Vector(c[:2])).length for c in CANDLES.values()) < 0.12:
            return "Table:NearCandles"
        return None

    top_masks(scene, w, h, path, "Table", classify)


def main():
    ap = arguments(__doc__)
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--only", choices=("flames", "moon"))
    ap.add_argument("--strength", type=float, default=40.0, help="the flames' Strength")
    ap.add_argument("--plain-wood", action="store_true",
                    help="the table's Base Color a constant brown, no Wave Texture")
    region_arguments(ap, bounces=False)
    a = ap.parse_args()
    import addon
    addon.register()
    scene = candles_scene(a.strength, a.drop, a.only, a.plain_wood)
    finish(scene, a, table_masks)


if __name__ == "__main__":
    main()
