"""A Bump node over a height steeper than any footprint resolves, against Cycles
(issue 14, bump50: docs/accuracy.md "### bump50").

bathroom49's tiles: a Brick Texture's Fac (1 in the grout, a 1 mm ramp of height 1 at
its edges) into a Bump node (Distance 1, Invert) under a glossy Principled BSDF
(roughness 0.1), a 2 x 2 m plane under a sun 45 degrees off its normal, seen from above.
Cycles takes the height's differences over Filter Width (0.1) x the ray footprint, so
each grout edge is a band a few millimetres wide whose slope sweeps through the angle
that mirrors the sun into the camera: the bumped plane reads 1.19 x the unbumped one in
Cycles (64 x 64, orthographic). Derivatives at a fixed 1e-4 barycentric step (before
bump50) resolved the ramp instead and read 0.99 x: ours / Cycles 0.83 orthographic, 0.970
in perspective; now 0.992 and 1.001 (0.998 before footprint51 counted the camera's clip
start in the footprint). Direct light only; an orthographic view (footprint:
the pixel's width) and a perspective one (the camera's differential times the
distance)."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W = H = 64


def _scene(bpy, scene, view, filter_width=None):
    from blender_helpers import black_world, looking_down_camera, node_material
    m, nt, out = node_material(bpy, "Tiles")
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    p.inputs["Roughness"].default_value = 0.1
    uv = nt.nodes.new("ShaderNodeTexCoord")
    b = nt.nodes.new("ShaderNodeTexBrick")
    b.offset = 0.0
    b.inputs["Scale"].default_value = 16.0
    b.inputs["Brick Width"].default_value = 0.25
    b.inputs["Row Height"].default_value = 0.25
    bu = nt.nodes.new("ShaderNodeBump")
    bu.invert = True
    if filter_width is not None:
        bu.inputs["Filter Width"].default_value = filter_width
    nt.links.new(uv.outputs["UV"], b.inputs["Vector"])
    nt.links.new(b.outputs["Fac"], bu.inputs["Height"])
    nt.links.new(bu.outputs["Normal"], p.inputs["Normal"])
    nt.links.new(p.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2.0)
    bpy.context.object.data.materials.append(m)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.0, math.radians(45.0), 0.0)
    scene.collection.objects.link(sun)
    if view == "ortho":
        looking_down_camera(bpy, scene, 3.0, ortho_scale=2.0)
    else:
        looking_down_camera(bpy, scene, 3.0, lens=60.0)
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100


def _mean(bpy, scene, path, engine):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    if engine == "CYCLES":
        cycles_plain(scene, 256, 0)
    else:
        scene.cycles.max_bounces = 0
        cheap(scene, spp=64, photons=1_000, caustic_photons=0)
        scene.photonmap.photon_mapping = False
    return float(read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean())


@pytest.mark.parametrize("view", ["ortho", "persp"])
def test_bump_differences_over_the_footprint_match_cycles(fresh_scene, bpy_addon, tmp_path,
                                                          view):
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, view)
    ours = _mean(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _mean(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(f"{view}: ours {ours:.4f} Cycles {ref:.4f} ratio {ours / ref:.4f}")
    assert ours == pytest.approx(ref, rel=0.02)


def test_bump_filter_width_is_read(fresh_scene, bpy_addon, tmp_path):
    """Filter Width 1: ten times the step, a tenth of the slope over ten times the band:
    Cycles' plane falls from 0.614 to 0.515 (ours, were the input not read, would stay
    at 0.61)."""
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, "ortho", filter_width=1.0)
    ours = _mean(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _mean(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(f"filter width 1: ours {ours:.4f} Cycles {ref:.4f} ratio {ours / ref:.4f}")
    assert ours == pytest.approx(ref, rel=0.02)
