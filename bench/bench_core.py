"""Core benchmark on the paper's Figure 6 box (default 400x300).

Prints: photons traced per second, camera+shadow rays per second through the engine next
to raw embreex on exactly the same rays, kd-tree build and gather times, total render
time. Run from the repo root:

    .venv/bin/python bench/bench_core.py [--width 400 --height 300] [--json out.json]
                                         [--plot out.png]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import RenderSettings  # noqa: E402
from engine.accel import Accel  # noqa: E402
from engine.api import cornell_box  # noqa: E402
from engine.effects import analyse  # noqa: E402
from engine.imageio import replacing  # noqa: E402
from engine.film import Film  # noqa: E402
from engine.integrator import render_camera  # noqa: E402
from engine.lights import allocate_photons  # noqa: E402
from engine.photonmap import PhotonMap  # noqa: E402
from engine.photons import trace_photons  # noqa: E402
from engine.render import Context, prepare_context, render  # noqa: E402


class RecordingAccel(Accel):
    """Accel that keeps a copy of every query so the same rays can be replayed raw.
    enabled = False stops the logging (its copies), for timing the engine alone."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.log = []
        self.enabled = True

    def intersect(self, o, d, tmax=None):
        if self.enabled:
            self.log.append(("INTERSECT", *self._prepare(o, d, tmax)))
        return super().intersect(o, d, tmax)

    def intersect_hits(self, o32, d32, tfar32, out=None):
        # The photon pass's float32 rays (Embree overwrites tfar: copy).
        if self.enabled:
            self.log.append(("INTERSECT", o32.copy(), d32.copy(), tfar32.copy()))
        return super().intersect_hits(o32, d32, tfar32, out)

    def occluded(self, o, d, tmax=None):
        if self.enabled:
            self.log.append(("OCCLUDED", *self._prepare(o, d, tmax)))
        return super().occluded(o, d, tmax)

    def occluded_into(self, o32, d32, tmax32, blocked):
        # The kernels' float32 shadow and visibility rays (Embree overwrites tmax: copy).
        if self.enabled:
            self.log.append(("OCCLUDED", o32.copy(), d32.copy(), tmax32.copy()))
        return super().occluded_into(o32, d32, tmax32, blocked)


def insert_at(src: str, anchor: str, before: str = "", after: str = "") -> str:
    """src with `before` / `after` put around its one occurrence of `anchor`: a kernel's
    source instrumented with counters (bench_widen, bench_secondary). AssertionError
    naming the anchor where it occurs other than once (the kernel changed)."""
    assert src.count(anchor) == 1, anchor
    return src.replace(anchor, before + anchor + after)


def capture_irradiance_calls(name, w, h, out, work, caller, radius_digits=3):
    """Render example blend `name` at w x h (default settings, 1 worker) with every
    PhotonMap.irradiance call recorded, print the CPU each caller's calls took, and
    pickle the maps and calls to `out` (read back by captured_maps). caller(): the
    calling stage's label from the Python stack (sys._getframe), None to leave a call
    unrecorded. work: the folder the blend is exported into (bench_kernels.exported)."""
    import pickle
    import bench_kernels as bk
    from engine.jit import ensure_compiled
    os.makedirs(work, exist_ok=True)
    pkl = bk.exported(name, work)
    ensure_compiled()
    with open(pkl, "rb") as f:
        scene = pickle.load(f)
    scene.width, scene.height = w, h
    irradiance = PhotonMap.irradiance
    maps, calls, cpu = {}, {}, {}

    def record(self, p, n, radius, k, min_photons, estimator, return_boundary=False,
               r_floor=None, should_cancel=None, masks=None):
        args = (p, n, radius, k, min_photons, estimator, return_boundary, r_floor,
                should_cancel, masks)
        label = caller()
        if label is None:
            return irradiance(self, *args)
        if self.tree is not None and self.structure == "kdtree":
            if id(self) not in maps:
                t, ph = self.tree, self.photons
                maps[id(self)] = dict(tree=(t.position, t.axis, t.split, t.leaf, t.bounds),
                                      photons=(ph.position, ph.power, ph.direction,
                                               ph.normal, ph.kind, ph.emitted))
            calls.setdefault((id(self), label, radius), []).append(
                (np.array(p), np.array(n), k, min_photons, estimator, return_boundary,
                 None if r_floor is None else np.array(np.broadcast_to(r_floor, (len(p),))),
                 None if masks is None else np.array(masks)))
        t0 = time.process_time()
        try:
            return irradiance(self, *args)
        finally:
            a = cpu.setdefault((label, len(self.photons), radius), [0, 0.0, 0])
            a[0] += len(p)
            a[1] += time.process_time() - t0
            a[2] += 1

    PhotonMap.irradiance = record
    try:
        t0 = time.process_time()
        render(scene, RenderSettings(workers=1))
        total = time.process_time() - t0
    finally:
        PhotonMap.irradiance = irradiance
    print(f"{name} {w}x{h}: render {total:.2f} CPU s")
    for (label, photons, radius), (rows, secs, nc) in sorted(cpu.items()):
        print(f"  {label} (map {photons:,} photons, r {radius:.{radius_digits}f} m): {nc} "
              f"calls, {rows:,} rows, {secs:.3f} CPU s ({secs / total * 100:.1f} %), "
              f"{secs / max(rows, 1) * 1e6:.2f} us a row")
    with open(out, "wb") as f:
        pickle.dump(dict(maps=maps, calls=calls), f, protocol=4)


def irradiance_rows_source(path=None) -> str:
    """The source of photonmap._irradiance_rows without its @kernel line: from the
    engine/photonmap.py file at path (a base commit's, `git show C:engine/photonmap.py`),
    or this checkout's (None)."""
    if path is None:
        import inspect
        import textwrap
        from engine import photonmap
        return textwrap.dedent(inspect.getsource(photonmap._irradiance_rows.py_func)
                               ).replace("@kernel\n", "")
    with open(path) as f:
        t = f.read()
    i = t.index("@kernel\ndef _irradiance_rows(")
    return t[i:t.index("@register_warm_up", i)].replace("@kernel\n", "")


def counted_irradiance_rows(src: str, counters: str, inserts):
    """(counted, plain): the k-NN estimate kernel of source src compiled in photonmap's
    module scope (numba.njit(nogil=True), uncached), once with counters and once as it
    is. counted takes the arrays named by `counters` (e.g. "cls, nph") before
    _irradiance_rows' own arguments; inserts: (anchor, before, after) triples put into
    the source by insert_at (each anchor must occur once: the kernel changed otherwise)."""
    import numba
    from engine import photonmap
    body = src.replace("def _irradiance_rows(", f"def _counted({counters}, ")
    for anchor, before, after in inserts:
        body = insert_at(body, anchor, before, after)
    scope = dict(photonmap.__dict__)
    exec(body, scope)
    plain = dict(photonmap.__dict__)
    exec(src, plain)
    return (numba.njit(nogil=True)(scope["_counted"]),
            numba.njit(nogil=True)(plain["_irradiance_rows"]))


def captured_maps(path):
    """The photon-map estimates a render made, as bench_lookup.py --render-calls captured
    them into the pickle at path: yields (caller, radius, calls, PhotonMap), the map
    rebuilt from its saved kd-tree and photons (calls: the irradiance arguments, row by
    row: p, n, k, min_photons, estimator, return_boundary, r_floor[, masks])."""
    import pickle
    from engine import kdtree
    from engine.photons import Photons
    with open(path, "rb") as f:
        cap = pickle.load(f)
    for (mid, caller, radius), calls in cap["calls"].items():
        m = cap["maps"][mid]
        t = kdtree.KdTree.__new__(kdtree.KdTree)
        t.position, t.axis, t.split, t.leaf, t.bounds = m["tree"]
        t.order = None
        pm = PhotonMap.__new__(PhotonMap)
        pm.workers, pm.structure, pm.tree = 1, "kdtree", t
        pm.photons = Photons(*m["photons"])
        yield caller, radius, calls, pm


def best_rows_time(pm, calls, classes, radius, rows_kernel, pick, repeat=3) -> float:
    """Best of `repeat` process-CPU seconds to replay the captured estimates `calls`
    (captured_maps) on PhotonMap pm with photonmap._irradiance_rows set to rows_kernel,
    each call on the rows pick(classes[i]) selects (classes: per call, each row's class
    from a counted run; pick(c) -> row indices), or on all of its rows (pick None)."""
    from engine import photonmap
    photonmap._irradiance_rows = rows_kernel
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        for (p, n, k, mp, est, rb, rf, mk), c in zip(calls, classes):
            if pick is None:
                pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb, r_floor=rf,
                              masks=mk)
                continue
            s = pick(c)
            if len(s):
                pm.irradiance(p[s], n[s], radius, k, mp, est, return_boundary=rb,
                              r_floor=None if rf is None else rf[s], masks=mk)
        best = min(best, time.process_time() - t0)
    return best


def recording(accel):
    """The RecordingAccel behind a context's accel (prepare_context wraps it in a
    VisibilityAccel, whose `full` BVH answers every class when no object hides from a
    ray kind, as in these benchmark scenes)."""
    return getattr(accel, "full", accel)


def raw_embree_time(accel: Accel, log) -> float:
    """Replay logged queries straight through embreex, split over the same threads."""
    scene = accel._scene
    t0 = time.perf_counter()
    for query, o, d, t in log:
        def work(a, b):
            if query == "INTERSECT":
                scene.run(o[a:b], d[a:b], dists=t[a:b].copy(), output=True)
            else:
                scene.run(o[a:b], d[a:b], dists=t[a:b].copy(), query="OCCLUDED")
        accel._run(work, len(o))
    return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=400)
    ap.add_argument("--height", type=int, default=300)
    ap.add_argument("--photons", type=int, default=RenderSettings.photons)
    ap.add_argument("--spp", type=int, default=RenderSettings.spp)
    ap.add_argument("--workers", type=int, default=0)
    ap.add_argument("--json", help="write the results as JSON")
    ap.add_argument("--plot", help="write a bar chart of stage times (PNG)")
    args = ap.parse_args(argv)

    try:  # compiled kernels (after issue 13): compile / load them before any timing
        from engine.jit import ensure_compiled
        ensure_compiled()
    except ImportError:
        pass
    scene = cornell_box(args.width, args.height)
    settings = RenderSettings(photons=args.photons, spp=args.spp, workers=args.workers)
    rows = []
    ctx = prepare_context(scene, settings, RecordingAccel)
    geo, table, accel, lights = ctx.geo, ctx.table, ctx.accel, ctx.lights
    rec = recording(accel)  # where the queries are logged

    # Photon tracing.
    t0 = time.perf_counter()
    shot = trace_photons(ctx, lights, allocate_photons(lights, settings.photons), False, 1)
    t_ph = time.perf_counter() - t0
    rows.append(("photon pass", f"{settings.photons:,} photons", t_ph,
                 f"{settings.photons / t_ph / 1e6:.2f} M photons/s emitted, "
                 f"{len(shot):,} stored ({len(shot) / t_ph / 1e6:.2f} M/s)"))
    rays_photon = sum(len(entry[1]) for entry in rec.log)
    raw = raw_embree_time(rec, rec.log)
    rows.append(("  raw embreex, same rays", f"{rays_photon:,} rays", raw,
                 f"engine at {100 * raw / t_ph:.0f} % of Embree's ceiling"))
    rec.log.clear()

    # kd-tree build and gather.
    t0 = time.perf_counter()
    pm = PhotonMap(shot, settings.threads)
    t_build = time.perf_counter() - t0
    rows.append(("kd-tree build", f"{len(shot):,} photons", t_build, ""))
    q = 200_000
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(shot), q)
    t0 = time.perf_counter()
    pm.irradiance(shot.position[idx].astype(float), shot.normal[idx].astype(float),
                  0.2, settings.k_nearest, settings.min_photons, settings.estimator)
    t_gather = time.perf_counter() - t0
    rows.append(("k-NN gather", f"{q:,} queries k={settings.k_nearest}", t_gather,
                 f"{t_gather / q * 1e6:.2f} s per million queries"))

    # Camera + shadow rays (direct light and mirrors: the ray-bound part of pass 2).
    direct = RenderSettings(photon_mapping=False, spp=settings.spp, workers=args.workers)
    ctx_d = Context(scene, direct, geo, table, accel, lights)
    ctx_d.plan = analyse(scene, geo, table, lights, accel, direct)
    film = Film(args.width, args.height)
    t0 = time.perf_counter()
    render_camera(ctx_d, (0, 0, args.width, args.height), film)
    t_cam = time.perf_counter() - t0
    n_rays = sum(len(entry[1]) for entry in rec.log)
    raw = raw_embree_time(rec, rec.log)
    rows.append(("camera+shadow rays", f"{n_rays:,} rays", t_cam,
                 f"{n_rays / t_cam / 1e6:.2f} M rays/s through the engine"))
    rows.append(("  raw embreex, same rays", f"{n_rays:,} rays", raw,
                 f"{n_rays / raw / 1e6:.2f} M rays/s; engine at {100 * raw / t_cam:.0f} %"))
    rec.log.clear()
    accel.close()

    # Whole default render.
    t0 = time.perf_counter()
    full = render(scene, settings)
    t_total = time.perf_counter() - t0
    st = full.stats
    rows.append(("full render (defaults)", f"{args.width}x{args.height}, {settings.spp} spp",
                 t_total, f"photons {st.get('time_photons', 0):.2f} s, maps "
                 f"{st.get('time_photon_map', 0):.2f} s, camera {st.get('time_camera', 0):.2f} s"))

    print(f"\nFigure 6 box, {geo.count:,} triangles, {settings.threads} worker(s)\n")
    print("| stage | work | seconds | note |\n|---|---|---:|---|")
    for name, work, secs, note in rows:
        print(f"| {name} | {work} | {secs:.3f} | {note} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump([dict(stage=r[0], work=r[1], seconds=r[2], note=r[3]) for r in rows], f, indent=1)
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.barh([r[0] for r in rows][::-1], [r[2] for r in rows][::-1])
        ax.set_xlabel("seconds")
        ax.set_title(f"Figure 6 box {args.width}x{args.height}")
        fig.tight_layout()
        with replacing(args.plot) as tmp:
            fig.savefig(tmp, dpi=100)
    return rows


if __name__ == "__main__":
    main()
