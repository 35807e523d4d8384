"""The glass of water (tests/blender/test_glass_of_water_cycles.py's _scene) rendered by
Cycles or ours at Light Paths > Max Bounces L (Transmission 64 unless --trans), one image
per seed saved as an (S, H, W, 3) .npy, each image's mean printed as a ratio to the
test's stored Cycles mean at 12 bounces (docs/accuracy.md "### glasswater51").

    PYTHONPATH=$PWD .venv/bin/python bench/glasswater51_scan.py cycles|ours flat|smooth L
        [--spp N] [--seeds 0,1,...] [--clamp C] [--knob module.attr=value] --out FILE.npy

Cycles: cycles_plain(scene, spp, L) (no clamp, Filter Glossy 0); ours: the tests'
cheap(spp, photons, caustic_photons), Filter Glossy 0, Clamp Indirect as the scene's
(Blender's 10) unless --clamp; --knob sets a module attribute before the render (an
A/B switch), --pm a Photon Mapping property."""
import argparse
import importlib
import os
import sys
import tempfile

import numpy as np
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
ap = argparse.ArgumentParser()
ap.add_argument("engine"); ap.add_argument("shading"); ap.add_argument("L", type=int)
ap.add_argument("--trans", type=int, default=64); ap.add_argument("--glossy", type=int, default=None)
ap.add_argument("--diffuse", type=int, default=None)
ap.add_argument("--spp", type=int, default=64); ap.add_argument("--photons", type=int, default=200_000)
ap.add_argument("--caustic", type=int, default=100_000)
ap.add_argument("--seeds", default="0"); ap.add_argument("--out", required=True)
ap.add_argument("--knob", action="append", default=[])
ap.add_argument("--pm", action="append", default=[])
ap.add_argument("--clamp", type=float, default=None)
a = ap.parse_args()
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
import test_glass_of_water_cycles as W
for k in a.knob:
    name, val = k.split("=")
    mod, attr = name.rsplit(".", 1)
    setattr(importlib.import_module(mod), attr, eval(val))
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
W._scene(bpy, scene, a.shading)
out = []
if a.engine == "cycles":
    cycles_plain(scene, a.spp, a.L)
else:
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=a.spp, photons=a.photons, caustic_photons=a.caustic)
    scene.cycles.blur_glossy = 0.0
    scene.cycles.max_bounces = a.L
    if a.clamp is not None:
        scene.cycles.sample_clamp_indirect = a.clamp
    for k in a.pm:
        name, val = k.split("=")
        setattr(scene.photonmap, name, eval(val))
scene.cycles.transmission_bounces = a.trans
if a.glossy is not None: scene.cycles.glossy_bounces = a.glossy
if a.diffuse is not None: scene.cycles.diffuse_bounces = a.diffuse
imgs = []
tmp = os.path.join(tempfile.gettempdir(), "glasswater51_scan")
os.makedirs(tmp, exist_ok=True)
for s in [int(x) for x in a.seeds.split(",")]:
    if a.engine == "cycles":
        scene.cycles.seed = s; scene.render.engine = "CYCLES"
    else:
        scene.photonmap.seed = s; scene.render.engine = "PHOTONMAP"
    p = render_exr(bpy, scene, os.path.join(tmp, f"{os.getpid()}_{s}.exr"))
    imgs.append(np.asarray(read_rgba(bpy, p))[..., :3])
imgs = np.array(imgs)
np.save(a.out, imgs)
ref = W._stored_means()[a.shading]
print(a.out, "means/ref12:", [round(float(i.mean()) / ref, 4) for i in imgs], "avg", round(float(imgs.mean()) / ref, 4))
