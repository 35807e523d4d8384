"""What Cycles' default Clamp Indirect 10 changes in the example blends' films: the blends
keep Cycles' defaults (scene.cycles Direct 0, Indirect 10, never set), which the add-on now
reads (addon/export.clamp_settings), while tools/film_hashes.py renders at the engine's
defaults (clamp off).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_clamp_blends.py \\
        [--blends figure6_box,figure7_blocker,figure8_caustic,figure3_sphere] \\
        [--size 80x60] [--spp 16] [--clamp 10]

Each blend as tools/film_hashes.py exports it ($TMPDIR/film_hashes), rendered with 1 worker
clamp off and Clamp Indirect --clamp; prints per pass the mean over the image (clamped /
off), the pixels that changed and the largest change (luminance).
"""
import argparse
import os
import pickle
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import numpy as np  # noqa: E402

from bench_kernels import exported  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

PASSES = ("combined", "direct", "indirect", "caustic", "specular", "emission")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic,"
                                        "figure3_sphere")
    ap.add_argument("--size", default="80x60")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--clamp", type=float, default=10.0)
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    print("| blend | pass | mean off | mean clamped / off | pixels changed | largest change |")
    print("|---|---|---:|---:|---:|---:|")
    for name in args.blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = width, height
        off = render(scene, RenderSettings(workers=1, spp=args.spp))
        on = render(scene, RenderSettings(workers=1, spp=args.spp, clamp_indirect=args.clamp))
        for p in PASSES:
            a = np.asarray(getattr(off, p), np.float64).mean(axis=2)
            b = np.asarray(getattr(on, p), np.float64).mean(axis=2)
            ratio = b.mean() / a.mean() if a.mean() > 0 else 1.0
            print(f"| {name} | {p} | {a.mean():.5f} | {ratio:.6f} | "
                  f"{int((a != b).sum())} / {a.size} | {np.abs(b - a).max():.4g} |", flush=True)


if __name__ == "__main__":
    main()
