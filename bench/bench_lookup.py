"""Photon lookups: the compiled kd-tree and hash grid against scipy's cKDTree (the numpy
estimators they replaced), in Embree traversals, plus compile and cached-start times, and
the default estimator's per-sample lookup (the gather map's, visibility ray included).

    .venv/bin/python bench/bench_lookup.py [--photons 200000] [--queries 50000]

One process prints one table (Markdown). All lookups run on one thread. The photon map is
the Figure 6 box's global shot (default photon count); queries sit at random stored
photons (position + normal), in random order. "Embree traversals" divides a lookup's
time by the time of one closest-hit ray of camera-like rays in the same scene
(embreex, one thread). Memory per photon is the map's bytes (photons + search structure)
over the photons stored. The dark-wall rows are issue 16's case: queries that find only
another surface's photons (a wall lit on its far side), where the k-NN query widens.
The gather-map row: GatherMap.lookup (nearest facing gather point + its visibility ray)
at the ends of rays shot from inside the box in random directions (where gather rays
end), in Embree traversals, split into its parts.

    .venv/bin/python bench/bench_lookup.py --render-calls [--base 1b8bc95]
        [--blends figure6_box,figure7_blocker] [--width 160 --height 120]
        [--saved /tmp/hosek_scene.pkl]

A render's own estimates instead: one 1-worker render of each exported example blend
(default settings, bench/bench_kernels.py's export; --saved: a scene bench_world_light.py
--save exported, at its add-on settings, 16 spp, seed 1) records every PhotonMap.irradiance
call (its map, its caller, its rows); then each version (this tree and --base, one
fresh process each) replays those calls, one thread, best of 3 CPU seconds, and prints
per map and caller: microseconds per estimate, the same in Embree closest-hit
traversals of that scene, and whether both versions' answers are the same bits. The
kernel gather lookups (GatherMap.lookup) of the same render are timed alike.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "bench"))

from engine import RenderSettings  # noqa: E402
from engine.api import cornell_box  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.lights import allocate_photons  # noqa: E402
from engine import photonmap  # noqa: E402
from engine.bsdf import surface_hit  # noqa: E402
from engine.photonmap import GatherMap, PhotonMap, auto_radius  # noqa: E402
from engine.photons import Photons, trace_photons  # noqa: E402
from engine.render import prepare_context  # noqa: E402
from reference_photonmap import ReferencePhotonMap  # noqa: E402  (the cKDTree estimators)

CKDTREE_NODE_BYTES = 72  # sizeof(ckdtreenode) in scipy's ckdtree_decl.h on 64-bit


def best(fn, repeat=3):
    """Best of `repeat` in CPU seconds of this process: every timed call here runs on one
    thread, and CPU time is far less disturbed than wall time by other jobs on the
    machine."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        times.append(time.process_time() - t0)
    return min(times), out


def embree_ray_seconds(ctx, n=200_000) -> float:
    """Seconds per closest-hit ray (one thread): rays from the camera region of the box
    towards random points on its surfaces."""
    rng = np.random.default_rng(1)
    geo = ctx.geo
    lo, hi = (np.asarray(b, np.float64) for b in geo.bounds)
    o = lo + (hi - lo) * (0.3 + 0.4 * rng.random((n, 3)))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    acc = ctx.accel.serial()
    acc.intersect(o[:10], d[:10])
    t, _ = best(lambda: acc.intersect(o, d))
    return t / n


def compile_times() -> tuple[float, float, float]:
    """(cold compile, cached start, import numba) seconds, each in a fresh process."""
    code = ("import time; t0 = time.perf_counter(); import numba; t1 = time.perf_counter(); "
            "import engine.jit as j; j.ensure_compiled(); "
            "print(time.perf_counter() - t0, t1 - t0)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        out = []
        for _ in range(2):
            r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env,
                               capture_output=True, text=True, check=True)
            out.append([float(v) for v in r.stdout.split()])
    return out[0][0], out[1][0], out[1][1]


def far_side_photons(n, rng):
    pos = np.c_[rng.random((n, 2)), np.full(n, 0.001)].astype(np.float32)
    down = np.tile(np.float32([0, 0, -1]), (n, 1))
    return Photons(pos, np.full((n, 3), 1.0 / n, np.float32), -down, down,
                   np.zeros(n, np.uint8))


def gather_lookup(ctx, shot, radius, k, s, ray, m=200_000):
    """The gather-map lookup row: its build time, one lookup in Embree traversals, and
    its parts (Morton order, the kernel's searches, the visibility rays)."""
    t_build, g = best(lambda: GatherMap(shot, radius, k, s.min_photons, s.estimator,
                                        accel=ctx.accel), repeat=1)
    g = g.serial()
    rng = np.random.default_rng(1)
    lo, hi = ctx.geo.bounds
    o = lo + (hi - lo) * (0.25 + 0.5 * rng.random((m, 3)))
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, prim, u, v = ctx.accel.serial().intersect(o, d)
    hit = prim >= 0
    y = surface_hit(ctx.geo, ctx.table, prim[hit], u[hit], v[hit], d[hit])
    M = int(hit.sum())
    t_all, _ = best(lambda: g.lookup(y.p, y.ng, offset=y.offset))
    p, n = np.ascontiguousarray(y.p), np.ascontiguousarray(y.ng)
    t_order, rows = best(lambda: photonmap.morton_order(p))
    out, bnd = np.empty((M, 3)), np.empty(M, bool)
    o32, d32 = np.empty((M, 3), np.float32), np.empty((M, 3), np.float32)
    t32, ray_row, blocked = np.empty(M, np.float32), np.empty(M, np.int64), np.zeros(M, bool)
    t_kernel, nrays = best(lambda: photonmap._gather_candidates(
        g.tree.position, g.tree.nodes, *g.neighbours, g.position, g.normal,
        photonmap.NO_SURFACE, g.E, g.boundary, p, n, photonmap.NO_SURFACE,
        np.ascontiguousarray(y.offset, dtype=np.float64), rows, g.radius ** 2, 64, True,
        out, bnd, o32, d32, t32, ray_row, photonmap._NO_POINT))
    t_vis, _ = best(lambda: g.accel.occluded_into(o32[:nrays], d32[:nrays], t32[:nrays],
                                                  blocked[:nrays]))
    per = t_all / M
    parts = (f"{len(g.position):,} gather points; order {t_order / M / ray:.2f}, search + "
             f"rays kernel {t_kernel / M / ray:.2f}, visibility {t_vis / M / ray:.2f} rays "
             f"({nrays / M:.0%} of lookups cast one)")
    return ("gather-map lookup (default estimator, per sample)", f"{t_build * 1e3:.0f} ms",
            f"{per * 1e6:.2f} us = {per / ray:.1f} rays", "", parts, "")


def listing_floor(pm, q, radius, k, ray):
    """Rows: what listing the estimate's photons alone costs on the compiled kd-tree
    (kdtree.ball_d2, then kdtree.nearest_first ordering the k nearest), one loop in a
    compiled harness, the queries in Morton order as the estimate takes them: the whole
    search sphere, the seeded sphere (1.44 x the k-th squared distance, as
    photonmap.SEED_GROWTH) and the k nearest exactly (their distance known in advance,
    which no search has): a floor under any estimate that lists its photons from this
    tree (docs/performance.md "perf47")."""
    from numba import njit
    from scipy.spatial import cKDTree
    from engine import kdtree

    @njit
    def listing(pos, axis, split, leaf, q, r2s, cap, m):
        d2 = np.empty(cap + 1)
        idx = np.empty(cap + 1, np.int64)
        o2 = np.empty(cap + 1)
        oi = np.empty(cap + 1, np.int64)
        hist = np.empty(cap + 2, np.int64)
        total = 0
        for i in range(q.shape[0]):
            c = kdtree.ball_d2(pos, axis, split, leaf, q[i, 0], q[i, 1], q[i, 2], r2s[i],
                               d2, idx, cap)
            if m > 0 and c <= cap:
                kdtree.nearest_first(d2, idx, c, m, r2s[i], o2, oi, hist)
            total += c
        return total

    t = pm.tree
    qo = np.ascontiguousarray(q[photonmap.morton_order(q)])
    kth2 = cKDTree(t.position).query(qo, k)[0][:, -1] ** 2
    cap = photonmap.LIST_FACTOR * k
    listing(t.position, t.axis, t.split, t.leaf, qo[:4], kth2[:4], cap, k)  # (compile)
    out = []
    for label, r2s in (("the whole search sphere", np.full(len(qo), radius * radius)),
                       ("the seeded sphere (1.44 x the k-th squared distance)",
                        kth2 * photonmap.SEED_GROWTH),
                       (f"the {k} nearest exactly (k-th distance given)", kth2 * 1.0001)):
        t_list, n = best(lambda: listing(t.position, t.axis, t.split, t.leaf, qo, r2s, cap, 0))
        t_sort, _ = best(lambda: listing(t.position, t.axis, t.split, t.leaf, qo, r2s, cap, k))
        per, pers = t_list / len(qo), t_sort / len(qo)
        out.append((f"listing floor: {label}", "", f"{per * 1e6:.2f} us = {per / ray:.1f} rays",
                    f"+ nearest_first {pers * 1e6:.2f} us = {pers / ray:.1f} rays",
                    f"{n / len(qo):.0f} photons listed a query", ""))
    return out


CAPTURE = r"""
import pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
from engine import photonmap
try:  # compact49: capture float32 maps (any version replays them; see REPLAY)
    from engine import photonlayout
    photonlayout.COMPACT = False
except ImportError:
    pass
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
maps, calls, lookups = {}, {}, []
irradiance, lookup = photonmap.PhotonMap.irradiance, photonmap.GatherMap.lookup
def record(self, p, n, radius, k, min_photons, estimator, return_boundary=False,
           r_floor=None, should_cancel=None, masks=None, hidden=None, read=None,
           surface=None):
    caller = sys._getframe(1).f_code.co_name
    if hidden is None and read is None:  # (photon visibility's calls: not replayed)
        if id(self) not in maps:
            t, ph = self.tree, self.photons
            maps[id(self)] = dict(tree=(t.position, t.axis, t.split, t.leaf, t.bounds),
                                  photons=(ph.position, ph.power, ph.direction, ph.normal,
                                           ph.kind, ph.emitted, None, ph.surface))
        calls.setdefault((id(self), caller, radius), []).append(
            (np.array(p), np.array(n), k, min_photons, estimator, return_boundary,
             None if r_floor is None else np.array(np.broadcast_to(r_floor, (len(p),))),
             None if masks is None else np.array(masks),
             None if surface is None else np.array(np.broadcast_to(surface, (len(p),)))))
    return irradiance(self, p, n, radius, k, min_photons, estimator, return_boundary,
                      r_floor, should_cancel, masks, hidden, read, surface)
def record_lookup(self, p, n, candidates=8, offset=None, **kw):  # kw: scratch=, surface=
    if not lookups:
        lookups.append((self.tree.position, self.tree.axis, self.tree.split,
                        self.tree.leaf, self.position, self.normal, self.E, self.boundary,
                        self.radius))
    lookups.append((np.array(p), np.array(n), None if offset is None else np.array(offset)))
    return lookup(self, p, n, candidates, offset, **kw)
photonmap.PhotonMap.irradiance = record
photonmap.GatherMap.lookup = record_lookup
render(scene, RenderSettings(workers=1))
with open(OUT, "wb") as f:
    pickle.dump(dict(maps=maps, calls=calls, lookups=lookups), f, protocol=4)
print('{"ok": true}')
"""

REPLAY = r"""
import hashlib, json, pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine import kdtree, photonmap
from engine.photons import Photons
from engine.render import prepare_context
from engine.settings import RenderSettings
ensure_compiled()
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
ctx = prepare_context(scene, RenderSettings(workers=1))
rng = np.random.default_rng(1)
lo, hi = (np.asarray(b, np.float64) for b in ctx.geo.bounds)
o = lo + (hi - lo) * (0.3 + 0.4 * rng.random((200_000, 3)))
d = rng.normal(size=(200_000, 3))
d /= np.linalg.norm(d, axis=1)[:, None]
acc = ctx.accel.serial()
def cpu(fn):
    best = 1e9
    for _ in range(3):
        t = time.process_time(); out = fn(); best = min(best, time.process_time() - t)
    return best, out
ray_s, _ = cpu(lambda: acc.intersect(o, d))
ray_us = ray_s / len(o) * 1e6
with open(CAPTURE, "rb") as f:
    cap = pickle.load(f)
def tree(arrays):
    t = kdtree.KdTree.__new__(kdtree.KdTree)
    t.position, t.axis, t.split, t.leaf, t.bounds = arrays
    t.order = None
    return t
rows = []
for (mid, caller, radius), calls in cap["calls"].items():
    m = cap["maps"][mid]
    pm = photonmap.PhotonMap.__new__(photonmap.PhotonMap)
    pm.workers, pm.structure, pm.tree = 1, "kdtree", tree(m["tree"])
    pm.photons = Photons(*m["photons"])
    try:  # compact49: a version with the compact layout holds its maps so
        from engine import photonlayout
        if photonlayout.COMPACT:
            photonlayout.compact(pm.photons)
    except ImportError:
        pass
    def run():
        # Captures before the gather map's masks (s18) hold 7 fields.
        return [pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb, r_floor=rf,
                              **({"masks": more[0]} if more and more[0] is not None else {}),
                              **({"surface": more[1]} if len(more) > 1
                                 and more[1] is not None else {}))
                for p, n, k, mp, est, rb, rf, *more in calls]
    t, outs = cpu(run)
    h = hashlib.sha1()
    for out in outs:
        for a in (out if isinstance(out, tuple) else (out,)):
            h.update(np.ascontiguousarray(a).tobytes())
    m_rows = sum(len(c[0]) for c in calls)
    if m_rows == 0:
        continue  # (calls without rows: nothing to time)
    rows.append(dict(caller=caller, photons=len(pm.photons), radius=radius,
                     calls=len(calls), rows=m_rows, us=t / m_rows * 1e6, hash=h.hexdigest()))
# (Versions whose gather lookups test the points' surfaces take arguments this replay
# does not record: their GatherMap.lookup row is left out.)
if cap["lookups"] and "surface" not in photonmap._gather_candidates.py_func.__code__.co_varnames[:8]:
    tp, ax, sp, lf, position, normal, E, B, radius = cap["lookups"][0]
    calls = cap["lookups"][1:]
    big = max(len(c[0]) for c in calls)
    o32, d32 = np.empty((big, 3), np.float32), np.empty((big, 3), np.float32)
    t32, ray_row = np.empty(big, np.float32), np.empty(big, np.int64)
    # Versions since the seventh slice walk the gather points' neighbour lists (built
    # with the map, once per render: timed as a row of its own).
    walks = "nbr" in photonmap._gather_candidates.py_func.__code__.co_varnames[:4]
    tables = ()
    if walks:
        gt = tree((tp, ax, sp, lf, None))
        t_nb, tables = cpu(gt.neighbour_lists)
        rows.append(dict(caller="gather map's neighbour lists (once per render)",
                         photons=len(tp), radius=radius, calls=1, rows=len(tp),
                         us=t_nb / len(tp) * 1e6, hash="-"))
    def run():
        outs = []
        for p, n, off in calls:
            out, bnd = np.empty((len(p), 3)), np.empty(len(p), bool)
            lift = (photonmap._NO_LIFT if off is None
                    else np.ascontiguousarray(off, dtype=np.float64))
            rows_ = photonmap.morton_order(p)
            photonmap._gather_candidates(tp, (ax, sp, lf), *tables, position, normal, E, B,
                                         p, n, lift, rows_, radius * radius, 64, True, out,
                                         bnd, o32, d32, t32, ray_row)
            outs.append((out, bnd))
        return outs
    t, outs = cpu(run)
    h = hashlib.sha1()
    for out, bnd in outs:
        h.update(out.tobytes()); h.update(bnd.tobytes())
    m_rows = sum(len(c[0]) for c in calls)
    rows.append(dict(caller="GatherMap.lookup (kernel: search + rays, no Embree)",
                     photons=len(position), radius=radius, calls=len(calls), rows=m_rows,
                     us=t / m_rows * 1e6, hash=h.hexdigest()))
print(json.dumps(dict(ray_us=ray_us, rows=rows)))
"""

CALLERS = {"__init__": "gather map's points (once per render)",
           "_smooth_estimate": "camera hits (caustic <= 16, secondary <= 4 per pixel)",
           "_secondary_irradiance": "regathered points (a tenth of them)"}


def render_calls(args):
    """The --render-calls table: a render's own estimates, replayed by both versions."""
    import bench_kernels as bk  # noqa: E402  (the blend export and the base-tree copy)
    where = args.work
    os.makedirs(where, exist_ok=True)
    # --base: a commit (extracted under --work) or a checkout's folder (its compiled
    # kernels' cache is used as it is: a fresh extraction compiles every kernel)
    roots = {"before": (os.path.abspath(args.base) if os.path.isdir(args.base)
                        else bk.base_tree(args.base, where)), "after": ROOT}
    head = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True).stdout.strip()
    print(f"before = {args.base}, after = {head} (+ working tree); load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {args.width}x{args.height}, "
          f"default settings, estimates of a 1-worker render replayed on one thread\n")
    print("| scene | estimate at | map photons | radius m | calls | rows | before us / row "
          "| after us / row | gain | after in Embree traversals | answers |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    import pickle
    names = [n for n in args.blends.split(",") if n] + args.saved
    for name in names:
        capture = CAPTURE
        if name in args.saved:  # a (scene, settings kwargs) pickle: its settings, 16 spp
            scene, kw = pickle.load(open(name, "rb"))
            kw = {**kw, "workers": 1, "spp": 16, "seed": 1}
            name = os.path.splitext(os.path.basename(name))[0]
            pkl = os.path.join(where, f"{name}.pkl")
            with open(pkl, "wb") as f:
                pickle.dump(scene, f)
            capture = CAPTURE.replace("RenderSettings(workers=1)", f"RenderSettings(**{kw!r})")
        else:
            pkl = bk.exported(name, where)
        cap = os.path.join(where, f"{name}-{args.width}x{args.height}.calls")
        bk.child(capture, ROOT=ROOT, PICKLE=pkl, W=args.width, H=args.height, OUT=cap)
        res = {v: bk.child(REPLAY, ROOT=roots[v], PICKLE=pkl, CAPTURE=cap) for v in roots}
        def key(r):
            return r["caller"], r["photons"], r["radius"]
        before = {key(r): r for r in res["before"]["rows"]}
        for a in res["after"]["rows"]:
            ray = res["after"]["ray_us"]
            b = before.get(key(a), dict(us=float("nan"), hash="-"))
            same = ("same bits" if a["hash"] == b["hash"] != "-" else
                    "new" if b["hash"] == "-" else "DIFFER")
            print(f"| {name} | {CALLERS.get(a['caller'], a['caller'])} | {a['photons']:,} | "
                  f"{a['radius']:.3f} | {a['calls']:,} | {a['rows']:,} | {b['us']:.2f} | "
                  f"{a['us']:.2f} | {b['us'] / a['us']:.2f}x | {a['us'] / ray:.1f} | {same} |",
                  flush=True)
        print(f"| {name} | (one Embree closest-hit ray, us: before / after) | | | | | "
              f"{res['before']['ray_us']:.3f} | {res['after']['ray_us']:.3f} | | | |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--render-calls", action="store_true",
                    help="only the table of a render's own estimates, before / after")
    ap.add_argument("--base", default="1b8bc95",
                    help="--render-calls: commit or checkout folder to compare")
    ap.add_argument("--blends", default="figure6_box,figure7_blocker")
    ap.add_argument("--saved", nargs="*", default=[],
                    help="--render-calls: also (scene, settings) pickles saved by "
                         "bench_world_light.py --save (X_scene.pkl), at their own settings")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    ap.add_argument("--photons", type=int, default=RenderSettings.photons)
    ap.add_argument("--queries", type=int, default=50_000)
    ap.add_argument("--k", type=int, default=RenderSettings.k_nearest)
    ap.add_argument("--skip-compile", action="store_true",
                    help="leave out the compile rows (bench_kernels.py measures them too)")
    args = ap.parse_args(argv)
    if args.render_calls:
        return render_calls(args)
    rows = []

    if not args.skip_compile:
        t_cold, t_cached, t_numba = compile_times()
        rows.append(("compile (fresh cache, new process, wall)", "", f"{t_cold:.2f} s", "",
                     "", ""))
        rows.append(("cached start (new process, wall)", "", f"{t_cached:.2f} s", "",
                     f"of which import numba {t_numba:.2f} s", ""))
    ensure_compiled()

    s = RenderSettings(photons=args.photons, workers=1)
    ctx = prepare_context(cornell_box(), s)
    shot = trace_photons(ctx, ctx.lights, allocate_photons(ctx.lights, s.photons), False, 1)
    N = len(shot)
    diffuse = ctx.table.has_diffuse[ctx.geo.material]
    radius = auto_radius(float(ctx.geo.area[diffuse].sum()), N, args.k, ctx.geo.extent)
    ray = embree_ray_seconds(ctx)  # CPU seconds per ray, one thread
    gather_row = gather_lookup(ctx, shot, radius, args.k, s, ray)
    ctx.accel.close()
    rng = np.random.default_rng(0)
    sel = rng.integers(0, N, args.queries)
    q = shot.position[sel].astype(np.float64)
    nq = shot.normal[sel].astype(np.float64)
    # Coherent order, as a camera chunk's hits come (neighbouring pixels, nearby points).
    o = np.lexsort((q[:, 2], q[:, 1], q[:, 0]))
    qs, nqs = q[o], nq[o]
    k, mp, est = args.k, s.min_photons, s.estimator
    print(f"\nFigure 6 box global shot: {N:,} photons stored, radius {radius:.4f} m, "
          f"{args.queries:,} queries, k={k}, {est}, 1 thread; one Embree closest-hit ray "
          f"{ray * 1e6:.3f} us\n")

    builds = {
        "kd-tree (compiled)": lambda: PhotonMap(shot, 1),
        "hash grid (compiled)": lambda: PhotonMap(shot, 1, structure="hashgrid", cell=radius),
        "cKDTree + numpy (before)": lambda: ReferencePhotonMap(shot, 1),
    }
    raw = {
        "kd-tree (compiled)": lambda pm: pm.tree.query(q, k, radius),
        "hash grid (compiled)": lambda pm: pm.tree.query(q, k, radius),
        "cKDTree + numpy (before)": lambda pm: pm.tree.query(q, k=k, distance_upper_bound=radius),
    }
    for name, build in builds.items():
        t_build, pm = best(build)
        t_q, _ = best(lambda: pm.irradiance(q, nq, radius, k, mp, est), repeat=2)
        t_qs, _ = best(lambda: pm.irradiance(qs, nqs, radius, k, mp, est), repeat=2)
        t_raw, _ = best(lambda: raw[name](pm), repeat=2)
        if isinstance(pm, ReferencePhotonMap):
            t = pm.tree
            nbytes = shot.nbytes + t.data.nbytes + t.indices.nbytes + t.size * CKDTREE_NODE_BYTES
        else:
            nbytes = pm.nbytes
        per = t_q / len(q)
        pers = t_qs / len(q)
        rows.append((name, f"{t_build * 1e3:.0f} ms",
                     f"{per * 1e6:.2f} us = {per / ray:.1f} rays",
                     f"{pers * 1e6:.2f} us = {pers / ray:.1f} rays",
                     f"k-NN alone {t_raw / len(q) * 1e6:.2f} us = {t_raw / len(q) / ray:.1f} rays",
                     f"{nbytes / N:.1f} B"))

    # Issue 16: the far side of a wall only (every query widens or is settled empty).
    far = far_side_photons(600_000, rng)
    m = 2000
    qf = np.c_[0.2 + 0.6 * rng.random((m, 2)), np.zeros(m)]
    up = np.tile([0.0, 0.0, 1.0], (m, 1))
    for r_far, label in ((0.08, "~12k photons in the sphere"),
                         (0.2, "~75k photons in the sphere")):
        for name, make in (("kd-tree (compiled)", lambda: PhotonMap(far, 1)),
                           ("cKDTree + numpy (before)", lambda: ReferencePhotonMap(far, 1))):
            pm = make()
            pm.irradiance(qf[:2], up[:2], r_far, k, mp, est)
            tracemalloc.start()
            t0 = time.process_time()
            pm.irradiance(qf, up, r_far, k, mp, est)
            t = time.process_time() - t0
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            rows.append((f"dark wall side, {label}: {name}", "",
                         f"{t / m * 1e6:.1f} us = {t / m / ray:.0f} rays", "",
                         f"peak numpy memory {peak / 1e6:.1f} MB for {m:,} queries", ""))

    rows.extend(listing_floor(PhotonMap(shot, 1), q, radius, k, ray))
    rows.append(gather_row)
    print("| lookup | build | one estimate, random order | coherent order | note | memory / photon |")
    print("|---|---:|---:|---:|---|---:|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    return rows


if __name__ == "__main__":
    main()
