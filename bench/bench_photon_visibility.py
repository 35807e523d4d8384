"""A/B of photon visibility (engine/photonvisibility.py, integrator.PHOTON_VISIBILITY off /
on, interleaved in one process): Figures 6/7/8 (the film_hashes exports) at the Cycles
references' 96x72, 16 spp, one worker, per seed: pixels changed, the largest change; per
variant: relMSE against tests/references/NAME.npy (mean over seeds +- its standard error),
mean brightness over the reference's, CPU seconds (time.process_time). Then the issue-14
lamp shade (tests/test_leak_lampshade.py's scene plus the repro's sun) pierced / 10 cm
clear of the wall: image max and mean.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_photon_visibility.py [--seeds 3]
        [--blends figure6_box,figure7_blocker,figure8_caustic] [--no-lamp]
"""
import argparse
import math
import os
import pickle
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, os.path.join(ROOT, "tests"))

from bench_kernels import exported  # noqa: E402
from engine import integrator  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402


def lum(a):
    return a[..., 0] * .2126 + a[..., 1] * .7152 + a[..., 2] * .0722


def figures(seeds, blends=("figure6_box", "figure7_blocker", "figure8_caustic")):
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    for name in blends:
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        ref = np.load(os.path.join(ROOT, "tests", "references", f"{name}.npy"))[..., :3]
        ref = ref.astype(np.float64)
        scene.width, scene.height = ref.shape[1], ref.shape[0]
        res = {False: [], True: []}
        for seed in range(seeds):
            imgs = {}
            for vis in (False, True):
                integrator.PHOTON_VISIBILITY = vis
                c0 = time.process_time()
                film = render(scene, RenderSettings(workers=1, spp=16, seed=seed))
                cpu = time.process_time() - c0
                x = film.combined[..., :3].astype(np.float64)
                imgs[vis] = x
                res[vis].append((np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2)),
                                 x.mean() / ref.mean(), cpu))
            d = np.abs(imgs[True] - imgs[False]).max(axis=2)
            print(f"{name} seed {seed}: pixels changed {np.mean(d > 0):.3f}, largest change "
                  f"{d.max():.4f} (image mean {imgs[False].mean():.4f})", flush=True)
        for vis in (False, True):
            a = np.array(res[vis])
            print(f"{name} visibility={vis}: relMSE {a[:, 0].mean():.5f} +- "
                  f"{a[:, 0].std() / math.sqrt(len(a)):.5f}, mean/ref {a[:, 1].mean():.4f}, "
                  f"CPU s {a[:, 2].mean():.2f}", flush=True)


def lamp():
    from test_leak_lampshade import lamp_scene
    for gap in (0.0, 0.1):
        for vis in (False, True):
            integrator.PHOTON_VISIBILITY = vis
            s = lamp_scene()
            if gap:
                for m in s.meshes:
                    if m.name == "shade":
                        m.vertices = m.vertices - np.array([0.0, gap, 0.0])
                s.lights[0].position = np.asarray(s.lights[0].position) - (0.0, gap, 0.0)
            s.add_sun(direction=(-0.1669, 0.5394, -0.825), strength=1.0)
            film = s.render(spp=4, photons=50_000, caustic_photons=10_000, seed=1, workers=1)
            y = lum(film.combined)
            print(f"lamp shade gap {gap} m, visibility={vis}: image max {y.max():.3f}, "
                  f"mean {y.mean():.4f}, caustic max {lum(film.caustic).max():.3f}", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic",
                    help="any with a tests/references/NAME.npy (figure3_sphere too)")
    ap.add_argument("--no-lamp", action="store_true", help="the figures only")
    args = ap.parse_args()
    ensure_compiled()
    if not args.no_lamp:
        lamp()
    figures(args.seeds, args.blends.split(","))
