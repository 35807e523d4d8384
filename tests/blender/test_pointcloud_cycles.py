"""Point clouds (Geometry Nodes points) render as Cycles' spheres (engine/pointcloud.py,
addon/export.py extract_pointcloud_geometry); a Volume object, which renders nothing here,
is warned.

Measured (s39, 96 x 72, Cycles 256 spp, ours 32 spp): the 42 vertices of an icosphere
made points of radius 0.08 m (Mesh to Points, Set Material) over a grey floor under a sun:
whole image 1.002 of Cycles, 8 x 6 blocks 0.995-1.008.

Cycles' side (12 x 12 block means, and for the plain points the brightest pixel among
the dots and the sky corner's mean; 256 spp, seed 0: the same numbers every run) is
stored in tests/references/pointcloud_cycles.json (this file run as a script writes it);
the slow test_stored_point_blocks_are_cycles_now renders it again live."""
import math
import os

import numpy as np
import pytest

from blender_helpers import (ROOT, assert_stored_means_are_now, block_means,
                             cycles_luminance, export_warnings, ours_luminance,
                             principled_material, stored_cycles_means, sun_light,
                             world_color)

pytestmark = pytest.mark.blender
REF_PATH = os.path.join(ROOT, "tests", "references", "pointcloud_cycles.json")


def _points_modifier(bpy, obj, radius, material=None, drop_radius=False):
    """Geometry Nodes on obj: its mesh's vertices as points of `radius` (Mesh to Points),
    in `material`; drop_radius removes the "radius" attribute (Cycles' 0.01 m)."""
    ng = bpy.data.node_groups.new("ToPoints", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    to_points = ng.nodes.new("GeometryNodeMeshToPoints")
    to_points.inputs["Radius"].default_value = radius
    last = to_points.outputs[0]
    ng.links.new(gin.outputs[0], to_points.inputs["Mesh"])
    if material is not None:
        set_material = ng.nodes.new("GeometryNodeSetMaterial")
        set_material.inputs["Material"].default_value = material
        ng.links.new(last, set_material.inputs[0])
        last = set_material.outputs[0]
    if drop_radius:
        remove = ng.nodes.new("GeometryNodeRemoveAttribute")
        remove.inputs["Name"].default_value = "radius"
        ng.links.new(last, remove.inputs[0])
        last = remove.outputs[0]
    ng.links.new(last, gout.inputs[0])
    obj.modifiers.new("Points", "NODES").node_group = ng


def _scene(bpy, radius=0.08):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world_color(bpy, sc, (0.05, 0.05, 0.05))
    bpy.ops.mesh.primitive_plane_add(size=4)
    bpy.context.object.data.materials.append(principled_material(bpy, "Grey", (0.5, 0.5, 0.5), 0.5))
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=0.8, location=(0, 0, 0.9))
    dots = bpy.context.object
    dots.name = "Dots"
    _points_modifier(bpy, dots, radius, principled_material(bpy, "Red", (0.8, 0.2, 0.1), 0.4))
    sun_light(bpy, sc, (math.radians(40), 0, math.radians(30)), energy=3.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -3.2, 1.6), (math.radians(65), 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 96, 72, 100
    return sc, dots


def test_points_export_as_spheres_of_their_radius(bpy_addon):
    """Each point a sphere round its position of its "radius" (without it Cycles' 0.01 m),
    in the Set Material's material; no warning."""
    bpy = bpy_addon
    _sc, dots = _scene(bpy, radius=0.05)
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    scene, _ = export.export_scene(pm, bpy.context.evaluated_depsgraph_get(), width=16,
                                   height=12)
    spheres = [m for m in scene.meshes if m.name.startswith("Dots#")]
    assert len(spheres) == 1 and spheres[0].materials == ["Red"]
    n = len(dots.data.vertices)  # 42: Blender's icosphere of Subdivisions 2
    level = pm.pointcloud.sphere_level(n)
    per_point = 20 * 4 ** level
    v = np.asarray(spheres[0].vertices).reshape(n, -1, 3)
    centres = v.mean(axis=1)
    np.testing.assert_allclose(np.linalg.norm(centres - (0, 0, 0.9), axis=1), 0.8, atol=1e-4)
    assert len(spheres[0].faces) == n * per_point
    f = np.asarray(spheres[0].faces)[:per_point]
    a, b, c = (np.asarray(spheres[0].vertices)[f[:, i]] for i in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    assert area == pytest.approx(4 * math.pi * 0.05 ** 2, rel=1e-4)
    assert not [w for w in scene.all_warnings() if "Dots" in w]
    view, _ = export.export_viewport(export.ViewportExport(pm),
                                     bpy.context.evaluated_depsgraph_get(),
                                     pm.Camera.look_at((0, -4, 2), (0, 0, 0)), 16, 12)
    seen = [m for m in view.meshes if m.name.startswith("Dots#")]
    assert len(seen) == 1 and np.allclose(seen[0].expanded().vertices, spheres[0].vertices)
    dots.modifiers.clear()
    _points_modifier(bpy, dots, 0.05, drop_radius=True)
    scene, _ = export.export_scene(pm, bpy.context.evaluated_depsgraph_get(), width=16,
                                   height=12)
    v = np.asarray(next(m for m in scene.meshes if m.name.startswith("Dots#")).vertices)
    r = np.linalg.norm(v[:12] - v[:12].mean(axis=0), axis=1)
    assert r.max() == pytest.approx(0.01 * pm.pointcloud.area_scale(
        *pm.pointcloud.icosphere(level)), rel=1e-4)


def test_points_of_radius_0_render_nothing_and_say_so(bpy_addon):
    bpy = bpy_addon
    _sc, dots = _scene(bpy, radius=0.0)
    from addon import export
    from addon.core import load_engine
    scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                   width=16, height=12)
    assert not [m for m in scene.meshes if m.name.startswith("Dots#")]
    hits = [w for w in scene.all_warnings() if "'Dots'" in w]
    assert len(hits) == 1 and "radius 0" in hits[0], hits


def test_a_volume_object_without_grids_is_warned_naming_it(bpy_addon):
    """(Volume objects render since vdb41: tests/blender/test_volume_objects_cycles.py;
    one without grids, a new Volume with no file, renders nothing, warned once.)"""
    bpy = bpy_addon
    _scene(bpy)
    vol = bpy.data.objects.new("Smoke", bpy.data.volumes.new("Smoke"))
    bpy.context.scene.collection.objects.link(vol)
    hits = [w for w in export_warnings(bpy) if "'Smoke'" in w]
    assert len(hits) == 1 and "the volume has no grids" in hits[0], hits


def test_points_match_cycles(bpy_addon, tmp_path):
    bpy = bpy_addon
    sc, _dots = _scene(bpy)
    ours = ours_luminance(bpy, sc, tmp_path)
    stored = stored_cycles_means(REF_PATH)
    ref = stored["points"].reshape(6, 8)  # 12 x 12 block means
    assert np.isfinite(ours).all()
    whole = ours.mean() / ref.mean()  # 96 x 72: the blocks' mean is the image's
    ratio = block_means(ours) / ref
    assert 0.99 < whole < 1.01, whole
    assert 0.97 < ratio.min() and ratio.max() < 1.03, np.round(ratio, 3)
    # the dots are there: the top rows (dots against the wall-less sky) differ from Cycles'
    # empty-scene look only if the spheres render; their blocks are bright red-lit spheres
    dots_max, sky = stored["points: dots max, sky corner mean"]
    assert dots_max > 3 * sky


def _point_info_scene(bpy):
    """_scene with the object moved up 0.3 m and its colour driven by Point Info."""
    sc, dots = _scene(bpy)
    dots.location.z += 0.3
    nt = bpy.data.materials["Red"].node_tree
    info = nt.nodes.new("ShaderNodePointInfo")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.02, 0.02, 0.02, 1.0)  # dark to light: the
    ramp.color_ramp.elements[1].color = (0.9, 0.9, 0.9, 1.0)  # luminance shows Random
    nt.links.new(info.outputs["Random"], ramp.inputs["Fac"])
    xyz = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(info.outputs["Position"], xyz.inputs[0])
    height = nt.nodes.new("ShaderNodeMath")
    height.operation = "MULTIPLY"
    height.inputs[1].default_value = 0.5
    nt.links.new(xyz.outputs["Z"], height.inputs[0])
    size = nt.nodes.new("ShaderNodeMath")
    size.operation = "MULTIPLY"
    size.inputs[1].default_value = 10.0
    nt.links.new(info.outputs["Radius"], size.inputs[0])
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    nt.links.new(height.outputs[0], mix.inputs["Factor"])
    nt.links.new(ramp.outputs["Color"], mix.inputs[6])
    nt.links.new(size.outputs[0], mix.inputs[7])  # 0.8: grey
    nt.links.new(mix.outputs[2], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return sc


def test_point_info_colours_the_points_as_in_cycles(bpy_addon, tmp_path):
    """Point Info's Random (through a Color Ramp), Radius and Position (world z, the
    object moved up 0.3 m) drive the points' colour, against Cycles."""
    ours = ours_luminance(bpy_addon, _point_info_scene(bpy_addon), tmp_path)
    ref = stored_cycles_means(REF_PATH)["point info"].reshape(6, 8)
    from addon import engine
    assert not [w for w in engine.last_render["warnings"] if "Point Info" in w]
    ratio = block_means(ours) / ref
    assert 0.99 < ours.mean() / ref.mean() < 1.01
    assert 0.96 < ratio.min() and ratio.max() < 1.04, np.round(ratio, 3)


def _cycles_blocks(bpy, tmp_path):
    """Cycles' side, rendered now: the 12 x 12 block means (6 x 8 flattened) of both
    scenes, and the plain points' brightest pixel among the dots (rows :24, columns
    24:72) and mean of the sky corner (rows and columns :8)."""
    ref = cycles_luminance(bpy, _scene(bpy)[0], tmp_path)
    out = {"points": block_means(ref).ravel().tolist(),
           "points: dots max, sky corner mean": [float(ref[:24, 24:72].max()),
                                                 float(ref[:8, :8].mean())]}
    info = cycles_luminance(bpy, _point_info_scene(bpy), tmp_path)
    out["point info"] = block_means(info).ravel().tolist()
    return out


@pytest.mark.slow
def test_stored_point_blocks_are_cycles_now(bpy_addon, tmp_path):
    """The stored numbers are what this Blender's Cycles renders (2 renders at 256 spp)."""
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_blocks(bpy_addon, tmp_path))


if __name__ == "__main__":  # write the stored numbers: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_blocks, cycles_samples=256, seed=0)
