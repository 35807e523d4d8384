"""What the shader nodes that trace rays cost: a sun-lit floor with a box on it (64 x 48,
photons on), its floor material plain, its colour an Ambient Occlusion node (Samples 4 /
16), or its normal a Bevel node (Samples 4 / 8); wall time of the whole render (best of
3, one worker) and the time per camera sample the node adds.

    .venv/bin/python bench/bench_ray_nodes.py [--spp 8] [--workers 1]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import RenderSettings  # noqa: E402
from engine.ambientocclusion import AmbientOcclusion, OcclusionCore  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.bevel import Bevel  # noqa: E402
from engine.scene import Material  # noqa: E402


def _scene(floor: Material) -> PaperScene:
    s = PaperScene(width=64, height=48)
    s.add_material(floor)
    s.add_material(Material("grey", (0.6, 0.6, 0.6)))
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, floor.name, name="floor")
    s.add_box((0.2, 0.1, 0.3), (0.6, 0.6, 0.6), "grey", name="box")
    s.add_sun(direction=(0.4, 0.3, -1.0), strength=3.0)
    s.set_camera((0, -2.2, 1.6), (0.1, 0.1, 0.1), view_angle=50)
    return s


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=8)
    p.add_argument("--workers", type=int, default=1)
    a = p.parse_args(argv)
    cases = {
        "plain": Material("floor", (0.8, 0.8, 0.8)),
        "AO, 4 samples": Material("floor", (0.8, 0.8, 0.8), texture=AmbientOcclusion(
            OcclusionCore(0.5, samples=4))),
        "AO, 16 samples": Material("floor", (0.8, 0.8, 0.8), texture=AmbientOcclusion(
            OcclusionCore(0.5, samples=16))),
        "Bevel, 4 samples": Material("floor", (0.8, 0.8, 0.8),
                                     normal_map=Bevel(0.05, samples=4)),
        "Bevel, 8 samples": Material("floor", (0.8, 0.8, 0.8),
                                     normal_map=Bevel(0.05, samples=8)),
    }
    st = RenderSettings(spp=a.spp, photons=20_000, caustic_photons=0, workers=a.workers,
                        seed=1)
    _scene(cases["plain"]).render(st)  # load the kernels
    rows, plain = [], None
    for name, mat in cases.items():
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            _scene(mat).render(st)
            best = min(best, time.perf_counter() - t0)
        plain = best if plain is None else plain
        per = (best - plain) / (64 * 48 * a.spp) * 1e6
        rows.append((name, best, per))
    print(f"| floor material | render (s) | added per camera sample (us) |")
    print("|---|---|---|")
    for name, t, per in rows:
        print(f"| {name} | {t:.2f} | {per:.1f} |")


if __name__ == "__main__":
    main()
