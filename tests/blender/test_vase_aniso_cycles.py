"""The anisotropic metal vase under a Spot from above against Cycles, with its highlight
resolved (vase47).

bench/vase45_metal.py `spot --high --aniso 0.6` read 0.947 of Cycles at 64 x 96 (ours 64
spp, seed 0; fgroom46). At that size the Spot's highlight is a few pixels and carries
the vase's mean: ours over seeds 0-3 at 64 spp read 0.947-1.037, at 1024 spp 0.981-0.993,
and Cycles' own 1024-spp mean moved 2.4 % between seeds 0-2. At 256 x 384 the highlight
covers many pixels and the same vase reads 0.996-0.998 anisotropic and 0.995-0.997
isotropic (docs/accuracy.md, vase47): no dark anisotropic lobe.

Cycles' luminance means over the vase's pixels (1024 spp, seed 0, 256 x 384; the bench's
settings) are stored in tests/references/vase47_aniso.json (this file run as a script
writes them); the slow test renders them again live.
"""
import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest

pytestmark = pytest.mark.blender

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
REF_PATH = os.path.join(ROOT, "tests", "references", "vase47_aniso.json")
RES = (256, 384)
CYCLES_SAMPLES = 1024
# Ours: over seeds 0-7 at 64 spp 0.9925-1.0030 (anisotropic, sd 0.0034) and 0.9921-1.0010
# (isotropic, sd 0.0025); at 16 spp (the test before flaky50) seeds 0-5 read 0.980-1.020
# (sd 0.017) and 0.983-1.011 (sd 0.011), under 2 sd inside the 2.5 % bound.
OUR_SPP = 64
ANISOTROPY = {"aniso": 0.6, "iso": 0.0}


def _bench():
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    import vase45_metal
    return vase45_metal


def _args(aniso, spp=16, cycles_spp=CYCLES_SAMPLES, seed=0):
    """bench/vase45_metal.py's arguments for `spot --high --aniso A --res 256 384`."""
    return SimpleNamespace(light="spot", flat=False, rough=0.25, aniso=aniso, metallic=1.0,
                           diffuse_bounces=None, no_reflective_caustics=False,
                           filter_glossy=None, wall_spec=0.5, scale=4.0, terminator=None,
                           spot_radius=None, top=False, high=True, lift=0.0,
                           shape="vase", spp=spp, cycles_spp=cycles_spp, cycles_seed=0,
                           res=RES, set=[f"seed={seed}"], keep=None, room=False)


def _vase_mean(tmp_path, key, engine, **kw):
    """The mean luminance over the vase's pixels of one engine's render."""
    vm = _bench()
    a = _args(ANISOTROPY[key], **kw)
    scene = vm.build(a)
    ids, names = vm.object_masks(scene, *a.res)
    mask = ids == names.index("Vase")
    img, _ = vm.render(scene, engine, str(tmp_path / f"{engine}_{key}.exr"), a)
    return float(vm.lum(img)[mask].mean())


def _cycles_means(bpy, tmp_path):
    return {k: _vase_mean(tmp_path, k, "CYCLES") for k in ANISOTROPY}


def _stored_means():
    from blender_helpers import stored_cycles_means
    return stored_cycles_means(REF_PATH)


@pytest.mark.parametrize("key", sorted(ANISOTROPY))
def test_metal_vase_highlight_resolved_matches_cycles(bpy_addon, tmp_path, key):
    """Ours (OUR_SPP, seed 0) over the vase within 2.5 % of Cycles' stored mean, with
    Anisotropic 0.6 and isotropic: the anisotropic GGX, its tangents from Blender and its
    energy compensation give the highlight Cycles gives (docs/accuracy.md, vase47). At 64
    spp the bound is 6-9 sd of the seed spread past the mean (0.9975; `pytest -s
    tests/blender/seed_sweeps.py -k vase`, docs/accuracy.md "flaky50")."""
    ours = _vase_mean(tmp_path, key, "PHOTONMAP", spp=OUR_SPP)
    want = _stored_means()[key]
    print(f"vase47 spot --high ({key}) at {RES[0]} x {RES[1]}: ours / Cycles "
          f"{ours / want:.4f}")
    assert ours / want == pytest.approx(1.0, abs=0.025)


@pytest.mark.slow
def test_stored_cycles_means_are_cycles_now(bpy_addon, tmp_path):
    """The stored means are what this Blender's Cycles renders (1024 spp, seed 0)."""
    from blender_helpers import assert_stored_means_are_now
    assert_stored_means_are_now(_stored_means(),
                                {k: np.asarray([v]) for k, v in
                                 _cycles_means(bpy_addon, tmp_path).items()})


if __name__ == "__main__":  # write the stored means: .venv/bin/python <this file>
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=CYCLES_SAMPLES, seed=0,
                       width=RES[0], height=RES[1],
                       bench="bench/vase45_metal.py spot --high --aniso A --res 256 384")
