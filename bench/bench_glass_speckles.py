"""Speckles on and through glass balls (issue 14): the camera chain's first glass hit split
into its reflection and its refraction (integrator.SPLIT_GLASS_HITS) against the random
choice between them, on the same seeds, interleaved.

    python bench/bench_glass_speckles.py [--scene sunball|spheres|figure6|figure8|all]
                                         [--seeds 4] [--spp N] [--size WxH]
                                         [--modes choice,split] [--save DIR]

Scenes: "sunball", a smooth glass ball on a white floor under a sun (angle 2 degrees)
behind the camera, 48 x 36, 64 spp, 50k + 50k photons (the sun's mirror image on the
ball's front: docs/performance.md, "Camera paths through glass"); "roughball", the same
ball of rough glass (roughness 0.2); "spheres", issue 14's
Principled spheres (the pickled export /tmp/pk/principled_spheres_df2.pkl, default
settings at --size); "figure6" / "figure8", the paper's boxes (/tmp/pk/*.pkl).
Modes: "choice" (SPLIT_GLASS_HITS = 0: one lobe picked at random, as before),
"split" (the first glass hit), "splitN" (the first N glass hits), with "+rough" (rough
glass split too) and "+mirror" (integrator.MIRROR_NO_ROULETTE), e.g. "split2+rough";
"default": the module's settings (now split2+rough+mirror).

Per mode and region (the pixels whose centre ray first meets that material, and the
whole image): the region's mean (luminance, the mean of R, G, B), the pixel variance over
seeds relative to the squared mean (ddof 1), CPU seconds per render (process_time,
1 worker, photon pass included) and their product (lower is better); and per region the
difference of the two modes' means in standard errors (z: unbiasedness, |z| < ~2-3).
Renders run seed by seed, the modes interleaved, after one untimed 1-spp warm-up render
per mode; report `uptime` beside the numbers.
"""
from __future__ import annotations

import argparse
import os
import pickle
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from engine import RenderSettings  # noqa: E402
import engine.integrator as integrator  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.integrator import camera_rays  # noqa: E402
from engine.render import prepare_context, render  # noqa: E402
from engine.scene import Material  # noqa: E402

PASSES = ("direct", "caustic", "indirect", "specular", "emission")


def sunball_scene(roughness=0.0):
    s = PaperScene(48, 36, background=(0.05, 0.05, 0.05))
    s.add_plane((0, 0, 0), (0, 0, 1), 12.0, "white_diffuse", name="floor")
    glass = Material("glass", (1.0, 1.0, 1.0), transmission=1.0, roughness=roughness,
                     ior=1.5, node="glass", multiscatter=False)
    s.add_sphere((0, 0, 0.6), 0.6, glass, name="ball", segments=48)
    s.add_sun((0.0, 0.8, -0.6), 3.0, angle_degrees=2.0)
    s.set_camera((0, -4.0, 1.4), (0, 0, 0.5), view_angle=30.0)
    return s, dict(spp=64, photons=50_000, caustic_photons=50_000)


def pickled_scene(name):
    with open(f"/tmp/pk/{name}.pkl", "rb") as f:
        return pickle.load(f), {}


SCENES = {"sunball": sunball_scene,
          "roughball": lambda: sunball_scene(0.2),
          "spheres": lambda: pickled_scene("principled_spheres_df2"),
          "figure6": lambda: pickled_scene("figure6_box"),
          "figure8": lambda: pickled_scene("figure8_caustic")}
SIZES = {"spheres": (80, 60), "figure6": (80, 60), "figure8": (80, 60)}


def first_hit_materials(scene, settings):
    """(H, W) the material name each pixel's centre ray meets first ('world': none)."""
    ctx = prepare_context(scene, settings)
    W, H = scene.width, scene.height
    py, px = np.mgrid[0:H, 0:W]
    px, py = px.ravel().astype(np.int64), py.ravel().astype(np.int64)
    half = np.full(len(px), 0.5)
    o, d, tmax = camera_rays(scene.camera, ctx.geo.offset, W, H, px, py, half, half)
    _, prim, _, _ = ctx.accel.intersect(o, d, tmax)
    names = np.array(list(ctx.table.names) + ["world"])
    mat = np.where(prim >= 0, np.asarray(ctx.geo.material)[np.maximum(prim, 0)], -1)
    return names[mat].reshape(H, W)


_FLAGS = ("SPLIT_GLASS_HITS", "SPLIT_ROUGH_GLASS", "MIRROR_NO_ROULETTE")
DEFAULTS = {k: getattr(integrator, k) for k in _FLAGS}


def set_mode(mode):
    """mode: "choice", or "split" / "splitN" (the first N glass hits), with "+rough"
    (rough glass split too) and / or "+mirror" (no Russian roulette at mirror-only first
    hits, integrator.MIRROR_NO_ROULETTE); "choice+mirror" too; "default": the module's."""
    if mode == "default":
        for k, v in DEFAULTS.items():
            setattr(integrator, k, v)
        return
    parts = mode.split("+")
    head = parts[0]
    integrator.SPLIT_GLASS_HITS = int(head[5:] or 1) if head != "choice" else 0
    integrator.SPLIT_ROUGH_GLASS = "rough" in parts[1:]
    integrator.MIRROR_NO_ROULETTE = "mirror" in parts[1:]


def render_mode(scene, kw, seed, mode):
    set_mode(mode)
    t0 = time.process_time()
    film = render(scene, RenderSettings(workers=1, seed=seed, **kw))
    cpu = time.process_time() - t0
    img = sum(np.asarray(getattr(film, k), np.float64) for k in PASSES)
    return img, cpu


def run(name, seeds, modes, spp=None, size=None, save=None):
    scene, kw = SCENES[name]()
    if size or name in SIZES:
        scene.width, scene.height = size or SIZES[name]
    if spp:
        kw["spp"] = spp
    mats = first_hit_materials(scene, RenderSettings(workers=1, **kw))
    regions = {m: mats == m for m in np.unique(mats) if (mats == m).sum() >= 4}
    regions["image"] = np.ones(mats.shape, bool)
    imgs = {m: [] for m in modes}
    cpus = {m: [] for m in modes}
    for m in modes:  # warm-up (tables, first calls): not timed
        render_mode(scene, dict(kw, spp=1), 12345, m)
    for seed in seeds:
        for m in modes:
            img, cpu = render_mode(scene, kw, seed, m)
            imgs[m].append(img)
            cpus[m].append(cpu)
            print(f"  {name} seed {seed} {m}: {cpu:.2f} CPU s", flush=True)
    set_mode("default")
    if save:
        os.makedirs(save, exist_ok=True)
        np.savez_compressed(os.path.join(save, f"{name}.npz"), mats=mats,
                            **{m: np.array(imgs[m]) for m in modes},
                            **{f"cpu_{m}": np.array(cpus[m]) for m in modes})
    n = len(seeds)
    print(f"\n{name}: {scene.width}x{scene.height}, {kw.get('spp', 'default')} spp, "
          f"{n} seeds, 1 worker")
    print(f"| region | px | mode | mean | rel. var | CPU s | var x CPU | z vs {modes[0]} |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for r, mask in regions.items():
        ref = None
        for m in modes:
            lum = np.array(imgs[m]).mean(axis=3)[:, mask]  # (seeds, px)
            mean = lum.mean()
            var = lum.var(axis=0, ddof=1).mean() if n > 1 else np.nan
            rel = var / max(mean * mean, 1e-300)
            cpu = float(np.mean(cpus[m]))
            # The region mean's standard error over seeds (its pixels' means per seed).
            per_seed = lum.mean(axis=1)
            se = per_seed.std(ddof=1) / np.sqrt(n) if n > 1 else np.nan
            if ref is None:
                ref = (mean, se)
                z = ""
            else:
                z = f"{(mean - ref[0]) / max(np.hypot(se, ref[1]), 1e-300):+.2f}"
            print(f"| {r} | {int(mask.sum())} | {m} | {mean:.4f} | {rel:.4g} | {cpu:.2f} | "
                  f"{rel * cpu:.4g} | {z} |")
    return imgs, cpus


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="sunball", choices=list(SCENES) + ["all"])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--spp", type=int, default=None)
    ap.add_argument("--size", default=None, help="WxH (pickled scenes: 80x60)")
    ap.add_argument("--modes", default="choice,default")
    ap.add_argument("--save", default=None, help="directory for the images (npz)")
    args = ap.parse_args(argv)
    size = tuple(int(x) for x in args.size.split("x")) if args.size else None
    names = list(SCENES) if args.scene == "all" else [args.scene]
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    print("load:", os.getloadavg())
    for name in names:
        run(name, seeds, args.modes.split(","), args.spp, size, args.save)
    print("load:", os.getloadavg())


if __name__ == "__main__":
    main()
