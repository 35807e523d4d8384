"""Ray visibility: one BVH per ray class (engine/visibility.py) against re-tracing from
just past each invisible hit on the one BVH (the other way to skip triangles when embreex
has no per-ray masks).

Scene: a floor of spheres seen from above, with a sheet of camera-invisible spheres
(`--layers` layers of them) between the camera and the floor. Prints the build time of the
extra BVH and the time per million camera rays both ways, and checks both find the same
hits. Run from the repo root:

    .venv/bin/python bench/bench_visibility.py [--rays 1000000 --layers 1 --segments 48]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine.accel import Accel  # noqa: E402
from engine.api import sphere_mesh  # noqa: E402
from engine.geometry import ALL_RAYS, CAMERA  # noqa: E402
from engine.sampling import offset_origin  # noqa: E402
from engine.visibility import VisibilityAccel  # noqa: E402


def build(layers: int, segments: int, grid: int = 8):
    verts, faces, vis = [], [], []
    n = 0
    for layer in range(layers + 1):
        z = 0.0 if layer == 0 else 1.0 + layer
        for i in range(grid):
            for j in range(grid):
                v, f, *_ = sphere_mesh((i - grid / 2 + 0.5, j - grid / 2 + 0.5, z), 0.45,
                                   segments, segments // 2)
                verts.append(v)
                faces.append(f + n)
                n += len(v)
                vis.append(np.full(len(f), ALL_RAYS if layer == 0 else ALL_RAYS & ~CAMERA,
                                   np.uint8))
    v = np.concatenate(verts)
    f = np.concatenate(faces)
    tri = v[f]
    ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ng /= np.maximum(np.linalg.norm(ng, axis=1), 1e-300)[:, None]
    return (tri.reshape(-1, 3).astype(np.float32), np.arange(3 * len(f), dtype=np.int32)
            .reshape(-1, 3), np.concatenate(vis), tri, ng)


def retrace(full: Accel, vis, tri, ng, o, d, eps, max_layers=64):
    """Closest camera-visible hit by re-tracing past invisible hits on the full BVH."""
    n = len(o)
    prim_out = np.full(n, -1, np.int64)
    rows = np.arange(n)
    for _ in range(max_layers):
        if len(rows) == 0:
            break
        t, prim, u, v = full.intersect(o, d)
        hit = prim >= 0
        ok = hit & ((vis[np.maximum(prim, 0)] & CAMERA) != 0)
        prim_out[rows[ok]] = prim[ok]
        again = hit & ~ok
        if not again.any():
            break
        p = tri[prim[again], 0] + u[again, None] * (tri[prim[again], 1] - tri[prim[again], 0]) \
            + v[again, None] * (tri[prim[again], 2] - tri[prim[again], 0])
        o = offset_origin(p, ng[prim[again]], d[again], eps)
        d = d[again]
        rows = rows[again]
    return prim_out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--layers", type=int, nargs="+", default=[1, 3])
    ap.add_argument("--segments", type=int, default=48)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    print("| invisible layers | triangles | extra BVH build s | per-class BVH s/Mray | "
          "re-trace s/Mray | same hits |")
    print("|---|---|---|---|---|---|")
    for layers in args.layers:
        v32, f32, vis, tri, ng = build(layers, args.segments)
        t0 = time.perf_counter()
        full = Accel(v32, f32)
        t_full = time.perf_counter() - t0
        t0 = time.perf_counter()
        va = VisibilityAccel(v32, f32, vis, Accel)
        t_vis = time.perf_counter() - t0 - t_full  # the extra camera BVH
        o = np.column_stack([rng.uniform(-4, 4, args.rays), rng.uniform(-4, 4, args.rays),
                             np.full(args.rays, 10.0)])
        d = np.tile([0.0, 0.0, -1.0], (args.rays, 1))
        t0 = time.perf_counter()
        _, prim_a, _, _ = va.intersect(o, d, cls=CAMERA)
        t_a = time.perf_counter() - t0
        t0 = time.perf_counter()
        prim_b = retrace(full, vis, tri, ng, o, d, eps=1e-5 * 20)
        t_b = time.perf_counter() - t0
        same = float(np.mean(prim_a == prim_b))
        scale = 1e6 / args.rays
        print(f"| {layers} | {len(f32)} | {t_vis:.3f} | {t_a * scale:.3f} | {t_b * scale:.3f} "
              f"| {100 * same:.2f} % |")


if __name__ == "__main__":
    main()
