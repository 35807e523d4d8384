"""A new user's scene (session 47 trial): a small bathroom at Blender's default render
settings, built with bpy as a Blender user builds it (bpy.ops primitives, lathed
profiles, Shade Smooth, node materials with procedural textures), rendered with Photon
Mapping (scene.render.engine = 'PHOTONMAP', the add-on's defaults) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser47_bathroom.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--filter-glossy F] [--cycles-seed S] [--only LIGHT] [--glossy-split]

The room: 2.6 x 2.4 x 2.5 m (x -1.3..1.3, y -1.2..1.2), closed (the camera inside); a window hole (0.7 x 0.8 m, no pane) high in the left (-X) wall with a Sun (3 W/m^2,
50 degrees up, Blender's default angle) shining in through it, the World a Sky Texture
(Blender 5.0's default Multiple Scattering sky, sun disc off as users turn it off beside
a Sun lamp, strength 0.3); a disk Area light (0.35 m, 40 W) under the ceiling. Glossy
wall tiles on the back and side walls (Principled roughness 0.15, Base Color from a
Brick Texture on the cubes' UV map: two tile colours and grey grout); a
floor of a Checker Texture (roughness 0.4); a wall mirror (a plane, Principled Metallic
1, roughness 0) over a white ceramic basin (a lathed shell on a pedestal, Principled,
Coat Weight 1); a chrome tap (two cylinders, Metallic 1, roughness 0.05); a frosted
shower screen (an 8 mm slab, Glass BSDF roughness 0.3, the node's IOR); a towel on a
chrome rail (a box, Principled roughness 0.8, Sheen Weight 1). Ceiling at the Principled
node's defaults; view transform AgX (the EXR is linear either way).
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed (0);
Cycles' other settings - Light Paths, clamping, Filter Glossy - at their defaults, which
the add-on reads too).
--only LIGHT keeps one light source: 'area', 'sun' or 'sky' (the others removed; without
the sky the World is black). --glossy-split sets engine/glossysplit.py ENABLED = True
(off on main, s47) before the render.

Prints `RESULT mode cpu_s=... wall_s=...` (this process and its children, from
resource.getrusage; the scene build excluded). --masks writes an (H, W) int array of
object ids (row 0 at the top; -1 the world) and a JSON of the names; compare with
bench/newuser26_compare.py and bench/newuser45_artefacts.py (relMSE, HDR-FLIP).
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
from newuser26_scenes import (assign, camera, cube, cylinder, new_material,  # noqa: E402
                              principled, world_colour)
from newuser44_table import arguments, lathe, render  # noqa: E402


def tiles(name):
    """Glossy tiles: Principled roughness 0.15, Base Color from a Brick Texture on the UV
    map (Texture Coordinate UV), white and pale blue tiles, grey grout."""
    m = principled(name, (0.8, 0.8, 0.8), 0.15)
    nt = m.node_tree
    uv = nt.nodes.new("ShaderNodeTexCoord")
    b = nt.nodes.new("ShaderNodeTexBrick")
    nt.links.new(uv.outputs["UV"], b.inputs["Vector"])
    b.inputs["Color1"].default_value = (0.85, 0.88, 0.9, 1)
    b.inputs["Color2"].default_value = (0.6, 0.72, 0.82, 1)
    b.inputs["Mortar"].default_value = (0.35, 0.35, 0.35, 1)
    b.inputs["Scale"].default_value = 40.0  # a cube's face is a quarter of its UV map
    b.inputs["Mortar Size"].default_value = 0.015
    nt.links.new(b.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def checker_floor(name):
    """Principled roughness 0.4, Base Color from a Checker Texture (Generated coords)."""
    m = principled(name, (0.8, 0.8, 0.8), 0.4)
    nt = m.node_tree
    c = nt.nodes.new("ShaderNodeTexChecker")
    c.inputs["Color1"].default_value = (0.75, 0.75, 0.72, 1)
    c.inputs["Color2"].default_value = (0.08, 0.08, 0.09, 1)
    c.inputs["Scale"].default_value = 8.0
    nt.links.new(c.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def frosted_glass(name, roughness=0.3):
    """A Glass BSDF at the node's defaults but its Roughness."""
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Roughness"].default_value = roughness
    nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def sky_world(scene, strength=0.3, elevation=50.0, rotation=20.0):
    """A World whose Background takes a Sky Texture (Blender's default type) with the sun
    disc off."""
    w = world_colour(scene, (1.0, 1.0, 1.0), strength)
    nt = w.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sun_disc = False
    sky.sun_elevation = math.radians(elevation)
    sky.sun_rotation = math.radians(rotation)
    nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    return w


def bathroom_scene(only=None):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    wall_tiles = tiles("WallTiles")
    ceiling = principled("Ceiling", (0.8, 0.8, 0.8), 0.5)  # the node's defaults
    ceramic = principled("Ceramic", (0.9, 0.9, 0.9), 0.5, Coat_Weight=1.0)
    chrome = principled("Chrome", (0.9, 0.9, 0.92), 0.05, metallic=1.0)
    mirror = principled("Mirror", (0.9, 0.9, 0.9), 0.0, metallic=1.0)
    towel = principled("Towel", (0.15, 0.35, 0.6), 0.8, Sheen_Weight=1.0)
    # Room (x -1.3..1.3, y -1.2..1.2, z 0..2.5), the camera inside.
    cube("Floor", (0, 0, -0.05), (2.8, 2.6, 0.1), checker_floor("FloorTiles"))
    cube("Ceiling", (0, 0, 2.55), (2.8, 2.6, 0.1), ceiling)
    cube("BackWall", (0, 1.25, 1.25), (2.8, 0.1, 2.5), wall_tiles)
    cube("RightWall", (1.35, 0, 1.25), (0.1, 2.4, 2.5), wall_tiles)
    cube("FrontWall", (0, -1.25, 1.25), (2.8, 0.1, 2.5), wall_tiles)  # behind the camera
    # Left wall (-X) round a window hole y in [-0.1, 0.6], z in [1.3, 2.1].
    cube("LeftWall_a", (-1.35, -0.65, 1.25), (0.1, 1.1, 2.5), wall_tiles)
    cube("LeftWall_b", (-1.35, 0.9, 1.25), (0.1, 0.6, 2.5), wall_tiles)
    cube("LeftWall_c", (-1.35, 0.25, 0.65), (0.1, 0.7, 1.3), wall_tiles)
    cube("LeftWall_d", (-1.35, 0.25, 2.3), (0.1, 0.7, 0.4), wall_tiles)
    # Wall mirror: a plane 2 mm before the back wall's tiles, facing -Y.
    bpy.ops.mesh.primitive_plane_add(size=1, location=(-0.3, 1.198, 1.55),
                                     rotation=(math.radians(90), 0, 0), scale=(0.7, 0.8, 1))
    mo = bpy.context.active_object
    mo.name = "Mirror"
    assign(mo, mirror)
    # Basin: a pedestal column and a lathed bowl shell (rim 6 mm thick) on it.
    cylinder("Pedestal", 0.08, 0.72, (-0.3, 1.0, 0.36), ceramic, vertices=32)
    bowl = [(0.1, 0.0), (0.2, 0.04), (0.25, 0.11), (0.26, 0.16), (0.252, 0.16),
            (0.24, 0.115), (0.19, 0.05), (0.09, 0.012)]
    lathe("Basin", bowl, ceramic, (-0.3, 0.95, 0.72))
    # Chrome tap behind the basin: a riser and a spout towards the room.
    cylinder("TapRiser", 0.015, 0.18, (-0.3, 1.17, 0.97), chrome, vertices=24)
    bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.012, depth=0.14,
                                        location=(-0.3, 1.11, 1.05),
                                        rotation=(math.radians(90), 0, 0))
    sp = bpy.context.active_object
    sp.name = "TapSpout"
    bpy.ops.object.shade_smooth()
    assign(sp, chrome)
    # Frosted shower screen: an 8 mm slab standing on the floor, x = 0.55, from the back
    # wall 0.85 m into the room.
    cube("ShowerScreen", (0.55, 0.775, 0.97), (0.008, 0.85, 1.9), frosted_glass("Frosted"))
    # Towel rail on the back wall, left of the basin, and a towel hanging over it.
    bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.012, depth=0.55,
                                        location=(-0.95, 1.14, 1.25),
                                        rotation=(0, math.radians(90), 0))
    rail = bpy.context.active_object
    rail.name = "TowelRail"
    bpy.ops.object.shade_smooth()
    assign(rail, chrome)
    cube("Towel", (-0.95, 1.14, 0.92), (0.45, 0.05, 0.66), towel)
    # Lights.
    if only in (None, "area"):
        bpy.ops.object.light_add(type="AREA", location=(0.0, 0.2, 2.48))
        a = bpy.context.active_object
        a.name = "CeilingDisk"
        a.data.shape = "DISK"
        a.data.size = 0.35
        a.data.energy = 40.0
    if only in (None, "sun"):
        bpy.ops.object.light_add(type="SUN", location=(-2.5, 0, 3.5))
        s = bpy.context.active_object
        s.name = "Sun"
        s.data.energy = 3.0
        el, az = math.radians(50), math.radians(20)  # travelling +X, a little +Y, down
        d = Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)))
        s.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    if only in (None, "sky"):
        sky_world(scene)
    else:
        world_colour(scene, (0.0, 0.0, 0.0), 0.0)  # black: the lamps alone
    camera((0.25, -1.1, 1.5), (-0.15, 1.2, 1.0), lens=22.0)
    return scene


def main():
    ap = arguments()
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Caustics > Filter Glossy (Cycles' default 1)")
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--only", choices=("area", "sun", "sky"))
    ap.add_argument("--glossy-split", action="store_true",
                    help="engine/glossysplit.py ENABLED = True before the render")
    a = ap.parse_args()
    import addon
    addon.register()
    if a.glossy_split:
        from engine import glossysplit
        glossysplit.ENABLED = True
    scene = bathroom_scene(a.only)
    if a.filter_glossy is not None:
        scene.cycles.blur_glossy = a.filter_glossy
    render(scene, a)


if __name__ == "__main__":
    main()
