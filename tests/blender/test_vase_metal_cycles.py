"""A smooth-shaded metal lathe (bench/vase45_metal.py's vase) under a Spot, seen from
above, against Cycles (glossyguard45).

The vase's top cap has smooth normals leaning ~54 degrees out; from the `--high` camera
the far part of the cap puts the viewer below them. Cycles keeps the shading normal and
turns the metal lobe's (ensure_valid_specular_reflection); camera paths replaced it by
the face normal (Veach's guard) until glossyguard45 (engine/turnedglossy.py), which made
the top quarter of the vase's rows read 1.22 of Cycles (docs/accuracy.md, vase45,
glossyguard45).

Cycles' luminance means (1024 spp, seed 0; the bench's settings) over the vase's pixels
and over the top quarter of its rows are stored in tests/references/vase45_metal.json
(this file run as a script writes them); the slow test renders them again live.
"""
import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest

pytestmark = pytest.mark.blender

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
REF_PATH = os.path.join(ROOT, "tests", "references", "vase45_metal.json")
RES = (64, 96)
CYCLES_SAMPLES = 1024
SHADINGS = ("smooth", "flat")


def _bench():
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    import vase45_metal
    return vase45_metal


def _args(flat, spp=16, cycles_spp=CYCLES_SAMPLES, seed=0):
    """bench/vase45_metal.py's arguments for `spot --high [--flat]`."""
    return SimpleNamespace(light="spot", flat=flat, rough=0.25, aniso=0.0, metallic=1.0,
                           diffuse_bounces=None, no_reflective_caustics=False,
                           filter_glossy=None, wall_spec=0.5, scale=4.0, terminator=None,
                           spot_radius=None, top=False, high=True, lift=0.0,
                           shape="vase", spp=spp, cycles_spp=cycles_spp, res=RES,
                           set=[f"seed={seed}"], keep=None, room=False)


def _means(tmp_path, shading, engine, **kw):
    """[vase mean, top-quarter mean] of luminance for one engine's render."""
    vm = _bench()
    a = _args(shading == "flat", **kw)
    scene = vm.build(a)
    ids, names = vm.object_masks(scene, *a.res)
    mask = ids == names.index("Vase")
    rows = np.nonzero(mask.any(axis=1))[0]
    top = mask.copy()
    top[rows[0] + len(rows) // 4:] = False  # the highest quarter of rows: lip and cap
    img, _ = vm.render(scene, engine, str(tmp_path / f"{engine}_{shading}.exr"), a)
    lum = vm.lum(img)
    return [float(lum[mask].mean()), float(lum[top].mean())]


def _cycles_means(bpy, tmp_path):
    return {s: _means(tmp_path, s, "CYCLES") for s in SHADINGS}


def _stored_means():
    from blender_helpers import stored_cycles_means
    return stored_cycles_means(REF_PATH)


@pytest.mark.parametrize("shading", SHADINGS)
def test_metal_vase_from_above_matches_cycles(bpy_addon, tmp_path, shading):
    """Ours (16 spp, seed 0) over the top quarter of the vase's rows (the lip and the
    cap, where the guard acted) within 4 % of Cycles' stored mean, smooth and flat.
    Seeds 0-2 at 16 spp read 0.995-1.003 (smooth) and 0.994-1.002 (flat); with the guard
    (turnedglossy.ENABLED False) the smooth cap read 1.21-1.22 (docs/accuracy.md,
    glossyguard45). The whole vase is printed, not asserted: at 16 spp it is the Spot's
    sub-pixel highlight (0.87-0.95 over seeds 0-2, the same with or without the guard)."""
    ours = _means(tmp_path, shading, "PHOTONMAP")
    want = _stored_means()[shading]
    print(f"vase45 --high ({shading}): ours / Cycles: vase {ours[0] / want[0]:.4f}, "
          f"top quarter {ours[1] / want[1]:.4f}")
    assert ours[1] / want[1] == pytest.approx(1.0, abs=0.04)


@pytest.mark.slow
def test_stored_cycles_means_are_cycles_now(bpy_addon, tmp_path):
    """The stored means are what this Blender's Cycles renders (1024 spp, seed 0)."""
    from blender_helpers import assert_stored_means_are_now
    assert_stored_means_are_now(_stored_means(),
                                {k: np.asarray(v) for k, v in
                                 _cycles_means(bpy_addon, tmp_path).items()})


if __name__ == "__main__":  # write the stored means: .venv/bin/python <this file>
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=CYCLES_SAMPLES, seed=0,
                       width=RES[0], height=RES[1], bench="bench/vase45_metal.py spot --high")
