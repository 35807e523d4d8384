"""tableroom45 (docs/accuracy.md "tableroom45"): working script, run from the worktree root with
PYTHONPATH=$PWD; reads and writes /tmp/tableroom45 (masks.npy from bench/newuser44_table.py
--masks, t_def.pkl from tableroom45_variant.py export)."""
import sys, os, pickle, time, ast, importlib, json
sys.path.insert(0, os.getcwd())
import numpy as np
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
pkl, out, *rest = sys.argv[1:]
over, patches = {}, {}
for item in rest:
    k, v = item.split("=", 1)
    v = ast.literal_eval(v)
    if k == "CAPX":
        R = importlib.import_module("engine.render")
        _cr = R.caustic_radius
        R.caustic_radius = lambda *a, _f=v, **kw: _f * _cr(*a, **kw)
        continue
    if k.startswith("@"):
        mod, name = k[1:].rsplit(".", 1)
        setattr(importlib.import_module("engine." + mod), name, v)
    else:
        over[k] = v
ensure_compiled()
scene, kw = pickle.load(open(pkl, "rb"))
kw = dict(kw, workers=1); kw.update(over)
t = time.process_time()
film = render(scene, RenderSettings(**kw))
cpu = time.process_time() - t
P = {n: np.asarray(a) for n, a in film.passes().items() if n in ("combined", "direct", "indirect", "caustic", "specular", "emission")}
np.savez_compressed(out, **P)
st = {k: v for k, v in film.stats.items() if isinstance(v, (int, float, str)) and k != "effects"}
print(json.dumps(st, default=str))
print("RESULT cpu", round(cpu, 1), "shape", P["combined"].shape)
