"""The compact photon layout's change to the example films (docs/performance.md
"compact50"): tools/film_hashes.py's renders (80 x 60, 16 spp, 1 worker, default
settings) with photonlayout.COMPACT off (float32 maps) and on, in one process. Prints
both films' hashes and the change of the summed passes: relMSE (mean (on - off)^2 /
(off^2 + 0.01)), max abs and mean abs over the mean.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_layout_films.py \\
        figure3_sphere,figure6_box,figure7_blocker,figure8_caustic,hdri_sphere
"""
import os
import pickle
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tools"), os.path.join(ROOT, "bench")]

import numpy as np  # noqa: E402

import film_hashes as fh  # noqa: E402
from bench_kernels import exported  # noqa: E402
from engine import photonlayout  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402


def main(blends):
    ensure_compiled()
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    print("| blend | float32 maps | compact maps | relMSE | max abs | mean abs / mean |")
    print("|---|---|---|---:|---:|---:|")
    old = photonlayout.COMPACT
    for name in blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = 80, 60
        films = {}
        try:
            for compact in (False, True):
                photonlayout.COMPACT = compact
                films[compact] = render(scene, RenderSettings(workers=1, spp=16))
        finally:
            photonlayout.COMPACT = old
        img = {c: sum(np.asarray(getattr(f, p), np.float64) for p in fh.PASSES)
               for c, f in films.items()}
        a, b = img[False], img[True]
        rel = np.mean((b - a) ** 2 / (a * a + 1e-2))
        print(f"| {name} | {fh.film_hash(films[False])[:8]} | {fh.film_hash(films[True])[:8]} "
              f"| {rel:.2e} | {np.abs(b - a).max():.2e} | "
              f"{np.abs(b - a).mean() / a.mean():.2e} |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else
         "figure3_sphere,figure6_box,figure7_blocker,figure8_caustic,hdri_sphere")
