"""A new user's scene (session 48 trial): a house, a car and a tree on a lawn under
Blender's Sky Texture (sun disc on, no Sun lamp), at both engines' default render
settings, built with bpy as a Blender user builds it (bpy.ops primitives, Shade Smooth,
node materials, images painted into packed Image Textures), rendered with Photon Mapping
(scene.render.engine = 'PHOTONMAP', the add-on's defaults) and with Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser48_garden.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--filter-glossy F] [--cycles-seed S] [--sky-type T] [--no-sun-disc]
        [--drop NAME ...] [--leaves principled|mix] [--transparent-bounces N] [--passes]

The world: a Sky Texture at Blender 5.0's node defaults (Multiple Scattering, sun disc
on, sun size 0.545 degrees) but the sun raised to 40 degrees and turned to light the
house's front from the camera's left, Background Strength 0.15 (the sky's own values
are the real sky's: a user lowers the strength or the exposure); no lamps; AgX.
The ground: a 40 x 40 m lawn (Principled roughness 0.9, Base Color a Noise Texture
through a Color Ramp of two greens) and a paved drive (Principled roughness 0.6,
grey). The house: a 6 x 4.5 x 2.8 m box of brick walls (Base Color from a brick Image
Texture and a Normal Map from the matching normal image, both on the cube's UVs, packed
PNG-like images painted with numpy), a pitched roof (a prism, red Principled roughness
0.55), two windows (thin slabs of Principled roughness 0.02, dark: the glass as users
fake it when the house has no inside) and a door. The car: a body of two smooth-shaded
scaled UV spheres in car paint (Principled red Base Color, Metallic 0.8, Roughness
0.35, Coat Weight 1, Coat Roughness 0.03), dark glossy cabin glass, four rubber wheels.
The tree: a bark trunk and a crown of 60 alpha-mapped leaf cards (1.1 m planes, a
packed RGBA image of leaf clusters: its Alpha into a Mix Shader of a Transparent BSDF
and a Principled BSDF (--leaves mix, the default, as older assets and many tutorials
build it) or into the Principled's Alpha (--leaves principled)); seeded positions.

MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed (0);
Cycles' other settings - Light Paths, clamping, Filter Glossy - at their defaults, which
the add-on reads too).
--drop NAME removes objects whose names start with NAME (an A/B sub-scene).

Prints `RESULT mode cpu_s=... wall_s=...` (this process and its children, from
resource.getrusage; the scene build excluded). --masks writes an (H, W) int array of
object ids (row 0 at the top; -1 the sky) and a JSON of the names: a camera ray passes
a leaf card where the leaf image's alpha is below 0.5, as the renders see it (Blender's
ray_cast alone would count the cards' whole squares), and MASKS_passed.npy the number of
cards each passed (Cycles' transparent bounces); compare with
bench/newuser26_compare.py and bench/newuser45_artefacts.py (relMSE, HDR-FLIP).
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
from newuser26_scenes import (assign, camera, cube, cylinder, new_material,  # noqa: E402
                              principled)
from newuser44_table import arguments, render  # noqa: E402
from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402

LEAF_N = 128  # the leaf image's size in texels


def packed_image(name, px, non_color=False):
    """A packed Image of (n, n, 4) float pixels (row 0 at the bottom, Blender's order)."""
    n = px.shape[0]
    img = bpy.data.images.new(name, n, n, alpha=True)
    img.pixels.foreach_set(px.astype(np.float32).ravel())
    img.pack()
    if non_color:
        img.colorspace_settings.name = "Non-Color"
    return img


def brick_pixels(n=128):
    """(colour, normal) (n, n, 4) images of 4 x 8 bricks a tile: red-brown bricks with a
    seeded tint each, light mortar; the normal map's mortar grooves lean 30 degrees."""
    rng = np.random.default_rng(48)
    y, x = np.mgrid[0:n, 0:n] + 0.5
    rows, bw = n / 8, n / 4
    r = (y // rows).astype(int)
    xs = x + (r % 2) * bw / 2
    c = (xs // bw).astype(int) % 4
    tint = rng.uniform(0.8, 1.15, (8, 4))[r, c]
    fy, fx = (y % rows) / rows, (xs % bw) / bw
    mortar = (fy < 0.1) | (fx < 0.05)
    col = np.ones((n, n, 4))
    col[..., 0] = np.where(mortar, 0.55, 0.45 * tint)
    col[..., 1] = np.where(mortar, 0.53, 0.18 * tint)
    col[..., 2] = np.where(mortar, 0.48, 0.10 * tint)
    # Tangent-space normals: bevels at the bricks' edges lean away from the mortar.
    t = math.sin(math.radians(30))
    nx = np.where(fx < 0.1, -t, np.where(fx > 0.95, t, 0.0)) * ~mortar
    ny = np.where(fy < 0.2, -t, np.where(fy > 0.9, t, 0.0)) * ~mortar
    nz = np.sqrt(1 - nx ** 2 - ny ** 2)
    nrm = np.ones((n, n, 4))
    nrm[..., 0], nrm[..., 1], nrm[..., 2] = nx * 0.5 + 0.5, ny * 0.5 + 0.5, nz * 0.5 + 0.5
    return col, nrm


def leaf_pixels(n=LEAF_N):
    """(n, n, 4) RGBA leaf clusters: 14 seeded ellipses (alpha 1, greens) on alpha 0."""
    rng = np.random.default_rng(7)
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n
    px = np.zeros((n, n, 4))
    for _ in range(14):
        cx, cy = rng.uniform(0.2, 0.8, 2)
        a, b = rng.uniform(0.08, 0.16), rng.uniform(0.03, 0.06)
        th = rng.uniform(0, math.pi)
        u = (x - cx) * math.cos(th) + (y - cy) * math.sin(th)
        v = -(x - cx) * math.sin(th) + (y - cy) * math.cos(th)
        inside = (u / a) ** 2 + (v / b) ** 2 < 1
        g = rng.uniform(0.7, 1.2)
        px[inside] = (0.06 * g, 0.22 * g, 0.03 * g, 1.0)
    return px


def leaves_material(name, img, how="mix"):
    """Leaf cards: the image's Color into a Principled (roughness 0.5); its Alpha into a
    Mix Shader(Transparent, Principled) factor ('mix') or the Principled's Alpha."""
    m = new_material(name)
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    p.inputs["Roughness"].default_value = 0.5
    it = nt.nodes.new("ShaderNodeTexImage")
    it.image = img
    nt.links.new(it.outputs["Color"], p.inputs["Base Color"])
    out = nt.nodes["Material Output"]
    if how == "principled":
        nt.links.new(it.outputs["Alpha"], p.inputs["Alpha"])
        return m
    t = nt.nodes.new("ShaderNodeBsdfTransparent")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(it.outputs["Alpha"], mix.inputs[0])
    nt.links.new(t.outputs[0], mix.inputs[1])
    nt.links.new(p.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def lawn(name):
    """Principled roughness 0.9, Base Color a Noise Texture through a Color Ramp."""
    m = principled(name, (0.1, 0.3, 0.05), 0.9)
    nt = m.node_tree
    nz = nt.nodes.new("ShaderNodeTexNoise")
    nz.inputs["Scale"].default_value = 3.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.05, 0.16, 0.02, 1)
    ramp.color_ramp.elements[1].color = (0.16, 0.32, 0.05, 1)
    nt.links.new(nz.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def brick_wall(name):
    """Principled roughness 0.8: Base Color and a Normal Map from packed images (UV)."""
    m = principled(name, (0.5, 0.2, 0.1), 0.8)
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    col, nrm = brick_pixels()
    ic = nt.nodes.new("ShaderNodeTexImage")
    ic.image = packed_image("Bricks", col)
    inn = nt.nodes.new("ShaderNodeTexImage")
    inn.image = packed_image("BricksNormal", nrm, non_color=True)
    nm = nt.nodes.new("ShaderNodeNormalMap")
    mp = nt.nodes.new("ShaderNodeMapping")  # the bricks 6 times over a face's UVs
    mp.inputs["Scale"].default_value = (6.0, 6.0, 1.0)
    tc = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(tc.outputs["UV"], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], ic.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], inn.inputs["Vector"])
    nt.links.new(ic.outputs["Color"], p.inputs["Base Color"])
    nt.links.new(inn.outputs["Color"], nm.inputs["Color"])
    nt.links.new(nm.outputs["Normal"], p.inputs["Normal"])
    return m


def prism(name, loc, length, width, height, mat):
    """A pitched roof: a triangular prism along x, ridge at loc's z + height."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    ends = []
    for x in (-length / 2, length / 2):
        ends.append([bm.verts.new((x, -width / 2, 0)), bm.verts.new((x, width / 2, 0)),
                     bm.verts.new((x, 0, height))])
    a, b = ends
    bm.faces.new(a)
    bm.faces.new(list(reversed(b)))
    for k in range(3):
        bm.faces.new((a[k], b[k], b[(k + 1) % 3], a[(k + 1) % 3]))
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    bm.to_mesh(me)
    bm.free()
    o = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(o)
    o.location = loc
    return assign(o, mat)


def sphere(name, loc, scale, mat):
    primitive_uv_sphere_add(segments=32, ring_count=16, location=loc,
                                         scale=scale)
    o = bpy.context.active_object
    o.name = name
    bpy.ops.object.shade_smooth()
    return assign(o, mat)


def sky_world(scene, strength=0.15, elevation=40.0, rotation=-60.0, sky_type=None,
              sun_disc=True):
    """The World: a Sky Texture (the node's defaults but the sun's place) into the
    Background."""
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    nt = w.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    if sky_type:
        sky.sky_type = sky_type
    sky.sun_disc = sun_disc
    sky.sun_elevation = math.radians(elevation)
    sky.sun_rotation = math.radians(rotation)
    bg = nt.nodes["Background"]
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    return w


def garden_scene(leaves="mix", sky_type=None, sun_disc=True, drop=()):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    # Ground.
    bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 0, 0))
    assign(bpy.context.active_object, lawn("Lawn")).name = "Lawn"
    cube("Drive", (1.2, -1.0, 0.01), (3.0, 9.0, 0.02), principled("Paving", (0.35, 0.34, 0.32), 0.6))
    # House: brick walls, a roof, windows, a door.
    walls = brick_wall("Brick")
    cube("House", (0, 6.0, 1.4), (6.0, 4.5, 2.8), walls)
    prism("Roof", (0, 6.0, 2.8), 6.6, 5.1, 1.6, principled("RoofTiles", (0.35, 0.07, 0.04), 0.55))
    window = principled("WindowGlass", (0.03, 0.035, 0.04), 0.02)
    for i, x in enumerate((-1.8, 1.9)):
        cube(f"Window{i}", (x, 3.74, 1.5), (1.1, 0.04, 1.0), window)
    cube("Door", (0.1, 3.74, 1.0), (0.9, 0.04, 2.0), principled("DoorPaint", (0.05, 0.12, 0.3), 0.4))
    # Car in car paint on the drive.
    paint = principled("CarPaint", (0.5, 0.02, 0.02), 0.35, metallic=0.8,
                       Coat_Weight=1.0, Coat_Roughness=0.03)
    sphere("CarBody", (1.2, 0.5, 0.62), (1.0, 2.2, 0.42), paint)
    sphere("CarCabin", (1.2, 0.3, 0.95), (0.78, 1.15, 0.38),
           principled("CarGlass", (0.02, 0.02, 0.025), 0.05))
    rubber = principled("Rubber", (0.03, 0.03, 0.03), 0.9)
    for i, (x, y) in enumerate([(0.28, -0.85), (2.12, -0.85), (0.28, 1.85), (2.12, 1.85)]):
        bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.33, depth=0.22,
                                            location=(x, y, 0.33),
                                            rotation=(0, math.radians(90), 0))
        wh = bpy.context.active_object
        wh.name = f"Wheel{i}"
        bpy.ops.object.shade_smooth()
        assign(wh, rubber)
    # Tree: a trunk and a crown of leaf cards.
    cylinder("Trunk", 0.14, 3.0, (-2.4, -0.5, 1.5), principled("Bark", (0.12, 0.08, 0.05), 0.9),
             vertices=16)
    leaf_mat = leaves_material("Leaves", packed_image("LeafClusters", leaf_pixels()), leaves)
    rng = np.random.default_rng(48)
    for k in range(60):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        c = np.array((-2.4, -0.5, 3.3)) + d * rng.uniform(0.3, 1.3) * (1.0, 1.0, 0.8)
        bpy.ops.mesh.primitive_plane_add(size=1.1, location=tuple(c),
                                         rotation=tuple(rng.uniform(0, math.pi, 3)))
        o = bpy.context.active_object
        o.name = f"Leaves{k:02d}"
        assign(o, leaf_mat)
    for name in drop:
        for o in [o for o in bpy.data.objects if o.name.startswith(name)]:
            bpy.data.objects.remove(o)
    sky_world(scene, sky_type=sky_type, sun_disc=sun_disc)
    camera((4.0, -7.5, 1.6), (-0.6, 3.0, 1.5), lens=30.0)
    return scene


def leaf_alpha_at(ob, loc):
    """The leaf image's alpha where a world-space point lies on leaf card ob (a plane of
    size 1.1: local x, y in -0.55..0.55, UVs 0..1 across)."""
    p = ob.matrix_world.inverted() @ loc
    u, v = p.x / 1.1 + 0.5, p.y / 1.1 + 0.5
    i = min(max(int(u * LEAF_N), 0), LEAF_N - 1)
    j = min(max(int(v * LEAF_N), 0), LEAF_N - 1)
    return LEAF_PX[j, i, 3]


LEAF_PX = leaf_pixels()


def garden_masks(scene, w, h):
    """((H, W) ids of the object each pixel centre sees, passing leaf cards where the
    image's alpha is below 0.5 (every leaf card is one object 'Leaves'), names, (H, W)
    the cards passed on the way: transparent bounces, as Cycles counts them)."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin0 = cam.matrix_world.translation
    names, ids = [], -np.ones((h, w), np.int32)
    passed = np.zeros((h, w), np.int32)
    for j in range(h):
        for i in range(w):
            p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
            d, origin = (p - origin0).normalized(), origin0
            for _ in range(64):
                hit, loc, _, _, ob, _ = scene.ray_cast(dg, origin, d)
                if not hit:
                    break
                if ob.name.startswith("Leaves") and leaf_alpha_at(ob, loc) < 0.5:
                    origin = loc + d * 1e-4
                    passed[j, i] += 1
                    continue
                name = "Leaves" if ob.name.startswith("Leaves") else ob.name
                if name not in names:
                    names.append(name)
                ids[j, i] = names.index(name)
                break
    return ids, names, passed


def main():
    ap = arguments()
    ap.add_argument("--filter-glossy", type=float,
                    help="Light Paths > Caustics > Filter Glossy (Cycles' default 1)")
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--leaves", default="mix", choices=("mix", "principled"))
    ap.add_argument("--sky-type", help="the Sky Texture's sky_type (default: the node's)")
    ap.add_argument("--no-sun-disc", action="store_true")
    ap.add_argument("--drop", nargs="*", default=[])
    ap.add_argument("--passes", action="store_true",
                    help="a multilayer EXR with the light passes (Diffuse / Glossy / "
                         "Transmission Direct, Indirect, Color; Emission; Environment): "
                         "bench/newuser46_passes.py compares them per object")
    ap.add_argument("--transparent-bounces", type=int,
                    help="Light Paths > Max Bounces > Transparent (Cycles' default 8)")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = garden_scene(a.leaves, a.sky_type, not a.no_sun_disc, a.drop)
    if a.filter_glossy is not None:
        scene.cycles.blur_glossy = a.filter_glossy
    if a.transparent_bounces is not None:
        scene.cycles.transparent_max_bounces = a.transparent_bounces
    if a.masks:
        scene.render.resolution_x, scene.render.resolution_y = a.res
        ids, names, passed = garden_masks(scene, *a.res)
        np.save(a.masks, ids)
        np.save(a.masks[:-4] + "_passed.npy", passed)
        Path(a.masks + ".json").write_text(json.dumps(names))
        return print("masks:", names, [int((ids == k).sum()) for k in range(len(names))])
    if a.passes:
        vl = scene.view_layers[0]
        for k in ("diffuse", "glossy", "transmission"):
            for t in ("direct", "indirect", "color"):
                setattr(vl, f"use_pass_{k}_{t}", True)
        vl.use_pass_emit = vl.use_pass_environment = True
    render(scene, a)


if __name__ == "__main__":
    main()
