"""Where photon visibility's read lists (engine/photonvisibility.py since visreuse: the
photons each estimate read, PhotonMap.knn_irradiance's read) go beyond the candidates of
the second search they replaced (_candidate_rays, 68aac1a: the k nearest accepted photons,
or for a row whose footprint floor passed its k-th distance the accepted photons within
the floor, at most 4k in the tree's order): a blend (the film_hashes export) rendered with
visibility on at --size / --spp, default settings, 1 worker; per map, the rows traced,
those whose read list is longer than k (a disc floored wider than the k-th accepted
photon: the footprint floor or MIN_RADIUS_FRACTION), the hidden pairs, and those whose
photon is read at rank k or later (which the old search traced only where the floor
exceeded the k-th fetched distance, and then not all of them past 4k), and the rows whose
footprint floor holds more than 4k photons (where the old search listed 4k of the floor's
ball in the tree's order, not necessarily the k nearest the estimate reads) with their
hidden pairs. Prints a line a map.

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_visreuse_reads.py \
        [--blends figure3_sphere] [--size 80x60] [--spp 16]
"""
import argparse
import os
import pickle
import sys
import tempfile
from collections import defaultdict

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

from bench_kernels import exported  # noqa: E402
from bench_visibility_cost import _label, _map_label  # noqa: E402
from engine import integrator, photonvisibility  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

STATS = defaultdict(lambda: defaultdict(int))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure3_sphere")
    ap.add_argument("--size", default="80x60")
    ap.add_argument("--spp", type=int, default=16)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    ensure_compiled()
    vis, pairs = photonvisibility.visible_irradiance, photonvisibility._hidden_pairs
    est = photonvisibility._estimate_read
    k_of = [64]
    chunk = [None]

    def _estimate_read(pmap, limits, counts, p, n, radius, k, min_photons, estimator,
                       r_floor):
        chunk[0] = (pmap, p, r_floor)
        return est(pmap, limits, counts, p, n, radius, k, min_photons, estimator, r_floor)

    def visible_irradiance(pmap, accel, p, n, lift, radius, k, *a, **kw):
        _label[0] = _map_label(pmap)
        k_of[0] = int(k)
        return vis(pmap, accel, p, n, lift, radius, k, *a, **kw)

    def _hidden_pairs(pmap, accel, p, n, lift, rows, slots, count, photons):
        r, hid = pairs(pmap, accel, p, n, lift, rows, slots, count, photons)
        s, k = STATS[_label[0]], k_of[0]
        s["traced"] += len(rows)
        s["longer than k"] += int((count[slots] > k).sum())
        s["pairs"] += len(r)
        slot_of = np.empty(len(p), np.int64)
        slot_of[rows] = slots
        pmap, pc, floor = chunk[0]
        over = np.zeros(len(p), bool)
        if floor is not None and len(rows):
            kind, pos, nodes, start, grid = pmap._arrays()
            from engine.photonmap import _ball_count
            buckets = np.zeros(0, np.int64)
            for i in rows.tolist():
                over[i] = _ball_count(kind, pos, nodes, start, grid, pc[i, 0], pc[i, 1],
                                      pc[i, 2], floor[i] * floor[i], buckets) > 4 * k
        s["rows whose floor holds > 4k"] += int(over[rows].sum())
        s["their hidden pairs"] += int(over[r].sum())
        for row, j in zip(r.tolist(), hid.tolist()):
            sl = slot_of[row]
            rank = int(np.flatnonzero(photons[sl, :count[sl]] == j)[0])
            s["pairs at rank >= k"] += rank >= k
        return r, hid

    photonvisibility.visible_irradiance = visible_irradiance
    photonvisibility._hidden_pairs = _hidden_pairs
    photonvisibility._estimate_read = _estimate_read
    integrator.PHOTON_VISIBILITY = True
    for name in args.blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = w, h
        STATS.clear()
        render(scene, RenderSettings(workers=1, spp=args.spp))
        for label in sorted(STATS):
            s = STATS[label]
            print(f"{name} {w}x{h} {args.spp} spp {label}: rows traced {s['traced']}, read "
                  f"lists longer than k {s['longer than k']}, hidden pairs {s['pairs']}, "
                  f"at rank >= k {s['pairs at rank >= k']}; rows whose floor holds > 4k "
                  f"photons {s['rows whose floor holds > 4k']}, their hidden pairs "
                  f"{s['their hidden pairs']}", flush=True)


if __name__ == "__main__":
    main()
