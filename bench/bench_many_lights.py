"""Many lights: time and error of direct light with 1 / 10 / 100 / 1000 point lights,
ours (light tree, and every light sampled) against Cycles at equal time.

    .venv/bin/python bench/bench_many_lights.py [--lights 1,10,100,1000] [--size 96x72]

Scene: a 10 m grey floor with a few boxes and balls, N point lights (radius 0) at random
places 0.5-2.5 m above it, total power 1000 W shared equally (seeded). Direct light only
on both sides (ours: ray tracing without photons; Cycles: no bounces), so the table
measures light sampling. Reference: Cycles at --ref-spp samples. Error: relMSE
(docs/design.md, Measuring accuracy). "Cycles at equal time": Cycles' relMSE interpolated
(log-log) at our wall time from Cycles renders at 1 / 4 / 16 / 64 / 256 samples.
Prints a markdown table.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from engine import RenderSettings  # noqa: E402
from engine.api import PaperScene  # noqa: E402
from engine.lights import selection  # noqa: E402


def build(n_lights, width, height, seed=0):
    rng = np.random.default_rng(seed)
    s = PaperScene(width, height)
    s.add_plane((0, 0, 0), (0, 0, 1), 10.0, "white_diffuse", name="floor")
    for k in range(4):
        x, y = rng.uniform(-3, 3, 2)
        s.add_box((float(x), float(y), 0.4), 0.8, "white_diffuse", name=f"box{k}")
        x, y = rng.uniform(-3, 3, 2)
        s.add_sphere((float(x), float(y), 0.5), 0.5, "white_diffuse", name=f"ball{k}",
                     segments=24)
    for _ in range(n_lights):
        x, y = rng.uniform(-4.5, 4.5, 2)
        z = rng.uniform(0.5, 2.5)
        s.add_point_light((float(x), float(y), float(z)), 1000.0 / n_lights)
    s.set_camera((0, -8, 6), (0, 0, 0), view_angle=55)
    return s


def relmse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def render_cycles(scene, spp, seed=0):
    import bpy
    import cycles_scene
    sc = cycles_scene.build(scene)
    c = sc.cycles
    sc.render.engine = "CYCLES"
    c.device, c.samples, c.seed = "CPU", spp, seed
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.max_bounces = 0  # direct light only
    c.pixel_filter_type, c.filter_width = "BOX", 1.0
    for light in bpy.data.lights:
        light.shadow_soft_size = 0.0
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        sc.render.filepath = os.path.join(tmp, "c.exr")
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        secs = time.perf_counter() - t0
        from engine.imageio import read_image
        return read_image(sc.render.filepath).astype(np.float64), secs


def render_ours(scene, spp, tree=True, seed=0):
    saved = selection.SAMPLE_ALL_UP_TO
    selection.SAMPLE_ALL_UP_TO = saved if tree else 10 ** 9
    try:
        t0 = time.perf_counter()
        film = scene.render(RenderSettings(spp=spp, photon_mapping=False, seed=seed))
        secs = time.perf_counter() - t0
    finally:
        selection.SAMPLE_ALL_UP_TO = saved
    return film.combined.astype(np.float64), secs, film.stats["shadow_rays"]


def at_time(points, t):
    """relMSE interpolated log-log at time t from (seconds, relMSE) points."""
    pts = sorted(points)
    ts = np.log([p[0] for p in pts])
    es = np.log([max(p[1], 1e-12) for p in pts])
    return float(np.exp(np.interp(math.log(t), ts, es)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lights", default="1,10,100,1000")
    ap.add_argument("--size", default="96x72")
    ap.add_argument("--spp", default="4,16,64")
    ap.add_argument("--ref-spp", type=int, default=2048)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    counts = [int(v) for v in args.lights.split(",")]
    spps = [int(v) for v in args.spp.split(",")]
    for n in (2, selection.SAMPLE_ALL_UP_TO + 1):  # compile / load kernels, both modes
        render_ours(build(n, 8, 6), 1)
    rows = []
    for n in counts:
        scene = build(n, w, h)
        ref, ref_secs = render_cycles(scene, args.ref_spp, seed=99)
        cyc = []
        for cspp in (1, 4, 16, 64, 256):
            img, secs = render_cycles(scene, cspp, seed=1)
            cyc.append((secs, relmse(img, ref)))
        modes = [("tree", True)] + ([("every light", False)] if n > selection.SAMPLE_ALL_UP_TO
                                    else [])
        for label, tree in modes:
            for spp in spps:
                if not tree and spp != spps[len(spps) // 2]:
                    continue  # the old way: one row is enough to show its cost
                img, secs, rays = render_ours(build(n, w, h), spp, tree)
                rows.append((n, label if n > selection.SAMPLE_ALL_UP_TO else "every light",
                             spp, secs, rays / (w * h * spp), relmse(img, ref),
                             at_time(cyc, secs), img.mean() / ref.mean()))
        print(f"{n} lights: Cycles reference {args.ref_spp} spp in {ref_secs:.1f} s; Cycles "
              + ", ".join(f"{t:.2f} s -> {e:.4f}" for t, e in cyc), flush=True)
    print()
    print(f"| lights | ours | spp | time (s) | shadow rays / sample | relMSE | Cycles relMSE "
          f"at equal time | brightness ours / Cycles |")
    print("|---|---|---|---|---|---|---|---|")
    for n, label, spp, secs, rps, err, cerr, bright in rows:
        print(f"| {n} | {label} | {spp} | {secs:.2f} | {rps:.2f} | {err:.4f} | {cerr:.4f} | "
              f"{bright:.3f} |")


if __name__ == "__main__":
    main()
