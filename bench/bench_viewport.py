"""Rendered viewport: time to the first image and to a given HDR-FLIP, and stop latency.

For each example blend at 640 x 360 (the scene camera, as a 3D view looking through it
would show it at that size), the viewport path runs as in Blender: export_viewport
(addon/export.py) and a Session (engine/session.py) with the viewport settings at their
defaults (addon/properties.py). Frames are picked up as they are published; afterwards
each is scored with HDR-FLIP against a Cycles render of the same view (cached under
--cache). Then the session is stopped at random moments to measure stop() latency.

    .venv/bin/python bench/bench_viewport.py [--only figure6_box] [--flip 0.15]
        [--passes 16] [--cycles-spp 64] [--stops 6]

Columns: first image (s from the start of the export: export + BVH + first photon pass +
1/4-size camera pass), first full-size pass, time to FLIP <= target, FLIP after the pass
budget, stop latency (median / max over --stops random moments).
"""
from __future__ import annotations

import argparse
import os
import sys
import threading
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)

import accuracy_scenes as A  # noqa: E402  (needs the bpy wheel)
import bpy  # noqa: E402

BLENDS = ("figure3_sphere", "figure6_box", "figure7_blocker", "figure8_caustic")
W, H = 640, 360


def cycles_reference(name, spp, cache):
    path = os.path.join(cache, f"viewport_{name}_{W}x{H}_{spp}spp.npy")
    if os.path.isfile(path):
        return np.load(path)
    scene = A.setup(name, W, H)
    A.set_cycles(scene, spp, seed=1)
    img, secs = A.render_rgb(scene)
    print(f"  Cycles reference {name}: {spp} spp in {secs:.1f} s", flush=True)
    os.makedirs(cache, exist_ok=True)
    np.save(path, img)
    return img


def start_viewport(name, passes):
    """Open the blend, export it as the viewport does and start a session; returns
    (session, t0) with t0 taken before the export."""
    import engine as pm
    from addon import export
    from engine.session import Session
    scene = A.setup(name, W, H)
    A.set_photonmap_defaults(scene)
    props = scene.photonmap
    depsgraph = bpy.context.evaluated_depsgraph_get()
    camera = export.convert_camera(pm, scene.camera.evaluated_get(depsgraph), W, H,
                                   scene.render, [])
    t0 = time.perf_counter()
    cache = export.ViewportExport(pm)
    pm_scene, _ = export.export_viewport(cache, depsgraph, camera, W, H)
    settings = pm.RenderSettings(**props.to_viewport_settings_kwargs())
    session = Session(pm_scene, settings, passes=passes or props.viewport_passes).start()
    return session, t0


def run(name, args):
    ref = cycles_reference(name, args.cycles_spp, args.cache)
    session, t0 = start_viewport(name, args.passes)
    frames = []  # (seconds since t0, frame)
    last = None
    try:
        while True:
            frame = session.frame
            if frame is not last and frame is not None:
                frames.append((time.perf_counter() - t0, frame))
                last = frame
                if frame.done:
                    break
            if session.error:
                raise RuntimeError(session.error)
            time.sleep(0.005)
    finally:
        session.stop()
    first = frames[0][0]
    first_full = next(t for t, f in frames if f.scale == 1)
    reached, final = None, None
    for t, f in frames:
        if f.scale != 1:
            continue
        score = A.flip(f.rgba[..., :3], ref)
        final = (f.passes, score, t)
        if reached is None and score <= args.flip:
            reached = (t, f.passes)
    # Stop latency at random moments of a fresh session.
    rng = np.random.default_rng(7)
    stops = []
    for _ in range(args.stops):
        session, _ = start_viewport(name, 0)
        time.sleep(rng.uniform(0.1, 2.0 * max(first_full, 0.5)))
        stops.append(session.stop())
        assert not session.running
    left = [t for t in threading.enumerate() if t.name.startswith("photonmap-session")]
    return dict(name=name, first=first, first_scale=frames[0][1].scale, first_full=first_full,
                reached=reached, final=final, stops=stops, threads_left=len(left))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="")
    ap.add_argument("--flip", type=float, default=0.15)
    ap.add_argument("--passes", type=int, default=16)
    ap.add_argument("--cycles-spp", type=int, default=64)
    ap.add_argument("--stops", type=int, default=6)
    ap.add_argument("--cache", default=os.path.join(os.path.expanduser("~"), ".cache",
                                                     "photonmap_bench"))
    args = ap.parse_args()
    names = [n for n in args.only.split(",") if n] or list(BLENDS)
    A.ensure_addon()
    rows = []
    for name in names:
        print(f"{name} ...", flush=True)
        rows.append(run(name, args))
        print("  " + row(rows[-1]), flush=True)  # a long run keeps what it measured
    print(f"\nRendered viewport at {W}x{H}, viewport defaults, {args.passes} passes; "
          f"FLIP against Cycles {args.cycles_spp} spp; {os.cpu_count()} cores")
    print(f"| blend | first image | first full pass | FLIP <= {args.flip:g} | "
          "FLIP at budget | stop median / max | threads left |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(row(r))


def row(r):
    reached = (f"{r['reached'][0]:.2f} s (pass {r['reached'][1]})" if r["reached"]
               else "not reached")
    passes, score, t = r["final"]
    return (f"| {r['name']} | {r['first']:.2f} s (1/{r['first_scale']}) | "
            f"{r['first_full']:.2f} s | {reached} | {score:.3f} (pass {passes}, {t:.1f} s) | "
            f"{np.median(r['stops']):.3f} / {max(r['stops']):.3f} s | {r['threads_left']} |")


if __name__ == "__main__":
    main()
