"""Multiple scattering in fog against Cycles (issue 14, volphotons38;
engine/photonmedium.py): the fog box of test_volume_scatter_cycles.py (Principled
Volume, Density 0.6, Color 0.8 / 0.7 / 0.6, Anisotropy 0.3, floating z 0.4..1.6 over a
white floor, a 400 W spot above), full light transport (Max Bounces 12), at Light Paths >
Volume bounces 0, 4 and 32 for both engines: photons scatter in the fog at 4 and 32 and
light the floor around the cone, the camera paths walk in it. Ours 256 spp with
photons, Cycles 1024 spp; 5 x 5 block means (docs/accuracy.md, volphotons38). Measured
(ours / Cycles; floor in the cone, beside it, god ray, image sum): bounces 0: 1.001,
0.968, 0.999, 0.999; 4: 1.000, 1.008, 1.005, 0.999; 32: 1.000, 0.995, 1.005, 0.998;
dense (Density 1, albedo 1) at 32: 0.996, 1.018, 1.008, 1.001. ~30-60 s per case."""
import numpy as np
import pytest

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def _render(bpy, scene, path, engine, spp, bounces):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    cycles_plain(scene, spp, 0)
    scene.cycles.max_bounces = 12
    scene.cycles.diffuse_bounces = 4
    scene.cycles.volume_bounces = bounces
    if engine != "CYCLES":
        cheap(scene, spp=spp, photons=200_000)
        scene.photonmap.photon_mapping = True
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3]


# (region, world point): the floor in the cone under the fog, the floor beside the cone
# (lit only by the fog's scattered light and the floor's own bounce), the god ray.
REGIONS = (("floor in the cone", (0.0, -0.3, 0.0)),
           ("floor beside the cone", (1.0, -0.6, 0.0)),
           ("god ray", (0.0, 0.0, 1.1)))
# Relative tolerances (5 x 5 blocks, luminance sums).
TOL = {"floor in the cone": 0.05, "floor beside the cone": 0.05, "god ray": 0.05, "sum": 0.03}


@pytest.mark.parametrize("bounces,dense", [(0, False), (4, False), (32, False), (32, True)])
def test_fog_box_over_a_floor_at_volume_bounces_matches_cycles(bpy_addon, tmp_path, bounces,
                                                              dense):
    """dense: the same box at Density 1, Color 1 (albedo 1)."""
    bpy = bpy_addon
    import os
    import sys
    from blender_helpers import project
    sys.path.insert(0, os.path.dirname(__file__))
    import test_volume_scatter_cycles as fog_box
    from test_volume_scatter_cycles import _block
    kept = fog_box.DENSITY, fog_box.FOG_COLOR
    if dense:
        fog_box.DENSITY, fog_box.FOG_COLOR = 1.0, (1.0, 1.0, 1.0)
    try:
        scene = fog_box._scene(bpy)
    finally:
        fog_box.DENSITY, fog_box.FOG_COLOR = kept
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 256, bounces)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 1024, bounces)
    for where, p in REGIONS:
        rc = project(bpy, scene, p)
        a, b = _block(ours, rc).sum(), _block(ref, rc).sum()
        print(bounces, where, round(a, 4), round(b, 4), round(a / b, 3))
        np.testing.assert_allclose(a, b, rtol=TOL[where], err_msg=where)
    ratio = ours.sum() / ref.sum()
    print(bounces, "image sum", round(ratio, 4))
    np.testing.assert_allclose(ratio, 1.0, rtol=TOL["sum"])
