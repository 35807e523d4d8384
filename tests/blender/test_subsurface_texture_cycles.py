"""A textured Base Color and Subsurface Weight walking beneath the surface (ssstex41,
issue 14) against live Cycles: a ball with a Checker Texture on Base Color (skin and a
pale blue) or on Subsurface Weight (1 and 0.2), Subsurface Scale 0.2, the sun from above
at an angle, black world, an orthographic camera looking down; per-channel mean and 4 x 4
block means of the ball's pixels. Before ssstex41 these rendered as the diffuse stand-in
on camera paths (no light spread beneath the surface)."""
import math

import numpy as np
import pytest

from blender_helpers import (black_world, cheap, cycles_plain, looking_down_camera,
                             read_rgba, render_exr, sun_light)

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
    else:
        checker.inputs["Color1"].default_value = (1.0, 1.0, 1.0, 1.0)
        checker.inputs["Color2"].default_value = (0.2, 0.2, 0.2, 1.0)
        # (A colour into a value socket: its luminance, 1 and 0.2.)
        nt.links.new(checker.outputs["Color"], p.inputs["Subsurface Weight"])
    return m


@pytest.mark.parametrize("on", ["color", "weight"])
def test_checker_ball_matches_cycles(fresh_scene, bpy_addon, tmp_path, on):
    bpy, scene = bpy_addon, fresh_scene
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, segments=48, ring_count=24)
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
    cheap(scene, spp=32, photons=20_000, caustic_photons=0)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    ours, ref = ours.astype(np.float64), ref.astype(np.float64)
    lum_o, lum_r = ours.mean(axis=2), ref.mean(axis=2)
    covered = lum_r > 1e-4
    got, want = ours[covered].mean(axis=0), ref[covered].mean(axis=0)
    bo = ours.reshape(6, 4, 6, 4, 3).mean(axis=(1, 3))
    br = ref.reshape(6, 4, 6, 4, 3).mean(axis=(1, 3))
    full = covered.reshape(6, 4, 6, 4).all(axis=(1, 3))
    err = np.abs(bo[full] - br[full]) / br[full]
    print(f"checker on {on}: ours / Cycles {np.round(got / want, 4)}, blocks "
          f"worst {err.max():.3f} mean {err.mean():.3f}")
    np.testing.assert_allclose(got, want, rtol=0.03)
    assert np.all(np.abs(bo[full] - br[full]) <= 0.08 * br[full] + 0.01 * br.max()), (bo, br)
