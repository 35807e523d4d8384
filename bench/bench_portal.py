"""Where the global shot's photons land with and without photon portals
(engine/portal.py, portal34): per row the photons stored, those that arrived from inside
the room (the point just before the hit inside the room's box), those of them in the gather
map (not caustic), their effective count (sum w)^2 / sum w^2 (w: a photon's power; equal
powers give the count), the power inside (W, RGB summed: the same in expectation), the
photon pass' wall seconds (its stats' time_photons) and the CPU seconds of the render
(1 spp). Prints a table.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_portal.py [--blend ROOM.blend
        --box X0,Y0,Z0,X1,Y1,Z1] [--seed 0] [--spp 1] [--workers N]

Default: tests/test_portal.py's 4 x 4 x 2 m room with a 1 x 1 m glass pane in its roof
(uniform sky). --blend: a .blend rendered through the add-on's export (objects hidden for
render left out), e.g. the new user's day room (built by /tmp/newuser32/scene.py, a one-off
script: box -2.5,-2,0,2.5,2,2.6).
"""
from __future__ import annotations

import argparse
import importlib
import os
import resource
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.join(ROOT, "tests"))

import numpy as np  # noqa: E402

from engine import portal  # noqa: E402
from engine.photonkernels import CAUSTIC  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

R = importlib.import_module("engine.render")


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def scene_and_settings(args):
    if not args.blend:
        import test_portal as T
        lo, hi = np.array([-T.HALF, -T.HALF, 0.0]), np.array([T.HALF, T.HALF, T.H])
        return T._room(), dict(photons=20_000), lo, hi
    import accuracy_scenes as A  # noqa: F401  (needs the bpy wheel)
    import bpy
    A.ensure_addon()
    import engine
    from addon import export as ex
    bpy.ops.wm.open_mainfile(filepath=args.blend)
    for ob in list(bpy.data.objects):
        if ob.hide_render:  # (the viewport depsgraph keeps them; a render does not)
            bpy.data.objects.remove(ob)
    scene = bpy.context.scene
    w, h = ex.render_size(scene.render)
    pm, _ = ex.export_scene(engine, bpy.context.evaluated_depsgraph_get(), width=w, height=h)
    box = np.array([float(x) for x in args.box.split(",")])
    return pm, scene.photonmap.to_settings_kwargs(scene.render.film_transparent), box[:3], box[3:]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blend", default="")
    ap.add_argument("--box", default="-2.5,-2,0,2.5,2,2.6")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--workers", type=int, default=0, help="0: the settings' (all cores)")
    args = ap.parse_args(argv)
    scene, kw, lo, hi = scene_and_settings(args)
    kw = {**kw, "spp": args.spp, "seed": args.seed}
    if args.workers:
        kw["workers"] = args.workers
    print("| portals | stored | inside | inside, gather map | effective count inside | "
          "power inside (W) | photon pass s | CPU s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for on in (False, True):
        got = {}
        orig, old = R.trace_photons, portal.ENABLED

        def spy(ctx, lights, counts, caustic_only, stream, *a, **k):
            ph = orig(ctx, lights, counts, caustic_only, stream, *a, **k)
            got.setdefault(stream, (ph, ctx.geo))
            return ph
        R.trace_photons, portal.ENABLED = spy, on
        t0 = cpu()
        try:
            film = R.render(scene, RenderSettings(**kw))
        finally:
            R.trace_photons, portal.ENABLED = orig, old
        t = cpu() - t0
        ph, geo = got[1]
        p = ph.position.astype(np.float64) + geo.offset - 1e-4 * ph.direction
        inside = np.all((p > lo) & (p < hi), axis=1)
        gather = inside & (ph.kind != CAUSTIC)
        w = ph.power[gather].astype(np.float64).sum(axis=1)
        ess = w.sum() ** 2 / max((w * w).sum(), 1e-300)
        power = ph.power[inside].astype(np.float64).sum()
        print(f"| {'on' if on else 'off'} | {len(ph):,} | {int(inside.sum()):,} | "
              f"{int(gather.sum()):,} | {ess:,.0f} | {power:.4g} | "
              f"{film.stats.get('time_photons', float('nan')):.2f} | {t:.1f} |")


if __name__ == "__main__":
    main()
