"""Every k-NN irradiance estimate of a render (issue 13, s21 causticknn): per caller (the
caustic map at the camera hits, the secondary map at the camera hits and at the
regathers, the gather map's estimates at its points), rows, CPU and us a row; then, per
row class, where a row's time goes.

    PYTHONPATH=$PWD python bench/bench_causticknn.py capture BLEND W H OUT.calls
    PYTHONPATH=$PWD python bench/bench_causticknn.py classes OUT.calls...
    PYTHONPATH=$PWD python bench/bench_causticknn.py replay BASE_ROOT OUT.calls...
    PYTHONPATH=$PWD python bench/bench_causticknn.py paths BASE_ROOT CALLERS OUT.calls...
    PYTHONPATH=$PWD python bench/bench_causticknn.py ratio BLEND OUT.calls [BASE_ROOT]

`capture` renders an example blend (exported through the add-on into WORK, default
/tmp/causticknn/work) at its default settings, 1 worker, records every
PhotonMap.irradiance call with its caller and prints their process CPU against the
render's. `classes` counts, per caller, the rows whose search sphere (the radius cap)
holds no photon at all, none accepted (arriving from the front on a surface facing the
same way), fewer than min_photons accepted, and the k-NN paths taken (seeded, listed,
heap, widened). `replay` times each caller's captured calls through BASE_ROOT's
photonmap.py kernel (with its kdtree.py, both compiled from source) and this checkout's,
interleaved, one thread, best of 3 process CPU, and checks that both give the same bits.
`paths` splits a caller's rows by the k-NN path BASE_ROOT's kernel takes (seeded from
a block's candidates or the tree, listed from candidates or the tree: empty / < k / >= k,
heap, widened, floored focus) and times each path alone.
`ratio` is issue 13's "one photon lookup (the default estimator, k = 64) <= 5 Embree
traversals": the captured caustic estimates at the camera hits (knn_simpson, k = 64) of
BLEND, all of them and the dense ones (at least k photons within the search radius: the
estimate reads its k nearest), CPU ns a row (one thread, best of 3, in the calls' own
rows order), against one Embree traversal of the same scene (BLEND's exported scene,
Embree's one-ray traversal: raw embreex run() on the engine's scene, one thread, best
of 3; not Accel.intersect's packet path): closest-hit and occlusion rays from those
dense rows' points into their hemisphere (as the gather rays leave them), and closest
hits from the middle of the scene's box (bench_lookup.py's rays). With BASE_ROOT, the
estimates through its kernel too (_kernel_from), interleaved. Then the same calls
through settings.caustic_lookup = "precomputed" (engine/causticcache.py): its precompute
once (CPU s), and the lookups.
"""
from __future__ import annotations

import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))
WORK = os.environ.get("CAUSTICKNN_WORK", "/tmp/causticknn/work")


def _caller(depth):
    """The estimate's caller, from the Python stack `depth` frames up: caustic / secondary
    (camera hits), regather (secondary at the regathered points), gathermap (GatherMap's
    estimates) or other."""
    f = sys._getframe(depth)
    while f is not None:
        c = f.f_code.co_name
        if c == "_secondary_irradiance":
            return "regather"
        if c == "_smooth_estimate":
            pm = f.f_locals.get("pmap")
            ctx = f.f_locals.get("ctx")
            if ctx is not None and pm is ctx.caustic_map:
                return "caustic"
            return "secondary"
        if c == "estimate" and "estimating" in f.f_locals:
            return "gathermap"
        f = f.f_back
    return "other"


def CALLER():
    """(capture_irradiance_calls' caller) the stage of the call being recorded."""
    return _caller(4)  # past _caller, CALLER, the recorder and the estimate's direct caller


def capture(name, w, h, out):
    from bench_core import capture_irradiance_calls
    capture_irradiance_calls(name, w, h, out, WORK, CALLER, radius_digits=4)


def _kernel_from(root, counters=None, inserts=()):
    """_irradiance_rows compiled from root's engine/photonmap.py, from _widen_listed on
    (the estimate's own helpers, with root's module constants), over root's
    engine/kdtree.py (compiled from source too, uncached); the other helpers are this
    checkout's. With counters (e.g. "cls"): (counted, plain), counted the kernel with
    bench_core.insert_at's (anchor, before, after) inserts, taking the counter arrays
    first (as bench_core.counted_irradiance_rows)."""
    import types
    import numba
    from engine import photonmap
    src = open(os.path.join(root, "engine", "kdtree.py")).read()
    src = src.replace("from .jit import kernel, register_warm_up",
                      "import numba as _numba\nkernel = _numba.njit(nogil=True)\n"
                      "register_warm_up = lambda f: f")
    src = src.replace("from .parallel import", "from engine.parallel import")
    kd = types.ModuleType("kdtree_of_" + root.strip("/").replace("/", "_"))
    sys.modules[kd.__name__] = kd
    exec(compile(src, os.path.join(root, "engine", "kdtree.py"), "exec"), kd.__dict__)
    t = open(os.path.join(root, "engine", "photonmap.py")).read()
    head = t[:t.index("class PhotonMap")]
    i = t.index("@kernel\ndef _widen_listed(")
    seg = t[i:t.index("@register_warm_up", i)].replace("@kernel\n", "@_nj\n")
    scope = dict(photonmap.__dict__)
    scope["_nj"] = numba.njit(nogil=True)
    exec("\n".join(x for x in head.splitlines() if not x.startswith(("from ", "import "))),
         scope)
    scope["kdtree"] = kd
    exec(seg, scope)
    if counters is None:
        return scope["_irradiance_rows"]
    from bench_core import insert_at, irradiance_rows_source
    body = irradiance_rows_source(os.path.join(root, "engine", "photonmap.py")).replace(
        "def _irradiance_rows(", f"def _counted({counters}, ")
    for anchor, before, after in inserts:
        body = insert_at(body, anchor, before, after)
    exec(body, scope)
    return scope["_nj"](scope["_counted"]), scope["_irradiance_rows"]


def classes(captures):
    """Per caller: rows, rows with no photon inside the radius cap, none accepted,
    fewer than min_photons accepted, and the mean photons in the cap's sphere."""
    import numpy as np
    from bench_core import captured_maps
    print("| capture | caller (map photons, radius) | rows | sphere empty % | none accepted % "
          "| < min accepted % | photons in sphere (mean / median) | k / min |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for path in captures:
        for caller, radius, calls, pm in captured_maps(path):
            t = pm.tree
            ph = pm.photons
            nb_all, acc_all = [], []
            for p, n, k, mp, est, rb, rf, mk in calls:
                nb = np.empty(len(p), np.int64)
                acc = np.empty(len(p), np.int64)
                _sphere_counts(t.position, t.axis, t.split, t.leaf, ph.direction, ph.normal,
                               np.ascontiguousarray(p, np.float64),
                               np.ascontiguousarray(n, np.float64), radius * radius, nb, acc)
                nb_all.append(nb)
                acc_all.append(acc)
            nb, acc = np.concatenate(nb_all), np.concatenate(acc_all)
            rows = len(nb)
            mp = calls[0][3]
            print(f"| {os.path.basename(path)} | {caller} ({len(ph):,}, {radius:.4f} m) | "
                  f"{rows:,} | {(nb == 0).mean() * 100:.1f} | {(acc == 0).mean() * 100:.1f} | "
                  f"{(acc < mp).mean() * 100:.1f} | {nb.mean():.0f} / {np.median(nb):.0f} | "
                  f"{calls[0][2]} / {mp} |", flush=True)


def _compiled_counts():
    """A compiled counter: per row, the photons within the radius cap (kdtree.ball) and
    how many of them are accepted (photonmap._accepted)."""
    import numba
    import numpy
    from engine import kdtree
    from engine.photonmap import _accepted
    g = dict(np=numpy, kdtree=kdtree, _accepted=_accepted)
    src = ("def f(pos, axis, split, leaf, direction, normal, p, n, r2, nb, acc):\n"
           "    scan = np.empty(1 << 22, np.int64)\n"
           "    unknown = np.full(pos.shape[0], -1, np.int32)  # no surfaces: the normal test\n"
           "    for i in range(p.shape[0]):\n"
           "        c = kdtree.ball(pos, axis, split, leaf, p[i, 0], p[i, 1], p[i, 2], r2,\n"
           "                        scan, scan.shape[0] - 1)\n"
           "        nb[i] = c\n"
           "        a = 0\n"
           "        nx, ny, nz = np.float32(n[i, 0]), np.float32(n[i, 1]), np.float32(n[i, 2])\n"
           "        for j in range(min(c, scan.shape[0] - 1)):\n"
           "            if _accepted(direction, normal, unknown, pos, scan[j], nx, ny, nz,\n"
           "                         -1, p[i, 0], p[i, 1], p[i, 2])[0]:\n"
           "                a += 1\n"
           "        acc[i] = a\n")
    exec(src, g)
    return numba.njit(nogil=True)(g["f"])


_sphere_counts_kernel = None


def _sphere_counts(*a):
    global _sphere_counts_kernel
    if _sphere_counts_kernel is None:
        _sphere_counts_kernel = _compiled_counts()
    _sphere_counts_kernel(*a)


def replay(base_root, captures, repeat=3):
    """Each caller's captured calls through base_root's kernel and this checkout's,
    alternating, best of `repeat` process CPU each; the bits compared."""
    from bench_core import captured_maps
    from engine import photonmap
    from engine.jit import ensure_compiled
    ensure_compiled()
    kernels = {"base": _kernel_from(base_root), "this": photonmap._irradiance_rows}
    print("| capture | caller (map photons, radius) | rows | base / this CPU ms | "
          "base / this us a row | same bits |")
    print("|---|---|---:|---:|---:|---|")
    for path in captures:
        for caller, radius, calls, pm in captured_maps(path):
            results = {}

            def run(label):
                photonmap._irradiance_rows = kernels[label]
                t0 = time.process_time()
                res = [pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb,
                                     r_floor=rf, masks=mk)
                       for p, n, k, mp, est, rb, rf, mk in calls]
                dt = time.process_time() - t0
                results[label] = res
                return dt
            best = {"base": 1e9, "this": 1e9}
            for _ in range(repeat):
                for label in ("base", "this"):
                    best[label] = min(best[label], run(label))
            same = all(_same(a, b) for a, b in zip(results["base"], results["this"]))
            rows = sum(len(c[0]) for c in calls)
            tb, tt = best["base"], best["this"]
            print(f"| {os.path.basename(path)} | {caller} ({len(pm.photons):,}, "
                  f"{radius:.4f} m) | {rows:,} | {tb * 1e3:.0f} / {tt * 1e3:.0f} | "
                  f"{tb / rows * 1e6:.3f} / {tt / rows * 1e6:.3f} | {same} |", flush=True)
            photonmap._irradiance_rows = kernels["this"]


def _same(a, b):
    import numpy as np
    if isinstance(a, tuple):
        return all(_same(x, y) for x, y in zip(a, b))
    return np.array_equal(a, b)


PATHS = {1: "seeded (block candidates)", 2: "seeded (tree)",
         11: "listed from candidates, sphere empty", 12: "listed from candidates, 1-63",
         13: "listed from candidates, 64-512", 21: "listed by the tree, sphere empty",
         22: "listed by the tree, 1-63", 23: "listed by the tree, 64-512",
         7: "heap (> 512 photons)", 8: "widened", 9: "focus floored"}
# cls + 100: the row tried a seeded sphere first (the previous row's kq-th distance).
_SET = "cls[i] = cls[i] - cls[i] % 100 + "


def paths(base_root, callers, captures):
    """Per caller in `callers` (comma-separated), each row's k-NN path in base_root's
    kernel (_kernel_from: its photonmap.py and kdtree.py; an instrumented copy: PATHS,
    + 100 where a seeded sphere was tried first), then each path's rows alone through the base kernel and this checkout's: rows,
    share, CPU us a row (best of 3 process CPU). A path's rows replayed alone lose their
    neighbours (seeds, blocks): their cost alone, not in the render's context."""
    import numpy as np
    from bench_core import best_rows_time, captured_maps
    from engine import photonmap
    from engine.jit import ensure_compiled
    ensure_compiled()
    counted, base = _kernel_from(base_root, "cls", [
        ("                b2 = prev_kth * SEED_GROWTH\n", "", "                cls[i] = 100\n"),
        ("            if seeded:\n                cnt = kq\n", "",
         " " * 16 + _SET + "(1 if from_cand else 2)\n"),
        ("                if from_cand:\n                    pass", " " * 16 + _SET
         + "(10 if from_cand else 20) + (1 if listed == 0 else 2 if listed < kq else 3)\n",
         ""),
        ("                    listed = -1\n                    cnt = _knn(",
         " " * 20 + _SET + "7\n", ""),
        ("                prev_kth = -1.0\n                if listed >= 0 and from_cand:",
         " " * 16 + _SET + "8\n", ""),
        ("            in_disc = _ball_count(", " " * 12 + _SET + "9\n", "")])
    kernels = {"base": base, "this": photonmap._irradiance_rows}
    print("| capture | caller | path | rows | share % | base / this CPU ms "
          "| base / this us a row |")
    print("|---|---|---|---:|---:|---:|---:|")
    for path in captures:
        for caller, radius, calls, pm in captured_maps(path):
            if caller not in callers.split(","):
                continue
            C = []
            for p, n, k, mp, est, rb, rf, mk in calls:
                cls = np.zeros(len(p), np.int64)
                photonmap._irradiance_rows = lambda *a: counted(cls, *a)
                pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb, r_floor=rf,
                              masks=mk)
                C.append(cls)

            def run(fn, pick):
                return best_rows_time(pm, calls, C, radius, fn, pick)
            allc = np.concatenate(C)
            tag = f"{os.path.basename(path)} | {caller} ({len(pm.photons):,}, {radius:.4f} m)"
            for cl in [None] + sorted(set(allc.tolist())):
                pick = ((lambda c: np.arange(len(c))) if cl is None
                        else (lambda c, cl=cl: np.flatnonzero(c == cl)))
                sel = np.ones(len(allc), bool) if cl is None else allc == cl
                tb, tt = (run(kernels[v], pick) for v in ("base", "this"))
                rows = int(sel.sum())
                name = ("all" if cl is None else PATHS.get(cl % 100, cl)
                        + (", seed tried" if cl >= 100 else ""))
                print(f"| {tag} | {name} | {rows:,} | "
                      f"{sel.mean() * 100:.1f} | {tb * 1e3:.0f} / {tt * 1e3:.0f} | "
                      f"{tb / rows * 1e6:.3f} / {tt / rows * 1e6:.3f} |", flush=True)
            photonmap._irradiance_rows = kernels["this"]


def ratio(name, path, base_root=None, repeat=3):
    """The k = 64 caustic estimate against one Embree traversal (module docstring)."""
    import pickle
    import numpy as np
    import bench_kernels as bk
    from bench_core import best_rows_time, captured_maps
    from engine import RenderSettings, photonmap
    from engine.jit import ensure_compiled
    from engine.render import prepare_context
    ensure_compiled()
    kernels = {"this": photonmap._irradiance_rows}
    if base_root:
        kernels = {"base": _kernel_from(base_root), **kernels}
    caustic = [(radius, calls, pm) for caller, radius, calls, pm in captured_maps(path)
               if caller == "caustic"]
    radius, calls, pm = caustic[0]
    t, ph = pm.tree, pm.photons
    dense_calls, pts, nrm = [], [], []
    for p, n, k, mp, est, rb, rf, mk in calls:
        nb = np.empty(len(p), np.int64)
        acc = np.empty(len(p), np.int64)
        p64, n64 = np.ascontiguousarray(p, np.float64), np.ascontiguousarray(n, np.float64)
        _sphere_counts(t.position, t.axis, t.split, t.leaf, ph.direction, ph.normal, p64,
                       n64, radius * radius, nb, acc)
        s = np.flatnonzero(nb >= k)
        if len(s):
            dense_calls.append((p[s], n[s], k, mp, est, rb, None if rf is None else rf[s],
                                mk))
            pts.append(p64[s])
            nrm.append(n64[s])
    # The photon-visibility pass's masked re-estimates (one Python call per few rows,
    # photonvisibility.visible_irradiance) are filed under "caustic" too; the precomputed
    # path cannot serve them: "dense, unmasked" leaves them out.
    dense_unmasked = [c for c in dense_calls if c[7] is None]
    est_of = {calls[0][4]}
    print(f"{name}: caustic map {len(ph):,} photons, radius {radius:.4f} m, "
          f"k = {calls[0][2]}, estimator {', '.join(est_of)}")

    def rows_ns(cs, label):
        best = best_rows_time(pm, cs, [None] * len(cs), radius, kernels[label], None, repeat)
        photonmap._irradiance_rows = kernels["this"]
        return best / sum(len(c[0]) for c in cs) * 1e9
    est = {}
    for label in kernels:  # interleaved per set
        est[("all", label)] = rows_ns(calls, label)
        est[("dense", label)] = rows_ns(dense_calls, label)
        est[("dense, unmasked", label)] = rows_ns(dense_unmasked, label)
    # The same calls through the precomputed estimates (settings.caustic_lookup =
    # "precomputed", engine/causticcache.py): their precompute once, then lookups.
    from engine import causticcache
    pm.lookup, pm.precomputed = "precomputed", {}
    p0, n0, k0, mp0, est0 = calls[0][:5]
    t_pre = 1e9
    for _ in range(2):  # the first compiles causticcache's kernels
        t0 = time.process_time()
        pre = causticcache.PrecomputedIrradiance(pm, radius, k0, mp0, est0,
                                                 surfaces=False)
        t_pre = min(t_pre, time.process_time() - t0)
    # (the calls give no query surfaces: the estimates without the surface test)
    pre_surfaces = False
    pm.precomputed[(float(radius), int(k0), int(mp0), est0, pre_surfaces)] = pre
    print(f"precomputed: {pre.stored:,} of {len(ph):,} photons hold an estimate, "
          f"{t_pre:.3f} CPU s ({t_pre / len(ph) * 1e9:.0f} ns a photon), "
          f"{pre.nbytes / len(ph):.0f} bytes a photon")

    def lookup_ns(cs):
        best = 1e9
        for _ in range(repeat):
            t0 = time.process_time()
            for p, n, k, mp, e, rb, rf, mk in cs:
                pm.irradiance(p, n, radius, k, mp, e, return_boundary=rb, r_floor=rf,
                              masks=mk)
            best = min(best, time.process_time() - t0)
        return best / sum(len(c[0]) for c in cs) * 1e9
    est[("all", "precomputed")] = lookup_ns(calls)
    est[("dense", "precomputed")] = lookup_ns(dense_calls)
    est[("dense, unmasked", "precomputed")] = lookup_ns(dense_unmasked)
    pm.lookup = "knn"
    # One Embree traversal of the scene the estimates were made in: Embree's own one-ray
    # traversal (raw embreex run(), rtcIntersect1 / rtcOccluded1 per ray, as
    # bench_core.raw_embree_time replays), not Accel.intersect's packet path (whose
    # float32 packet filling and Python wrapper made a ray ~71 ns against Embree's ~49).
    with open(bk.exported(name, WORK), "rb") as f:
        scene = pickle.load(f)
    ctx = prepare_context(scene, RenderSettings(workers=1))
    emb = getattr(ctx.accel, "full", ctx.accel)._scene  # (VisibilityAccel: the whole scene)
    rng = np.random.default_rng(1)
    P, N = np.vstack(pts), np.vstack(nrm)
    pick = rng.integers(0, len(P), 200_000)
    d = rng.normal(size=(len(pick), 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    d *= np.where((d * N[pick]).sum(1) < 0, -1.0, 1.0)[:, None]  # into the hemisphere
    o = P[pick] + 1e-4 * N[pick]
    lo, hi = (np.asarray(b, np.float64) for b in ctx.geo.bounds)
    ob = lo + (hi - lo) * (0.3 + 0.4 * rng.random((len(pick), 3)))
    o32, ob32, d32 = (np.ascontiguousarray(a, np.float32) for a in (o, ob, d))
    far = np.full(len(pick), 1e30, np.float32)

    def ray_ns(fn):
        fn()
        best = 1e9
        for _ in range(repeat):
            t0 = time.process_time()
            fn()
            best = min(best, time.process_time() - t0)
        return best / len(pick) * 1e9
    ray = {"closest hit, from the dense rows' points": ray_ns(
               lambda: emb.run(o32, d32, dists=far.copy(), output=True)),
           "occlusion, from the dense rows' points": ray_ns(
               lambda: emb.run(o32, d32, dists=far.copy(), query="OCCLUDED")),
           "closest hit, from the box's middle": ray_ns(
               lambda: emb.run(ob32, d32, dists=far.copy(), output=True))}
    ctx.accel.close()
    ref = ray["closest hit, from the dense rows' points"]
    n_rows_of = {"all": sum(len(c[0]) for c in calls),
                 "dense": sum(len(c[0]) for c in dense_calls),
                 "dense, unmasked": sum(len(c[0]) for c in dense_unmasked)}
    print("| work | rows / rays | CPU ns each | in one-ray closest-hit traversals |")
    print("|---|---:|---:|---:|")
    for (which, label), ns in est.items():
        n_rows = n_rows_of[which]
        print(f"| caustic estimates, {which} ({label}) | {n_rows:,} | {ns:.0f} | "
              f"{ns / ref:.1f} |")
    for what, ns in ray.items():
        print(f"| Embree one-ray {what} | {len(pick):,} | {ns:.0f} | {ns / ref:.2f} |")


if __name__ == "__main__":
    if sys.argv[1] == "capture":
        capture(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5])
    elif sys.argv[1] == "paths":
        paths(sys.argv[2], sys.argv[3], sys.argv[4:])
    elif sys.argv[1] == "ratio":
        ratio(sys.argv[2], sys.argv[3], *sys.argv[4:5])
    elif sys.argv[1] == "classes":
        classes(sys.argv[2:])
    else:
        replay(sys.argv[2], sys.argv[3:])
