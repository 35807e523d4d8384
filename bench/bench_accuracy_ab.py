"""Equal-FLIP A/B in CPU seconds: settings variants of our renderer against Cycles' curve.

For one scene of tools/accuracy_scenes.py: the scene is exported once through the add-on
(its default settings), then rendered by engine.render on one worker for each variant and
seed, in this process, timing the process's CPU seconds (wall seconds mean little on a
shared machine: both cores busy with other jobs slow a render 2-3x). Cycles is rendered in
the same process at a few sample counts, also timed in CPU seconds (all its threads). Per
render: CPU s, wall s, shadow and gather rays, mean HDR-FLIP against the stored reference
and, where the reference has object labels, each object's brightness against Cycles'
(tests/test_principled_cycles.py asks for 2 %). Per variant: the mean over the seeds and
the equal-FLIP ratio (Cycles' CPU s to reach our mean FLIP, log-log on its curve, over our
mean CPU s; > 1: we are faster). With --where, per variant and object (the reference's
labels; 'rest' is edges and sky): its share of the summed HDR-FLIP, and its relMSE split
into noise (the seeds' variance) and bias (what the seeds' mean keeps beyond its own
noise). docs/accuracy_time_principled_spheres.md quotes its runs.

    .venv/bin/python bench/bench_accuracy_ab.py principled_spheres --seeds 0,1,2 \\
        --variant spp64:spp=64 --variant g1:gather_rays=1 [--cycles 64,256,1024]

A variant is NAME:key=value,key=value of engine.settings.RenderSettings fields; the
default settings are always measured first as "default". A key @module.NAME patches a
module constant of engine/ for that variant (a diagnostic: only constants read by Python
code take effect; those compiled into a kernel keep their value).
"""
from __future__ import annotations

import argparse
import ast
import importlib
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import accuracy_scenes as A  # noqa: E402  (needs the bpy wheel)
from bench_accuracy import _loglog  # noqa: E402


def export(name):
    """(engine Scene, RenderSettings kwargs) of scene `name` at our default settings, as
    the add-on hands them to the engine (accuracy_scenes.export_ours)."""
    return A.export_ours(name)


def parse_variant(text):
    """NAME:k=v,k=v -> (name, settings overrides, {(module, constant): value})."""
    name, _, rest = text.partition(":")
    overrides, patches = {}, {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            pass
        if key.startswith("@"):
            module, _, const = key[1:].rpartition(".")
            patches[(module, const)] = value
        else:
            overrides[key] = value
    return name, overrides, patches


def render_ours(pm_scene, kwargs, patches):
    """(image (H,W,3) float32, CPU s, wall s, stats) of one engine render, constants
    patched for its duration."""
    from engine.render import render
    from engine.settings import RenderSettings
    saved = {}
    for (module, const), value in patches.items():
        mod = importlib.import_module("engine." + module)
        saved[(mod, const)] = getattr(mod, const)
        setattr(mod, const, value)
    try:
        settings = RenderSettings(**kwargs)
        t0, c0 = time.perf_counter(), time.process_time()
        film = render(pm_scene, settings)
        return (np.asarray(film.combined, np.float32), time.process_time() - c0,
                time.perf_counter() - t0, film.stats)
    finally:
        for (mod, const), value in saved.items():
            setattr(mod, const, value)


def render_cycles(name, spp, seed=1):
    """(image, CPU s, wall s) of Cycles at spp samples."""
    scene = A.setup(name)
    A.set_cycles(scene, spp, seed)
    c0 = time.process_time()
    img, wall = A.render_rgb(scene)
    return img, time.process_time() - c0, wall


def object_ratios(img, name):
    stored = A.load_labels(name)
    if stored is None:
        return {}
    labels, names = stored
    meta = A.load_scene_meta(name)
    return {n: float(img[labels == i + 1].mean() / np.mean(meta["means"][n]))
            for i, n in enumerate(names) if np.any(labels == i + 1)}


def where(images, ref, flip_maps, name):
    """Lines: per object of the reference's labels (and 'rest': edges, sky) its pixels,
    its share of the summed HDR-FLIP, its mean FLIP, and its relMSE split into noise and
    bias: noise = the seeds' pixel variance (from their spread, unbiased), bias = the
    squared error of the seeds' mean image less the noise that mean still holds."""
    stack = np.stack([np.asarray(i, np.float64) for i in images])
    ref = np.asarray(ref, np.float64)
    n = len(stack)
    fmap = np.mean(flip_maps, axis=0)
    denom = ref * ref + 0.01
    var = stack.var(axis=0, ddof=1) if n > 1 else np.zeros_like(ref)
    err_mean = (stack.mean(axis=0) - ref) ** 2
    stored = A.load_labels(name)
    regions = []
    if stored is not None:
        labels, names = stored
        regions = [(nm, labels == i + 1) for i, nm in enumerate(names)]
        regions.append(("rest", labels == 0))
    regions.append(("image", np.ones(ref.shape[:2], bool)))
    total = fmap.sum()
    out = []
    for nm, m in regions:
        if not m.any():
            continue
        noise = float((var[m] / denom[m]).mean())
        bias = float(((err_mean[m] - var[m] / n) / denom[m]).mean())
        out.append(f"  {nm:8s} px {int(m.sum()):6d}  FLIP share {fmap[m].sum() / total:6.1%}"
                   f"  mean {fmap[m].mean():.4f}  relMSE noise {noise:.2e} bias {bias:+.2e}")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--seeds", default="0", help="comma-separated seeds of our renders")
    ap.add_argument("--variant", action="append", default=[],
                    help="NAME:key=value,... (RenderSettings fields, @module.CONST)")
    ap.add_argument("--cycles", default="64,256,1024",
                    help="Cycles sample counts for its curve ('' to skip)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--where", action="store_true",
                    help="per object: share of the FLIP, relMSE noise and bias (where())")
    args = ap.parse_args(argv)
    import engine
    engine.jit.ensure_compiled()
    ref = A.load_reference(args.scene)
    curve = []
    for spp in [int(s) for s in args.cycles.split(",") if s]:
        img, cpu, wall = render_cycles(args.scene, spp)
        f = A.flip(img, ref)
        curve.append((cpu, f))
        print(f"cycles {spp:5d} spp            cpu {cpu:6.1f} s  wall {wall:6.1f} s  "
              f"FLIP {f:.4f}", flush=True)
    pm_scene, base = export(args.scene)
    base = dict(base, workers=args.workers)
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"load average {os.getloadavg()[0]:.1f}", flush=True)
    for text in ["default:"] + args.variant:
        name, overrides, patches = parse_variant(text)
        flips, cpus, images, maps = [], [], [], []
        for seed in seeds:
            img, cpu, wall, st = render_ours(pm_scene, dict(base, seed=seed, **overrides),
                                             patches)
            f, fmap = A.flip(img, ref, return_map=True)
            flips.append(f)
            cpus.append(cpu)
            if args.where:
                images.append(img)
                maps.append(fmap)
            ratios = object_ratios(img, args.scene)
            off = " ".join(f"{n} {r:.3f}" for n, r in ratios.items() if abs(r - 1) > 0.02)
            print(f"{name:14s} seed {seed}  cpu {cpu:6.1f} s  wall {wall:6.1f} s  "
                  f"FLIP {f:.4f}  shadow {st.get('shadow_rays', 0) / 1e6:.2f}M  "
                  f"gather {st.get('gather_rays', 0) / 1e6:.2f}M"
                  + (f"  objects > 2 %: {off}" if off else ""), flush=True)
        line = f"{name:14s} mean     cpu {np.mean(cpus):6.1f} s  FLIP {np.mean(flips):.4f}"
        if len(curve) >= 2:
            t, extrapolated = _loglog(np.mean(flips), [f for _, f in curve],
                                      [c for c, _ in curve])
            line += (f"  Cycles cpu at that FLIP {'~' if extrapolated else ''}{t:.1f} s"
                     f"  equal-FLIP ratio {t / np.mean(cpus):.2f}")
        print(line, f"(load {os.getloadavg()[0]:.1f})", flush=True)
        if args.where:
            print("\n".join(where(images, ref, maps, args.scene)), flush=True)


if __name__ == "__main__":
    main()
