"""Issue 14's glossy product shot (s23 new-user trial): where its fireflies come from, and
ours against Cycles in CPU seconds (HDR-FLIP / relMSE against a high-spp Cycles reference).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_glossy_product.py \\
        [--spp 4,16] [--seeds 0,1] [--cycles 16,64,256] [--ref 1024] [--size 160x120]
        [--gold 0.3] [--split | --trace]

The scene (bpy, `build`): bevelled gold text (a Text object, extrude + bevel, converted to
a mesh; Principled Metallic 1, gold base colour, roughness 0.3), a row of balls with a Mix
Shader (fac 0.5) of a Diffuse BSDF and a Glossy BSDF (roughness 0.2), a Principled floor
(roughness 0.5, Blender's default), one area light and a world colour. The reference is
Cycles at --ref spp without clamp, glossy filter or denoising (tools/accuracy_scenes
set_cycles), cached in $TMPDIR by spp, size and gold roughness. Per render: CPU s (time.process_time:
every thread of this process), mean HDR-FLIP and relMSE against the reference, image mean
over the reference's, mean HDR-FLIP over the image rows of the text, the balls and the
floor, and the outlier pixels (ours - ref > 3 (ref + 0.05), luminance) with, for ours,
each pass's sum over them (which term carries the speckles). --split and --trace: the
diagnostics split_terms and trace_samples instead (docs/accuracy.md "glossygather").
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
    import flip_evaluator
    # The error map itself (applyMagma False: the default is its colour-mapped picture).
    fmap, mean = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                         np.ascontiguousarray(img, np.float32), "HDR",
                                         applyMagma=False)[:2]
    fmap = np.asarray(fmap, np.float64).reshape(ref.shape[:2])
    h = ref.shape[0]
    bands = " ".join(f"{fmap[int(a * h):int(b * h)].mean():.3f}" for _, a, b in BANDS)
    out = outliers(img, ref)
    line = (f"{label:7s} {spp:5d} {seed:4d} {cpu:7.1f} {mean:.4f} {A.relmse(img, ref):.4f}"
            f" {img.mean() / ref.mean():7.4f}  {bands}  {int(out.sum()):4d}")
    if film is not None:
        # The passes' sums over the outlier pixels: which term carries them.
        line += "  " + " ".join(
            f"{np.asarray(getattr(film, n), np.float64).mean(axis=2)[out].sum():.1f}"
            for n in ("direct", "indirect", "caustic", "specular"))
    print(line, flush=True)


def split_terms(pm_scene, kwargs, ref, spp, seed):
    """Which term of the camera path's secondary hits carries the speckles: renders with
    the direct (light samples, the rough lobes' included), caustic or indirect (final
    gather) radiance of integrator.shade_diffuse dropped at camera bounces > 0, one at a
    time (a diagnostic: those images are dark by design). Prints the specular pass's mean,
    max and 99.9th percentile and the outlier pixels of each."""
    import engine.integrator as integrator
    inner = integrator.shade_diffuse
    drop = [None]

    def shade(*args, **kw):
        out = list(inner(*args, **kw))
        if drop[0] is not None and (kw.get("bounce") or 0) > 0 and out[drop[0]] is not None:
            out[drop[0]] = np.zeros_like(out[drop[0]])
        return tuple(out)

    integrator.shade_diffuse = shade
    try:
        print("dropped at bounce > 0   specular mean    max  p99.9  outliers")
        for name, i in (("nothing", None), ("direct", 0), ("caustic", 1), ("indirect", 2)):
            drop[0] = i
            film, _ = ours(pm_scene, kwargs, spp, seed)
            sp = np.asarray(film.specular, np.float64).mean(axis=2)
            print(f"{name:22s} {sp.mean():14.4f} {sp.max():6.2f} {np.percentile(sp, 99.9):6.3f}"
                  f" {int(outliers(film.combined, ref).sum()):9d}", flush=True)
    finally:
        integrator.shade_diffuse = inner


def trace_samples(pm_scene, kwargs, spp, seed, width, floor=3.0):
    """The specular pass's single samples above `floor` (radiance x throughput, luminance):
    integrator.Accumulator.add wrapped to log each by the line of integrator that adds it
    (the light met by a continuation, a secondary hit's shading, ...), the camera bounce,
    the image row band and the path throughput; prints the counts and the largest."""
    import collections
    import sys as _sys
    import engine.integrator as integrator
    inner = integrator.Accumulator.add
    log = []

    def add(self, name, pix, rgb, tp=None, rows=None):
        if name == "specular" and len(rgb):
            caller = _sys._getframe(1)
            r = np.asarray(rgb, np.float64)
            k = np.arange(len(r)) if rows is None or len(rows) == 0 else np.asarray(rows)
            t = (np.asarray(tp, np.float64)[k] if tp is not None and len(tp)
                 else np.ones_like(r))
            v = (r * t).mean(axis=1)
            y = np.asarray(pix)[k] // width
            for i in np.nonzero(v > floor)[0]:
                band = next((b for b, lo, hi in BANDS
                             if lo <= y[i] / pm_scene.height < hi), "sky")
                log.append((float(v[i]), caller.f_lineno, int(caller.f_locals.get("bounce", -1)),
                            band, float(t[i].mean())))
        return inner(self, name, pix, rgb, tp, rows)

    integrator.Accumulator.add = add
    try:
        ours(pm_scene, {**kwargs, "workers": 1}, spp, seed)
    finally:
        integrator.Accumulator.add = inner
    print(f"specular-pass samples above {floor}: (integrator line, bounce, band) -> count")
    for key, n in sorted(collections.Counter(e[1:4] for e in log).items()):
        print(f"  {key}: {n}")
    print("largest: value, line, bounce, band, throughput")
    for e in sorted(log, reverse=True)[:12]:
        print(f"  {e[0]:6.1f} {e[1]:5d} {e[2]:2d} {e[3]:6s} {e[4]:.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", default="4,16")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--cycles", default="16,64,256")
    ap.add_argument("--ref", type=int, default=1024)
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--gold", type=float, default=0.3, help="the gold's roughness")
    ap.add_argument("--trace", action="store_true",
                    help="only the diagnostic trace_samples at the first --spp and --seeds")
    ap.add_argument("--split", action="store_true",
                    help="only the diagnostic split_terms at the first --spp and --seeds")
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
    if a.trace:
        trace_samples(pm_scene, kwargs, int(a.spp.split(",")[0]), int(a.seeds.split(",")[0]),
                      width)
        return
    if a.split:
        split_terms(pm_scene, kwargs, ref, int(a.spp.split(",")[0]),
                    int(a.seeds.split(",")[0]))
        return
    for spp in (int(s) for s in a.spp.split(",")):
        for seed in (int(s) for s in a.seeds.split(",")):
            film, cpu = ours(pm_scene, kwargs, spp, seed)
            row("ours", spp, seed, cpu, film.combined, ref, film)
    for spp in (int(s) for s in a.cycles.split(",")):
        img, cpu = cycles(spp, 1, width, height, a.gold)
        row("cycles", spp, 1, cpu, img, ref)


if __name__ == "__main__":
    main()
