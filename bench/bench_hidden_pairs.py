"""Photon visibility's hidden-pair census: a blend (the film_hashes export) rendered with
integrator.PHOTON_VISIBILITY on, default settings, one worker, at --size, with
photonvisibility._estimate_hidden (the estimate and its hidden pairs) wrapped to count the
estimate rows it is given, the rows that hide a photon and the hidden (row, photon) pairs. Prints one line per blend.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_hidden_pairs.py \
        [--blends figure3_sphere,figure7_blocker] [--size 160x120]
"""
import argparse
import os
import pickle
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

from bench_kernels import exported  # noqa: E402
from engine import integrator, photonvisibility  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure3_sphere,figure7_blocker")
    ap.add_argument("--size", default="160x120")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    ensure_compiled()
    count = dict(rows=0, pairs=0, hiding=0)
    hidden = photonvisibility._estimate_hidden

    def wrapped(pmap, accel, p, *a, **kw):
        E, rows, photons = hidden(pmap, accel, p, *a, **kw)
        count["rows"] += len(p)
        count["pairs"] += len(rows)
        count["hiding"] += len(np.unique(rows))
        return E, rows, photons

    photonvisibility._estimate_hidden = wrapped
    integrator.PHOTON_VISIBILITY = True
    for name in args.blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = w, h
        count.update(rows=0, pairs=0, hiding=0)
        c0 = time.process_time()
        render(scene, RenderSettings(workers=1))
        print(f"{name} {w}x{h}: estimate rows {count['rows']}, rows hiding a photon "
              f"{count['hiding']}, hidden pairs {count['pairs']}, CPU s "
              f"{time.process_time() - c0:.2f}", flush=True)


if __name__ == "__main__":
    main()
