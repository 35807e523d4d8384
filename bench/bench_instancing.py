"""Instanced geometry and the ray engine (issue 16): 100 instances of a 65k-triangle
sphere, two ways, each measured in a fresh process (resident memory kept after the
build, build time, closest-hit throughput of the same rays, and how many hits agree):

  flattened   every instance copied into world space, one BVH over all copies (what the
              engine does: engine/geometry.prepare + engine/accel.Accel)
  two-level   engine/instancing.InstanceAccel: one BVH of the sphere in object space, a
              compiled BVH over the instances' world boxes listing the boxes each ray
              enters nearest first; rays are transformed into each instance's object
              space (unnormalised directions, so t stays the world parameter) and traced
              up to the nearest hit so far, in rounds (the k-th box of every ray).

--render renders a scene instead (the engine's whole path, each case in a fresh
process): a floor and a point light over N instances of a sphere with normals and UVs
(Mesh.prototype records, as addon/export.py writes them), the instances expanded into
the BVH or traced two-level (engine/resources.INSTANCE_BUDGET_FRACTION forces the
choice): resident memory kept by the prepared context and its peak, prepare (tables +
BVH) and render time, and the image's mean against the expanded render's. The Scene's
own meshes (the exporter's world-space copies) exist before the measurement and are not
counted.

Prints a table (docs/performance.md, "Instancing").

    .venv/bin/python bench/bench_instancing.py [--instances 100] [--rays 200000]
    .venv/bin/python bench/bench_instancing.py --render [--instances 10 100 1000] [--segments 64]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)

CHILD = r"""
import json, sys, time
sys.path.insert(0, ROOT)
sys.path.insert(0, BENCH)
from procmem import hwm, rss
import numpy as np
from engine.accel import Accel



def sphere(rings=128, segments=256):
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    V = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    r = np.arange(rings)[:, None]
    s = np.arange(segments)[None, :]
    a = r * segments + s
    b = r * segments + (s + 1) % segments
    c = a + segments
    d = b + segments
    F = np.concatenate([np.stack([a, c, d], -1).reshape(-1, 3), np.stack([a, d, b], -1).reshape(-1, 3)])
    return V, F


def instances(n, seed=1):
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    out = []
    for i in range(n):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        w, x, y, z = q
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        M = np.eye(4)
        M[:3, :3] = R * rng.uniform(0.5, 1.2)
        M[:3, 3] = [3.0 * (i % side), 3.0 * (i // side), 0.0]
        out.append(M)
    return out


V, F = sphere()
Ms = instances(NI)
rng = np.random.default_rng(2)
side = 3.0 * np.ceil(np.sqrt(NI))
o = np.column_stack([rng.uniform(-2, side, NR), rng.uniform(-2, side, NR), np.full(NR, 10.0)])
d = np.column_stack([rng.normal(0, 0.2, NR), rng.normal(0, 0.2, NR), -np.ones(NR)])
d /= np.linalg.norm(d, axis=1)[:, None]
from engine.instancing import InstanceAccel, Instances

# Load numba and the top-level kernel before measuring (the same for any scene).
_w = Instances(prototypes=[(V[:3], F[:1] * 0 + [0, 1, 2])], prototype=np.zeros(1, np.int64),
               base=np.zeros(1, np.int64), to_world=np.eye(4)[None, :3], flip=np.zeros(1, bool),
               visibility=np.full(1, 31, np.uint8), static=np.zeros(0, np.int64))
InstanceAccel(None, None, _w).intersect(o[:1], d[:1])
del _w
extra = {}
before = rss()
t0 = time.perf_counter()
if MODE == "flattened":
    Vw = np.concatenate([V @ M[:3, :3].T + M[:3, 3] for M in Ms])
    Fw = np.concatenate([F + i * len(V) for i in range(NI)])
    # What engine/geometry.prepare keeps per triangle (v0, e1, e2 float64, corner normals
    # and UVs float32, 16 B of per-triangle ids) stands in for the tables here.
    tri = Vw[Fw]
    tables = [tri[:, 0].copy(), tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0],
              np.zeros((len(Fw), 3, 3), np.float32), np.zeros((len(Fw), 3, 2), np.float32),
              np.zeros((len(Fw), 4), np.int32)]
    del tri
    acc = Accel(Vw, Fw)
    del Vw, Fw
else:
    # engine/instancing.py: the sphere's BVH once, the compiled top level over the boxes.
    ins = Instances(prototypes=[(V, F)], prototype=np.zeros(NI, np.int64),
                    base=np.arange(NI, dtype=np.int64) * len(F),
                    to_world=np.array([M[:3] for M in Ms]), flip=np.zeros(NI, bool),
                    visibility=np.full(NI, 31, np.uint8), static=np.zeros(0, np.int64))
    acc = InstanceAccel(None, None, ins)
build = time.perf_counter() - t0
kept = rss() - before
t0 = time.perf_counter()
t, prim, u, v = acc.intersect(o, d)
trace = time.perf_counter() - t0
if MODE != "flattened":
    top = acc._top
    t1 = time.perf_counter()
    from engine.toplevel import top_level_candidates
    offsets, _, _ = top_level_candidates(o, d, np.full(len(o), np.inf), top.node_lo,
                                         top.node_hi, top.child, top.first, top.count,
                                         top.order, top.lo, top.hi)
    extra["top level (s)"] = time.perf_counter() - t1
    extra["rays per ray"] = float(offsets[-1]) / len(o)
np.save(OUT, np.stack([t, prim.astype(float)]))
print(json.dumps({"kept": kept, "build": build, "trace": trace, "triangles": len(F) * NI,
                  "hits": int((prim >= 0).sum()), "extra": extra}))
"""


RENDER_CHILD = r"""
import gc, json, sys, time
sys.path.insert(0, ROOT)
sys.path.insert(0, BENCH)
from procmem import hwm, rss
import numpy as np
from engine import RenderSettings, resources
from engine.api import PaperScene, sphere_mesh
from engine.render import prepare_context, render_pass
from engine.scene import Material, Mesh, Prototype, place




def scene(n, segments):
    s = PaperScene(width=64, height=48)
    s.add_material(Material("white", (0.8, 0.8, 0.8)))
    side = int(np.ceil(np.sqrt(n)))
    s.add_plane((1.5 * side, 1.5 * side, -1.0), (0, 0, 1), 3.0 * side + 4, "white", name="floor")
    v, f, nrm, uv = sphere_mesh((0, 0, 0), 1.0, segments, segments // 2)
    # Placements without world-space copies (Mesh.place), as addon/export.py writes them.
    proto = Prototype("sphere", v, f, normals=nrm, uvs=uv)
    rng = np.random.default_rng(1)
    for i in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q *= np.sign(np.linalg.det(q))
        M = np.eye(4)
        M[:3, :3] = q * rng.uniform(0.6, 1.2)
        M[:3, 3] = [3.0 * (i % side), 3.0 * (i // side), 0.0]
        s.add_mesh(Mesh.place(f"ball.{i}", proto, M, materials=["white"]))
    s.add_point_light((1.5 * side, 1.5 * side, 4.0 + side), power=200.0 * side * side)
    s.set_camera((1.5 * side, -1.0 * side, 1.5 * side), (1.5 * side, 1.5 * side, 0.0),
                 view_angle=60)
    return s


settings = RenderSettings(photons=20000, caustic_photons=0, spp=4, workers=1, seed=1)
warm = scene(2, 8)  # load the compiled kernels before measuring
render_pass(prepare_context(warm, settings), (0, 0, 64, 48))
del warm
gc.collect()
try:
    import ctypes
    ctypes.CDLL("libc.so.6").malloc_trim(0)
except (OSError, AttributeError):
    pass
resources.INSTANCE_BUDGET_FRACTION = 0.0 if MODE == "two-level" else 1e9
resources.INSTANCE_FLOOR = 0 if MODE == "two-level" else 1 << 62
start = rss()
sc = scene(NI, SEG)
sc.validate()
scene_mb = rss() - start
T = sum(len(m.faces) for m in sc.meshes)
resources.check_resources(sc, settings)  # refuses what cannot fit (the estimate)
before = rss()
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")
t0 = time.perf_counter()
ctx = prepare_context(sc, settings)
t_prepare = time.perf_counter() - t0
kept = rss() - before
peak_prepare = hwm() - before
assert ctx.accel.two_level == (MODE == "two-level")
t0 = time.perf_counter()
film = render_pass(ctx, (0, 0, 64, 48))
t_render = time.perf_counter() - t0
peak = hwm() - before
print(json.dumps({"T": T, "scene": scene_mb, "kept": kept, "peak_prepare": peak_prepare,
                  "peak": peak,
                  "t_prepare": t_prepare, "t_render": t_render,
                  "mean": float(film.combined.mean())}))
"""


def run_render(mode, instances, segments):
    code = (f"ROOT={ROOT!r}; BENCH={BENCH!r}; MODE={mode!r}; NI={instances}; SEG={segments}\n"
            + RENDER_CHILD)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(res.strip().splitlines()[-1])


def main_render(instances, segments, expand_max):
    mb = 1 << 20
    print(f"instances of a sphere of {segments} segments; 64x48, 4 spp, 20k photons, "
          "1 worker")
    print("| instances | triangles | method | scene (MB) | kept after preparing (MB) | "
          "peak (MB) | prepare (s) | render (s) | image mean / expanded |")
    print("|---|---|---|---|---|---|---|---|---|")
    for ni in instances:
        modes = ("expanded", "shared") if ni <= expand_max else ("shared",)
        res = {m: run_render("two-level" if m == "shared" else m, ni, segments) for m in modes}
        for m, r in res.items():
            ratio = (f"{r['mean'] / max(res['expanded']['mean'], 1e-30):.4f}"
                     if "expanded" in res else "")
            print(f"| {ni} | {r['T']:,} | {m} | {r['scene'] / mb:.0f} | {r['kept'] / mb:.0f} | "
                  f"{r['peak'] / mb:.0f} | {r['t_prepare']:.2f} | {r['t_render']:.2f} | "
                  f"{ratio} |", flush=True)


def run(mode, instances, rays, out):
    code = (f"ROOT={ROOT!r}; BENCH={BENCH!r}; MODE={mode!r}; NI={instances}; NR={rays}; "
            f"OUT={out!r}\n" + CHILD)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(res.strip().splitlines()[-1])


def main():
    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--rays", type=int, default=200_000)
    ap.add_argument("--flatten-max", type=int, default=100,
                    help="flatten only up to this many instances (1000 copies of the "
                    "sphere need ~14 GB)")
    ap.add_argument("--render", action="store_true",
                    help="render a scene, expanded against two-level (engine path)")
    ap.add_argument("--expand-max", type=int, default=100,
                    help="--render: expand only up to this many instances (1000 copies of "
                    "the 65k-triangle sphere need ~21 GB expanded)")
    ap.add_argument("--segments", type=int, default=64,
                    help="--render: the sphere's segments (2 x segments^2 / 2 triangles)")
    args = ap.parse_args()
    if args.render:
        main_render(args.instances, args.segments, args.expand_max)
        return
    tmp = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"bench_instancing_{os.getpid()}")
    mb = 1 << 20
    print(f"instances of a 65,536-triangle sphere, {args.rays:,} closest-hit rays, 1 thread")
    print("| instances | method | memory kept (MB) | build (s) | closest hits (Mrays/s) | "
          "hits | agreement with flattened |")
    print("|---|---|---|---|---|---|---|")
    for ni in args.instances:
        modes = ("flattened", "two-level") if ni <= args.flatten_max else ("two-level",)
        res = {m: run(m, ni, args.rays, f"{tmp}_{m}.npy") for m in modes}
        agree = ""
        if len(modes) == 2:
            a = np.load(f"{tmp}_flattened.npy")
            b = np.load(f"{tmp}_two-level.npy")
            same_prim = float(np.mean(a[1] == b[1]))
            both = (a[1] >= 0) & (b[1] >= 0)
            dt = float(np.max(np.abs(a[0][both] - b[0][both]) / np.maximum(a[0][both], 1e-30))) \
                if both.any() else 0.0
            agree = f"same triangle {100 * same_prim:.3f} %, t within {dt:.0e}"
        for m in modes:
            os.remove(f"{tmp}_{m}.npy")
        for m, r in res.items():
            note = ""
            if r["extra"]:
                note = (f" (top level alone {r['extra']['top level (s)']:.2f} s, "
                        f"{r['extra']['rays per ray']:.1f} boxes a ray enters)")
            print(f"| {ni} | {m}{note} | {r['kept'] / mb:.0f} | {r['build']:.2f} | "
                  f"{args.rays / r['trace'] / 1e6:.2f} | {r['hits']:,} | "
                  f"{agree if m == 'two-level' else ''} |", flush=True)


if __name__ == "__main__":
    main()
