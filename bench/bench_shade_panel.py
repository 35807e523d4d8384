"""The panel lit through a Translucent BSDF lamp shade, ours against Cycles at equal CPU time
(issue 14, shade32): tests/blender/test_translucent_shade_cycles.py's scene (a 100 W point
lamp of radius 0.05 m in an open cylinder shade, a white Diffuse panel the camera sees,
black world, 48 x 36). Per run: CPU seconds of the render call (all threads), the image
mean / the reference's, relMSE, and the smoothness of the panel: its 8 x 8 pixel blocks
divided by the reference's, max / min and standard deviation over the blocks
brighter than a quarter of the brightest (the panel's far edge is dark). The reference: Cycles
(--ref-spp, default 16384, seed 0); the runs use seed 1.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_shade_panel.py [--ours 4,16,64]
        [--cycles 64,256,1024,4096] [--ref-spp 16384] [--ref REF.exr]
        [--shade translucent|glass] [--shadelight on|off]

--shade glass: tests/blender/test_rough_glass_shade_cycles.py's shade instead (Principled,
Transmission 1, roughness 0.5, Multiscatter GGX; roughshade33). --shadelight off: the
light through the shade by caustic photons alone (engine.shadelight.ENABLED), as main
before shade32 / roughshade33.

--ref: the reference's EXR, rendered and saved there when the file is missing (to
compare two checkouts against one reference).
"""
import argparse
import os
import resource
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))


def run(bpy, engine, spp, seed, path, shade="translucent"):
    """(image (H,W) grey, CPU seconds of the render call)."""
    from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
    if shade == "glass":
        from test_rough_glass_shade_cycles import _shade_scene
        scene = _shade_scene(bpy, 0.5, "MULTI_GGX")
    else:
        from test_translucent_shade_cycles import _shade_scene, _translucent
        scene = _shade_scene(bpy, 0.0, "GGX", shade=_translucent)
    c = cycles_plain(scene, spp, 12)
    c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 4, 4, 12
    c.seed = seed
    scene.render.engine = engine
    if engine == "PHOTONMAP":
        pm = default_photonmap(scene)
        pm.spp, pm.seed = spp, seed
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    img = read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean(axis=2)
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    return img, (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)


def blocks(img):
    h, w = (img.shape[0] // 8) * 8, (img.shape[1] // 8) * 8
    return img[:h, :w].reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ours", default="4,16,64")
    ap.add_argument("--cycles", default="64,256,1024,4096")
    ap.add_argument("--ref-spp", type=int, default=16384)
    ap.add_argument("--ref")
    ap.add_argument("--shade", default="translucent", choices=("translucent", "glass"))
    ap.add_argument("--shadelight", default="on", choices=("on", "off"))
    a = ap.parse_args()
    from engine import shadelight
    shadelight.ENABLED = a.shadelight == "on"
    import bpy  # noqa: F401
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="shade_panel_")
    if a.ref and os.path.exists(a.ref):
        from blender_helpers import read_rgba
        ref = read_rgba(bpy, a.ref)[..., :3].mean(axis=2)
        print(f"reference: {a.ref}")
    else:
        ref, cpu = run(bpy, "CYCLES", a.ref_spp, 0, a.ref or os.path.join(tmp, "ref.exr"),
                       a.shade)
        print(f"reference: Cycles {a.ref_spp} spp, {cpu:.1f} CPU s")
    rb = blocks(ref)
    # The panel's lit blocks (its far edge, beyond the first block column, is dark).
    lit = rb > 0.25 * rb.max()
    print("| run | CPU s | mean / ref | relMSE | 8x8 blocks / ref: max / min | std |")
    print("|---|---|---|---|---|---|")
    rows = [("ours", s) for s in a.ours.split(",") if s] + [
        ("Cycles", s) for s in a.cycles.split(",") if s]
    for who, s in rows:
        img, cpu = run(bpy, "PHOTONMAP" if who == "ours" else "CYCLES", int(s), 1,
                       os.path.join(tmp, f"{who}_{s}.exr"), a.shade)
        b = (blocks(img) / rb)[lit]
        rel = float(np.mean((img - ref) ** 2 / (ref ** 2 + 0.01)))
        print(f"| {who} {s} spp | {cpu:.1f} | {img.mean() / ref.mean():.4f} | {rel:.5f} | "
              f"{b.max() / b.min():.4f} | {b.std() / b.mean():.4f} |", flush=True)


if __name__ == "__main__":
    main()
