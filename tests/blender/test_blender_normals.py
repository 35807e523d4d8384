"""Shading normals: the export gives the normals Cycles shades with (addon/normals.py), in
every way a mesh can be smooth or flat, checked as arrays against the rule read from
Cycles' source and against live Cycles' Normal pass and image.

The case that made this file: a cylinder with smooth sides and flat caps, no edge marked
sharp. Python's Mesh.normals_domain says CORNER and corner_normals keeps the side normals
horizontal (the caps split the rim); Cycles syncs it as POINT and tilts the side normals
towards the caps (vertex normals over all faces), which puts a rough metal cylinder's
highlight on its side: 0.109 (ours, corner normals) against 0.527 (Cycles) in a user's
trial scene.
"""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import (ROOT, cheap, cycles_plain, project, read_layers, render_exr)

pytestmark = pytest.mark.blender

SEGMENTS = 16


def _mb():
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    return mb


def _cylinder(name, mat, location=(0, 0, 0), smooth_sides=True, flat_caps=True,
              rotation=(0, 0, 0), link=True):
    """Radius 0.8, height 1.6 cylinder (16 sides, capped), sides smooth / caps flat as asked."""
    import bmesh
    import bpy
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cone(bm, cap_ends=True, segments=SEGMENTS, radius1=0.8, radius2=0.8,
                          depth=1.6)
    bm.to_mesh(me)
    bm.free()
    sides = np.array([len(p.vertices) == 4 for p in me.polygons])
    smooth = np.where(sides, smooth_sides, not flat_caps)
    me.polygons.foreach_set("use_smooth", smooth)
    me.update()
    if mat is not None:
        me.materials.append(mat)
    obj = bpy.data.objects.new(name, me)
    obj.location, obj.rotation_euler = location, rotation
    if link:
        bpy.context.scene.collection.objects.link(obj)
    return obj


def _mark_rims_sharp(me):
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    ev = np.empty(len(me.edges) * 2, np.int32)
    me.edges.foreach_get("vertices", ev)
    z = co.reshape(-1, 3)[ev.reshape(-1, 2), 2]
    me.edges.foreach_set("use_edge_sharp", np.abs(z[:, 0] - z[:, 1]) < 1e-6)
    me.update()


def build_cases(bpy, mat):
    """One object per way of being smooth or flat, in a row along x (2.2 m apart).
    Returns [(case name, object, x)]."""
    mb = _mb()
    out = []

    def place(name, obj):
        x = -2.2 * 4 + 2.2 * len(out)
        obj.location = (x, 0.0, 0.0)
        out.append((name, obj, x))

    place("smooth", _cylinder("smooth", mat, flat_caps=False))
    place("flat", _cylinder("flat", mat, smooth_sides=False))
    place("mixed", _cylinder("mixed", mat))
    sharp = _cylinder("sharp_rims", mat)
    _mark_rims_sharp(sharp.data)
    place("sharp_rims", sharp)
    custom = _cylinder("custom", mat)
    co = np.empty(len(custom.data.vertices) * 3, np.float32)
    custom.data.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    # Custom normals: every vertex's normal points away from the centre (a sphere's).
    custom.data.normals_split_custom_set_from_vertices(
        (co / np.linalg.norm(co, axis=1, keepdims=True)).tolist())
    place("custom", custom)
    by_angle = _cylinder("by_angle", mat, flat_caps=False)
    with bpy.context.temp_override(object=by_angle, active_object=by_angle,
                                   selected_objects=[by_angle],
                                   selected_editable_objects=[by_angle]):
        bpy.ops.object.shade_auto_smooth(angle=math.radians(30.0))  # Smooth by Angle
    place("by_angle", by_angle)
    subsurf = _cylinder("subsurf", mat)
    mod = subsurf.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 1
    place("subsurf", subsurf)
    # Every edge sharp while the faces stay marked smooth in a sharp_face attribute: the
    # domain is FACE, yet Cycles shades the smooth faces with vertex normals.
    cube = mb.box("all_sharp_edges", 1.4, 1.4, 1.4, mat, rotation=(0.4, 0.3, 0.5))
    cube.data.polygons.foreach_set("use_smooth", np.ones(len(cube.data.polygons), bool))
    cube.data.edges.foreach_set("use_edge_sharp", np.ones(len(cube.data.edges), bool))
    cube.data.update()
    place("all_sharp_edges", cube)
    # A collection instance of a mixed cylinder, tilted towards the camera.
    coll = bpy.data.collections.new("instanced")
    src = _cylinder("instanced_src", mat, link=False)
    coll.objects.link(src)
    empty = bpy.data.objects.new("instance", None)
    empty.instance_type = "COLLECTION"
    empty.instance_collection = coll
    empty.rotation_euler = (-0.5, 0.0, 0.3)
    bpy.context.scene.collection.objects.link(empty)
    place("instance", empty)
    return out


@pytest.fixture(scope="module")
def cases(bpy_addon):
    bpy = bpy_addon
    mb = _mb()
    scene = mb.reset()
    grey = mb.material("grey", "diffuse", (0.6, 0.6, 0.6))
    out = build_cases(bpy, grey)
    mb.set_world((0.5, 0.5, 0.5))
    mb.camera((0.0, -13.0, 5.0), (0.0, 0.0, 0.0), fov_deg=70.0)
    scene.render.resolution_x, scene.render.resolution_y = 200, 64
    return scene, out


def _exported(bpy, obj):
    """(local geometry, the object's evaluated mesh normals as Blender reports them)."""
    from addon import export
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    return export.extract_geometry(ev)


def _corner(normals, faces):
    return normals[faces] if normals.ndim == 2 else normals


def test_exported_normals_follow_cycles_rule(cases, bpy_addon):
    """Per case, the exported corner normals are the arrays Cycles reads (blender/mesh.cpp
    create_mesh with Mesh::normals_domain(true)): vertex normals on smooth triangles of a
    POINT/FACE mesh, the triangle's own normal on flat ones, corner_normals for CORNER."""
    bpy = bpy_addon
    _, out = cases
    objs = {name: obj for name, obj, _ in out}
    dg = bpy.context.evaluated_depsgraph_get()

    def blender_arrays(obj):
        ev = obj.evaluated_get(dg)
        me = ev.to_mesh()
        try:
            nt = len(me.loop_triangles)
            f = np.empty(nt * 3, np.int32)
            me.loop_triangles.foreach_get("vertices", f)
            lp = np.empty(nt * 3, np.int32)
            me.loop_triangles.foreach_get("loops", lp)
            sm = np.empty(nt, bool)
            me.loop_triangles.foreach_get("use_smooth", sm)
            tn = np.empty(nt * 3, np.float32)
            me.loop_triangles.foreach_get("normal", tn)
            vn = np.empty(len(me.vertices) * 3, np.float32)
            me.vertex_normals.foreach_get("vector", vn)
            cn = np.empty(len(me.loops) * 3, np.float32)
            me.corner_normals.foreach_get("vector", cn)
            return dict(faces=f.reshape(-1, 3), smooth=sm, tri=tn.reshape(-1, 3),
                        vertex=vn.reshape(-1, 3)[f.reshape(-1, 3)],
                        corner=cn.reshape(-1, 3)[lp.reshape(-1, 3)],
                        domain=me.normals_domain)
        finally:
            ev.to_mesh_clear()

    for name in ("smooth", "flat", "mixed", "sharp_rims", "custom", "by_angle", "subsurf",
                 "all_sharp_edges"):
        g = _exported(bpy, objs[name])
        b = blender_arrays(objs[name])
        if name == "flat":
            assert g.normals is None, name
            continue
        got = _corner(g.normals, g.faces)
        if name in ("sharp_rims", "custom", "by_angle"):
            assert b["domain"] == "CORNER", name
            want = b["corner"]
        elif name == "all_sharp_edges":
            assert b["domain"] == "FACE" and b["smooth"].all(), name
            want = b["vertex"]
        else:  # smooth, mixed, subsurf: POINT for Cycles
            want = np.where(b["smooth"][:, None, None], b["vertex"], b["tri"][:, None, :])
        np.testing.assert_allclose(got, want, atol=2e-6, err_msg=name)
    # The trial's cylinder: Python reads CORNER with horizontal side normals; the side
    # corners at the rims now lean towards the caps (about 42 degrees for 16 sides).
    g = _exported(bpy, objs["mixed"])
    z = np.abs(_corner(g.normals, g.faces)[..., 2])
    assert blender_arrays(objs["mixed"])["domain"] == "CORNER"
    assert np.count_nonzero(z == 1.0) == 3 * 2 * (SEGMENTS - 2)  # the flat caps
    assert z[z < 0.999].max() > 0.6                              # the sides' rims


def test_instanced_normals_are_the_prototypes_turned(cases, bpy_addon):
    """An instance of the mixed cylinder: the world normals are the prototype's normals
    rotated with the instance (the mixed rule survives instancing)."""
    bpy = bpy_addon
    from addon import export
    _, out = cases
    dg = bpy.context.evaluated_depsgraph_get()
    seen = 0
    for inst in dg.object_instances:
        if not inst.is_instance or inst.object.name != "instanced_src":
            continue
        g = export.extract_geometry(inst.object)
        m = np.array(inst.matrix_world, np.float64)
        _, faces, normals, _ = export.transform_geometry(g, m)
        local = _corner(g.normals, g.faces)
        np.testing.assert_allclose(_corner(normals, faces), local @ m[:3, :3].T, atol=1e-6)
        z = np.abs(local[..., 2])
        assert z[z < 0.999].max() > 0.6  # the side leans towards the caps, as "mixed"
        seen += 1
    assert seen == 1


def _normal_pass(bpy, scene, engine, path):
    scene.render.engine = engine
    scene.render.film_transparent = True
    scene.view_layers[0].use_pass_normal = True
    if engine == "CYCLES":
        cycles_plain(scene, 16, 1)
    else:
        cheap(scene, spp=16, photons=2_000, caustic_photons=200)
    return read_layers(render_exr(bpy, scene, path, multilayer=True))


def test_normal_pass_matches_cycles(cases, bpy_addon, tmp_path):
    """Live Cycles' Normal pass against ours, object by object (inner pixels only: both
    films fully covered in a 3x3 neighbourhood; 16 spp each, 200 x 64). Measured with this
    export: median 0.2-0.6 degrees, 90th percentile 0.6-3.9. With the normals Python
    reports (the export before, corner normals) the median / 90th percentile were 18 / 35
    degrees on the mixed cylinder, 19 / 32 on its instance, 9 / 17 subdivided and 32 / 42
    on the all-sharp-edges cube."""
    bpy = bpy_addon
    scene, out = cases
    cyc = _normal_pass(bpy, scene, "CYCLES", tmp_path / "cycles.exr")
    ours = _normal_pass(bpy, scene, "PHOTONMAP", tmp_path / "ours.exr")
    nc, no = cyc["Normal"][..., :3], ours["Normal"][..., :3]
    cover = (cyc["Combined"][..., 3] > 0.999) & (ours["Combined"][..., 3] > 0.999)
    inner = cover.copy()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            inner[1:-1, 1:-1] &= cover[1 + dr:cover.shape[0] - 1 + dr,
                                       1 + dc:cover.shape[1] - 1 + dc]
    cos = np.clip(np.sum(nc * no, axis=-1) / np.maximum(
        np.linalg.norm(nc, axis=-1) * np.linalg.norm(no, axis=-1), 1e-12), -1, 1)
    angle = np.degrees(np.arccos(cos))
    report = {}
    for name, _, x in out:
        c0 = project(bpy, scene, (x - 1.0, 0, 0))[1]
        c1 = project(bpy, scene, (x + 1.0, 0, 0))[1]
        mask = inner.copy()
        mask[:, :max(c0, 0)] = False
        mask[:, c1 + 1:] = False
        a = angle[mask]
        assert a.size > 40, (name, a.size)
        report[name] = (float(np.median(a)), float(np.percentile(a, 90)))
    print(report)
    for name, (med, p90) in report.items():
        assert med < 2.0 and p90 < 8.0, (name, med, p90, report)


def _metal_cylinder_scene(bpy):
    """The trial's case, small: a rough metal cylinder (Principled, metallic 1, roughness
    0.4) with smooth sides and flat caps, no sharp edge, under an area light, black world;
    the camera sees the side's highlight (Cycles) where the corner normals see none."""
    mb = _mb()
    scene = mb.reset()
    metal = mb.material("metal", "principled", (0.8, 0.8, 0.82), roughness=0.4, metallic=1.0)
    _cylinder("Metal", metal)
    mb.light("Area", "AREA", (0.0, -2.5, 2.6), 300.0, look_at=(0, 0, 0.4), size=1.0)
    mb.camera((0.0, -4.5, 0.6), (0.0, 0.0, 0.1), fov_deg=35.0)
    scene.render.resolution_x, scene.render.resolution_y = 48, 40
    scene.render.film_transparent = True
    return scene


def _side_mean(bpy, scene, rgba):
    """Mean luminance of the side's pixels (inner columns, between the rims)."""
    from blender_helpers import luminance
    r0 = project(bpy, scene, (0, -0.8, 0.7))[0]
    r1 = project(bpy, scene, (0, -0.8, -0.7))[0]
    c0 = project(bpy, scene, (-0.55, -0.6, 0.0))[1]
    c1 = project(bpy, scene, (0.55, -0.6, 0.0))[1]
    return float(luminance(rgba[r0:r1 + 1, c0:c1 + 1, :3]).mean())


def test_metal_cylinder_side_matches_cycles(bpy_addon, tmp_path):
    """The side of the trial's metal cylinder as bright as in live Cycles (within 5 %):
    measured 1.050 against Cycles' 1.054 (256 spp); with the corner normals Python
    reports it read 0.128, x0.12 (the trial's scene: 0.109 against 0.527)."""
    bpy = bpy_addon
    from blender_helpers import read_rgba
    scene = _metal_cylinder_scene(bpy)
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 256, 1)
    ref = _side_mean(bpy, scene, read_rgba(bpy, render_exr(bpy, scene, tmp_path / "c.exr")))
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=64, photons=2_000, caustic_photons=2_000)
    ours = _side_mean(bpy, scene, read_rgba(bpy, render_exr(bpy, scene, tmp_path / "o.exr")))
    print("side luminance: ours", ours, "Cycles", ref)
    assert ref > 0.05
    assert abs(ours / ref - 1.0) < 0.05, (ours, ref)
