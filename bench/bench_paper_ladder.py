"""The paper's Figure 6 ladder in paper mode and with the defaults: what changes.

Renders cornell_box() at each rung (photons, paper radius x PAPER_FIGURE6_RADIUS_SCALE)
in paper mode (classic estimator, no final gathering) and with the default estimator and
final gathering, and prints the green / red ratio of the indirect light on the upper back
wall (colour bleeding), the mean brightness and the wall time:

    .venv/bin/python bench/bench_paper_ladder.py [--width 80 --height 60 --spp 4]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from engine import RenderSettings  # noqa: E402
from engine.api import PAPER_FIGURE6_LADDER, PAPER_FIGURE6_RADIUS_SCALE, cornell_box  # noqa: E402


def back_wall_bleed(film) -> float:
    h, w = film.height, film.width
    patch = film.indirect[int(0.1 * h):int(0.3 * h), int(0.3 * w):int(0.7 * w)]
    return float(patch[..., 1].mean() / max(patch[..., 0].mean(), 1e-12))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=80)
    ap.add_argument("--height", type=int, default=60)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    scene = cornell_box(args.width, args.height)
    print(f"{'photons':>8} {'r paper':>7} {'r (m)':>6} | {'mode':8} {'G/R':>6} {'mean':>7} "
          f"{'time':>7}")
    for photons, r in PAPER_FIGURE6_LADDER:
        for paper in (True, False):
            st = RenderSettings(photons=photons, caustic_photons=photons // 2,
                                radius=r * PAPER_FIGURE6_RADIUS_SCALE, paper_mode=paper,
                                spp=args.spp, seed=args.seed)
            t0 = time.perf_counter()
            film = scene.render(st)
            secs = time.perf_counter() - t0
            print(f"{photons:>8,} {r:>7.1f} {r * PAPER_FIGURE6_RADIUS_SCALE:>6.2f} | "
                  f"{'paper' if paper else 'default':8} {back_wall_bleed(film):>6.3f} "
                  f"{film.combined.mean():>7.4f} {secs:>6.1f}s", flush=True)


if __name__ == "__main__":
    main()
