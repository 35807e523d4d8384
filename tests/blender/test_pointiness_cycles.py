"""Geometry node > Pointiness (and the Attribute node of its standard name) against
Cycles, pixel by pixel (issue 14): Cycles' per-vertex curvature (blender/mesh.cpp
attr_create_pointiness: welded duplicates, the angle of the normal to the mean edge, one
blur step; engine/pointiness.py), interpolated over the triangles. It read the socket's
own value before (a warning, the node unread).

The harness of test_color_nodes_cycles.py (an emissive surface whose colour is the node
under test, lifted by LIFT; samples at the pixel centres in both renderers), on a bumpy
subdivided grid (seeded heights), the same grid with its edges split (duplicate vertices
that Cycles welds), Suzanne under a Subdivision Surface modifier (the evaluated mesh) and a
cube, seen from above."""
import numpy as np
import pytest

from test_color_nodes_cycles import LIFT, _plane_scene

pytestmark = pytest.mark.blender

W = H = 32


def _bumpy_grid(bpy, mat, split=False):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=10, y_subdivisions=10, size=2.0)
    ob = bpy.context.object
    me = ob.data
    co = np.empty(3 * len(me.vertices), np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    co[:, 2] = np.random.default_rng(35).uniform(-0.12, 0.12, len(co))
    me.vertices.foreach_set("co", co.ravel())
    me.update()
    me.materials.append(mat)
    if split:
        mod = ob.modifiers.new("Split", "EDGE_SPLIT")
        mod.split_angle = np.radians(10.0)
    return ob


def _monkey(bpy, mat):
    """Suzanne under a Subdivision Surface modifier (the evaluated mesh), her face up:
    concave eye sockets and mouth, convex brows, nose and ears."""
    bpy.ops.mesh.primitive_monkey_add(size=1.6)
    ob = bpy.context.object
    ob.rotation_euler = (np.radians(90.0), 0.0, np.radians(180.0))
    ob.modifiers.new("Subdivision", "SUBSURF").levels = 1
    ob.data.materials.append(mat)
    return ob


def _cube(bpy, mat):
    bpy.ops.mesh.primitive_cube_add(size=1.2)
    ob = bpy.context.object
    ob.rotation_euler = (0.6, 0.5, 0.2)
    ob.data.materials.append(mat)
    return ob


SHAPES = {"bumpy_grid": _bumpy_grid,
          "bumpy_grid_split": lambda bpy, mat: _bumpy_grid(bpy, mat, split=True),
          "monkey": _monkey, "cube": _cube}


def _pointiness(source):
    def build(nodes, links):
        if source == "geometry":
            return nodes.new("ShaderNodeNewGeometry").outputs["Pointiness"]
        a = nodes.new("ShaderNodeAttribute")
        a.attribute_type, a.attribute_name = "GEOMETRY", "pointiness"
        return a.outputs["Color"]
    return build


@pytest.mark.parametrize("shape,source", [("bumpy_grid", "geometry"),
                                          ("bumpy_grid_split", "geometry"),
                                          ("monkey", "geometry"),
                                          ("cube", "geometry"),
                                          ("bumpy_grid", "attribute")])
def test_pointiness_matches_cycles_pixel_by_pixel(fresh_scene, bpy_addon, tmp_path, shape,
                                                  source):
    bpy = bpy_addon
    scene = fresh_scene
    mat = _plane_scene(bpy, scene, _pointiness(source), LIFT)
    bpy.data.objects.remove(bpy.context.object)  # the harness' plane
    SHAPES[shape](bpy, mat)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3]
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3]
    # The surface away from its outline (the background is black; a pixel on the
    # outline has samples on both sides, which the two renderers place differently).
    inside = np.pad(ref[..., 0] > 0.5 * LIFT, 1)
    seen = np.logical_and.reduce([inside[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
                                  for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    ours, ref = ours[seen] - LIFT, ref[seen] - LIFT
    err = np.abs(ours - ref)
    print(f"{shape} ({source}): {seen.sum()} pixels, Cycles {ref.min():.4f} .. "
          f"{ref.max():.4f}, |ours - Cycles| max {err.max():.5f}, 99 % "
          f"{np.percentile(err, 99):.5f}")
    assert seen.sum() > 0.25 * W * H
    if shape == "cube":  # every corner: acos(-1 / sqrt(3)) / pi, so every pixel
        np.testing.assert_allclose(ref, np.arccos(-1.0 / np.sqrt(3.0)) / np.pi, atol=1e-4)
    else:  # pointiness varies over the surface (a few % on smooth meshes: Cycles' blur)
        assert np.ptp(ref) > 0.02
    # The samples sit within 0.01 px of the centres, where the value changes by up to
    # ~0.06 a pixel on the bumpy grid: 1 % of the range covers where they fall.
    assert err.max() <= 0.01 * np.ptp(ref) + 1e-5
