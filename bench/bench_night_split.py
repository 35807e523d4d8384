"""Ours against Cycles on one variant of a scene, to split a brightness difference (night43,
docs/accuracy.md "night43"): some lights alone, other Light Paths limits, objects removed
or moved, every Principled BSDF's input set. Prints the image means, their ratio and the
ratio by region (floor / walls, bench_interior.regions); saves both images as .npy.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_night_split.py SCENE.blend \\
        [--keep Point] [--bounces 12,1,4] [--cycles-spp 512] [--spp 64] \\
        [--remove SofaSeat] [--move "Point=(0, 0, 1.3)"] [--light "Point.shadow_soft_size=0"] \\
        [--principled "Specular IOR Level=0"] [--set photons=1600000] \\
        [--const integrator.MAX_GATHER_LEVEL=1] [--cycles-set use_light_tree=False] \\
        [--no-cycles | --no-ours] [--out /tmp/night43]

Ours: engine.render on 1 worker, seed 0, the add-on's settings from the scene (as
bench_interior.py); Cycles: seed 7, no denoising or adaptive sampling, Clamp Indirect 0,
Filter Glossy 0. Values are Python literals."""
from __future__ import annotations

import argparse
import ast
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "tools"))

import bench_interior as BI  # noqa: E402  (imports bpy)
import accuracy_scenes as A  # noqa: E402
import bpy  # noqa: E402


def _pairs(items):
    """["a.b=1", ...] -> [("a.b", 1), ...] (values as Python literals)."""
    out = []
    for text in items:
        key, value = text.split("=", 1)
        out.append((key.strip(), ast.literal_eval(value.strip())))
    return out


def setup(args):
    """Open args.scene at args.width and apply the variant; returns the scene."""
    sc = BI.open_scene(args.scene, args.width)
    keep = set(args.keep.split(",")) if args.keep else None
    for o in list(bpy.data.objects):
        if o.type == "LIGHT" and keep is not None and o.name not in keep:
            bpy.data.objects.remove(o, do_unlink=True)
    c = sc.cycles
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces = (
        int(x) for x in args.bounces.split(","))
    for name in [x for x in args.remove.split(",") if x]:
        bpy.data.objects.remove(bpy.data.objects[name], do_unlink=True)
    for name, loc in _pairs(args.move):
        bpy.data.objects[name].location = loc
    for key, value in _pairs(args.light):
        name, attr = key.split(".")
        setattr(bpy.data.objects[name].data, attr, value)
    for key, value in _pairs(args.principled):
        for m in bpy.data.materials:
            for n in (m.node_tree.nodes if m.node_tree else ()):
                if n.type == "BSDF_PRINCIPLED":
                    n.inputs[key].default_value = value
    return sc


def render_cycles(args):
    sc = setup(args)
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device, c.samples, c.seed = "CPU", args.cycles_spp, 7
    c.use_adaptive_sampling = c.use_denoising = False
    for key, value in _pairs(args.cycles_set):
        setattr(c, key, value)
    c0 = time.process_time()
    img, _ = A.render_rgb(sc)
    return img.astype(np.float64), time.process_time() - c0


def render_ours(args):
    from addon import export as ex
    import engine
    sc = setup(args)
    sc.render.engine = "PHOTONMAP"
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(sc.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h, render_visibility=True)
    kw = dict(sc.photonmap.to_settings_kwargs(sc.render.film_transparent), workers=1,
              spp=args.spp, seed=0)
    kw.update(_pairs(args.set))
    patches = {tuple(k.split(".")): v for k, v in _pairs(args.const)}
    film, cpu, _ = BI.render_film(pm_scene, kw, patches)
    print(f"ours: global search radius {film.stats.get('radius_global', float('nan')):.4f} m")
    means = {n: float(getattr(film, n).mean()) for n in
             ("direct", "indirect", "caustic", "specular", "emission")}
    return film.combined.astype(np.float64), cpu, means


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--keep", default="", help="lights kept, by name (default: all)")
    ap.add_argument("--bounces", default="12,4,4", help="Max, Diffuse, Glossy bounces")
    ap.add_argument("--cycles-spp", type=int, default=512)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--width", type=int, default=80)
    ap.add_argument("--remove", default="", help="objects removed, by name")
    ap.add_argument("--move", action="append", default=[], help='OBJECT=(x, y, z)')
    ap.add_argument("--light", action="append", default=[], help="LIGHT.attribute=value")
    ap.add_argument("--principled", action="append", default=[],
                    help="every Principled BSDF's input: 'Input Name=value'")
    ap.add_argument("--set", action="append", default=[], help="our setting=value")
    ap.add_argument("--const", action="append", default=[],
                    help="engine module constant for the render: module.NAME=value")
    ap.add_argument("--cycles-set", action="append", default=[],
                    help="scene.cycles property=value")
    ap.add_argument("--no-cycles", action="store_true")
    ap.add_argument("--no-ours", action="store_true")
    ap.add_argument("--tag", default="variant")
    ap.add_argument("--out", default="/tmp/night43")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    regs = BI.regions(args.scene, args.width, "none", 0.0)
    cyc = ours = None
    if not args.no_cycles:
        cyc, cpu = render_cycles(args)
        np.save(os.path.join(args.out, f"cycles-{args.tag}-{args.cycles_spp}.npy"), cyc)
        print(f"cycles {args.cycles_spp} spp: CPU {cpu:.0f} s, mean {cyc.mean():.5f}",
              flush=True)
    if not args.no_ours:
        ours, cpu, means = render_ours(args)
        np.save(os.path.join(args.out, f"ours-{args.tag}-{args.spp}.npy"), ours)
        print(f"ours {args.spp} spp: CPU {cpu:.0f} s, mean {ours.mean():.5f}; passes "
              + " ".join(f"{k} {v:.5f}" for k, v in means.items()), flush=True)
    if cyc is not None and ours is not None:
        print(f"[{args.tag}] ours / Cycles {ours.mean() / cyc.mean():.4f} | " + " ".join(
            f"{k} {ours[m].mean() / cyc[m].mean():.4f}" for k, m in regs.items()
            if m.any() and k in ("floor", "walls")), flush=True)


if __name__ == "__main__":
    main()
