"""Blender users' scenes at both engines' default settings (fgroom46): ours as the add-on
exports the scene (Filter Glossy 1, Clamp Indirect 10: Blender's defaults, which the
add-on passes) against Cycles at the same settings, per object.

    PYTHONPATH=$PWD .venv/bin/python bench/fgroom46.py SCENE [--seeds 0,1]
        [--ref-spp 1024] [--cycles-spp 256] [--ref-dir /tmp/fgroom46/refs] [--fg 1]
        [--set NAME=VALUE ...]

SCENE: principled_spheres (issue 14's row of Principled balls, tools/accuracy_scenes.py:
its comparison settings - no clamp, its bounce limits - with Filter Glossy --fg in both),
sun_sky (bench/bench_exterior.py's yard under a Sun and a sky) or product (its product
shot: two balls on a floor, an area light, a world colour); the exterior blends are built
with bench_exterior.build and rendered at the file's settings (160 x 120, Blender's
defaults; only Filter Glossy set to --fg in both). Cycles: CPU, no denoising, no adaptive
sampling, seed 0; the --ref-spp reference is cached in --ref-dir as .npy.

Prints, per object covering >= 100 pixels (newuser26_scenes.object_masks: the object a
pixel centre's camera ray meets first) and the whole image: the reference's mean Rec. 709
luminance, each render's mean-luminance ratio and relMSE (newuser26_compare.rel_mse),
then per render its HDR-FLIP against the reference and CPU seconds (process_time; ours
one engine render of the exported scene, workers as --set), and the Cycles spp / CPU s at
our relMSE: Cycles at --cycles-spp against the reference holds v/N + v/REF of per-sample
variance v, so N = v / (relMSE_ours - v/REF) (newuser45's estimate, docs/accuracy.md).
"""
from __future__ import annotations

import argparse
import ast
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.join(ROOT, "bench"))
ARGV, sys.argv = sys.argv[1:], sys.argv[:1]  # keep them from Cycles' add-on

import numpy as np  # noqa: E402
import bpy  # noqa: E402

import accuracy_scenes as acc  # noqa: E402
from newuser26_compare import LUM, rel_mse  # noqa: E402
from newuser26_scenes import object_masks  # noqa: E402

EXTERIORS = ("sun_sky", "product")


def open_scene(name, out_dir, fg):
    """The bpy scene `name` at its comparison settings, Filter Glossy fg in Cycles' (both
    engines read it)."""
    if name in EXTERIORS:
        import bench_exterior
        path = os.path.join(out_dir, name + ".blend")
        if not os.path.exists(path):
            bench_exterior.build(name, path)
        acc.ensure_addon()
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
        scene = bpy.context.scene
    else:
        scene = acc.setup(name)
        acc.set_cycles(scene, 16)  # the comparison's Light Paths, also read by ours
        acc.set_photonmap_defaults(scene)
    scene.cycles.blur_glossy = fg
    return scene


def cycles(scene, spp, seed=0):
    """((H, W, 3) float64, CPU s of this process and its children)."""
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.seed = "CPU", spp, seed
    c.use_adaptive_sampling = c.use_denoising = False
    t0 = cpu()
    img, _ = acc.render_rgb(scene)
    return np.asarray(img, np.float64), cpu() - t0


def ours(scene, seed, overrides):
    """((H, W, 3) float64, CPU s) of one engine render of the scene as the add-on exports
    it (every photonmap property unset but overrides)."""
    from addon import export as ex
    import engine
    from engine.render import render
    from engine.settings import RenderSettings
    scene.render.engine = "PHOTONMAP"
    pm = scene.photonmap
    for prop in pm.bl_rna.properties:
        if prop.identifier != "rna_type":
            pm.property_unset(prop.identifier)
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(scene.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h, render_visibility=True)
    kw = dict(pm.to_settings_kwargs(scene.render.film_transparent), seed=seed, **overrides)
    t0 = cpu()
    film = render(pm_scene, RenderSettings(**kw))
    return np.asarray(film.combined, np.float64)[..., :3], cpu() - t0


def cpu():
    import resource
    s, c = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def flip(ref, img):
    import flip_evaluator
    return float(flip_evaluator.evaluate(ref.astype(np.float32), img.astype(np.float32),
                                         "HDR")[1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", choices=("principled_spheres",) + EXTERIORS)
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--cycles-spp", type=int, default=256)
    ap.add_argument("--ref-dir", default="/tmp/fgroom46/refs")
    ap.add_argument("--fg", type=float, default=1.0)
    ap.add_argument("--set", action="append", default=[], help="RenderSettings NAME=VALUE")
    a = ap.parse_args(ARGV)
    os.makedirs(a.ref_dir, exist_ok=True)
    overrides = {k: ast.literal_eval(v) for k, v in (s.split("=", 1) for s in a.set)}
    from engine.jit import ensure_compiled
    ensure_compiled()
    scene = open_scene(a.scene, a.ref_dir, a.fg)
    W, H = scene.render.resolution_x, scene.render.resolution_y
    ids, names = object_masks(scene, W, H)
    print(f"{a.scene} {W} x {H}, Filter Glossy {a.fg:g}, load {os.getloadavg()[0]:.1f}",
          flush=True)

    def cached(spp):
        path = os.path.join(a.ref_dir, f"{a.scene}-fg{a.fg:g}-{spp}.npy")
        if os.path.exists(path):
            d = np.load(path, allow_pickle=True).item()
            return d["img"], d["cpu"]
        img, t = cycles(open_scene(a.scene, a.ref_dir, a.fg), spp)
        np.save(path, {"img": img, "cpu": t})
        return img, t

    ref, ref_cpu = cached(a.ref_spp)
    runs = {}
    for s in (int(x) for x in a.seeds.split(",")):
        runs[f"ours s{s}"] = ours(open_scene(a.scene, a.ref_dir, a.fg), s, overrides)
        print(f"ours seed {s}: {runs[f'ours s{s}'][1]:.1f} CPU s", flush=True)
    if a.cycles_spp:
        runs[f"Cycles {a.cycles_spp}"] = cached(a.cycles_spp)
    print(f"| object (pixels) | Cycles {a.ref_spp} luminance | "
          + " | ".join(f"{k} ratio / relMSE" for k in runs) + " |")
    print("|---|---|" + "---|" * len(runs))
    rows = [(f"{n} ({int((ids == i).sum())})", ids == i) for i, n in enumerate(names)
            if (ids == i).sum() >= 100]
    rows += [(f"background ({int((ids < 0).sum())})", ids < 0), ("whole image", ids > -9)]
    for label, m in rows:
        if not m.any():
            continue
        lr = float((ref[m] @ LUM).mean())
        cells = [f"{float((img[m] @ LUM).mean()) / lr:.3f} / {rel_mse(img[m], ref[m]):.4f}"
                 for img, _ in runs.values()]
        print(f"| {label} | {lr:.4f} | " + " | ".join(cells) + " |", flush=True)
    print(f"Cycles {a.ref_spp} (reference): {ref_cpu:.1f} CPU s")
    v = None
    if a.cycles_spp:
        rc = rel_mse(runs[f"Cycles {a.cycles_spp}"][0], ref)
        v = rc / (1.0 / a.cycles_spp + 1.0 / a.ref_spp)
    for k, (img, t) in runs.items():
        r = rel_mse(img, ref)
        line = f"{k}: relMSE {r:.5f}, HDR-FLIP {flip(ref, img):.4f}, {t:.1f} CPU s"
        if v is not None and k.startswith("ours"):
            left = r - v / a.ref_spp
            if left > 0:
                n = v / left
                t_c = runs[f"Cycles {a.cycles_spp}"][1] * n / a.cycles_spp
                line += (f"; Cycles at this relMSE: ~{n:.0f} spp, ~{t_c:.1f} CPU s "
                         f"(ratio Cycles / ours {t_c / t:.2f})")
            else:
                line += "; below the reference's own noise"
        print(line, flush=True)


if __name__ == "__main__":
    main()
