"""Textured volume emission (volemit40, issue 14): the distances per segment
(engine/volumefields.py EMISSION_SAMPLES) against noise and time.

  slab   tests/test_volume_fields.py's "fire" slab (density and emission one ramp 4z,
         sigma_a (0.5, 1, 2) at density 1), 32 x 32 px x 16 spp, photon mapping off:
         per-pixel relative std against the closed form E0 (1 - exp(-sigma_a 4 H^2/2)) /
         sigma_a, the image mean over it, seconds (cheap tracking: a 0.5 m slab)
  cloud  tests/blender/test_volume_fields_cycles.py's glowing Noise cloud (Density 3 x,
         Emission Strength 4 x one ramp of a Noise), 64 x 48, full transport (Max Bounces
         4, Volume bounces 0), ours SPP against Cycles REF_SPP (rendered once): relMSE,
         seconds, relMSE x seconds (--cloud; needs bpy)

    PYTHONPATH=$PWD .venv/bin/python bench/bench_volume_fields.py [--cloud [SPP [REF_SPP]]]

Measured (2 shared cores, s40): slab 1 / 2 / 4 / 8 distances: std 0.173 / 0.082 / 0.054 /
0.047 in 0.51 / 0.63 / 0.72 / 1.22 s; cloud at 64 spp against Cycles 1024: relMSE 0.0089 /
0.0063 / 0.0053 / 0.0045 in 4.9 / 7.4 / 13.2 / 17.9 s (each distance ratio-tracks its own
transmittance: the tracking dominates). Default 2.
"""
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))
import numpy as np  # noqa: E402

from engine import volumefields  # noqa: E402

COUNTS = (1, 2, 4, 8)


def slab():
    import test_volume_fields as t
    from engine.shadernodes import VectorMath
    expect = t.E0 * -np.expm1(-t.SIGMA_A * t.A * t.H ** 2 / 2) / t.SIGMA_A
    print(f"{'slab':8s} {'N':>3s} {'seconds':>8s} {'rel. std':>9s}  mean / closed form")
    t._image(t._slab(absorption=t.SIGMA_A, density=t._ramp(), width=4), spp=1)  # (warm)
    for n in COUNTS:
        volumefields.EMISSION_SAMPLES = n
        scene = t._slab(absorption=t.SIGMA_A, density=t._ramp(), width=32,
                        emission_texture=VectorMath("MULTIPLY", t._ramp(), t.E0))
        t0 = time.time()
        img = t._image(scene, spp=16)
        dt = time.time() - t0
        rel = img / expect - 1
        print(f"{'':8s} {n:3d} {dt:8.2f} {rel.std():9.4f}  "
              f"{np.round(img.reshape(-1, 3).mean(axis=0) / expect, 4)}")


def cloud(spp, ref_spp):
    sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
    import bpy
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    import test_volume_fields_cycles as t
    tmp = "/tmp/volemit40-bench"
    os.makedirs(tmp, exist_ok=True)
    scene = t._scene(bpy, "glow")
    ref = t._render(bpy, scene, os.path.join(tmp, "cycles.exr"), "CYCLES", ref_spp, 4)
    t._render(bpy, scene, os.path.join(tmp, "warm.exr"), "PHOTONMAP", 4, 4)
    print(f"{'cloud':8s} {'N':>3s} {'seconds':>8s} {'relMSE':>9s} {'x seconds':>10s}")
    for n in COUNTS:
        volumefields.EMISSION_SAMPLES = n
        t0 = time.time()
        img = t._render(bpy, scene, os.path.join(tmp, f"n{n}.exr"), "PHOTONMAP", spp, 4)
        dt = time.time() - t0
        rel = float(np.mean((img - ref) ** 2 / (ref ** 2 + 0.01)))
        print(f"{'':8s} {n:3d} {dt:8.2f} {rel:9.5f} {rel * dt:10.5f}", flush=True)


if __name__ == "__main__":
    if "--cloud" in sys.argv:
        rest = [a for a in sys.argv[1:] if a != "--cloud"]
        cloud(int(rest[0]) if rest else 64, int(rest[1]) if len(rest) > 1 else 1024)
    else:
        slab()
