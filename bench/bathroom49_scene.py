"""A new user's scene (session 49 trial): a small bathroom at both engines' default render
settings, built with bpy as a Blender user builds it (bpy.ops primitives, lathed
profiles, Shade Smooth, node materials: Principled BSDF everywhere, a Brick Texture and a
Bump node on the tiles), rendered with Photon Mapping (scene.render.engine = 'PHOTONMAP',
the add-on's defaults) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/bathroom49_scene.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--filter-glossy F] [--cycles-seed S] [--drop NAME ...]
        [--only area|sun|sky|strip] [--no-bump] [--ceramic-coat W]
        [--bounces N]

The room: 2.5 x 2.0 x 2.4 m (x -1.25..1.25, y -1..1, z 0..2.4), closed but for a window
hole (0.7 x 0.6 m, no pane) in the left (-X) wall, the camera inside (20 mm lens). Glossy
tiles on every wall and the floor (Principled roughness 0.1; Base Color from a Brick
Texture on the cubes' UV map, stacked square tiles, white / pale grey on the walls, grey
on the floor, grey grout; the Brick's Fac through a Bump node at its defaults, Invert on:
the grout sunk 1 mm); ceiling at the Principled node's defaults. On the back wall: a
mirror (a plane, Principled Metallic 1, roughness 0) under a small emissive strip
(Principled Emission Strength 8, warm white) and over a ceramic basin (a lathed bowl shell
on a pedestal, Principled white roughness 0.05, Coat Weight 1) with a chrome tap (Metallic
1, roughness 0.05); a towel (a box, Principled roughness 0.8, Sheen Weight 1) on a chrome
rail. A shower in the right back corner behind a front of two 8 mm glass panels: a
frosted one (Principled Transmission Weight 1, roughness 0.3) and a clear door (the same,
roughness 0); its open side faces the room. Lights: a square Area light (0.5 m, 60 W)
under the ceiling, a Sun (4 W/m^2, 45 degrees up) through the window, the World a Sky
Texture (Blender 5.0's default type, sun disc off, strength 0.3), the strip. AgX.
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed (0);
Cycles' other settings - Light Paths, clamping, Filter Glossy - at their defaults, which
the add-on reads too).
--drop NAME removes objects whose names start with NAME (an A/B sub-scene); --only LIGHT
keeps one light source ('strip': the strip's emission, the others removed, the World
black; otherwise the strip is kept unlit, emission 0); --no-bump unlinks the tiles' Bump;
--ceramic-coat W sets the basin's and pedestal's Coat Weight (default 1); --bounces N sets
Light Paths > Max Bounces Total, Diffuse, Glossy and Transmission to N.

Prints `RESULT mode cpu_s=... wall_s=...` (this process and its children, from
resource.getrusage; the scene build excluded). --masks writes an (H, W) int array of
object ids (row 0 at the top; -1 the world) and a JSON of the names (the first surface
each pixel centre's ray meets: a glass panel counts as itself); compare with
bench/newuser26_compare.py, bench/newuser45_artefacts.py and bench/newuser48_flip.py
(docs/accuracy.md "## bathroom49").
"""
from __future__ import annotations

import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import assign, camera, cube, cylinder, principled, world_colour  # noqa: E402
from newuser44_table import arguments, lathe, render  # noqa: E402
from newuser47_bathroom import sky_world  # noqa: E402


def tiles(name, c1, c2, scale=16.0, bump=True):
    """Glossy tiles: Principled roughness 0.1, Base Color from a Brick Texture on the UV
    map (square stacked tiles: Brick Width = Row Height = 0.25, Offset 0; grey grout),
    its Fac (1 in the grout) through a Bump node at its defaults with Invert on."""
    m = principled(name, (0.8, 0.8, 0.8), 0.1)
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    uv = nt.nodes.new("ShaderNodeTexCoord")
    b = nt.nodes.new("ShaderNodeTexBrick")
    b.offset = 0.0
    nt.links.new(uv.outputs["UV"], b.inputs["Vector"])
    b.inputs["Color1"].default_value = (*c1, 1)
    b.inputs["Color2"].default_value = (*c2, 1)
    b.inputs["Mortar"].default_value = (0.3, 0.3, 0.3, 1)
    b.inputs["Scale"].default_value = scale  # a cube's face is a quarter of its UV map
    b.inputs["Brick Width"].default_value = 0.25
    b.inputs["Row Height"].default_value = 0.25
    nt.links.new(b.outputs["Color"], p.inputs["Base Color"])
    if bump:
        bu = nt.nodes.new("ShaderNodeBump")
        bu.invert = True
        nt.links.new(b.outputs["Fac"], bu.inputs["Height"])
        nt.links.new(bu.outputs["Normal"], p.inputs["Normal"])
    return m


def bathroom_scene(only=None, drop=(), bump=True, coat=1.0):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    wall = tiles("WallTiles", (0.86, 0.87, 0.88), (0.74, 0.76, 0.78), bump=bump)
    floor = tiles("FloorTiles", (0.35, 0.35, 0.36), (0.28, 0.28, 0.3), scale=10.0, bump=bump)
    ceiling = principled("Ceiling", (0.8, 0.8, 0.8), 0.5)
    ceramic = principled("Ceramic", (0.9, 0.9, 0.9), 0.05, Coat_Weight=coat)
    chrome = principled("Chrome", (0.9, 0.9, 0.92), 0.05, metallic=1.0)
    mirror = principled("Mirror", (0.9, 0.9, 0.9), 0.0, metallic=1.0)
    towel = principled("Towel", (0.7, 0.25, 0.2), 0.8, Sheen_Weight=1.0)
    frosted = principled("Frosted", (1, 1, 1), 0.3, Transmission_Weight=1.0)
    clear = principled("ClearGlass", (1, 1, 1), 0.0, Transmission_Weight=1.0)
    strip = principled("Strip", (0.8, 0.8, 0.8), 0.5, Emission_Color=(1.0, 0.9, 0.75, 1.0),
                       Emission_Strength=8.0 if only in (None, "strip") else 0.0)
    # The room (x -1.25..1.25, y -1..1, z 0..2.4), walls 0.1 m thick outside it.
    cube("Floor", (0, 0, -0.05), (2.7, 2.2, 0.1), floor)
    cube("Ceiling", (0, 0, 2.45), (2.7, 2.2, 0.1), ceiling)
    cube("BackWall", (0, 1.05, 1.2), (2.7, 0.1, 2.4), wall)
    cube("RightWall", (1.3, 0, 1.2), (0.1, 2.0, 2.4), wall)
    cube("FrontWall", (0, -1.05, 1.2), (2.7, 0.1, 2.4), wall)  # behind the camera
    # Left wall (-X) round a window hole y in [-0.5, 0.1], z in [1.3, 2.0].
    cube("LeftWall_a", (-1.3, -0.75, 1.2), (0.1, 0.5, 2.4), wall)
    cube("LeftWall_b", (-1.3, 0.55, 1.2), (0.1, 0.9, 2.4), wall)
    cube("LeftWall_c", (-1.3, -0.2, 0.65), (0.1, 0.6, 1.3), wall)
    cube("LeftWall_d", (-1.3, -0.2, 2.2), (0.1, 0.6, 0.4), wall)
    # The mirror: a plane 2 mm before the back wall, facing -Y; the strip above it.
    bpy.ops.mesh.primitive_plane_add(size=1, location=(-0.55, 0.998, 1.5),
                                     rotation=(math.radians(90), 0, 0), scale=(0.6, 0.7, 1))
    mo = bpy.context.active_object
    mo.name = "Mirror"
    assign(mo, mirror)
    cube("Strip", (-0.55, 0.985, 1.92), (0.5, 0.03, 0.025), strip)
    # The basin: a pedestal and a lathed bowl shell (rim 8 mm thick) on it.
    cylinder("Pedestal", 0.07, 0.72, (-0.55, 0.82, 0.36), ceramic, vertices=32)
    bowl = [(0.08, 0.0), (0.17, 0.035), (0.22, 0.1), (0.23, 0.15), (0.222, 0.15),
            (0.212, 0.105), (0.165, 0.045), (0.075, 0.01)]
    lathe("Basin", bowl, ceramic, (-0.55, 0.77, 0.72))
    # The chrome tap behind the basin: a riser and a spout towards the room.
    cylinder("TapRiser", 0.015, 0.16, (-0.55, 0.97, 0.95), chrome, vertices=24)
    bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.012, depth=0.13,
                                        location=(-0.55, 0.91, 1.02),
                                        rotation=(math.radians(90), 0, 0))
    sp = bpy.context.active_object
    sp.name = "TapSpout"
    bpy.ops.object.shade_smooth()
    assign(sp, chrome)
    # The towel rail on the back wall between the basin and the shower, the towel on it.
    bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.012, depth=0.5,
                                        location=(0.0, 0.94, 1.3),
                                        rotation=(0, math.radians(90), 0))
    rail = bpy.context.active_object
    rail.name = "TowelRail"
    bpy.ops.object.shade_smooth()
    assign(rail, chrome)
    cube("Towel", (0.0, 0.94, 0.98), (0.4, 0.05, 0.62), towel)
    # The shower's front at y = 0.15: the frosted panel (x 0.75..1.25) and the clear
    # door (x 0.35..0.75), 1.95 m high on the floor; the shower's left side is open.
    cube("FrostedScreen", (1.0, 0.15, 0.975), (0.5, 0.008, 1.95), frosted)
    cube("ClearDoor", (0.55, 0.15, 0.975), (0.4, 0.008, 1.95), clear)
    # The shower's chrome head on its back wall.
    cylinder("ShowerHead", 0.06, 0.02, (0.85, 0.9, 1.95), chrome, vertices=32)
    # Lights.
    if only in (None, "area"):
        bpy.ops.object.light_add(type="AREA", location=(-0.2, -0.1, 2.38))
        a = bpy.context.active_object
        a.name = "CeilingLight"
        a.data.size = 0.5
        a.data.energy = 60.0
    if only in (None, "sun"):
        bpy.ops.object.light_add(type="SUN", location=(-2.5, 0, 3.5))
        s = bpy.context.active_object
        s.name = "Sun"
        s.data.energy = 4.0
        el, az = math.radians(45), math.radians(25)  # travelling +X, a little +Y, down
        d = Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)))
        s.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    if only in (None, "sky"):
        sky_world(scene, strength=0.3, elevation=45.0, rotation=25.0)
    else:
        world_colour(scene, (0.0, 0.0, 0.0), 0.0)  # black: the lamps alone
    for name in drop:
        for o in [o for o in bpy.data.objects if o.name.startswith(name)]:
            bpy.data.objects.remove(o)
    camera((0.55, -0.92, 1.5), (-0.2, 0.8, 1.0), lens=18.0)
    return scene


def main():
    ap = arguments()
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Caustics > Filter Glossy (Cycles' default 1)")
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--only", choices=("area", "sun", "sky", "strip"))
    ap.add_argument("--no-bump", action="store_true", help="the tiles without their Bump")
    ap.add_argument("--ceramic-coat", type=float, default=1.0,
                    help="the basin's and pedestal's Coat Weight (default 1)")
    ap.add_argument("--bounces", type=int,
                    help="Light Paths > Max Bounces: Total, Diffuse, Glossy and Transmission "
                         "all N (both engines read them; Cycles' defaults 12 / 4 / 4 / 12)")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = bathroom_scene(a.only, a.drop, not a.no_bump, a.ceramic_coat)
    if a.filter_glossy is not None:
        scene.cycles.blur_glossy = a.filter_glossy
    if a.bounces is not None:
        c = scene.cycles
        c.max_bounces = c.diffuse_bounces = c.glossy_bounces = a.bounces
        c.transmission_bounces = a.bounces
    render(scene, a)


if __name__ == "__main__":
    main()
