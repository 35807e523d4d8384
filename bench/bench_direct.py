"""The direct-light stage (light sampling + shadow rays + accumulation) against raw Embree
OCCLUDED on exactly the same rays, on the paper's Figure 6 box and on a 1M-triangle scene.

One batch of first diffuse hits (one camera ray per pixel) is lit by every light
(integrator.direct_irradiance); every occlusion query it makes is recorded and replayed
straight through embreex. Both on one thread. Prints rays/s of the stage, of raw Embree,
and their ratio (the target of issue 13: >= 60 %), plus the kernels' compile time.

    .venv/bin/python bench/bench_direct.py [--width 400 --height 300] [--repeat 3]
        [--root DIR]   # run another checkout's engine (e.g. the numpy stage before)
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--width", type=int, default=400)
ap.add_argument("--height", type=int, default=300)
ap.add_argument("--repeat", type=int, default=3)
ap.add_argument("--root", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ap.add_argument("--scenes", default="box,box1m")
args = ap.parse_args()
sys.path.insert(0, os.path.abspath(args.root))

from engine import RenderSettings  # noqa: E402
from engine.accel import Accel  # noqa: E402
from engine.api import cornell_box, sphere_mesh  # noqa: E402
from engine.bsdf import lobe_weights, surface_hit  # noqa: E402
from engine.integrator import Counters, camera_rays, direct_irradiance  # noqa: E402
from engine.render import prepare_context  # noqa: E402
from engine.sampling import max3  # noqa: E402
from engine.scene import Mesh  # noqa: E402


class RecordingAccel(Accel):
    """Accel that keeps a copy of every occlusion query so the same rays can be replayed."""
    record = False

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.log = []

    def occluded(self, o, d, tmax=None):
        if self.record:
            self.log.append(self._prepare(o, d, tmax))
        return super().occluded(o, d, tmax)

    def occluded_into(self, o32, d32, tmax32, blocked):
        if self.record:
            self.log.append((o32.copy(), d32.copy(), tmax32.copy()))
        return super().occluded_into(o32, d32, tmax32, blocked)


def scene(name, width, height):
    s = cornell_box(width, height)
    if name == "box1m":
        # A 1M-triangle ball on the floor (1000 x 500 segments x 2 triangles).
        v, f, n, uv = sphere_mesh((0.2, 0.6, 0.9), 0.9, 1000, 500)
        s.add_mesh(Mesh("ball1m", v, f, normals=n, uvs=uv, materials=["white_diffuse"]))
    return s


def first_diffuse_hits(ctx):
    sc = ctx.scene
    W, H = sc.width, sc.height
    pix = np.arange(W * H)
    o, d, tmax = camera_rays(sc.camera, ctx.geo.offset, W, H, pix % W, pix // W,
                             np.full(len(pix), 0.5), np.full(len(pix), 0.5))
    t, prim, u, v = ctx.accel.intersect(o, d, tmax)
    keep = prim >= 0
    hit = surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])
    wd = lobe_weights(ctx.table, hit)["diffuse"]
    return hit.take(np.nonzero(max3(wd) > 0)[0])


def main():
    rows = []
    compile_s = None
    try:
        from engine import jit
        t0 = time.perf_counter()
        jit._warm = False
        import engine.directlight as dl
        dl._warm_up()
        compile_s = time.perf_counter() - t0
    except ImportError:
        pass  # the numpy stage: nothing to compile
    for name in args.scenes.split(","):
        t0 = time.perf_counter()
        sc = scene(name, args.width, args.height)
        ctx = prepare_context(sc, RenderSettings(workers=1, photon_mapping=False),
                              accel_class=RecordingAccel)
        hit = first_diffuse_hits(ctx)
        accels = {id(a): a for a in [ctx.accel.full, *ctx.accel._by_class.values()]}
        rec = [a for a in accels.values() if isinstance(a, RecordingAccel)]
        tris = ctx.geo.count
        prep = time.perf_counter() - t0
        # Stage and raw replay alternate, best of each: the machine's load changes.
        best = raw = np.inf
        for r in range(args.repeat + 1):
            rng = np.random.default_rng(r)
            counters = Counters()
            for a in rec:
                a.log, a.record = [], r == 0
            t0 = time.perf_counter()
            direct_irradiance(ctx, hit, rng, counters)
            if r == 0:  # the recording run copies every query: not timed
                n_rays = counters.shadow_rays
                logs = [(a, list(a.log)) for a in rec]
                for a in rec:
                    a.record = False
                continue
            best = min(best, time.perf_counter() - t0)
            t0 = time.perf_counter()
            for a, log in logs:
                for o, d, t in log:
                    a._scene.run(o, d, dists=t.copy(), query="OCCLUDED")
            raw = min(raw, time.perf_counter() - t0)
        rows.append((name, tris, len(hit.p), n_rays, n_rays / best, n_rays / raw, raw / best, prep))
    print(f"engine: {os.path.abspath(args.root)}")
    if compile_s is not None:
        print(f"kernel warm-up (compile or cache load): {compile_s:.2f} s")
    print(f"{'scene':8s} {'triangles':>10s} {'hits':>8s} {'shadow rays':>11s} "
          f"{'stage rays/s':>13s} {'raw rays/s':>12s} {'stage/raw':>9s}")
    for name, tris, nh, nr, st, rw, ratio, prep in rows:
        print(f"{name:8s} {tris:10,d} {nh:8,d} {nr:11,d} {st/1e6:11.2f} M {rw/1e6:10.2f} M "
              f"{100*ratio:8.1f} %")


if __name__ == "__main__":
    main()
