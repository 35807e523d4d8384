"""A new user's scene (session 48 trial): a studio still life on a curved backdrop, lit
only by an HDRI (an Environment Texture of a small equirectangular .hdr written with
numpy: a bright softbox rectangle and dim surroundings) and one large Area light, at both
engines' default render settings, built with bpy as a Blender user builds it (bpy.ops
primitives, lathed profiles, a Subdivision Surface modifier, Shade Smooth, node
materials, images painted with numpy into packed Image Textures), rendered with Photon
Mapping (scene.render.engine = 'PHOTONMAP', the add-on's defaults) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/studio48_stilllife.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--filter-glossy F] [--cycles-seed S] [--drop NAME ...] [--only area|hdri]
        [--passes] [--hdr FILE.hdr] [--candle-flat-caps]

The backdrop: a bent plane (a floor 1.6 m deep, a quarter circle of radius 0.5 m, a
wall 1.5 m high; 4 m wide; Shade Smooth), Principled grey roughness 0.5. The world: an
Environment Texture of a 256 x 128 equirectangular Radiance .hdr (RGBE, written with
numpy; --hdr names the file, default /tmp/studio48/studio.hdr): surroundings of
radiance 0.06-0.12 (a warm grey, lighter above the horizon), a softbox rectangle of
radiance 30 (36 x 24 degrees) to the camera's front left, 35 degrees up. An Area light
(square 1 m, 40 W) to the front right, 1.4 m up, aimed at the set. AgX.
On the backdrop's floor: a crate (a 0.22 m cube on its default UV map; Base Color, Roughness and
Metallic maps and a tangent-space Normal Map from 64 x 64 packed images painted with
numpy: wooden planks, metal bands, grooves), a velvet cushion (a cube under a
Subdivision Surface modifier, Principled Sheen Weight 1, Sheen Roughness 0.3), a ceramic
cup with a handle (lathed, Principled white, Coat Weight 1, Coat Roughness 0.03), a
brushed-metal kettle (lathed, spout and handle; Principled Metallic 1, Roughness 0.3,
Anisotropic 0.8; the default radial tangent), a standing wine bottle (a lathed glass
shell 3 mm thick, Glass BSDF pale green, IOR 1.5) holding red wine (a lathed body 0.5 mm
inside the shell's inner wall, Glass BSDF IOR 1.33 and Volume Absorption, colour
(0.8, 0.05, 0.1), density 20), a candle (a cylinder, Principled cream, Subsurface
Weight 1, the node's Radius and Scale; Shade Smooth, so the flat caps take the rim's
leaning vertex normals unless --candle-flat-caps).
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed (0);
Cycles' other settings - Light Paths, clamping, Filter Glossy - at their defaults, which
the add-on reads too).
--drop NAME removes objects whose names start with NAME (an A/B sub-scene); --only area
keeps the Area light (the World black), --only hdri the World (the Area light removed).

Prints `RESULT mode cpu_s=... wall_s=...` (this process and its children, from
resource.getrusage; the scene build excluded). --masks writes an (H, W) int array of
object ids (row 0 at the top; -1 the world) and a JSON of the names (Blender's
scene.ray_cast through each pixel centre; the liquid seen through the bottle counts as
the bottle); compare with bench/newuser26_compare.py, bench/newuser45_artefacts.py and
bench/newuser48_flip.py.
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
from newuser26_scenes import assign, camera, cube, cylinder, new_material, principled  # noqa: E402
from newuser44_table import arguments, render  # noqa: E402

HDR_W, HDR_H = 256, 128


def studio_pixels(w=HDR_W, h=HDR_H):
    """(h, w, 3) float radiance of the equirectangular studio, row 0 at the top (v = 1):
    dim warm-grey surroundings (0.06 below the horizon to 0.12 at the zenith) and a
    softbox rectangle of radiance 30, 36 degrees wide and 24 high, centred on the
    direction (-0.6, -0.8) in azimuth, 35 degrees up. Blender's equirectangular mapping
    (Cycles' direction_to_equirectangular): u = atan2(y, -x) / 2 pi + 0.5,
    v = atan2(z, hypot(x, y)) / pi + 0.5."""
    u = (np.arange(w) + 0.5) / w
    v = 1.0 - (np.arange(h) + 0.5) / h
    phi = (u - 0.5) * 2 * math.pi  # atan2(y, -x)
    theta = (v - 0.5) * math.pi  # elevation
    up = np.clip(np.sin(theta), 0, 1)[:, None]
    px = np.empty((h, w, 3))
    base = 0.06 + 0.06 * up
    px[...] = base[..., None] * np.array([1.0, 0.95, 0.85])
    c_phi = math.atan2(-0.8, 0.6)  # the direction (-0.6, -0.8): atan2(y, -x)
    c_el = math.radians(35)
    dphi = (phi[None, :] - c_phi + math.pi) % (2 * math.pi) - math.pi
    box = (np.abs(dphi) < math.radians(18)) & (np.abs(theta[:, None] - c_el) < math.radians(12))
    px[box] = 30.0
    return px


def write_hdr(path, px):
    """A Radiance .hdr (RGBE, flat scanlines) of (h, w, 3) float radiance, row 0 the top."""
    h, w, _ = px.shape
    m = px.max(-1)
    e = np.zeros((h, w), np.int32)
    mant, e_ = np.frexp(m)
    ok = m > 1e-32
    e[ok] = e_[ok]
    scale = np.where(ok, mant * 256.0 / np.maximum(m, 1e-32), 0.0)
    rgbe = np.zeros((h, w, 4), np.uint8)
    rgbe[..., :3] = np.clip(px * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(ok, e + 128, 0).astype(np.uint8)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
        f.write(f"-Y {h} +X {w}\n".encode())
        f.write(rgbe.tobytes())


def revolve(name, profile, mat, loc, steps=48):
    """A closed solid of revolution about z from (r, z) pairs; points with r = 0 are
    single vertices on the axis (triangle fans); Shade Smooth."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    rings = []
    for r, z in profile:
        if r == 0:
            rings.append([bm.verts.new((0, 0, z))])
        else:
            rings.append([bm.verts.new((r * math.cos(2 * math.pi * k / steps),
                                        r * math.sin(2 * math.pi * k / steps), z))
                          for k in range(steps)])
    for a, b in zip(rings[:-1], rings[1:]):
        for k in range(steps):
            q = [a[k % len(a)], a[(k + 1) % len(a)], b[(k + 1) % len(b)], b[k % len(b)]]
            q = [v for i, v in enumerate(q) if v not in q[:i]]
            bm.faces.new(q)
    if len(rings[0]) > 1:
        bm.faces.new(list(reversed(rings[0])))
    if len(rings[-1]) > 1:
        bm.faces.new(rings[-1])
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    bm.to_mesh(me)
    bm.free()
    o = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(o)
    o.location = loc
    for p in me.polygons:
        p.use_smooth = True
    return assign(o, mat)


def backdrop(name, mat, depth=1.6, radius=0.5, height=1.5, width=4.0, y0=-1.0, arc=12):
    """A bent plane: the floor from y0 to y0 + depth, a quarter circle, the wall; smooth."""
    prof = [(y0, 0.0), (y0 + depth, 0.0)]
    for k in range(1, arc + 1):
        a = 0.5 * math.pi * k / arc
        prof.append((y0 + depth + radius * math.sin(a), radius * (1 - math.cos(a))))
    prof.append((prof[-1][0], radius + height))
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    left = [bm.verts.new((-width / 2, y, z)) for y, z in prof]
    right = [bm.verts.new((width / 2, y, z)) for y, z in prof]
    for k in range(len(prof) - 1):
        bm.faces.new((left[k], right[k], right[k + 1], left[k + 1]))
    bm.to_mesh(me)
    bm.free()
    o = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(o)
    for p in me.polygons:
        p.use_smooth = True
    if o.data.polygons[0].normal.z < 0:
        me.flip_normals()
    return assign(o, mat)


def packed_image(name, px, non_color=False):
    """A packed Image of (n, n, 4) float pixels (row 0 at the bottom, Blender's order)."""
    n = px.shape[0]
    img = bpy.data.images.new(name, n, n, alpha=True)
    img.pixels.foreach_set(px.astype(np.float32).ravel())
    img.pack()
    if non_color:
        img.colorspace_settings.name = "Non-Color"
    return img


def crate_maps(n=64):
    """(base colour, roughness, metallic, normal) (n, n, 4) images: four wooden planks
    (seeded brown tints, grain stripes) between metal bands along the edges; the planks'
    edges bevel 25 degrees in the normal map."""
    rng = np.random.default_rng(48)
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n
    band = (x < 0.1) | (x > 0.9) | (y < 0.1) | (y > 0.9)
    plank = np.clip(((y - 0.1) / 0.2).astype(int), 0, 3)
    fy = ((y - 0.1) / 0.2) % 1.0
    tint = rng.uniform(0.8, 1.2, 4)[plank]
    grain = 0.85 + 0.15 * np.sin(40 * x + 3 * plank)
    col = np.ones((n, n, 4))
    col[..., 0] = np.where(band, 0.55, 0.42 * tint * grain)
    col[..., 1] = np.where(band, 0.56, 0.25 * tint * grain)
    col[..., 2] = np.where(band, 0.58, 0.12 * tint * grain)
    rough = np.ones((n, n, 4))
    rough[..., :3] = np.where(band, 0.25, 0.7)[..., None]
    metal = np.ones((n, n, 4))
    metal[..., :3] = np.where(band, 1.0, 0.0)[..., None]
    t = math.sin(math.radians(25))
    ny = np.where(fy < 0.08, -t, np.where(fy > 0.92, t, 0.0)) * ~band
    nz = np.sqrt(1 - ny ** 2)
    nrm = np.ones((n, n, 4))
    nrm[..., 0], nrm[..., 1], nrm[..., 2] = 0.5, ny * 0.5 + 0.5, nz * 0.5 + 0.5
    return col, rough, metal, nrm


def crate_material(name):
    """Principled: Base Color, Roughness, Metallic and a Normal Map from packed images."""
    m = principled(name)
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    col, rough, metal, nrm = crate_maps()
    tex = {}
    for key, px, nc in (("col", col, False), ("rough", rough, True), ("metal", metal, True),
                        ("nrm", nrm, True)):
        it = nt.nodes.new("ShaderNodeTexImage")
        it.image = packed_image(f"Crate_{key}", px, nc)
        tex[key] = it
    nm = nt.nodes.new("ShaderNodeNormalMap")
    nt.links.new(tex["col"].outputs["Color"], p.inputs["Base Color"])
    nt.links.new(tex["rough"].outputs["Color"], p.inputs["Roughness"])
    nt.links.new(tex["metal"].outputs["Color"], p.inputs["Metallic"])
    nt.links.new(tex["nrm"].outputs["Color"], nm.inputs["Color"])
    nt.links.new(nm.outputs["Normal"], p.inputs["Normal"])
    return m


def glass_bsdf(name, color=(1, 1, 1), ior=1.5, absorb=None):
    """A Glass BSDF (roughness 0); absorb = (colour, density): a Volume Absorption on the
    Material Output's Volume."""
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Color"].default_value = (*color, 1)
    g.inputs["IOR"].default_value = ior
    g.inputs["Roughness"].default_value = 0.0
    out = nt.nodes["Material Output"]
    nt.links.new(g.outputs[0], out.inputs["Surface"])
    if absorb:
        va = nt.nodes.new("ShaderNodeVolumeAbsorption")
        va.inputs["Color"].default_value = (*absorb[0], 1)
        va.inputs["Density"].default_value = absorb[1]
        nt.links.new(va.outputs[0], out.inputs["Volume"])
    return m


def studio_world(scene, hdr_path):
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    nt = w.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdr_path)
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = 1.0
    return w


def studio_scene(hdr_path, drop=(), only=None, flat_caps=False):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    backdrop("Backdrop", principled("BackdropPaper", (0.6, 0.6, 0.6), 0.5))
    # The crate: a cube on its default UV map.
    cube("Crate", (-0.42, 0.08, 0.11), (0.22, 0.22, 0.22), crate_material("CrateMat"))
    bpy.context.active_object.rotation_euler.z = math.radians(20)
    # The velvet cushion, behind on the right.
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0.3, 0.3, 0.07),
                                    scale=(0.42, 0.42, 0.16),
                                    rotation=(0, 0, math.radians(-12)))
    cu = bpy.context.active_object
    cu.name = "Cushion"
    sub = cu.modifiers.new("Subdivision", "SUBSURF")
    sub.levels = sub.render_levels = 2
    bpy.ops.object.shade_smooth()
    assign(cu, principled("Velvet", (0.35, 0.03, 0.08), 0.8, Sheen_Weight=1.0,
                          Sheen_Roughness=0.3))
    # The ceramic cup and its handle.
    cup = principled("CupGlaze", (0.85, 0.85, 0.82), 0.5, Coat_Weight=1.0,
                     Coat_Roughness=0.03)
    revolve("Cup", [(0, 0), (0.035, 0), (0.04, 0.006), (0.045, 0.085), (0.043, 0.09),
                    (0.04, 0.086), (0.037, 0.012), (0, 0.012)], cup, (0.2, -0.25, 0.0))
    bpy.ops.mesh.primitive_torus_add(major_radius=0.025, minor_radius=0.006,
                                     location=(0.2 + 0.05, -0.25, 0.045),
                                     rotation=(math.radians(90), 0, 0))
    h = bpy.context.active_object
    h.name = "CupHandle"
    bpy.ops.object.shade_smooth()
    assign(h, cup)
    # The brushed-metal kettle: body, lid knob, spout, handle.
    steel = principled("BrushedSteel", (0.8, 0.8, 0.8), 0.3, metallic=1.0, Anisotropic=0.8)
    revolve("Kettle", [(0, 0), (0.1, 0), (0.115, 0.015), (0.12, 0.07), (0.112, 0.13),
                       (0.08, 0.175), (0.045, 0.19), (0.04, 0.2), (0.012, 0.205),
                       (0.012, 0.225), (0, 0.228)], steel, (-0.15, 0.05, 0.0))
    bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.014, depth=0.14,
                                        location=(-0.15 - 0.15, 0.05, 0.12),
                                        rotation=(0, math.radians(-50), 0))
    sp = bpy.context.active_object
    sp.name = "KettleSpout"
    bpy.ops.object.shade_smooth()
    assign(sp, steel)
    bpy.ops.mesh.primitive_torus_add(major_radius=0.08, minor_radius=0.01,
                                     location=(-0.15, 0.05, 0.2),
                                     rotation=(math.radians(90), 0, 0))
    kh = bpy.context.active_object
    kh.name = "KettleHandle"
    bpy.ops.object.shade_smooth()
    assign(kh, steel)
    # The wine bottle: a glass shell 3 mm thick and the wine 0.5 mm inside it.
    outer = [(0.037, 0.0), (0.037, 0.2), (0.03, 0.23), (0.014, 0.26), (0.013, 0.32)]
    inner = [(max(r - 0.003, 0.0), z + (0.004 if k == 0 else 0.0)) for k, (r, z)
             in enumerate(outer)]
    shell = [(0, 0)] + outer + [(0.01, 0.32)] + list(reversed(inner)) + [(0, 0.004)]
    revolve("Bottle", shell, glass_bsdf("BottleGlass", (0.75, 0.9, 0.75)), (0.06, -0.05, 0))
    wine = [(0, 0.0045), (0.0335, 0.0045), (0.0335, 0.17), (0, 0.17)]
    revolve("Wine", wine, glass_bsdf("Wine", ior=1.33, absorb=((0.8, 0.05, 0.1), 20.0)),
            (0.06, -0.05, 0))
    # The candle.
    candle = cylinder("Candle", 0.035, 0.14, (0.42, -0.18, 0.07),
                      principled("Wax", (0.9, 0.82, 0.65), 0.4, Subsurface_Weight=1.0),
                      vertices=48)
    if flat_caps:  # the caps' own normals (a user's Shade Auto Smooth / Mark Sharp fix)
        for poly in candle.data.polygons:
            if abs(poly.normal.z) > 0.9:
                poly.use_smooth = False
    # Lights: the World's HDRI and one large Area light.
    studio_world(scene, hdr_path)
    bpy.ops.object.light_add(type="AREA", location=(1.1, -0.9, 1.4))
    area = bpy.context.active_object
    area.name = "AreaLight"
    area.data.energy = 40.0
    area.data.size = 1.0
    area.rotation_euler = (Vector((0.0, 0.0, 0.1)) - area.location).to_track_quat(
        "-Z", "Y").to_euler()
    if only == "area":
        bg = scene.world.node_tree.nodes["Background"]
        bg.inputs["Strength"].default_value = 0.0
    elif only == "hdri":
        bpy.data.objects.remove(area)
    for name in drop:
        for o in [o for o in bpy.data.objects if o.name.startswith(name)]:
            bpy.data.objects.remove(o)
    camera((0.0, -1.9, 0.6), (0.0, 0.05, 0.12), lens=60.0)
    return scene


def main():
    ap = arguments()
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Caustics > Filter Glossy (Cycles' default 1)")
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--only", choices=("area", "hdri"))
    ap.add_argument("--hdr", default="/tmp/studio48/studio.hdr")
    ap.add_argument("--candle-flat-caps", action="store_true",
                    help="the candle's two caps flat-shaded (the side stays smooth)")
    ap.add_argument("--passes", action="store_true",
                    help="a multilayer EXR with the light passes (Diffuse / Glossy / "
                         "Transmission Direct, Indirect, Color; Emission; Environment): "
                         "bench/newuser46_passes.py compares them per object")
    a = ap.parse_args()
    write_hdr(a.hdr, studio_pixels())
    import addon
    addon.register()
    scene = studio_scene(a.hdr, a.drop, a.only, a.candle_flat_caps)
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
