"""A new user's three scenes (session s24 trial), built with bpy the way an artist builds
them (bpy.ops primitives, node materials), rendered with Photon Mapping and with Cycles.

    NUMBA_CACHE_DIR=... PYTHONPATH=. .venv/bin/python bench/newuser24_scenes.py \
        SCENE MODE OUT.exr [--res W H] [--save FILE.blend]

SCENE: bathroom (Sun through a window, dim world colour, a glass of water, a chrome tap)
       turntable (generated Image Texture albedo, a normal map, Subsurface, Emission
                  strength, a Noise-mixed pair of Principled; spot + point light)
       corridor  (an L corridor lit by one lamp round the corner: mostly indirect light;
                  collection instances and Geometry Nodes instances)
MODE:  ours | cycles:SPP  (Cycles plain: no denoise, no adaptive, no clamp, seed 0)

Prints one line `RESULT scene mode cpu_s maxrss_MB` after the render (CPU time of this
process, all threads, from resource.getrusage; the build is not counted).
"""
from __future__ import annotations

import argparse
import math
import os
import resource
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402

from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime


def principled(name, color=(0.8, 0.8, 0.8), roughness=0.5, metallic=0.0, **inputs):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Roughness"].default_value = roughness
    p.inputs["Metallic"].default_value = metallic
    for k, v in inputs.items():
        p.inputs[k.replace("_", " ")].default_value = v
    return m


def glass(name, ior=1.33):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["IOR"].default_value = ior
    g.inputs["Roughness"].default_value = 0.0
    nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def assign(obj, mat):
    obj.data.materials.clear()
    obj.data.materials.append(mat)
    return obj


def cube(name, size, loc, mat, scale=(1, 1, 1), rot=(0, 0, 0)):
    bpy.ops.mesh.primitive_cube_add(size=size, location=loc, rotation=rot, scale=scale)
    o = bpy.context.active_object
    o.name = name
    return assign(o, mat)


def world_colour(scene, color, strength=1.0):
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength


def camera(loc, target, lens=35.0):
    bpy.ops.object.camera_add(location=loc)
    cam = bpy.context.active_object
    cam.data.lens = lens
    d = np.subtract(target, loc)
    from mathutils import Vector
    cam.rotation_euler = Vector(d).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = cam
    return cam


def empty_scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    return scene


# --- (a) bathroom corner ---------------------------------------------------------------

def bathroom():
    scene = empty_scene()
    tiles = principled("Tiles", (0.75, 0.78, 0.8), roughness=0.3)
    wallm = principled("Paint", (0.7, 0.65, 0.55), roughness=0.8)
    chrome = principled("Chrome", (0.9, 0.9, 0.9), roughness=0.05, metallic=1.0)
    ceramic = principled("Ceramic", (0.9, 0.9, 0.88), roughness=0.15)
    water = glass("Water", 1.33)
    # Room 3 x 3 x 2.5 m, open towards the camera (-Y); window in the +X wall.
    cube("Floor", 1, (0, 0, -0.05), tiles, scale=(3, 3, 0.1))
    cube("Ceiling", 1, (0, 0, 2.55), wallm, scale=(3, 3, 0.1))
    cube("BackWall", 1, (0, 1.55, 1.25), tiles, scale=(3, 0.1, 2.5))
    cube("LeftWall", 1, (-1.55, 0, 1.25), wallm, scale=(0.1, 3, 2.5))
    # Right wall with a 1.0 x 0.8 m window (centre y=0.3, z=1.5): four boxes round the hole.
    cube("RightWall_low", 1, (1.55, 0, 0.55), wallm, scale=(0.1, 3, 1.1))
    cube("RightWall_high", 1, (1.55, 0, 2.2), wallm, scale=(0.1, 3, 0.7))
    cube("RightWall_front", 1, (1.55, -0.85, 1.5), wallm, scale=(0.1, 1.3, 0.8))
    cube("RightWall_back", 1, (1.55, 1.15, 1.5), wallm, scale=(0.1, 0.7, 0.8))
    # Vanity and basin against the back wall.
    cube("Vanity", 1, (0.2, 1.2, 0.4), ceramic, scale=(1.4, 0.6, 0.8))
    # Tap: a vertical chrome cylinder and a spout (chrome, mirror-like).
    bpy.ops.mesh.primitive_cylinder_add(radius=0.025, depth=0.25, location=(0.2, 1.4, 0.925))
    assign(bpy.context.active_object, chrome).name = "TapStem"
    bpy.ops.mesh.primitive_cylinder_add(radius=0.02, depth=0.18, location=(0.2, 1.31, 1.03),
                                        rotation=(math.pi / 2, 0, 0))
    assign(bpy.context.active_object, chrome).name = "TapSpout"
    bpy.ops.object.shade_smooth()
    # A glass of water on the vanity (solid cylinder of water, smooth shaded).
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=0.04, depth=0.12,
                                        location=(-0.2, 1.1, 0.86))
    g = assign(bpy.context.active_object, water)
    g.name = "GlassOfWater"
    bpy.ops.object.shade_smooth()
    # Sun through the window, low, from +X, dim bluish "HDRI-like" world colour.
    bpy.ops.object.light_add(type="SUN", location=(4, 0, 4),
                             rotation=(0, math.radians(60), 0))
    sun = bpy.context.active_object
    sun.name = "Sun"
    sun.data.energy = 4.0
    sun.data.angle = math.radians(1.0)
    sun.rotation_euler = (math.radians(15), math.radians(60), math.radians(-10))
    world_colour(scene, (0.05, 0.07, 0.1), 1.0)
    camera((-0.9, -1.2, 1.4), (0.3, 1.1, 0.9), lens=28)
    return scene


# --- (b) turntable ---------------------------------------------------------------------

def checker_image(name, n=64):
    img = bpy.data.images.new(name, n, n, alpha=False)
    y, x = np.mgrid[0:n, 0:n]
    c = ((x // 8 + y // 8) % 2).astype(np.float32)
    px = np.ones((n, n, 4), np.float32)
    px[..., 0] = 0.2 + 0.6 * c
    px[..., 1] = 0.3 + 0.2 * c
    px[..., 2] = 0.7 - 0.5 * c
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def bumps_normal_image(name, n=64):
    img = bpy.data.images.new(name, n, n, alpha=False)
    y, x = np.mgrid[0:n, 0:n] / n * 2 * np.pi * 4
    dx, dy = 0.5 * np.cos(x), 0.5 * np.cos(y)
    nrm = np.stack([-dx, -dy, np.ones_like(dx)], -1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    px = np.ones((n, n, 4), np.float32)
    px[..., :3] = nrm * 0.5 + 0.5
    img.pixels.foreach_set(px.ravel())
    img.colorspace_settings.name = "Non-Color"
    img.pack()
    return img


def turntable():
    scene = empty_scene()
    floor = principled("Floor", (0.5, 0.5, 0.5), roughness=0.6)
    bpy.ops.mesh.primitive_plane_add(size=12)
    assign(bpy.context.active_object, floor).name = "Floor"
    # 1. Image Texture albedo on a cube (UVs from the primitive).
    tex = principled("Checker", roughness=0.5)
    nt = tex.node_tree
    it = nt.nodes.new("ShaderNodeTexImage")
    it.image = checker_image("checker")
    nt.links.new(it.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    cube("TexturedCube", 0.8, (-1.2, 0, 0.4), tex, rot=(0, 0, 0.5))
    # 2. Normal map on a sphere.
    bumpy = principled("Bumpy", (0.8, 0.3, 0.2), roughness=0.35)
    nt = bumpy.node_tree
    it = nt.nodes.new("ShaderNodeTexImage")
    it.image = bumps_normal_image("bumps")
    nm = nt.nodes.new("ShaderNodeNormalMap")
    nt.links.new(it.outputs["Color"], nm.inputs["Color"])
    nt.links.new(nm.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Normal"])
    primitive_uv_sphere_add(radius=0.45, location=(0, -0.2, 0.45))
    o = assign(bpy.context.active_object, bumpy)
    o.name = "NormalMappedBall"
    bpy.ops.object.shade_smooth()
    # 3. Subsurface on a monkey.
    skin = principled("Skin", (0.9, 0.6, 0.5), roughness=0.4, Subsurface_Weight=1.0,
                      Subsurface_Scale=0.1)
    bpy.ops.mesh.primitive_monkey_add(size=0.7, location=(1.2, 0.1, 0.45),
                                      rotation=(0, 0, math.radians(-20)))
    o = assign(bpy.context.active_object, skin)
    o.name = "SubsurfaceMonkey"
    bpy.ops.object.shade_smooth()
    # 4. Emission strength on a torus (Principled Emission).
    glow = principled("Glow", (0.1, 0.1, 0.1), roughness=0.5,
                      Emission_Color=(1.0, 0.5, 0.1, 1.0), Emission_Strength=5.0)
    bpy.ops.mesh.primitive_torus_add(location=(0.3, 1.3, 0.25), major_radius=0.35,
                                     minor_radius=0.1)
    assign(bpy.context.active_object, glow).name = "GlowTorus"
    # 5. Mix of two Principled by a Noise texture on a cylinder.
    mix = bpy.data.materials.new("NoiseMix")
    if bpy.app.version < (5, 0, 0):
        mix.use_nodes = True
    nt = mix.node_tree
    p1 = nt.nodes["Principled BSDF"]
    p1.inputs["Base Color"].default_value = (0.1, 0.4, 0.8, 1)
    p1.inputs["Roughness"].default_value = 0.6
    p2 = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p2.inputs["Base Color"].default_value = (0.95, 0.8, 0.4, 1)
    p2.inputs["Metallic"].default_value = 1.0
    p2.inputs["Roughness"].default_value = 0.25
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 6.0
    ms = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(noise.outputs["Fac"], ms.inputs[0])
    nt.links.new(p1.outputs[0], ms.inputs[1])
    nt.links.new(p2.outputs[0], ms.inputs[2])
    nt.links.new(ms.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.ops.mesh.primitive_cylinder_add(radius=0.3, depth=0.9, location=(-0.5, 1.2, 0.45))
    o = assign(bpy.context.active_object, mix)
    o.name = "NoiseMixCylinder"
    bpy.ops.object.shade_smooth()
    # Lights: a key spot and a warm point fill.
    bpy.ops.object.light_add(type="SPOT", location=(-2.5, -2.5, 3.5))
    spot = bpy.context.active_object
    spot.name = "KeySpot"
    spot.data.energy = 1500.0
    spot.data.spot_size = math.radians(60)
    spot.data.spot_blend = 0.3
    spot.data.shadow_soft_size = 0.2
    from mathutils import Vector
    spot.rotation_euler = Vector((2.5, 2.5, -3.3)).to_track_quat("-Z", "Y").to_euler()
    bpy.ops.object.light_add(type="POINT", location=(2.5, -1.0, 2.0))
    pt = bpy.context.active_object
    pt.name = "FillPoint"
    pt.data.energy = 300.0
    pt.data.color = (1.0, 0.85, 0.7)
    pt.data.shadow_soft_size = 0.3
    world_colour(scene, (0.02, 0.02, 0.025), 1.0)
    # Turntable: the camera orbits an empty (2 keyed frames used for the animation test).
    bpy.ops.object.empty_add(location=(0, 0.4, 0.4))
    pivot = bpy.context.active_object
    pivot.name = "Turntable"
    cam = camera((0, -4.0, 2.0), (0, 0.4, 0.4), lens=40)
    cam.parent = pivot
    scene.frame_start, scene.frame_end = 1, 2
    pivot.rotation_euler = (0, 0, 0)
    pivot.keyframe_insert("rotation_euler", frame=1)
    pivot.rotation_euler = (0, 0, math.radians(20))
    pivot.keyframe_insert("rotation_euler", frame=2)
    scene.frame_set(1)
    return scene


# --- (c) dark corridor lit round the corner --------------------------------------------

def corridor():
    scene = empty_scene()
    plaster = principled("Plaster", (0.75, 0.75, 0.72), roughness=0.9)
    wood = principled("Wood", (0.45, 0.28, 0.15), roughness=0.6)
    brass = principled("Brass", (0.9, 0.7, 0.35), roughness=0.3, metallic=1.0)
    # L corridor, 1.6 m wide, 2.6 m high: arm A along +Y (camera), arm B along +X at the end.
    cube("FloorA", 1, (0, 2.5, -0.05), wood, scale=(1.6, 6.6, 0.1))
    cube("FloorB", 1, (3.0, 5.0, -0.05), wood, scale=(4.4, 1.6, 0.1))
    cube("CeilA", 1, (0, 2.5, 2.65), plaster, scale=(1.6, 6.6, 0.1))
    cube("CeilB", 1, (3.0, 5.0, 2.65), plaster, scale=(4.4, 1.6, 0.1))
    cube("WallA_left", 1, (-0.85, 2.5, 1.3), plaster, scale=(0.1, 6.6, 2.6))
    cube("WallA_right", 1, (0.85, 1.65, 1.3), plaster, scale=(0.1, 4.9, 2.6))
    cube("WallEnd", 1, (0.5, 5.85, 1.3), plaster, scale=(2.7, 0.1, 2.6))
    cube("WallB_near", 1, (3.0, 4.15, 1.3), plaster, scale=(4.4, 0.1, 2.6))
    cube("WallB_far", 1, (5.25, 5.0, 1.3), plaster, scale=(0.1, 1.8, 2.6))
    cube("WallA_back", 1, (0, -0.85, 1.3), plaster, scale=(1.8, 0.1, 2.6))
    # The lamp: a point light with a radius, in arm B, out of the camera's sight.
    bpy.ops.object.light_add(type="POINT", location=(4.2, 5.0, 2.0))
    lamp = bpy.context.active_object
    lamp.name = "CorridorLamp"
    lamp.data.energy = 400.0
    lamp.data.color = (1.0, 0.8, 0.55)
    lamp.data.shadow_soft_size = 0.1
    # Collection instances: a brass post in its own (excluded) collection, instanced 4x
    # along arm A by empties.
    posts = bpy.data.collections.new("Posts")
    bpy.context.scene.collection.children.link(posts)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.05, depth=1.0, location=(0, 0, 0.5))
    post = assign(bpy.context.active_object, brass)
    post.name = "BrassPost"
    for c in list(post.users_collection):
        c.objects.unlink(post)
    posts.objects.link(post)
    bpy.context.view_layer.layer_collection.children["Posts"].exclude = True
    for i, y in enumerate((0.8, 1.8, 2.8, 3.8)):
        e = bpy.data.objects.new(f"PostInstance{i}", None)
        e.instance_type = "COLLECTION"
        e.instance_collection = posts
        e.location = (-0.6, y, 0)
        scene.collection.objects.link(e)
    # Geometry Nodes instances: a row of wooden boxes along the right wall of arm A.
    bpy.ops.mesh.primitive_plane_add(size=0.1, location=(0.55, 0, 0))
    host = bpy.context.active_object
    host.name = "BoxRowGN"
    mod = host.modifiers.new("GeometryNodes", "NODES")
    ng = bpy.data.node_groups.new("BoxRow", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi = ng.nodes.new("NodeGroupInput")
    go = ng.nodes.new("NodeGroupOutput")
    line = ng.nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = 5
    line.inputs["Offset"].default_value = (0, 0.8, 0)
    line.inputs["Start Location"].default_value = (0, 0.6, 0.2)
    box = ng.nodes.new("GeometryNodeMeshCube")
    box.inputs["Size"].default_value = (0.4, 0.4, 0.4)
    inst = ng.nodes.new("GeometryNodeInstanceOnPoints")
    setm = ng.nodes.new("GeometryNodeSetMaterial")
    setm.inputs["Material"].default_value = wood
    ng.links.new(line.outputs["Mesh"], inst.inputs["Points"])
    ng.links.new(box.outputs["Mesh"], setm.inputs["Geometry"])
    ng.links.new(setm.outputs["Geometry"], inst.inputs["Instance"])
    ng.links.new(inst.outputs["Instances"], go.inputs[0])
    mod.node_group = ng
    world_colour(scene, (0.0, 0.0, 0.0), 1.0)
    camera((0, 0.0, 1.5), (0.8, 5.0, 1.0), lens=24)
    return scene


SCENES = {"bathroom": bathroom, "turntable": turntable, "corridor": corridor}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", choices=sorted(SCENES))
    ap.add_argument("mode")
    ap.add_argument("out")
    ap.add_argument("--res", type=int, nargs=2, default=(160, 120))
    ap.add_argument("--pct", type=int, default=100)
    ap.add_argument("--save")
    ap.add_argument("--border", type=float, nargs=4)
    ap.add_argument("--animation", action="store_true")
    ap.add_argument("--set", action="append", default=[],
                    help="photonmap.NAME=VALUE (Python literal)")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = SCENES[a.scene]()
    r = scene.render
    r.resolution_x, r.resolution_y = a.res
    r.resolution_percentage = a.pct
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
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"RESULT {a.scene} {a.mode} cpu_s={t:.1f} maxrss_MB={rss:.0f}", flush=True)


if __name__ == "__main__":
    main()
