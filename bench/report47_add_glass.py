"""Add(Transparent, smooth Glass) on the sweep's sphere (bench/bench_add_shader_sweep.py)
against the closures' sum, per Max Bounces (docs/accuracy.md, report47).

    PYTHONPATH=. .venv/bin/python bench/report47_add_glass.py ENGINE SPP [--res 32]
        [--bounces 1 3 8] [--pixel COL ROW] [--seeds 0 1]

ENGINE: CYCLES or PHOTONMAP. White Transparent and white Glass (roughness 0, IOR 1.5),
a uniform world of 0.5. Prints per bounce limit the image mean, and the mean and median
of ours-or-Cycles over the sum on the pixels whose unbent ray is totally reflected at
the far wall (b > 1 / 1.5 of the radius) and the mean on the rest. --pixel: render only
that pixel (a border render; row 0 at the top) at each seed and print it beside the sum.
The sum is tests/blender/test_add_transparent_cycles.py's _closure_sum_image.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (ROOT, os.path.join(ROOT, "tests", "blender"), os.path.join(ROOT, "bench")):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("engine", choices=("CYCLES", "PHOTONMAP"))
    ap.add_argument("spp", type=int)
    ap.add_argument("--res", type=int, default=32)
    ap.add_argument("--bounces", type=int, nargs="+", default=[1, 3, 8])
    ap.add_argument("--pixel", type=int, nargs=2, default=None)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    a = ap.parse_args()
    import bpy
    import addon
    addon.register()
    from bench_add_shader_sweep import _node, join, sphere_scene, surface_material
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    from test_add_transparent_cycles import _closure_sum_image
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    mat = surface_material(bpy, "Pair", lambda nd, ln: join(
        nd, ln, _node(nd, "ShaderNodeBsdfTransparent", Color=(1.0, 1.0, 1.0)),
        _node(nd, "ShaderNodeBsdfGlass", Color=(1.0, 1.0, 1.0), Roughness=0.0)))
    res = a.res
    sphere_scene(bpy, scene, mat, res)
    xs = (np.arange(res) + 0.5) / res * 1.2 - 0.6
    tir = np.hypot(xs[None, :], xs[:, None]) > 1.0 / 1.5
    if a.pixel is not None:
        col, row = a.pixel
        r = scene.render
        r.use_border, r.use_crop_to_border = True, False
        r.border_min_x, r.border_max_x = col / res, (col + 1) / res
        r.border_max_y, r.border_min_y = 1 - row / res, 1 - (row + 1) / res
    tmp = tempfile.mkdtemp()
    for m in a.bounces:
        c = cycles_plain(scene, a.spp, m)
        c.glossy_bounces = c.transmission_bounces = c.diffuse_bounces = m
        c.transparent_max_bounces = 8
        c.caustics_reflective = c.caustics_refractive = True
        c.pixel_filter_type, c.filter_width = "BOX", 1.0
        scene.render.engine = a.engine
        if a.engine == "PHOTONMAP":
            cheap(scene, spp=a.spp, photons=50_000, caustic_photons=20_000)
        want = _closure_sum_image((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), res, m, sub=6).mean(-1)
        for seed in a.seeds:
            c.seed = seed
            if a.engine == "PHOTONMAP":
                scene.photonmap.seed = seed
            img = read_rgba(bpy, render_exr(bpy, scene, os.path.join(tmp, "x.exr")))
            img = img[..., :3].mean(-1)
            if a.pixel is not None:
                print(f"{a.engine} {a.spp} spp, {m} bounces, seed {seed}: pixel "
                      f"{img[row, col]:.3f}, the sum {want[row, col]:.3f}", flush=True)
                continue
            ratio = img[tir] / want[tir]
            print(f"{a.engine} {a.spp} spp, {m} bounces, seed {seed}: mean {img.mean():.4f} "
                  f"(the sum {want.mean():.4f}); totally reflecting pixels "
                  f"{img[tir].mean() / want[tir].mean():.3f} (median "
                  f"{np.median(ratio):.3f}, max pixel {img.max():.1f}), the rest "
                  f"{img[~tir].mean() / want[~tir].mean():.4f}", flush=True)


if __name__ == "__main__":
    main()
