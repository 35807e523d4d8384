"""Light through a flat glass pane at low Light Paths limits by lobe (docs/performance.md,
"glossycap"), live Cycles against ours, image means at 40 x 30 (Cycles CSPP samples per
seed, SEEDS seeds, ours 16 spp): a floor lit through a pane (`pane`), a diffuse + glossy
floor under it (`glossy_pane`), a rough glass sheet under it seen from below
(`rough_glass`); the scenes of tests/blender/test_blender_bounces.py (_floor_lit_through).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_limits_lobes_cycles.py pane|glossy_pane|rough_glass
"""
import os, sys, tempfile, time
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
from test_blender_bounces import _floor_lit_through
which = sys.argv[1]
cases = {"pane": [(12, 1, 0, 1), (12, 4, 4, 12)],
         "glossy_pane": [(12, 1, 0, 12), (12, 1, 1, 12), (12, 0, 1, 12)],
         "rough_glass": [(12, 4, 4, 0), (12, 4, 4, 1), (12, 4, 4, 2)]}[which]
spp, seeds = int(os.environ.get("CSPP", 4096)), int(os.environ.get("SEEDS", 2))
tmp = tempfile.mkdtemp()
scene = _floor_lit_through(bpy, which)
if os.environ.get("NOPANE"):  # the same scene without the pane (the light seen directly)
    bpy.data.objects.remove(scene.objects["Pane"])
for lim in cases:
    cyc = []
    t0 = time.process_time()
    for seed in range(seeds):
        c = cycles_plain(scene, spp, lim[0])
        c.seed = seed
        c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = lim[1:]
        scene.render.engine = "CYCLES"
        cyc.append(float(read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/c.exr"))[..., :3].mean()))
    scene.render.engine = "PHOTONMAP"
    pm = default_photonmap(scene)
    pm.spp, pm.seed = 16, 0
    ours = read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/o.exr"))[..., :3].mean()
    print(f"{which} limits {lim}: cycles {np.mean(cyc):.5f} (seeds {' '.join(f'{v:.5f}' for v in cyc)}) "
          f"ours {ours:.5f} ours/cycles {ours / np.mean(cyc):.4f}", flush=True)
