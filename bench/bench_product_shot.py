"""Issue 14's product shot (product29): ours against Cycles at equal CPU time, and where our
error comes from (per object, per pass, the pixels far above the reference).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_product_shot.py [--spp 128] [--seeds 0,1]
        [--cycles 256,768] [--ref 4096] [--size 160x120] [--lift 0] [--set NAME=VALUE ...]

The scene (`build`, in bpy as a user builds it): a seamless Principled backdrop (a floor
sweeping up into a wall, roughness 0.5), bevelled gold text (a Text object, extrude 0.1,
bevel depth 0.02, converted to a mesh and shaded smooth; Principled Metallic 1, roughness
0.25), two balls of a Mix Shader 0.5 of Diffuse and Glossy (roughness 0.1), a clear glass
bottle (a smooth-shaded 48-sided cylinder, Principled Transmission 1, IOR 1.45) standing
on the floor, a 1 x 0.6 m rectangle key light 45 degrees up, a rim spot light of radius
0.1 m, and a world colour of strength 0.3. --lift raises the bottle off the floor (m):
standing on it, its bottom cap lies in the floor's plane (docs/accuracy.md "product29").

The reference is Cycles at --ref spp (no denoising, adaptive sampling, clamping or glossy
blur; 32 bounces; the 1-pixel box filter of tools/accuracy_scenes), cached in $TMPDIR.
Ours renders at the add-on's defaults (engine.render on the add-on's export) but for
--spp and --set. Per render: CPU s (time.process_time of this process, every thread),
mean HDR-FLIP, relMSE, mean over the reference's, the pixels whose luminance is over 10x
the reference's (or 0.01); then per object (the first surface of the pixel centre's
camera ray, Blender's scene.ray_cast) the luminance ratio, its share of the image's
relMSE and its mean FLIP. With two or more seeds of ours: relMSE split into noise
(the seeds' difference) and bias^2, and the noise by pass (direct, indirect, caustic,
specular: the specular pass is every light that reaches the camera after a glossy or
glass bounce).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)

import accuracy_scenes as A  # noqa: E402  (needs the bpy wheel)
import bpy  # noqa: E402

mb = A.mb
GOLD = (1.0, 0.766, 0.336)
LUM = np.array([0.2126, 0.7152, 0.0722])
PASSES = ("direct", "indirect", "caustic", "specular")


def _principled(name, color, roughness, metallic=0.0, **inputs):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Roughness"].default_value = roughness
    p.inputs["Metallic"].default_value = metallic
    for k, v in inputs.items():
        p.inputs[k].default_value = v
    return m


def _backdrop(mat):
    """A seamless sweep: floor y in [-5, 1], a quarter circle of radius 1.2 up into a wall
    at y = 2.2, 14 m wide, shaded smooth."""
    prof = [(y, 0.0) for y in np.linspace(-5.0, 1.0, 7)]
    r = 1.2
    prof += [(1.0 + r * math.sin(a), r - r * math.cos(a))
             for a in np.linspace(0.0, math.pi / 2, 13)[1:]]
    prof += [(1.0 + r, z) for z in np.linspace(r, 6.0, 6)[1:]]
    verts = [(x, y, z) for (y, z) in prof for x in (-7.0, 7.0)]
    faces = [(2 * i, 2 * i + 1, 2 * i + 3, 2 * i + 2) for i in range(len(prof) - 1)]
    me = bpy.data.meshes.new("Backdrop")
    me.from_pydata(verts, [], faces)
    me.update()
    me.shade_smooth()
    return mb.add_object("Backdrop", me, mat)


def build(width=160, height=120, lift=0.0):
    """The product shot in the current bpy session; returns bpy.context.scene."""
    A.ensure_addon()
    mb.reset()
    scene = bpy.context.scene
    _backdrop(_principled("Backdrop", (0.8, 0.8, 0.8), 0.5))
    curve = bpy.data.curves.new("GoldText", "FONT")
    curve.body, curve.size, curve.extrude, curve.bevel_depth = "GOLD", 0.9, 0.1, 0.02
    curve.align_x = "CENTER"
    curve.materials.append(_principled("Gold", GOLD, 0.25, metallic=1.0))
    text = bpy.data.objects.new("GoldText", curve)
    text.location, text.rotation_euler = (0.0, 0.5, 0.1), (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(text)
    bpy.context.view_layer.objects.active = text
    text.select_set(True)
    bpy.ops.object.convert(target="MESH")
    bpy.context.active_object.data.shade_smooth()
    bpy.context.active_object.select_set(False)
    for i, (color, x) in enumerate((((0.8, 0.1, 0.1), -1.1), ((0.1, 0.3, 0.8), 0.2))):
        mat = mb.material(f"Ball{i}", "glossy_mix", color=color, roughness=0.1, mix=0.5)
        mb.sphere(f"Ball{i}", 0.3, mat, (x, -0.7, 0.3), segments=48, rings=24)
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=0.22, depth=0.9,
                                        location=(1.7, -0.1, 0.45 + lift))
    bottle = bpy.context.active_object
    bottle.name = "Bottle"
    bpy.ops.object.shade_smooth()
    bottle.data.materials.append(_principled("Glass", (1.0, 1.0, 1.0), 0.0, **{
        "Transmission Weight": 1.0, "IOR": 1.45}))
    bottle.select_set(False)
    d = 3.5
    mb.light("Key", "AREA", (-d * 0.5, -d * 0.5, 0.4 + d * math.sqrt(0.5)), 120.0,
             look_at=(0.0, 0.0, 0.4), shape="RECTANGLE", size=1.0, size_y=0.6)
    mb.light("Rim", "SPOT", (2.5, 2.2, 2.2), 400.0, look_at=(0.0, 0.0, 0.4),
             spot_size=math.radians(45), spot_blend=0.2, shadow_soft_size=0.1)
    mb.camera((0.0, -5.2, 1.7), (0.0, 0.0, 0.45), 42.0)
    mb.set_world((0.7, 0.8, 1.0), 0.3)
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    return scene


def object_ids(scene, width, height):
    """((H, W) int ids of the object each pixel centre's camera ray meets first, -1 none;
    row 0 at the top), names."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    names, ids = [], -np.ones((height, width), np.int32)
    for j in range(height):
        for i in range(width):
            u, v = (i + 0.5) / width, (j + 0.5) / height
            p = tl.lerp(tr, u).lerp(bl.lerp(br, u), v)
            hit, _, _, _, ob, _ = scene.ray_cast(dg, origin, (p - origin).normalized())
            if hit:
                if ob.name not in names:
                    names.append(ob.name)
                ids[j, i] = names.index(ob.name)
    return ids, names


def cycles(spp, seed, width, height, lift):
    scene = build(width, height, lift)
    A.set_cycles(scene, spp, seed)
    c0 = time.process_time()
    img, _ = A.render_rgb(scene)
    return img, time.process_time() - c0


def reference(spp, width, height, lift):
    path = os.path.join(tempfile.gettempdir(),
                        f"product_shot_ref_{width}x{height}_{spp}_{lift:g}.npy")
    if os.path.isfile(path):
        return np.load(path)
    img, cpu = cycles(spp, 7, width, height, lift)
    np.save(path, img)
    print(f"reference: Cycles {spp} spp, {cpu:.1f} CPU s -> {path}")
    return img


def ours(width, height, lift, spp, seed, overrides):
    """(Film, CPU s) of our render at the add-on's defaults, spp and seed."""
    from addon import export as ex
    import engine
    from engine.jit import ensure_compiled
    from engine.render import render
    from engine.settings import RenderSettings
    scene = build(width, height, lift)
    A.set_photonmap_defaults(scene)
    dg = bpy.context.evaluated_depsgraph_get()
    pm_scene, _ = ex.export_scene(engine, dg, width=width, height=height)
    kw = scene.photonmap.to_settings_kwargs(False)
    kw.update(overrides, spp=spp, seed=seed)
    ensure_compiled()  # loading the kernels is not a render's cost
    c0 = time.process_time()
    film = render(pm_scene, RenderSettings(**kw))
    return film, time.process_time() - c0


def relmse_map(x, ref):
    return ((x - ref) ** 2 / (ref * ref + 0.01)).mean(axis=2)


def row(label, cpu, img, ref, ids, names):
    import flip_evaluator
    fmap, mean = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                         np.ascontiguousarray(img, np.float32), "HDR",
                                         applyMagma=False)[:2]
    fmap = np.asarray(fmap, np.float64).reshape(ref.shape[:2])
    e = relmse_map(img, ref)
    lr, li = ref @ LUM, img @ LUM
    far = li > 10.0 * np.maximum(lr, 0.01)
    cells = []
    for i, name in enumerate(names):
        m = ids == i
        cells.append(f"{name} {li[m].mean() / lr[m].mean():.3f}/{e[m].sum() / e.sum():.2f}/"
                     f"{fmap[m].mean():.3f}")
    print(f"{label:14s} {cpu:7.1f} {mean:.4f} {e.mean():.5f} {img.mean() / ref.mean():7.4f} "
          f"{int(far.sum()):5d}  " + "  ".join(cells), flush=True)


def split(films, ref, ids, names):
    """relMSE of two renders of other seeds as noise + bias^2, noise by pass and object."""
    w = 1.0 / (ref * ref + 0.01)
    a, b = (np.asarray(f.combined, np.float64)[..., :3] for f in films[:2])
    noise = ((a - b) ** 2 / 2 * w).mean()
    bias2 = (((a + b) / 2 - ref) ** 2 * w).mean() - noise / 2
    print(f"ours, seeds' relMSE = noise {noise:.5f} + bias^2 {bias2:.5f}")
    vb = ((a + b) / 2 - ref) ** 2 * w - (a - b) ** 2 / 4 * w
    print("  bias^2 by object: " + " ".join(
        f"{n} {vb[ids == i].sum() / vb.sum():.2f}" for i, n in enumerate(names)))
    for name in PASSES:
        pa, pb = (np.asarray(getattr(f, name), np.float64)[..., :3] for f in films[:2])
        v = (pa - pb) ** 2 / 2 * w
        print(f"  noise {name:9s} {v.mean():.5f} ({v.mean() / noise:.2f}): " + " ".join(
            f"{n} {v[ids == i].sum() / max(v.sum(), 1e-30):.2f}" for i, n in enumerate(names)))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--cycles", default="256,768")
    ap.add_argument("--ref", type=int, default=4096)
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--lift", type=float, default=0.0, help="the bottle above the floor (m)")
    ap.add_argument("--set", action="append", default=[],
                    help="RenderSettings NAME=VALUE (a Python literal) for ours")
    a = ap.parse_args(argv)
    width, height = (int(v) for v in a.size.split("x"))
    import ast
    overrides = {k: ast.literal_eval(v) for k, v in (s.split("=", 1) for s in a.set)}
    ref = reference(a.ref, width, height, a.lift)
    ids, names = object_ids(build(width, height, a.lift), width, height)
    print(f"load {os.getloadavg()[0]:.1f}; reference Cycles {a.ref} spp, mean {ref.mean():.4f}"
          f"; bottle lifted {a.lift:g} m")
    print("renderer        CPU s   FLIP   relMSE  mean/ref  >10x  per object: luminance "
          "ratio / share of relMSE / FLIP")
    films = []
    for seed in (int(s) for s in a.seeds.split(",")):
        film, cpu = ours(width, height, a.lift, a.spp, seed, overrides)
        films.append(film)
        row(f"ours {a.spp} s{seed}", cpu, np.asarray(film.combined)[..., :3], ref, ids, names)
    for spp in (int(s) for s in a.cycles.split(",") if s):
        img, cpu = cycles(spp, 1, width, height, a.lift)
        row(f"cycles {spp}", cpu, img, ref, ids, names)
    if len(films) >= 2:
        split(films, ref, ids, names)


if __name__ == "__main__":
    main()
