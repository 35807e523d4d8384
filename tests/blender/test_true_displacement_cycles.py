"""True displacement (Material > Settings > Displacement "Displacement Only" and
"Displacement and Bump") against Cycles (issue 14). Cycles moves each vertex of the
tessellated mesh by the displacement shader evaluated there (mesh_displace.cpp) and, for
Displacement Only, recomputes the vertex normals; before, ours warned and rendered the
surface flat.

A grid of 48 x 48 quads (smooth, scaled 1.2: the Displacement node's Object space scales
with the object) whose height is a Wave texture's bands along x, seen obliquely under a
sun from +x: the ridges cast shadows and turn to and from the sun. Pixel centres only
(render_pixel_centres: no photon mapping, Cycles without bounces)."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W, H = 48, 36


def _scene(bpy, scene, method, smooth=True):
    from blender_helpers import black_world, node_material, sun_light
    from mathutils import Vector
    m, nt, out = node_material(bpy, "Displaced")
    m.displacement_method = method
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.wave_type, wave.bands_direction = "BANDS", "X"
    wave.inputs["Scale"].default_value = 1.2
    disp = nt.nodes.new("ShaderNodeDisplacement")
    disp.inputs["Scale"].default_value = 0.25
    nt.links.new(wave.outputs["Fac"], disp.inputs["Height"])
    nt.links.new(disp.outputs["Displacement"], out.inputs["Displacement"])
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=48, y_subdivisions=48, size=2.0)
    ob = bpy.context.object
    ob.scale = (1.2, 1.2, 1.2)
    if smooth:
        bpy.ops.object.shade_smooth()
    ob.data.materials.append(m)
    sun_light(bpy, scene, (0.0, math.radians(55.0), 0.0))  # from +x, 55 degrees low
    cam_data = bpy.data.cameras.new("Cam")
    cam = bpy.data.objects.new("Cam", cam_data)
    cam.location = (0.3, -2.6, 2.2)
    cam.rotation_euler = (Vector((0.0, 0.0, 0.0)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100


@pytest.mark.parametrize("method,shading", [("DISPLACEMENT", "smooth"), ("BOTH", "smooth"),
                                            ("DISPLACEMENT", "flat"), ("BOTH", "flat")])
def test_true_displacement_matches_cycles(fresh_scene, bpy_addon, tmp_path, method, shading):
    """Flat shading: Displacement Only shows the moved facets; Displacement and Bump is
    shaded smooth with the normals from before the move, as Cycles renders it (its flat
    and smooth renders are the same; before s36's new-user trial ours showed facets
    under the bump, 3.8 % of pixels off)."""
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, method, smooth=shading == "smooth")
    from blender_helpers import export_warnings, render_pixel_centres
    warnings = export_warnings(bpy)
    assert not [w for w in warnings if "isplacement" in w], warnings
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3]
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3]
    bpy.data.materials["Displaced"].displacement_method = "BUMP"
    bump = render_pixel_centres(bpy, scene, tmp_path / "bump.exr", "CYCLES")[..., :3]
    err = np.abs(ours - ref).mean(axis=2)
    moved = np.abs(bump - ref).mean(axis=2)  # what moving the surface changes in Cycles
    print(f"{method} {shading}: mean |ours - Cycles| {err.mean():.4f} (pixels > 0.05: "
          f"{(err > 0.05).sum()}), mean |bump only - Cycles| {moved.mean():.4f} "
          f"(> 0.05: {(moved > 0.05).sum()}); means {ours.mean():.4f} / {ref.mean():.4f}")
    assert moved.mean() > 0.02  # the relief shows: silhouettes, shadows
    assert err.mean() < 0.15 * moved.mean()
    # Measured (48 x 36): Displacement Only mean error 0.0002, 2 pixels over 0.05; and
    # Bump 0.0061, 43 pixels (+-0.06, scattered: the bump on top is taken from Cycles'
    # screen-space differences, ours from the surface gradient, as in texture_bump).
    assert (err > 0.05).sum() <= (0.005 if method == "DISPLACEMENT" else 0.04) * err.size
    assert ours.mean() == pytest.approx(ref.mean(), rel=0.01)
