"""Cycles' Clamp Indirect 10 (Blender's default) on issue 14's glossy product shot
(bench/bench_glossy_product.build, 80x60): ours clamped against Cycles clamped alike, by
image band (docs/accuracy.md "clampind": at 160x120, 16 spp, ours / Cycles 1.012-1.036 on
the text, 1.015-1.027 balls, 1.012-1.013 floor, 1.013-1.018 image; unclamped 1.005 /
0.999 / 1.003 / 1.002; this test at 80x60 measured 1.003 / 1.023 / 1.015 / 1.016 on the
AMD EPYC). Cycles' clamp takes more than ours off the balls and the floor:
its diffuse paths that reach the light by a glossy reflection are single spiky samples,
ours are photon-density estimates, smooth enough to pass under the limit."""
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def test_glossy_product_clamped_matches_cycles_clamped_by_band(bpy_addon):
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import bench_glossy_product as G
    from engine.render import render
    from engine.settings import RenderSettings
    w, h = 80, 60
    scene = G.build(w, h)
    G.A.set_cycles(scene, 1024, 7)
    scene.cycles.sample_clamp_indirect = 10.0
    cycles, _ = G.A.render_rgb(scene)
    pm_scene, kwargs = G.export(w, h)
    films = {c: render(pm_scene, RenderSettings(**{**kwargs, "spp": 16, "seed": 0,
                                                    "clamp_indirect": c}))
             for c in (10.0, 0.0)}

    def bands(img):
        lum = np.asarray(img, np.float64).mean(axis=2)
        return {name: lum[int(a * h):int(b * h)].mean() for name, a, b in
                G.BANDS + (("image", 0.0, 1.0),)}

    ref, ours, free = bands(cycles), bands(films[10.0].combined), bands(films[0.0].combined)
    assert ours["text"] < free["text"]  # the gold text's glossy-glossy samples were cut
    for name, tol in (("text", 0.05), ("balls", 0.03), ("floor", 0.03), ("image", 0.025)):
        assert abs(ours[name] / ref[name] - 1.0) <= tol, (name, ours[name], ref[name])
