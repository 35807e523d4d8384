"""percost54's cuts on and off in one process (docs/performance.md "percost54"): a .blend
(or an example blend's name) exported once through the add-on, then rendered alternately
as on main (coincident's normals through geo.ng on every read, a k-NN call per camera
count in chaincounts.subset_irradiance, DiffusePdf.reject_for's test in numpy) and as on
this branch, at its saved settings,
one thread; prints each render's camera-pass CPU s (engine.render's stage clock read as
process CPU), the film's hash (the same bits both ways), then each variant's minimum
and the ratio. Alternating in one process puts both variants under the same load.

    PYTHONPATH=$PWD .venv/bin/python bench/percost54_ab.py FILE.blend [--percent 50]
        [--repeat 3]
"""
import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = r"""
import hashlib, os, sys, time
ROOT, BLEND, PERCENT, REPEAT = sys.argv[1:5]
import bpy
bpy.ops.wm.open_mainfile(filepath=BLEND if BLEND.endswith(".blend")
                         else os.path.join(ROOT, "example_blends", BLEND + ".blend"))
sys.path.insert(0, ROOT)
import numpy as np
import addon
import engine
import engine.jit as jit
jit.ensure_compiled()
import engine.chaincounts as cc
import engine.coincident as co
import engine.glossysplit as gs
from engine.photonlayout import vectors
er = sys.modules["engine.render"]


class _CpuClock:
    perf_counter = staticmethod(time.process_time)

    def __getattr__(self, name):
        return getattr(time, name)


er.time = _CpuClock()
ng, estimate, reject_for = (co.CoincidentSurfaces._ng, cc._estimate_counts,
                            gs.DiffusePdf.reject_for)


def numpy_reject_for(self, pmap, sel):
    # main's DiffusePdf.reject_for: the test in numpy, block by block
    ph = pmap.photons
    stored = getattr(ph, "blur_pdf", None)
    sel = np.asarray(sel, np.int64)

    def block(rows, photons):
        r = np.take(sel, rows)
        out = np.ones(len(r), bool)
        test = np.flatnonzero(np.take(self.largest, r) >= self.fg)
        if len(test):
            pid = np.take(photons, test)
            wi = -vectors(ph.direction, pid)
            wi /= np.maximum(np.linalg.norm(wi, axis=1), 1e-300)[:, None]
            pd = self.pdf(r[test], wi)
            if stored is not None:
                pd = np.minimum(pd, np.take(stored, pid).astype(np.float64))
            out[test] = ~(pd >= self.fg)
        return out

    # (main's block of pairs at the time: glossysplit.REJECT_BLOCK, gone since percost55
    # made the test one kernel call)
    step = 1 << 14

    def reject(rows, photons):
        out = np.empty(len(rows), bool)
        for a in range(0, len(rows), step):
            out[a:a + step] = block(rows[a:a + step], photons[a:a + step])
        return out
    return reject


def variant(on):
    co.CoincidentSurfaces._ng = ng if on else (lambda self, tri: self.geo.ng[tri])
    cc._estimate_counts = estimate if on else (lambda *a, **k: None)
    gs.DiffusePdf.reject_for = reject_for if on else numpy_reject_for


render = engine.render


def rendered(scene, settings=None, progress=None, **k):
    k.pop("should_cancel", None)  # (one thread, inline)
    film = None
    for _ in range(int(REPEAT)):
        for name, on in (("main", False), ("percost54", True)):
            variant(on)
            film = render(scene, settings, **k)
            h = hashlib.sha1()
            for p in ("direct", "indirect", "caustic", "specular", "emission"):
                h.update(np.ascontiguousarray(getattr(film, p)).tobytes())
            print("ROW", name, film.stats["time_camera"], h.hexdigest()[:8],
                  os.getloadavg()[0], flush=True)
    return film


engine.render = rendered
addon.register()
sc = bpy.context.scene
sc.render.engine = "PHOTONMAP"
sc.render.resolution_percentage = int(sc.render.resolution_percentage * int(PERCENT) / 100)
sc.photonmap.threads = 1
print("SPP", sc.photonmap.spp, flush=True)
bpy.ops.render.render(write_still=False)
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("blend")
    ap.add_argument("--percent", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    out = subprocess.run([sys.executable, "-c", CHILD, HERE, a.blend, str(a.percent),
                          str(a.repeat)], env=dict(os.environ, PYTHONPATH=HERE), cwd=HERE,
                         capture_output=True, text=True)
    rows = [line.split()[1:] for line in out.stdout.splitlines() if line.startswith("ROW")]
    spp = [int(line.split()[1]) for line in out.stdout.splitlines() if line.startswith("SPP")]
    if not rows:
        sys.exit(out.stdout[-2000:] + out.stderr[-3000:])
    name = os.path.basename(a.blend)
    print("| blend | variant | load | camera CPU s | per frame sample | film |")
    print("|---|---|---:|---:|---:|---|")
    for v, cam, film, load in rows:
        print(f"| {name} | {v} | {float(load):.1f} | {float(cam):.2f} | "
              f"{float(cam) / spp[0]:.3f} | {film} |")
    best = {v: min(float(c) for w, c, _, _ in rows if w == v) for v in ("main", "percost54")}
    print(f"\nminimum: main {best['main']:.2f}, percost54 {best['percost54']:.2f} CPU s "
          f"({best['percost54'] / best['main']:.3f}x); films "
          + ("the same" if len({r[2] for r in rows}) == 1 else "DIFFER"))


if __name__ == "__main__":
    main()
