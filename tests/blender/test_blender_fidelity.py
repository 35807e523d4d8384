"""Blender fidelity (issue 12): what Cycles renders, we render, or we say why not.

Each test builds a small scene in bpy and checks a number that fails on the fault it
guards: triangle counts against Blender's own evaluated meshes (each evaluated geometry
exported exactly once), light footprints and brightness against Cycles (CPU, no
denoising, box filter), and ray-visibility flags in the rendered image.
"""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender


# --- scene building -----------------------------------------------------------------

def _principled(bpy, name, rgb):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    node = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Base Color"].default_value = (*rgb, 1.0)
    node.inputs["Roughness"].default_value = 1.0
    m.diffuse_color = (*rgb, 1.0)
    return m


def _gn_balls_on_curve(bpy, ball, realize, location):
    """A Bezier circle whose Geometry Nodes put `ball` on 6 points (realized or as
    instances) and keep the curve itself: the issue's red-balls case."""
    bpy.ops.curve.primitive_bezier_circle_add(location=location)
    curve = bpy.context.object
    ng = bpy.data.node_groups.new("BallsOnCurve", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = ng.nodes, ng.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    resample = nodes.new("GeometryNodeResampleCurve")
    resample.inputs["Count"].default_value = 6
    on_points = nodes.new("GeometryNodeInstanceOnPoints")
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs[0].default_value = ball
    join = nodes.new("GeometryNodeJoinGeometry")
    links.new(gin.outputs[0], resample.inputs[0])
    links.new(resample.outputs[0], on_points.inputs["Points"])
    links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
    out = on_points.outputs[0]
    if realize:
        r = nodes.new("GeometryNodeRealizeInstances")
        links.new(out, r.inputs[0])
        out = r.outputs[0]
    links.new(out, join.inputs[0])
    links.new(gin.outputs[0], join.inputs[0])
    links.new(join.outputs[0], gout.inputs[0])
    curve.modifiers.new("GN", "NODES").node_group = ng
    return curve


def _evaluated_triangles(bpy, obj):
    """Loop triangles of one evaluated copy of obj's geometry (Blender's own count),
    without the zero-area ones (text and NURBS poles have some), which the engine's scene
    model drops with a warning (Cycles renders nothing there either)."""
    dg = bpy.context.evaluated_depsgraph_get()
    me = bpy.data.meshes.new_from_object(obj.evaluated_get(dg))
    try:
        me.calc_loop_triangles()
        n = len(me.loop_triangles)
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        tri = np.empty(n * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tri)
        p = co.reshape(-1, 3).astype(np.float64)[tri.reshape(-1, 3)]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
        scale = np.maximum(np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1))
        return int(np.count_nonzero(area2 > 1e-12 * scale * scale))
    finally:
        bpy.data.meshes.remove(me)


def _export(bpy, width=32, height=24):
    from addon import export
    from addon.core import load_engine
    return export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                               width=width, height=height)


def _camera(bpy, location, rotation, lens=50.0):
    cd = bpy.data.cameras.new("Cam")
    cd.lens = lens
    cam = bpy.data.objects.new("Cam", cd)
    cam.location, cam.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    return cam


# --- item 3: each evaluated geometry exported exactly once --------------------------

def test_each_geometry_exported_once(fresh_scene, bpy_addon):
    bpy = bpy_addon
    red = _principled(bpy, "Red", (0.8, 0.02, 0.02))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.1, segments=8, ring_count=4,
                                         location=(0, 0, -20))
    ball = bpy.context.object
    ball.data.materials.append(red)
    for c in ball.users_collection:  # only its instances are in the scene
        c.objects.unlink(ball)
    bpy.data.collections.new("Library").objects.link(ball)
    ball_tris = len(ball.data.polygons) * 2 - 16  # 8x4 UV sphere: 16 triangle fans
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 0))
    cube = bpy.context.object
    bpy.ops.curve.primitive_bezier_circle_add(location=(3, 0, 0))
    curve = bpy.context.object
    curve.data.bevel_depth = 0.1
    bpy.ops.object.text_add(location=(6, 0, 0))
    text = bpy.context.object
    bpy.ops.object.metaball_add(location=(9, 0, 0))
    meta = bpy.context.object
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(location=(12, 0, 0))
    nurbs = bpy.context.object
    realized = _gn_balls_on_curve(bpy, ball, True, (15, 0, 0))
    instanced = _gn_balls_on_curve(bpy, ball, False, (18, 0, 0))
    coll = bpy.data.collections.new("Held")
    bpy.ops.mesh.primitive_cube_add(location=(0, 30, 0))
    held = bpy.context.object
    held.name = "Held"
    for c in held.users_collection:
        c.objects.unlink(held)
    coll.objects.link(held)
    for x in (21.0, 24.0):
        e = bpy.data.objects.new(f"Inst{x:.0f}", None)
        e.instance_type, e.instance_collection, e.location = "COLLECTION", coll, (x, 0, 0)
        bpy.context.scene.collection.objects.link(e)
    _camera(bpy, (0, -10, 0), (math.radians(90), 0, 0))

    expect = {
        "Cube": _evaluated_triangles(bpy, cube),
        curve.name: _evaluated_triangles(bpy, curve),
        text.name: _evaluated_triangles(bpy, text),
        meta.name: _evaluated_triangles(bpy, meta),
        nurbs.name: _evaluated_triangles(bpy, nurbs),
        realized.name: _evaluated_triangles(bpy, realized),  # the realized balls
        instanced.name: 6 * ball_tris,
        "Held": 2 * 12,
    }
    assert ball_tris == 48 and expect["Cube"] == 12 and expect[realized.name] == 6 * 48
    assert min(expect.values()) > 0, expect

    scene, info = _export(bpy)
    got = dict.fromkeys(expect, 0)
    for m in scene.meshes:
        owner = next((k for k in sorted(expect, key=len, reverse=True)
                      if m.name == k or m.name.startswith(k + "/") or f"/{k}#" in m.name),
                     m.name)
        got[owner] = got.get(owner, 0) + len(m.faces)
    assert got == expect
    assert info["triangles"] == sum(expect.values())

    # The material case: balls made by Geometry Nodes keep their own (red) material.
    for m in scene.meshes:
        if m.name.startswith((realized.name + "/", instanced.name + "/")):
            for name in np.unique(np.asarray(m.materials)[m.material_ids]):
                np.testing.assert_allclose(scene.materials[name].base_color,
                                           (0.8, 0.02, 0.02), atol=1e-3)
