"""The cloud cube of tests/blender/test_heterogeneous_cycles.py (a Noise -> Color Ramp ->
Multiply density under a spot; hetvol39, docs/compatibility.md) against live Cycles 5.0:
ours with the density field, ours with the field's homogeneous stand-in alone (the
ratio-tracking correction and the scatter weights' field switched off), ours at density 1
(the Density socket's own value: what rendered before hetvol39), and ours and Cycles at
equal samples, as bright-block ratios to a Cycles reference.

    PYTHONPATH=$PWD .venv/bin/python tools/hetvol_cycles.py            # direct light
    VB=4 PYTHONPATH=$PWD .venv/bin/python tools/hetvol_cycles.py       # Volume bounces 4
    COORDS=Object PYTHONPATH=$PWD .venv/bin/python tools/hetvol_cycles.py

Env: VB (Volume bounces; > 0: Max Bounces 8 and photon mapping on), COORDS (Generated /
Object), SPP (ours, default 512), REF (Cycles' reference spp, default 2048), EQUAL (the
equal-samples list, default 64,128,256; empty: none). Prints one line per render.
"""
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))

VB = int(os.environ.get("VB", "0"))
COORDS = os.environ.get("COORDS", "Generated")
SPP = int(os.environ.get("SPP", "512"))
REF = int(os.environ.get("REF", "2048"))
EQUAL = [int(s) for s in os.environ.get("EQUAL", "64,128,256").split(",") if s]


def stats(a, b, n):
    """n x n bright blocks (luminance above 0.2 x the brightest) of a against b: their
    ratios' range and mean |r - 1|, and the image sums' ratio."""
    import test_heterogeneous_cycles as T
    A, B = T._blocks(a, n), T._blocks(b, n)
    lum = B @ np.array([0.2126, 0.7152, 0.0722])
    bright = lum > 0.2 * lum.max()
    r = (A / np.maximum(B, 1e-9))[bright][:, 1]
    return (f"{n}x{n} bright blocks {bright.sum()}: {r.min():.3f}-{r.max():.3f}, mean |r-1| "
            f"{np.abs(r - 1).mean():.3f}; sum {a.sum() / b.sum():.4f}")


def render(bpy, scene, path, engine, spp):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    c = cycles_plain(scene, spp, 8 if VB else 0)
    c.volume_bounces = VB
    if engine != "CYCLES":
        cheap(scene, spp=spp, photons=200_000)
        scene.photonmap.photon_mapping = bool(VB)
    t = time.time()
    img = read_rgba(bpy, render_exr(bpy, scene, path))[..., :3]
    return img, time.time() - t


def main():
    import bpy
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    import engine.heterogeneous as H
    import engine.photonmedium as PM
    import test_heterogeneous_cycles as T
    out = tempfile.mkdtemp(prefix="hetvol_cycles-")
    scene = T._scene(bpy, COORDS)
    ref, sec = render(bpy, scene, os.path.join(out, "ref.exr"), "CYCLES", REF)
    print(f"VB {VB}, {COORDS}: Cycles {REF} spp {sec:.1f} s (reference)", flush=True)
    img, sec = render(bpy, scene, os.path.join(out, "ours.exr"), "PHOTONMAP", SPP)
    for n in (4, 8):
        print(f"ours {SPP} spp {sec:.1f} s: {stats(img, ref, n)}", flush=True)
    saved = (H.HeterogeneousMedia.correction, H.HeterogeneousMedia.scatter_weights)
    try:
        H.HeterogeneousMedia.correction = lambda self, o, d, t, salt=0: np.ones((len(o), 3))
        H.HeterogeneousMedia.scatter_weights = lambda self, o, d, p, m, w: w
        img, sec = render(bpy, scene, os.path.join(out, "mean.exr"), "PHOTONMAP", SPP)
        print(f"ours, the mean density's stand-in alone: {stats(img, ref, 8)}", flush=True)
    finally:
        H.HeterogeneousMedia.correction, H.HeterogeneousMedia.scatter_weights = saved
    if VB:
        saved_init = PM.PhotonScattering.__init__

        def no_flights(self, *a, **k):
            saved_init(self, *a, **k)
            type(self).hetero = property(lambda s: None, lambda s, v: None)
        try:
            PM.PhotonScattering.__init__ = no_flights
            img, sec = render(bpy, scene, os.path.join(out, "flights.exr"), "PHOTONMAP", SPP)
            print(f"ours, the photons' free flights at the mean: {stats(img, ref, 8)}",
                  flush=True)
        finally:
            PM.PhotonScattering.__init__ = saved_init
            if isinstance(PM.PhotonScattering.__dict__.get("hetero"), property):
                del PM.PhotonScattering.hetero
    saved_scene = H.HeterogeneousMedia.for_scene
    try:
        H.HeterogeneousMedia.for_scene = classmethod(lambda cls, g, t, s=0: None)
        img, sec = render(bpy, scene, os.path.join(out, "one.exr"), "PHOTONMAP", SPP)
        print(f"ours at density 1 (before hetvol39): {stats(img, ref, 8)}", flush=True)
    finally:
        H.HeterogeneousMedia.for_scene = saved_scene
    for spp in EQUAL:
        a, ta = render(bpy, scene, os.path.join(out, f"o{spp}.exr"), "PHOTONMAP", spp)
        b, tb = render(bpy, scene, os.path.join(out, f"c{spp}.exr"), "CYCLES", spp)
        print(f"{spp} spp: ours {ta:.1f} s {stats(a, ref, 8)} | Cycles {tb:.1f} s "
              f"{stats(b, ref, 8)}", flush=True)


if __name__ == "__main__":
    main()
