"""The glow of a rough specular layer from the glow shot against the global shot's photons
(issue 14, s23 roughglint): CPU and accuracy, A/B in one process.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_roughglint.py [--seeds 1,2,3,4] [--spp 16]

The scene of tests/blender/test_rough_glow_cycles.py (bpy): a shaded plaster wall lit by
40 m of sunlit grass (Principled roughness 0.9), whose specular layer's glow reaches the
wall through the caustic map. Per seed, interleaved, engine/render.py's GLOW_SHOT off
(before: the glow from the visual-importance-aimed global shot) and on (the glow shot):
the photon pass's CPU seconds (time.process_time, every thread of the process), the whole
render's, and the wall's and its 3x3 patches' luminance against Cycles 1024 spp without
clamp (the test's CYCLES). Then the patches' seed-to-seed std and their means' worst
deviation, as docs/performance.md "roughglint" reports them.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1,2,3,4")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--photons", type=int, default=200_000)
    a = ap.parse_args()
    import bpy
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    import engine
    from addon import export
    from engine import RenderSettings
    import test_rough_glow_cycles as t
    er = sys.modules["engine.render"]
    sc, rot = t._scene(bpy)
    masks = t._patches(rot)
    pm_scene, _ = export.export_scene(engine, bpy.context.evaluated_depsgraph_get())
    kw = sc.photonmap.to_settings_kwargs(False)
    photon_cpu = []
    inner = er._photon_pass

    def timed(*args, **kwargs):  # the calling thread runs the pass; process_time sums all
        c0 = time.process_time()
        out = inner(*args, **kwargs)
        photon_cpu.append(time.process_time() - c0)
        return out

    er._photon_pass = timed
    rows = {False: [], True: []}
    print("seed glow  photon-pass CPU s  render CPU s  wall x Cycles")
    for seed in [int(s) for s in a.seeds.split(",")]:
        for glow in (False, True):
            er.GLOW_SHOT = glow
            kw.update(spp=a.spp, photons=a.photons, caustic_photons=50_000, seed=seed)
            c0 = time.process_time()
            film = er.render(pm_scene, RenderSettings(**kw))
            cpu = time.process_time() - c0
            rgb = film.combined.astype(np.float64)
            lum = rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722
            r = np.array([lum[m].mean() for m in masks]) / np.array(t.CYCLES)
            rows[glow].append(r)
            print(f"{seed:4d} {'on ' if glow else 'off'}  {photon_cpu[-1]:16.3f}  {cpu:12.2f}  {r[0]:.3f}")
    er._photon_pass, er.GLOW_SHOT = inner, True
    for glow in (False, True):
        r = np.array(rows[glow])
        std = r[:, 1:].std(axis=0, ddof=1) if len(r) > 1 else np.zeros(9)
        print(f"glow {'on ' if glow else 'off'}: wall {r[:, 0].mean():.3f}, patch seed std mean "
              f"{std.mean():.3f} max {std.max():.3f}, patch means' worst deviation "
              f"{np.abs(r[:, 1:].mean(axis=0) - 1).max():.3f}")


if __name__ == "__main__":
    main()
