"""tableroom45 (docs/accuracy.md "tableroom45"): working script, run from the worktree root with
PYTHONPATH=$PWD; reads and writes /tmp/tableroom45 (masks.npy from bench/newuser44_table.py
--masks, t_def.pkl from tableroom45_variant.py export)."""
import sys, os, pickle, time, importlib
sys.path.insert(0, os.getcwd())
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
R = importlib.import_module("engine.render"); I = importlib.import_module("engine.integrator")
ensure_compiled()
scene, kw = pickle.load(open("/tmp/tableroom45/t_def.pkl", "rb"))
spp = int(sys.argv[1])
for name, apart, every in (("main", False, True), ("apart+stride", True, False), ("main", False, True), ("apart+stride", True, False)):
    R.GLOW_MAP_APART, I.GLOW_EVERY_SAMPLE_PAST_BOUNCE = apart, every
    t = time.process_time()
    film = render(scene, RenderSettings(**dict(kw, workers=1, spp=spp, seed=0)))
    print(f"{name} spp={spp} cpu {time.process_time() - t:.1f} load {os.getloadavg()[0]:.1f}", flush=True)
