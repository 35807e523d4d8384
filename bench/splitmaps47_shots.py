"""The caustic / glow shots Filter Glossy's split leaves unread (docs/compatibility.md
"splitmaps47"): ours at Filter Glossy 1 with the split on (glossysplit.ENABLED), the
shots traced (render.SKIP_UNREAD_SHOTS False) and not (True), per scene: photons
emitted, the photon pass's and the map build's wall seconds, the render's CPU seconds
(process_time) and whether the two images hold the same bits.

    PYTHONPATH=$PWD .venv/bin/python bench/splitmaps47_shots.py [--only figure6,figure8]
        [--spp 4] [--width 160] [--workers 1]

Scenes: scenes/<name>.toml at their own photon counts, --width wide (its height in
proportion). The traced render runs first, after a small render that loads the kernels.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from engine import RenderSettings, glossysplit  # noqa: E402
from engine.scenefile import load_scene  # noqa: E402

rd = sys.modules["engine.render"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", default="figure6,figure8")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args()
    glossysplit.ENABLED = True
    print("| scene | shots | photons emitted | photon pass s | map build s | CPU s | same bits |")
    print("|---|---|---:|---:|---:|---:|---|")
    # (a small render first: the kernels' load is no scene's)
    warm, _ = load_scene(os.path.join(ROOT, "scenes", "figure6.toml"))
    warm.width, warm.height = 16, 12
    rd.render(warm, RenderSettings(photons=2000, caustic_photons=2000, spp=1, workers=1))
    for name in a.only.split(","):
        scene, over = load_scene(os.path.join(ROOT, "scenes", f"{name}.toml"))
        over = dict(over)
        scene.width, scene.height = a.width, max(1, round(scene.height * a.width
                                                          / scene.width))
        over.update(spp=a.spp, seed=0, workers=a.workers, cycles_filter_glossy=1.0)
        s = replace(RenderSettings(), **over)
        films = {}
        for skip in (False, True):
            rd.SKIP_UNREAD_SHOTS = skip
            c0 = time.process_time()
            f = rd.render(scene, s)
            cpu = time.process_time() - c0
            films[skip] = f
            st = f.stats
            print(f"| {name} | {'skipped ' + '+'.join(st['shots_unread']) if skip and st.get('shots_unread') else 'traced'} "
                  f"| {st['photons_emitted_all']:,} | {st['time_photons']:.2f} "
                  f"| {st['time_photon_map']:.2f} | {cpu:.2f} | "
                  + ("" if not skip else str(bool(np.array_equal(
                      np.asarray(films[False].combined), np.asarray(f.combined))))) + " |")


if __name__ == "__main__":
    main()
