"""Even light at a floor's corners: the caustic map's k-NN estimate with one image (across
the nearer edge) and with the corner's three (across both edges and across the corner;
engine/edgeimages.CORNERS), on synthetic photons with the engine's map and estimator
(issue 14, s21 secedges; docs/performance.md "secedges").

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_edge_corners.py [--seeds 10]

The floor x in [0, 2], y in [0, 1] m (tests/test_edge_images.py's), 1 W/m^2 of even light
as n photons; queries on its diagonals at c = 0 ... 1 R from each of its four corners
(R = 0.17 m, k = 64, knn_simpson); dense: n = 16000 (the k-NN radius ~0.3 R), sparse:
n = 1600 (~R). Prints E / truth by c / R, the mean over the seeds and the four corners,
and a control at the floor's middle.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "tests"))
import engine.edgeimages as ei  # noqa: E402
from test_edge_images import FLOOR, R, _estimate, _geo, _photons, _with_images  # noqa: E402

CS = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    a = ap.parse_args()
    print("| photons | images | " + " | ".join(f"c = {c:g} R" for c in CS) + " | middle |")
    print("|---" * (len(CS) + 3) + "|")
    for n in (16000, 1600):
        for corners in (False, True):
            ei.CORNERS = corners
            rows = []
            for seed in range(a.seeds):
                rng = np.random.default_rng(seed)
                geo, diffuse, accel = _geo(FLOOR)
                ph = _photons(rng.uniform([0, 0], [2, 1], (n, 2)), 2.0 / n)
                pm, _ = _with_images(ph, geo, diffuse, accel)
                row = []
                for c in np.asarray(CS) * R:
                    q = np.array([[c, c], [2 - c, c], [c, 1 - c], [2 - c, 1 - c]])
                    row.append(_estimate(pm, q).mean())
                row.append(_estimate(pm, np.array([[1.0, 0.5], [0.7, 0.5], [1.3, 0.5]])).mean())
                rows.append(row)
            m = np.mean(rows, axis=0)
            print(f"| {n} | {'three (corners)' if corners else 'one'} | "
                  + " | ".join(f"{v:.3f}" for v in m) + " |", flush=True)


if __name__ == "__main__":
    main()
