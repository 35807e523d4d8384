"""What seating a fog box on the floor costs at scene preparation (engine/volumecontact.py).

A floor of N triangles (a grid over 12 x 12 m) and a 4 x 4 x 3 m volume-only box standing
on it (seated) or floating 0.1 m above it (tested, not seated); the best of three calls of
seat_volume_faces. Prints a table. Run: .venv/bin/python bench/bench_volume_contact.py
"""
import time

import numpy as np

from engine.api import box_mesh
from engine.scene import Material, Mesh
from engine.volumecontact import seat_volume_faces

MATERIALS = {"grey": Material("grey"),
             "fog": Material("fog", volume_only=True, absorption=(0.1, 0.1, 0.1))}


def floor(n):
    """A grid of n x n quads (2 n^2 triangles) over 12 x 12 m at z = 0."""
    xs = np.linspace(-6.0, 6.0, n + 1)
    X, Y = np.meshgrid(xs, xs)
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    f = np.concatenate([np.stack([i, i + 1, i + n + 2], 1), np.stack([i, i + n + 2, i + n + 1], 1)])
    return Mesh("floor", v, f, materials=["grey"])


def best_of(fn, k=3):
    out = []
    for _ in range(k):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def main():
    print("| floor triangles | box | seated | seat_volume_faces (s) |")
    print("|---|---|---|---|")
    for n in (10, 100, 300, 708):
        fl = floor(n)
        for where, z in (("standing", 1.5), ("floating 0.1 m", 1.6)):
            v, f = box_mesh((0.0, 0.0, z), (4.0, 4.0, 3.0))
            box = Mesh("fog", v, f, materials=["fog"])
            seated = seat_volume_faces([fl, box], MATERIALS)[1]
            dt = best_of(lambda: seat_volume_faces([fl, box], MATERIALS))
            print(f"| {len(fl.faces):,} | {where} | {bool(seated)} | {dt:.3f} |")


if __name__ == "__main__":
    main()
