"""A render's photon pass (its global and caustic shots) against raw Embree on its rays.

    NUMBA_CACHE_DIR=... .venv/bin/python bench/bench_photon_shots.py CHECKOUT SCENE WORKERS \\
        [RENDERS] [--split] [--seed=N]

CHECKOUT is put first on sys.path (run it once per checkout, alternating, for an A/B).
SCENE: a paper blend exported as a pickled engine Scene (PICKLES/SCENE.pkl, rendered at
80 x 60 with the default settings and spp=16; PICKLES from the PHOTON_PICKLES environment
variable, default /tmp/filmsha, where the films check exports figure6_box, figure7_blocker
and figure8_caustic through the add-on), or "box" (bench_scaling.box at 500k photons).

Runs render.shoot_photons as a render does (inside render.small_pages), RENDERS times after
one warm-up, and times only its traces (render.trace_photons: emission, Embree, scatter,
the shot's copies; not the pilot or the map build): the median process CPU. The same
traces' rays, recorded once, are replayed through embreex (bench_core.raw_embree_time,
process CPU, best of 3). Prints one line: rays, traces CPU s, raw CPU s, raw / traces %,
each render's CPU s, stored photons and their summed power per shot, and a SHA-1 prefix
of the stored photons (the same on both sides of an A/B that keeps the bits). --split adds
the thread CPU of a render's traces by part (Accel.intersect_hits, the scatter kernel,
_Shot.append, the rest: emission kernels and Python glue), median over the renders.
"""
import hashlib
import importlib
import os
import pickle
import sys
import time

root = os.path.abspath(sys.argv[1])
name = sys.argv[2]
workers = int(sys.argv[3])
renders = int(sys.argv[4]) if len(sys.argv) > 4 and sys.argv[4].isdigit() else 5
split = "--split" in sys.argv
seed = next((int(a[7:]) for a in sys.argv if a.startswith("--seed=")), None)
sys.path.insert(0, os.path.join(root, "bench"))
sys.path.insert(0, root)

import numpy as np  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine import photonkernels as pk  # noqa: E402
from engine import photons as photons_mod  # noqa: E402
from engine.accel import Accel  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402
from bench_core import RecordingAccel, raw_embree_time  # noqa: E402

R = importlib.import_module("engine.render")  # engine.render is also a function's name
ensure_compiled()
kw = {} if seed is None else dict(seed=seed)
if name == "box":
    from bench_scaling import box
    scene, st = box(160, 120), RenderSettings(photons=500_000, workers=workers, **kw)
else:
    pickles = os.environ.get("PHOTON_PICKLES", "/tmp/filmsha")
    with open(os.path.join(pickles, f"{name}.pkl"), "rb") as f:
        scene = pickle.load(f)
    scene.width, scene.height = 80, 60
    st = RenderSettings(workers=workers, spp=16, **kw)
ctx = R.prepare_context(scene, st, RecordingAccel)
rec = getattr(ctx.accel, "full", ctx.accel)
rec.enabled = False
trace = R.trace_photons
state = dict(cpu=0.0, thread=0.0, log=False, shots=[])


def traced(*a, **k):
    rec.enabled = state["log"]
    c0, t0 = time.process_time(), time.thread_time()
    out = trace(*a, **k)
    state["cpu"] += time.process_time() - c0
    state["thread"] += time.thread_time() - t0
    rec.enabled = False
    state["shots"].append(out)
    return out


R.trace_photons = traced
spent = {}
if split:
    def timed(fn, part):
        def call(*a, **k):
            t0 = time.thread_time()
            out = fn(*a, **k)
            spent[part] = spent.get(part, 0.0) + time.thread_time() - t0
            return out
        return call
    pk.scatter = timed(pk.scatter, "scatter")
    Accel.intersect_hits = timed(Accel.intersect_hits, "embree")
    photons_mod._Shot.append = timed(photons_mod._Shot.append, "append")


def one():
    state.update(cpu=0.0, thread=0.0, shots=[])
    spent.clear()
    with R.small_pages():
        R.shoot_photons(ctx, {})
    return state["cpu"], state["thread"], dict(spent)


one()  # warm: loads kernels, faults the allocator's first arenas
rows = [one() for _ in range(renders)]
h = hashlib.sha1()
for shot in state["shots"]:
    for field in ("position", "power", "direction", "normal", "kind", "bounces"):
        h.update(np.ascontiguousarray(getattr(shot, field)).tobytes())
stored = [len(s) for s in state["shots"]]
power = [float(np.asarray(s.power, np.float64).sum()) for s in state["shots"]]
state["log"] = True
rec.log.clear()
one()
state["log"] = False
log = list(rec.log)
rec.log.clear()
rays = sum(len(e[1]) for e in log)
raw = float("inf")
for _ in range(3):
    c0 = time.process_time()
    raw_embree_time(rec, log)
    raw = min(raw, time.process_time() - c0)
cpu = sorted(r[0] for r in rows)[len(rows) // 2]
print(f"{os.path.basename(root):12s} {name:16s} workers={workers} load={os.getloadavg()[0]:.1f} "
      f"rays={rays / 1e6:.2f}M traces={cpu:.3f} s raw={raw:.3f} s {100 * raw / cpu:.1f} % of raw; "
      f"renders {' '.join(f'{r[0]:.3f}' for r in rows)}; stored {stored} "
      f"power {[f'{p:.6g}' for p in power]} sha {h.hexdigest()[:12]}", flush=True)
if split:
    def med(part):
        return sorted(r[2].get(part, 0.0) for r in rows)[len(rows) // 2]
    thread = sorted(r[1] for r in rows)[len(rows) // 2]
    rest = thread - med("embree") - med("scatter") - med("append")
    print(f"  thread CPU s: total {thread:.3f}, Embree {med('embree'):.3f}, scatter "
          f"{med('scatter'):.3f}, _Shot.append {med('append'):.3f}, rest {rest:.3f}")
