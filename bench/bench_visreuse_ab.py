"""Photon visibility's estimates, this tree (one search a row: the estimate's read lists)
against another checkout's (--base ROOT, e.g. `git archive 68aac1a | tar -x -C ROOT`: the
second k-NN search's candidates, _candidate_rays), call by call in one render: each
visible_irradiance call's E is compared with the base's visible_irradiance on the same
inputs (its estimate from chaincounts.irradiance), and the hidden pairs of each (this
tree's _estimate_hidden, the base's hidden_photons). A blend (the film_hashes export) at
--size, 16 spp, default settings, 1 worker. Prints per blend the calls, rows, rows whose
E differs, hidden pairs of each and those this tree finds that the base does not.
The base's engine is imported as the package `bengine` (a copy under a temporary folder;
its kernels compile on first use).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_visreuse_ab.py \
        --base ROOT [--blends figure3_sphere,figure7_blocker] [--size 80x60]
"""
import argparse
import os
import pickle
import shutil
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

from bench_kernels import exported  # noqa: E402
from engine import chaincounts, photonvisibility as pv  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True)
    ap.add_argument("--blends", default="figure3_sphere,figure7_blocker")
    ap.add_argument("--size", default="80x60")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    pkg = tempfile.mkdtemp()
    shutil.copytree(os.path.join(args.base, "engine"), os.path.join(pkg, "bengine"))
    sys.path.insert(0, pkg)
    import bengine.photonvisibility as bpv
    ensure_compiled()
    stats = {}
    vis, est = pv.visible_irradiance, pv._estimate_hidden

    def _estimate_hidden(pmap, accel, p, n, lift, radius, k, min_photons, estimator, r_floor,
                         limits, counts, geo):
        E, rows, ph = est(pmap, accel, p, n, lift, radius, k, min_photons, estimator,
                          r_floor, limits, counts, geo)
        orow, oph = bpv.hidden_photons(pmap, accel, p, n, lift, radius, k, r_floor, geo=geo)
        new, old = set(zip(rows.tolist(), ph.tolist())), set(zip(orow.tolist(), oph.tolist()))
        stats["pairs"] += len(new)
        stats["base pairs"] += len(old)
        stats["pairs not in base"] += len(new - old)
        return E, rows, ph

    def visible_irradiance(pmap, accel, p, n, lift, radius, k, min_photons, estimator,
                           r_floor=None, limits=None, counts=None, geo=None):
        kw = dict(r_floor=r_floor, limits=limits, counts=counts, geo=geo)
        E = vis(pmap, accel, p, n, lift, radius, k, min_photons, estimator, **kw)
        E0 = chaincounts.irradiance(pmap, limits, counts, p, n, radius, k, min_photons,
                                    estimator, r_floor=r_floor)
        Eb = bpv.visible_irradiance(E0, pmap, accel, p, n, lift, radius, k, min_photons,
                                    estimator, **kw)
        stats["calls"] += 1
        stats["rows"] += len(p)
        stats["rows whose E differs"] += int(np.any(E != Eb, axis=1).sum())
        return E

    pv.visible_irradiance = visible_irradiance
    pv._estimate_hidden = _estimate_hidden
    for name in args.blends.split(","):
        with open(exported(name, os.path.join(tempfile.gettempdir(), "film_hashes")),
                  "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = w, h
        stats.clear()
        stats.update({key: 0 for key in ("calls", "rows", "rows whose E differs", "pairs",
                                         "base pairs", "pairs not in base")})
        render(scene, RenderSettings(workers=1, spp=16))
        print(f"{name} {w}x{h}: " + ", ".join(f"{key} {v}" for key, v in stats.items()),
              flush=True)
    shutil.rmtree(pkg, ignore_errors=True)


if __name__ == "__main__":
    main()
