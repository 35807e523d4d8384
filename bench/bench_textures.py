"""Texture lookup cost per hit: image interpolation modes and a small node tree.

    .venv/bin/python bench/bench_textures.py [--hits 200000]

Prints nanoseconds per lookup (best of 3) for a 1024 x 1024 RGB image under each
Interpolation, with sRGB conversion and Clip, and for the node chain UV -> Mapping ->
Image -> Mix Color -> Hue/Saturation evaluated over hits of a quad (engine/shadernodes.py).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import shadernodes as sn  # noqa: E402
from engine.geometry import prepare  # noqa: E402
from engine.scene import Material, Mesh, Scene  # noqa: E402
from engine.textures import ImageTexture  # noqa: E402


def best_of(fn, n=3):
    best = float("inf")
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--hits", type=int, default=200_000)
    args = p.parse_args(argv)
    rng = np.random.default_rng(0)
    img = rng.random((1024, 1024, 3)).astype(np.float32)
    uv = rng.random((args.hits, 2)) * 3 - 1
    rows = []
    for interp in ("Closest", "Linear", "Cubic"):
        for srgb, ext in ((False, "REPEAT"), (True, "REPEAT"), (False, "CLIP")):
            t = ImageTexture(img, interpolation=interp, srgb=srgb, extension=ext)
            rows.append((f"image {interp}, {'sRGB' if srgb else 'linear'}, {ext}",
                         best_of(lambda: t.sample(uv)) / len(uv) * 1e9))
    s = Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    s.add_material(Material("m"))
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2], materials=["m"]))
    geo, _ = prepare(s)
    tree = sn.HueSaturation(0.6, 0.9, 1.0, 1.0, sn.MixColor(
        0.5, sn.ImageLookup(ImageTexture(img), sn.Mapping(sn.UVCoord(), scale=(2, 2, 1))),
        (0.2, 0.4, 0.9), blend="MULTIPLY"))
    prim = rng.integers(0, 2, args.hits)
    bu = rng.random(args.hits) * 0.5
    bv = rng.random(args.hits) * 0.5
    rows.append(("tree UV-Mapping-Image-Mix-HSV",
                 best_of(lambda: tree.evaluate(geo, prim, bu, bv)) / args.hits * 1e9))
    print(f"{'lookup':45s} {'ns/hit':>8s}")
    for name, ns in rows:
        print(f"{name:45s} {ns:8.1f}")


if __name__ == "__main__":
    main()
