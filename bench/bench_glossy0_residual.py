"""The smooth glass of water's Glossy-0 residual (docs/accuracy.md, turnedcamera45): the
table's light through the glass by the caustic photons against the same light
path-traced by ours' final-gather chains, on tests/blender/test_glass_of_water_cycles.py's
scene (16 x 16) at Light Paths Glossy G, ours only, one thread, seed 0.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glossy0_residual.py G SHADING SPP [water|empty]

Three renders of one exported scene: as it is ("photons"); with
turnedlight.TurnedReflections.turned patched to flag every glass continuation, so every
gather chain through glass adds the sun disc it escapes into ("traced": the photons'
light plus the path-traced one); and with the caustic estimate left out
(integrator._photon_terms patched). Prints the pass means and the split.
"""
import os, sys, pickle, time
ROOT = os.getcwd()
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import numpy as np
import bpy, addon
addon.register()
from addon import export
from addon.core import load_engine
from blender_helpers import cheap, cycles_plain
from test_glass_of_water_cycles import _scene
glossy = int(sys.argv[1]); shading = sys.argv[2]; spp = int(sys.argv[3])
water = (sys.argv[4] if len(sys.argv) > 4 else "water") == "water"
bpy.ops.wm.read_homefile(use_empty=True)
sc = bpy.context.scene
_scene(bpy, sc, shading, water=water)
cycles_plain(sc, 16, 12)
sc.cycles.glossy_bounces = glossy
cheap(sc, spp=spp, photons=20_000, caustic_photons=100_000)
pm = load_engine()
scene, _ = export.export_scene(pm, bpy.context.evaluated_depsgraph_get(), width=16, height=16)
kw = sc.photonmap.to_settings_kwargs(False)
kw.update(workers=1, seed=0)
from engine.render import render
from engine.settings import RenderSettings
from engine import turnedlight
passes = ("direct", "indirect", "caustic", "specular", "emission")
def run():
    f = render(scene, RenderSettings(**kw))
    return {k: float(np.asarray(getattr(f, k)).mean()) for k in passes}
a = run()
orig = turnedlight.TurnedReflections.turned
def turned_all(self, y, rows, d_in, d_out):
    return self.glass_mat[np.asarray(y.mat)[rows]]
turnedlight.TurnedReflections.turned = turned_all
b = run()
turnedlight.TurnedReflections.turned = orig
from engine import integrator
orig_pt = integrator._photon_terms
def no_caustic(*a, **k):
    c, i = orig_pt(*a, **k)
    return np.zeros_like(c), i
integrator._photon_terms = no_caustic
c = run()
integrator._photon_terms = orig_pt
tot = lambda r: sum(r.values())
print("no caustic:", round(tot(c), 4), " => caustic photons", round(tot(a) - tot(c), 4),
      " path-traced chains to the sun", round(tot(b) - tot(a), 4), " rest", round(tot(c), 4),
      " PT total (rest + traced)", round(tot(b) - tot(a) + tot(c), 4))
print("glossy", glossy, shading, "spp", spp)
print("photons:   ", {k: round(v, 4) for k, v in a.items()}, "total", round(sum(a.values()), 4))
print("traced:    ", {k: round(v, 4) for k, v in b.items()}, "total - caustic", round(sum(b.values()) - b["caustic"], 4))
