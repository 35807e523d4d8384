"""The thread CPU time of the pane shadow rays (engine/panelight.pane_irradiance) and of its
two Embree calls per pane, in bench_window_pane.py's room built as a PaperScene (no
Blender): a 4 x 3 x 2.6 m box room, a 1.2 x 1.0 m single-plane glass pane in one wall, lit
by a white world (color), its 64 x 32 sky with a bright patch (hdri) or a 3-degree sun at
40 degrees elevation (sun).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_pane_irradiance.py \
        [--worlds color hdri sun] [--res 80 60] [--spp 32] [--repeat 1] [--engine DIR]

--engine: the checkout whose engine/ is timed (default this one; e.g. the base's worktree
for a before / after pair).

One thread (workers=1), photons 50k, seed 1; each render once per repeat, the best kept.
Prints per world: the render's process CPU s, pane_irradiance's thread CPU s, the part in
_through (its Embree calls and the kernels around them) and in Embree itself
(accel.intersect + occluded_into), the points shaded and the calls.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def room(world, res):
    import numpy as np
    from engine.api import PaperScene
    from engine.scene import Material
    s = PaperScene(width=res[0], height=res[1],
                   background=(0.0,) * 3 if world == "sun" else (1.0,) * 3)
    s.add_material(Material("plaster", (0.8,) * 3))
    s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.5,
                            roughness=0.0))
    for c, sz in (((0, 0, -0.05), (4.2, 3.2, 0.1)), ((0, 0, 2.65), (4.2, 3.2, 0.1)),
                  ((-2.05, 0, 1.3), (0.1, 3.2, 2.6)), ((2.05, 0, 1.3), (0.1, 3.2, 2.6)),
                  ((0, -1.55, 1.3), (4.0, 0.1, 2.6)), ((0, 1.55, 0.45), (4.0, 0.1, 0.9)),
                  ((0, 1.55, 2.25), (4.0, 0.1, 0.7)), ((-1.3, 1.55, 1.4), (1.4, 0.1, 1.0)),
                  ((1.3, 1.55, 1.4), (1.4, 0.1, 1.0))):
        s.add_box(c, sz, "plaster")
    v = np.array([[-0.6, 1.55, 0.9], [0.6, 1.55, 0.9], [0.6, 1.55, 1.9], [-0.6, 1.55, 1.9]])
    s.add_triangles(v, np.array([[0, 2, 1], [0, 3, 2]]), "glass", name="pane")
    if world == "hdri":
        sys.path.insert(0, os.path.join(ROOT, "bench"))
        import bench_window_pane
        s.set_environment(bench_window_pane._hdri())
    elif world == "sun":
        el, az = math.radians(40.0), math.radians(20.0)
        s.add_sun((-math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), -math.sin(el)),
                  strength=4.0, angle_degrees=3.0)
    s.set_camera((1.8, 1.3, 2.0), (-0.2, -1.1, 2.7), view_angle=90.0)
    return s


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--worlds", nargs="+", default=["color", "hdri", "sun"],
                    choices=("color", "hdri", "sun"))
    ap.add_argument("--res", type=int, nargs=2, default=(80, 60))
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--engine", default=ROOT)
    a = ap.parse_args()
    sys.path.insert(0, os.path.abspath(a.engine))
    from engine import RenderSettings, accel, integrator, jit, panelight
    jit.ensure_compiled()
    acc = {}
    lock = threading.Lock()
    local = threading.local()  # inside pane_irradiance: its Embree calls are counted

    def timed(key, fn):
        def wrap(*args, **kw):
            if key == "embree" and not getattr(local, "pane", False):
                return fn(*args, **kw)
            if key == "pane":
                local.pane = True
            t = time.thread_time()
            try:
                return fn(*args, **kw)
            finally:
                dt = time.thread_time() - t
                if key == "pane":
                    local.pane = False
                with lock:
                    acc[key] = acc.get(key, 0.0) + dt
                    if key == "pane":
                        acc["calls"] = acc.get("calls", 0) + 1
                        acc["points"] = acc.get("points", 0) + len(args[2])
        return wrap

    integrator.pane_irradiance = timed("pane", integrator.pane_irradiance)
    panelight._through = timed("through", panelight._through)
    for name in ("intersect", "occluded_into"):  # the raw Embree scene's two queries
        setattr(accel.Accel, name, timed("embree", getattr(accel.Accel, name)))
    import engine
    print(f"engine {os.path.dirname(os.path.dirname(engine.__file__))}; room {a.res[0]}x"
          f"{a.res[1]}, {a.spp} spp, workers 1, best of {a.repeat} (thread CPU s)")
    print("| world | render CPU s | pane_irradiance | of which _through | of which Embree "
          "| points | calls |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for world in a.worlds:
        best = None
        for _ in range(a.repeat):
            acc.clear()
            s = room(world, a.res)
            t = time.process_time()
            s.render(RenderSettings(spp=a.spp, photons=50_000, seed=1, workers=1))
            row = (time.process_time() - t, acc.get("pane", 0.0), acc.get("through", 0.0),
                   acc.get("embree", 0.0), acc.get("points", 0), acc.get("calls", 0))
            best = row if best is None or row[1] < best[1] else best
        print(f"| {world} | {best[0]:.2f} | {best[1]:.3f} | {best[2]:.3f} | {best[3]:.2f} | "
              f"{best[4]} | {best[5]} |", flush=True)


if __name__ == "__main__":
    main()
