"""A new user's scene (session 51 trial): the Blender donut, built with bpy as a beginner
builds it in the donut tutorial, at both engines' default render settings, rendered with
Photon Mapping (scene.render.engine = 'PHOTONMAP', the add-on's defaults) and Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser51_donut.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--cycles-seed S] [--drop NAME ...] [--only area|world] [--no-dof]
        [--sprinkles gn|dup|none] [--icing-sss W] [--flat NAME ...] [--area-watts P]
        [--lamp AREA|POINT] [--passes]
        [--hdr FILE.hdr]

The set (metres): a table (a 2 m plane; Principled, Base Color a Wave Texture's bands
(scale 3, distortion 6, detail 2) through a Color Ramp of two browns, Roughness 0.45); a
plate (lathed, radius 0.125 m, its foot ring standing on the table; Principled white,
Roughness 0.4, Coat Weight 1, Coat Roughness 0.03); the donut (a torus, major radius
0.045, minor 0.025, under a Subdivision Surface modifier (2) and a Displace modifier of a
Clouds texture (noise size 0.02, strength 0.002); Shade Smooth; Principled dough
(0.55, 0.3, 0.1), Roughness 0.5); the icing (the torus' upper half with a wavy edge,
minor radius 0.0265, under Solidify (1.5 mm, inward) and Subdivision Surface (2); Shade
Smooth; Principled pink (0.9, 0.25, 0.4), Roughness 0.25, Subsurface Weight 0.15 (the
node's Radius, Scale 0.05), Coat Weight 0.3); the sprinkles: a Geometry Nodes modifier on
the icing, as in the tutorial - Distribute Points on Faces (density 20,000 /m^2, seed 51;
faces whose normal z > 0.2), Instance on Points of a Collection Info of five sprinkle
capsules (6 mm x 1.6 mm; Separate Children, Reset Children) with Pick Instance by a
Random Value integer, Rotation aligned to the normal, a random twist; the collection of
shapes not linked to the scene (hidden); five Principled materials (pink, white, yellow,
blue, green, Roughness 0.3); a coffee mug (lathed, a torus handle; Principled dark blue,
Roughness 0.3, Coat Weight 1). Light: one Area light (0.6 m square, 10 W, front right,
0.6 m up, aimed at the donut) and the World: an Environment Texture of a 128 x 64
equirectangular .hdr written with numpy (warm surroundings 0.12-0.25, a window
rectangle of radiance 6, behind left, 25 degrees up). Camera 35 mm, Depth of Field on
the donut at F/2 (--no-dof: off). AgX. MODE: ours | cycles:SPP (no denoise, no adaptive
sampling, seed --cycles-seed; Cycles' Light Paths at their defaults, read by the add-on).

--sprinkles dup makes the same sprinkles linked duplicates (one object each, sharing the
shapes' meshes, at the Geometry Nodes instances' matrices), none removes them; --drop NAME
removes objects whose names start with NAME; --only area / world keeps one light;
--icing-sss W sets the icing's Subsurface Weight; --flat NAME shades those objects flat;
--area-watts P sets the Area light's Power (W); --lamp POINT puts a point light of
radius 0 in its place.

Prints `RESULT mode cpu_s=... wall_s=...` (bench/newuser44_table.py render). --masks
writes an (H, W) int array of object ids (row 0 at the top; -1 the world; pinhole rays,
so Depth of Field's blur is not in them) and a JSON of names, every sprinkle counted as
"Sprinkles"; compare with bench/newuser26_compare.py, bench/newuser45_artefacts.py,
bench/newuser48_flip.py and bench/newuser51_plate.py.
"""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402
import bmesh  # noqa: E402
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import assign, camera, object_masks, principled  # noqa: E402
from newuser44_table import arguments, finish, region_arguments  # noqa: E402
from studio48_stilllife import revolve, studio_world, write_hdr  # noqa: E402
from tools.canonical_mesh import canonical_faces  # noqa: E402

DONUT_Z = 0.006 + 0.025  # the plate's top + the torus' minor radius
SPRINKLE_COLOURS = {"Pink": (0.9, 0.2, 0.4), "White": (0.85, 0.85, 0.85),
                    "Yellow": (0.9, 0.7, 0.1), "Blue": (0.1, 0.25, 0.8),
                    "Green": (0.15, 0.6, 0.15)}


def kitchen_pixels(w=128, h=64):
    """(h, w, 3) radiance of the equirectangular World, row 0 at the top: warm
    surroundings (0.12 below the horizon to 0.25 at the zenith) and a window rectangle
    of radiance 6 (40 x 30 degrees) centred on the direction (-0.5, 0.87) in azimuth
    (behind the donut, on the left), 25 degrees up. Blender's mapping as
    studio48_stilllife.studio_pixels."""
    u = (np.arange(w) + 0.5) / w
    v = 1.0 - (np.arange(h) + 0.5) / h
    phi = (u - 0.5) * 2 * math.pi
    theta = (v - 0.5) * math.pi
    up = np.clip(np.sin(theta), 0, 1)[:, None]
    px = np.empty((h, w, 3))
    base = 0.12 + 0.13 * up
    px[...] = base[..., None] * np.array([1.0, 0.9, 0.75])
    c_phi = math.atan2(0.87, 0.5)  # atan2(y, -x) of the direction (-0.5, 0.87)
    dphi = (phi[None, :] - c_phi + math.pi) % (2 * math.pi) - math.pi
    box = (np.abs(dphi) < math.radians(20)) & (np.abs(theta[:, None]
                                                      - math.radians(25)) < math.radians(15))
    px[box] = np.array([6.0, 6.0, 6.3])
    return px


def wood_material(name):
    """Principled: Base Color from a Wave Texture's bands through a Color Ramp."""
    m = principled(name, (0.4, 0.22, 0.1), 0.45)
    nt = m.node_tree
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = 3.0
    wave.inputs["Distortion"].default_value = 6.0
    wave.inputs["Detail"].default_value = 2.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.18, 0.08, 0.03, 1)
    ramp.color_ramp.elements[1].color = (0.45, 0.25, 0.11, 1)
    nt.links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def torus(name, minor, mat, location):
    bpy.ops.mesh.primitive_torus_add(major_radius=0.045, minor_radius=minor,
                                     major_segments=48, minor_segments=16, location=location)
    o = bpy.context.active_object
    o.name = name
    bpy.ops.object.shade_smooth()
    return assign(o, mat)


def donut(mat):
    o = torus("Donut", 0.025, mat, (0, 0, DONUT_Z))
    sub = o.modifiers.new("Subdivision", "SUBSURF")
    sub.levels = sub.render_levels = 2
    tex = bpy.data.textures.new("DoughNoise", "CLOUDS")
    tex.noise_scale = 0.02
    d = o.modifiers.new("Displace", "DISPLACE")
    d.texture, d.strength = tex, 0.002
    return o


def icing(mat):
    """The torus' upper half (a wavy edge 2-6 mm below the middle), Solidify + Subdivision."""
    o = torus("Icing", 0.0265, mat, (0, 0, DONUT_Z))
    bm = bmesh.new()
    bm.from_mesh(o.data)
    cut = [v for v in bm.verts
           if v.co.z < -0.004 + 0.002 * math.sin(7 * math.atan2(v.co.y, v.co.x))]
    bmesh.ops.delete(bm, geom=cut, context="VERTS")
    bm.to_mesh(o.data)
    bm.free()
    sol = o.modifiers.new("Solidify", "SOLIDIFY")
    sol.thickness, sol.offset = 0.0015, -1.0
    sub = o.modifiers.new("Subdivision", "SUBSURF")
    sub.levels = sub.render_levels = 2
    return o


def sprinkle_shapes():
    """A Collection (not linked to the scene) of five capsules along x, one material each."""
    col = bpy.data.collections.new("SprinkleShapes")
    for name, rgb in SPRINKLE_COLOURS.items():
        me = bpy.data.meshes.new(f"Sprinkle{name}")
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=8, v_segments=6, radius=0.0008)
        for v in bm.verts:  # stretch the ball's middle into a 6 mm capsule along x
            v.co.x += 0.0022 if v.co.x > 0 else -0.0022
        bm.to_mesh(me)
        bm.free()
        canonical_faces(me)
        for p in me.polygons:
            p.use_smooth = True
        o = bpy.data.objects.new(f"Sprinkle{name}", me)
        col.objects.link(o)
        assign(o, principled(f"Sprinkle{name}", rgb, 0.3))
    return col


def sprinkle_nodes(col):
    """The tutorial's node tree: the icing joined with sprinkles instanced on its points."""
    ng = bpy.data.node_groups.new("Sprinkles", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, link = ng.nodes, ng.links.new
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    dist = n.new("GeometryNodeDistributePointsOnFaces")
    dist.inputs["Density"].default_value = 20000.0
    dist.inputs["Seed"].default_value = 51
    normal, sep = n.new("GeometryNodeInputNormal"), n.new("ShaderNodeSeparateXYZ")
    cmp = n.new("FunctionNodeCompare")
    cmp.data_type, cmp.operation = "FLOAT", "GREATER_THAN"
    cmp.inputs[1].default_value = 0.2
    link(normal.outputs[0], sep.inputs[0])
    link(sep.outputs["Z"], cmp.inputs[0])
    link(gin.outputs[0], dist.inputs["Mesh"])
    link(cmp.outputs[0], dist.inputs["Selection"])
    info = n.new("GeometryNodeCollectionInfo")
    info.inputs["Collection"].default_value = col
    info.inputs["Separate Children"].default_value = True
    info.inputs["Reset Children"].default_value = True
    pick = n.new("FunctionNodeRandomValue")
    pick.data_type = "INT"
    pick.inputs[4].default_value, pick.inputs[5].default_value = 0, len(col.objects) - 1
    pick.inputs["Seed"].default_value = 7
    twist = n.new("FunctionNodeRandomValue")
    twist.data_type = "FLOAT_VECTOR"
    twist.inputs[1].default_value = (0.0, 0.0, 2 * math.pi)
    align = n.new("FunctionNodeAlignRotationToVector")
    align.axis = "Z"
    link(twist.outputs[0], align.inputs["Rotation"])
    link(dist.outputs["Normal"], align.inputs["Vector"])
    inst = n.new("GeometryNodeInstanceOnPoints")
    inst.inputs["Pick Instance"].default_value = True
    link(dist.outputs["Points"], inst.inputs["Points"])
    link(info.outputs[0], inst.inputs["Instance"])
    link(pick.outputs[2], inst.inputs["Instance Index"])
    link(align.outputs[0], inst.inputs["Rotation"])
    join = n.new("GeometryNodeJoinGeometry")
    link(inst.outputs[0], join.inputs[0])
    link(gin.outputs[0], join.inputs[0])
    link(join.outputs[0], gout.inputs[0])
    return ng


def duplicate_sprinkles(icing_obj, col):
    """Replace the Geometry Nodes sprinkles by linked duplicates at their matrices."""
    dg = bpy.context.evaluated_depsgraph_get()
    made = []
    for inst in dg.object_instances:
        if inst.is_instance and inst.parent and inst.parent.original == icing_obj:
            src = inst.object.original
            made.append((src, inst.matrix_world.copy()))
    icing_obj.modifiers.remove(icing_obj.modifiers["Sprinkles"])
    for k, (src, mat) in enumerate(made):
        o = bpy.data.objects.new(f"Sprinkle.{k:04d}", src.data)
        bpy.context.collection.objects.link(o)
        o.matrix_world = mat
    return len(made)


def donut_scene(hdr_path, sprinkles="gn", drop=(), only=None, dof=True, icing_sss=0.15,
                flat=(), area_watts=10.0, lamp="AREA"):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0, 0.3, 0))
    table = bpy.context.active_object
    table.name = "Table"
    assign(table, wood_material("Wood"))
    plate = principled("Ceramic", (0.85, 0.85, 0.85), 0.4, Coat_Weight=1.0,
                       Coat_Roughness=0.03)
    revolve("Plate", [(0, 0.002), (0.06, 0.002), (0.065, 0.0), (0.075, 0.0), (0.08, 0.004),
                      (0.125, 0.016), (0.127, 0.019), (0.122, 0.02), (0.08, 0.008),
                      (0.07, 0.006), (0, 0.006)], plate, (0, 0, 0), steps=64)
    donut(principled("Dough", (0.55, 0.3, 0.1), 0.5))
    ice = icing(principled("Icing", (0.9, 0.25, 0.4), 0.25, Subsurface_Weight=icing_sss,
                           Coat_Weight=0.3))
    if sprinkles != "none":
        col = sprinkle_shapes()
        mod = ice.modifiers.new("Sprinkles", "NODES")
        mod.node_group = sprinkle_nodes(col)
        if sprinkles == "dup":
            print("linked duplicates:", duplicate_sprinkles(ice, col))
    mug = principled("MugGlaze", (0.03, 0.07, 0.25), 0.3, Coat_Weight=1.0)
    revolve("Mug", [(0, 0), (0.035, 0), (0.04, 0.006), (0.045, 0.095), (0.043, 0.1),
                    (0.04, 0.096), (0.037, 0.012), (0, 0.012)], mug, (0.17, 0.16, 0.0))
    bpy.ops.mesh.primitive_torus_add(major_radius=0.028, minor_radius=0.007,
                                     location=(0.17 + 0.055, 0.16, 0.05),
                                     rotation=(math.radians(90), 0, 0))
    h = bpy.context.active_object
    h.name = "MugHandle"
    bpy.ops.object.shade_smooth()
    assign(h, mug)
    studio_world(scene, hdr_path)
    bpy.ops.object.light_add(type=lamp, location=(0.45, -0.35, 0.6))
    area = bpy.context.active_object
    area.name = "AreaLight"
    area.data.energy = area_watts
    if lamp == "AREA":
        area.data.size = 0.6
    else:  # --lamp POINT: a point light without size (Radius 0) in its place
        area.data.shadow_soft_size = 0.0
    area.rotation_euler = (Vector((0.0, 0.0, DONUT_Z)) - area.location).to_track_quat(
        "-Z", "Y").to_euler()
    if only == "area":
        scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    elif only == "world":
        bpy.data.objects.remove(area)
    for name in drop:
        for o in [o for o in bpy.data.objects if o.name.startswith(name)]:
            bpy.data.objects.remove(o)
    for name in flat:  # Shade Flat
        for p in bpy.data.objects[name].data.polygons:
            p.use_smooth = False
    cam = camera((0.0, -0.33, 0.25), (0.02, 0.02, 0.02), lens=35.0)
    if dof:
        cam.data.dof.use_dof = True
        if "Donut" in bpy.data.objects:
            cam.data.dof.focus_object = bpy.data.objects["Donut"]
        else:  # a sub-scene without it: the same plane (its depth along the view axis)
            view = cam.matrix_world.to_quaternion() @ Vector((0.0, 0.0, -1.0))
            cam.data.dof.focus_distance = (Vector((0.0, 0.0, DONUT_Z)) - cam.location).dot(view)
        cam.data.dof.aperture_fstop = 2.0
    return scene


def grouped_masks(scene, w, h, path):
    """object_masks with every sprinkle (instance or duplicate) one object 'Sprinkles'."""
    ids, names = object_masks(scene, w, h)
    merged = []
    out = -np.ones_like(ids)
    for i, n in enumerate(names):
        key = "Sprinkles" if n.startswith("Sprinkle") else n
        if key not in merged:
            merged.append(key)
        out[ids == i] = merged.index(key)
    np.save(path, out)
    Path(path + ".json").write_text(json.dumps(merged))
    print("masks:", merged, "(raw names:", len(names), ")")


def main():
    ap = arguments()
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--only", choices=("area", "world"))
    ap.add_argument("--no-dof", action="store_true")
    ap.add_argument("--sprinkles", choices=("gn", "dup", "none"), default="gn")
    ap.add_argument("--icing-sss", type=float, default=0.15)
    ap.add_argument("--flat", nargs="*", default=[], help="these objects Shade Flat")
    ap.add_argument("--area-watts", type=float, default=10.0, help="the Area light's Power")
    ap.add_argument("--lamp", choices=("AREA", "POINT"), default="AREA",
                    help="POINT: a point light of radius 0 in the Area light's place")
    ap.add_argument("--hdr", default="/tmp/newuser51/kitchen.hdr")
    ap.add_argument("--passes", action="store_true",
                    help="a multilayer EXR with the light passes (bench/newuser46_passes.py)")
    region_arguments(ap, bounces=False)
    a = ap.parse_args()
    write_hdr(a.hdr, kitchen_pixels())
    import addon
    addon.register()
    scene = donut_scene(a.hdr, a.sprinkles, a.drop, a.only, not a.no_dof, a.icing_sss,
                        a.flat, a.area_watts, a.lamp)
    if a.passes:
        vl = scene.view_layers[0]
        for k in ("diffuse", "glossy", "transmission"):
            for t in ("direct", "indirect", "color"):
                setattr(vl, f"use_pass_{k}_{t}", True)
        vl.use_pass_emit = vl.use_pass_environment = True
    finish(scene, a, grouped_masks)


if __name__ == "__main__":
    main()
