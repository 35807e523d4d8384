"""A lamp with Diffuse visibility off (lampvis51, issue 14): its highlight's noise and
brightness, ours with and without the rough reflective lobes' shadow rays for it
(integrator.REFLECTION_ONLY_SAMPLING) against Cycles at equal samples.
Scene: tests/blender/test_light_lobe_visibility_cycles.py's (a grey Principled floor of
roughness 0.3 under an area lamp of 0.5 m, or a point lamp of radius 0.1 (sphere), 40 x
30, direct light only: ours photon mapping off, Cycles Max Bounces 0).
Per row: the pixel variance a sample (each pixel's variance over seeds 0..SEEDS-1 times
spp, averaged over the pixels), its ratio to Cycles', the image mean over Cycles' at
REF_SPP (mean and sd over the seeds), CPU seconds a render.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_lampvis51.py [SPP [SEEDS [REF_SPP]]]

References are cached in /tmp/lampvis51/ref-<case>-<REF_SPP>.npy.
"""
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
import numpy as np  # noqa: E402
import bpy  # noqa: E402
import addon  # noqa: E402
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cheap, cycles_plain, read_rgba, render_exr  # noqa: E402
import test_light_lobe_visibility_cycles as L  # noqa: E402
from engine import integrator as EI  # noqa: E402

SPP = int(sys.argv[1]) if len(sys.argv) > 1 else 64
SEEDS = int(sys.argv[2]) if len(sys.argv) > 2 else 8
REF_SPP = int(sys.argv[3]) if len(sys.argv) > 3 else 8192
CASES = os.environ.get("LAMPVIS_CASES", "AREA no_diffuse,POINT_R no_diffuse,AREA both")
TMP = "/tmp/lampvis51"
os.makedirs(TMP, exist_ok=True)


def build(case):
    kind, vis = case.split()
    scene, lamp = L._scene(bpy, "POINT" if kind == "POINT_R" else kind)
    if kind == "POINT_R":
        lamp.data.shadow_soft_size = 0.1
    lamp.visible_diffuse = vis != "no_diffuse"
    lamp.visible_glossy = vis != "no_glossy"
    return scene


def render(scene, engine, spp, seed):
    scene.render.engine = engine
    cycles_plain(scene, spp, 0).seed = seed
    if engine != "CYCLES":
        cheap(scene, spp=spp, photons=2_000, caustic_photons=0)
        scene.photonmap.photon_mapping = False
        scene.photonmap.seed = seed
    t = time.process_time()
    img = read_rgba(bpy, render_exr(bpy, scene, os.path.join(TMP, "bench.exr")))[..., :3]
    return img.astype(np.float64), time.process_time() - t


print("| case | renderer | spp | pixel variance a sample | / Cycles' | mean / ref (sd) | CPU s |")
print("|---|---|---|---|---|---|---|")
for case in CASES.split(","):
    scene = build(case)
    ref_file = os.path.join(TMP, f"ref-{case.replace(' ', '_')}-{REF_SPP}.npy")
    if os.path.exists(ref_file):
        ref = np.load(ref_file)
    else:
        ref = render(scene, "CYCLES", REF_SPP, 12345)[0]
        np.save(ref_file, ref)
    cyc_var = None
    for name, engine, switch in (("Cycles", "CYCLES", None),
                                 ("ours, continuation only (before)", "PHOTONMAP", False),
                                 ("ours, shadow rays + MIS (after)", "PHOTONMAP", True)):
        if switch is not None:
            EI.REFLECTION_ONLY_SAMPLING = switch
        imgs, secs = [], []
        for seed in range(SEEDS):
            img, sec = render(scene, engine, SPP, seed + (1 if engine == "CYCLES" else 0))
            imgs.append(img)
            secs.append(sec)
        imgs = np.stack(imgs)
        var = float(imgs.var(axis=0, ddof=1).mean() * SPP)
        cyc_var = var if cyc_var is None else cyc_var
        means = imgs.mean(axis=(1, 2, 3)) / ref.mean()
        print(f"| {case} | {name} | {SPP} | {var:.5f} | {var / cyc_var:.2f} | "
              f"{means.mean():.4f} ({means.std(ddof=1):.4f}) | {np.mean(secs):.2f} |",
              flush=True)
EI.REFLECTION_ONLY_SAMPLING = True
