"""The secondary-caustic k-NN estimates of a render (issue 13, s20 secondary): their share
of a 1-worker default render, and per row class (seeded, listed, widened and how far)
their rows, photons listed and CPU us a row, in a base kernel and in this checkout's.

    PYTHONPATH=$PWD python bench/bench_secondary.py capture BLEND W H OUT.calls
    git show 1a4541d:engine/photonmap.py > /tmp/base_photonmap.py
    PYTHONPATH=$PWD python bench/bench_secondary.py classes /tmp/base_photonmap.py OUT.calls...

`capture` renders an example blend (exported through the add-on into WORK, default
/tmp/secondary/work) at its default settings, 1 worker, records the secondary map's
irradiance calls (at the camera hits: _smooth_estimate's SECONDARY_SAMPLES_PER_PIXEL
call; at the regathers: _secondary_irradiance) and prints their process CPU against the
render's. `classes` classifies each captured row with an instrumented copy of the base
file's _irradiance_rows (its anchors are 1a4541d's kernel), then replays each class's rows
alone through the base kernel and this checkout's (compiled from source, one thread, best
of 3 process CPU), and prints a Markdown table. Classes: seeded (the previous row's
sphere sufficed), listed (the whole sphere listed, <= LIST_FACTOR k photons, no widening),
heap (fuller sphere: kdtree.knn), widened with no accepted photon (settled empty), widened
to kq = 256 with >= k / 2 accepted among them, widened over a whole sphere of fewer photons
than the next width (the estimate reads all of it).
"""
from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))
WORK = os.environ.get("SECONDARY_WORK", "/tmp/secondary/work")


def _which():
    """(capture_irradiance_calls' caller) regather / camera for the secondary map's
    estimates, None for the other maps' (not recorded)."""
    f = sys._getframe(2)  # past _which and the recorder
    while f is not None:
        c = f.f_code.co_name
        if c == "_secondary_irradiance":
            return "regather"
        if c == "_smooth_estimate":  # the secondary map's call: 4 samples a pixel
            return "camera" if f.f_locals.get("per_pixel") == 4 else None
        if c in ("gather_indirect", "_photon_terms", "__init__"):
            return None
        f = f.f_back
    return None


def capture(name, w, h, out):
    from bench_core import capture_irradiance_calls
    capture_irradiance_calls(name, w, h, out, WORK, _which)


NAMES = {0: "seeded", 1: "listed", 2: "heap", 3: "widened: no accepted photon",
         5: "widened to 256, >= k / 2 accepted", 6: "widened to 1024", 7: "widened to 4096",
         9: "widened over a whole sphere < next width"}


def classes(base_file, captures):
    import numpy as np
    from bench_core import (best_rows_time, captured_maps, counted_irradiance_rows,
                            irradiance_rows_source)
    from engine import photonmap
    from engine.jit import ensure_compiled
    ensure_compiled()
    counted, base = counted_irradiance_rows(irradiance_rows_source(base_file), "cls, nph", [
        ("            if seeded:\n                cnt = kq\n", "", "                cls[i] = 0\n"),
        ("                if 0 <= listed <= list_cap:\n", "",
         "                    cls[i] = 1\n                    nph[i] = listed\n"),
        ("                    listed = -1\n                    cnt = _knn(",
         "                    cls[i] = 2\n                    nph[i] = listed\n", ""),
        ("                prev_kth = -1.0\n                if listed >= 0:",
         "                cls[i] = 3\n", ""),
        ("                    nb = _ball(kind, pos, nodes, start, grid, qx, qy, qz, r2, scan,\n"
         "                               SCAN_BUDGET, buckets)\n", "",
         "                    nph[i] = nb\n"),
        ("                    if cnt < kq or kq >= widest:\n                        break\n",
         "                    cls[i] = 9 if cnt < kq else 5 + (kq >= 1024) + (kq >= 4096)\n", "")])
    kernels = {"base": base, "this": photonmap._irradiance_rows}
    print("| capture | at | class | rows | share % | photons listed a row | base / this CPU ms "
          "| base / this us a row |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for path in captures:
        for caller, radius, calls, pm in captured_maps(path):
            C, NP = [], []
            for p, n, k, mp, est, rb, rf, mk in calls:
                cls, nph = np.full(len(p), -1, np.int64), np.zeros(len(p), np.int64)
                photonmap._irradiance_rows = lambda *a: counted(cls, nph, *a)
                pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb, r_floor=rf,
                              masks=mk)
                C.append(cls)
                NP.append(nph)

            def run(fn, pick):
                return best_rows_time(pm, calls, C, radius, fn, pick)
            allc, alln = np.concatenate(C), np.concatenate(NP)
            tag = f"{os.path.basename(path)} | {caller} ({len(pm.photons):,}, {radius:.3f} m)"
            for cl in [None] + sorted(set(allc.tolist())):
                pick = ((lambda c: np.arange(len(c))) if cl is None
                        else (lambda c, cl=cl: np.flatnonzero(c == cl)))
                sel = np.ones(len(allc), bool) if cl is None else allc == cl
                tb, tt = (run(kernels[v], pick) for v in ("base", "this"))
                rows = int(sel.sum())
                listed = f"{alln[sel].mean():.0f}" if cl else "-"  # (seeded: not counted)
                print(f"| {tag} | {'all' if cl is None else NAMES[cl]} | {rows:,} | "
                      f"{sel.mean() * 100:.1f} | {listed} | "
                      f"{tb * 1e3:.0f} / {tt * 1e3:.0f} | {tb / rows * 1e6:.2f} / "
                      f"{tt / rows * 1e6:.2f} |", flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "capture":
        capture(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5])
    else:
        classes(sys.argv[2], sys.argv[3:])
