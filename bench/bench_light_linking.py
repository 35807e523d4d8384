"""Noise cost of Light Linking's zeroed samples (engine/lightlinking.py).

Cycles builds a light tree per receiver set, so a surface never picks a lamp that does not
light it; so does the engine (lightlinking.set_selector). With one shared tree such a pick
gives a zero sample (lightlinking.PER_SET_TREES = False). This measures both: two patches
under LAMPS point lamps (the light tree picks one per sample), every other lamp linked to
the left patch only. The right patch is lit by half the lamps; its pixel noise is
compared with the same patch in a scene holding only those lamps. Per-pixel standard
deviation over SEEDS renders, and the render time, per configuration.

    PYTHONPATH=. .venv/bin/python bench/bench_light_linking.py
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from engine import RenderSettings, lightlinking
from engine.api import PaperScene
from engine.scene import Camera, Material

LAMPS, SEEDS, SPP, RES = 48, 8, 4, 32  # 24 lamps left: still past SAMPLE_ALL_UP_TO (tree)


def scene(mode: str) -> PaperScene:
    s = PaperScene(width=RES, height=RES)
    s.add_material(Material("matte", (0.5, 0.5, 0.5)))
    s.add_plane((-1.0, 0, 0), (0, 0, 1), (2.0, 4.0), "matte", name="left", up=(0, 1, 0))
    s.add_plane((1.0, 0, 0), (0, 0, 1), (2.0, 4.0), "matte", name="right", up=(0, 1, 0))
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO", ortho_scale=4.0)
    for i in range(LAMPS):
        linked = i % 2 == 0
        if mode == "subset" and linked:
            continue  # what lights the right patch, alone
        lamp = s.add_point_light((-2.0 + 4.0 * i / (LAMPS - 1), 0.5 * math.sin(i), 2.0),
                                 power=2000.0 / LAMPS, name=f"lamp{i}")
        if mode == "linked" and linked:
            lamp.receivers = ["left"]
    return s


def measure(mode: str):
    imgs, seconds = [], 0.0
    for seed in range(SEEDS):
        t0 = time.perf_counter()
        film = scene(mode).render(RenderSettings(spp=SPP, seed=seed, photon_mapping=False,
                                                 max_depth=0))
        seconds += time.perf_counter() - t0
        imgs.append(film.combined[..., 1])
    imgs = np.array(imgs)
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    right = np.tile(c, (RES, 1)) > 0.2
    mean = imgs.mean(axis=0)[right].mean()
    std = imgs.std(axis=0, ddof=1)[right].mean()
    return mean, std, seconds / SEEDS


def main() -> int:
    print(f"{LAMPS} point lamps, half linked to the left patch; right patch, {SPP} spp, "
          f"{SEEDS} seeds, {RES}x{RES}")
    print(f"{'configuration':34s} {'mean':>8s} {'pixel std':>10s} {'std/mean':>9s} "
          f"{'s/render':>9s}")
    rows = {}
    for key, mode, per_set, label in (
            ("shared", "linked", False, "linked, one shared tree (zeroed)"),
            ("per_set", "linked", True, "linked, a tree per set (ours)"),
            ("subset", "subset", True, "only the right patch's lamps")):
        lightlinking.PER_SET_TREES = per_set
        rows[key] = measure(mode)
        m, sd, sec = rows[key]
        print(f"{label:34s} {m:8.4f} {sd:10.4f} {sd / m:9.4f} {sec:9.3f}")
    lightlinking.PER_SET_TREES = True
    for key in ("shared", "per_set"):
        print(f"variance ratio {key} / subset (samples for equal noise): "
              f"{(rows[key][1] / rows['subset'][1]) ** 2:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
