"""A new user's scene (session 44 trial): a table by a window, built with bpy as a
Blender user builds it (bpy.ops primitives, Shade Smooth, node materials), rendered with
Photon Mapping (Blender's RenderEngine, the add-on's default settings) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser44_table.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--world sky|colour]

The room: 4 x 4 x 2.6 m, a window (1.4 x 1.0 m hole, no pane) in the +X wall; a Sun
(2 W/m^2) shining in through it and a Sky Texture (Blender 5.0's default sky type, sun
disc off) as the world, or a plain world colour (--world colour); an area light under
the ceiling (40 W, 0.5 m). On a table: a wine bottle (a lathed profile, Shade Smooth,
Principled Transmission 1, roughness 0), a mug (cylinder and torus handle, Principled,
roughness 0.3); a wooden-brown floor; a curtain card beside the window whose material is
an Add Shader of a Transparent BSDF and a Diffuse BSDF.
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed 0; Cycles' other
settings - Light Paths, clamping - at their defaults, which the add-on reads too).

Prints `RESULT mode cpu_s=... wall_s=...` (this process and its children, from
resource.getrusage; the scene build excluded). --masks writes an (H, W) int array of
object ids (row 0 at the top; -1 the world) from Blender's scene.ray_cast through each
pixel centre and a JSON of the names; compare with bench/newuser26_compare.py.
"""
from __future__ import annotations

import argparse
import ast
import json
import math
import os
import resource
import sys
import time
from pathlib import Path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402
import bmesh  # noqa: E402
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import (assign, camera, cpu, cube, cylinder, empty_scene,  # noqa: E402
                              new_material, object_masks, principled)


def add_shader_curtain(name, color=(0.85, 0.8, 0.7)):
    """Transparent BSDF + Diffuse BSDF through an Add Shader (a common 'sheer' hack)."""
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    t = nt.nodes.new("ShaderNodeBsdfTransparent")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*color, 1.0)
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(t.outputs[0], add.inputs[0])
    nt.links.new(d.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def lathe(name, profile, mat, loc, steps=32):
    """A solid of revolution about z from (r, z) pairs (bottom to top), capped, smooth."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    rings = []
    for r, z in profile:
        rings.append([bm.verts.new((r * math.cos(2 * math.pi * k / steps),
                                    r * math.sin(2 * math.pi * k / steps), z))
                      for k in range(steps)])
    for a, b in zip(rings[:-1], rings[1:]):
        for k in range(steps):
            bm.faces.new((a[k], a[(k + 1) % steps], b[(k + 1) % steps], b[k]))
    bm.faces.new(list(reversed(rings[0])))
    bm.faces.new(rings[-1])
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    bm.to_mesh(me)
    bm.free()
    o = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(o)
    o.location = loc
    for p in me.polygons:
        p.use_smooth = True  # Shade Smooth
    return assign(o, mat)


def table_scene(world="sky"):
    scene = empty_scene()
    wall = principled("Wall", (0.75, 0.73, 0.7), 0.8)
    wood = principled("WoodFloor", (0.35, 0.18, 0.08), 0.5)
    top = principled("TableTop", (0.6, 0.55, 0.5), 0.6)
    ceramic = principled("Ceramic", (0.8, 0.3, 0.2), 0.3)
    bottle_glass = principled("BottleGlass", (0.6, 0.9, 0.6), 0.0, Transmission_Weight=1.0,
                              IOR=1.5)
    # Room, open towards the camera (-Y side missing): floor, ceiling, walls.
    cube("Floor", (0, 0, -0.05), (4, 4, 0.1), wood)
    cube("Ceiling", (0, 0, 2.65), (4, 4, 0.1), wall)
    cube("BackWall", (0, 2.05, 1.3), (4.2, 0.1, 2.6), wall)
    cube("LeftWall", (-2.05, 0, 1.3), (0.1, 4.2, 2.6), wall)
    # Right wall (+X) round a window hole y in [-0.2, 1.2], z in [0.9, 1.9].
    cube("RightWall_a", (2.05, -1.1, 1.3), (0.1, 1.8, 2.6), wall)
    cube("RightWall_b", (2.05, 1.6, 1.3), (0.1, 0.8, 2.6), wall)
    cube("RightWall_c", (2.05, 0.5, 0.45), (0.1, 1.4, 0.9), wall)
    cube("RightWall_d", (2.05, 0.5, 2.25), (0.1, 1.4, 0.7), wall)
    # Table by the window.
    cube("TableTop", (1.0, 0.6, 0.75), (1.2, 0.8, 0.04), top)
    for i, (x, y) in enumerate([(0.5, 0.3), (1.5, 0.3), (0.5, 0.9), (1.5, 0.9)]):
        cube(f"TableLeg{i}", (x, y, 0.365), (0.05, 0.05, 0.73), top)
    # Wine bottle: body, shoulder, neck (radius, height) from the table top.
    prof = [(0.0, 0.0), (0.04, 0.0), (0.042, 0.01), (0.042, 0.2), (0.035, 0.24),
            (0.018, 0.27), (0.014, 0.30), (0.014, 0.33), (0.0, 0.33)]
    lathe("WineBottle", prof[1:-1], bottle_glass, (0.8, 0.5, 0.77))
    # Mug: cylinder plus a torus handle, smooth.
    cylinder("Mug", 0.045, 0.1, (1.15, 0.55, 0.82), ceramic)
    bpy.ops.mesh.primitive_torus_add(major_radius=0.03, minor_radius=0.008,
                                     location=(1.2, 0.55 - 0.045 - 0.02, 0.82),
                                     rotation=(0, math.radians(90), math.radians(90)))
    h = bpy.context.active_object
    h.name = "MugHandle"
    bpy.ops.object.shade_smooth()
    assign(h, ceramic)
    # Curtain card hanging beside the window, 0.1 m in from the wall.
    bpy.ops.mesh.primitive_plane_add(size=1, location=(1.93, 1.35, 1.4),
                                     rotation=(math.radians(90), 0, math.radians(90)),
                                     scale=(0.5, 1.6, 1))
    c = bpy.context.active_object
    c.name = "Curtain"
    assign(c, add_shader_curtain("Sheer"))
    # Lights: a sun through the window, an area light under the ceiling.
    bpy.ops.object.light_add(type="SUN", location=(4, 0, 4))
    sun = bpy.context.active_object
    sun.name = "Sun"
    sun.data.energy = 2.0
    sun.rotation_euler = Vector((-1.0, -0.15, -0.6)).to_track_quat("-Z", "Y").to_euler()
    bpy.ops.object.light_add(type="AREA", location=(-0.5, 0.0, 2.55))
    area = bpy.context.active_object
    area.name = "CeilingArea"
    area.data.energy = 40.0
    area.data.size = 0.5
    # World.
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    nt = w.node_tree
    bg = nt.nodes["Background"]
    if world == "sky":
        sky = nt.nodes.new("ShaderNodeTexSky")
        sky.sun_disc = False
        sky.sun_elevation = math.radians(40)
        sky.sun_rotation = math.radians(0)
        nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = 0.3
    else:
        bg.inputs["Color"].default_value = (0.4, 0.5, 0.7, 1.0)
        bg.inputs["Strength"].default_value = 1.0
    camera((-0.4, -0.9, 1.3), (1.1, 0.7, 0.85), lens=28.0)
    return scene


def arguments(doc=None):
    """The command line shared with bench/newuser45_room.py: MODE OUT.exr and the options
    render() reads."""
    ap = argparse.ArgumentParser(description=doc)
    ap.add_argument("mode")
    ap.add_argument("out")
    ap.add_argument("--res", type=int, nargs=2, default=(160, 120))
    ap.add_argument("--masks")
    ap.add_argument("--save")
    ap.add_argument("--no-clamp", action="store_true",
                    help="Light Paths > Clamping Direct and Indirect 0 (read by both engines)")
    ap.add_argument("--set", action="append", default=[],
                    help="photonmap.NAME=VALUE (Python literal)")
    return ap


def render(scene, a):
    """Masks (--masks) or a render of scene by a.mode (ours | cycles:SPP) to a.out, a linear
    32-bit EXR; prints RESULT with the CPU seconds of the render."""
    r = scene.render
    r.resolution_x, r.resolution_y = a.res
    r.resolution_percentage = 100
    if a.masks:  # which object each pixel centre sees, for newuser26_compare.py
        ids, names = object_masks(scene, *a.res)
        np.save(a.masks, ids)
        Path(a.masks + ".json").write_text(json.dumps(names))
        return print("masks:", names)
    c = scene.cycles  # Light Paths: Cycles' settings, read by the add-on too
    if a.no_clamp:
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    r.engine = "PHOTONMAP" if a.mode == "ours" else "CYCLES"
    for k, v in (s.split("=", 1) for s in a.set):
        setattr(scene.photonmap, k, ast.literal_eval(v))
    if r.engine == "CYCLES":  # plain: no denoiser, every pixel the same samples
        c.device, c.samples = "CPU", int(a.mode.split(":")[1])
        c.seed = getattr(a, "cycles_seed", 0)  # newuser46_kitchen.py --cycles-seed
        c.use_denoising = c.use_adaptive_sampling = False
    if a.save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(a.save))
    fmt = r.image_settings  # linear 32-bit EXR: the comparison reads radiance
    multilayer = getattr(a, "passes", False)  # newuser46_kitchen.py --passes
    fmt.media_type = "MULTI_LAYER_IMAGE" if multilayer else "IMAGE"
    fmt.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    fmt.color_depth = "32"
    r.filepath, r.use_file_extension = os.path.abspath(a.out), False
    t0, w0 = cpu(), time.time()
    bpy.ops.render.render(write_still=True)
    t, wall = cpu() - t0, time.time() - w0
    if r.engine == "PHOTONMAP":
        import addon.engine as ae
        print("last_render:", {k: v for k, v in ae.last_render.items()
                               if k in ("width", "height", "cancelled", "error")})
    print(f"RESULT {a.mode} cpu_s={t:.1f} wall_s={wall:.1f}", flush=True)


def region_arguments(ap, bounces=True):
    """Adds the new-user scripts' --bounces (Light Paths > Max Bounces of both engines;
    left out with bounces=False) and --border (a Render Region, not cropped) to ap."""
    if bounces:
        ap.add_argument("--bounces", type=int,
                        help="Light Paths > Max Bounces (both engines; 0: direct light only)")
    ap.add_argument("--border", type=float, nargs=4, metavar=("X0", "X1", "Y0", "Y1"),
                    help="a Render Region (fractions; y from the bottom), not cropped")
    return ap


def finish(scene, a, masks=None):
    """The new-user scripts' end: a.bounces and a.border (region_arguments) set on scene,
    then, with --masks and a masks(scene, width, height, path) function, the scene's own
    masks; else render(scene, a) and, for ours, print_report()."""
    if getattr(a, "bounces", None) is not None:
        scene.cycles.max_bounces = a.bounces
    if getattr(a, "border", None):
        r = scene.render
        r.use_border, r.use_crop_to_border = True, False
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = a.border
    if a.masks and masks is not None:
        scene.render.resolution_x, scene.render.resolution_y = a.res
        scene.render.resolution_percentage = 100
        return masks(scene, *a.res, a.masks)
    render(scene, a)
    if a.mode == "ours":
        print_report()


def print_report():
    """Print what the add-on's last render reported besides its effect lines: warnings,
    the export's counts and the stats (the new-user trials read them)."""
    import addon.engine as ae
    lr = ae.last_render
    for w in lr.get("warnings", []):
        print("WARNING:", w)
    print("export:", lr.get("export"))
    print("stats:", {k: v for k, v in lr.get("stats", {}).items() if k != "effects"})


def main():
    ap = arguments()
    ap.add_argument("--world", default="sky", choices=("sky", "colour"))
    a = ap.parse_args()
    import addon
    addon.register()
    render(table_scene(a.world), a)


if __name__ == "__main__":
    main()
