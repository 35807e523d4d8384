"""A new user's scene (session 52 trial): a jewellery display - a cut gem, two rings and a
crystal pendant on a white plinth on dark velvet, lit by one small spot light and a dim
HDRI - built with bpy as a Blender user builds it (Principled BSDF everywhere, Blender's
defaults where a user leaves them), at both engines' default render settings, rendered
with Photon Mapping (scene.render.engine = 'PHOTONMAP', the add-on's defaults) and Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser52_jewellery.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--cycles-seed S] [--drop NAME ...] [--only spot|world] [--filter-glossy F]
        [--hdr FILE.hdr] [--border X0 X1 Y0 Y1]

The set (metres): the cloth (a 1 m plane; Principled dark burgundy (0.08, 0.01, 0.02),
Roughness 0.8, Sheen Weight 1: velvet); the plinth (a cube 0.1 x 0.1 x 0.03 standing on
it; Principled white (0.8, 0.8, 0.8), Roughness 0.5 (the default)); on the plinth: the
gem (a low-poly round brilliant of 8 sides: girdle radius 8 mm, pavilion 7 mm to the
culet, crown 2.6 mm to a table of radius 4.5 mm - one closed mesh, as a user makes it
from a Cylinder by merging its bottom ring to a point and scaling the top in; Shade Flat;
standing on its culet; Principled Transmission Weight 1, IOR 2.42, Roughness 0, white);
the gold ring (a torus, major radius 9 mm, minor 1.4 mm, lying flat; Shade Smooth;
Principled Metallic 1, (1.0, 0.78, 0.34), Roughness 0.1); the silver ring (a torus, major
8.5 mm, minor 1.3 mm, standing upright; Shade Smooth; Metallic 1, (0.96, 0.96, 0.97),
Roughness 0.25); the crystal pendant (a UV sphere of radius 7 mm scaled 1.4 x in z, a
drop; Shade Smooth; Principled Transmission Weight 1, Roughness 0, IOR the node's default)
hanging 15 mm above the plinth on a thin silver chain (a cylinder of radius 0.4 mm) from
a silver stand (a post and an arm, cylinders of radius 1.5 mm). Light: one Spot light
(15 W, Radius 10 mm, Spot Size 45 degrees (the default), Blend 0.15 (the default)) front
right, 0.32 m up, aimed at the plinth; the World: an Environment Texture of a 128 x 64
equirectangular .hdr written with numpy (dim surroundings 0.02-0.05 and a softbox of
radiance 1.5 behind left, 30 degrees up). Camera 70 mm. AgX. MODE: ours | cycles:SPP (no
denoise, no adaptive sampling, seed --cycles-seed; Cycles' Light Paths at their defaults,
read by the add-on).

--drop NAME removes objects whose names start with NAME; --only spot / world keeps one
light; --filter-glossy F sets Light Paths > Filter Glossy (both engines read it);
--border renders only that Render Region (fractions of the frame, y from the bottom; the
EXR keeps the full frame, black outside).
Prints `RESULT mode cpu_s=... wall_s=...` (bench/newuser44_table.py render). --masks
writes an (H, W) int array of object ids (row 0 at the top; -1 the world) and a JSON of
names, where the plinth's top is split into the regions the casters' light falls on:
"Plinth:GemShadow" / "Plinth:PendantShadow" / "Plinth:SilverShadow" (its shadow ray to
the spot's centre meets that object) and "Plinth:InGoldRing" (inside the gold ring, where
its reflected caustic lies); compare with bench/newuser26_compare.py,
bench/newuser45_artefacts.py and bench/newuser48_flip.py.
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
from newuser26_scenes import assign, camera, principled, top_masks  # noqa: E402
from newuser44_table import arguments, finish, region_arguments  # noqa: E402
from tools.canonical_mesh import canonical_faces  # noqa: E402
from studio48_stilllife import revolve, studio_world, write_hdr  # noqa: E402

TOP = 0.03  # the plinth's top (m)
GEM_AT = (-0.012, 0.012)
GOLD_AT = (0.022, -0.006)
PENDANT_AT = (-0.022, -0.024)
SPOT_AT = (0.18, -0.22, 0.32)


def display_pixels(w=128, h=64):
    """(h, w, 3) radiance of the equirectangular World, row 0 at the top: dim surroundings
    (0.02 below the horizon to 0.05 at the zenith) and a softbox of radiance 1.5 (40 x 30
    degrees) centred on the direction (-0.6, 0.8) in azimuth (behind the plinth, left),
    30 degrees up. Blender's mapping as studio48_stilllife.studio_pixels."""
    u = (np.arange(w) + 0.5) / w
    v = 1.0 - (np.arange(h) + 0.5) / h
    phi = (u - 0.5) * 2 * math.pi
    theta = (v - 0.5) * math.pi
    up = np.clip(np.sin(theta), 0, 1)[:, None]
    px = np.empty((h, w, 3))
    px[...] = (0.02 + 0.03 * up)[..., None] * np.array([1.0, 1.0, 1.05])
    c_phi = math.atan2(0.8, 0.6)  # atan2(y, -x) of the direction (-0.6, 0.8)
    dphi = (phi[None, :] - c_phi + math.pi) % (2 * math.pi) - math.pi
    box = (np.abs(dphi) < math.radians(20)) & (np.abs(theta[:, None]
                                                      - math.radians(30)) < math.radians(15))
    px[box] = 1.5
    return px


def flat(o):
    for p in o.data.polygons:
        p.use_smooth = False
    return o


def cylinder_between(name, a, b, radius, mat):
    """A 12-sided cylinder from point a to point b (Shade Smooth)."""
    a, b = Vector(a), Vector(b)
    bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=radius, depth=(b - a).length,
                                        location=(a + b) / 2)
    o = bpy.context.active_object
    o.name = name
    o.rotation_euler = (b - a).to_track_quat("Z", "Y").to_euler()
    bpy.ops.object.shade_smooth()
    return assign(o, mat)


def torus(name, major, minor, mat, location, rotation=(0, 0, 0)):
    bpy.ops.mesh.primitive_torus_add(major_radius=major, minor_radius=minor,
                                     major_segments=48, minor_segments=12,
                                     location=location, rotation=rotation)
    o = bpy.context.active_object
    o.name = name
    bpy.ops.object.shade_smooth()
    return assign(o, mat)


def jewellery_scene(hdr_path, drop=(), only=None):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 0.2, 0))
    cloth = bpy.context.active_object
    cloth.name = "Cloth"
    assign(cloth, principled("Velvet", (0.08, 0.01, 0.02), 0.8, Sheen_Weight=1.0))
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, TOP / 2), scale=(0.1, 0.1, TOP))
    plinth = bpy.context.active_object
    plinth.name = "Plinth"
    assign(plinth, principled("PlinthWhite", (0.8, 0.8, 0.8), 0.5))
    # The gem: an 8-sided round brilliant standing on its culet, Shade Flat.
    diamond = principled("Diamond", (1, 1, 1), 0.0, Transmission_Weight=1.0, IOR=2.42)
    r = 0.008
    gem = revolve("Gem", [(0, 0), (r, 0.007), (r, 0.0078), (0.0045, 0.0104), (0, 0.0104)],
                  diamond, (*GEM_AT, TOP), steps=8)
    gem.rotation_euler.z = math.radians(10)
    flat(gem)
    gold = principled("Gold", (1.0, 0.78, 0.34), 0.1, metallic=1.0)
    torus("GoldRing", 0.009, 0.0014, gold, (*GOLD_AT, TOP + 0.0014))
    silver = principled("Silver", (0.96, 0.96, 0.97), 0.25, metallic=1.0)
    torus("SilverRing", 0.0085, 0.0013, silver, (0.012, 0.03, TOP + 0.0098),
          rotation=(math.radians(90), 0, math.radians(25)))
    # The crystal pendant: a UV sphere drop (its faces in a fixed order) on a chain.
    crystal = principled("Crystal", (1, 1, 1), 0.0, Transmission_Weight=1.0)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.007,
                                         location=(*PENDANT_AT, TOP + 0.015 + 0.0098))
    pend = bpy.context.active_object
    pend.name = "Pendant"
    pend.scale.z = 1.4
    canonical_faces(pend.data)
    bpy.ops.object.shade_smooth()
    assign(pend, crystal)
    top_z = TOP + 0.015 + 2 * 0.0098
    arm_z = TOP + 0.075
    cylinder_between("Chain", (*PENDANT_AT, top_z - 0.0005), (*PENDANT_AT, arm_z), 0.0004,
                     silver)
    post = (PENDANT_AT[0] - 0.024, PENDANT_AT[1])
    cylinder_between("StandPost", (*post, TOP), (*post, arm_z + 0.0015), 0.0015, silver)
    cylinder_between("StandArm", (*post, arm_z), (PENDANT_AT[0] + 0.003, PENDANT_AT[1], arm_z),
                     0.0015, silver)
    studio_world(scene, hdr_path)
    bpy.ops.object.light_add(type="SPOT", location=SPOT_AT)
    spot = bpy.context.active_object
    spot.name = "Spot"
    spot.data.energy = 15.0
    spot.data.shadow_soft_size = 0.01
    spot.rotation_euler = (Vector((0.0, 0.0, TOP)) - spot.location).to_track_quat(
        "-Z", "Y").to_euler()
    if only == "spot":
        scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    elif only == "world":
        bpy.data.objects.remove(spot)
    for name in drop:
        for o in [o for o in bpy.data.objects if o.name.startswith(name)]:
            bpy.data.objects.remove(o)
    camera((0.02, -0.26, 0.17), (0.0, 0.0, TOP + 0.008), lens=70.0)
    return scene


def caster_masks(scene, w, h, path):
    """object_masks with the plinth's top split by which caster's light falls there."""
    light = Vector(SPOT_AT)
    gold = Vector((*GOLD_AT, TOP))
    shadow = {"Gem": "Plinth:GemShadow", "Pendant": "Plinth:PendantShadow",
              "SilverRing": "Plinth:SilverShadow"}

    def classify(x, n, dg):
        if (x - gold).xy.length < 0.009 - 0.0014:
            return "Plinth:InGoldRing"
        x1 = x + n * 1e-5
        d = light - x1
        hit2, _, _, _, ob2, _ = scene.ray_cast(dg, x1, d.normalized(), distance=d.length)
        return shadow.get(ob2.name) if hit2 else None

    top_masks(scene, w, h, path, "Plinth", classify)


def main():
    ap = arguments(__doc__)
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--only", choices=("spot", "world"))
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Filter Glossy (default: Blender's, 1.0)")
    ap.add_argument("--hdr", default="/tmp/newuser52/display.hdr")
    region_arguments(ap, bounces=False)
    a = ap.parse_args()
    write_hdr(a.hdr, display_pixels())
    import addon
    addon.register()
    scene = jewellery_scene(a.hdr, a.drop, a.only)
    if a.filter_glossy is not None:
        scene.cycles.blur_glossy = a.filter_glossy
    finish(scene, a, caster_masks)


if __name__ == "__main__":
    main()
