"""Add of a smooth Glass BSDF and a Diffuse BSDF on a closed sphere in a grey world,
Light Paths 8 bounces, against Cycles (issue 14: "Closures as Cycles defines them ...
Mix and Add"; s44 gatherlevel44).

The sphere traps light: its diffuse part gains ~1.4x a bounce inside (weight 1 plus the
glass's total internal reflection), so its deep photons carry most of the light inside
and little of the whole map's. Final-gather lookups reached through the glass chain drop
some of their level map's photons; the last level read the map scaled by the whole map's
kept power share (chaincounts.GatherCounts.kept_share): 1.53x Cycles. They now read
their usable photons alone at their gather point (chaincounts.subset_irradiance):
1.01-1.02x at 64 spp (docs/accuracy.md, gatherlevel44).

The scene of bench/bench_add_shader_sweep.py, 24 x 24, ours 16 spp (~2 s CPU) against a
stored Cycles mean at 4096 spp (Cycles' image mean still climbs with its samples here, a
few rare bright paths: 2.693 at 256 spp, 2.763 at 1024, 2.790 at 4096), made by
`bench/bench_add_shader_sweep.py --scene sphere --pairs "add glass+diffuse"
--cycles-spp 4096`.
"""
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))), "bench"))
import numpy as np  # noqa: E402
from bench_add_shader_sweep import PAIRS, material, sphere_scene  # noqa: E402
from bench_add_shader_sweep import render as _render  # noqa: E402

pytestmark = pytest.mark.blender

CYCLES_4096 = np.array([2.7899, 2.7899, 1.1103])  # image mean (R, G, B)


def test_glass_plus_diffuse_sphere_traps_light_as_in_cycles(fresh_scene, bpy_addon,
                                                            tmp_path):
    bpy = bpy_addon
    sphere_scene(bpy, fresh_scene, material(bpy, "Pair", PAIRS["add glass+diffuse"]), 24)
    ours = _render(bpy, fresh_scene, "PHOTONMAP", 16, tmp_path / "ours.exr", 8)
    ratio = ours / CYCLES_4096
    print(f"ours / Cycles {ratio.round(4)}")
    # Red over 8 renders at 16 spp: 0.99-1.08 (seeds 0-2, and the scene built and
    # rendered again in one Blender process, which reads another value at the same seed:
    # 1.005 then 1.068: Blender's UV sphere primitive orders its loops and triangles
    # differently at each build, the same triangles and vertices, so the same seed draws
    # other samples; the engine renders one exported scene to the same bits each time);
    # at 64 spp 1.007-1.016. Before, 1.53 / 1.53 / 1.13. Bound 10 %.
    assert abs(ratio - 1.0).max() < 0.10, ratio
