"""A textured Base Color, Subsurface Weight or Radius walking beneath the surface (ssstex41,
issue 14) against live Cycles: a ball with a Checker Texture on Base Color (skin and a
pale blue), on Subsurface Weight (1 and 0.2) or on Subsurface Radius ((1, 0.2, 0.1) and
(0.1, 0.3, 1)), Subsurface Scale 0.2, the sun from above at an angle, black world, an
orthographic camera looking down; per-channel mean and 4 x 4 block means of the ball's
pixels. Before ssstex41 a textured colour or weight rendered as the diffuse stand-in on
camera paths, a textured radius walked with the socket's own value."""
import math

import numpy as np
import pytest

from blender_helpers import (black_world, cheap, cycles_plain, looking_down_camera,
                             read_rgba, render_exr, sun_light)
from tools.canonical_mesh import primitive_uv_sphere_add

pytestmark = pytest.mark.blender


def _material(bpy, on: str):
    m = bpy.data.materials.new("SkinTex")
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (0.8, 0.55, 0.45, 1.0)
    p.inputs["Roughness"].default_value = 0.5
    p.inputs["Subsurface Weight"].default_value = 1.0
    p.inputs["Subsurface Scale"].default_value = 0.2
    p.inputs["Subsurface Radius"].default_value = (1.0, 0.2, 0.1)
    checker = nt.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 3.0
    if on == "color":
        checker.inputs["Color1"].default_value = (0.8, 0.5, 0.4, 1.0)
        checker.inputs["Color2"].default_value = (0.3, 0.5, 0.8, 1.0)
        nt.links.new(checker.outputs["Color"], p.inputs["Base Color"])
    elif on == "radius":
        checker.inputs["Color1"].default_value = (1.0, 0.2, 0.1, 1.0)
        checker.inputs["Color2"].default_value = (0.1, 0.3, 1.0, 1.0)
        nt.links.new(checker.outputs["Color"], p.inputs["Subsurface Radius"])
    else:
        checker.inputs["Color1"].default_value = (1.0, 1.0, 1.0, 1.0)
        checker.inputs["Color2"].default_value = (0.2, 0.2, 0.2, 1.0)
        # (A colour into a value socket: its luminance, 1 and 0.2.)
        nt.links.new(checker.outputs["Color"], p.inputs["Subsurface Weight"])
    return m


@pytest.mark.parametrize("on", ["color", "weight", "radius"])
def test_checker_ball_matches_cycles(fresh_scene, bpy_addon, tmp_path, on):
    """Both at 256 samples a pixel (24 x 24; ~4 s a case): the walk's per-channel means
    within 1.5 % of Cycles', its 4 x 4 block means within 3 % on average; the stand-in
    (walk off) printed for comparison."""
    bpy, scene = bpy_addon, fresh_scene
    primitive_uv_sphere_add(radius=0.5, segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    ball = bpy.context.object
    ball.data.materials.append(_material(bpy, on))
    black_world(bpy, scene)
    sun_light(bpy, scene, (0.5, 0.3, 0.0), energy=3.0)
    looking_down_camera(bpy, scene, 2.0, ortho_scale=1.1)
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 256, 8)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=256, photons=20_000, caustic_photons=0)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    scene.photonmap.subsurface_walk = False
    stand = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "stand_in.exr"))[..., :3]
    ours, ref = ours.astype(np.float64), ref.astype(np.float64)
    covered = ref.mean(axis=2) > 1e-4
    full = covered.reshape(6, 4, 6, 4).all(axis=(1, 3))
    br = ref.reshape(6, 4, 6, 4, 3).mean(axis=(1, 3))[full]
    want = ref[covered].mean(axis=0)
    errs = {}
    for name, img in (("walk", ours), ("stand-in", stand.astype(np.float64))):
        got = img[covered].mean(axis=0)
        bo = img.reshape(6, 4, 6, 4, 3).mean(axis=(1, 3))[full]
        errs[name] = np.abs(bo - br) / br
        print(f"checker on {on}, {name}: ours / Cycles {np.round(got / want, 4)}, "
              f"4x4 block channels |err| worst {errs[name].max():.3f} "
              f"mean {errs[name].mean():.3f}")
    # The walk's means within 1 % here (the stand-in's red 1.5-2.2 % low), its blocks'
    # channels 1.3-1.8 % off on average (the stand-in's 1.8-2.6 %).
    got = ours[covered].mean(axis=0)
    np.testing.assert_allclose(got, want, rtol=0.015)
    assert errs["walk"].mean() < 0.03, errs["walk"]
