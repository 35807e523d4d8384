"""Issue 14's house on a sunlit lawn (tests/blender/test_blender_bounces.py,
_house_on_a_lawn; 48 x 36) at Light Paths Diffuse 1 ... 32 (Total max(12, D), Glossy 4):
live Cycles (CSPP spp, seeds 0 and 1) against ours (16 spp, 100k photons, seeds 0 and 1),
image means and their ratio (docs/performance.md, bounces4). Run it on two checkouts for
an A/B (the Cycles images are the same).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_house_bounces_cycles.py
"""
import os, sys, tempfile
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
from test_blender_bounces import _house_on_a_lawn
scene = _house_on_a_lawn(bpy)
tmp = tempfile.mkdtemp()
for d in [int(x) for x in os.environ.get("DIFFS", "1,2,3,4,6,8,32").split(",")]:
    total = max(12, d)
    cyc = []
    for seed in (0, 1):
        c = cycles_plain(scene, int(os.environ.get("CSPP", 256)), total)
        c.seed = seed
        c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = d, 4, 12
        c.caustics_reflective = c.caustics_refractive = True
        scene.render.engine = "CYCLES"
        cyc.append(read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/c.exr"))[..., :3].mean())
    scene.render.engine = "PHOTONMAP"
    pm = default_photonmap(scene)
    pm.spp, pm.photons = 16, 100_000
    ours = []
    for seed in (0, 1):
        pm.seed = seed
        ours.append(read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/o.exr"))[..., :3].mean())
    cm, om = np.mean(cyc), np.mean(ours)
    print(f"Diffuse {d:2d}: cycles {cm:.5f} (seeds {cyc[0] / cm:.4f} / {cyc[1] / cm:.4f}) "
          f"ours {om:.5f} (seeds {ours[0] / cm:.4f} / {ours[1] / cm:.4f}) ratio {om / cm:.4f}",
          flush=True)
