"""Progressive passes on Dask (engine/distributed.py): passes per second with 1 and 2 local
worker processes, scheduler overhead per pass, bytes shipped per pass.

    .venv/bin/python bench/bench_distributed.py              # Figure 6 box, 96x72, 2-5 min
    .venv/bin/python bench/bench_distributed.py --quick      # smaller, about 1 min

Each case renders the same passes (same seed); the script checks that every image is
bitwise the single-machine one. Controls measured in the same run: one process with 1 and
2 engine threads, and 1 and 2 plain engine processes side by side without Dask (what the
machine gives two processes at that moment: on a shared machine that, not Dask, bounds
the 2-worker speed-up). Workers are LocalCluster processes with one task thread
and one engine thread each, so 1 vs 2 workers measures what Dask adds on top of one core
per pass. Overhead per pass = client wall time per pass minus the workers' own pass time
(per worker), on a tiny scene where a pass is a few milliseconds. Bytes: what Dask
serialises for one task (arguments; the scene is scattered once and counted apart) and for
one result (the pass film).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from engine import RenderSettings  # noqa: E402
from engine.api import cornell_box  # noqa: E402
from engine.distributed import render_distributed, run_pass  # noqa: E402
from engine.progressive import Budget, render_progressive  # noqa: E402


def same_bits(a, b) -> bool:
    names = ("direct", "indirect", "caustic", "specular", "emission", "alpha", "normal", "depth")
    return all(getattr(a, n).tobytes() == getattr(b, n).tobytes() for n in names)


def serialized_bytes(obj) -> int:
    from distributed.protocol import serialize_bytes
    return len(serialize_bytes(obj))


def run(scene, settings, passes, workers, label, reference):
    import distributed
    with distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        # Warm-up: worker processes import the engine (and numba kernels) once.
        render_distributed(cornell_box(8, 6), RenderSettings(spp=1, photons=500,
                           caustic_photons=100), Budget(passes=workers), client=client,
                           worker_threads=1)
        t0 = time.perf_counter()
        film = render_distributed(scene, settings, Budget(passes=passes), client=client,
                                  worker_threads=1)
        wall = time.perf_counter() - t0
    worker_seconds = sum(p["pass_seconds"] for p in film.stats["pass_log"])
    return dict(case=label, workers=workers, passes=passes, wall_s=wall,
                passes_per_s=passes / wall, worker_s_per_pass=worker_seconds / passes,
                overhead_ms_per_pass=1000 * (wall / passes - worker_seconds / passes / workers),
                same_image=same_bits(film, reference))


def plain_processes(n, passes, args):
    """Control without Dask: n independent engine processes (one engine thread each) render
    passes / n passes each at the same time; passes per second = passes / the slowest
    one's render time (start-up excluded). What this machine gives two processes now."""
    import json
    import subprocess
    cmd = [sys.executable, os.path.abspath(__file__), "--child", str(passes // n)]
    if args.quick:
        cmd.append("--quick")
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True) for _ in range(n)]
    times = [json.loads(p.communicate()[0].strip().splitlines()[-1])["seconds"] for p in procs]
    wall = max(times)
    return dict(case=f"{n} plain process(es), no Dask", workers=n, passes=passes // n * n,
                wall_s=wall, passes_per_s=passes // n * n / wall,
                worker_s_per_pass=sum(times) / (passes // n * n), overhead_ms_per_pass=0.0,
                same_image=True)


def print_table(title, rows):
    keys = list(rows[0])
    print(f"\n### {title}\n")
    print("| " + " | ".join(keys) + " |")
    print("|" + "|".join("---:" if isinstance(rows[0][k], (int, float)) else "---" for k in keys) + "|")
    for r in rows:
        print("| " + " | ".join(f"{v:,.3f}" if isinstance(v, float) else str(v)
                                for v in r.values()) + " |")
    sys.stdout.flush()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller scene and fewer passes")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)  # plain_processes' children
    args = ap.parse_args()
    w, h, spp, photons, passes = (48, 36, 1, 10_000, 6) if args.quick else (96, 72, 2, 40_000, 8)
    scene = cornell_box(w, h)
    settings = RenderSettings(spp=spp, photons=photons, caustic_photons=photons // 2, seed=7)
    if args.child:
        import json
        t0 = time.perf_counter()
        render_progressive(scene, RenderSettings(**{**settings.__dict__, "workers": 1}),
                           Budget(passes=args.child))
        print(json.dumps({"seconds": time.perf_counter() - t0}))
        return
    print(f"scene: Figure 6 box {w}x{h}, {spp} spp, {photons:,} + {photons // 2:,} photons per "
          f"pass, {passes} passes; {os.cpu_count()} cores")
    # Other jobs on the machine change every number: the load before and after says how much.
    print("load average (1, 5, 15 min) at start: %.2f %.2f %.2f" % os.getloadavg())

    rows = []
    for threads in (1, 2):
        t0 = time.perf_counter()
        reference = render_progressive(scene, RenderSettings(**{**settings.__dict__,
                                                                "workers": threads}),
                                       Budget(passes=passes))
        wall = time.perf_counter() - t0
        rows.append(dict(case=f"one process, {threads} engine thread(s)", workers=0,
                         passes=passes, wall_s=wall, passes_per_s=passes / wall,
                         worker_s_per_pass=wall / passes, overhead_ms_per_pass=0.0,
                         same_image=True))
    for workers in (1, 2):
        rows.append(run(scene, settings, passes, workers, f"Dask, {workers} worker(s)", reference))
    for n in (1, 2):
        rows.append(plain_processes(n, passes, args))
    print_table("Passes per second", rows)
    rate = {r["case"]: r["passes_per_s"] for r in rows}
    print(f"\n2 workers / 1 worker: "
          f"{rate['Dask, 2 worker(s)'] / rate['Dask, 1 worker(s)']:.2f}x passes per second; "
          f"controls on this machine now: one process 2 / 1 engine threads "
          f"{rows[1]['passes_per_s'] / rows[0]['passes_per_s']:.2f}x, two / one plain "
          f"processes {rate['2 plain process(es), no Dask'] / rate['1 plain process(es), no Dask']:.2f}x")

    tiny = cornell_box(8, 6)
    tiny_settings = RenderSettings(spp=1, photons=300, caustic_photons=100, seed=7)
    tiny_ref = render_progressive(tiny, tiny_settings, Budget(passes=40))
    over = [run(tiny, tiny_settings, 40, n, f"8x6 px, 300 photons, {n} worker(s)", tiny_ref)
            for n in (1, 2)]
    print_table("Scheduler overhead (a pass of a few milliseconds)", over)

    one = run_pass(scene, settings, 1, (0, 0, w, h), "bench-bytes", 1)
    task_args = (settings, 1, (0, 0, w, h), "photonmap-0123456789abcdef0123456789abcdef", 1)
    print_table("Bytes shipped", [
        dict(item="scene (scattered once per render, to every worker)",
             bytes=serialized_bytes(scene)),
        dict(item="task arguments per pass (settings, pass, region, key)",
             bytes=serialized_bytes(task_args)),
        dict(item=f"result per pass (film {w}x{h}: 5 effects, alpha, depth, normal)",
             bytes=serialized_bytes(one)),
        dict(item="result per pass per pixel", bytes=round(serialized_bytes(one) / (w * h), 1)),
    ])
    print("\nload average (1, 5, 15 min) at end: %.2f %.2f %.2f" % os.getloadavg())


if __name__ == "__main__":
    main()
