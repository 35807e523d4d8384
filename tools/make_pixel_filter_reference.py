"""Cycles' pixel filter, measured: the reference for tests/blender/test_pixel_filter_cycles.py.

    .venv/bin/python tools/make_pixel_filter_reference.py

An emissive strip (radiance 1) on a black world, seen straight down by an orthographic
camera at one world unit per pixel (32 x 16 pixels): a step edge at x = 16.3 px, and a
line 0.2 px wide over pixel 15's centre. Cycles renders each with a pixel filter
(Film > Pixel Filter: scene.cycles.pixel_filter_type, filter_width) at 4096 spp; the
column profile (mean over the 16 rows) is stored in tests/references/pixel_filter.json
(a few KB).
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import accuracy_scenes as acc  # noqa: E402  (bpy session helpers, Cycles settings)

bpy = acc.bpy
mb = acc.mb
REF_PATH = os.path.join(os.path.dirname(HERE), "tests", "references", "pixel_filter.json")
WIDTH, HEIGHT = 32, 16
SAMPLES = 4096
# name: ((x0, x1) of the strip in pixels, Cycles filter type, width)
CASES = {
    "edge_blackman_harris_1.5": ((16.3, WIDTH + 8.0), "BLACKMAN_HARRIS", 1.5),
    "edge_blackman_harris_3": ((16.3, WIDTH + 8.0), "BLACKMAN_HARRIS", 3.0),
    "edge_gaussian_1.5": ((16.3, WIDTH + 8.0), "GAUSSIAN", 1.5),
    "edge_box": ((16.3, WIDTH + 8.0), "BOX", 1.0),
    "line_blackman_harris_1.5": ((15.4, 15.6), "BLACKMAN_HARRIS", 1.5),
}


def strip_scene(x0: float, x1: float, kind: str, width: float):
    """The strip x0 <= x <= x1 (pixel units) with the pixel filter (kind, width) set."""
    acc.ensure_addon()
    scene = mb.reset()
    m, nt, out = mb.empty_material("glow")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    em.inputs["Strength"].default_value = 1.0
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    mb.plane("Strip", x1 - x0, 2.0 * HEIGHT, m, (0.5 * (x0 + x1) - WIDTH / 2, 0.0, 0.0))
    cd = bpy.data.cameras.new("Camera")
    cd.type, cd.ortho_scale = "ORTHO", float(WIDTH)
    cd.clip_start, cd.clip_end = 0.1, 100.0
    cam = bpy.data.objects.new("Camera", cd)
    cam.location = (0.0, 0.0, 5.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = WIDTH, HEIGHT, 100
    r.use_border = False
    acc.set_pixel_filter(scene, kind, width)
    return scene


def profile(rgba: np.ndarray) -> np.ndarray:
    """Mean over the rows of the red channel, per column: (WIDTH,) float64."""
    return rgba[..., 0].astype(np.float64).mean(axis=0)


def render_cycles(name: str) -> np.ndarray:
    (x0, x1), kind, width = CASES[name]
    scene = strip_scene(x0, x1, kind, width)
    acc.set_cycles(scene, SAMPLES, seed=0, pixel_filter=(kind, width))
    img, _ = acc.render_rgba(scene)
    return profile(img)


def render_ours(name: str, spp: int = 256) -> np.ndarray:
    (x0, x1), kind, width = CASES[name]
    scene = strip_scene(x0, x1, kind, width)
    acc.set_photonmap_defaults(scene, pixel_filter=(kind, width))
    scene.photonmap.spp = spp
    scene.photonmap.photon_mapping = False
    img, _ = acc.render_rgba(scene)
    return profile(img)


def main():
    out = dict(width=WIDTH, height=HEIGHT, samples=SAMPLES, blender=bpy.app.version_string,
               cases={})
    for name, ((x0, x1), kind, width) in CASES.items():
        p = render_cycles(name)
        out["cases"][name] = dict(x0=x0, x1=x1, filter=kind, width=width,
                                  profile=[round(float(v), 6) for v in p])
        print(name, np.round(p[12:20], 4), flush=True)
    with open(REF_PATH, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
