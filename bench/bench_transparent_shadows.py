"""Cost of transparent shadows (engine/shadowtransmittance.py): the direct-light stage on
the same floor hits with no card, an opaque card, and 1 / 2 / 4 stacked cards of alpha 0.5
(or an image-alpha cut-out card) between a soft area light and the floor.

Every shadow ray is one OCCLUDED query; in a scene with a transparent material the blocked
ones are walked again surface by surface (closest hit per transparent surface + one for the
end). Prints ms per batch, shadow rays/s, and the time relative to the opaque card (the
price of transparency). One thread.

    .venv/bin/python bench/bench_transparent_shadows.py [--hits 200000] [--repeat 3]
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
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import RenderSettings  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.bsdf import surface_hit  # noqa: E402
from engine.integrator import Counters, direct_irradiance  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import prepare_context  # noqa: E402
from engine.scene import Material  # noqa: E402
from engine.shadernodes import ImageLookup  # noqa: E402
from engine.textures import ImageTexture  # noqa: E402


def scene(cards, alpha, texture=False, beside=False):
    """beside: an opaque card over the floor and the transparent cards off to one side,
    where no measured shadow ray meets them (the price of transparency elsewhere)."""
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    if beside:
        s.add_plane((0, 0, 1.0), (0, 0, 1), 3.0, "white_diffuse", name="opaque")
    node = None
    if texture:
        px = np.ones((64, 64, 4), np.float32)
        yy, xx = np.mgrid[0:64, 0:64]
        px[..., 3] = ((xx // 8 + yy // 8) % 2).astype(np.float32)  # a checker of holes
        node = ImageLookup(ImageTexture(px, name="holes"), output="ALPHA")
    for i in range(cards):
        s.add_material(Material(f"card{i}", (0.6, 0.6, 0.6), alpha=alpha, alpha_texture=node))
        s.add_plane((20.0 if beside else 0.0, 0, 1.0 + 0.2 * i), (0, 0, 1), 3.0, f"card{i}",
                    name=f"card{i}")
    s.add_rect_area_light((0, 0, 2.5), 1.0, 400.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    return s


def floor_hits(ctx, n):
    rng = np.random.default_rng(0)
    o = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), np.full(n, 0.05)])
    o -= ctx.geo.offset
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, d)
    keep = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])


def main():
    ensure_compiled()
    cases = [("no card", 0, 1.0, False, False), ("opaque card", 1, 1.0, False, False),
             ("1 card alpha 0.5", 1, 0.5, False, False),
             ("2 cards alpha 0.5", 2, 0.5, False, False),
             ("4 cards alpha 0.5", 4, 0.5, False, False),
             ("1 image-alpha card", 1, 1.0, True, False),
             ("opaque, alpha beside", 1, 0.5, False, True)]
    rows = []
    for label, cards, alpha, tex, beside in cases:
        ctx = prepare_context(scene(cards, alpha, tex, beside), RenderSettings(workers=1))
        hit = floor_hits(ctx, args.hits)
        best = np.inf
        for r in range(args.repeat):
            c = Counters()
            t0 = time.perf_counter()
            E = direct_irradiance(ctx, hit, np.random.default_rng(r), c)
            best = min(best, time.perf_counter() - t0)
        rows.append((label, best, c.shadow_rays, float(E[:, 0].mean())))
    base = rows[1][1]
    print(f"{'scene':22s} {'ms':>8s} {'Mrays/s':>8s} {'x opaque':>8s} {'mean E':>8s}")
    for label, t, rays, e in rows:
        print(f"{label:22s} {1e3 * t:8.1f} {rays / t / 1e6:8.2f} {t / base:8.2f} {e:8.3f}")


if __name__ == "__main__":
    main()
