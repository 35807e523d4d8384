"""Cost of flat passages (engine/shadowtransmittance.py): the direct-light stage on the
same floor hits under a soft area light with an opaque card (one OCCLUDED query per shadow
ray, no transparent material), an alpha-0.5 card (one transparent surface walked) and a
2 cm glass slab (two surfaces walked: the entry, then the exit's flat-passage test and the
two refractions' transmittance). Prints CPU ms per batch, best of --repeat, interleaved in
one process. One thread.

    .venv/bin/python bench/bench_flat_glass.py [--hits 200000] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--hits", type=int, default=200_000)
ap.add_argument("--repeat", type=int, default=3)
args = ap.parse_args()
root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, root)

from engine import RenderSettings  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.bsdf import surface_hit  # noqa: E402
from engine.integrator import Counters, direct_irradiance  # noqa: E402
from engine.render import prepare_context  # noqa: E402
from engine.scene import Material  # noqa: E402


def context(kind):
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    if kind == "slab":
        s.add_box((0, 0, 1.0), (4.0, 4.0, 0.02),
                  Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=1.5,
                           node="glass"), name="pane")
    elif kind == "opaque":
        s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, "white_diffuse", name="card")
    else:
        s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, Material("card", (0.5, 0.5, 0.5), alpha=0.5),
                    name="card")
    s.add_rect_area_light((0.0, 0.0, 3.0), (1.0, 1.0), power=100.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    return prepare_context(s, RenderSettings(workers=1))


def floor_hits(ctx, n):
    rng = np.random.default_rng(0)
    o = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n),
                         np.full(n, 0.05)])
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, d)
    keep = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])


kinds = ("opaque", "card", "slab")
ctxs = {k: context(k) for k in kinds}
hits = {k: floor_hits(ctxs[k], args.hits) for k in kinds}
best = {k: float("inf") for k in kinds}
for _ in range(args.repeat):
    for k in kinds:
        t0 = time.process_time()
        direct_irradiance(ctxs[k], hits[k], np.random.default_rng(1), Counters())
        best[k] = min(best[k], time.process_time() - t0)
print(f"{'blocker':8s} {'CPU ms':>8s} {'x opaque':>9s}   ({args.hits} floor hits, best of "
      f"{args.repeat}; load {os.getloadavg()[0]:.1f})")
for k in kinds:
    print(f"{k:8s} {best[k] * 1000:8.0f} {best[k] / best['opaque']:9.1f}")
