"""The glowing bar's edge pixels against their exact value (lampvis51, item 3 of issue 14):
test_light_linking_cycles' glowing bar (Emission 20, 0.8 x 0.2 m, seen from above by an
orthographic camera, 48 x 48) alone on the floor, its emission seen directly. Each edge
pixel's expectation is 20 x the filter-weighted share of the pixel the bar's top covers,
computed from the pixel filter's own inverse CDF (engine/pixelfilter.py); the renders'
"emission" pass against it, summed over the bar's pixels and over the ones in
test_light_linking_cycles' "floor by CubeB" region (the bar's left half, |x| < 1).
Prints, per filter and spp: mean ratio and its standard error over SEEDS seeds, and the
mean of seeds 0-7 alone (the seeds docs/accuracy.md "flaky50" swept).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_emitter_edge.py [SEEDS [SPP,SPP..]]
"""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
import numpy as np  # noqa: E402
import bpy  # noqa: E402
import addon  # noqa: E402
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from addon import export  # noqa: E402
from addon.core import load_engine  # noqa: E402
from blender_helpers import cheap, cycles_plain  # noqa: E402
import test_light_linking_cycles as K  # noqa: E402
from engine import RenderSettings  # noqa: E402
from engine.pixelfilter import filter_table, lookup_filter  # noqa: E402
from engine.render import render  # noqa: E402

SEEDS = int(sys.argv[1]) if len(sys.argv) > 1 else 200
SPPS = [int(x) for x in (sys.argv[2] if len(sys.argv) > 2 else "25,32,256").split(",")]
RES, VIEW = K.RES, K.VIEW
X0, X1, Y0, Y1 = 0.6, 1.4, -1.3, -1.1  # the bar's top face (glowing_bar_scene)

scene, _ = K.glowing_bar_scene(bpy)
cycles_plain(scene, 16, 0)
cheap(scene, spp=32, photons=1_000, caustic_photons=0)
scene.photonmap.photon_mapping = False
pm_scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                  width=RES, height=RES)
pm_scene.lights = []  # (the fill lamp: the bar's pixels are its emission alone)
pm_scene.meshes = [m for m in pm_scene.meshes if m.name in ("Bar", "Floor")]
kw = dict(scene.photonmap.to_settings_kwargs(False), workers=1)

edges = np.arange(RES + 1) / RES * VIEW - VIEW / 2
centres = (np.arange(RES) + 0.5) / RES * VIEW - VIEW / 2
x = np.tile(centres, (RES, 1))
y = np.tile(-centres[:, None], (1, RES))
region = K._regions()["floor by CubeB"]


def exact(kind):
    """(RES, RES) expected emission a pixel (rows top to bottom)."""
    u = (np.arange(200_000) + 0.5) / 200_000
    pos = lookup_filter(filter_table(kind, 1.5), u) * (VIEW / RES)
    ex = np.array([np.mean((edges[i] + pos > X0) & (edges[i] + pos < X1)) for i in range(RES)])
    ey = np.array([np.mean((-edges[i] - pos > Y0) & (-edges[i] - pos < Y1))
                   for i in range(RES)])
    return 20.0 * ey[:, None] * ex[None, :]


print("| filter | spp | seeds | bar / exact (se) | its left half, in 'floor by CubeB' (se) "
      "| seeds 0-7 only: bar, left half |")
print("|---|---|---|---|---|---|")
for kind in ("blackman_harris", "box"):
    want = exact(kind)
    bar = want > 0.05
    half = bar & region
    for spp in SPPS:
        rows = []
        for seed in range(SEEDS if spp < 100 else min(SEEDS, 8)):
            f = render(pm_scene, RenderSettings(**dict(kw, spp=spp, seed=seed,
                                                       pixel_filter=kind)))
            img = np.asarray(f.emission, np.float64).mean(axis=2)
            rows.append((img[bar].sum() / want[bar].sum(), img[half].sum() / want[half].sum()))
        r = np.array(rows)
        se = r.std(axis=0, ddof=1) / np.sqrt(len(r))
        print(f"| {kind} | {spp} | {len(r)} | {r[:, 0].mean():.4f} ({se[0]:.4f}) | "
              f"{r[:, 1].mean():.4f} ({se[1]:.4f}) | {r[:8, 0].mean():.4f}, "
              f"{r[:8, 1].mean():.4f} |", flush=True)
