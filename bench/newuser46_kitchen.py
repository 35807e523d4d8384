"""A new user's scene (session 46 trial): a kitchen corner at Blender's default render
settings, built with bpy as a Blender user builds it (bpy.ops primitives, lathed
profiles, Shade Smooth, node materials, a generated HDRI), rendered with Photon Mapping
(scene.render.engine = 'PHOTONMAP', the add-on's defaults) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser46_kitchen.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--filter-glossy F] [--cycles-seed S] [--only LIGHT] [--window portal|emit]
        [--passes] [--bottle-color R G B] [--bottle-flat] [--border X0 X1 Y0 Y1]

The room: 4 x 4 x 2.7 m, open towards the camera (-Y); a window hole (1.0 x 1.5 m, no
pane) in the back (+Y) wall, an Area light of 1 x 1.5 m (150 W) in its frame shining
into the room (as users fake the daylight of a window; --window portal makes it a
Cycles Light Portal instead, emitting nothing); the World an equirectangular HDRI
(128 x 64, written beside OUT as a Radiance .hdr by Blender from numpy: a blue sky
brightening to the horizon, a brown ground, a soft sun 35 degrees up behind the window);
a Point lamp (60 W, Blender's default radius) over the worktop. A counter along the back
wall: a cabinet (Principled, green-grey) under a white Principled worktop (roughness
0.2); on it a metal kettle (a lathed body, a cylinder spout, a torus handle; Principled
Metallic 1, roughness 0.3), a glass bottle (a closed lathe with a 4 mm wall, Glass BSDF,
IOR 1.5), a ceramic bowl (a lathed shell, Principled roughness 0.5 with Coat Weight 1,
Coat Roughness 0.03); a wooden floor (a Wave Texture with Noise distortion through a
Color Ramp into Base Color). White Principled walls and ceiling at the node's defaults.
View transform AgX (the EXR is linear either way).
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed (0);
Cycles' other settings - Light Paths, clamping, Filter Glossy - at their defaults, which
the add-on reads too).
--only LIGHT keeps one light source: 'window' (the Area light), 'point', or 'world' (the
HDRI; the lamps removed; with the others the World is black).

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

import numpy as np  # noqa: E402
import bpy  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import (assign, camera, cube, glass, principled,  # noqa: E402
                              world_colour)
from newuser44_table import arguments, lathe, render  # noqa: E402

WORKTOP_Z = 0.92  # the worktop's upper face


def sky_hdr(path, w=128, h=64):
    """A small equirectangular HDRI written as Radiance .hdr by Blender: linear RGB, a sky
    from (0.25, 0.45, 0.9) at the zenith to (0.9, 0.95, 1.0) x 1.3 at the horizon, a ground
    of (0.25, 0.2, 0.15) x 0.6, and a sun of peak 300 (Gaussian, sigma 2.5 degrees) at
    elevation 35 degrees towards +Y (behind the window), azimuth 15 degrees towards +X.
    Blender's equirectangular mapping: u = atan2(d.y, -d.x) / 2 pi + 0.5,
    v = atan2(d.z, hypot(d.x, d.y)) / pi + 0.5; pixel row 0 at the bottom (v = 0)."""
    v, u = np.mgrid[0:h, 0:w]
    u = (u + 0.5) / w
    v = (v + 0.5) / h
    phi = (u - 0.5) * 2 * np.pi
    theta = (v - 0.5) * np.pi  # elevation
    d = np.stack([-np.cos(phi) * np.cos(theta), np.sin(phi) * np.cos(theta),
                  np.sin(theta)], -1)
    t = np.clip(np.sin(theta), 0, 1)[..., None]
    horizon = np.array([0.9, 0.95, 1.0]) * 1.3
    zenith = np.array([0.25, 0.45, 0.9])
    rgb = np.where(theta[..., None] >= 0, horizon * (1 - t) ** 2 + zenith * (1 - (1 - t) ** 2),
                   np.array([0.25, 0.2, 0.15]) * 0.6)
    el, az = math.radians(35), math.radians(15)
    sun = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    ang = np.arccos(np.clip(d @ sun, -1, 1))
    rgb = rgb + 300.0 * np.exp(-0.5 * (ang / math.radians(2.5)) ** 2)[..., None] * \
        np.array([1.0, 0.92, 0.8])
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = rgb
    img = bpy.data.images.new("sky_gen", w, h, alpha=False, float_buffer=True)
    img.pixels.foreach_set(px.ravel())  # row 0 = v near 0 = the bottom, as Blender's
    img.filepath_raw = path
    img.file_format = "HDR"
    img.save()
    bpy.data.images.remove(img)
    return path


def hdri_world(scene, path, strength=1.0):
    """A new World whose Background takes its Color from an Environment Texture of the
    image at path (equirectangular, the node's defaults)."""
    world = world_colour(scene, (1.0, 1.0, 1.0), strength)
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(path)
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    return world


def wood_floor(name):
    """Principled, roughness 0.4; Base Color from a Wave Texture (bands along x, Noise
    distortion inside the node) through a two-stop Color Ramp of browns."""
    m = principled(name, (0.4, 0.25, 0.12), 0.4)
    nt = m.node_tree
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = 2.0
    wave.inputs["Distortion"].default_value = 6.0
    wave.inputs["Detail"].default_value = 3.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.12, 0.06, 0.025, 1)
    ramp.color_ramp.elements[1].color = (0.45, 0.26, 0.12, 1)
    nt.links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def kitchen_scene(hdr, only=None, window="emit", bottle_color=(0.85, 0.95, 0.9),
                  bottle_flat=False):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    wall = principled("Wall", (0.8, 0.8, 0.8), 0.5)  # the Principled node's defaults
    cabinet = principled("Cabinet", (0.25, 0.35, 0.3), 0.5)
    worktop = principled("Worktop", (0.9, 0.9, 0.88), 0.2)
    steel = principled("KettleMetal", (0.8, 0.8, 0.82), 0.3, metallic=1.0)
    ceramic = principled("Ceramic", (0.75, 0.8, 0.9), 0.5, Coat_Weight=1.0,
                         Coat_Roughness=0.03)
    bottle_glass = glass("BottleGlass", 1.5, tuple(bottle_color))
    # Room (x -2..2, y -2..2, z 0..2.7), open towards the camera.
    cube("Floor", (0, 0, -0.05), (4, 4, 0.1), wood_floor("WoodFloor"))
    cube("Ceiling", (0, 0, 2.75), (4, 4, 0.1), wall)
    cube("LeftWall", (-2.05, 0, 1.35), (0.1, 4.2, 2.7), wall)
    cube("RightWall", (2.05, 0, 1.35), (0.1, 4.2, 2.7), wall)
    # Back wall (+Y) round a window hole x in [-0.2, 0.8], z in [1.0, 2.5].
    cube("BackWall_a", (-1.1, 2.05, 1.35), (1.8, 0.1, 2.7), wall)
    cube("BackWall_b", (1.4, 2.05, 1.35), (1.2, 0.1, 2.7), wall)
    cube("BackWall_c", (0.3, 2.05, 0.5), (1.0, 0.1, 1.0), wall)
    cube("BackWall_d", (0.3, 2.05, 2.6), (1.0, 0.1, 0.2), wall)
    # Counter along the back wall: cabinet and a 4 cm white worktop.
    cube("Cabinet", (-0.6, 1.7, 0.45), (2.8, 0.58, 0.9), cabinet)
    cube("Worktop", (-0.6, 1.69, WORKTOP_Z - 0.02), (2.8, 0.62, 0.04), worktop)
    z = WORKTOP_Z
    # Kettle: a lathed body (radius, height) with a lid knob, a spout and a handle.
    body = [(0.09, 0.0), (0.12, 0.03), (0.13, 0.09), (0.115, 0.16), (0.07, 0.21),
            (0.05, 0.225), (0.02, 0.24), (0.015, 0.26)]
    lathe("Kettle", body, steel, (-1.2, 1.65, z))
    bpy.ops.mesh.primitive_cylinder_add(vertices=16, radius=0.018, depth=0.16,
                                        location=(-1.2 + 0.16, 1.65, z + 0.14),
                                        rotation=(0, math.radians(50), 0))
    s = bpy.context.active_object
    s.name = "KettleSpout"
    bpy.ops.object.shade_smooth()
    assign(s, steel)
    bpy.ops.mesh.primitive_torus_add(major_radius=0.08, minor_radius=0.012,
                                     location=(-1.2 - 0.11, 1.65, z + 0.17),
                                     rotation=(math.radians(90), 0, 0))
    hnd = bpy.context.active_object
    hnd.name = "KettleHandle"
    bpy.ops.object.shade_smooth()
    assign(hnd, steel)
    # Glass bottle: a closed shell, the outside up to the lip and the inside back down
    # (a 4 mm wall; the neck open).
    outer = [(0.055, 0.0), (0.058, 0.01), (0.058, 0.2), (0.045, 0.25), (0.02, 0.29),
             (0.016, 0.33), (0.016, 0.36)]
    inner = [(0.012, 0.36), (0.012, 0.33), (0.016, 0.29), (0.041, 0.25), (0.054, 0.2),
             (0.054, 0.014), (0.05, 0.006)]
    bottle = lathe("Bottle", outer + inner, bottle_glass, (0.15, 1.62, z))
    if bottle_flat:  # Shade Flat: the geometric normals
        for p in bottle.data.polygons:
            p.use_smooth = False
    # Ceramic bowl: a lathed shell, 6 mm thick, foot ring at the bottom.
    bowl = [(0.04, 0.0), (0.09, 0.025), (0.13, 0.07), (0.14, 0.095), (0.134, 0.095),
            (0.124, 0.07), (0.085, 0.03), (0.036, 0.008)]
    lathe("Bowl", bowl, ceramic, (-0.55, 1.55, z))
    # Lights.
    if only in (None, "window"):
        bpy.ops.object.light_add(type="AREA", location=(0.3, 2.05, 1.75),
                                 rotation=(-math.pi / 2, 0, 0))  # -Z into the room (-Y)
        win = bpy.context.active_object
        win.name = "WindowLight"
        win.data.shape = "RECTANGLE"
        win.data.size, win.data.size_y = 1.0, 1.5
        win.data.energy = 150.0
        if window == "portal":
            win.data.cycles.is_portal = True
    if only in (None, "point"):
        bpy.ops.object.light_add(type="POINT", location=(-0.8, 1.3, 2.1))
        pt = bpy.context.active_object
        pt.name = "PointLamp"
        pt.data.energy = 60.0
    if only in (None, "world"):
        hdri_world(scene, hdr, 1.0)
    else:
        world_colour(scene, (0.0, 0.0, 0.0), 0.0)  # black: the lamps alone
    camera((0.7, 0.2, 1.5), (-0.5, 1.65, 0.95), lens=28.0)
    return scene


def main():
    ap = arguments()
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Caustics > Filter Glossy (Cycles' default 1; read "
                         "by both engines, ours does not blur: docs/compatibility.md "
                         "filterglossy45)")
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--only", choices=("window", "point", "world"))
    ap.add_argument("--window", choices=("emit", "portal"), default="emit")
    ap.add_argument("--bottle-color", type=float, nargs=3, default=(0.85, 0.95, 0.9),
                    help="the Glass BSDF's Color (default 0.85 0.95 0.9)")
    ap.add_argument("--bottle-flat", action="store_true", help="the bottle Shade Flat")
    ap.add_argument("--border", type=float, nargs=4, metavar=("X0", "X1", "Y0", "Y1"),
                    help="render only this region (Render Region, fractions; cropped)")
    ap.add_argument("--passes", action="store_true",
                    help="a multilayer EXR with the light passes (Diffuse / Glossy / "
                         "Transmission Direct, Indirect, Color; Emission, Environment): "
                         "bench/newuser46_passes.py compares them per object")
    a = ap.parse_args()
    import addon
    addon.register()
    hdr = os.path.join(os.path.dirname(os.path.abspath(a.out)), "newuser46_sky.hdr")
    scene = kitchen_scene(sky_hdr(hdr), a.only, a.window, a.bottle_color, a.bottle_flat)
    if a.border:
        r = scene.render
        r.use_border, r.use_crop_to_border = True, False
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = a.border
    if a.filter_glossy is not None:
        scene.cycles.blur_glossy = a.filter_glossy
    if a.passes:
        vl = scene.view_layers[0]
        for k in ("diffuse", "glossy", "transmission"):
            for t in ("direct", "indirect", "color"):
                setattr(vl, f"use_pass_{k}_{t}", True)
        vl.use_pass_emit = vl.use_pass_environment = True
    render(scene, a)


if __name__ == "__main__":
    main()
