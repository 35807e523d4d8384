"""Bevel node against Cycles (issue 14): a shading normal averaged from the surface within
Radius, found by rays inside the shader (engine/bevel.py, Cycles' svm_bevel). It was
warned before and the surface normal used (hard edges).

A Diffuse cube (1 m, turned so three faces and their edges face the camera) whose BSDF
Normal is a Bevel (Radius 0.12, 8 samples), lit by a sun from the side, seen from above
orthographically; direct light only, 64 samples at the pixel centres in both renderers,
compared in blocks of 4 x 4 pixels. The rounded edges show as gradients across them
where the plain cube steps from one face's shade to the next."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W = H = 32
SPP = 64


def _scene(bpy, scene, chained_bump=False):
    from blender_helpers import black_world, looking_down_camera, node_material, sun_light
    m, nt, out = node_material(bpy, "Rounded")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bevel = nt.nodes.new("ShaderNodeBevel")
    bevel.samples = 8
    bevel.inputs["Radius"].default_value = 0.12
    nt.links.new(bevel.outputs["Normal"], d.inputs["Normal"])
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    if chained_bump:  # a Bump (a gentle ramp along x) on the Bevel's Normal input
        bump = nt.nodes.new("ShaderNodeBump")
        bump.inputs["Distance"].default_value = 0.3
        coords = nt.nodes.new("ShaderNodeTexCoord")
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(coords.outputs["Object"], sep.inputs["Vector"])
        nt.links.new(sep.outputs["X"], bump.inputs["Height"])
        nt.links.new(bump.outputs["Normal"], bevel.inputs["Normal"])
    bpy.ops.mesh.primitive_cube_add(size=1.0)
    cube = bpy.context.object
    cube.rotation_euler = (math.radians(35.0), math.radians(-25.0), math.radians(20.0))
    cube.data.materials.append(m)
    sun_light(bpy, scene, (math.radians(40.0), math.radians(30.0), 0.0))
    looking_down_camera(bpy, scene, 3.0, ortho_scale=1.8)
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100


def _blocks(img, k=4):
    h, w = img.shape[:2]
    return img[:h - h % k, :w - w % k].reshape(h // k, k, w // k, k, -1).mean(axis=(1, 3))


@pytest.mark.parametrize("chained_bump", [False, True])
def test_bevel_matches_cycles(fresh_scene, bpy_addon, tmp_path, chained_bump):
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, chained_bump)
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", spp=SPP)
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES", spp=SPP)
    bo, br = _blocks(ours[..., :3]), _blocks(ref[..., :3])
    err = np.abs(bo - br)
    print(f"bump {chained_bump}: mean ours {ours[..., :3].mean():.4f} Cycles "
          f"{ref[..., :3].mean():.4f}, blocks {br.min():.3f} .. {br.max():.3f}, max block "
          f"|ours - Cycles| {err.max():.4f}")
    assert abs(ours[..., :3].mean() - ref[..., :3].mean()) <= 0.01 * ref[..., :3].mean()
    assert err.max() <= 0.03 * br.max()
    # The bevel shows: the cube with its plain normals is far from Cycles' rounded edges.
    nt = bpy.data.materials["Rounded"].node_tree
    diffuse = next(n for n in nt.nodes if n.type == "BSDF_DIFFUSE")
    nt.links.remove(diffuse.inputs["Normal"].links[0])
    plain = render_pixel_centres(bpy, scene, tmp_path / "plain.exr", "PHOTONMAP", spp=SPP)
    plain_err = np.abs(_blocks(plain[..., :3]) - br).max()
    print(f"without the bevel: max block |ours - Cycles| {plain_err:.4f}")
    assert plain_err > 3.0 * err.max()
