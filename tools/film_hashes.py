"""SHA-1 of the film passes (direct, indirect, caustic, specular, emission) of example blends
rendered at a small size: the bitwise check docs/performance.md calls "films". A change that
claims "films bitwise" prints the same hashes as its base, with 1 and with 2 workers.

    PYTHONPATH=$PWD .venv/bin/python tools/film_hashes.py [--workers 1 2] [--size 80x60]
        [--spp 16] [--blends figure6_box,figure7_blocker,figure8_caustic] [--label NAME]

Each blend is exported once through the add-on by a child Blender (bpy) process into
$TMPDIR/film_hashes/ (bench/bench_kernels.exported); delete that folder after changing the
export. Prints one line per blend and worker count: label, blend, workers, SHA-1.
"""
import argparse
import hashlib
import os
import pickle
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import numpy as np  # noqa: E402

from bench_kernels import exported  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

PASSES = ("direct", "indirect", "caustic", "specular", "emission")


def film_hash(film) -> str:
    """SHA-1 over the film's PASSES, each as its array's bytes."""
    h = hashlib.sha1()
    for name in PASSES:
        h.update(np.ascontiguousarray(getattr(film, name)).tobytes())
    return h.hexdigest()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--size", default="80x60", help="WIDTHxHEIGHT")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--label", default=os.path.basename(ROOT))
    args = ap.parse_args(argv)
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        ap.error(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 80x60")
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    ensure_compiled()
    for name in args.blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = width, height
        for workers in args.workers:
            film = render(scene, RenderSettings(workers=workers, spp=args.spp))
            print(args.label, name, workers, film_hash(film), flush=True)


if __name__ == "__main__":
    main()
