"""The guided gather's noise in tests/test_gather_guiding_auto.py's patch room (a closed
grey room lit by a spot's small floor patch, 16 x 16, 8 spp), by the global search
radius' rule: per set of 5 paired seeds the radius (m), the indirect pass's per-pixel
spread over the seeds / its mean with gather_guiding "off" and "auto", their ratio (the
test asks < 0.8) and the paired difference of the means in standard errors.
docs/accuracy.md "radius44" quotes its runs.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_patch_room_guide.py [--sets 1,6,11,16]
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, ROOT)

import test_gather_guiding_auto as T  # noqa: E402  (its _room)

RULES = {"photons": False, "lookups": True}  # render.RADIUS_FROM_LOOKUPS


def _indirect(film):
    return np.asarray(film.passes()["indirect"], np.float64)[..., :3].mean(axis=-1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", default="1,6,11,16", help="first seed of each set of 5")
    args = ap.parse_args(argv)
    R = importlib.import_module("engine.render")  # (engine.render is also a function)
    print("| rule | seeds | radius (m) | noise off | noise auto | auto / off | "
          "means apart (se) | CPU s |\n|---|---|---:|---:|---:|---:|---:|---:|")
    for rule, on in RULES.items():
        R.RADIUS_FROM_LOOKUPS = on
        for start in (int(x) for x in args.sets.split(",")):
            seeds = range(start, start + 5)
            t = time.process_time()
            off_f = [T._room(True, seed=s, gather_guiding="off") for s in seeds]
            off = np.array([_indirect(f) for f in off_f])
            auto = np.array([_indirect(T._room(True, seed=s)) for s in seeds])
            n_off = off.std(axis=0).mean() / off.mean()
            n_auto = auto.std(axis=0).mean() / auto.mean()
            d = auto.mean(axis=(1, 2)) - off.mean(axis=(1, 2))
            se = abs(d.mean()) / (d.std(ddof=1) / np.sqrt(len(d)))
            radius = np.mean([f.stats["radius_global"] for f in off_f])
            print(f"| {rule} | {start}-{start + 4} | {radius:.3f} | {n_off:.3f} | "
                  f"{n_auto:.3f} | {n_auto / n_off:.3f} | {se:.2f} | "
                  f"{time.process_time() - t:.1f} |", flush=True)
    print(f"(load average {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
