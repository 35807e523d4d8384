"""Build the paper's example scenes as .blend files (run: make blends).

    .venv/bin/python example_blends/make_blends.py [OUTPUT_DIR]

Figure 3: red sphere on a white floor, rectangular area light.
Figure 6: box with a green and a red wall, a block and a glass sphere, area light on the
          ceiling.
Figure 7: box with a blocker between the light and the left wall (the wall is lit only
          indirectly), reflective floor.
Figure 8: spot light focused through a glass sphere onto the floor: a strong caustic.

Each file is saved compressed at 320x240 with the Photon Mapping engine selected and the
add-on's default settings, so it renders in well under a minute on two cores.
"""
from __future__ import annotations

import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402  (must come first: it provides bmesh and mathutils)
import bmesh  # noqa: E402
from mathutils import Vector  # noqa: E402

from tools.canonical_mesh import canonical_faces  # noqa: E402

WIDTH, HEIGHT = 320, 240


# --- helpers ------------------------------------------------------------------------

def reset():
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights,
                 bpy.data.cameras, bpy.data.worlds, bpy.data.images):
        for block in list(coll):
            coll.remove(block)
    for c in list(bpy.data.collections):
        bpy.data.collections.remove(c)
    scene = bpy.context.scene
    scene.name = "Scene"
    r = scene.render
    try:
        r.engine = "PHOTONMAP"
    except TypeError:
        pass
    r.resolution_x, r.resolution_y, r.resolution_percentage = WIDTH, HEIGHT, 100
    r.film_transparent = False
    r.use_motion_blur = False  # a case that animates turns it on (tools/feature_matrix.py)
    settings = r.image_settings
    if hasattr(settings, "media_type"):  # Blender 5.0: an earlier multilayer EXR limits formats
        settings.media_type = "IMAGE"
    settings.file_format = "PNG"
    scene.view_settings.view_transform = "Standard"
    # The paper's scenes are meant unclamped, as their Cycles references are: Light Paths >
    # Clamping off in Cycles' settings (which the add-on reads when Cycles is there) and ours
    # (Cycles' default Indirect 10 dims Figure 8's caustic focus to ~0.8).
    for source in (getattr(scene, "cycles", None), getattr(scene, "photonmap", None)):
        if source is not None and hasattr(source, "sample_clamp_indirect"):
            source.sample_clamp_direct = source.sample_clamp_indirect = 0.0
    world = bpy.data.worlds.new("World")
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    set_world((0.0, 0.0, 0.0))  # new worlds default to a 0.05 grey background
    return scene


def set_world(color, strength=1.0):
    world = bpy.context.scene.world
    nt = world.node_tree if world.node_tree is not None else None
    if nt is None:
        world.use_nodes = True  # Blender < 5 only: 5.x worlds always have a node tree
        nt = world.node_tree
    bg = next((n for n in nt.nodes if n.type == "BACKGROUND"), None)
    if bg is None:
        bg = nt.nodes.new("ShaderNodeBackground")
        out = nt.nodes.new("ShaderNodeOutputWorld")
        nt.links.new(bg.outputs[0], out.inputs["Surface"])
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    world.color = color


def sky_hdri(width=64, height=32, sun_elevation=35.0, sun_azimuth=-40.0, sun_irradiance=3.0,
             zenith=(0.12, 0.22, 0.55), horizon=(0.55, 0.62, 0.75), ground=(0.18, 0.15, 0.12)):
    """A small procedural equirectangular HDRI (H, W, 3) float32, top row first: a sky
    gradient from `horizon` to `zenith`, a dark ground below the horizon and a sun of one
    texel whose radiance gives `sun_irradiance` W/m^2 (at normal incidence), at
    `sun_elevation` / `sun_azimuth` degrees (azimuth from +X towards +Y; Blender's
    orientation: the image centre looks along +X)."""
    rows = (np.arange(height) + 0.5) / height
    theta = np.pi * rows                       # from the zenith
    elev = np.pi / 2 - theta
    t = np.clip(np.sin(elev), 0.0, 1.0)[:, None] ** 0.5
    sky = (1 - t) * np.asarray(horizon) + t * np.asarray(zenith)
    img = np.where((elev > 0)[:, None], sky, np.asarray(ground)[None, :])
    img = np.repeat(img[:, None, :], width, axis=1)
    # The sun: the texel holding its direction (u = 0.5 - azimuth / 360, v from theta).
    i = min(int((90.0 - sun_elevation) / 180.0 * height), height - 1)
    j = int((0.5 - sun_azimuth / 360.0) % 1.0 * width) % width
    th0, th1 = np.pi * i / height, np.pi * (i + 1) / height
    omega = (np.cos(th0) - np.cos(th1)) * 2 * np.pi / width
    img[i, j] = sun_irradiance / omega * np.array([1.0, 0.93, 0.82])
    return img.astype(np.float32)


def set_world_hdri(pixels, strength=1.0, rotation=None, name="sky"):
    """World = Environment Texture of an (H, W, 3) top-first image (packed in the file)
    x strength, behind a Texture Coordinate -> Mapping pair when `rotation` (XYZ Euler,
    radians) is given."""
    h, w = pixels.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=False, float_buffer=True)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = pixels[::-1]  # Blender rows run bottom to top
    img.pixels.foreach_set(px.ravel())
    img.pack()
    set_world((0.0, 0.0, 0.0), strength)
    world = bpy.context.scene.world
    nt = world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = img
    nt.links.new(env.outputs[0], bg.inputs["Color"])
    if rotation is not None:
        coord = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.inputs["Rotation"].default_value = rotation
        nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        nt.links.new(mapping.outputs[0], env.inputs["Vector"])
    world.color = tuple(float(c) for c in pixels.reshape(-1, 3).mean(axis=0))
    return img


def empty_material(name):
    """A node material with only its Material Output: (material, node tree, output)."""
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    return m, nt, out


def material(name, kind="diffuse", color=(0.8, 0.8, 0.8), roughness=0.5, ior=1.5,
             metallic=0.0, mix=0.5):
    """kind: diffuse | principled | glass | glossy_mix (diffuse + glossy mix shader)."""
    m, nt, out = empty_material(name)
    rgba = (*color, 1.0)
    if kind == "diffuse":
        n = nt.nodes.new("ShaderNodeBsdfDiffuse")
        n.inputs["Color"].default_value = rgba
        nt.links.new(n.outputs[0], out.inputs["Surface"])
    elif kind == "principled":
        n = nt.nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = rgba
        n.inputs["Roughness"].default_value = roughness
        n.inputs["Metallic"].default_value = metallic
        nt.links.new(n.outputs[0], out.inputs["Surface"])
    elif kind == "glass":
        n = nt.nodes.new("ShaderNodeBsdfGlass")
        n.inputs["Color"].default_value = rgba
        n.inputs["Roughness"].default_value = 0.0
        n.inputs["IOR"].default_value = ior
        nt.links.new(n.outputs[0], out.inputs["Surface"])
    elif kind == "glossy_mix":
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = rgba
        g = nt.nodes.new("ShaderNodeBsdfGlossy")
        g.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
        g.inputs["Roughness"].default_value = roughness
        mx = nt.nodes.new("ShaderNodeMixShader")
        mx.inputs[0].default_value = mix
        nt.links.new(d.outputs[0], mx.inputs[1])
        nt.links.new(g.outputs[0], mx.inputs[2])
        nt.links.new(mx.outputs[0], out.inputs["Surface"])
    else:
        raise ValueError(kind)
    m.diffuse_color = rgba
    return m


def add_object(name, mesh, mat=None, location=(0, 0, 0), rotation=(0, 0, 0),
               scale=(1, 1, 1)):
    obj = bpy.data.objects.new(name, mesh)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    if mat is not None:
        mesh.materials.append(mat)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def plane(name, size_x, size_y, mat, location=(0, 0, 0), rotation=(0, 0, 0)):
    hx, hy = size_x / 2, size_y / 2
    me = bpy.data.meshes.new(name)
    me.from_pydata([(-hx, -hy, 0), (hx, -hy, 0), (hx, hy, 0), (-hx, hy, 0)], [],
                   [(0, 1, 2, 3)])
    me.update()
    return add_object(name, me, mat, location, rotation)


def linear_keys(obj):
    """Linear interpolation on every key of obj's action (Blender 4.4+ layered actions
    and the older fcurves alike): a constant speed between keys, for motion blur."""
    action = obj.animation_data.action
    curves = list(getattr(action, "fcurves", []) or [])
    for layer in getattr(action, "layers", []):
        for strip in layer.strips:
            for bag in strip.channelbags:
                curves.extend(bag.fcurves)
    for fc in curves:
        for k in fc.keyframe_points:
            k.interpolation = "LINEAR"


def box(name, sx, sy, sz, mat, location=(0, 0, 0), rotation=(0, 0, 0)):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.scale(bm, vec=(sx, sy, sz), verts=bm.verts)
    bm.to_mesh(me)
    bm.free()
    return add_object(name, me, mat, location, rotation)


def sphere(name, radius, mat, location, segments=48, rings=24):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    bm.to_mesh(me)
    bm.free()
    canonical_faces(me)  # create_uvsphere's face order differs in every process
    me.shade_smooth()
    return add_object(name, me, mat, location)


def mesh_to_volume(name, source, voxel_size=0.1, mat=None):
    """A Volume object whose Mesh to Volume modifier fills the mesh object `source` (its
    "density" grid 1 inside; the source hidden in renders), voxels voxel_size m; `mat` in
    its first slot (None: none, Cycles' default volume)."""
    source.hide_render = True
    vo = bpy.data.objects.new(name, bpy.data.volumes.new(name))
    bpy.context.scene.collection.objects.link(vo)
    mod = vo.modifiers.new("Mesh to Volume", "MESH_TO_VOLUME")
    mod.object = source
    mod.resolution_mode = "VOXEL_SIZE"
    mod.voxel_size = voxel_size
    if mat is not None:
        vo.data.materials.append(mat)
    return vo


def grid_volume(name, grids, lo, hi, res=24, mat=None, colors=None):
    """A Volume object made by Geometry Nodes: a Volume Cube from lo to hi (res voxels a
    side) whose "density" grid ramps linearly along z, with more named grids beside it
    (Store Named Grid, each another Volume Cube's grid): grids {name: (value at lo.z,
    value at hi.z)} (without "density": the volume has no such grid). mat: set by a Set
    Material node (a
    Geometry Nodes volume has no material of its own: Cycles then renders its default
    volume). colors: {name: rgb} constant vector grids on the density's voxels (Field to
    Grid)."""
    vo = bpy.data.objects.new(name, bpy.data.volumes.new(name))
    bpy.context.scene.collection.objects.link(vo)
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    out = nodes.new("NodeGroupOutput")
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(nodes.new("GeometryNodeInputPosition").outputs[0], sep.inputs[0])

    def cube(a, b):
        rng = nodes.new("ShaderNodeMapRange")
        rng.clamp = False
        for key, val in (("From Min", lo[2]), ("From Max", hi[2]), ("To Min", a),
                         ("To Max", b)):
            rng.inputs[key].default_value = val
        links.new(sep.outputs["Z"], rng.inputs["Value"])
        c = nodes.new("GeometryNodeVolumeCube")
        c.inputs["Min"].default_value = lo
        c.inputs["Max"].default_value = hi
        for axis in "XYZ":
            c.inputs[f"Resolution {axis}"].default_value = res
        links.new(rng.outputs["Result"], c.inputs["Density"])
        return c

    vol = cube(*grids.get("density", (1.0, 1.0))).outputs["Volume"]
    for gname, (a, b) in grids.items():
        if gname == "density":
            continue
        get = nodes.new("GeometryNodeGetNamedGrid")
        get.inputs["Name"].default_value = "density"
        links.new(cube(a, b).outputs["Volume"], get.inputs["Volume"])
        store = nodes.new("GeometryNodeStoreNamedGrid")
        store.inputs["Name"].default_value = gname
        links.new(vol, store.inputs["Volume"])
        links.new(get.outputs["Grid"], store.inputs["Grid"])
        vol = store.outputs["Volume"]
    for gname, rgb in (colors or {}).items():
        topo = nodes.new("GeometryNodeGetNamedGrid")
        topo.inputs["Name"].default_value = "density"
        topo.inputs["Remove"].default_value = False
        links.new(vol, topo.inputs["Volume"])
        ftg = nodes.new("GeometryNodeFieldToGrid")
        ftg.grid_items.new("VECTOR", "Color")
        ftg.inputs[1].default_value = rgb
        links.new(topo.outputs["Grid"], ftg.inputs["Topology"])
        store = nodes.new("GeometryNodeStoreNamedGrid")
        store.data_type = "VECTOR_FLOAT"
        store.inputs["Name"].default_value = gname
        links.new(topo.outputs["Volume"], store.inputs["Volume"])
        links.new(ftg.outputs[0], store.inputs["Grid"])
        vol = store.outputs["Volume"]
    if "density" not in grids:
        drop = nodes.new("GeometryNodeGetNamedGrid")
        drop.inputs["Name"].default_value = "density"
        drop.inputs["Remove"].default_value = True
        links.new(vol, drop.inputs["Volume"])
        vol = drop.outputs["Volume"]
    if mat is not None:
        setm = nodes.new("GeometryNodeSetMaterial")
        setm.inputs["Material"].default_value = mat
        links.new(vol, setm.inputs["Geometry"])
        vol = setm.outputs["Geometry"]
    links.new(vol, out.inputs[0])
    vo.modifiers.new("Grids", "NODES").node_group = tree
    return vo


def tuft(name, mat, count, keys, spread, height, lean, radius, seed):
    """A tuft of hair: a Curves object of `count` strands of `keys` points rooted
    uniformly in [-spread, spread]^2 at z 0, rising to `height`, bent sideways by a
    normal(0, lean) offset times (s^2) along the strand (s 0..1), the point attribute
    "radius" going from radius[0] at the root to radius[1] at the tip; seeded."""
    rng = np.random.default_rng(seed)
    curves = bpy.data.hair_curves.new(name)
    curves.add_curves([keys] * count)
    s = np.linspace(0.0, 1.0, keys)
    root = rng.uniform(-spread, spread, (count, 2))
    bend = rng.normal(0.0, lean, (count, 2))
    pos = np.zeros((count, keys, 3))
    pos[..., :2] = root[:, None] + bend[:, None] * (s * s)[None, :, None]
    pos[..., 2] = height * s
    curves.position_data.foreach_set("vector", pos.reshape(-1).astype(np.float32))
    r = curves.attributes.new("radius", "FLOAT", "POINT")
    r.data.foreach_set("value", np.tile(np.linspace(*radius, keys), count).astype(np.float32))
    if mat is not None:
        curves.materials.append(mat)
    obj = bpy.data.objects.new(name, curves)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def camera(location, look_at, fov_deg=40.0):
    cd = bpy.data.cameras.new("Camera")
    cd.sensor_fit = "AUTO"
    cd.sensor_width = 36.0
    cd.lens = cd.sensor_width / (2.0 * math.tan(math.radians(fov_deg) / 2.0))
    cd.clip_start, cd.clip_end = 0.05, 100.0
    obj = bpy.data.objects.new("Camera", cd)
    obj.location = location
    direction = Vector(look_at) - Vector(location)
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.scene.camera = obj
    return obj


def light(name, kind, location, power, look_at=None, rotation=None, color=(1, 1, 1),
          **props):
    ld = bpy.data.lights.new(name, kind)
    ld.energy = power
    ld.color = color
    for k, v in props.items():
        setattr(ld, k, v)
    obj = bpy.data.objects.new(name, ld)
    obj.location = location
    if look_at is not None:
        direction = Vector(look_at) - Vector(location)
        obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    elif rotation is not None:
        obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def cornell_box(white, left, right, size=4.0):
    """Open-front box: x, y in [-s/2, s/2], z in [0, s]; the camera looks along +y."""
    h = size / 2
    plane("Floor", size, size, white, (0, 0, 0))
    plane("Ceiling", size, size, white, (0, 0, size), (math.pi, 0, 0))
    plane("Back", size, size, white, (0, h, h), (math.pi / 2, 0, 0))
    plane("LeftWall", size, size, left, (-h, 0, h), (0, math.pi / 2, 0))
    plane("RightWall", size, size, right, (h, 0, h), (0, -math.pi / 2, 0))


def save(path):
    bpy.context.view_layer.update()
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, check_existing=False)
    print(f"wrote {path} ({os.path.getsize(path) // 1024} KiB)")


# --- the paper's scenes -------------------------------------------------------------

def figure3(path):
    reset()
    red = material("red_plastic", "principled", (0.8, 0.05, 0.05), roughness=0.1)
    white = material("white_plastic_dull", "diffuse", (0.75, 0.75, 0.75))
    plane("Floor", 10, 10, white)
    sphere("Sphere", 1.0, red, (0, 0, 1))
    light("AreaLight", "AREA", (0, 0, 4), 400.0, rotation=(0, 0, 0), shape="RECTANGLE",
          size=2.0, size_y=1.0)
    camera((0, -6, 2.5), (0, 0, 0.8), 40.0)
    save(path)


def figure6(path):
    reset()
    white = material("white", "diffuse", (0.75, 0.75, 0.75))
    red = material("red", "diffuse", (0.75, 0.1, 0.1))
    green = material("green", "diffuse", (0.1, 0.6, 0.1))
    glass = material("glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    cornell_box(white, red, green)
    box("Block", 1.1, 1.1, 2.2, white, (-0.8, 0.7, 1.1), (0, 0, math.radians(20)))
    sphere("GlassSphere", 0.7, glass, (0.85, -0.5, 0.7))
    lamp = light("CeilingLight", "AREA", (0, 0, 3.98), 120.0, rotation=(0, 0, 0),
                 shape="SQUARE", size=1.0)
    lamp.visible_camera = True
    # Higher and looking down a little, so the floor in front of the glass sphere - its
    # caustic - is in view.
    camera((0, -7.6, 2.4), (0, 0, 1.6), 38.0)
    save(path)


def figure7(path):
    reset()
    white = material("white", "diffuse", (0.75, 0.75, 0.75))
    blue = material("blue", "diffuse", (0.15, 0.2, 0.7))
    floor = material("reflective_floor", "glossy_mix", (0.6, 0.6, 0.6), roughness=0.05,
                     mix=0.5)
    h = 2.0
    plane("Floor", 4, 4, floor, (0, 0, 0))
    plane("Ceiling", 4, 4, white, (0, 0, 4), (math.pi, 0, 0))
    plane("Back", 4, 4, white, (0, h, h), (math.pi / 2, 0, 0))
    plane("LeftWall", 4, 4, white, (-h, 0, h), (0, math.pi / 2, 0))
    plane("RightWall", 4, 4, blue, (h, 0, h), (0, -math.pi / 2, 0))
    # A tall panel between the light (right of centre) and the left wall: the left wall
    # gets no direct light, only what bounces off the floor, ceiling and walls.
    box("Blocker", 0.1, 2.6, 3.0, white, (-0.3, 0.2, 1.5))
    light("Light", "AREA", (0.9, 0.0, 3.0), 60.0, look_at=(0.9, 0.0, 0.0), shape="DISK",
          size=0.6)
    camera((0, -7.6, 2.0), (0, 0, 1.8), 38.0)
    save(path)


def figure8(path):
    reset()
    white = material("white", "diffuse", (0.8, 0.8, 0.8))
    glass = material("glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    plane("Floor", 8, 8, white)
    plane("Back", 8, 4, white, (0, 3, 2), (math.pi / 2, 0, 0))
    # Ball lens: effective focal length n*D / (4*(n-1)) = 0.9 m from the centre; with the
    # spot 2.73 m above the centre the image lands 1.27 m below it: on the floor.
    sphere("GlassSphere", 0.6, glass, (0, 0, 1.27), segments=64, rings=32)
    light("Spot", "SPOT", (0, 0, 4.0), 500.0, look_at=(0, 0, 0),
          spot_size=math.radians(30.0), spot_blend=0.1, shadow_soft_size=0.0)
    light("Fill", "POINT", (-2.0, -3.0, 3.5), 60.0, shadow_soft_size=0.5)
    camera((0, -6, 1.6), (0, 0, 0.5), 40.0)
    save(path)


def hdri_sphere(path):
    """Blender's everyday look: objects lit only by an HDRI (a procedural sky with a sun,
    packed in the file), with a rotated Mapping node in front of it."""
    reset()
    white = material("white", "diffuse", (0.8, 0.8, 0.8))
    red = material("red_plastic", "principled", (0.8, 0.08, 0.05), roughness=0.3)
    plane("Floor", 12, 12, white)
    sphere("Ball", 1.0, red, (0, 0, 1))
    box("Block", 0.8, 0.8, 0.8, white, (1.8, 0.9, 0.4), (0, 0, math.radians(25)))
    set_world_hdri(sky_hdri(), 1.0, rotation=(0.0, 0.0, math.radians(60.0)))
    camera((1.0, -6.5, 2.4), (0.4, 0, 0.8), 40.0)
    save(path)


SCENES = {
    "figure3_sphere.blend": figure3,
    "figure6_box.blend": figure6,
    "figure7_blocker.blend": figure7,
    "figure8_caustic.blend": figure8,
    "hdri_sphere.blend": hdri_sphere,
}


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    only = None
    if "--only" in argv:  # --only NAME[,NAME]: rebuild just these files
        k = argv.index("--only")
        only = set(argv[k + 1].split(","))
        del argv[k:k + 2]
    out_dir = argv[0] if argv else HERE
    os.makedirs(out_dir, exist_ok=True)
    import addon
    try:
        addon.register()
    except ValueError:
        pass  # already registered in this process
    for name, build in SCENES.items():
        if only is None or name in only:
            build(os.path.join(out_dir, name))


if __name__ == "__main__":
    main()
