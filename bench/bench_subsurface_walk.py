"""The time random-walk subsurface scattering (engine/subsurfacewalk.py) adds to a render:
a ball 1 m across of a skin colour (Base Color (0.8, 0.5, 0.4), Subsurface Weight 1,
Radius (1, 0.2, 0.1)) under a 1 m square area light, black world, the ball filling about
half of a SIZE x SIZE image, at several Subsurface Scales; the same scene with the walk off
(the diffuse stand-in) for the base time. Printed per scale: seconds off / on, the ratio,
the walks started, the share that left the surface, Embree rays per walk, and the ball's
mean (the walk off / on).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_subsurface_walk.py [--size 64] [--spp 8]
        [--scales 0.01 0.05 0.3] [--workers 1]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from engine import RenderSettings  # noqa: E402
from engine import subsurfacewalk as sw  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.scene import Material  # noqa: E402


def render(scale, walk, size, spp, workers):
    s = PaperScene(width=size, height=size)
    sp = sw.SubsurfaceParams.make(1.0, (0.8, 0.5, 0.4), np.array([1.0, 0.2, 0.1]) * scale,
                                  1.5, 0.0, 0.5)
    s.add_material(Material("skin", tuple(sp.stand_in()), roughness=0.5, subsurface=sp))
    s.add_sphere((0, 0, 0), 0.5, "skin", segments=48)
    s.add_rect_area_light((0.8, -0.8, 1.2), size=(1.0, 1.0), power=300.0)
    s.set_camera((0, -3, 0.3), (0, 0, 0), view_angle=30)
    hooks = []
    made = sw.SubsurfaceWalks.for_context.__func__

    def record(cls, ctx):
        hook = made(cls, ctx)
        if hook is not None and hook not in hooks:
            hooks.append(hook)
        return hook

    sw.SubsurfaceWalks.for_context = classmethod(record)
    try:
        t = time.perf_counter()
        film = s.render(RenderSettings(photons=50_000, caustic_photons=0, spp=spp, seed=1,
                                       workers=workers, subsurface_walk=walk))
        seconds = time.perf_counter() - t
    finally:
        sw.SubsurfaceWalks.for_context = classmethod(made)
    img = np.asarray(film.combined, np.float64)[..., :3]
    ball = img.sum(axis=2) > 0
    stats = {"walks": 0, "exits": 0, "rays": 0}
    for h in hooks:
        for k in stats:
            stats[k] += h.stats[k]
    return seconds, stats, img[ball].mean()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--scales", type=float, nargs="+", default=[0.01, 0.05, 0.3])
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args()
    ensure_compiled()
    render(0.05, True, 8, 1, a.workers)  # warm-up (imports, first BVH)
    print(f"| Scale | off s | on s | on / off | walks | left | rays / walk | ball off | "
          f"ball on |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scale in a.scales:
        t_off, _, m_off = render(scale, False, a.size, a.spp, a.workers)
        t_on, st, m_on = render(scale, True, a.size, a.spp, a.workers)
        walks = max(st["walks"], 1)
        print(f"| {scale:g} | {t_off:.2f} | {t_on:.2f} | {t_on / t_off:.2f} | {st['walks']} | "
              f"{st['exits'] / walks:.3f} | {st['rays'] / walks:.1f} | {m_off:.4f} | "
              f"{m_on:.4f} |", flush=True)


if __name__ == "__main__":
    main()
