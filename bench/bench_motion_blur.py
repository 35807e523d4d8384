"""Motion blur by time steps (engine/motionblur.py) against live Cycles: prints a table
(docs/compatibility.md motionblur38).

    .venv/bin/python bench/bench_motion_blur.py [--steps 1,4,8,16] [--spp 64]
        [--cycles-spp 512] [--size 128x64] [--move ball|camera] [--plot out.png]

The test's scene (tests/blender/test_motion_blur_cycles.py `_scene`: a red ball moving
3 m over two frames, Shutter 0.5 centred on frame 1, a sun, a grey floor). Columns:
steps (0: motion blur off, the still; auto: Steps 0, its count printed below), our render seconds (wall, this process) and
theirs, the whole image's luminance ratio, the streak's profile (8 rows through the
ball) against Cycles': mean and largest |difference| per column, and relMSE over the
image.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", default="0,4,8,16,auto",
                    help="0: motion blur off (the still); auto: Steps 0")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--cycles-spp", type=int, default=512)
    ap.add_argument("--size", default="128x64")
    ap.add_argument("--move", default="ball", choices=("ball", "camera"))
    ap.add_argument("--plot", default=None, help="write the profiles to this PNG")
    a = ap.parse_args(argv)
    import bpy
    import addon
    addon.register()
    from addon import engine
    from blender_helpers import cycles_plain, read_rgba, render_exr
    from test_motion_blur_cycles import _scene
    w, h = (int(v) for v in a.size.split("x"))
    out = tempfile.mkdtemp(prefix="bench_motion_blur_")

    def luminance(sc, name):
        path = os.path.join(out, name)
        t0 = time.perf_counter()
        render_exr(bpy, sc, path)
        return read_rgba(bpy, path)[..., :3] @ LUMINANCE, time.perf_counter() - t0

    sc = _scene(bpy, a.move)
    sc.render.resolution_x, sc.render.resolution_y = w, h
    sc.render.engine = "CYCLES"
    cycles_plain(sc, a.cycles_spp, 12)
    ref, t_ref = luminance(sc, "cycles.exr")
    band = slice(h // 2 - 4, h // 2 + 4)
    pc = ref[band].mean(0)
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = a.spp
    print(f"Cycles {a.cycles_spp} spp: {t_ref:.1f} s; ours {a.spp} spp, {w} x {h}, "
          f"moving: {a.move}")
    print(f"{'steps':>5} {'ours s':>7} {'whole':>6} {'profile mean':>12} "
          f"{'profile max':>11} {'relMSE':>8}")
    profiles = {}
    for token in a.steps.split(","):
        auto = token == "auto"
        steps = 0 if auto else int(token)
        sc.render.use_motion_blur = auto or steps > 0
        sc.photonmap.motion_blur_steps = 0 if auto else max(steps, 1)
        ours, t = luminance(sc, f"ours{token}.exr")
        if auto:
            steps = engine.last_render["stats"].get("motion_blur_steps")
        po = ours[band].mean(0)
        profiles[steps] = po
        rel = float(np.mean((ours - ref) ** 2 / (ref ** 2 + 0.01)))
        print(f"{steps:>5} {t:7.1f} {ours.mean() / ref.mean():6.3f} "
              f"{np.abs(po - pc).mean():12.4f} {np.abs(po - pc).max():11.4f} {rel:8.5f}")
        got = engine.last_render["stats"].get("motion_blur_steps")
        assert steps == 0 or got == steps, (steps, got)
        if auto:
            print(f"      (auto: {got} steps)")
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.plot(pc, "k-", lw=2, label=f"Cycles {a.cycles_spp} spp")
        for steps, po in profiles.items():
            ax.plot(po, label="still" if steps == 0 else f"{steps} steps")
        ax.set_xlabel("column")
        ax.set_ylabel("luminance (8 rows through the ball)")
        ax.legend()
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
        print(f"wrote {a.plot}")


if __name__ == "__main__":
    main()
