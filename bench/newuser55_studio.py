"""A new user's scene (session 55 trial): a studio product shot - a car-paint Suzanne on a
rubber puck inside a chrome ring, a frosted glass cube beside it, on a cyclorama lit by a
three-point rig of area lights - built with bpy as a Blender user builds it (Blender's
defaults where a user leaves them), at both engines' default render settings, rendered
with Photon Mapping (the add-on's defaults) and Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser55_studio.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--cycles-seed S] [--bounces N] [--border X0 X1 Y0 Y1] [--only-light NAME]
        [--no-coat] [--spread DEG] [--puck-sheen W]

The set (metres, the floor at z = 0): a cyclorama - a plane 16 m wide from y = -8 to the
wall at y = 3, 8 m high, its corner edge rounded by a Bevel (offset 2 m, 16 segments, as
the bmesh Bevel operator makes it), Shade Smooth; Principled (0.7, 0.7, 0.7), roughness
0.5. A rubber puck (a cylinder of 48 sides, radius 1.3, 0.3 high, Shade Smooth; Principled
(0.03, 0.03, 0.03), roughness 0.8, Sheen Weight 0.5); on it Suzanne (primitive_monkey_add
at its default size, turned 20 degrees towards the key, a Subdivision Surface modifier of
level 2, Shade Smooth) in car paint (Principled (0.5, 0.02, 0.03), Metallic 1, roughness
0.35, Coat Weight 1, Coat Roughness 0.03); a chrome ring round the puck (a torus, major
radius 1.6, minor 0.1, Shade Smooth; Principled (0.9, 0.9, 0.9), Metallic 1, roughness
0.05); a frosted glass cube (0.9 m, turned 30 degrees; Principled Transmission Weight 1,
roughness 0.3, the rest the node's defaults) beside it; an emissive strip on the wall (a
cube 3 x 0.05 x 0.12 m; Principled black, Emission Colour white, Emission Strength 5).
Lights, all Area lights aimed at Suzanne: the key (Rectangle 2.5 x 1.5 m, 200 W, Spread
60 degrees, --spread) front left above; the fill (Disk 2 m, 50 W) front right low; the rim
(Rectangle 0.3 x 3 m, 150 W) behind on the left. World: a dim grey colour
(0.02, 0.02, 0.025). Camera 85 mm; AgX.
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed; Cycles'
Light Paths at their defaults, read by the add-on). Prints `RESULT mode cpu_s=...
wall_s=...` (bench/newuser44_table.py render) and, for ours, the add-on's warnings,
export and stats. --bounces sets Light Paths > Max Bounces (read by both; 0 renders
direct light only); --border renders only that Render Region (fractions, y from the
bottom; the EXR keeps the full frame, black outside); --only-light keeps one of Key, Fill,
Rim (the others deleted) and the strip's emission; --no-coat sets the paint's Coat Weight 0;
--puck-sheen the rubber's Sheen Weight.

--masks writes an (H, W) int array of region ids (row 0 at the top; -1 the world) and a
JSON of names, from Blender's scene.ray_cast through each pixel centre: every object, with
the cyclorama split into "Cyc:KeyShadow" (the key light's centre hidden from the point),
"Cyc:Highlight" (lit, its mirror direction within 20 degrees of the key's centre), "Cyc:Lit"
(the rest); Suzanne into "Suzanne:CoatHighlight" (its mirror ray meets one of the lights'
shapes, enlarged 1.3x), "Suzanne:RimEdge" (facing the rim light and unshadowed from it, the
view within 70-90 degrees of the face normal: the rim light's edge) and "Suzanne".
Face normals (Blender's ray_cast) stand in for the smooth ones. Compare with
bench/newuser26_compare.py, bench/newuser45_artefacts.py, bench/newuser48_flip.py and
bench/newuser54_regions.py.
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
import bmesh  # noqa: E402
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import (assign, camera, cube, cylinder, principled,  # noqa: E402
                              world_colour)
from newuser44_table import arguments, finish, region_arguments  # noqa: E402

TARGET = Vector((0.0, 0.0, 1.1))  # where the lights aim: Suzanne's head
# name: (type, shape, size, size_y, location, watts)
LIGHTS = {"Key": ("RECTANGLE", 2.5, 1.5, (-4.0, -4.5, 4.5), 200.0),
          "Fill": ("DISK", 2.0, 2.0, (5.0, -4.0, 1.8), 50.0),
          "Rim": ("RECTANGLE", 0.3, 3.0, (-2.2, 2.0, 3.2), 150.0)}


def cyclorama(mat):
    """A floor plane and a wall plane sharing their corner edge, the edge rounded by a
    Bevel (what Edit Mode > Bevel Edges does), Shade Smooth."""
    bm = bmesh.new()
    v = [bm.verts.new(p) for p in ((-8, -8, 0), (8, -8, 0), (8, 3, 0), (-8, 3, 0),
                                   (-8, 3, 8), (8, 3, 8))]
    bm.faces.new((v[0], v[1], v[2], v[3]))
    bm.faces.new((v[3], v[2], v[5], v[4]))
    corner = [e for e in bm.edges if set(e.verts) == {v[2], v[3]}]
    bmesh.ops.bevel(bm, geom=corner, offset=2.0, segments=16, profile=0.5,
                    affect="EDGES")
    me = bpy.data.meshes.new("Cyclorama")
    bm.to_mesh(me)
    bm.free()
    o = bpy.data.objects.new("Cyclorama", me)
    bpy.context.collection.objects.link(o)
    for p in me.polygons:
        p.use_smooth = True
    return assign(o, mat)


def aim(obj, target=TARGET):
    obj.rotation_euler = (target - obj.location).to_track_quat("-Z", "Y").to_euler()


def studio_scene(only_light=None, coat=True, spread=60.0, puck_sheen=0.5):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    cyclorama(principled("Backdrop", (0.7, 0.7, 0.7), 0.5))
    cylinder("Puck", 1.3, 0.3, (0, 0, 0.15),
             principled("Rubber", (0.03, 0.03, 0.03), 0.8, Sheen_Weight=puck_sheen))
    bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 0), rotation=(0, 0, math.radians(-20)))
    suz = bpy.context.active_object
    suz.name = "Suzanne"
    bpy.ops.object.shade_smooth()
    mod = suz.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 2
    ev = suz.evaluated_get(bpy.context.evaluated_depsgraph_get())  # the subdivided mesh
    lowest = min((suz.matrix_world @ v.co).z for v in ev.data.vertices)
    suz.location.z = 0.3 - lowest
    assign(suz, principled("CarPaint", (0.5, 0.02, 0.03), 0.35, 1.0,
                           Coat_Weight=1.0 if coat else 0.0, Coat_Roughness=0.03))
    bpy.ops.mesh.primitive_torus_add(major_radius=1.6, minor_radius=0.1, location=(0, 0, 0.1))
    ring = bpy.context.active_object
    ring.name = "Ring"
    bpy.ops.object.shade_smooth()
    assign(ring, principled("Chrome", (0.9, 0.9, 0.9), 0.05, 1.0))
    glass = cube("GlassCube", (2.4, -0.7, 0.45), (0.9, 0.9, 0.9),
                 principled("FrostedGlass", (0.8, 0.8, 0.8), 0.3, Transmission_Weight=1.0))
    glass.rotation_euler.z = math.radians(30)
    cube("Strip", (-1.5, 2.95, 3.0), (3.0, 0.05, 0.12),
         principled("StripLight", (0.0, 0.0, 0.0), 0.5, Emission_Strength=5.0))
    world_colour(scene, (0.02, 0.02, 0.025), 1.0)
    for name, (shape, sx, sy, loc, watts) in LIGHTS.items():
        if only_light and name != only_light:
            continue
        bpy.ops.object.light_add(type="AREA", location=loc)
        lamp = bpy.context.active_object
        lamp.name = name
        lamp.data.shape, lamp.data.size, lamp.data.size_y = shape, sx, sy
        lamp.data.energy = watts
        if name == "Key":
            lamp.data.spread = math.radians(spread)
        aim(lamp)
    camera((0.5, -16.0, 2.2), (0.7, 0.0, 0.9), lens=85.0)
    return scene


def _hits_light(x, d):
    """Whether the ray x + t d (t > 0) meets a light's shape enlarged 1.3x."""
    for name, (shape, sx, sy, loc, _) in LIGHTS.items():
        ob = bpy.data.objects.get(name)
        if ob is None:
            continue
        mw = ob.matrix_world
        n = (mw.to_3x3() @ Vector((0, 0, -1))).normalized()
        denom = d.dot(n)
        if abs(denom) < 1e-9:
            continue
        t = (mw.translation - x).dot(n) / denom
        if t <= 0:
            continue
        p = mw.inverted() @ (x + d * t)
        if shape == "DISK":
            inside = (p.x ** 2 + p.y ** 2) <= (0.65 * sx) ** 2
        else:
            inside = abs(p.x) <= 0.65 * sx and abs(p.y) <= 0.65 * sy
        if inside:
            return True
    return False


def studio_masks(scene, w, h, path):
    """Region ids per pixel centre (module docstring), saved to path and path + '.json'."""
    import json
    from pathlib import Path
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    key = Vector(LIGHTS["Key"][3])
    rim = Vector(LIGHTS["Rim"][3])
    names, ids = [], -np.ones((h, w), np.int32)

    def visible(x, n, target):
        d = target - x
        hit = scene.ray_cast(dg, x + n * 1e-4, d.normalized(), distance=d.length - 1e-3)[0]
        return not hit

    for j in range(h):
        for i in range(w):
            p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
            d = (p - origin).normalized()
            hit, x, n, _, ob, _ = scene.ray_cast(dg, origin, d)
            if not hit:
                continue
            name = ob.name
            nf = n if n.dot(d) < 0 else -n
            mirror = d - 2 * d.dot(nf) * nf
            if name == "Cyclorama":
                if not visible(x, nf, key):
                    name = "Cyc:KeyShadow"
                elif math.degrees(mirror.angle((key - x).normalized())) < 20:
                    name = "Cyc:Highlight"
                else:
                    name = "Cyc:Lit"
            elif name == "Suzanne":
                to_rim = (rim - x).normalized()
                if _hits_light(x + nf * 1e-4, mirror) and not scene.ray_cast(
                        dg, x + nf * 1e-4, mirror)[0]:
                    name = "Suzanne:CoatHighlight"
                elif (nf.dot(to_rim) > 0 and abs(nf.dot(d)) < math.cos(math.radians(70))
                      and visible(x, nf, rim)):
                    name = "Suzanne:RimEdge"
            if name not in names:
                names.append(name)
            ids[j, i] = names.index(name)
    np.save(path, ids)
    Path(path + ".json").write_text(json.dumps(names))
    print("masks:", {nm: int((ids == k).sum()) for k, nm in enumerate(names)})


def main():
    ap = arguments(__doc__)
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--only-light", choices=tuple(LIGHTS), help="keep one area light")
    ap.add_argument("--no-coat", action="store_true", help="the paint's Coat Weight 0")
    ap.add_argument("--spread", type=float, default=60.0, help="the key's Spread (degrees)")
    ap.add_argument("--puck-sheen", type=float, default=0.5, help="the rubber's Sheen Weight")
    region_arguments(ap)
    a = ap.parse_args()
    import addon
    addon.register()
    scene = studio_scene(a.only_light, not a.no_coat, a.spread, a.puck_sheen)
    finish(scene, a, studio_masks)


if __name__ == "__main__":
    main()
