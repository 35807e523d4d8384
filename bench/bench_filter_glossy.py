"""Cycles' Filter Glossy (Light Paths > Clamping > Filter Glossy, `scene.cycles.blur_glossy`)
measured: Cycles at Filter Glossy 1 (its default) against Filter Glossy 0, the same seed.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_filter_glossy.py [--samples N]
                                                                   [--seed S] [--only a,b]

Cycles only (the bpy wheel, CPU, tools/accuracy_scenes.set_cycles: no denoising, no
clamping, 32 bounces, 1 px box filter), each scene twice with only `blur_glossy`
changed. Prints a markdown table: mean luminance (Rec. 709) of the whole image at
Filter Glossy 0 and 1 and their ratio, and per object where the scene has labels
(principled_spheres' stored labels, else acc.object_labels: pixels an object covers
fully).
Same seed in both renders, so the ratio's noise is the part the blur changes.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import accuracy_scenes as acc  # noqa: E402
import bpy  # noqa: E402

mb = acc.mb
LUM = np.array([0.2126, 0.7152, 0.0722])


def _glossy_floor():
    """A rough metal floor (Principled, metallic 1, roughness 0.25) under a point lamp, a
    white diffuse back wall and a white diffuse ball: the wall and ball see the lamp's
    light off the floor (diffuse then glossy: the path Filter Glossy blurs)."""
    mb.reset()
    metal = mb.material("Metal", "principled", (0.9, 0.9, 0.9), roughness=0.25, metallic=1.0)
    white = mb.material("White", "diffuse", (0.8, 0.8, 0.8))
    mb.plane("Floor", 8, 8, metal)
    mb.plane("Wall", 8, 4, white, (0, 2.0, 2.0), (np.pi / 2, 0, 0))
    mb.sphere("Ball", 0.5, white, (0.8, 0.4, 0.5))
    mb.light("Lamp", "POINT", (-0.8, -0.5, 1.6), 300.0, shadow_soft_size=0.1)
    mb.camera((0.0, -5.0, 1.6), (0.0, 0.5, 0.8), 50.0)


acc.SCENES["glossy_floor"] = (_glossy_floor, "specular")
SCENES = ("figure6_box", "hdri_sphere", "principled_spheres", "glossy_floor")


def lum(img):
    return img[..., :3] @ LUM


def regions(name, shape) -> dict:
    """{"image": all pixels, object name: the pixels it covers fully} of scene `name`
    ((H, W) bool masks): its stored labels, else Cycles coverage renders, one per mesh
    object (16 spp: cheap)."""
    out = {"image": np.ones(shape, bool)}
    lab = acc.load_labels(name)
    if lab is None:
        lab = acc.object_labels(name, samples=16)
    if lab is not None:
        labels, names = lab
        for i, n in enumerate(names):
            m = labels == i + 1
            if m.any():
                out[n] = m
    return out


def render(name, samples, fg, seed=0):
    scene = acc.setup(name)
    acc.set_cycles(scene, samples, seed)
    scene.cycles.blur_glossy = fg
    return acc.render_rgb(scene)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, default=256)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", default=",".join(SCENES))
    a = p.parse_args(argv)
    print(f"Cycles {bpy.app.version_string}, {a.samples} spp, seed {a.seed}, CPU, "
          f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    print("| scene | region | pixels | lum FG 0 | lum FG 1 | FG 1 / FG 0 |")
    print("|---|---|---:|---:|---:|---:|")
    for name in a.only.split(","):
        t0, w0 = os.times(), time.perf_counter()
        imgs = {fg: render(name, a.samples, fg, a.seed)[0] for fg in (0.0, 1.0)}
        t1 = os.times()
        secs = (t1.user + t1.system - t0.user - t0.system, time.perf_counter() - w0)
        for r, m in regions(name, imgs[0.0].shape[:2]).items():
            l0, l1 = float(lum(imgs[0.0])[m].mean()), float(lum(imgs[1.0])[m].mean())
            print(f"| {name} | {r} | {int(m.sum())} | {l0:.5g} | {l1:.5g} | {l1 / l0:.4f} |",
                  flush=True)
        print(f"<!-- {name}: 2 renders, {secs[0]:.0f} CPU s, {secs[1]:.0f} s wall -->", flush=True)


if __name__ == "__main__":
    main()
