"""A new user's two scenes (session s26 trial), built with bpy as an artist builds them
(bpy.ops primitives, node materials, modifiers), rendered with Photon Mapping (through
Blender's RenderEngine, the add-on's default settings) and with Cycles.

    NUMBA_CACHE_DIR=... PYTHONPATH=. .venv/bin/python bench/newuser26_scenes.py \
        SCENE MODE OUT.exr [--res W H] [--save FILE.blend] [--border x0 x1 y0 y1]
        [--animation] [--set NAME=VALUE] [--masks MASKS.npy]

SCENE: kitchen (Sun + Nishita Sky world through a window of one glass plane; a Noise-
                textured floor, an Image-textured back wall, a steel pot, a drinking glass
                made hollow by a Solidify modifier, a ceiling lamp)
       product (a glass bottle, Solidify shell, holding coloured liquid: nested glass
                volumes; an Image-textured label sleeve; a Mix Shader cap; an area soft
                box, a world colour; camera depth of field focused on the bottle)
MODE:  ours | cycles:SPP  (Cycles plain: no denoise, no adaptive, no clamp, seed 0,
       blur glossy 0, Blackman-Harris 1.5 px as ours)

Prints `RESULT scene mode cpu_s=... maxrss_MB=...` after the render (CPU time of this
process, all threads, from resource.getrusage; the scene build is not counted).
--masks writes an int array (H, W) of object ids, row 0 at the top, from a camera ray
cast through each pixel centre with Blender's own scene.ray_cast, and a JSON of the names.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime


def new_material(name):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    return m


def principled(name, color=(0.8, 0.8, 0.8), roughness=0.5, metallic=0.0, **inputs):
    m = new_material(name)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Roughness"].default_value = roughness
    p.inputs["Metallic"].default_value = metallic
    for k, v in inputs.items():
        p.inputs[k.replace("_", " ")].default_value = v
    return m


def glass(name, ior=1.5, color=(1.0, 1.0, 1.0)):
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["IOR"].default_value = ior
    g.inputs["Roughness"].default_value = 0.0
    g.inputs["Color"].default_value = (*color, 1.0)
    nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def assign(obj, mat):
    obj.data.materials.clear()
    obj.data.materials.append(mat)
    return obj


def cube(name, loc, scale, mat):
    bpy.ops.mesh.primitive_cube_add(size=1, location=loc, scale=scale)
    o = bpy.context.active_object
    o.name = name
    return assign(o, mat)


def cylinder(name, radius, depth, loc, mat, vertices=48, smooth=True):
    bpy.ops.mesh.primitive_cylinder_add(vertices=vertices, radius=radius, depth=depth,
                                        location=loc)
    o = bpy.context.active_object
    o.name = name
    if smooth:
        bpy.ops.object.shade_smooth()
    return assign(o, mat)


def camera(loc, target, lens=35.0):
    bpy.ops.object.camera_add(location=loc)
    cam = bpy.context.active_object
    cam.data.lens = lens
    cam.rotation_euler = Vector(np.subtract(target, loc)).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = cam
    return cam


def empty_scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    return scene


def world_colour(scene, color, strength=1.0):
    """A new World of a constant Background colour (RGB, linear) and strength."""
    world = bpy.data.worlds.new("World")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1)
    bg.inputs["Strength"].default_value = strength
    return world


def tile_image(name, n=64):
    """A generated tile pattern (grout lines), packed: an Image Texture a user paints."""
    img = bpy.data.images.new(name, n, n, alpha=False)
    y, x = np.mgrid[0:n, 0:n]
    grout = ((x % 16) < 2) | ((y % 16) < 2)
    px = np.ones((n, n, 4), np.float32)
    px[..., 0] = np.where(grout, 0.35, 0.85)
    px[..., 1] = np.where(grout, 0.35, 0.82)
    px[..., 2] = np.where(grout, 0.33, 0.70)
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def label_image(name, n=64):
    """Stripes and a dark band: a label's artwork."""
    img = bpy.data.images.new(name, n, n, alpha=False)
    y, x = np.mgrid[0:n, 0:n]
    px = np.ones((n, n, 4), np.float32)
    band = (y > 24) & (y < 40)
    stripe = (x // 4) % 2 == 0
    px[..., 0] = np.where(band, 0.05, np.where(stripe, 0.9, 0.7))
    px[..., 1] = np.where(band, 0.05, np.where(stripe, 0.85, 0.2))
    px[..., 2] = np.where(band, 0.1, np.where(stripe, 0.6, 0.15))
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


# --- (a) kitchen ------------------------------------------------------------------------

def kitchen():
    scene = empty_scene()
    plaster = principled("Plaster", (0.8, 0.78, 0.72), roughness=0.8)
    # Floor: Noise Texture through a Color Ramp into Base Color (a stone-like floor).
    floor = principled("StoneFloor", roughness=0.5)
    nt = floor.node_tree
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 8.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.25, 0.2, 0.15, 1)
    ramp.color_ramp.elements[1].color = (0.6, 0.55, 0.45, 1)
    nt.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    # Splashback tiles: an Image Texture on the cube's own UVs.
    tiles = principled("Tiles", roughness=0.2)
    nt = tiles.node_tree
    it = nt.nodes.new("ShaderNodeTexImage")
    it.image = tile_image("tiles")
    nt.links.new(it.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    counter = principled("Counter", (0.15, 0.15, 0.17), roughness=0.25)
    steel = principled("Steel", (0.8, 0.8, 0.82), roughness=0.2, metallic=1.0)
    pane = glass("WindowGlass", 1.5)
    tumbler = glass("Tumbler", 1.5)
    # Room 4 x 3 x 2.6 m (x -2..2, y -1.5..1.5), closed: daylight enters by the window.
    cube("Floor", (0, 0, -0.05), (4.2, 3.2, 0.1), floor)
    cube("Ceiling", (0, 0, 2.65), (4.2, 3.2, 0.1), plaster)
    cube("LeftWall", (-2.05, 0, 1.3), (0.1, 3.2, 2.6), plaster)
    cube("RightWall", (2.05, 0, 1.3), (0.1, 3.2, 2.6), plaster)
    cube("FrontWall", (0, -1.55, 1.3), (4.0, 0.1, 2.6), plaster)
    # Back wall (+Y) with a window 1.2 x 0.9 m, centre x=0.6, z=1.65.
    cube("BackWall_low", (0, 1.55, 0.6), (4.0, 0.1, 1.2), tiles)
    cube("BackWall_high", (0, 1.55, 2.405), (4.0, 0.1, 0.39), plaster)
    cube("BackWall_left", (-0.8, 1.55, 1.65), (2.4, 0.1, 0.9), plaster)
    cube("BackWall_right", (1.6, 1.55, 1.65), (0.8, 0.1, 0.9), plaster)
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0.6, 1.55, 1.65),
                                     rotation=(math.pi / 2, 0, 0))
    w = assign(bpy.context.active_object, pane)
    w.name = "WindowPane"
    w.scale = (1.2, 0.9, 1)
    # Counter along the back wall, a steel pot and a drinking glass on it.
    cube("Counter", (0, 1.2, 0.45), (4.0, 0.6, 0.9), counter)
    pot = cylinder("Pot", 0.15, 0.18, (-0.5, 1.15, 0.99), steel)
    sol = pot.modifiers.new("Solidify", "SOLIDIFY")
    sol.thickness = 0.006
    # Open the pot: delete its top cap face (the largest face with +Z normal).
    me = pot.data
    top = max((f for f in me.polygons if f.normal.z > 0.9), key=lambda f: f.center.z)
    import bmesh
    bm = bmesh.new()
    bm.from_mesh(me)
    bm.faces.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.faces[top.index]], context="FACES_ONLY")
    bm.to_mesh(me)
    bm.free()
    g = cylinder("DrinkingGlass", 0.035, 0.11, (0.2, 1.0, 0.955), tumbler)
    me = g.data
    top = max((f for f in me.polygons if f.normal.z > 0.9), key=lambda f: f.center.z)
    bm = bmesh.new()
    bm.from_mesh(me)
    bm.faces.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.faces[top.index]], context="FACES_ONLY")
    bm.to_mesh(me)
    bm.free()
    sol = g.modifiers.new("Solidify", "SOLIDIFY")
    sol.thickness = 0.003
    # Sun (low, through the window) and a Nishita sky world.
    bpy.ops.object.light_add(type="SUN", location=(0, 4, 4))
    sun = bpy.context.active_object
    sun.name = "Sun"
    sun.data.energy = 3.0
    sun.data.angle = math.radians(0.5)
    sun.rotation_euler = Vector((-0.3, -1.0, -0.55)).to_track_quat("-Z", "Y").to_euler()
    world = bpy.data.worlds.new("SkyWorld")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    wnt = world.node_tree
    sky = wnt.nodes.new("ShaderNodeTexSky")
    wnt.links.new(sky.outputs["Color"], wnt.nodes["Background"].inputs["Color"])
    wnt.nodes["Background"].inputs["Strength"].default_value = 0.3
    # A ceiling lamp: a small disk area light pointing down.
    bpy.ops.object.light_add(type="AREA", location=(-0.6, 0.3, 2.55))
    lamp = bpy.context.active_object
    lamp.name = "CeilingLamp"
    lamp.data.shape = "DISK"
    lamp.data.size = 0.4
    lamp.data.energy = 60.0
    lamp.data.color = (1.0, 0.85, 0.7)
    camera((-0.9, -0.6, 1.5), (-0.1, 1.2, 1.0), lens=30)
    return scene


# --- (b) product shot --------------------------------------------------------------------

def product():
    scene = empty_scene()
    backdrop = principled("Backdrop", (0.7, 0.72, 0.75), roughness=0.6)
    bottle_glass = glass("BottleGlass", 1.5, (0.9, 1.0, 0.95))
    liquid = glass("Liquid", 1.34, (0.9, 0.45, 0.1))
    # Backdrop: a floor plane and a back plane.
    bpy.ops.mesh.primitive_plane_add(size=4, location=(0, 0, 0))
    assign(bpy.context.active_object, backdrop).name = "Floor"
    bpy.ops.mesh.primitive_plane_add(size=4, location=(0, 1.0, 2.0),
                                     rotation=(math.pi / 2, 0, 0))
    assign(bpy.context.active_object, backdrop).name = "BackPlane"
    # Bottle: a closed cylinder made a 4 mm shell by Solidify (two nested glass surfaces).
    b = cylinder("Bottle", 0.08, 0.3, (0, 0, 0.15), bottle_glass, vertices=64)
    sol = b.modifiers.new("Solidify", "SOLIDIFY")
    sol.thickness = 0.004
    sol.offset = -1.0
    # Liquid: a cylinder inside the shell, 0.5 mm off the inner wall, filled to 0.2 m.
    cylinder("Liquid", 0.0755, 0.2, (0, 0, 0.0045 + 0.1), liquid, vertices=64)
    # Label: an open sleeve just outside the bottle, Image Texture on the cylinder's UVs.
    lab = principled("LabelPaper", roughness=0.5)
    nt = lab.node_tree
    it = nt.nodes.new("ShaderNodeTexImage")
    it.image = label_image("label")
    nt.links.new(it.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    bpy.ops.mesh.primitive_cylinder_add(vertices=64, radius=0.0815, depth=0.1,
                                        location=(0, 0, 0.13), end_fill_type="NOTHING")
    o = assign(bpy.context.active_object, lab)
    o.name = "Label"
    bpy.ops.object.shade_smooth()
    # Cap: a Mix Shader of a gold Glossy and a red Diffuse, Fresnel factor.
    capm = new_material("CapMix")
    nt = capm.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    gl = nt.nodes.new("ShaderNodeBsdfGlossy")
    gl.inputs["Color"].default_value = (0.9, 0.7, 0.3, 1)
    gl.inputs["Roughness"].default_value = 0.25
    df = nt.nodes.new("ShaderNodeBsdfDiffuse")
    df.inputs["Color"].default_value = (0.6, 0.05, 0.05, 1)
    fr = nt.nodes.new("ShaderNodeFresnel")
    fr.inputs["IOR"].default_value = 1.5
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(fr.outputs[0], mix.inputs[0])
    nt.links.new(df.outputs[0], mix.inputs[1])
    nt.links.new(gl.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    cylinder("Cap", 0.03, 0.04, (0, 0, 0.32), capm)
    # Lights: a soft box (rectangle area) key from the left, a dim world colour.
    bpy.ops.object.light_add(type="AREA", location=(-0.8, -0.5, 0.9))
    key = bpy.context.active_object
    key.name = "SoftBox"
    key.data.shape = "RECTANGLE"
    key.data.size, key.data.size_y = 0.8, 0.5
    key.data.energy = 25.0
    key.rotation_euler = Vector((0.8, 0.5, -0.75)).to_track_quat("-Z", "Y").to_euler()
    world_colour(scene, (0.6, 0.65, 0.7), 0.15)
    cam = camera((0.2, -1.1, 0.35), (0, 0, 0.17), lens=60)
    cam.data.dof.use_dof = True
    cam.data.dof.focus_object = bpy.data.objects["Bottle"]
    cam.data.dof.aperture_fstop = 2.0
    # A 2-frame animation: the bottle turns 30 degrees.
    scene.frame_start, scene.frame_end = 1, 2
    for name in ("Bottle", "Liquid", "Label", "Cap"):
        ob = bpy.data.objects[name]
        ob.keyframe_insert("rotation_euler", frame=1)
        ob.rotation_euler.z = math.radians(30)
        ob.keyframe_insert("rotation_euler", frame=2)
        ob.rotation_euler.z = 0.0
    scene.frame_set(1)
    return scene


SCENES = {"kitchen": kitchen, "product": product}


def object_masks(scene, w, h):
    """(H, W) int ids of the object each pixel centre's camera ray hits first (-1: none),
    row 0 at the top; Blender's scene.ray_cast on the evaluated depsgraph. Depth of field
    is ignored (the pinhole ray)."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    frame = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    # view_frame: top-right, bottom-right, bottom-left, top-left.
    tr, br, bl, tl = frame
    names = []
    ids = -np.ones((h, w), np.int32)
    for j in range(h):
        v = (j + 0.5) / h
        for i in range(w):
            u = (i + 0.5) / w
            top = tl.lerp(tr, u)
            bot = bl.lerp(br, u)
            p = top.lerp(bot, v)
            hit, _, _, _, ob, _ = scene.ray_cast(dg, origin, (p - origin).normalized())
            if hit:
                if ob.name not in names:
                    names.append(ob.name)
                ids[j, i] = names.index(ob.name)
    return ids, names


def top_masks(scene, w, h, path, surface, classify):
    """object_masks with the upward faces (normal z >= 0.9) of object `surface` split into
    regions: classify(x, n, depsgraph) gives the region's name (e.g. "Table:Caustic") of
    the point x with normal n (mathutils Vectors) that a pixel centre's camera ray meets
    first, or None (the pixel stays the object's). Saves the (H, W) ids to path (.npy)
    and their names to path + ".json"; prints each region's pixel count."""
    import json
    from pathlib import Path
    ids, names = object_masks(scene, w, h)
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    out = ids.copy()
    names = list(names)
    for j, i in zip(*np.nonzero(ids == names.index(surface))):
        p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
        hit, x, n, _, _, _ = scene.ray_cast(dg, origin, (p - origin).normalized())
        if not hit or n.z < 0.9:  # the top only
            continue
        key = classify(x, n, dg)
        if key:
            if key not in names:
                names.append(key)
            out[j, i] = names.index(key)
    np.save(path, out)
    Path(path + ".json").write_text(json.dumps(names))
    print("masks:", {n: int((out == k).sum()) for k, n in enumerate(names)})


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", choices=sorted(SCENES))
    ap.add_argument("mode")
    ap.add_argument("out")
    ap.add_argument("--res", type=int, nargs=2, default=(160, 120))
    ap.add_argument("--save")
    ap.add_argument("--border", type=float, nargs=4)
    ap.add_argument("--animation", action="store_true")
    ap.add_argument("--masks")
    ap.add_argument("--no-pane", action="store_true",
                    help="kitchen: an open window (the glass plane removed)")
    ap.add_argument("--flat", nargs="?", const="Bottle,Liquid",
                    help="product: these objects flat shaded (Shade Flat; default "
                    "Bottle,Liquid)")
    ap.add_argument("--no-dof", action="store_true",
                    help="product: the camera's depth of field off (ours has none)")
    ap.add_argument("--unsupported", action="store_true",
                    help="give the Pot / Cap a Toon BSDF (a node the engine lacks)")
    ap.add_argument("--cancel-after", type=float,
                    help="press Esc (addon.engine.test_break_hook) after this many CPU s")
    ap.add_argument("--set", action="append", default=[],
                    help="photonmap.NAME=VALUE (Python literal)")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = SCENES[a.scene]()
    r = scene.render
    r.resolution_x, r.resolution_y = a.res
    r.resolution_percentage = 100
    if a.masks:
        ids, names = object_masks(scene, *a.res)
        np.save(a.masks, ids)
        with open(a.masks + ".json", "w") as f:
            json.dump(names, f)
        print("masks:", names)
        return
    if a.no_pane:
        bpy.data.objects.remove(bpy.data.objects["WindowPane"])
    if a.flat:
        for name in a.flat.split(","):
            for f in bpy.data.objects[name].data.polygons:
                f.use_smooth = False
    if a.no_dof:
        scene.camera.data.dof.use_dof = False
    if a.unsupported:
        m = new_material("Toon")
        nt = m.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        toon = nt.nodes.new("ShaderNodeBsdfToon")
        nt.links.new(toon.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        assign(bpy.data.objects["Pot" if a.scene == "kitchen" else "Cap"], m)
    if a.cancel_after is not None:
        import addon.engine as ae
        t_cancel = cpu() + a.cancel_after
        ae.test_break_hook = lambda: cpu() > t_cancel
    if a.border:
        r.use_border = True
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = a.border
    if a.mode == "ours":
        r.engine = "PHOTONMAP"
        import ast
        for s in a.set:
            k, v = s.split("=", 1)
            setattr(scene.photonmap, k, ast.literal_eval(v))
    else:
        r.engine = "CYCLES"
        c = scene.cycles
        c.device, c.samples, c.seed = "CPU", int(a.mode.split(":")[1]), 0
        c.use_denoising = c.use_adaptive_sampling = False
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        c.blur_glossy = 0.0
        r.filter_size = 1.5
    if a.save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(a.save))
    s = r.image_settings
    if a.out.endswith(".exr"):
        if hasattr(s, "media_type"):
            s.media_type = "IMAGE"
        s.file_format = "OPEN_EXR"
        s.color_depth = "32"
    else:
        s.file_format = "PNG"
    r.filepath = os.path.abspath(a.out)
    r.use_file_extension = False
    t0 = cpu()
    if a.animation:
        r.filepath = os.path.abspath(a.out) + "_####"
        r.use_file_extension = True
        bpy.ops.render.render(animation=True)
    else:
        bpy.ops.render.render(write_still=True)
    t = cpu() - t0
    if r.engine == "PHOTONMAP":
        import addon.engine as ae
        print("last_render:", {k: v for k, v in ae.last_render.items()
                               if k in ("width", "height", "full_size", "region", "cancelled", "error")})
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"RESULT {a.scene} {a.mode} cpu_s={t:.1f} maxrss_MB={rss:.0f}", flush=True)


if __name__ == "__main__":
    main()
