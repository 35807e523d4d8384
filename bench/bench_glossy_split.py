"""Cycles' Filter Glossy split (engine/glossysplit.py) measured: ours at Filter Glossy 0
and 1 against Cycles at 0 and 1, per object, with the light the maps drop and the light
the gather chains add, each from its own pass.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glossy_split.py [--spp N] [--seed S]
        [--cycles-spp N] [--only glossy_floor,figure6_box] [--fg 1.0]

--fg: the Filter Glossy compared with 0 (default 1, Cycles' default; 0.3: only the
bounces of pdf below 0.3 blur). Scenes: tools/accuracy_scenes' and glossy_floor
(bench/bench_filter_glossy.py), sharp_floor (here: a Principled floor of roughness 0.1
with Blender's default specular 0.5 under a glossy metal ball, seen at a grazing angle:
photons from the ball arriving near the floor's mirror direction of the view keep
pdf_D above Filter Glossy, docs/compatibility.md "fgphoton46").

Ours: the add-on's export (tools/accuracy_scenes.export_ours), only
cycles_filter_glossy changed between the two renders. "dropped" is the caustic pass at
Filter Glossy 0 (the caustic and glow maps' estimates, which the split leaves out at 1);
"chains" is the caustic pass at 1 (the gather chains' light sampling and emission,
which the split puts there).
Cycles: the bpy wheel, tools/accuracy_scenes.set_cycles (bench/bench_filter_glossy.py's
renders). Mean Rec. 709 luminance over the pixels each object covers fully.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, ROOT)
import bench_filter_glossy as bfg  # noqa: E402  (registers glossy_floor; needs bpy)

acc = bfg.acc
LUM = bfg.LUM
mb = acc.mb


def _sharp_floor():
    """A Principled floor (base 0.8, roughness 0.1, specular 0.5: Blender's default) and
    a glossy metal ball (roughness 0.2) lit by a narrow spot aimed at it from the camera's
    side, low (the floor lit by the ball's glow alone, nearly); the camera looks at the
    floor at a grazing angle towards the ball, so much of that glow arrives near the
    floor's mirror direction of the view (pdf_D high: photons Cycles does not blur)."""
    mb.reset()
    floor = mb.material("FloorMat", "principled", (0.8, 0.8, 0.8), roughness=0.1)
    metal = mb.material("Metal", "principled", (0.9, 0.9, 0.9), roughness=0.2, metallic=1.0)
    mb.plane("Floor", 8, 8, floor)
    mb.sphere("Ball", 0.5, metal, (0.0, 0.5, 0.5))
    mb.light("Lamp", "SPOT", (0.0, -1.5, 0.4), 300.0, look_at=(0.0, 0.5, 0.5),
             shadow_soft_size=0.05, spot_size=math.radians(24.0), spot_blend=0.0)
    mb.camera((0.0, -4.0, 0.6), (0.0, 0.0, 0.0), 40.0)


acc.SCENES["sharp_floor"] = (_sharp_floor, "specular")


def ours(name, fg, spp, seed):
    from engine.render import render
    from engine.settings import RenderSettings
    pm_scene, kwargs = acc.export_ours(name)
    kw = dict(kwargs, seed=seed, spp=spp, cycles_filter_glossy=fg)
    t0 = os.times()
    film = render(pm_scene, RenderSettings(**kw))
    t1 = os.times()
    return film, t1.user + t1.system - t0.user - t0.system


def ours_diffuse(film):
    """The light at the camera's diffuse hits D in our film (H, W, 3): its direct,
    indirect and caustic passes (the maps, the final gather and the gather chains; the
    specular pass holds what D's glossy lobes see)."""
    return sum(np.asarray(getattr(film, p), np.float64)[..., :3]
               for p in ("direct", "indirect", "caustic"))


def cycles_diffuse(name, spp, fg, seed):
    """Cycles' (Diffuse Direct + Diffuse Indirect) x Diffuse Color of scene `name` at
    Filter Glossy fg (H, W, 3): the light its diffuse closures return, as ours_diffuse
    (tools/accuracy_scenes.set_cycles, a multilayer EXR read with OpenEXR)."""
    import tempfile
    import bpy
    import OpenEXR
    scene = acc.setup(name)
    acc.set_cycles(scene, spp, seed)
    scene.cycles.blur_glossy = fg
    layer = scene.view_layers[0]
    for p in ("diffuse_direct", "diffuse_indirect", "diffuse_color"):
        setattr(layer, "use_pass_" + p, True)
    scene.render.use_compositing = False
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # Blender 5.0+
        s.media_type = "MULTI_LAYER_IMAGE"
    s.file_format, s.color_depth = "OPEN_EXR_MULTILAYER", "32"
    fd, path = tempfile.mkstemp(suffix=".exr", prefix="acc_")
    os.close(fd)
    try:
        scene.render.filepath, scene.render.use_file_extension = path, False
        bpy.ops.render.render(write_still=True)
        img = {n: np.asarray(c.pixels, np.float64)[..., :3]
               for part in OpenEXR.File(path).parts for n, c in part.channels.items()}
    finally:
        os.unlink(path)
    d = {k: img[f"{layer.name}.Diffuse {k}"] for k in ("Direct", "Indirect", "Color")}
    return (d["Direct"] + d["Indirect"]) * d["Color"]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cycles-spp", type=int, default=512)
    p.add_argument("--only", default="glossy_floor,figure6_box")
    p.add_argument("--fg", type=float, default=1.0)
    a = p.parse_args(argv)
    print(f"FG1 = Filter Glossy {a.fg}; ours {a.spp} spp seed {a.seed}; Cycles {a.cycles_spp} spp; load "
          f"{os.getloadavg()[0]:.1f}")
    print("| scene | region | ours FG0 | ours FG1 | ours 1/0 | Cycles FG0 | Cycles FG1 | "
          "Cycles 1/0 | ours FG1 / Cycles FG1 | dropped / FG0 | chains / FG0 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in a.only.split(","):
        f0, s0 = ours(name, 0.0, a.spp, a.seed)
        f1, s1 = ours(name, a.fg, a.spp, a.seed)
        cyc = {fg: bfg.render(name, a.cycles_spp, fg, 1)[0] for fg in (0.0, a.fg)}
        L = {k: np.asarray(v, np.float64)[..., :3] @ LUM for k, v in (
            ("o0", f0.combined), ("o1", f1.combined), ("c0", cyc[0.0]), ("c1", cyc[a.fg]),
            ("drop", f0.caustic), ("chains", f1.caustic))}
        for r, m in bfg.regions(name, f0.combined.shape[:2]).items():
            v = {k: float(x[m].mean()) for k, x in L.items()}
            print(f"| {name} | {r} | {v['o0']:.5g} | {v['o1']:.5g} | {v['o1'] / v['o0']:.4f} | "
                  f"{v['c0']:.5g} | {v['c1']:.5g} | {v['c1'] / v['c0']:.4f} | "
                  f"{v['o1'] / v['c1']:.4f} | {v['drop'] / v['o0']:.4f} | "
                  f"{v['chains'] / v['o0']:.4f} |", flush=True)
        print(f"<!-- {name}: ours FG0 {s0:.0f} CPU s, FG1 {s1:.0f} CPU s -->", flush=True)


if __name__ == "__main__":
    main()
