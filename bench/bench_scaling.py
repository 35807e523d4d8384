"""Performance suite for issue 8: ceiling ratios, kd-tree, scaling, memory, workers.

Everything runs in this one process (ratios are computed between runs made side by side,
best of --repeat), except peak RSS, which is measured in a fresh child process per case.

    .venv/bin/python bench/bench_scaling.py --quick            # < 2 minutes
    .venv/bin/python bench/bench_scaling.py                    # full (1M triangles, 5M photons)
    .venv/bin/python bench/bench_scaling.py --only kdtree --json out/bench.json

Sections: rays (engine vs raw embreex on the same rays), photons (per bounce), kdtree
(build / gather per million queries), scaling (pixels, photons, triangles, lights),
memory (peak RSS, bytes per photon), workers (1 vs 2, same image), camera_workers (where
two workers lose in a default render's camera stage: per-thread timeline of the chunks),
critical_path (issue 13's 2 workers >= 1.8x: per stage the CPU on the critical path,
traced through engine.parallel.Trace, predicted and measured speed-ups), faults (the
minor page faults of a render by Python function / numpy call, 1 worker against 2):

    .venv/bin/python bench/bench_scaling.py --only critical_path --repeat 1 \\
        --blends figure6_box,figure7_blocker,principled_spheres_df2 --sizes 160x120,320x240
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import threading
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

from engine import RenderSettings  # noqa: E402
from engine.api import cornell_box, sphere_mesh  # noqa: E402
from engine.film import Film  # noqa: E402
from engine.geometry import prepare  # noqa: E402
from engine.integrator import render_camera  # noqa: E402
from engine.lights import allocate_photons  # noqa: E402
from engine.photonmap import PhotonMap  # noqa: E402
from engine.photons import Photons, trace_photons  # noqa: E402
from engine.render import prepare_context, render  # noqa: E402

from bench_core import RecordingAccel, raw_embree_time, recording  # noqa: E402

TABLES: dict[str, list[dict]] = {}


def table(name, rows):
    TABLES[name] = rows
    if not rows:
        return
    keys = list(rows[0].keys())
    print(f"\n### {name}\n")
    print("| " + " | ".join(keys) + " |")
    print("|" + "|".join("---:" if isinstance(rows[0][k], (int, float)) else "---" for k in keys) + "|")
    for r in rows:
        cells = []
        for k in keys:
            v = r[k]
            cells.append(f"{v:,.3f}" if isinstance(v, float) else (f"{v:,}" if isinstance(v, int) else str(v)))
        print("| " + " | ".join(cells) + " |")
    sys.stdout.flush()


def best_of(n, fn):
    """(best wall s, last result) of n calls."""
    wall, _, out = best_of_cpu(n, fn)
    return wall, out


def box(width, height, sphere_tris=None, lights=1):
    """Figure 6 box; sphere_tris replaces the glass sphere by a subdivided diffuse sphere
    of about that many triangles; lights > 1 adds small point lights."""
    s = cornell_box(width, height, glass_sphere=sphere_tris is None)
    if sphere_tris is not None:
        seg = max(4, int(round(np.sqrt(sphere_tris))))
        v, f, n, _ = sphere_mesh((-0.7, -0.4, 0.7), 0.7, segments=seg, rings=max(3, seg // 2))
        s.add_triangles(v, f, "white_diffuse", name="sphere", normals=n)
    for i in range(lights - 1):
        a = 2 * np.pi * i / max(1, lights - 1)
        s.add_point_light((1.2 * np.cos(a), 1.2 * np.sin(a) - 0.5, 3.2), power=20.0, radius=0.05)
    return s


def make_ctx(scene, settings):
    """Context over a RecordingAccel: every query is logged for a raw replay."""
    return prepare_context(scene, settings, RecordingAccel)


# --------------------------------------------------------------------------- sections

def best_of_cpu(n, fn):
    """(best wall s, best CPU s of the process (all threads), last result) of n calls."""
    wall = cpu = float("inf")
    out = None
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu, out


def engine_vs_raw(ctx, run, repeat):
    """Time run() (the engine) with the query log off, then once with it on, and replay
    the logged rays straight through embreex: (rays, engine wall s, engine CPU s, raw wall
    s, raw CPU s). The log's copies are kept out of the engine's time."""
    rec = recording(ctx.accel)
    run()  # loads / compiles whatever the first call needs
    rec.enabled = False
    wall, cpu, _ = best_of_cpu(repeat, run)
    rec.enabled = True
    rec.log.clear()
    run()
    log = list(rec.log)
    rec.log.clear()
    raw_wall, raw_cpu, _ = best_of_cpu(repeat, lambda: raw_embree_time(rec, log))
    return sum(len(e[1]) for e in log), wall, cpu, raw_wall, raw_cpu


def sec_rays(a):
    """Engine vs raw embreex, same rays: photon pass and camera + shadow (direct light),
    wall and CPU seconds (on a shared machine the CPU ratio moves less with the load)."""
    try:  # compile / load the kernels before any timing
        from engine.jit import ensure_compiled
        ensure_compiled()
    except ImportError:
        pass
    rows = []

    def row(stage, n, wall, cpu, raw_wall, raw_cpu):
        rows.append(dict(stage=stage, rays=n, engine_s=wall, raw_embree_s=raw_wall,
                         engine_Mrays_s=n / wall / 1e6, ceiling_pct=100 * raw_wall / wall,
                         engine_cpu_s=cpu, raw_cpu_s=raw_cpu, cpu_ceiling_pct=100 * raw_cpu / cpu))

    scene = box(a.width, a.height)
    st = RenderSettings(photons=a.photons, workers=a.workers)
    ctx = make_ctx(scene, st)
    counts = allocate_photons(ctx.lights, st.photons)
    row("photon pass", *engine_vs_raw(
        ctx, lambda: trace_photons(ctx, ctx.lights, counts, False, 1), a.repeat))
    ctx.accel.close()
    direct = RenderSettings(photon_mapping=False, spp=a.spp, workers=a.workers)
    # The ratio depends on the scene as much as on the engine: a traversal of the 30
    # triangles of the box costs less than a 1M-triangle sphere's.
    heavy = 200_000 if a.quick else 1_000_000
    for label, sc in (("box", scene), (f"box + {heavy // 1000}k-tri sphere",
                                        box(a.width, a.height, sphere_tris=heavy))):
        ctx = make_ctx(sc, direct)
        cam = lambda: render_camera(ctx, (0, 0, a.width, a.height),  # noqa: E731
                                    Film(a.width, a.height))
        row(f"camera+shadow, {label}, {a.width}x{a.height} {a.spp} spp",
            *engine_vs_raw(ctx, cam, a.repeat))
        ctx.accel.close()
    table("rays: engine vs raw embreex (same rays, same threads)", rows)


def sec_photons(a):
    """Photons per second and rays per bounce (from the recorded intersect calls)."""
    scene = box(a.width, a.height)
    st = RenderSettings(photons=a.photons, workers=a.workers)
    ctx = make_ctx(scene, st)
    counts = allocate_photons(ctx.lights, st.photons)
    t, shot = best_of(a.repeat, lambda: (recording(ctx.accel).log.clear(), trace_photons(ctx, ctx.lights, counts, False, 1))[1])
    # Each chunk issues one intersect per bounce, in order: bounce b = b-th call of a chunk.
    per_bounce = {}
    calls = [len(e[1]) for e in recording(ctx.accel).log if e[0] == "INTERSECT"]
    chunk_first = [i for i, c in enumerate(calls) if i == 0 or c > calls[i - 1]]
    for ci, start in enumerate(chunk_first):
        end = chunk_first[ci + 1] if ci + 1 < len(chunk_first) else len(calls)
        for b, c in enumerate(calls[start:end]):
            per_bounce[b] = per_bounce.get(b, 0) + c
    total_rays = sum(per_bounce.values())
    rows = [dict(bounce=b, rays=c, share_pct=100 * c / total_rays,
                 est_M_per_s=c / (t * c / total_rays) / 1e6) for b, c in sorted(per_bounce.items())]
    rows.append(dict(bounce="all", rays=total_rays, share_pct=100.0,
                     est_M_per_s=total_rays / t / 1e6))
    print(f"\nphoton pass: {st.photons:,} emitted, {len(shot):,} stored in {t:.3f} s = "
          f"{st.photons / t / 1e6:.3f} M emitted/s, {len(shot) / t / 1e6:.3f} M stored/s")
    ctx.accel.close()
    table("photons per bounce (time split in proportion to rays)", rows)


def synthetic_photons(n, seed=0):
    """n photons on the six walls of a 4 m box, with plausible directions and normals."""
    rng = np.random.default_rng(seed)
    face = rng.integers(0, 6, n)
    ax = face % 3
    sgn = np.where(face < 3, -1.0, 1.0)
    pos = np.zeros((n, 3), np.float32)
    nrm = np.zeros((n, 3), np.float32)
    uv = rng.random((n, 2)) * 4 - 2
    for k in range(3):
        m = ax == k
        pos[m, k] = 2 * sgn[m]
        pos[m, (k + 1) % 3] = uv[m, 0]
        pos[m, (k + 2) % 3] = uv[m, 1]
        nrm[m, k] = -sgn[m]
    d = -nrm + rng.normal(0, 0.4, (n, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    power = np.full((n, 3), 1e-4, np.float32)
    return Photons(pos, power, d.astype(np.float32), nrm, np.zeros(n, np.uint8))


def sec_kdtree(a):
    rows = []
    sizes = [100_000, 1_000_000] if a.quick else [100_000, 1_000_000, 5_000_000]
    q = 20_000 if a.quick else 100_000
    for n in sizes:
        ph = synthetic_photons(n)
        t_build, pm = best_of(a.repeat, lambda: PhotonMap(ph, a.threads))
        # k-NN radius from the density (as auto_radius does): 96 m^2 of walls.
        r = 2.0 * np.sqrt(64 * 96.0 / (np.pi * n))
        rng = np.random.default_rng(1)
        sel = np.sort(rng.integers(0, n, q))
        p = ph.position[sel].astype(np.float64)
        nn = ph.normal[sel].astype(np.float64)
        o = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))  # coherent order, as camera queries
        p, nn = p[o], nn[o]
        row = dict(photons=n, build_s=t_build)
        for est, rad in (("knn_simpson", r), ("radius", r / 2)):
            t, _ = best_of(a.repeat, lambda: pm.irradiance(p, nn, rad, 64, 8, est))
            row[f"{est}_s_per_Mq"] = t / q * 1e6
        t, _ = best_of(a.repeat, lambda: pm.tree.query(p, 64, r))
        row["raw_query_k64_s_per_Mq"] = t / q * 1e6
        row["tree_MB"] = _tree_bytes(pm) / 1e6
        rows.append(row)
        del pm, ph
    table(f"photon map: build and gather (k=64, {q:,} queries, {a.threads} worker(s))", rows)


def _tree_bytes(pm):
    """Bytes the search structure adds to the photons (the compiled kd-tree: axes)."""
    return pm.nbytes - pm.photons.nbytes


def sec_scaling(a):
    base = dict(spp=a.spp, photons=a.photons, caustic_photons=a.photons // 2, workers=a.workers)

    def run(scene, **kw):
        s = RenderSettings(**{**base, **kw})
        t, f = best_of(1 if a.quick else a.repeat, lambda: render(scene, s))
        st = f.stats
        return dict(total_s=t, photons_s=st.get("time_photons", 0.0),
                    maps_s=st.get("time_photon_map", 0.0), camera_s=st.get("time_camera", 0.0))
    pix = [(40, 30), (80, 60), (160, 120)] if a.quick else [(80, 60), (160, 120), (320, 240)]
    table("scaling: pixels", [dict(pixels=f"{w}x{h}", **run(box(w, h))) for w, h in pix])
    ph = [25_000, 100_000, 400_000] if a.quick else [50_000, 200_000, 800_000, 3_200_000]
    table("scaling: photons", [dict(photons=n, **run(box(a.width, a.height), photons=n,
                                                    caustic_photons=n // 2)) for n in ph])
    tris = [1_000, 10_000, 100_000] if a.quick else [1_000, 10_000, 100_000, 1_000_000]
    rows = []
    for n in tris:
        t0 = time.perf_counter()
        scene = box(a.width, a.height, sphere_tris=n)
        geo, _ = prepare(scene)
        rows.append(dict(triangles=geo.count, prepare_s=time.perf_counter() - t0, **run(scene)))
    table("scaling: triangles (subdivided sphere in the box)", rows)
    table("scaling: lights", [dict(lights=n, **run(box(a.width, a.height, lights=n)))
                              for n in ([1, 4, 16] if a.quick else [1, 4, 16, 64])])


CHILD = r"""
import sys, json, numpy as np
sys.path.insert(0, {root!r})
from engine import RenderSettings
from engine.api import cornell_box
from engine.render import render
def hwm():  # VmHWM is per address space (ru_maxrss survives exec and reports the parent's)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
base = hwm()
s = RenderSettings(photons={photons}, caustic_photons={cphotons}, spp={spp}, workers={workers})
f = render(cornell_box({w}, {h}), s)
peak = hwm()
st = f.stats
print(json.dumps(dict(base_kb=base, peak_kb=peak, photon_bytes=st.get("photon_bytes", 0),
      stored=st.get("global_photons", 0) + st.get("caustic_photons", 0))))
"""


def sec_memory(a):
    rows = []
    for n in ([100_000, 400_000] if a.quick else [200_000, 1_000_000, 3_000_000]):
        code = CHILD.format(root=os.path.dirname(HERE), photons=n, cphotons=n // 2, spp=4,
                            workers=a.workers, w=80, h=60)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
        d = json.loads(out.stdout.strip().splitlines()[-1])
        stored = max(d["stored"], 1)
        rows.append(dict(photons_emitted=n, stored=d["stored"], peak_rss_MB=d["peak_kb"] / 1024,
                         over_import_MB=(d["peak_kb"] - d["base_kb"]) / 1024,
                         photon_arrays_B_per_photon=d["photon_bytes"] / stored))
    # Bytes per stored photon including the kd-tree and the gather pack.
    ph = synthetic_photons(1_000_000)
    pm = PhotonMap(ph, 1)
    rows_b = [dict(item="Photons arrays (pos, power, dir, normal f32 + kind u8)",
                   bytes_per_photon=ph.nbytes / len(ph)),
              dict(item="+ kd-tree (one split axis byte per photon, engine/kdtree.py)",
                   bytes_per_photon=(ph.nbytes + _tree_bytes(pm)) / len(ph))]
    table("memory: peak RSS (child process per case, 80x60, 4 spp)", rows)
    table("memory: bytes per stored photon", rows_b)


def sec_workers(a):
    rows = []
    cases = [("full render", dict()), ("direct only", dict(photon_mapping=False))]
    for name, kw in cases:
        res = {}
        for rep in range(a.repeat):
            for w in (1, 2):
                s = RenderSettings(spp=a.spp, photons=a.photons, workers=w, **kw)
                t0 = time.perf_counter()
                f = render(box(a.width, a.height), s)
                dt = time.perf_counter() - t0
                if w not in res or dt < res[w][0]:
                    res[w] = (dt, f.combined.copy())
        same = bool(np.array_equal(res[1][1], res[2][1]))
        rows.append(dict(case=f"{name} {a.width}x{a.height} {a.spp} spp", workers1_s=res[1][0],
                         workers2_s=res[2][0], speedup=res[1][0] / res[2][0], same_image=same))
    table("workers: 1 vs 2 threads (Embree + kd-tree)", rows)


# --------------------------------------------------------------------------- camera workers

def _thread_clock():
    """(wall s, run s, run-queue wait s, minor faults, voluntary switches, system s) of
    this thread: the kernel's schedstat (run time, time runnable but not running) and
    RUSAGE_THREAD (system time: page faults, futex calls)."""
    with open(f"/proc/self/task/{threading.get_native_id()}/schedstat") as f:
        run, rq = (int(x) * 1e-9 for x in f.read().split()[:2])
    ru = resource.getrusage(resource.RUSAGE_THREAD)
    return np.array([time.perf_counter(), run, rq, ru.ru_minflt, ru.ru_nvcsw, ru.ru_stime],
                    float)


def camera_timeline(scene, settings, runs=1):
    """Render scene with every camera chunk timed on its worker thread (_thread_clock at
    its start and end), the calling thread's merges timed, and the camera stage's span:
    {"chunks": [(thread, ci, start, end)], "merge": s, "caller": delta, "span": (t0, t1),
    "film": Film} of the last of `runs` renders."""
    import importlib
    integrator = importlib.import_module("engine.integrator")
    render_mod = importlib.import_module("engine.render")  # engine.render is also a function
    log = {}
    chunk0, merge0, camera0 = integrator._render_chunk, integrator.Accumulator.merge, \
        render_mod.render_camera

    def chunk(ctx, region, ci, *args, **kw):
        a = _thread_clock()
        out = chunk0(ctx, region, ci, *args, **kw)
        log["chunks"].append((threading.get_native_id(), ci, a, _thread_clock()))
        return out

    def merge(self, part):
        t0 = time.perf_counter()
        merge0(self, part)
        log["merge"] += time.perf_counter() - t0

    def camera(*args, **kw):
        a = _thread_clock()
        try:
            return camera0(*args, **kw)
        finally:
            b = _thread_clock()
            log["span"] = (a[0], b[0])
            log["caller"] = b - a

    integrator._render_chunk, integrator.Accumulator.merge = chunk, merge
    render_mod.render_camera = camera
    try:
        for _ in range(runs):
            log.update(chunks=[], merge=0.0)
            log["film"] = render(scene, settings)
    finally:
        integrator._render_chunk, integrator.Accumulator.merge = chunk0, merge0
        render_mod.render_camera = camera0
    return log


def timeline_rows(name, workers, log):
    """Per worker thread: chunks, busy wall, run / run-queue / blocked seconds inside its
    chunks, idle seconds inside the stage, minor faults; then the stage's totals."""
    t0, t1 = log["span"]
    wall = t1 - t0
    rows = []
    by = {}
    for tid, ci, a, b in log["chunks"]:
        by.setdefault(tid, []).append((a, b))
    ends = sorted(max(b[0] for _, b in ch) for ch in by.values())
    tot = np.zeros(6)
    for k, tid in enumerate(sorted(by, key=lambda t: min(a[0] for a, _ in by[t]))):
        d = sum(b - a for a, b in by[tid])
        busy = d[0]
        blocked = busy - d[1] - d[2]
        tot += d
        rows.append(dict(
            blend=name, workers=workers, thread=f"worker {k}", chunks=len(by[tid]),
            busy_s=busy, run_s=d[1], runqueue_s=d[2], blocked_s=blocked, idle_s=wall - busy,
            system_s=d[5], minor_faults=int(d[3]), vol_switches=int(d[4])))
    c = log["caller"]
    if workers > 1:  # (one worker: the chunks run inline on the calling thread)
        rows.append(dict(blend=name, workers=workers, thread="calling thread", chunks=0,
                         busy_s=log["merge"], run_s=c[1], runqueue_s=c[2], blocked_s=0.0,
                         idle_s=0.0, system_s=c[5], minor_faults=int(c[3]),
                         vol_switches=int(c[4])))
    # The slowest worker's run + blocked time: the stage's wall on a machine with no
    # other load (run-queue waits left out), tail imbalance included.
    critical = max(r["run_s"] + r["blocked_s"] for r in rows)
    summary = dict(blend=name, workers=workers, camera_wall_s=wall, critical_s=critical,
                   chunk_run_s=tot[1], chunk_blocked_s=tot[0] - tot[1] - tot[2],
                   chunk_runqueue_s=tot[2], tail_s=ends[-1] - ends[0],
                   merge_s=log["merge"], system_s=tot[5], minor_faults=int(tot[3]))
    return rows, summary


def _compiled_kernels():
    """Compile or load the kernels before any timing (engines before numba have none)."""
    try:
        from engine.jit import ensure_compiled
    except ImportError:
        return
    ensure_compiled()


def _export(name):
    """An example blend's engine scene, exported once through the add-on (bpy)."""
    import pickle
    from bench_kernels import exported
    import tempfile
    with open(exported(name, os.path.join(tempfile.gettempdir(), "bench_kernels")), "rb") as f:
        return pickle.load(f)


def sec_camera_workers(a):
    """Where two workers lose against one in the camera stage of a default render
    (Figures 6 and 7, --width x --height, default spp): per worker thread the chunks'
    run time (schedstat), time runnable but waiting for a core (other processes' load),
    blocked time (wall - run - run queue inside a chunk: GIL and kernel-lock waits),
    idle time in the stage (between its chunks and in the tail), minor page faults; the
    calling thread's merge time. 1 and 2 workers alternate, --repeat times; the run with
    the least run-queue wait is kept."""
    _compiled_kernels()
    rows, sums = [], []
    for name in a.blends:
        scene = _export(name)
        scene.width, scene.height = a.width, a.height
        best = {}
        for _ in range(a.repeat):
            for w in (1, 2):
                log = timeline_rows(name, w, camera_timeline(scene, RenderSettings(workers=w)))
                if w not in best or (log[1]["chunk_runqueue_s"]
                                     < best[w][1]["chunk_runqueue_s"]):
                    best[w] = log
        for w in (1, 2):
            rows += best[w][0]
            sums.append(best[w][1])
        one, two = best[1][1], best[2][1]
        sums.append(dict(blend=name, workers="1 / 2",
                         camera_wall_s=one["camera_wall_s"] / two["camera_wall_s"],
                         critical_s=one["critical_s"] / two["critical_s"],
                         chunk_run_s=one["chunk_run_s"] / two["chunk_run_s"],
                         chunk_blocked_s=two["chunk_blocked_s"] - one["chunk_blocked_s"],
                         chunk_runqueue_s=two["chunk_runqueue_s"] - one["chunk_runqueue_s"],
                         tail_s=two["tail_s"], merge_s=two["merge_s"],
                         system_s=two["system_s"] - one["system_s"],
                         minor_faults=two["minor_faults"] - one["minor_faults"]))
    table(f"camera stage per worker thread ({a.width}x{a.height}, default settings; "
          f"seconds inside the stage)", rows)
    table("camera stage: totals over the chunks (critical = slowest worker's run + blocked s; "
          "rows 1 / 2: ratios for wall, critical and run, 2w - 1w for the rest)", sums)


# --------------------------------------------------------------------------- critical path

def _schedstat():
    """(run s, run-queue s) of this thread (Linux; zeros elsewhere)."""
    try:
        with open(f"/proc/self/task/{threading.get_native_id()}/schedstat") as f:
            run, rq = (int(x) * 1e-9 for x in f.read().split()[:2])
        return run, rq
    except OSError:
        return 0.0, 0.0


def _leaf_waits(task):
    """(cpu s, wall s) summed over the tasks that start no threaded group (the chunks
    and blocks that do the work): wall - cpu there is time waiting for a core (other
    processes), for the GIL or for a kernel's lock."""
    from engine.parallel import Task  # noqa: F401
    cpu = wall = 0.0
    for g in task.groups:
        for t in g.tasks:
            if any(not h.inline for h in t.groups):
                c, w = _leaf_waits(t)
                cpu, wall = cpu + c, wall + w
            elif not g.inline:
                cpu, wall = cpu + t.cpu, wall + t.wall
    return cpu, wall


def traced_render(scene, settings):
    """Render with every stage traced (engine.parallel.Trace): {stage: dict(wall, cpu =
    process CPU, work, span, caller = the calling thread's own CPU, leaf cpu / wall,
    run-queue s of the calling thread)}, the film and the render's wall and CPU. Stages:
    photons (each trace_photons call), maps (the map build under run_cancellable and the
    gather count's indirect share), camera (render_camera; the photon-hit view on its side
    thread counted in its work, not its span: it fills the idle tail), other (the rest:
    preparation, effect analysis, film)."""
    import importlib
    from engine import parallel
    render_mod = importlib.import_module("engine.render")
    stages = {}
    names = ("trace_photons", "run_cancellable", "indirect_share", "render_camera",
             "_photon_hit_view")
    originals = {n: getattr(render_mod, n) for n in names}
    stage_of = dict(trace_photons="photons", run_cancellable="maps", indirect_share="maps",
                    render_camera="camera")
    side = {"cpu": 0.0}

    def traced(name):
        fn = originals[name]

        def run(*args, **kw):
            if name == "_photon_hit_view":
                c0 = time.thread_time()
                try:
                    return fn(*args, **kw)
                finally:
                    side["cpu"] += time.thread_time() - c0
            if parallel._trace is not None:
                # Inside a traced stage already (indirect_share in the map build's gather
                # chain): its CPU is that stage's; a trace of its own counted it twice.
                return fn(*args, **kw)
            trace = parallel.Trace()
            w0, p0, c0, q0 = (time.perf_counter(), time.process_time(), time.thread_time(),
                              _schedstat()[1])
            r0 = resource.getrusage(resource.RUSAGE_SELF)
            with parallel.tracing(trace):
                try:
                    return fn(*args, **kw)
                finally:
                    trace.root.cpu = time.thread_time() - c0
                    leaf_cpu, leaf_wall = _leaf_waits(trace.root)
                    r1 = resource.getrusage(resource.RUSAGE_SELF)
                    d = stages.setdefault(stage_of[name], dict(
                        wall=0.0, cpu=0.0, work=0.0, span=0.0, caller=0.0, leaf_cpu=0.0,
                        leaf_wall=0.0, caller_rq=0.0, system=0.0, faults=0))
                    d.setdefault("traces", []).append(trace.root)
                    for k, v in (("wall", time.perf_counter() - w0),
                                 ("cpu", time.process_time() - p0),
                                 ("work", trace.root.work()),
                                 ("span", trace.root.time_on(settings.threads)),
                                 ("caller", trace.root.own()), ("leaf_cpu", leaf_cpu),
                                 ("leaf_wall", leaf_wall),
                                 ("caller_rq", _schedstat()[1] - q0),
                                 ("system", r1.ru_stime - r0.ru_stime),
                                 ("faults", r1.ru_minflt - r0.ru_minflt)):
                        d[k] += v
        return run

    for n in names:
        setattr(render_mod, n, traced(n))
    try:
        w0, p0 = time.perf_counter(), time.process_time()
        film = render(scene, settings)
        wall, cpu = time.perf_counter() - w0, time.process_time() - p0
    finally:
        for n, fn in originals.items():
            setattr(render_mod, n, fn)
    if "camera" in stages:
        stages["camera"]["work"] += side["cpu"] if settings.threads > 1 else 0.0
        stages["camera"]["side"] = side["cpu"]
    rest_wall = wall - sum(d["wall"] for d in stages.values())
    rest_cpu = cpu - sum(d["cpu"] for d in stages.values())
    stages["other"] = dict(wall=rest_wall, cpu=rest_cpu, work=rest_cpu, span=rest_cpu,
                           caller=rest_cpu, leaf_cpu=0.0, leaf_wall=0.0, caller_rq=0.0,
                           system=float("nan"), faults=-1, traces=[])
    return stages, film, wall, cpu


# Issue 14's Principled spheres (tools/accuracy_scenes.py, "principled_spheres") as the
# add-on exports them for a render, pickled (the engine's scene, no bpy) when missing.
_PRINCIPLED = """
import pickle, sys
sys.path.insert(0, ROOT)
from tools import accuracy_scenes
scene, _ = accuracy_scenes.export_ours("principled_spheres")
with open(OUT, "wb") as f:
    pickle.dump(scene, f)
print("{}")
"""


def _scene(name):
    """/tmp/pk/<name>.pkl (engine scenes pickled without bpy) if present, else the example
    blend exported through the add-on; principled_spheres_df2 (the Principled spheres,
    rendered at default settings here) is exported once into /tmp/pk when missing."""
    import pickle
    pk = os.path.join("/tmp/pk", name + ".pkl")
    if not os.path.exists(pk) and name == "principled_spheres_df2":
        from bench_kernels import child
        os.makedirs(os.path.dirname(pk), exist_ok=True)
        child(_PRINCIPLED, ROOT=os.path.dirname(HERE), OUT=pk)
    if os.path.exists(pk):
        with open(pk, "rb") as f:
            return pickle.load(f)
    return _export(name)


def _group_rows(scene, stage, roots, threads):
    """Where a stage's critical path goes (--groups): per traced call, the calling
    thread's own CPU (serial), then its pools (ordered_map / run_tasks / run_cancellable
    groups), nested pools indented below the pool whose jobs started them and summed
    over those jobs by name: jobs, work (CPU s of the jobs and all they started), span
    (their share of the critical path: the jobs dispatched in order to the pool's
    threads, Task.span; summed over the pools of one name) and lost = span - work /
    threads (idle thread time: uneven or too few jobs, a last job's tail, inline pools
    0), own = the jobs' own CPU (their pools' jobs taken out)."""
    rows = []

    def span_of(g):
        free = [0.0] * g.threads
        for t in g.tasks:
            i = free.index(min(free))
            free[i] += t.span()
        return max(free) if free else 0.0

    def walk(groups, depth, call):
        by = {}
        for g in groups:
            key = ((g.name or "?").replace("<locals>.", ""), g.threads, g.inline)
            by.setdefault(key, []).append(g)
        for (name, th, inl), gs in by.items():
            tasks = [t for g in gs for t in g.tasks]
            work = sum(t.work() for t in tasks)
            span = sum(span_of(g) for g in gs)
            rows.append(dict(scene=scene, stage=stage, call=call,
                             group="  " * depth + name + (" (inline)" if inl else ""),
                             threads=th, pools=len(gs), jobs=len(tasks), work_s=work,
                             own_s=sum(t.own() for t in tasks), span_s=span,
                             lost_s=0.0 if inl else max(
                                 0.0, span - work / max(1, min(th, threads)))))
            walk([h for t in tasks for h in t.groups], depth + 1, call)

    for call, root in enumerate(roots):
        rows.append(dict(scene=scene, stage=stage, call=call, group="(calling thread)",
                         threads=1, pools=0, jobs=1, work_s=root.work(), own_s=root.own(),
                         span_s=root.span(), lost_s=0.0))
        walk(root.groups, 1, call)
    return rows


def _film_sha(film):
    import hashlib
    h = hashlib.sha1()
    for k in ("direct", "indirect", "caustic", "specular", "emission"):
        h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
    return h.hexdigest()[:16]


def sec_critical_path(a):
    """Per stage of a default render (photons, maps, camera, other), 1 and 2 workers:
    wall, process CPU, the traced work (CPU of every job and of the calling thread's own
    code), the critical path (span: the calling thread's own CPU, then each pool's jobs
    dispatched in order to its threads; at least work / workers, as nested pools share
    the cores: Task.time_on), the calling thread's serial CPU, the leaf jobs'
    waits (wall - CPU inside the chunks: other processes' load, GIL and lock waits).
    predicted = 1-worker work / 2-worker span (what two idle cores would give, no GIL
    contention), measured = 1-worker wall / 2-worker wall (meaningful only at load < 1.5).
    --blends names /tmp/pk pickles or example blends; --sizes WxH list; default settings."""
    _compiled_kernels()
    rows, sums = [], []
    for name in a.blends:
        scene = _scene(name)
        # A small render first: the process's first render loads kernels and warms
        # caches, which would count against whichever worker count ran first.
        scene.width, scene.height = 32, 24
        render(scene, RenderSettings(workers=2, spp=4))
        for size in a.sizes:
            w_, h_ = (int(x) for x in size.split("x"))
            scene.width, scene.height = w_, h_
            best = {}
            for rep in range(a.repeat):
                for w in ((1, 2) if rep % 2 == 0 else (2, 1)):
                    load = os.getloadavg()[0]
                    out = traced_render(scene, RenderSettings(workers=w))
                    key = 3 if a.best == "cpu" else 2  # the render's process CPU / wall
                    if w not in best or out[key] < best[w][0][key]:
                        best[w] = (out, load)
                    cam = out[0].get("camera", {})
                    print(f"# run {name} {size} {w} worker(s), repeat {rep + 1}: wall "
                          f"{out[2]:.2f} s, CPU {out[3]:.2f} s; camera work "
                          f"{cam.get('work', 0):.2f} s, system {cam.get('system', 0):.2f} s, "
                          f"{int(cam.get('faults', 0)):,} minor faults; load {load:.1f}",
                          flush=True)
            shas = {w: _film_sha(best[w][0][1]) for w in (1, 2)}
            for w in (1, 2):
                (stages, film, wall, cpu), load = best[w]
                for st, d in stages.items():
                    rows.append(dict(
                        scene=f"{name} {size}", workers=w, stage=st, wall_s=d["wall"],
                        cpu_s=d["cpu"], work_s=d["work"], span_s=d["span"],
                        serial_s=d["caller"], leaf_wait_s=d["leaf_wall"] - d["leaf_cpu"],
                        system_s=d["system"], minor_faults=int(d["faults"]),
                        bound=d["work"] / d["span"] if d["span"] > 0 else 1.0))
            if a.groups:
                for w in (1, 2):
                    grows = []
                    for st, d in best[w][0][0].items():
                        grows += _group_rows(f"{name} {size}", st, d.get("traces", []), w)
                    table(f"{name} {size}, {w} worker(s): the critical path by pool "
                          "(CPU s; lost = span - work / threads)", grows)
            one, two = best[1][0][0], best[2][0][0]
            work1 = sum(d["work"] for d in one.values())
            span2 = sum(d["span"] for d in two.values())
            for st in ("photons", "maps", "camera", "other", "all"):
                if st == "all":
                    w1, s2 = work1, span2
                    wall1, wall2 = best[1][0][2], best[2][0][2]
                elif st in one and st in two:
                    w1, s2 = one[st]["work"], two[st]["span"]
                    wall1, wall2 = one[st]["wall"], two[st]["wall"]
                else:
                    continue
                sums.append(dict(
                    scene=f"{name} {size}", stage=st, work_1w_s=w1,
                    work_2w_s=(sum(d["work"] for d in two.values()) if st == "all"
                               else two[st]["work"]),
                    span_2w_s=s2, predicted=w1 / s2 if s2 > 0 else 1.0,
                    wall_1w_s=wall1, wall_2w_s=wall2, measured=wall1 / wall2,
                    load=f"{best[1][1]:.1f} / {best[2][1]:.1f}",
                    image="1 = 2 workers" if shas[1] == shas[2] else "DIFFERS"))
            print(f"# {name} {size}: film SHA-1 1 worker {shas[1]}, 2 workers {shas[2]}; "
                  + "; ".join(f"{r['stage']} {r['predicted']:.2f}x predicted, "
                              f"{r['measured']:.2f}x measured"
                              for r in sums if r["scene"] == f"{name} {size}"), flush=True)
    table("critical path per stage (CPU s; span = critical path on idle cores; serial = "
          "calling thread's own CPU; leaf wait = wall - CPU inside the chunks; system s and "
          "minor faults of the process during the stage)", rows)
    table("2 workers / 1 worker: predicted = 1w work / 2w span, measured = wall ratio "
          "(loaded machine: not a measurement above load ~1.5)", sums)
    _critical_plot(a, sums)


def _critical_plot(a, sums):
    if not a.plot:
        return
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("(matplotlib not installed: no plot)")
        return
    labels = [f"{r['scene']}\n{r['stage']}" for r in sums]
    x = np.arange(len(sums))
    fig, ax = plt.subplots(figsize=(max(6, 0.6 * len(sums)), 4))
    ax.bar(x - 0.2, [r["predicted"] for r in sums], 0.4, label="predicted (1w work / 2w span)")
    ax.bar(x + 0.2, [r["measured"] for r in sums], 0.4, label="measured (wall)")
    ax.axhline(1.8, color="k", lw=0.8, ls="--")
    ax.set_xticks(x, labels, rotation=90, fontsize=6)
    ax.set_ylabel("2 workers / 1 worker")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.plot, dpi=120)
    print(f"(plot: {a.plot})")


def fault_profile(scene, settings):
    """{place: minor page faults} of one render: each thread's faults
    (getrusage(RUSAGE_THREAD), read at every profiler event of sys.setprofile /
    threading.setprofile) charged to the Python function it ran, or to the C function
    it called ("C name <- caller": numpy's allocations and copies); a compiled kernel's
    faults fall to its dispatcher's name (the first touches of the arrays it writes).
    Slow (a profiler event per call): for where, not how much time."""
    faults = {}
    tls = threading.local()
    usage, who = resource.getrusage, resource.RUSAGE_THREAD

    def profile(frame, event, arg):
        now = usage(who).ru_minflt
        last = getattr(tls, "last", None)
        if last is not None and now != last:
            faults[tls.key] = faults.get(tls.key, 0) + now - last
        if event == "c_call":
            tls.key = f"C {getattr(arg, '__qualname__', arg)} <- {frame.f_code.co_name}"
        else:
            tls.key = (f"{os.path.basename(frame.f_code.co_filename)}:"
                       f"{frame.f_code.co_name}")
        tls.last = usage(who).ru_minflt

    threading.setprofile(profile)
    sys.setprofile(profile)
    try:
        render(scene, settings)
    finally:
        sys.setprofile(None)
        threading.setprofile(None)
    return faults


def sec_faults(a):
    """Where a default render's minor page faults happen, 1 worker against 2 (each
    thread's faults per Python function / numpy call: fault_profile), the places with the
    most faults on either: which allocations a second worker's malloc arena makes fault
    again (issue 13). --blends, --sizes as critical_path (the first size)."""
    for name in a.blends:
        scene = _scene(name)
        scene.width, scene.height = 32, 24
        render(scene, RenderSettings(workers=2, spp=4))  # kernels loaded, caches warm
        w_, h_ = (int(x) for x in a.sizes[0].split("x"))
        scene.width, scene.height = w_, h_
        counts = {w: fault_profile(scene, RenderSettings(workers=w)) for w in (1, 2)}
        places = sorted(set(counts[1]) | set(counts[2]),
                        key=lambda k: -max(counts[1].get(k, 0), counts[2].get(k, 0)))
        rows = [dict(place=k, faults_1w=counts[1].get(k, 0), faults_2w=counts[2].get(k, 0))
                for k in places[:25]]
        rows.append(dict(place="all", faults_1w=sum(counts[1].values()),
                         faults_2w=sum(counts[2].values())))
        table(f"minor faults by place, {name} {w_}x{h_} (load {os.getloadavg()[0]:.1f})",
              rows)


SECTIONS = dict(rays=sec_rays, photons=sec_photons, kdtree=sec_kdtree, scaling=sec_scaling,
                memory=sec_memory, workers=sec_workers,
                camera_workers=sec_camera_workers, critical_path=sec_critical_path,
                faults=sec_faults)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, best of 1-2 (< 2 min)")
    ap.add_argument("--only", nargs="*", choices=list(SECTIONS), help="run only these sections")
    ap.add_argument("--width", type=int, default=None)
    ap.add_argument("--height", type=int, default=None)
    ap.add_argument("--spp", type=int, default=None)
    ap.add_argument("--photons", type=int, default=None)
    ap.add_argument("--workers", type=int, default=0, help="0 = all cores")
    ap.add_argument("--repeat", type=int, default=None, help="best of N (default 3, quick 1)")
    ap.add_argument("--blends", default="figure6_box,figure7_blocker",
                    help="camera_workers: example blends (exported through the add-on)")
    ap.add_argument("--sizes", default="160x120,320x240",
                    help="critical_path: image sizes WxH")
    ap.add_argument("--groups", action="store_true",
                    help="critical_path: also print each stage's pools (work, span, lost)")
    ap.add_argument("--plot", help="critical_path: write a PNG of the speed-ups (matplotlib)")
    ap.add_argument("--best", choices=("wall", "cpu"), default="wall",
                    help="critical_path with --repeat > 1: keep each worker count's run with "
                         "the least wall time (default) or process CPU time (a loaded machine)")
    ap.add_argument("--malloc-single", action="store_true",
                    help="re-run this process under glibc's single malloc arena without "
                         "trimming (MALLOC_ARENA_MAX=1, MALLOC_TRIM_THRESHOLD_=512 MB, "
                         "MALLOC_MMAP_THRESHOLD_=32 MB): the allocator A/B of "
                         "docs/performance.md's sixteenth slice")
    ap.add_argument("--json", help="write all tables as JSON")
    a = ap.parse_args(argv)
    if a.malloc_single and os.environ.get("MALLOC_ARENA_MAX") != "1" and argv is None:
        # glibc reads these once, at the process's start: run again under them.
        os.environ.update(MALLOC_ARENA_MAX="1", MALLOC_TRIM_THRESHOLD_=str(512 << 20),
                          MALLOC_MMAP_THRESHOLD_=str(32 << 20))
        os.execv(sys.executable, [sys.executable] + sys.argv)
    q = a.quick
    a.width = a.width or (80 if q else 160)
    a.height = a.height or (60 if q else 120)
    a.spp = a.spp or (8 if q else 64)
    a.photons = a.photons or (50_000 if q else 200_000)
    a.repeat = a.repeat or (1 if q else 3)
    a.blends = a.blends.split(",")
    a.sizes = a.sizes.split(",")
    a.threads = a.workers if a.workers > 0 else (os.cpu_count() or 1)
    print(f"# bench_scaling ({'quick' if q else 'full'}), {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}, numpy {np.__version__}, malloc env "
          + (" ".join(f"{k}={os.environ[k]}" for k in ("MALLOC_ARENA_MAX",
                                                         "MALLOC_TRIM_THRESHOLD_",
                                                         "MALLOC_MMAP_THRESHOLD_")
                      if k in os.environ) or "default"))
    t0 = time.perf_counter()
    for name in (a.only or list(SECTIONS)):
        SECTIONS[name](a)
    print(f"\n(total {time.perf_counter() - t0:.1f} s, peak RSS "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(TABLES, f, indent=1, default=str)
    return TABLES


if __name__ == "__main__":
    main()
