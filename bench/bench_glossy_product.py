"""Issue 14's glossy product shot (s23 new-user trial): where its fireflies come from, and
ours against Cycles in CPU seconds (HDR-FLIP / relMSE against a high-spp Cycles reference).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_glossy_product.py \\
        [--spp 4,16] [--seeds 0,1] [--cycles 16,64] [--ref 1024] [--size 160x120]

The scene (bpy, `build`): bevelled gold text (a Text object, extrude + bevel, converted to
a mesh; Principled Metallic 1, gold base colour, roughness 0.3), a row of balls with a Mix
Shader (fac 0.5) of a Diffuse BSDF and a Glossy BSDF (roughness 0.2), a Principled floor
(roughness 0.5, Blender's default), one area light and a world colour. The reference is
Cycles at --ref spp without clamp, glossy filter or denoising (tools/accuracy_scenes
set_cycles), cached in $TMPDIR by spp and size. Per render: CPU s (time.process_time:
every thread of this process), mean HDR-FLIP and relMSE against the reference, image mean
over the reference's, mean HDR-FLIP over the image rows of the text, the balls and the
floor, and the outlier pixels (ours - ref > 3 (ref + 0.05), luminance) with, for ours,
each pass's sum over them (which term carries the speckles).
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


def build(width=160, height=120, gold_roughness=0.3):
    """The product shot in the current bpy session; returns bpy.context.scene."""
    A.ensure_addon()
    mb.reset()
    floor = A.principled("Floor", base_color=(0.6, 0.6, 0.6), roughness=0.5)
    mb.plane("Floor", 30, 30, floor)
    gold = A.principled("Gold", base_color=GOLD, metallic=1.0, roughness=gold_roughness)
    curve = bpy.data.curves.new("GoldText", "FONT")
    curve.body = "GOLD"
    curve.size = 1.0
    curve.extrude = 0.12
    curve.bevel_depth = 0.03
    curve.align_x = "CENTER"
    text = bpy.data.objects.new("GoldText", curve)
    text.location = (0.0, 0.6, 0.0)
    text.rotation_euler = (math.pi / 2, 0.0, 0.0)
    bpy.context.scene.collection.objects.link(text)
    dg = bpy.context.evaluated_depsgraph_get()
    me = bpy.data.meshes.new_from_object(text.evaluated_get(dg))
    bpy.data.objects.remove(text)
    curve.materials.clear()
    mb.add_object("GoldText", me, gold, (0.0, 0.6, 0.12), (math.pi / 2, 0.0, 0.0))
    for i in range(4):
        mat = mb.material(f"Ball{i}", "glossy_mix", color=(0.8, 0.15 + 0.2 * i, 0.1),
                          roughness=0.2, mix=0.5)
        mb.sphere(f"Ball{i}", 0.3, mat, ((i - 1.5) * 0.8, -0.6, 0.3), segments=48, rings=24)
    mb.light("AreaLight", "AREA", (-1.5, -2.5, 3.5), 300.0, look_at=(0.0, 0.0, 0.3),
             shape="SQUARE", size=1.0)
    mb.camera((0.0, -5.0, 1.8), (0.0, 0.0, 0.45), 45.0)
    world = bpy.data.worlds.new("World")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.05, 0.06, 0.08, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene = bpy.context.scene
    scene.world = world
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.film_transparent = False
    r.use_border = False
    return scene


def export(width, height, gold_roughness=0.3):
    """(engine Scene, RenderSettings kwargs) at our defaults (accuracy_scenes.export_ours)."""
    from addon import export as ex
    import engine
    scene = build(width, height, gold_roughness)
    A.set_photonmap_defaults(scene)
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(scene.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h)
    return pm_scene, scene.photonmap.to_settings_kwargs(False)


def cycles(spp, seed, width, height, gold_roughness=0.3):
    """(image (H,W,3), CPU s) of Cycles at spp."""
    scene = build(width, height, gold_roughness)
    A.set_cycles(scene, spp, seed)
    c0 = time.process_time()
    img, _ = A.render_rgb(scene)
    return img, time.process_time() - c0


def reference(spp, width, height, gold_roughness=0.3):
    path = os.path.join(tempfile.gettempdir(),
                        f"glossy_product_ref_{width}x{height}_{spp}_{gold_roughness:g}.npy")
    if os.path.isfile(path):
        return np.load(path)
    img, cpu = cycles(spp, 7, width, height, gold_roughness)
    np.save(path, img)
    print(f"reference: Cycles {spp} spp, {cpu:.1f} CPU s -> {path}")
    return img


def ours(pm_scene, kwargs, spp, seed):
    from engine.render import render
    from engine.settings import RenderSettings
    settings = RenderSettings(**{**kwargs, "spp": spp, "seed": seed})
    c0 = time.process_time()
    film = render(pm_scene, settings)
    return film, time.process_time() - c0


def outliers(img, ref):
    """(H,W) bool: pixels far above the reference (3x its level plus a floor of 0.05)."""
    lum = lambda x: np.asarray(x, np.float64).mean(axis=2)  # noqa: E731
    return lum(img) - lum(ref) > 3.0 * (lum(ref) + 0.05)


# Image rows of the scene's parts at 160x120 (scaled with the height): the gold text,
# the balls, the floor in front.
BANDS = (("text", 40 / 120, 60 / 120), ("balls", 60 / 120, 85 / 120), ("floor", 85 / 120, 1.0))


def row(label, spp, seed, cpu, img, ref, film=None):
    fmap = np.asarray(A.flip(img, ref, return_map=True)[1], np.float64)
    fmap = fmap.reshape(ref.shape)[..., 0] if fmap.size == ref.size else fmap.reshape(
        ref.shape[:2])
    h = ref.shape[0]
    bands = " ".join(f"{fmap[int(a * h):int(b * h)].mean():.3f}" for _, a, b in BANDS)
    out = outliers(img, ref)
    line = (f"{label:7s} {spp:5d} {seed:4d} {cpu:7.1f} {fmap.mean():.4f} {A.relmse(img, ref):.4f}"
            f" {img.mean() / ref.mean():7.4f}  {bands}  {int(out.sum()):4d}")
    if film is not None:
        # The passes' sums over the outlier pixels: which term carries them.
        line += "  " + " ".join(
            f"{np.asarray(getattr(film, n), np.float64).mean(axis=2)[out].sum():.1f}"
            for n in ("direct", "indirect", "caustic", "specular"))
    print(line, flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", default="4,16")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--cycles", default="16,64,256")
    ap.add_argument("--ref", type=int, default=1024)
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--gold", type=float, default=0.3, help="the gold's roughness")
    a = ap.parse_args(argv)
    width, height = (int(v) for v in a.size.split("x"))
    ref = reference(a.ref, width, height, a.gold)
    print(f"load {os.getloadavg()[0]:.1f}; reference mean {ref.mean():.4f}; gold roughness "
          f"{a.gold:g}")
    print("         spp seed   CPU s   FLIP  relMSE mean/ref  FLIP text balls floor  "
          "outliers (direct indirect caustic specular)")
    pm_scene, kwargs = export(width, height, a.gold)
    from engine.jit import ensure_compiled
    ensure_compiled()  # the kernels' load from the cache is not a render's cost
    for spp in (int(s) for s in a.spp.split(",")):
        for seed in (int(s) for s in a.seeds.split(",")):
            film, cpu = ours(pm_scene, kwargs, spp, seed)
            row("ours", spp, seed, cpu, film.combined, ref, film)
    for spp in (int(s) for s in a.cycles.split(",")):
        img, cpu = cycles(spp, 1, width, height, a.gold)
        row("cycles", spp, 1, cpu, img, ref)


if __name__ == "__main__":
    main()
