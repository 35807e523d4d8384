"""A Bump node seen from the back of a single-sided surface, against Cycles (issue 14).

Seen from the back, Cycles shades with the front's bumped normal turned over, as ours
does (engine.bsdf.surface_hit turns the winding-side normal to the ray). A reading of
svm_node_set_bump (it bumps sd->N, already turned to the viewer) suggested the tilt
mirrored instead; measured, that reads against Cycles (column correlation -0.996).

A plane (a grid of 4 x 4 quads) with wave bands along x as its Bump height, under a sun 70
degrees from the plane's normal coming from +x, seen from the side the sun is on: from
above (the winding's front) and from below (its back, sun and camera below)."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W = H = 32


def _scene(bpy, scene, side):
    from blender_helpers import black_world, looking_down_camera, node_material, sun_light
    m, nt, out = node_material(bpy, "Bumped")
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.wave_type, wave.bands_direction = "BANDS", "X"
    wave.inputs["Scale"].default_value = 1.5
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.05
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(wave.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], d.inputs["Normal"])
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2.0)
    bpy.context.object.data.materials.append(m)
    # light travelling to -x and down (front) or up (back), 70 degrees off the normal
    sun_light(bpy, scene, (0.0, math.radians(70.0 if side == "front" else 110.0), 0.0))
    cam = looking_down_camera(bpy, scene, 3.0, ortho_scale=2.0)
    if side == "back":  # under the plane, looking up
        cam.location.z = -3.0
        cam.rotation_euler = (math.pi, 0.0, 0.0)
    cam.location.y += 0.02
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100


def _columns(img):
    """Brightness per image column (along x, across the bands)."""
    return img[..., :3].mean(axis=(0, 2))


@pytest.mark.parametrize("side", ["front", "back"])
def test_bump_seen_from_either_side_matches_cycles(fresh_scene, bpy_addon, tmp_path, side):
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, side)
    from blender_helpers import render_pixel_centres
    ours = _columns(render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP"))
    ref = _columns(render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES"))
    corr = np.corrcoef(ours, ref)[0, 1]
    print(f"{side}: Cycles columns {np.round(ref[::4], 3)}\n      ours {np.round(ours[::4], 3)}"
          f", correlation {corr:.3f}, max |ours - Cycles| {np.abs(ours - ref).max():.4f}")
    assert np.ptp(ref) > 0.1  # the bands show under the grazing sun
    assert corr > 0.95  # (the tilt mirrored at back faces instead: -0.996)
    assert np.abs(ours - ref).max() <= 0.1 * np.ptp(ref)
    assert ours.mean() == pytest.approx(ref.mean(), rel=0.03)
