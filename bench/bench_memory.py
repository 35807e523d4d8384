"""Peak memory: the estimate engine/resources.py refuses renders with, beside the peak
resident memory measured for the same render (each in a fresh process, ru_maxrss after
the render minus before it). Prints a table; the estimate should stay above the
measurement without being far above it.

--triangles prints bytes per triangle instead (docs/performance.md, "Memory per
triangle"): a grid of 1M and 5M triangles in the Figure 3 scene, rendered tiny, each in a
fresh process: the resident memory the prepared scene keeps (geometry tables + BVHs)
and the peak during the render (the process's peak reset just before it), per triangle,
with the geometry's arrays one by one. The scene is rendered once without the grid
first, so the compiled kernels it loads are not counted. --smooth gives the grid and the
spheres vertex normals and UVs, else no mesh has either. --root measures another
checkout (e.g. the main branch, for a before/after table).

--photon-bytes prints bytes per stored photon instead (issue 13's "<= 64 B a stored
photon", docs/performance.md "perf47"): each pickled scene (an example blend's export,
or a (scene, settings) pair) rendered at 160 x 120, 16 spp, 1 worker, seed 0, in a fresh
process per checkout (--roots: e.g. the main branch and this one); at the camera pass'
start and end, the bytes of the arrays the maps hold (the Context's maps, each buffer
once, the same walk as engine/resources.held_bytes but self-contained, so an older
checkout is measured alike) by map, over the stored photons (global + caustic + glow),
beside the shots' arrays (the figure photon_bytes gave before perf47) and what the
photon-hit view keeps through the camera pass (before perf47 the shots' positions and
kinds; since, its chosen dots), and the render's CPU seconds. --arrays B lists, per
scene and checkout, the arrays of at least B bytes a stored photon at the camera pass'
end: path from the Context, dtype, shape (docs/performance.md "hdri52").

    .venv/bin/python bench/bench_memory.py [--quick] [--only HDRI]
    .venv/bin/python bench/bench_memory.py --triangles [--sizes 1000000 5000000] [--smooth]
    .venv/bin/python bench/bench_memory.py --photon-bytes --roots BASE . \
        --pickles $TMPDIR/film_hashes/figure6_box.pkl ... [--arrays 0.5]

(BASE: another checkout, e.g. `git worktree add /tmp/base main`; the pickles are the ones
tools/film_hashes.py writes.)
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)

# (label, scene, width, height, settings, extra triangles)
CASES = [
    ("defaults 160x120, Figure 3", "figure3", 160, 120, {"spp": 4}, 0),
    ("2M photons", "figure3", 64, 48, {"photons": 2_000_000, "caustic_photons": 0, "spp": 1}, 0),
    ("4M photons", "figure3", 64, 48, {"photons": 4_000_000, "caustic_photons": 0, "spp": 1}, 0),
    ("2M photons, closed box", "box", 32, 24, {"photons": 2_000_000, "caustic_photons": 0,
                                               "spp": 1}, 0),
    ("4M caustic photons", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 4_000_000,
                                               "spp": 1}, 0),
    ("1024x1024, 1 spp", "figure3", 1024, 1024, {"photons": 1000, "caustic_photons": 0,
                                                 "spp": 1}, 0),
    ("256 spp, 64x48", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 0, "spp": 256}, 0),
    ("256 spp, 8 gather rays", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 0,
                                                   "spp": 256, "gather_rays": 8}, 0),
    ("1M triangles", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 0, "spp": 1},
     1_000_000),
    # The Figure 3 ground lit by a 4k x 2k HDRI alone (its sampling tables: 170 MB).
    ("4k x 2k HDRI", "hdri", 64, 48, {"photons": 100_000, "caustic_photons": 0, "spp": 1}, 0),
]
QUICK = {"defaults 160x120, Figure 3", "2M photons", "256 spp, 64x48"}

CHILD = r"""
import json, resource, sys
sys.path.insert(0, ROOT)
import numpy as np
from engine import RenderSettings, render
from engine.api import cornell_box
from engine.resources import estimate_memory
from engine.scene import Mesh
from engine.scenefile import load_scene
scene = cornell_box() if NAME == "box" else load_scene(ROOT + "/scenes/figure3.toml")[0]
if NAME == "hdri":
    from engine import Environment
    h, w = 2048, 4096
    sky = np.empty((h, w, 3), np.float32)
    sky[:] = 0.3
    sky[h // 2:] = 0.02
    sky[h // 8, w // 3] = 5000.0
    scene.lights = []
    scene.environment = Environment(sky)
    del sky
scene.width, scene.height = W, H
if TRIS:
    n = int((TRIS / 2) ** 0.5)
    xs = np.linspace(-3, 3, n + 1)
    X, Y = np.meshgrid(xs, xs)
    V = np.stack([X.ravel(), Y.ravel() + 3, np.full(X.size, 0.01)], 1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    F = np.concatenate([np.stack([i, i + 1, i + n + 2], 1), np.stack([i, i + n + 2, i + n + 1], 1)])
    scene.add_mesh(Mesh("grid", V, F, materials=["white_plastic_dull"]))
    del V, F, X, Y, i
settings = RenderSettings(**SETTINGS)
est = estimate_memory(scene, settings)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
film = render(scene, settings)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"estimate": est.total, "parts": est.parts, "measured": peak - before}))
"""


TRIANGLES_CHILD = r"""
import gc, json, sys, time
sys.path.insert(0, ROOT)
sys.path.insert(0, BENCH)
from procmem import hwm, rss
import numpy as np
from engine import RenderSettings
from engine.render import prepare_context, render_pass
from engine.scene import Mesh
from engine.scenefile import load_scene




scene = load_scene(ROOT + "/scenes/figure3.toml")[0]
scene.width, scene.height = 32, 24
if not SMOOTH:  # no mesh has normals or UVs: the tables leave them out
    for m in scene.meshes:
        m.normals = m.uvs = None
settings = RenderSettings(photons=1000, caustic_photons=0, spp=1, workers=1)
# Render the scene once without the grid first: the compiled kernels it loads (tens of
# MB, the same for any scene) must not count as memory per triangle.
warm = prepare_context(scene, settings)
render_pass(warm, (0, 0, scene.width, scene.height))
del warm
gc.collect()
try:  # hand the warm-up's freed memory back, or the grid would reuse it uncounted
    import ctypes
    ctypes.CDLL("libc.so.6").malloc_trim(0)
except (OSError, AttributeError):
    pass
n = int((TRIS / 2) ** 0.5)
xs = np.linspace(-3, 3, n + 1)
X, Y = np.meshgrid(xs, xs)
V = np.stack([X.ravel(), Y.ravel() + 3, 0.01 + 0.02 * np.sin(X.ravel())], 1)
i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
F = np.concatenate([np.stack([i, i + 1, i + n + 2], 1), np.stack([i, i + n + 2, i + n + 1], 1)])
N = np.tile([0.0, 0.0, 1.0], (len(V), 1)) if SMOOTH else None
UV = V[:, :2].copy() if SMOOTH else None
scene.add_mesh(Mesh("grid", V, F, normals=N, uvs=UV, materials=["white_plastic_dull"]))
del V, F, X, Y, i, N, UV
T = sum(len(m.faces) for m in scene.meshes)
before = rss()
with open("/proc/self/clear_refs", "w") as f:  # reset the peak (VmHWM) to the current RSS
    f.write("5")
t0 = time.perf_counter()
ctx = prepare_context(scene, settings)
t_prepare = time.perf_counter() - t0
kept = rss() - before
peak_prepare = hwm() - before
geo = ctx.geo
arrays = {}
for name, value in vars(geo).items():
    if isinstance(value, np.ndarray) and value.ndim >= 1 and len(value) == geo.count:
        arrays[name] = value.nbytes / T
    elif isinstance(value, dict):
        for k, a in value.items():
            arrays[name + "." + k] = a.nbytes / T
render_pass(ctx, (0, 0, scene.width, scene.height))
peak = hwm() - before
print(json.dumps({"T": T, "kept": kept / T, "peak_prepare": peak_prepare / T,
                  "peak": peak / T, "arrays": arrays, "t_prepare": t_prepare}))
"""


def run_triangles(tris, smooth, root):
    code = f"ROOT={root!r}; BENCH={BENCH!r}; TRIS={tris}; SMOOTH={smooth}\n" + TRIANGLES_CHILD
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main_triangles(sizes, smooth, root):
    print(f"checkout {root}; grid in the Figure 3 scene, "
          + ("grid and spheres with vertex normals and UVs" if smooth
             else "no mesh with normals or UVs") + "; kernels loaded before measuring")
    print("| triangles | kept after preparing (B/tri) | peak preparing (B/tri) | "
          "peak in render (B/tri) | prepare + BVH (s) | geometry arrays (B/tri) |")
    print("|---|---|---|---|---|---|")
    for tris in sizes:
        r = run_triangles(tris, smooth, root)
        arrays = ", ".join(f"{k} {v:.0f}" for k, v in sorted(r["arrays"].items(),
                                                            key=lambda kv: -kv[1]) if v >= 1)
        total = sum(r["arrays"].values())
        print(f"| {r['T']:,} | {r['kept']:.0f} | {r['peak_prepare']:.0f} | {r['peak']:.0f} | "
              f"{r['t_prepare']:.1f} | {total:.0f}: {arrays} |", flush=True)


PHOTON_BYTES_CHILD = r"""
import importlib, json, pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.settings import RenderSettings
R = importlib.import_module("engine.render")
ensure_compiled()
FIELDS = ("global_map", "caustic_map", "glow_map", "gather_map", "secondary_map",
          "regather_maps", "regather_secondary", "gather_counts")


def held(roots, seen, arrays=None):
    # arrays: {path: [bytes, dtype, shape]} of each buffer, by the first path met
    total, stack = 0, list(roots)
    while stack:
        path, obj = stack.pop()
        if isinstance(obj, np.ndarray):
            base = obj
            while isinstance(base.base, np.ndarray):
                base = base.base
            key = ("a", base.__array_interface__["data"][0], base.nbytes)
            if key not in seen:
                seen.add(key)
                total += base.nbytes
                if arrays is not None:
                    arrays[path] = [base.nbytes, str(base.dtype), list(base.shape)]
            continue
        if obj is None or isinstance(obj, (int, float, str, bool)) or id(obj) in seen:
            continue
        seen.add(id(obj))
        if isinstance(obj, (list, tuple)):
            stack.extend((f"{path}[{i}]", v) for i, v in enumerate(obj))
        elif isinstance(obj, dict):
            stack.extend((f"{path}{{{k}}}", v) for k, v in obj.items())
        elif type(obj).__module__.startswith("engine.") and hasattr(obj, "__dict__"):
            stack.extend((f"{path}.{k}", v) for k, v in vars(obj).items() if k != "accel")
    return total


def parts(ctx, arrays=None):
    seen, out = set(), {}
    for name in FIELDS:  # (in this order: a regather map shares the gather map's arrays)
        out[name] = held([(name, getattr(ctx, name, None))], seen, arrays)
    return out


got = {}
camera = R.render_camera
def spy(ctx, *a, **kw):
    got["start"] = parts(ctx)
    try:
        return camera(ctx, *a, **kw)
    finally:
        got["arrays"] = {}
        got["end"] = parts(ctx, got["arrays"])
R.render_camera = spy
photon_pass = R.shoot_photons
def shots_spy(*a, **kw):
    shots = photon_pass(*a, **kw)
    got["hit_view"] = sum(ph.position.nbytes + ph.kind.nbytes for ph in shots)
    return shots
R.shoot_photons = shots_spy
if hasattr(R, "_photon_hit_dots"):  # (perf47 on: the view's dots alone are kept)
    dots_of = R._photon_hit_dots
    def dots_spy(*a, **kw):
        fraction, dots = dots_of(*a, **kw)
        got["hit_view"] = 0 if dots is None else sum(x.nbytes for x in dots)
        return fraction, dots
    R._photon_hit_dots = dots_spy
with open(PICKLE, "rb") as f:
    obj = pickle.load(f)
scene, kw = obj if isinstance(obj, tuple) else (obj, {})
scene.width, scene.height = 160, 120
cpu = time.process_time()
film = R.render(scene, RenderSettings(**dict(kw, workers=1, spp=16, seed=0)))
cpu = time.process_time() - cpu
st = film.stats
stored = st.get("global_photons", 0) + st.get("caustic_photons", 0) + st.get("glow_photons", 0)
print(json.dumps(dict(stored=stored, shots=st.get("shot_bytes", st.get("photon_bytes", 0)),
                      stat=st.get("photon_bytes", 0), hit_view=got["hit_view"],
                      start=got["start"], end=got["end"], arrays=got["arrays"], cpu=cpu)))
"""


def main_photon_bytes(pickles, roots, arrays=0.0):
    print("160 x 120, 16 spp, 1 worker, seed 0; B a stored photon (global + caustic + glow)")
    print("| scene | checkout | stored | shots' arrays | maps at the camera pass' start | "
          "at its end | of which (end): gather map / caustic / counts / other | "
          "photon_bytes stat | photon-hit view | render CPU s |")
    print("|---|---|---:|---:|---:|---:|---|---:|---:|---:|")
    listed = []
    for path in pickles:
        for root in roots:
            code = f"ROOT={root!r}; PICKLE={path!r}\n" + PHOTON_BYTES_CHILD
            out = subprocess.run([sys.executable, "-c", code], capture_output=True,
                                 text=True, check=True).stdout
            r = json.loads(out.strip().splitlines()[-1])
            n = max(r["stored"], 1)
            start, end = sum(r["start"].values()), sum(r["end"].values())
            e = r["end"]
            other = end - e["gather_map"] - e["caustic_map"] - e["gather_counts"]
            split = " / ".join(f"{v / n:.1f}" for v in (e["gather_map"], e["caustic_map"],
                                                        e["gather_counts"], other))
            name = os.path.splitext(os.path.basename(path))[0]
            print(f"| {name} | {root} | {r['stored']:,} | {r['shots'] / n:.1f} | "
                  f"{start / n:.1f} | {end / n:.1f} | {split} | {r['stat'] / n:.1f} | "
                  f"{r['hit_view'] / n:.1f} | {r['cpu']:.1f} |", flush=True)
            if arrays:
                listed.append((name, root, n, r["arrays"]))
    for name, root, n, held_arrays in listed:
        # (each buffer under the first path the walk met: a level shared by the views
        # shows under one of them)
        print(f"\n{name}, {root}: arrays of at least {arrays} B a stored photon at the "
              "camera pass' end")
        print("| B a stored photon | array | dtype | shape |")
        print("|---:|---|---|---|")
        for path, (nbytes, dtype, shape) in sorted(held_arrays.items(),
                                                   key=lambda kv: -kv[1][0]):
            if nbytes / n >= arrays:
                print(f"| {nbytes / n:.2f} | {path} | {dtype} | {tuple(shape)} |")


def run(case):
    label, name, w, h, settings, tris = case
    code = (f"ROOT={ROOT!r}; NAME={name!r}; W={w}; H={h}; TRIS={tris}; "
            f"SETTINGS={settings!r}\n" + CHILD)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="three cases only")
    ap.add_argument("--only", default=None, help="the cases whose label holds this text")
    ap.add_argument("--triangles", action="store_true", help="bytes per triangle instead")
    ap.add_argument("--sizes", type=int, nargs="+", default=[1_000_000, 5_000_000],
                    help="triangle counts for --triangles")
    ap.add_argument("--smooth", action="store_true",
                    help="--triangles: the grid and the spheres have vertex normals and UVs "
                    "(else no mesh has either)")
    ap.add_argument("--root", default=ROOT, help="--triangles: checkout to measure")
    ap.add_argument("--photon-bytes", action="store_true",
                    help="bytes per stored photon of the maps instead (--pickles, --roots)")
    ap.add_argument("--pickles", nargs="+", default=[],
                    help="--photon-bytes: pickled scenes (example blends' exports)")
    ap.add_argument("--roots", nargs="+", default=[ROOT],
                    help="--photon-bytes: checkouts to measure, each in a fresh process")
    ap.add_argument("--arrays", type=float, default=0.0, metavar="B",
                    help="--photon-bytes: also list the arrays held at the camera pass' "
                    "end of at least B bytes a stored photon (path, dtype, shape)")
    args = ap.parse_args()
    if args.photon_bytes:
        main_photon_bytes(args.pickles, [os.path.abspath(r) for r in args.roots],
                          args.arrays)
        return
    if args.triangles:
        main_triangles(args.sizes, args.smooth, os.path.abspath(args.root))
        return
    mb = 1 << 20
    print("| render | estimate (MB) | measured peak (MB) | estimate / measured | largest part |")
    print("|---|---|---|---|---|")
    for case in CASES:
        if (args.quick and case[0] not in QUICK) or (args.only and args.only not in case[0]):
            continue
        r = run(case)
        largest = max(r["parts"], key=r["parts"].get)
        print(f"| {case[0]} | {r['estimate'] / mb:.0f} | {r['measured'] / mb:.0f} | "
              f"{r['estimate'] / max(r['measured'], 1):.2f} | {largest} |", flush=True)


if __name__ == "__main__":
    main()
