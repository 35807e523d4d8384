"""A new user's scene (session 54 trial): a potted plant on a windowsill in the sun - leaf
cards cut out by an image's alpha, a glazed pot of node-built material, soil with a Bump -
built with bpy as a Blender user builds it (Blender's defaults where a user leaves them),
at both engines' default render settings, rendered with Photon Mapping (the add-on's
defaults) and Cycles.

    PYTHONPATH=. .venv/bin/python bench/newuser54_plant.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--save FILE.blend] [--set NAME=VALUE] [--no-clamp]
        [--cycles-seed S] [--leaves N] [--edge-colour black|green] [--bounces N]
        [--border X0 X1 Y0 Y1] [--opaque-leaves] [--leaf-specular S]

The set (metres; the sill's top at z = 0): a windowsill (a cube 0.9 x 0.3 x 0.04;
Principled (0.8, 0.8, 0.78), roughness 0.4) and a wall 0.15 m behind the pot (a plane
1.6 x 1.0 m; Principled (0.7, 0.66, 0.6), roughness 0.6). A pot (a lathed closed shell,
48 sides, Shade Smooth: radius 55 mm at the foot, 75 mm at the rim, 135 mm tall, its
inside down to 110 mm) whose material is a Mix Shader of a Diffuse BSDF (terracotta
(0.55, 0.2, 0.1)) and a Glossy BSDF (roughness 0.1, the rest the node's defaults) by a
Layer Weight node's Facing output (Blend left at 0.5): a glazed pot, glossier towards its
silhouette. Soil: a disc (cylinder of 48 sides, radius 68 mm, 10 mm) inside it; Principled
(0.06, 0.04, 0.025), roughness 0.9, its Normal from a Bump node (Strength 1, Distance 1,
the node's defaults) of a Noise Texture's Fac (Scale 40, Generated coordinates). Leaves:
--leaves (36) planes of 0.11-0.15 m, their bases round the pot's centre 0.15-0.25 m up,
pointing up and out (a fixed random layout, seed 54), each a Principled (roughness 0.5, the
rest the node's defaults) whose Base Color is an Image Texture's Color and whose Alpha is
its Alpha: a 128 x 128 leaf made with numpy (a pointed ellipse with a midrib and veins,
alpha 1 inside, 0 outside, one anti-aliased pixel between; RGB 0 outside as a user leaves
it: --edge-colour green fills it with the leaf's green), saved as a PNG and packed into
the .blend; the Image Texture at its defaults (Linear, Straight alpha, sRGB), the
material's Blend Mode (render method) left at its default. Light: a Sun (Strength 4,
Angle 3 degrees) from the front left above, throwing the leaves' shadows on the wall and
the sill, and the World a pale blue Background ((0.25, 0.32, 0.45), Strength 1). Camera
50 mm; AgX.
MODE: ours | cycles:SPP (no denoise, no adaptive sampling, seed --cycles-seed; Cycles'
Light Paths at their defaults, read by the add-on). Prints `RESULT mode cpu_s=...
wall_s=...` (bench/newuser44_table.py render) and, for ours, the add-on's warnings,
export and stats. --bounces sets Light Paths > Max Bounces (read by both; 0 renders
direct light only); --border renders only that Render Region (fractions, y from the
bottom; the EXR keeps the full frame, black outside).

--masks writes an (H, W) int array of region ids (row 0 at the top; -1 the world) and a
JSON of names, from Blender's scene.ray_cast through each pixel centre continued through
the leaves' cut-away texels (the leaf image's alpha below 0.5 at the hit's UV):
"Leaf:Sunlit" (the side the camera sees faces the sun and the sun reaches it),
"Leaf:Backlit" (the side seen faces away from the sun), "Leaf:Shaded" (faces the sun, in
another leaf's shadow); "Wall:Sunlit", "Wall:LeafShadow", "Wall:PotShadow" and
"Wall:ShadowEdge" (a pixel whose 3 x 3 neighbours on the wall are not all of its class:
the shadows' outlines), the same for "Sill"; "Pot:Rim" (above 0.12 m) and "Pot", "Soil".
Compare with bench/newuser26_compare.py, bench/newuser45_artefacts.py and
bench/newuser48_flip.py.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402
from mathutils import Matrix, Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import (assign, camera, cube, cylinder, new_material,  # noqa: E402
                              principled, world_colour)
from newuser44_table import arguments, finish, region_arguments  # noqa: E402
from studio48_stilllife import revolve  # noqa: E402

LEAF_N = 128  # the leaf image's size (texels)
SUN_DIR = Vector((0.45, 1.0, -0.75)).normalized()  # the direction the sun's light travels
POT_TOP = 0.135


def leaf_rgba(n=LEAF_N, edge="black"):
    """(n, n, 4) float32 RGBA of a leaf along v (row 0 at the bottom, as Blender stores
    pixels): a pointed ellipse, a lighter midrib and side veins; alpha with one
    anti-aliased texel at the outline. RGB outside the leaf 0 (edge "black") or the leaf's
    green (edge "green")."""
    v, u = (np.mgrid[0:n, 0:n] + 0.5) / n
    half = 0.42 * np.sin(np.pi * np.clip((v - 0.04) / 0.92, 0, 1)) ** 0.9
    half *= np.clip(1.4 - v, 0, 1)  # narrower towards the tip
    d = half - np.abs(u - 0.5)  # > 0 inside, in UV units
    alpha = np.clip(d * n + 0.5, 0.0, 1.0)
    green = np.array([0.16, 0.42, 0.08])
    vein = np.array([0.42, 0.62, 0.22])
    mid = np.exp(-((u - 0.5) * n / 1.2) ** 2)
    side = (np.abs(((v - 0.9 * np.abs(u - 0.5)) * 9.0) % 1.0 - 0.5) < 0.06) * 0.5
    w = np.clip(mid + side, 0, 1)[..., None]
    rgb = green * (1 - w) + vein * w
    rgba = np.zeros((n, n, 4), np.float32)
    rgba[..., :3] = rgb if edge == "green" else rgb * (alpha > 0)[..., None]
    rgba[..., 3] = alpha
    return rgba


def leaf_image(edge="black"):
    """The leaf as a user makes it: numpy pixels into a new image, saved as a PNG, packed."""
    img = bpy.data.images.new("Leaf", LEAF_N, LEAF_N, alpha=True)
    img.pixels.foreach_set(leaf_rgba(edge=edge).ravel())
    path = os.path.join(tempfile.mkdtemp(prefix="newuser54_"), "leaf.png")
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    img.pack()
    return img


def leaf_material(img, alpha=True, specular=0.5):
    m = principled("Leaf", (0.2, 0.5, 0.1), 0.5)
    nt = m.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    p = nt.nodes["Principled BSDF"]
    nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    if alpha:
        nt.links.new(tex.outputs["Alpha"], p.inputs["Alpha"])
    p.inputs["Specular IOR Level"].default_value = specular
    return m


def glazed_pot_material():
    """Mix Shader(Diffuse, Glossy) by Layer Weight Facing (Blend at the node's 0.5)."""
    m = new_material("GlazedPot")
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.55, 0.2, 0.1, 1.0)
    g = nt.nodes.new("ShaderNodeBsdfGlossy")
    g.inputs["Roughness"].default_value = 0.1
    lw = nt.nodes.new("ShaderNodeLayerWeight")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(lw.outputs["Facing"], mix.inputs["Fac"])
    nt.links.new(d.outputs[0], mix.inputs[1])
    nt.links.new(g.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def soil_material():
    """Dark Principled, its Normal a Bump of a Noise Texture (the nodes' defaults)."""
    m = principled("Soil", (0.06, 0.04, 0.025), 0.9)
    nt = m.node_tree
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 40.0
    bump = nt.nodes.new("ShaderNodeBump")
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Principled BSDF"].inputs["Normal"])
    return m


def leaf_layout(count, seed=54):
    """[(matrix_world, size)] of the leaf planes: each plane's +y (the image's v) along
    the leaf, its base near the pot's axis."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(count):
        az = 2 * math.pi * (k / count) + rng.uniform(-0.3, 0.3)
        el = math.radians(rng.uniform(15, 70))
        d = Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)))
        base = Vector((0.02 * math.cos(az), 0.02 * math.sin(az),
                       POT_TOP + rng.uniform(0.02, 0.12)))
        size = rng.uniform(0.11, 0.15)
        side = Vector((0, 0, 1)).cross(d).normalized()
        roll = math.radians(rng.uniform(-35, 35))
        x = side * math.cos(roll) + d.cross(side) * math.sin(roll)
        z = x.cross(d)
        centre = base + d * (0.5 * size)
        m = Matrix((x, d, z)).transposed().to_4x4()
        m.translation = centre
        out.append((m, size))
    return out


def plant_scene(leaves=36, edge="black", alpha=True, specular=0.5):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "AgX"
    cube("Sill", (0, 0.0, -0.02), (0.9, 0.3, 0.04),
         principled("SillPaint", (0.8, 0.8, 0.78), 0.4))
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 0.15, 0.4),
                                     rotation=(math.pi / 2, 0, 0), scale=(1.6, 1.0, 1))
    wall = bpy.context.active_object
    wall.name = "Wall"
    assign(wall, principled("WallPaint", (0.7, 0.66, 0.6), 0.6))
    revolve("Pot", [(0, 0), (0.055, 0), (0.075, 0.125), (0.078, POT_TOP), (0.07, POT_TOP),
                    (0.066, 0.11), (0, 0.11)], glazed_pot_material(), (0, 0, 0))
    cylinder("Soil", 0.068, 0.01, (0, 0, 0.117), soil_material())
    mat = leaf_material(leaf_image(edge), alpha, specular)
    for k, (m, size) in enumerate(leaf_layout(leaves)):
        bpy.ops.mesh.primitive_plane_add(size=1.0)
        o = bpy.context.active_object
        o.name = f"Leaf{k:02d}"
        o.matrix_world = m @ Matrix.Diagonal((size, size, 1, 1))
        assign(o, mat)
    world_colour(scene, (0.25, 0.32, 0.45), 1.0)
    bpy.ops.object.light_add(type="SUN", location=(-0.5, -0.8, 1.0))
    sun = bpy.context.active_object
    sun.name = "Sun"
    sun.data.energy = 4.0
    sun.data.angle = math.radians(3.0)
    sun.rotation_euler = SUN_DIR.to_track_quat("-Z", "Y").to_euler()
    camera((0.05, -0.95, 0.32), (0.0, 0.0, 0.2), lens=50.0)
    return scene


def _leaf_alpha():
    return leaf_rgba()[..., 3]


def _cast(scene, dg, origin, direction, alpha, distance=1e3):
    """The first hit (x, n, object) from origin along direction, passing the leaves'
    cut-away texels (alpha < 0.5 at the plane's UV); (None, None, None) for none."""
    o = origin.copy()
    for _ in range(64):
        hit, x, n, _, ob, mw = scene.ray_cast(dg, o, direction, distance=distance)
        if not hit:
            return None, None, None
        if ob.name.startswith("Leaf"):
            p = mw.inverted() @ x
            u, v = p.x + 0.5, p.y + 0.5
            i = min(max(int(v * LEAF_N), 0), LEAF_N - 1)
            j = min(max(int(u * LEAF_N), 0), LEAF_N - 1)
            if alpha[i, j] < 0.5:
                distance -= (x - o).length + 1e-5
                o = x + direction * 1e-5
                continue
        return x, n, ob
    return None, None, None


def plant_masks(scene, w, h, path):
    """Region ids per pixel centre (module docstring), saved to path and path + '.json'."""
    import json
    from pathlib import Path
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    alpha = _leaf_alpha()
    to_sun = -SUN_DIR
    names, ids = [], -np.ones((h, w), np.int32)
    for j in range(h):
        for i in range(w):
            p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
            d = (p - origin).normalized()
            x, n, ob = _cast(scene, dg, origin, d, alpha)
            if ob is None:
                continue
            name = ob.name
            if name.startswith("Leaf") or name in ("Wall", "Sill"):
                nf = n if n.dot(d) < 0 else -n  # the side the camera sees
                sx, _, sob = _cast(scene, dg, x + nf * 1e-5, to_sun, alpha)
                shadow = sob.name if sob is not None else None
                if name.startswith("Leaf"):
                    name = ("Leaf:Backlit" if nf.dot(to_sun) <= 0 else
                            "Leaf:Sunlit" if shadow is None else "Leaf:Shaded")
                elif shadow is None:
                    name += ":Sunlit"
                elif shadow.startswith("Leaf"):
                    name += ":LeafShadow"
                else:
                    name += ":PotShadow"
            elif name == "Pot" and x.z > 0.12:
                name = "Pot:Rim"
            if name not in names:
                names.append(name)
            ids[j, i] = names.index(name)
    for surface in ("Wall", "Sill"):  # the outlines: a neighbour of another class
        mine = [k for k, nm in enumerate(names) if nm.startswith(surface + ":")]
        on = np.isin(ids, mine)
        pad = np.pad(ids, 1, mode="edge")
        edge = np.zeros_like(on)
        for dj in (-1, 0, 1):
            for di in (-1, 0, 1):
                nb = pad[1 + dj:1 + dj + h, 1 + di:1 + di + w]
                edge |= on & np.isin(nb, mine) & (nb != ids)
        names.append(surface + ":ShadowEdge")
        ids[edge] = len(names) - 1
    np.save(path, ids)
    Path(path + ".json").write_text(json.dumps(names))
    print("masks:", {nm: int((ids == k).sum()) for k, nm in enumerate(names)})


def main():
    ap = arguments(__doc__)
    ap.add_argument("--cycles-seed", type=int, default=0, help="Cycles' seed (default 0)")
    ap.add_argument("--leaves", type=int, default=36)
    ap.add_argument("--edge-colour", choices=("black", "green"), default="black",
                    help="the leaf image's RGB outside the leaf")
    ap.add_argument("--opaque-leaves", action="store_true",
                    help="the image's Alpha left unlinked: square opaque leaf cards")
    ap.add_argument("--leaf-specular", type=float, default=0.5,
                    help="the leaves' Specular IOR Level (the node's 0.5)")
    region_arguments(ap, bounces=True)
    a = ap.parse_args()
    import addon
    addon.register()
    scene = plant_scene(a.leaves, a.edge_colour, not a.opaque_leaves, a.leaf_specular)
    finish(scene, a, plant_masks)


if __name__ == "__main__":
    main()
