"""A clear glass ball before a bright emitting wall, Cycles' Clamp Indirect biting on the
light seen through the ball: ours (the first glass hits split, integrator.SPLIT_GLASS_HITS)
against Cycles, both clamped alike, with each split half clamped at its Cycles
probability x the limit (sampleclamp.SPLIT_SCALE, the default) and at the whole limit
(the old bookkeeping); unclamped both for scale.

    PYTHONPATH=$PWD .venv/bin/python bench/splitclamp46_glass.py \\
        [--strength 40] [--clamp 10] [--ior 1.45] [--spp 16] [--ref 1024] [--size 64] \\
        [--cycles-only]

The scene (built with bpy, the add-on's export for ours): a black world, an emitting
plane (Emission strength --strength, white) 2 m behind a smooth Glass BSDF ball (radius
0.5 m, IOR --ior) at the origin, the camera 4 m in front (30 degrees). Every pixel of the
ball sees the wall through two refractions (Cycles' bounce 2: indirect) or, at the rim,
after inner reflections. Prints the mean radiance of Cycles and ours per region of the
ball's disc (centre r < 0.5, middle 0.5-0.8, rim 0.8-0.93 of its image radius, the whole
disc < 0.93) and ours / Cycles; CPU s is time.process_time of this process. Cycles'
images are cached in $TMPDIR (--cycles-only renders just them).
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

mb = A.mb
RADIUS, CAM_DIST, FOV = 0.5, 4.0, 30.0
# (Past 0.93 of the radius a pixel's square reaches past the ball's edge at 64 px.)
REGIONS = (("centre", 0.0, 0.5), ("middle", 0.5, 0.8), ("rim", 0.8, 0.93),
           ("disc", 0.0, 0.93))


def build(size, strength, ior):
    """The scene in the current bpy session; returns bpy.context.scene."""
    A.ensure_addon()
    mb.reset()
    m, nt, out = mb.empty_material("Wall")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    em.inputs["Strength"].default_value = strength
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    mb.plane("Wall", 12.0, 12.0, m, (0.0, 2.0, 0.0), (math.pi / 2, 0.0, 0.0))
    glass = mb.material("Glass", "glass", (1.0, 1.0, 1.0), ior=ior)
    mb.sphere("Ball", RADIUS, glass, (0.0, 0.0, 0.0), segments=64, rings=32)
    mb.camera((0.0, -CAM_DIST, 0.0), (0.0, 0.0, 0.0), FOV)
    scene = A.bpy.context.scene
    r = scene.render
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    return scene


def region_masks(size):
    """Per region (H, W) bool by the pixel centre's distance from the ball's image centre
    over the ball's image radius (a perspective camera: tan(asin(R / d)) / tan(fov / 2))."""
    r_img = math.tan(math.asin(RADIUS / CAM_DIST)) / math.tan(math.radians(FOV) / 2.0)
    y, x = np.mgrid[0:size, 0:size]
    px = (x + 0.5) / size * 2.0 - 1.0
    py = (y + 0.5) / size * 2.0 - 1.0
    rr = np.hypot(px, py) / r_img
    return {name: (rr >= a) & (rr < b) for name, a, b in REGIONS}


def cycles(size, strength, ior, spp, clamp, seed=7):
    """(image (H,W,3), CPU s) of Cycles, cached in $TMPDIR (CPU s 0: from the cache)."""
    path = os.path.join(tempfile.gettempdir(), f"splitclamp46_{size}_{strength:g}_{ior:g}_"
                                               f"{spp}_{clamp:g}_{seed}.npy")
    scene = build(size, strength, ior)
    A.set_cycles(scene, spp, seed)
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = clamp
    return A.render_rgb_cached(scene, path)


def ours(size, strength, ior, spp, clamp, split_scale, seed=0):
    from addon import export as ex
    import engine
    from engine import sampleclamp
    from engine.render import render
    from engine.settings import RenderSettings
    scene = build(size, strength, ior)
    A.set_photonmap_defaults(scene)
    dg = A.bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(scene.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h)
    kwargs = scene.photonmap.to_settings_kwargs(False)
    kwargs.update(spp=spp, seed=seed, clamp_direct=0.0, clamp_indirect=clamp)
    old = sampleclamp.SPLIT_SCALE
    sampleclamp.SPLIT_SCALE = split_scale
    try:
        c0 = time.process_time()
        film = render(pm_scene, RenderSettings(**kwargs))
        cpu = time.process_time() - c0
    finally:
        sampleclamp.SPLIT_SCALE = old
    return np.asarray(film.combined, np.float64), cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--strength", type=float, default=40.0)
    ap.add_argument("--clamp", type=float, default=10.0)
    ap.add_argument("--ior", type=float, default=1.45)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--ref", type=int, default=1024)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--cycles-only", action="store_true",
                    help="render (and cache) Cycles' images only")
    args = ap.parse_args(argv)
    if args.cycles_only:
        for clamp in (args.clamp, 0.0):
            _, cpu = cycles(args.size, args.strength, args.ior, args.ref, clamp)
            print(f"Cycles {args.ref} spp, clamp {clamp:g}: {cpu:.1f} CPU s", flush=True)
        return
    masks = region_masks(args.size)
    names = " / ".join(n for n, _, _ in REGIONS)

    def means(img):
        lum = np.asarray(img, np.float64).mean(axis=2)
        return [lum[masks[n]].mean() for n, _, _ in REGIONS]

    print(f"| renderer | clamp indirect | split halves clamped at | spp | CPU s | "
          f"mean {names} | ours / Cycles {names} |")
    print("|---|---:|---|---:|---:|---|---|")
    for clamp in (args.clamp, 0.0):
        ref, cpu = cycles(args.size, args.strength, args.ior, args.ref, clamp)
        cyc = means(ref)
        print(f"| Cycles | {clamp:g} | | {args.ref} | {cpu:.1f} | "
              + " / ".join(f"{m:.4f}" for m in cyc) + " | |", flush=True)
        for split_scale in ((True, False) if clamp else (True,)):
            img, cpu = ours(args.size, args.strength, args.ior, args.spp, clamp, split_scale)
            m = means(img)
            how = ("P_b x limit" if split_scale else "the limit") if clamp else ""
            print(f"| ours | {clamp:g} | {how} | {args.spp} | {cpu:.1f} | "
                  + " / ".join(f"{v:.4f}" for v in m) + " | "
                  + " / ".join(f"{o / c:.4f}" for o, c in zip(m, cyc)) + " |", flush=True)


if __name__ == "__main__":
    main()
