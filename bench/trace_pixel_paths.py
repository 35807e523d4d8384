"""Which paths make a firefly pixel (docs/accuracy.md, turnedcamera45: newuser44's table).

    PYTHONPATH=$PWD .venv/bin/python bench/trace_pixel_paths.py SCENE.blend ROW COL

Exports SCENE.blend through the add-on (its Photon Mapping settings; 160 x 120; e.g.
`bench/newuser44_table.py ours X.exr --no-clamp --set final_gather=False --save
SCENE.blend` saves the table), renders it on one worker, and prints every contribution
to pixel (ROW, COL) above luminance 500 in one sample (Accumulator.add wrapped), then
that path bounce by bounce (_trace_paths' state at each bounce, read from its frame:
origin, direction, throughput, chain counts (total, glossy, transmission), ray class and
continuation pdf). The path is matched back from the escaping ray's origin by the ray
passing nearest it, so a row may be another sample's where several pass close.
"""

import pickle, sys, os
import numpy as np
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
from engine import integrator
def _export(blend):
    """(engine Scene, RenderSettings kwargs) of blend through the add-on, in a child
    Blender process (bpy's add-on and the engine's numba threads kept apart)."""
    import subprocess
    import tempfile
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = os.path.join(tempfile.mkdtemp(), "scene.pkl")
    subprocess.run([sys.executable, "-c", EXPORT, root, blend, out], check=True)
    with open(out, "rb") as f:
        return pickle.load(f)


EXPORT = """
import pickle, sys
sys.path.insert(0, sys.argv[1])
import bpy
import addon
addon.register()
from addon import export
from addon.core import load_engine
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
sc = bpy.context.scene
sc.render.resolution_x, sc.render.resolution_y = 160, 120
scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                               width=160, height=120)
with open(sys.argv[3], "wb") as f:
    pickle.dump((scene, sc.photonmap.to_settings_kwargs(False)), f)
"""

ensure_compiled()
scene, kw = _export(sys.argv[1])
PIX = int(sys.argv[2]) * scene.width + int(sys.argv[3])
thr = 500.0
kw = dict(kw, workers=1)
hist, big = [], []
orig_count = integrator.Counters.count
def count(self, stage, depth, n):
    if stage == "paths":
        f = sys._getframe(1).f_locals
        if "pix" in f and "o" in f and "bounce" in f:
            pix = np.asarray(f["pix"])
            rows = np.nonzero(pix == PIX)[0]
            if len(rows):
                hist.append((f["bounce"], np.asarray(f["o"])[rows].copy(), np.asarray(f["d"])[rows].copy(),
                             np.asarray(f["tp"])[rows].copy(), np.asarray(f["chain"])[rows].copy(),
                             np.broadcast_to(np.asarray(f["ray_cls"]), pix.shape)[rows].copy(),
                             np.asarray(f["pdf_b"])[rows].copy()))
    return orig_count(self, stage, depth, n)
integrator.Counters.count = count
orig = integrator.Accumulator.add
def add(self, name, pix, rgb, tp=None, rows=None):
    c = np.asarray(rgb, float)
    if tp is not None and len(c):
        t = np.asarray(tp)[rows] if rows is not None else np.asarray(tp)
        c = c * t
    if len(c):
        lum = c @ np.array([0.2126, 0.7152, 0.0722])
        p = np.asarray(pix)[rows] if rows is not None else np.asarray(pix)
        for b in np.nonzero((lum > thr) & (p == PIX))[0]:
            f = sys._getframe(1).f_locals
            r = rows[b] if rows is not None else b
            big.append(dict(name=name, lum=float(lum[b]), rgb=np.asarray(rgb)[b], bounce=f.get("bounce"),
                            o=np.asarray(f["o"])[r], d=np.asarray(f["d"])[r], tp=np.asarray(f["tp"])[r],
                            chain=np.asarray(f["chain"])[r], pdf_b=np.asarray(f["pdf_b"])[r],
                            cls=np.broadcast_to(np.asarray(f["ray_cls"]), (len(f["o"]),))[r]))
    return orig(self, name, pix, rgb, tp, rows)
integrator.Accumulator.add = add
film = render(scene, RenderSettings(**kw))
np.set_printoptions(precision=4, suppress=True, linewidth=200)
for e in big:
    print("BIG", e)
    # the path: match o backwards through hist
    p = e["o"]
    for bounce, o, d, tp, chain, cls, pdf in reversed(hist):
        if bounce > e["bounce"]:
            continue
        # the ray whose hit became the origin p: find the row at bounce-1 whose ray passes p
        if bounce == e["bounce"]:
            k = np.nonzero(np.all(np.isclose(o, e["o"]), axis=1))[0]
        else:
            v = nxt - o
            t = np.einsum("ij,ij->i", v, d)
            off = np.linalg.norm(v - t[:, None] * d / np.einsum("ij,ij->i", d, d)[:, None], axis=1)
            k = np.argsort(off)[:1]
        if not len(k):
            print("no match at bounce", bounce); break
        k = k[0]
        print("bounce", bounce, "o", o[k], "d", d[k], "tp", tp[k], "chain", chain[k], "cls", cls[k], "pdf_b", pdf[k])
        nxt = o[k]
