"""What photon visibility (engine/photonvisibility.py) costs: Figures 6/7/8 (the film_hashes
exports) at 320x240 and default settings, one worker, one process, with
integrator.PHOTON_VISIBILITY off / on interleaved; CPU s by time.process_time (min over
--repeat), the on run's visibility time split by map (caustic / secondary / global):
photonvisibility.visible_irradiance's time ("total", which holds the estimate itself: one
search a row for the estimate and its rays since visreuse), the estimate with its read
lists (_estimate_read; the rows whose lists were cut are read again in it), finding the
hidden photons (the pre-test and the rays: the rest but the re-estimate) and the
re-estimate of the rows that have one (_reestimate), with the rows, the rows read again
wider, the rows that hide a photon and the hidden (row, photon) pairs. "visibility s" is
total - estimate: what visibility adds to the render. Prints a table.

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_visibility_cost.py \
        [--size 320x240] [--repeat 1] [--blends figure6_box,figure7_blocker,figure8_caustic]
"""
import argparse
import os
import pickle
import sys
import tempfile
import time
from collections import defaultdict

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

from bench_kernels import exported  # noqa: E402
from engine import integrator, photonvisibility  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

STATS = defaultdict(lambda: defaultdict(float))
_label = ["?"]


def _map_label(pmap):
    """caustic / secondary / global: which of the calling integrator's maps pmap is."""
    f = sys._getframe(2)
    while f is not None and "ctx" not in f.f_locals:
        f = f.f_back
    ctx = None if f is None else f.f_locals["ctx"]
    if ctx is None:
        return "?"
    if pmap is getattr(ctx, "caustic_map", None):
        return "caustic"
    if pmap is getattr(ctx, "global_map", None):
        return "global"
    return "secondary"


def instrument():
    """Wrap photonvisibility's stages to time them by map (process CPU time)."""
    vis = photonvisibility.visible_irradiance
    est, hid, re = (photonvisibility._estimate_read, photonvisibility._estimate_hidden,
                    photonvisibility._reestimate)

    def visible_irradiance(pmap, accel, p, *a, **kw):
        _label[0] = label = _map_label(pmap)
        c0 = time.process_time()
        out = vis(pmap, accel, p, *a, **kw)
        STATS[label]["total"] += time.process_time() - c0
        STATS[label]["rows"] += len(p)
        return out

    def _estimate_read(*a, **kw):
        c0 = time.process_time()
        out = est(*a, **kw)
        s = STATS[_label[0]]
        s["estimate"] += time.process_time() - c0
        s["wide rows"] += len(out[3][0])
        return out

    def _estimate_hidden(*a, **kw):
        E, rows, photons = hid(*a, **kw)
        s = STATS[_label[0]]
        s["hiding rows"] += len(np.unique(rows))
        s["pairs"] += len(rows)
        return E, rows, photons

    def _reestimate(*a, **kw):
        c0 = time.process_time()
        out = re(*a, **kw)
        STATS[_label[0]]["re-estimate"] += time.process_time() - c0
        return out

    photonvisibility.visible_irradiance = visible_irradiance
    photonvisibility._estimate_read = _estimate_read
    photonvisibility._estimate_hidden = _estimate_hidden
    photonvisibility._reestimate = _reestimate


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic")
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    ensure_compiled()
    instrument()
    rows = []
    for name in args.blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = width, height
        cpu = {False: [], True: []}
        split = None
        for _ in range(args.repeat):
            for on in (False, True):
                integrator.PHOTON_VISIBILITY = on
                STATS.clear()
                c0 = time.process_time()
                render(scene, RenderSettings(workers=1))
                cpu[on].append(time.process_time() - c0)
                if on and (split is None or cpu[on][-1] == min(cpu[on])):
                    split = {k: dict(v) for k, v in STATS.items()}
        off, on = min(cpu[False]), min(cpu[True])
        print(f"{name}: off {off:.2f} on {on:.2f} CPU s ({100 * (on / off - 1):+.1f} %)",
              flush=True)
        rows.append((name, off, on, split))
    integrator.PHOTON_VISIBILITY = True
    print(f"\n{width}x{height}, default settings, 1 worker, min of {args.repeat}; "
          "CPU s (time.process_time)\n")
    print("| blend | off | on | cost | map | estimate s | visibility s | hidden s | "
          "re-estimate s | rows | rows read again | rows hiding a photon | hidden pairs |")
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, off, on, split in rows:
        first = True
        for label in sorted(split):
            s = defaultdict(float, split[label])
            head = (f"| {name} | {off:.2f} | {on:.2f} | {100 * (on / off - 1):+.1f} % "
                    if first else "| | | | ")
            vis = s["total"] - s["estimate"]
            print(f"{head}| {label} | {s['estimate']:.2f} | {vis:.2f} | "
                  f"{vis - s['re-estimate']:.2f} | {s['re-estimate']:.2f} | "
                  f"{int(s['rows'])} | {int(s['wide rows'])} | "
                  f"{int(s['hiding rows'])} | {int(s['pairs'])} |")
            first = False


if __name__ == "__main__":
    main()
