"""Principled Hair BSDF on hair against live Cycles: prints a table (docs/accuracy.md,
hairbsdf37).

    .venv/bin/python bench/bench_hair_bsdf_cycles.py [--strands 400] [--modes a,b]
        [--cycles-spp 256] [--spp 32] [--shape RIBBONS|THICK] [--fallback]

The lead's tuft (tests/blender/test_hair_cycles.py `_tuft`: a sun from the camera's side,
a grey floor, 96 x 72, Ribbons), its material a Principled Hair BSDF of each mode; with
--strands N other than 400, N thinner strands (radius 6 -> 2 mm) on the same patch.
Columns: whole-image luminance ratio ours / Cycles, the tuft's 12 x 12-pixel blocks (rows
1-3, columns 2-5) min / max / mean ratio, and the tuft's mean R / G / B ratio.
--fallback renders the node as main did before hairbsdf37 (a Diffuse BSDF of its Color).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))

from test_hair_bsdf_cycles import MODES as TEST_MODES  # noqa: E402

# The test's modes, and two the tests leave out.
MODES = {
    **TEST_MODES,
    "absorb": {"parametrization": "ABSORPTION", "Absorption Coefficient": (0.2, 0.6, 1.5)},
    "huang": {"model": "HUANG", "parametrization": "MELANIN", "Melanin": 0.4,
              "Melanin Redness": 0.4},
}
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def groom(bpy, sc, n):
    """Replace the tuft's strands by n thinner ones on the same patch (seeded)."""
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends
    make_blends.tuft("Groom", bpy.data.materials["Hair"], count=n, keys=5, spread=0.8,
                     height=0.6, lean=0.15, radius=(0.006, 0.002), seed=5)
    bpy.data.objects.remove(bpy.data.objects["Tuft"])


def run(bpy, mode, strands, spp_cycles, spp, out_dir, shape="RIBBONS"):
    from blender_helpers import cycles_plain, read_rgba, render_exr
    from test_hair_bsdf_cycles import _hair_node
    from test_hair_cycles import _tuft
    sc = _tuft(bpy, shape)
    if strands != 400:
        groom(bpy, sc, strands)
    _hair_node(bpy, MODES[mode])
    sc.render.engine = "CYCLES"
    cycles_plain(sc, spp_cycles, 12)
    sc.cycles.sample_clamp_indirect = 10.0
    t0 = time.time()
    ref = read_rgba(bpy, render_exr(bpy, sc, os.path.join(out_dir, "cycles.exr")))[..., :3]
    t1 = time.time()
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = spp
    ours = read_rgba(bpy, render_exr(bpy, sc, os.path.join(out_dir, "ours.exr")))[..., :3]
    t2 = time.time()

    def blocks(img):
        return img.reshape(6, 12, 8, 12).mean(axis=(1, 3))
    hair = (blocks(ours @ LUMINANCE) / blocks(ref @ LUMINANCE))[1:4, 2:6]
    rgb = ours[18:48, 24:72].mean(axis=(0, 1)) / ref[18:48, 24:72].mean(axis=(0, 1))
    whole = (ours @ LUMINANCE).mean() / (ref @ LUMINANCE).mean()
    print(f"| {strands} | {mode} | {whole:.3f} | {hair.min():.3f}-{hair.max():.3f}, "
          f"{hair.mean():.3f} | {' / '.join(f'{x:.3f}' for x in rgb)} | "
          f"{t1 - t0:.0f} s / {t2 - t1:.0f} s |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--strands", type=int, default=400)
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--cycles-spp", type=int, default=256)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--shape", default="RIBBONS", choices=("RIBBONS", "THICK"),
                    help="Cycles' curve shape (ours renders tubes for both)")
    ap.add_argument("--fallback", action="store_true")
    args = ap.parse_args()
    import tempfile

    import bpy
    import addon
    addon.register()
    if args.fallback:
        from addon import materials

        def fallback(self, node):
            base, tex = self._color(node, "Color")
            return materials.Closure(base_color=base, texture=tex, roughness=1.0,
                                     specular=0.0, normal_map=self._normal(node))
        materials.MaterialConverter._principled_hair = fallback
    print("| strands | mode | whole image | hair blocks (min-max, mean) | tuft R / G / B | "
          "Cycles / ours time |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="hairbsdf-") as out_dir:
        for mode in args.modes.split(","):
            run(bpy, mode, args.strands, args.cycles_spp, args.spp, out_dir, args.shape)


if __name__ == "__main__":
    main()
