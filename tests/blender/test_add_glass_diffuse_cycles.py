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

The scene of bench/bench_add_shader_sweep.py, 24 x 24, ours at 16 spp and 200,000 photons,
four seeds averaged (~6 s CPU), against a stored Cycles mean at 65,536 spp. Cycles' image
mean climbs with its samples here (a few rare bright paths, heavy-tailed: 2.693 at 256
spp, 2.763 at 1024, 2.790 at 4096, 2.878 at 16,384, 2.885 at 65,536); the test first
compared against the 4096-spp mean, 3.4 % low, and one 16-spp render at 50,000 photons
(0.94-1.07 of the 65,536-spp mean over 12 seeds), which a clean-clone CI read as 1.124.
Made by `bench/bench_add_shader_sweep.py --scene sphere --pairs "add glass+diffuse"
--cycles-spp 65536`.
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

CYCLES_65536 = np.array([2.8853, 2.8853, 1.1191])  # image mean (R, G, B)


def test_glass_plus_diffuse_sphere_traps_light_as_in_cycles(fresh_scene, bpy_addon,
                                                            tmp_path):
    bpy = bpy_addon
    sphere_scene(bpy, fresh_scene, material(bpy, "Pair", PAIRS["add glass+diffuse"]), 24)
    means = []
    for seed in range(4):
        fresh_scene.photonmap.seed = seed
        means.append(_render(bpy, fresh_scene, "PHOTONMAP", 16, tmp_path / f"ours{seed}.exr",
                             8, photons=200_000, caustic_photons=80_000))
    ratio = np.mean(means, axis=0) / CYCLES_65536
    print(f"ours / Cycles {ratio.round(4)}, per seed {(np.array(means) / CYCLES_65536).round(3)}")
    # One render (16 spp, 200,000 photons) reads 0.94-1.09 of Cycles' red over 24 seeds,
    # mean 1.010, spread 0.037 (the photon map and the camera paths both: 64 spp at 50,000
    # photons spreads as wide, 1,000,000 photons at 16 spp 0.99-1.03); the mean of four
    # has a spread ~0.019, so the 10 % bound is ~5 of them. It catches what it is for: the
    # chain's last level reading the whole map's kept power share read 1.53 / 1.53 / 1.13.
    assert abs(ratio - 1.0).max() < 0.10, ratio
