"""Widening k-NN rows (issue 13, s19 knn): what each path costs and how many rows take it.

A k-NN row whose nearest photons mostly face another surface widens x4 up to MAX_WIDEN_K
(engine/photonmap.py). Its sphere, scanned once (at most SCAN_BUDGET photons), is ordered
without a heap (_widen_listed); a sphere fuller than the scan takes the kd-tree heap.

    PYTHONPATH=$PWD python bench/bench_widen.py --roots BEFORE_TREE $PWD [--repeat 2]

The synthetic case, one fresh process per tree, alternating: a wall's far side crowded
(600,000 photons facing away from the queries) and a sparse near side (20,000 or 60,000
facing them), 3,000 queries, k = 64, knn_simpson, one thread; spheres of r = 0.05 m (~4,700
photons) and 0.08 m (~12,000): more than MAX_WIDEN_K, so every row widens to the 4096
nearest. Prints CPU us per row (best of 3) and a hash of the estimates (the same bits
in both trees).

    PYTHONPATH=$PWD python bench/bench_widen.py --paths CAPTURE.calls [...]

Per map and caller of a captured render (bench/bench_lookup.py --render-calls writes
WORK/NAME-WxH.calls), how many k-NN rows widen and which path each takes: the sphere
listed already (at most 8 k photons), settled empty by the scan, the scan's sphere of at
most 4096 / 4097-65536 / more photons, and the rows left to the heap search (_knn).
It runs an instrumented copy of this tree's _irradiance_rows (compiled, not cached).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SYNTHETIC = r"""
import hashlib, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
from engine.photonmap import PhotonMap
from engine.photons import Photons
ensure_compiled()
rng = np.random.default_rng(5)
out = []
for n_near in (20_000, 60_000):
    nf = 600_000
    pos = np.r_[np.c_[rng.random((nf, 2)), np.full(nf, 0.001)],
                np.c_[rng.random((n_near, 2)), np.zeros(n_near)]].astype(np.float32)
    nrm = np.r_[np.tile(np.float32([0, 0, -1]), (nf, 1)),
                np.tile(np.float32([0, 0, 1]), (n_near, 1))]
    n = len(pos)
    ph = Photons(pos, np.full((n, 3), 1.0 / n, np.float32), -nrm, nrm, np.zeros(n, np.uint8))
    pm = PhotonMap(ph, 1)
    m = 3000
    q = np.c_[0.2 + 0.6 * rng.random((m, 2)), np.zeros(m)]
    up = np.tile([0.0, 0.0, 1.0], (m, 1))
    for r in (0.05, 0.08):
        pm.irradiance(q[:2], up[:2], r, 64, 8, "knn_simpson")
        best = 1e9
        for _ in range(3):
            t0 = time.process_time()
            e = pm.irradiance(q, up, r, 64, 8, "knn_simpson")
            best = min(best, time.process_time() - t0)
        h = hashlib.sha1(np.ascontiguousarray(e).tobytes()).hexdigest()[:10]
        out.append(f"near {n_near:,}, r {r} (~{int(np.pi * r * r * nf):,} far-side photons): "
                   f"{best / m * 1e6:.1f} us/row {h}")
print(" | ".join(out))
"""


def synthetic(roots, repeat):
    for _ in range(repeat):
        for root in roots:
            out = subprocess.run([sys.executable, "-c", f"ROOT = {root!r}\n" + SYNTHETIC],
                                 capture_output=True, text=True, check=True).stdout
            print(f"{root}: {out.strip().splitlines()[-1]}", flush=True)


def paths(captures):
    import numpy as np
    sys.path.insert(0, ROOT)
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    from bench_core import captured_maps, counted_irradiance_rows, irradiance_rows_source
    from engine import photonmap
    from engine.jit import ensure_compiled
    ensure_compiled()
    counted, _ = counted_irradiance_rows(irradiance_rows_source(), "stats", [
        ("            kq = min(k, P)\n", "            stats[0] += 1\n", ""),
        ("                if listed >= 0:\n                    # The sphere is listed already",
         "                stats[1] += 1\n", ""),
        ("                    # The sphere is listed already (list_d2 / list_idx, tree order;"
         " a row\n", "", "                    stats[2] += 1\n"),
        ("nx, ny, nz) < min_photons:\n                        continue\n", "",
         "                    stats[3 if nb <= widest else 4 if nb <= SCAN_BUDGET "
         "else 5] += 1\n"),
        ("                    if found < 0:\n", "", "                        stats[6] += 1\n")])
    stats = np.zeros(7, np.int64)
    photonmap._irradiance_rows = lambda *a: counted(stats, *a)
    print("| capture | caller | map photons | radius m | k-NN rows | widening | listed | "
          "settled empty | scan <= 4096 | 4097-65536 | > 65536 | heap search |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for path in captures:
        for caller, radius, calls, pm in captured_maps(path):
            stats[:] = 0
            for p, n, k, mp, est, rb, rf, *more in calls:
                pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb, r_floor=rf,
                              **({"masks": more[0]} if more and more[0] is not None else {}))
            s = stats
            empty = s[1] - s[2] - s[3] - s[4] - s[5]
            print(f"| {os.path.basename(path)} | {caller} | {len(pm.photons):,} | "
                  f"{radius:.3f} | {s[0]:,} | {s[1]:,} | {s[2]:,} | {empty:,} | {s[3]:,} | "
                  f"{s[4]:,} | {s[5]:,} | {s[6]:,} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--roots", nargs="+", default=[ROOT], help="trees to time, alternating")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--paths", nargs="+", default=None, help="captures to count paths in")
    a = ap.parse_args()
    if a.paths:
        paths(a.paths)
    else:
        synthetic(a.roots, a.repeat)


if __name__ == "__main__":
    main()
