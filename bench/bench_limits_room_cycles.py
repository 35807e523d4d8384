"""A closed room with a mirror ball and a glass ball (area light) at Total 5 and 64: live
Cycles (CSPP=512 spp) against ours with the lookups' subsets (chaincounts.GatherCounts.partial,
subset_irradiance; gatherlevel44, before it the last level's whole-map scale
last_level_scale) and without them (the map read whole, the read before s20), 48 x 36,
16 spp x 3 seeds (docs/performance.md, "limits").

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_limits_room_cycles.py
"""
import math, os, sys, tempfile
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
sys.path.insert(0, os.path.join(ROOT, "example_blends"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cycles_plain, read_rgba, render_exr
from engine import chaincounts
import make_blends as mb
scene = mb.reset()
wall = mb.material("wall", "diffuse", (0.8,) * 3)
mb.box("Room", 4, 5, 3, wall, location=(0, 0, 1.5))
mb.light("Lamp", "AREA", (0.0, 0.5, 2.9), 300.0, look_at=(0, 0.5, 0), size=0.8)
m, nt, out = mb.empty_material("mirror")
n = nt.nodes.new("ShaderNodeBsdfGlossy"); n.inputs["Roughness"].default_value = 0.0
n.inputs["Color"].default_value = (0.95, 0.95, 0.95, 1)
nt.links.new(n.outputs[0], out.inputs["Surface"])
mb.sphere("MBall", 0.6, m, (1.0, 1.0, 0.6))
mb.sphere("GBall", 0.6, mb.material("glass", "glass", (1, 1, 1), roughness=0.0, ior=1.5), (-1.0, 0.8, 0.6))
mb.camera((0.5, -2.2, 1.4), (-0.3, 2.0, 1.0), fov_deg=70)
mb.set_world((0.0, 0.0, 0.0))
scene.render.resolution_x, scene.render.resolution_y = 48, 36
scene.render.resolution_percentage = 100
orig = chaincounts.GatherCounts.partial
ones = lambda self, level, counts: np.zeros(len(counts), bool)
tmp = tempfile.mkdtemp()
for total in (5, 64):
    c = cycles_plain(scene, int(os.environ.get("CSPP", 512)), total)
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 64
    c.caustics_reflective = c.caustics_refractive = True
    scene.render.engine = "CYCLES"
    cyc = read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/rc.exr"))[..., :3].mean()
    scene.render.engine = "PHOTONMAP"
    pm = scene.photonmap
    pm.spp, pm.photons = 16, 100_000
    got = {}
    for name, fn in (("main", ones), ("branch", orig)):
        chaincounts.GatherCounts.partial = fn
        vals = []
        for seed in (0, 1, 2):
            pm.seed = seed
            vals.append(read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/ro.exr"))[..., :3].mean())
        got[name] = (np.mean(vals), np.std(vals) / np.sqrt(3))
    print(f"Total {total}: cycles {cyc:.5f}; " + "; ".join(
        f"{k} {v[0]:.5f} (se {v[1]:.5f}) / cycles {v[0] / cyc:.4f}" for k, v in got.items()), flush=True)
