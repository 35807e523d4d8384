"""Compiled kernels, before / after: this checkout against an older commit (default
7be1f83, the last commit before the lookup / offset / camera-ray kernels), same machine,
one command.

    .venv/bin/python bench/bench_kernels.py [--base 7be1f83] [--quick]
        [--blends figure7_blocker,...] [--width 320 --height 240] [--repeat 1]

Prints Markdown tables:
- end to end per example blend at default settings (prepare + photons + camera), before
  and after, 1 and 2 workers: wall seconds, CPU seconds, peak RSS, and whether the image
  is bitwise the same (before vs after, and 1 vs 2 workers);
- gather-map lookups (the final gather's per-ray lookup) in microseconds and in Embree
  closest-hit traversals of the same scene, in one call and in a render's calls of a
  few thousand rows;
- peak memory per resolution (320x240 .. 1920x1080, 1 sample per pixel: chunks are
  bounded, so spp does not change the peak) and per photon count, estimated
  (engine/resources.py) and measured (ru_maxrss of a fresh process), with bytes per
  stored photon;
- the photon map stage alone (render._build_maps after the photon pass), before and
  after, 1 and 2 workers: CPU seconds of the process while it runs (only its threads
  work then), wall seconds, and whether the maps (every estimate, flag and stored
  photon the camera pass reads) are bitwise the same;
- cold compile (empty numba cache) and cached start (import + load), fresh processes;
- the camera pass of an example blend against raw Embree on its own rays (`--only camera`):
  the pass's CPU seconds (1 worker, best of --repeat, after its photon pass) and embreex
  replaying every closest-hit and occlusion query it made (camera, shadow, final gather,
  gather-lookup visibility and specular rays) on one thread: the issue's "camera +
  shadow stages against raw Embree" for whole default renders, gathers included;
- the final gather's regathers of a 1-worker render (`--only regather`, after only): ends
  regathered per level and why (the lookup met a boundary point, or the gather ray was
  short), their secondary-caustic k-NN queries (CPU us a query, and in raw Embree
  closest-hit traversals of the same scene), and the regathers' CPU split by cProfile
  (k-NN estimates, gather-map lookups, Embree, other kernels, Python / numpy glue);
- where a 1-worker render's CPU time goes (cProfile on the process clock, after only):
  compiled kernels, Embree, and the Python / numpy glue between them, which holds the GIL
  and so bounds what a second worker can gain (Amdahl: 2 / (1 + glue share)).
Every render runs in its own process; before and after alternate. The example blends are
exported once through the add-on (the bpy wheel) into pickled engine scenes.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDS = ("figure3_sphere", "figure6_box", "figure7_blocker", "figure8_caustic")
RESOLUTIONS = ((320, 240), (640, 480), (1280, 720), (1920, 1080))
PHOTON_COUNTS = (100_000, 1_600_000)

EXPORT = r"""
import pickle, sys
sys.path.insert(0, ROOT)
import bpy
from addon import export
from addon.core import load_engine
bpy.ops.wm.open_mainfile(filepath=f"{ROOT}/example_blends/{NAME}.blend")
scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get())
with open(OUT, "wb") as f:
    pickle.dump(scene, f)
print('{"ok": true}')
"""

RENDER = r"""
import hashlib, json, pickle, resource, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.render import render
from engine.resources import estimate_memory
from engine.settings import RenderSettings
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
settings = RenderSettings(workers=WORKERS, **SETTINGS)
est = estimate_memory(scene, settings).total
ru0 = resource.getrusage(resource.RUSAGE_SELF)
t0 = time.perf_counter()
film = render(scene, settings)
wall = time.perf_counter() - t0
ru = resource.getrusage(resource.RUSAGE_SELF)
h = hashlib.sha1()
for k in ("direct", "indirect", "caustic", "specular", "emission"):
    h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
st = film.stats
stored = st.get("global_photons", 0) + st.get("caustic_photons", 0)
print(json.dumps(dict(wall=wall, cpu=(ru.ru_utime + ru.ru_stime) - (ru0.ru_utime + ru0.ru_stime),
                      rss=ru.ru_maxrss * 1024, estimate=est, hash=h.hexdigest(),
                      photons=st.get("time_photons", 0.0), maps=st.get("time_photon_map", 0.0),
                      camera=st.get("time_camera", 0.0), prepare=st.get("time_prepare", 0.0),
                      stored=stored, photon_bytes=st.get("photon_bytes", 0))))
"""

LOOKUP = r"""
import json, pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.render import _photon_pass, prepare_context
from engine.settings import RenderSettings
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
ctx = prepare_context(scene, RenderSettings(workers=1))
_photon_pass(ctx, {}, None, None)
g = ctx.gather_map.complete().serial()  # (estimates made: the lookups timed alone)
rng = np.random.default_rng(1)
# Queries where gather rays end: rays from inside the scene's box to random directions.
lo, hi = ctx.geo.bounds
m = 200_000
o = lo + (hi - lo) * (0.25 + 0.5 * rng.random((m, 3)))
d = rng.normal(size=(m, 3))
d /= np.linalg.norm(d, axis=1)[:, None]
acc = ctx.accel.serial()
def cpu(fn):
    best = 1e9
    for _ in range(3):
        t = time.process_time(); out = fn(); best = min(best, time.process_time() - t)
    return best, out
ray_s, (t, prim, u, v) = cpu(lambda: acc.intersect(o, d))
hit = prim >= 0
from engine.bsdf import surface_hit
y = surface_hit(ctx.geo, ctx.table, prim[hit], u[hit], v[hit], d[hit])
look_s, (E, B) = cpu(lambda: g.lookup(y.p, y.ng, offset=y.offset))
# As a render calls it: a few thousand rows per call, spread over the whole scene (the
# gather rays of a chunk of pixels), so fewer neighbours share cache lines.
perm = np.random.default_rng(5).permutation(len(y.p))
calls = [perm[a:a + 2300] for a in range(0, len(perm), 2300)]
chunk_s, _ = cpu(lambda: [g.lookup(y.p[c], y.ng[c], offset=y.offset[c]) for c in calls])
print(json.dumps(dict(ray_us=ray_s / m * 1e6, lookup_us=look_s / hit.sum() * 1e6,
                      chunk_us=chunk_s / hit.sum() * 1e6,
                      lookups=int(hit.sum()), points=len(g.position),
                      found=float(np.mean(~B)), Esum=float(E.sum()))))
"""

# The engine's kernels, (module file, function), read from the sources: the child scripts'
# profiles count time inside them as "kernels".
KERNEL_NAMES = r"""
kernels = set()
for path in glob.glob(os.path.join(ROOT, "engine", "**", "*.py"), recursive=True):
    lines = open(path).read().splitlines()
    for i, line in enumerate(lines):
        if line.strip() == "@kernel":
            m = next((re.match(r"\s*def (\w+)", x) for x in lines[i + 1:i + 3]
                      if re.match(r"\s*def (\w+)", x)), None)
            if m:
                kernels.add((os.path.basename(path), m.group(1)))
"""

PROFILE = r"""
import cProfile, glob, json, os, pickle, re, sys, time
sys.path.insert(0, ROOT)
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
""" + KERNEL_NAMES + r"""
pr = cProfile.Profile(time.process_time)
pr.enable()
film = render(scene, RenderSettings(workers=1))
pr.disable()
pr.create_stats()
parts = dict(kernels=0.0, embree=0.0, glue=0.0, other=0.0)
glue = {}
for (path, line, name), (cc, nc, tt, ct, callers) in pr.stats.items():
    base = os.path.basename(path)
    if (base, name) in kernels:
        parts["kernels"] += tt
    elif base == "accel.py" and name in ("work", "_occluded"):
        parts["embree"] += tt
    elif "acquire" in name or "/numba/" in path or "llvmlite" in path:
        parts["other"] += tt  # waits for worker threads, lazy compiles
    else:
        parts["glue"] += tt
        key = f"{base}:{name}" if base != "~" else \
            (name.split("'")[1] if name.startswith("<method '") else name.strip("<>"))
        glue[key] = glue.get(key, 0.0) + tt
top = sorted(glue.items(), key=lambda x: -x[1])[:6]
# Every function by its own time (tottime), named and sorted, with its category; and the
# camera pass's stages by their inclusive time (cumtime; a recursive stage counted once).
own = {}
for (path, line, name), (cc, nc, tt, ct, callers) in pr.stats.items():
    base = os.path.basename(path)
    cat = ("kernel" if (base, name) in kernels else
           "embree" if base == "accel.py" and name in ("work", "_occluded") else
           "wait / compile" if "acquire" in name or "/numba/" in path or "llvmlite" in path
           else "glue")
    key = f"{base}:{name}" if base != "~" else \
        (name.split("'")[1] if name.startswith("<method '") else name.strip("<>"))
    o = own.setdefault(key, [cat, 0.0, 0])
    o[1] += tt
    o[2] += nc
ranked = sorted(([k, *v] for k, v in own.items()), key=lambda x: -x[2])[:TOP]
STAGES = (("render.py", "shoot_photons"), ("render.py", "_build_maps"),
          ("integrator.py", "render_camera"), ("integrator.py", "direct_irradiance"),
          ("integrator.py", "gather_indirect"), ("integrator.py", "_regather"),
          ("integrator.py", "_secondary_irradiance"), ("integrator.py", "_smooth_estimate"),
          ("photonmap.py", "lookup"), ("photonmap.py", "irradiance"),
          ("integrator.py", "continue_specular"), ("bsdf.py", "surface_hit_lobes"),
          ("bsdf.py", "surface_hit"))
cum = {f"{b}:{n}": 0.0 for b, n in STAGES}
for (path, line, name), (cc, nc, tt, ct, callers) in pr.stats.items():
    key = f"{os.path.basename(path)}:{name}"
    if key in cum:
        cum[key] += ct
print(json.dumps(dict(parts=parts, top=top, camera=film.stats.get("time_camera", 0.0),
                      ranked=ranked, stages=cum)))
"""

MAPS = r"""
import hashlib, importlib, json, pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.settings import RenderSettings
render = importlib.import_module("engine.render")
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
ctx = render.prepare_context(scene, RenderSettings(workers=WORKERS))
build, spent = render._build_maps, {}
def timed(*a, **kw):
    c, w = time.process_time(), time.perf_counter()
    out = build(*a, **kw)
    spent.update(cpu=time.process_time() - c, wall=time.perf_counter() - w)
    return out
render._build_maps = timed
render.shoot_photons(ctx, {})
h = hashlib.sha1()
def add(m):
    if m is None:
        return
    for name in ("E", "boundary", "position", "normal"):
        if hasattr(m, name):
            h.update(np.ascontiguousarray(getattr(m, name)).tobytes())
    if hasattr(m, "photons"):
        for name in ("position", "power", "direction", "normal", "kind"):
            h.update(np.ascontiguousarray(getattr(m.photons, name)).tobytes())
for m in (ctx.gather_map, ctx.caustic_map, ctx.secondary_map, ctx.global_map,
          *ctx.regather_maps, *ctx.regather_secondary):
    add(m)
h.update(np.float64([ctx.global_radius, ctx.caustic_radius, ctx.secondary_radius,
                     ctx.gather_short]).tobytes())
print(json.dumps(dict(spent, hash=h.hexdigest())))
"""

CAMERA = r"""
import contextlib, dataclasses, hashlib, json, pickle, sys, time
sys.path.insert(0, ROOT)
sys.path.insert(0, ROOT + "/bench")
import numpy as np
from engine.jit import ensure_compiled
ensure_compiled()
import importlib
R = importlib.import_module("engine.render")
from engine.film import Film
from engine.integrator import render_camera
from engine.settings import RenderSettings
from bench_core import RecordingAccel, raw_embree_time, recording
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
ctx = R.prepare_context(scene, RenderSettings(workers=1), RecordingAccel)
rec = recording(ctx.accel)
R.shoot_photons(ctx, {})
pages = getattr(R, "small_pages", contextlib.nullcontext)  # (trees before it: none)
region = (0, 0, W, H)
if ctx.gather_rays and ctx.gather_rays != ctx.settings.gather_rays:  # as render_pass
    ctx = dataclasses.replace(ctx, settings=dataclasses.replace(
        ctx.settings, gather_rays=ctx.gather_rays))
rec.log.clear()
film = Film(W, H)
with pages():
    render_camera(ctx, region, film)  # logs the pass's queries
log = list(rec.log)
rec.log.clear()
rec.enabled = False
h = hashlib.sha1()
for k in ("direct", "indirect", "caustic", "specular", "emission"):
    h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
cpu = float("inf")
for _ in range(REPEAT):
    c0 = time.process_time()
    with pages():
        render_camera(ctx, region, Film(W, H))
    cpu = min(cpu, time.process_time() - c0)
raw = float("inf")
for _ in range(REPEAT):
    c0 = time.process_time()
    raw_embree_time(rec, log)
    raw = min(raw, time.process_time() - c0)
closest = sum(len(e[1]) for e in log if e[0] == "INTERSECT")
occluded = sum(len(e[1]) for e in log if e[0] != "INTERSECT")
print(json.dumps(dict(cpu=cpu, raw=raw, closest=closest, occluded=occluded,
                      hash=h.hexdigest())))
"""

REGATHER = r"""
import cProfile, collections, glob, json, os, pickle, re, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
import engine.integrator as I
import engine.photonmap as PM
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
""" + KERNEL_NAMES + r"""
count = collections.Counter()
# (One worker: the wrappers below count from the only thread that calls them.)
add_gathered, regather, irradiance = I.add_gathered, I._regather, PM.PhotonMap.irradiance
def counted_add(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, again_ok, again):
    if again_ok:
        lvl = sys._getframe(1).f_locals["level"] + 1
        b, s = boundary.astype(bool), lt < short
        count[f"lookups {lvl}"] += len(rows)
        count[f"boundary {lvl}"] += int((b & ~s).sum())
        count[f"short {lvl}"] += int((s & ~b).sum())
        count[f"both {lvl}"] += int((s & b).sum())
    return add_gathered(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, again_ok, again)
def timed_knn(self, p, *a, **kw):
    if sys._getframe(1).f_code.co_name != "_secondary_irradiance":
        return irradiance(self, p, *a, **kw)
    c0 = time.process_time()
    out = irradiance(self, p, *a, **kw)
    count["knn s"] += time.process_time() - c0
    count["knn queries"] += len(p)
    return out
pr = cProfile.Profile(time.process_time)
def profiled(ctx, E, pending, G, rng, counters, level, *a):
    if level:
        return regather(ctx, E, pending, G, rng, counters, level, *a)
    pr.enable()
    try:
        return regather(ctx, E, pending, G, rng, counters, level, *a)
    finally:
        pr.disable()
def timed(ctx, E, pending, G, rng, counters, level, *a):
    if level:
        return regather(ctx, E, pending, G, rng, counters, level, *a)
    c1 = time.process_time()
    try:
        return regather(ctx, E, pending, G, rng, counters, level, *a)
    finally:
        count["regathers s"] += time.process_time() - c1
# Two renders of the same bits: one counts and times the regathers without the profiler
# (whose per-call cost would read as glue; the counting wrappers cost ~1 % of it), one is
# profiled.
I.add_gathered, PM.PhotonMap.irradiance, I._regather = counted_add, timed_knn, timed
c0 = time.process_time()
film = render(scene, RenderSettings(workers=1))
cpu = time.process_time() - c0
I.add_gathered, PM.PhotonMap.irradiance, I._regather = add_gathered, irradiance, profiled
render(scene, RenderSettings(workers=1))
pr.create_stats()
parts = dict(knn=0.0, lookup=0.0, embree=0.0, kernels=0.0, glue=0.0)
glue = {}
for (path, line, name), (cc, nc, tt, ct, callers) in pr.stats.items():
    base = os.path.basename(path)
    if name == "_irradiance_rows":
        parts["knn"] += tt
    elif name in ("_gather_candidates", "morton_order", "_agreeing_lists", "_list_rays",
                  "_pick_visible"):
        parts["lookup"] += tt
    elif base == "accel.py" and name in ("work", "_occluded", "_intersect_packets"):
        parts["embree"] += tt
    elif (base, name) in kernels:
        parts["kernels"] += tt
    elif path != "<string>":  # (not this script's wrapper)
        parts["glue"] += tt
        key = f"{base}:{name}" if base != "~" else \
            (name.split("'")[1] if name.startswith("<method '") else name.strip("<>"))
        glue[key] = glue.get(key, 0.0) + tt
stages = film.stats.get("ray_stages", {})
# One Embree traversal of this scene: closest hits of rays from inside its box.
from engine.render import prepare_context
ctx = prepare_context(scene, RenderSettings(workers=1))
rng = np.random.default_rng(1)
lo, hi = ctx.geo.bounds
o = lo + (hi - lo) * (0.25 + 0.5 * rng.random((200_000, 3)))
d = rng.normal(size=(200_000, 3))
d /= np.linalg.norm(d, axis=1)[:, None]
acc = ctx.accel.serial()
ray = float("inf")
for _ in range(3):
    c1 = time.process_time()
    acc.intersect(o, d)
    ray = min(ray, (time.process_time() - c1) / len(o))
top = sorted(glue.items(), key=lambda x: -x[1])[:5]
print(json.dumps(dict(cpu=cpu, count=dict(count), parts=parts, ray_ns=ray * 1e9, top=top,
                      ends={k: v for k, v in stages.items() if k.startswith("regathered")})))
"""

COMPILE = r"""
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, ROOT)
from engine.jit import ensure_compiled, needs_compile
cold = needs_compile()
t1 = time.perf_counter()
ensure_compiled()
print(json.dumps(dict(import_s=t1 - t0, compile_s=time.perf_counter() - t1, cold=cold)))
"""


def child(code: str, env=None, **values) -> dict:
    head = "".join(f"{k}={v!r}\n" for k, v in values.items())
    out = subprocess.run([sys.executable, "-c", head + code], capture_output=True, text=True,
                         env=env)
    if out.returncode != 0:
        raise RuntimeError(f"child failed ({values.get('ROOT')}):\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def base_tree(commit: str, where: str) -> str:
    path = os.path.join(where, f"base-{commit}")
    if not os.path.isdir(path):
        os.makedirs(path)
        archive = subprocess.run(["git", "-C", ROOT, "archive", commit], capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", path], input=archive, check=True)
    return path


def exported(name: str, where: str) -> str:
    out = os.path.join(where, f"{name}.pkl")
    if not os.path.exists(out):
        os.makedirs(where, exist_ok=True)  # a fresh machine's /tmp has no such folder
        child(EXPORT, ROOT=ROOT, NAME=name, OUT=out)
    return out


def mb(x):
    return x / (1 << 20)


def end_to_end(roots, blends, args, where):
    print(f"\n### End to end, default settings, {args.width}x{args.height}\n")
    print("| blend | workers | before wall s | after wall s | wall gain | before CPU s | "
          "after CPU s | CPU gain | after: photons / maps / camera s | peak RSS before / "
          "after MB | image |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|---|---|")
    for name in blends:
        pkl = exported(name, where)
        hashes = {}
        for workers in args.workers:
            res = {"before": [], "after": []}
            for _ in range(args.repeat):
                for label in ("before", "after"):
                    res[label].append(child(RENDER, ROOT=roots[label], PICKLE=pkl,
                                            W=args.width, H=args.height, WORKERS=workers,
                                            SETTINGS={}))
            b = min(res["before"], key=lambda r: r["wall"])
            a = min(res["after"], key=lambda r: r["wall"])
            bc = min(r["cpu"] for r in res["before"])
            ac = min(r["cpu"] for r in res["after"])
            hashes[workers] = a["hash"]
            same = "same bits" if a["hash"] == b["hash"] else "DIFFERS"
            if len(hashes) > 1:
                same += ", 1 = 2 workers" if len(set(hashes.values())) == 1 else \
                    ", 1 vs 2 workers DIFFER"
            print(f"| {name} | {workers} | {b['wall']:.1f} | {a['wall']:.1f} | "
                  f"{b['wall'] / a['wall']:.2f}x | {bc:.1f} | {ac:.1f} | {bc / ac:.2f}x | "
                  f"{a['photons']:.1f} / {a['maps']:.1f} / {a['camera']:.1f} | "
                  f"{mb(b['rss']):.0f} / {mb(a['rss']):.0f} | {same} |", flush=True)


def lookups(roots, args, where):
    print("\n### Gather-map lookups (one thread, CPU time, best of 3)\n")
    print("| scene | gather points | version | one lookup us | Embree closest-hit us | "
          "lookup in Embree traversals | in calls of 2,300 rows: us / traversals |")
    print("|---|---:|---|---:|---:|---:|---|")
    for name in args.lookup_blends:
        pkl = exported(name, where)
        for label in ("before", "after"):
            r = child(LOOKUP, ROOT=roots[label], PICKLE=pkl)
            print(f"| {name} | {r['points']:,} | {label} | {r['lookup_us']:.2f} | "
                  f"{r['ray_us']:.3f} | {r['lookup_us'] / r['ray_us']:.1f} | "
                  f"{r['chunk_us']:.2f} / {r['chunk_us'] / r['ray_us']:.1f} |", flush=True)


def memory(roots, args, where):
    pkl = exported("figure6_box", where)
    print("\n### Peak memory, Figure 6 box (fresh process each; 1 spp)\n")
    print("| case | version | estimate MB | measured peak RSS MB | stored photons | "
          "B / stored photon |")
    print("|---|---|---:|---:|---:|---:|")
    cases = [(f"{w}x{h}", w, h, {"spp": 1}) for w, h in RESOLUTIONS[:args.resolutions]]
    cases += [(f"{n:,} + {n // 2:,} photons, 160x120", 160, 120,
               {"spp": 1, "photons": n, "caustic_photons": n // 2})
              for n in PHOTON_COUNTS[:args.photon_counts]]
    for label, w, h, settings in cases:
        for version in ("before", "after"):
            r = child(RENDER, ROOT=roots[version], PICKLE=pkl, W=w, H=h, WORKERS=2,
                      SETTINGS=settings)
            per = r["photon_bytes"] / max(r["stored"], 1)
            print(f"| {label} | {version} | {mb(r['estimate']):.0f} | {mb(r['rss']):.0f} | "
                  f"{r['stored']:,} | {per:.0f} |", flush=True)


def compile_times(roots):
    print("\n### Kernel compile (fresh processes)\n")
    print("| version | cold: import s | cold: compile s | cached: import s | cached: load s |")
    print("|---|---:|---:|---:|---:|")
    for label in ("before", "after"):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            cold = child(COMPILE, env=env, ROOT=roots[label])
            warm = child(COMPILE, env=env, ROOT=roots[label])
        print(f"| {label} | {cold['import_s']:.2f} | {cold['compile_s']:.2f} | "
              f"{warm['import_s']:.2f} | {warm['compile_s']:.2f} |", flush=True)


def map_stage(roots, blends, args, where):
    print("\n### The photon map stage (render._build_maps), default settings\n")
    print("| blend | workers | before CPU s | after CPU s | CPU gain | before wall s | "
          "after wall s | wall gain | maps |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for name in blends:
        pkl = exported(name, where)
        for workers in args.workers:
            res = {"before": [], "after": []}
            for _ in range(max(args.repeat, 2)):
                for label in ("before", "after"):
                    res[label].append(child(MAPS, ROOT=roots[label], PICKLE=pkl,
                                            W=args.width, H=args.height, WORKERS=workers))
            bc, ac = (min(r["cpu"] for r in res[x]) for x in ("before", "after"))
            bw, aw = (min(r["wall"] for r in res[x]) for x in ("before", "after"))
            same = "same bits" if res["before"][0]["hash"] == res["after"][0]["hash"] else \
                "DIFFER"
            print(f"| {name} | {workers} | {bc:.2f} | {ac:.2f} | {bc / ac:.2f}x | {bw:.2f} | "
                  f"{aw:.2f} | {bw / aw:.2f}x | {same} |", flush=True)


def camera_vs_embree(roots, blends, args, where):
    print(f"\n### Camera pass against raw Embree on its own rays, default settings, "
          f"{args.width}x{args.height}, 1 worker (CPU s, best of {args.repeat})\n")
    print("| blend | tree | closest-hit rays | occlusion rays | camera pass CPU s | "
          "raw Embree CPU s | % of raw Embree | film |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for name in blends:
        got = {}
        for tag in ("before", "after"):
            got[tag] = r = child(CAMERA, ROOT=roots[tag], PICKLE=exported(name, where),
                                 W=args.width, H=args.height, REPEAT=args.repeat)
            same = "" if tag == "before" else \
                ("same bits" if r["hash"] == got["before"]["hash"] else "DIFFERS")
            print(f"| {name} | {tag} | {r['closest']:,} | {r['occluded']:,} | "
                  f"{r['cpu']:.2f} | {r['raw']:.2f} | {100 * r['raw'] / r['cpu']:.1f} | "
                  f"{r['hash'][:8]} {same} |", flush=True)


def regathers(roots, blends, args, where):
    print(f"\n### The final gather's regathers, default settings, {args.width}x{args.height}, "
          f"1 worker (after; render and regathers: CPU s unprofiled; their split: cProfile "
          f"on the process clock, whose own per-call cost lands in the glue)\n")
    print("| blend | render CPU s | regathers CPU s | ends level 1 / 2 | why regathered "
          "(boundary / short / both), level 1; level 2 | secondary k-NN queries | us a query "
          "| Embree ns a ray | traversals a query | profiled: k-NN / lookups / Embree / "
          "kernels / glue s | largest glue items (s) |")
    print("|---|---:|---:|---|---|---:|---:|---:|---:|---|---|")
    for name in blends:
        r = child(REGATHER, ROOT=roots["after"], PICKLE=exported(name, where), W=args.width,
                  H=args.height)
        c, p, e = r["count"], r["parts"], r["ends"]
        ends = " / ".join(f"{e.get(f'regathered {lv}', 0):,}" for lv in (1, 2))
        why = "; ".join(" / ".join(f"{c.get(f'{k} {lv}', 0):,}" for k in
                                   ("boundary", "short", "both")) for lv in (1, 2))
        q = c.get("knn queries", 0)
        us = 1e6 * c.get("knn s", 0.0) / max(q, 1)
        split = " / ".join(f"{p[k]:.2f}" for k in ("knn", "lookup", "embree", "kernels", "glue"))
        print(f"| {name} | {r['cpu']:.1f} | {c.get('regathers s', 0.0):.2f} | {ends} | {why} | "
              f"{q:,} | {us:.2f} | {r['ray_ns']:.0f} | {1e3 * us / r['ray_ns']:.0f} | {split} | "
              f"{', '.join(f'{k} {v:.2f}' for k, v in r['top'])} |", flush=True)


def glue_profile(roots, blends, args, where):
    print(f"\n### Where a 1-worker render's CPU goes (cProfile, process clock, "
          f"{args.width}x{args.height}, after)\n")
    print("| blend | profiled CPU s | kernels s | Embree s | Python + numpy glue s | glue share "
          "| 2-worker bound | largest glue items (s) |")
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    ranked = []
    for name in blends:
        r = child(PROFILE, ROOT=roots["after"], PICKLE=exported(name, where), W=args.width,
                  H=args.height, TOP=args.top)
        p = r["parts"]
        total = sum(p.values())
        share = p["glue"] / total
        top = ", ".join(f"{k} {v:.2f}" for k, v in r["top"])
        print(f"| {name} | {total:.1f} | {p['kernels']:.1f} | {p['embree']:.1f} | "
              f"{p['glue']:.1f} | {100 * share:.0f} % | {2 / (1 + share):.2f}x | {top} |",
              flush=True)
        ranked.append((name, total, r))
    for name, total, r in ranked:
        print(f"\n#### {name}: stages (inclusive CPU s, profiled; camera pass "
              f"{r['stages']['integrator.py:render_camera']:.2f} s)\n")
        print("| stage | CPU s | share of render |")
        print("|---|---:|---:|")
        for k, v in sorted(r["stages"].items(), key=lambda x: -x[1]):
            print(f"| {k} | {v:.2f} | {100 * v / total:.1f} % |")
        print(f"\n#### {name}: functions by own CPU (profiled, top {len(r['ranked'])})\n")
        print("| function | kind | own CPU s | share of render | calls |")
        print("|---|---|---:|---:|---:|")
        for k, cat, tt, nc in r["ranked"]:
            print(f"| {k} | {cat} | {tt:.2f} | {100 * tt / total:.1f} % | {nc:,} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="7be1f83", help="commit to compare against")
    ap.add_argument("--before-root", default=None,
                    help="an existing checkout of --base to measure as 'before' (numba caches "
                         "by source path: a checkout compiled already saves a compile)")
    ap.add_argument("--after", default=None,
                    help="commit to measure as 'after' (default: this working tree)")
    ap.add_argument("--blends", default=",".join(BLENDS))
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--workers", default="2,1", help="worker counts for end to end")
    ap.add_argument("--repeat", type=int, default=1, help="best of this many per version")
    ap.add_argument("--resolutions", type=int, default=len(RESOLUTIONS))
    ap.add_argument("--photon-counts", type=int, default=len(PHOTON_COUNTS))
    ap.add_argument("--only", default="compile,lookups,end_to_end,maps,memory,profile")
    ap.add_argument("--quick", action="store_true",
                    help="160x120, Figure 7 only, 2 workers, two resolutions, one photon count")
    ap.add_argument("--top", type=int, default=25,
                    help="profile: functions listed by their own CPU time")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    args = ap.parse_args(argv)
    args.workers = [int(w) for w in args.workers.split(",")]
    if args.quick:
        args.width, args.height, args.blends, args.workers = 160, 120, "figure7_blocker", [2]
        args.resolutions, args.photon_counts = 2, 1
    args.lookup_blends = ["figure6_box", "figure7_blocker"]
    blends = args.blends.split(",")
    os.makedirs(args.work, exist_ok=True)
    roots = {"before": args.before_root or base_tree(args.base, args.work),
             "after": ROOT if args.after is None else base_tree(args.after, args.work)}
    head = args.after or subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                                        capture_output=True, text=True).stdout.strip() \
        + " (+ working tree)"
    print(f"before = {args.base}, after = {head}; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    only = args.only.split(",")
    if "compile" in only:
        compile_times(roots)
    if "lookups" in only:
        lookups(roots, args, args.work)
    if "end_to_end" in only:
        end_to_end(roots, blends, args, args.work)
    if "maps" in only:
        map_stage(roots, blends, args, args.work)
    if "memory" in only:
        memory(roots, args, args.work)
    if "profile" in only:
        glue_profile(roots, blends, args, args.work)
    if "camera" in only:
        camera_vs_embree(roots, blends, args, args.work)
    if "regather" in only:
        regathers(roots, blends, args, args.work)


if __name__ == "__main__":
    main()
