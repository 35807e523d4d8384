"""Where the glass of water's photons go at smooth-shaded glass sides (smoothglass43).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_smooth_glass_photons.py
        [--angle 30] [--water] [--caustic-photons 200000] [--photons 20000]

Renders tests/blender/test_glass_of_water_cycles.py's scene (the empty glass unless
--water; flat and smooth sides) with ours, watching photonkernels.scatter's inputs (its
rules are not changed): prints two Markdown tables.

1. Caustic photons reaching the table under the glass (the camera's view: |x|, |y| <
   0.2 m) by the glass faces they crossed (outer side, inner side, caps), count and
   power (W, the mean of RGB), flat against smooth.
2. Smooth sides only: the photon power (W, every shot) arriving at each side face, from
   the air or from inside the glass, and what scatter does with it in expectation (a
   numpy replica of the smooth glass rule before engine/glassadjoint.py, for comparison:
   Fresnel at the shading normal, which falls back to the geometric one where the photon
   arrives below it ("guard"); refracted,
   reflected, dropped because the reflection leaves below Ng or the refraction above it).

docs/accuracy.md, smoothglass43, gives the numbers measured.
"""
import argparse
import collections
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy  # noqa: E402
import addon  # noqa: E402
addon.register()
import engine.photonkernels as pk  # noqa: E402
from blender_helpers import cheap  # noqa: E402
from test_glass_of_water_cycles import _mean, _scene  # noqa: E402

FACES = ("outer", "inner", "cap")
INNER_RADIUS = 0.3849  # between the glass's inner (0.37 m) and outer (0.4 m) sides
VIEW = 0.2  # half the camera's orthographic width (m)


def _fresnel(c, eta):
    """Unpolarised dielectric Fresnel at cosine c (N,), eta = n_far / n_near; (F, cos_t,
    total internal reflection) (N,) each."""
    s2 = (1.0 - c * c) / (eta * eta)
    tir = s2 >= 1.0
    ct = np.sqrt(np.maximum(1.0 - s2, 0.0))
    rs = (c - eta * ct) / (c + eta * ct)
    rp = (eta * c - ct) / (eta * c + ct)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp)), ct, tir


class Watch:
    """Wraps photonkernels.scatter: per-path face history, arrivals in view, fates."""

    def __init__(self):
        self.history = {}
        self.arrive = collections.defaultdict(float)
        self.count = collections.defaultdict(int)
        self.fate = collections.defaultdict(float)
        self.real = pk.scatter

    def __call__(self, *a, **k):
        bounce, d, power, slot, geom, prim, starts = a[1], a[2], a[3], a[6], a[8], a[9], a[10]
        u, v, v0, e1, e2, cn, material = a[11], a[12], a[13], a[14], a[15], a[16], a[17]
        glass_rows = np.asarray(a[31]).astype(np.int8) == pk.SMOOTH_GLASS
        mat_ior, caustic_shot = a[32], bool(a[37])
        if bounce == 0:
            self.history.clear()
        idx = np.nonzero(np.asarray(geom[:geom.shape[0]]) >= 0)[0]
        tri = starts[geom[idx]] + prim[idx]
        b1, b2 = u[idx].astype(float), v[idx].astype(float)
        p = v0[tri] + b1[:, None] * e1[tri] + b2[:, None] * e2[tri]
        g = np.cross(e1[tri].astype(float), e2[tri].astype(float))
        g /= np.linalg.norm(g, axis=1)[:, None]
        glass = glass_rows[material[tri]]
        face = np.where(np.abs(g[:, 2]) > 0.9, 2,
                        np.where(np.hypot(p[:, 0], p[:, 1]) > INNER_RADIUS, 0, 1))
        for j in range(len(idx)):
            s = int(slot[idx[j]])
            if glass[j]:
                self.history[s] = self.history.get(s, 0) | (1 << face[j])
            elif (caustic_shot and abs(p[j, 0]) < VIEW and abs(p[j, 1]) < VIEW
                  and p[j, 2] < 0.0005):
                mask = self.history.get(s, 0)
                label = "+".join(FACES[b] for b in range(3) if mask >> b & 1) or "none"
                self.arrive[label] += float(power[idx[j]].mean())
                self.count[label] += 1
        if cn.shape[0]:
            self._fates(d[idx], power[idx].mean(1), g, tri, b1, b2, cn, material, mat_ior,
                        face, glass & (face < 2))
        return self.real(*a, **k)

    def _fates(self, d, pw, g, tri, b1, b2, cn, material, mat_ior, face, side):
        d, pw, g, tri, b1, b2 = d[side], pw[side], g[side], tri[side], b1[side], b2[side]
        f = face[side]
        front = (d * g).sum(1) < 0.0
        sign = np.where(front, 1.0, -1.0)[:, None]
        g = g * sign
        c3 = cn[tri].astype(float)
        n = ((1.0 - b1 - b2)[:, None] * c3[:, 0] + b1[:, None] * c3[:, 1]
             + b2[:, None] * c3[:, 2])
        n = n / np.linalg.norm(n, axis=1)[:, None] * sign
        guard = -(d * n).sum(1) <= 1e-6
        n = np.where(guard[:, None], g, n)
        c = -(d * n).sum(1)
        ior = mat_ior[material[tri]]
        eta = np.where(front, ior, 1.0 / ior)
        F, ct, tir = _fresnel(c, eta)
        r = d + 2.0 * c[:, None] * n
        t = (d / eta[:, None]) + (c / eta - ct)[:, None] * n
        r_bad = (r * g).sum(1) <= 0.0
        t_bad = ((t * g).sum(1) >= 0.0) & ~tir
        for name, sel in (("outer, from air", front & (f == 0)),
                          ("outer, from glass", ~front & (f == 0)),
                          ("inner, from air", front & (f == 1)),
                          ("inner, from glass", ~front & (f == 1))):
            for what, val in (("power", pw), ("guard", pw * guard),
                              ("refracted", pw * (1 - F) * ~t_bad * ~tir),
                              ("reflected", pw * F * ~r_bad),
                              ("dropped: reflection below Ng", pw * F * r_bad),
                              ("dropped: refraction above Ng", pw * (1 - F) * t_bad)):
                self.fate[(name, what)] += float(val[sel].sum())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--angle", type=float, default=30.0)
    ap.add_argument("--water", action="store_true")
    ap.add_argument("--photons", type=int, default=20_000)
    ap.add_argument("--caustic-photons", type=int, default=200_000)
    args = ap.parse_args()
    watches = {}
    for shading in ("flat", "smooth"):
        w = watches[shading] = Watch()
        pk.scatter = w
        try:
            bpy.ops.wm.read_homefile(use_empty=True)
            scene = bpy.context.scene
            _scene(bpy, scene, shading, args.angle, args.water)
            cheap(scene, spp=1, photons=args.photons, caustic_photons=args.caustic_photons)
            scene.photonmap.seed = 0
            scene.photonmap.threads = 1  # one path history at a time (Watch.history)
            with tempfile.TemporaryDirectory() as tmp:
                w.mean = _mean(bpy, scene, os.path.join(tmp, "o.exr"), "PHOTONMAP")
        finally:
            pk.scatter = w.real
    print(f"\nsun {args.angle:g} deg, {'glass of water' if args.water else 'empty glass'}, "
          f"{args.caustic_photons} caustic photons; image mean flat "
          f"{watches['flat'].mean:.4f}, smooth {watches['smooth'].mean:.4f}\n")
    print("| faces crossed | flat: photons | flat: W | smooth: photons | smooth: W |")
    print("|---|---:|---:|---:|---:|")
    labels = sorted(set(watches["flat"].arrive) | set(watches["smooth"].arrive),
                    key=lambda k: -watches["flat"].arrive.get(k, 0.0))
    for lab in labels:
        f, s = watches["flat"], watches["smooth"]
        print(f"| {lab} | {f.count.get(lab, 0)} | {f.arrive.get(lab, 0.0):.4f} | "
              f"{s.count.get(lab, 0)} | {s.arrive.get(lab, 0.0):.4f} |")
    fate = watches["smooth"].fate
    whats = ("power", "guard", "refracted", "reflected", "dropped: reflection below Ng",
             "dropped: refraction above Ng")
    print("\n| smooth side hit | " + " | ".join(whats) + " |")
    print("|---|" + "---:|" * len(whats))
    for name in ("outer, from air", "outer, from glass", "inner, from air",
                 "inner, from glass"):
        print(f"| {name} | " + " | ".join(f"{fate[(name, w)]:.3f}" for w in whats) + " |")


if __name__ == "__main__":
    main()
