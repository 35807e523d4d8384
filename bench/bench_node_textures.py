"""Cost per hit of the procedural textures ported in numpy (engine/shadernodes.py: Brick,
Magic, Gabor), beside the compiled Noise kernel for scale.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_node_textures.py [--hits 200000]

Points are seeded uniform in a 2 x 2 x 2 box at the nodes' default Scale (5 cells per
unit); prints nanoseconds per hit (best of 3).
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from engine import shadernodes as sn  # noqa: E402
from bench_node_values import _Points  # noqa: E402  (fixed coordinates per hit)
from bench_textures import best_of  # noqa: E402  (the best of n timings)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--hits", type=int, default=200_000)
    args = p.parse_args(argv)
    n = args.hits
    pts = _Points(np.random.default_rng(0).uniform(-1.0, 1.0, (n, 3)))
    prim, z = np.arange(n), np.zeros(n)
    nodes = {
        "Noise (compiled kernel)": sn.Noise(pts),
        "Brick (Color)": sn.Brick(pts),
        "Magic (depth 2)": sn.Magic(pts),
        "Magic (depth 10)": sn.Magic(pts, depth=10),
        "Gabor 2D (anisotropic)": sn.Gabor(pts),
        "Gabor 2D (isotropic)": sn.Gabor(pts, {"Anisotropy": 0.0}),
        "Gabor 3D (anisotropic)": sn.Gabor(pts, dims=3),
        "Gabor 3D (isotropic)": sn.Gabor(pts, {"Anisotropy": 0.0}, dims=3),
    }
    print(f"| texture | ns per hit ({n} hits, best of 3) |")
    print("|---|---:|")
    for name, node in nodes.items():
        node.evaluate(None, prim[:16], z[:16], z[:16])  # warm (a kernel's first call)
        t = best_of(lambda: node.evaluate(None, prim, z, z))
        print(f"| {name} | {t / n * 1e9:.0f} |")


if __name__ == "__main__":
    main()
