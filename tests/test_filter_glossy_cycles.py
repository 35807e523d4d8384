"""Cycles' Filter Glossy on our camera paths (fgcamera46, engine/filterglossy.py) against
Cycles at Filter Glossy 1 on issue 14's Principled spheres: the two metals (Steel,
roughness 0.5; Gold), which reflect their neighbours' lobes after their own rough bounce.

Cycles' means over each metal's pixels at Filter Glossy 0 and 1 (1024 spp, seed 0) are
stored in tests/references/filter_glossy_metals.json (bench/fgcamera46.py --json writes
them). Cycles dims Steel / Gold by 1.7 / 2.0 % at 1. Ours blurs the camera chains
(docs/compatibility.md "fgcamera46": 0.6 / 0.2 % of that alone) and, with the split
(engine/glossysplit.py, "fgsplit46"), the floor's final-gather chains, which start at the
camera path's min_ray_pdf (the metal's bounce): 1.5 / 1.5 % at seeds 0-1, 32 spp (the
split's chains starting at the floor's pdf alone dimmed Steel 2.2 %, past Cycles). So the
test holds ours' drop between none and Cycles' within 0.3 % (a blur never brightens the
metals here) and ours at 1 within 4 % of Cycles at 1."""
import json
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REF = os.path.join(ROOT, "tests", "references", "filter_glossy_metals.json")
METALS = ("Steel", "Gold")
LUM = np.array([0.2126, 0.7152, 0.0722])

pytestmark = pytest.mark.blender


def _ours(fg, seeds=(0, 1), spp=32):
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import accuracy_scenes as acc
    from engine.render import render
    from engine.settings import RenderSettings
    scene, kw = acc.export_ours("principled_spheres")
    labels, names = acc.load_labels("principled_spheres")
    imgs = [np.asarray(render(scene, RenderSettings(**dict(
        kw, spp=spp, seed=s, workers=1, cycles_filter_glossy=fg))).combined, np.float64)
        for s in seeds]
    lum = np.mean(imgs, axis=0)[..., :3] @ LUM
    return {n: float(lum[labels == names.index(n) + 1].mean()) for n in METALS}


@pytest.mark.slow
def test_metals_blur_towards_cycles_filter_glossy_1():
    pytest.importorskip("bpy")
    with open(REF) as f:
        cycles = json.load(f)["means"]
    o0, o1 = _ours(0.0), _ours(1.0)
    for n in METALS:
        c_ratio = cycles[n]["fg1"] / cycles[n]["fg0"]
        o_ratio = o1[n] / o0[n]
        info = (f"{n}: ours FG 1 / FG 0 {o_ratio:.4f}, Cycles {c_ratio:.4f}; ours / Cycles "
                f"at FG 1 {o1[n] / cycles[n]['fg1']:.4f}")
        print(info)
        assert c_ratio < 0.99, info  # (the stored means: Cycles' blur dims both)
        assert c_ratio - 0.003 <= o_ratio <= 1.001, info
        assert o1[n] / cycles[n]["fg1"] == pytest.approx(1.0, abs=0.04), info
    # Steel's own rough bounce (alpha 0.25) blurs most of what it reflects: its drop shows.
    assert o1["Steel"] / o0["Steel"] < 0.998
