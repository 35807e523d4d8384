"""Blender fidelity (issue 12): what Cycles renders, we render, or we say why not.

Each test builds a small scene in bpy and checks a number that fails on the fault it
guards: triangle counts against Blender's own evaluated meshes (each evaluated geometry
exported exactly once), light footprints and brightness against Cycles (CPU, no
denoising, box filter), and ray-visibility flags in the rendered image.
"""
import math

import numpy as np
import pytest
from tools.canonical_mesh import primitive_uv_sphere_add

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
    primitive_uv_sphere_add(radius=0.1, segments=8, ring_count=4,
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
                      if m.name == k or m.name.startswith((k + "/", k + "#"))
                      or f"/{k}#" in m.name),
                     m.name)
        got[owner] = got.get(owner, 0) + len(m.faces)
    assert got == expect
    assert info["triangles"] == sum(expect.values())

    # The material case: balls made by Geometry Nodes keep their own (red) material.
    balls = [m for m in scene.meshes
             if m.name.startswith(tuple(f"{o.name}{sep}" for o in (realized, instanced)
                                        for sep in "/#"))]
    assert len(balls) >= 2, [m.name for m in scene.meshes]
    for m in balls:
        for name in np.unique(np.asarray(m.materials)[m.material_ids]):
            np.testing.assert_allclose(scene.materials[name].base_color,
                                       (0.8, 0.02, 0.02), atol=1e-3)


# --- rendering: ours and Cycles on the same bpy scene ---------------------------------

def _render(bpy, scene, path, engine="PHOTONMAP", spp=16, bounces=0):
    """Linear RGBA (H, W, 4), rows top down. Cycles: CPU, no denoising, box filter 1 px,
    no clamping (the settings that change its image, docs/units.md); `bounces` limits
    both engines to direct light (0) or allows indirect light."""
    from blender_helpers import cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    # Cycles' pixel filter setting, which our add-on reads as well
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    if engine == "CYCLES":
        cycles_plain(scene, spp, bounces)
    else:
        from blender_helpers import cheap
        cheap(scene, spp=spp, photons=20_000, caustic_photons=0)
        scene.photonmap.photon_mapping = bounces > 0
    return read_rgba(bpy, render_exr(bpy, scene, path))


def _floor_scene(bpy, size=(48, 48), ortho=8.0):
    """A 20 m white diffuse floor seen from straight above by an orthographic camera
    (ortho_scale metres across), black world."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=20)
    floor = bpy.context.object
    floor.data.materials.append(_principled(bpy, "White", (0.8, 0.8, 0.8)))
    cam = _camera(bpy, (0, 0, 10), (0, 0, 0))
    cam.data.type, cam.data.ortho_scale = "ORTHO", ortho
    world = bpy.data.worlds.new("Black")
    scene.world = world
    for n in world.node_tree.nodes:
        if n.type == "BACKGROUND":
            n.inputs["Strength"].default_value = 0.0
    return scene


def _light(bpy, kind, location, scale=(1, 1, 1), rotation=(0, 0, 0), parent=None, **props):
    ld = bpy.data.lights.new(kind.title(), kind)
    for k, v in props.items():
        setattr(ld, k, v)
    obj = bpy.data.objects.new(kind.title(), ld)
    obj.location, obj.scale, obj.rotation_euler = location, scale, rotation
    obj.parent = parent
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _lit_extent(img, frac=0.5):
    """Width and height in pixels of the region brighter than frac x the maximum."""
    lum = img[..., :3].mean(axis=2)
    ys, xs = np.nonzero(lum > frac * lum.max())
    return xs.max() - xs.min() + 1, ys.max() - ys.min() + 1


# --- item 4: light object transforms read as Cycles reads them ----------------------

@pytest.mark.parametrize("scale", [(2.0, 0.5, 1.0), (1.0, 1.0, 2.0), (-1.5, 1.0, 1.0)])
def test_spot_scale_stretches_cone(fresh_scene, bpy_addon, tmp_path, scale):
    """Cycles >= 3.5 stretches the spot cone by the object scale: (2, 0.5, 1) lights a
    4:1 ellipse (tan-space half axes 2t and t/2), z scale 2 halves it."""
    bpy = bpy_addon
    scene = _floor_scene(bpy)
    _light(bpy, "SPOT", (0, 0, 3), scale=scale, energy=1000.0,
           spot_size=math.radians(40), spot_blend=0.0)
    ours = _render(bpy, scene, tmp_path / "ours.exr", spp=4)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", engine="CYCLES", spp=4)
    # 8 m across 48 px; round spot: tan(20 deg) * 3 m radius = 1.09 m = 13 px across.
    sx, sy, sz = (abs(s) for s in scale)
    expect = (13.1 * sx / sz, 13.1 * sy / sz)
    for img in (ref, ours):
        w, h = _lit_extent(img)
        assert abs(w - expect[0]) <= 2.0 and abs(h - expect[1]) <= 2.0, (w, h, expect)
    lit = ref[..., :3].mean(axis=2) > 0.05
    rel = np.abs(ours[..., :3] - ref[..., :3]).mean() / ref[..., :3][lit].mean()
    assert rel < 0.08, rel


def _sheared_parent(bpy):
    """An empty scaled (2, 1, 1): a child rotated about Z gets a sheared world matrix."""
    e = bpy.data.objects.new("Shear", None)
    e.scale = (2.0, 1.0, 1.0)
    bpy.context.scene.collection.objects.link(e)
    return e


LIGHT_CASES = {
    "area_nonuniform": lambda bpy: _light(bpy, "AREA", (0, 0, 1.5), scale=(2.0, 0.5, 1.0),
                                          energy=200.0, size=1.0),
    "area_negative_x": lambda bpy: _light(bpy, "AREA", (0.5, 0, 1.5), scale=(-2.0, 1.0, 1.0),
                                          rotation=(0.4, 0, 0), energy=200.0, size=1.0,
                                          shape="RECTANGLE", size_y=0.5),
    "area_negative_z": lambda bpy: _light(bpy, "AREA", (0, 0, 1.5), scale=(1.0, 1.0, -1.0),
                                          energy=200.0, size=1.0),
    "area_shear": lambda bpy: _light(bpy, "AREA", (0, 0, 0.75), rotation=(0, 0, 0.6),
                                     parent=_sheared_parent(bpy), energy=200.0, size=1.0),
    "disk_nonuniform": lambda bpy: _light(bpy, "AREA", (0, 0, 1.5), scale=(2.0, 0.5, 3.0),
                                          energy=200.0, shape="ELLIPSE", size=1.0,
                                          size_y=0.5),
    "point_radius_scaled": lambda bpy: _light(bpy, "POINT", (0, 0, 1.0), scale=(3.0, 1.0, 2.0),
                                              energy=200.0, shadow_soft_size=0.3),
    "sun_scaled": lambda bpy: _light(bpy, "SUN", (0, 0, 3), scale=(2.0, 0.5, 3.0),
                                     rotation=(0.5, 0, 0), energy=2.0),
    "spot_sheared": lambda bpy: _light(bpy, "SPOT", (0, 0, 1.5), rotation=(0, 0, 0.6),
                                       parent=_sheared_parent(bpy), energy=500.0,
                                       spot_size=math.radians(50), spot_blend=0.1),
}


@pytest.mark.parametrize("case", sorted(LIGHT_CASES))
def test_light_transform_matches_cycles(fresh_scene, bpy_addon, tmp_path, case):
    """Every light kind under scale, negative scale and shear lights the floor (and a
    small occluder's shadow) as Cycles does: direct light only, per-pixel comparison."""
    bpy = bpy_addon
    scene = _floor_scene(bpy, size=(40, 40), ortho=6.0)
    bpy.ops.mesh.primitive_cube_add(size=0.4, location=(0.6, 0.4, 0.2))
    LIGHT_CASES[case](bpy)
    ours = _render(bpy, scene, tmp_path / "ours.exr", spp=16)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", engine="CYCLES", spp=64)
    lum_o = ours[..., :3].mean(axis=2)
    lum_r = ref[..., :3].mean(axis=2)
    if case == "area_negative_z":  # emits upward: the floor stays dark in both
        assert lum_r.max() < 1e-3 and lum_o.max() < 1e-3
        return
    # Mean, and 4x4-block differences relative to the brightest block (noise of 16 / 64
    # spp averages out over a block; a wrong footprint or brightness does not).
    # Sheared area light: Cycles' floor is 11 % brighter than unsheared at 3 m, though the
    # emitter it shows (test below) has 1/sin(u, v) = 1.22x the area at radiance
    # P / (pi len_u len_v); its light sampling and its emitter disagree. We follow the
    # emitter (consistent for camera, shadow rays and photons): floor within 10 %.
    tol = 0.10 if case == "area_shear" else 0.05
    assert abs(lum_o.mean() / lum_r.mean() - 1.0) < tol, (lum_o.mean(), lum_r.mean())
    blocks = lambda a: a.reshape(10, 4, 10, 4).mean(axis=(1, 3))  # noqa: E731
    err = np.abs(blocks(lum_o) - blocks(lum_r)).max() / blocks(lum_r).max()
    # The sheared light's block error is systematic (the emitter vs Cycles' light
    # sampling, above): 0.146 at 256 spp, 0.148-0.150 at 64 spp; at 16 spp seeds 0-3 read
    # 0.130-0.156 (0.133-0.164 with the lights' points on the linear cell shift, before
    # glossy02), so 0.15 held at seed 0 by chance. Bounded above the systematic error.
    assert err < (0.20 if case == "area_shear" else 0.15), err


def test_sheared_area_light_seen_as_cycles_shows_it(fresh_scene, bpy_addon, tmp_path):
    """A rectangle light under a non-uniformly scaled parent, rotated: the camera below
    sees Cycles' emitter, the region |p.u| <= len_u/2, |p.v| <= len_v/2 (a parallelogram
    1.22x the area of the orthogonalised rectangle), at radiance P / (pi len_u len_v)."""
    bpy = bpy_addon
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 48
    scene.render.resolution_percentage = 100
    cam = _camera(bpy, (0, 0, -5), (math.pi, 0, 0))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 5.0
    light = LIGHT_CASES["area_shear"](bpy)
    light.visible_camera = True
    ours = _render(bpy, scene, tmp_path / "ours.exr", spp=4)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", engine="CYCLES", spp=4)
    lo, lr = ours[..., :3].mean(axis=2), ref[..., :3].mean(axis=2)
    mo, mr = lo > 0.5 * lr.max(), lr > 0.5 * lr.max()
    assert mr.sum() > 200 and (mo != mr).sum() <= 0.04 * mr.sum(), ((mo != mr).sum(), mr.sum())
    inner = mr & mo
    assert abs(lo[inner].mean() / lr[inner].mean() - 1.0) < 0.03


# --- item 1: ray visibility, holdout, indirect-only -----------------------------------

def _cube_on_floor(bpy, color=(0.8, 0.02, 0.02), size=(48, 36)):
    """A red 1 m cube 0.5 m above a white floor, a sun from above (slightly tilted, so
    the shadow falls beside the cube), a camera looking down at 45 degrees."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=12)
    bpy.context.object.data.materials.append(_principled(bpy, "White", (0.8, 0.8, 0.8)))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 1.0))
    cube = bpy.context.object
    cube.data.materials.append(_principled(bpy, "Red", color))
    _light(bpy, "SUN", (0, 0, 5), rotation=(0.0, math.radians(35), 0.0), energy=3.0, angle=0.0)
    _camera(bpy, (0, -6, 6), (math.radians(45), 0, 0), lens=35)
    world = bpy.data.worlds.new("Black")
    scene.world = world
    for n in world.node_tree.nodes:
        if n.type == "BACKGROUND":
            n.inputs["Strength"].default_value = 0.0
    return scene, cube


def _region(bpy, scene, center, half=1):
    from blender_helpers import project
    bpy.context.view_layer.update()  # matrix_world of objects made this test
    r, c = project(bpy, scene, center)
    return np.s_[r - half:r + half + 1, c - half:c + half + 1]


def _redness(img, sl):
    rgb = img[sl][..., :3].reshape(-1, 3).mean(axis=0)
    return rgb[0] / max(rgb[1], 1e-6), rgb


def test_camera_invisible_cube_shows_floor_and_shadow(fresh_scene, bpy_addon, tmp_path):
    """The issue's scene: a red cube with Visibility > Camera off is not drawn; its shadow
    is (Cycles: the floor behind the cube, and the shadow beside it)."""
    bpy = bpy_addon
    scene, cube = _cube_on_floor(bpy)
    cube.visible_camera = False
    top = _region(bpy, scene, (0, 0, 1.5))
    shadow = _region(bpy, scene, (-1.05, 0, 0.0))   # sun tilted 35 deg towards -x
    lit = _region(bpy, scene, (1.5, -1.0, 0.0))
    for engine, spp in (("CYCLES", 16), ("PHOTONMAP", 4)):
        img = _render(bpy, scene, tmp_path / f"{engine}.exr", engine=engine, spp=spp)
        red, rgb = _redness(img, top)
        assert red < 1.2, (engine, rgb)  # white floor, not the red cube
        s = img[shadow][..., :3].mean()
        f = img[lit][..., :3].mean()
        assert s < 0.2 * f, (engine, s, f)  # the invisible cube still casts its shadow


def test_shadow_invisible_cube_casts_no_shadow(fresh_scene, bpy_addon, tmp_path):
    bpy = bpy_addon
    scene, cube = _cube_on_floor(bpy)
    cube.visible_shadow = False
    top = _region(bpy, scene, (0, 0, 1.5))
    shadow = _region(bpy, scene, (-1.05, 0, 0.0))
    lit = _region(bpy, scene, (1.5, -1.0, 0.0))
    for engine, spp in (("CYCLES", 16), ("PHOTONMAP", 4)):
        img = _render(bpy, scene, tmp_path / f"{engine}.exr", engine=engine, spp=spp)
        assert _redness(img, top)[0] > 5.0  # the cube is drawn
        s = img[shadow][..., :3].mean()
        f = img[lit][..., :3].mean()
        assert s > 0.85 * f, (engine, s, f)  # but casts no shadow


@pytest.mark.parametrize("how,transparent", [("object", True), ("collection", True),
                                             ("object", False), ("material", True)])
def test_holdout_gives_alpha_zero(fresh_scene, bpy_addon, tmp_path, how, transparent):
    """Holdout (object, view-layer collection, or a material that is a Holdout shader: a
    product shot's holdout card): the cube's pixels have alpha 0 and no colour, with
    Film > Transparent or without (as Cycles); the rest is opaque."""
    bpy = bpy_addon
    scene, cube = _cube_on_floor(bpy)
    if how == "object":
        cube.is_holdout = True
    elif how == "material":
        mat = bpy.data.materials.new("HoldoutCard")
        nt = mat.node_tree
        for n in list(nt.nodes):
            if n.type != "OUTPUT_MATERIAL":
                nt.nodes.remove(n)
        hold = nt.nodes.new("ShaderNodeHoldout")
        nt.links.new(hold.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        cube.data.materials[0] = mat
    else:
        coll = bpy.data.collections.new("Held out")
        scene.collection.children.link(coll)
        for c in cube.users_collection:
            c.objects.unlink(cube)
        coll.objects.link(cube)
        bpy.context.view_layer.layer_collection.children["Held out"].holdout = True
    scene.render.film_transparent = transparent
    top = _region(bpy, scene, (0, 0, 1.5))
    lit = _region(bpy, scene, (1.5, -1.0, 0.0))
    for engine, spp in (("CYCLES", 16), ("PHOTONMAP", 4)):
        img = _render(bpy, scene, tmp_path / f"{engine}.exr", engine=engine, spp=spp)
        assert img[top][..., 3].max() < 0.05, (engine, img[top][..., 3])
        assert img[top][..., :3].max() < 0.05, (engine, img[top][..., :3])
        assert img[lit][..., 3].min() > 0.95 and img[lit][..., :3].mean() > 0.1
    if how == "material":
        # The export makes it an object holdout and says nothing is unsupported.
        from addon import export
        from addon.core import load_engine
        sc, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                    width=48, height=36)
        cube_mesh = [m for m in sc.meshes if m.name.startswith(cube.name)]
        assert cube_mesh and all(m.holdout for m in cube_mesh)
        texts = list(sc.warnings) + [w for m in sc.materials.values() for w in m.warnings]
        assert not [w for w in texts if "HOLDOUT" in w], texts


def test_indirect_only_collection(fresh_scene, bpy_addon, tmp_path):
    """An indirect-only collection is invisible to the camera but casts its shadow."""
    bpy = bpy_addon
    scene, cube = _cube_on_floor(bpy)
    coll = bpy.data.collections.new("Indirect")
    scene.collection.children.link(coll)
    for c in cube.users_collection:
        c.objects.unlink(cube)
    coll.objects.link(cube)
    bpy.context.view_layer.layer_collection.children["Indirect"].indirect_only = True
    top = _region(bpy, scene, (0, 0, 1.5))
    shadow = _region(bpy, scene, (-1.05, 0, 0.0))
    lit = _region(bpy, scene, (1.5, -1.0, 0.0))
    for engine, spp in (("CYCLES", 16), ("PHOTONMAP", 4)):
        img = _render(bpy, scene, tmp_path / f"{engine}.exr", engine=engine, spp=spp)
        assert _redness(img, top)[0] < 1.2, engine
        assert img[shadow][..., :3].mean() < 0.2 * img[lit][..., :3].mean(), engine


def _node_material(bpy, name, shader, **inputs):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    node = nt.nodes.new(shader)
    for k, v in inputs.items():
        node.inputs[k].default_value = v
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return m


def _glowing_cube_scene(bpy, floor_material):
    """An emissive red cube above a floor of the given material, grey world light."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 48, 36
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=12)
    bpy.context.object.data.materials.append(floor_material)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 1.0))
    cube = bpy.context.object
    cube.data.materials.append(_node_material(bpy, "Glow", "ShaderNodeEmission",
                                              Color=(1.0, 0.02, 0.02, 1.0), Strength=4.0))
    _camera(bpy, (0, -6, 6), (math.radians(45), 0, 0), lens=35)
    world = bpy.data.worlds.new("Grey")
    scene.world = world
    for n in world.node_tree.nodes:
        if n.type == "BACKGROUND":
            n.inputs["Color"].default_value = (0.2, 0.2, 0.2, 1.0)
            n.inputs["Strength"].default_value = 1.0
    return scene, cube


def test_glossy_invisible_cube_not_in_mirror(fresh_scene, bpy_addon, tmp_path):
    """A mirror floor does not reflect a cube with Visibility > Glossy off; the camera
    still sees the cube itself."""
    bpy = bpy_addon
    mirror = _node_material(bpy, "Mirror", "ShaderNodeBsdfGlossy", Roughness=0.0,
                            Color=(0.9, 0.9, 0.9, 1.0))
    scene, cube = _glowing_cube_scene(bpy, mirror)
    cube.visible_glossy = False
    direct = _region(bpy, scene, (0, -0.5, 1.0))
    mirrored = _region(bpy, scene, (0, -0.5, -1.0))  # the cube's mirror image
    for engine, spp in (("CYCLES", 16), ("PHOTONMAP", 4)):
        img = _render(bpy, scene, tmp_path / f"{engine}.exr", engine=engine, spp=spp, bounces=4)
        assert _redness(img, direct)[0] > 5.0, engine
        red, rgb = _redness(img, mirrored)
        assert red < 1.3, (engine, rgb)  # the grey sky, not the red cube


def test_transmission_invisible_cube_not_through_glass(fresh_scene, bpy_addon, tmp_path):
    """Seen through a glass slab, a cube with Visibility > Transmission off is absent."""
    bpy = bpy_addon
    scene, cube = _glowing_cube_scene(bpy, _principled(bpy, "White", (0.8, 0.8, 0.8)))
    cube.visible_transmission = False
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 2.2), scale=(6.0, 6.0, 0.05))
    bpy.context.object.data.materials.append(
        _node_material(bpy, "Glass", "ShaderNodeBsdfGlass", IOR=1.45, Roughness=0.0))
    top = _region(bpy, scene, (0, 0, 1.5))
    for engine, spp in (("CYCLES", 16), ("PHOTONMAP", 4)):
        img = _render(bpy, scene, tmp_path / f"{engine}.exr", engine=engine, spp=spp, bounces=8)
        # The cube would show its emission (red 4 W/m^2/sr less ~10 % Fresnel loss); the
        # floor it lights glows ~0.3 red.
        red = img[top][..., 0].mean()
        assert red < 1.0, (engine, red)


def test_diffuse_invisible_wall_bleeds_no_colour(fresh_scene, bpy_addon, tmp_path):
    """A sunlit red wall with Visibility > Diffuse off bleeds no red onto the floor
    beside it (final gathering and photons skip it), yet still casts its shadow."""
    bpy = bpy_addon
    scene, cube = _cube_on_floor(bpy)
    cube.scale = (0.1, 3.0, 2.0)     # a red wall, 0.1 m thick, 2 m high
    cube.location = (0.0, 0.0, 1.0)
    floor_near = _region(bpy, scene, (0.6, -0.8, 0.0))   # sunlit floor beside the wall
    ratios = {}
    for flag in (True, False):
        cube.visible_diffuse = flag
        for engine, spp in (("CYCLES", 32), ("PHOTONMAP", 4)):
            img = _render(bpy, scene, tmp_path / f"{engine}{flag}.exr", engine=engine,
                          spp=spp, bounces=1)
            ratios[engine, flag] = _redness(img, floor_near)[0]
    for engine in ("CYCLES", "PHOTONMAP"):
        assert ratios[engine, True] > 1.1, ratios    # colour bleeding when visible
        assert ratios[engine, False] < 1.03, ratios  # none when invisible to diffuse


def test_shadow_catcher_and_light_visibility_exported(fresh_scene, bpy_addon):
    """Shadow Catcher is read into the Mesh (no warning any more: engine/shadowcatcher.py,
    tests/blender/test_shadow_catcher_cycles.py), as is a light's ray visibility."""
    bpy = bpy_addon
    scene, cube = _cube_on_floor(bpy)
    cube.is_shadow_catcher = True
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    sun.visible_diffuse = False
    out, _ = _export(bpy)
    warnings = out.all_warnings()
    assert not [w for w in warnings if "shadow catcher" in w.lower()], warnings
    assert {m.name: m.shadow_catcher for m in out.meshes}[cube.name], out.meshes
    # A light object's ray visibility is honoured now (no warning), read into the Light.
    assert not [w for w in warnings if sun.name in w], warnings
    light = next(li for li in out.lights if li.name == sun.name)
    assert not light.visible_diffuse and light.visible_glossy and light.visible_transmission
    meshes = {m.name: m for m in out.meshes}
    assert meshes[cube.name].visible_camera and not meshes[cube.name].holdout


# Was an xfail: the floor's indirect light under the plane read ~25 % above Cycles' for any
# material (ours 0.783 vs Cycles 0.627 with the specular layer off). That was Cycles'
# default bounce limits, which we did not read (issue 14, docs/design.md, Bounce limits).
def test_shadow_invisible_plane_photons_pass_through(fresh_scene, bpy_addon, tmp_path):
    """A sunlit plane 0.6 m over the floor, invisible to shadow and camera rays: the
    floor under it is lit directly, and indirectly by its own light bounced off the
    plane's underside. Photons must both land on the plane and pass through it (else
    the floor under it gets no photons and its indirect light drops by a third)."""
    bpy = bpy_addon
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 40, 30
    scene.render.resolution_percentage = 100
    for size, z in ((12, 0.0), (4, 0.6)):
        bpy.ops.mesh.primitive_plane_add(size=size, location=(0, 0, z))
        bpy.context.object.data.materials.append(_principled(bpy, f"White{z}", (0.8,) * 3))
    plane = bpy.context.object
    plane.visible_shadow = plane.visible_camera = False
    _light(bpy, "SUN", (0, 0, 5), rotation=(0.3, 0, 0), energy=3.0, angle=0.0)
    _camera(bpy, (0, -6, 6), (math.radians(45), 0, 0), lens=35)
    world = bpy.data.worlds.new("Black")
    scene.world = world
    for n in world.node_tree.nodes:
        if n.type == "BACKGROUND":
            n.inputs["Strength"].default_value = 0.0
    under = _region(bpy, scene, (0, 0, 0), half=3)
    indirect = {}
    for engine, spp in (("CYCLES", 128), ("PHOTONMAP", 8)):
        lum = [_render(bpy, scene, tmp_path / f"{engine}{b}.exr", engine=engine, spp=spp,
                       bounces=b)[under][..., :3].mean() for b in (0, 4)]
        indirect[engine] = lum[1] - lum[0]
    assert indirect["CYCLES"] > 0.4, indirect  # the underside's light is most of it
    assert abs(indirect["PHOTONMAP"] / indirect["CYCLES"] - 1) < 0.2, indirect


def test_an_object_without_a_material_renders_the_default_principled(bpy_addon, tmp_path):
    """Cycles (Blender 5.0) renders an object with no material as the default Principled
    BSDF, specular layer included (newuser40: a material-less floor read 1.047 of Cycles
    as a Lambert 0.8): the converter's default is that material, and the floor's
    brightness follows Cycles'."""
    from addon.core import load_engine
    from addon.materials import MaterialConverter
    from blender_helpers import cycles_plain, render_luminance, sun_light, world_color
    bpy = bpy_addon
    conv = MaterialConverter(load_engine())
    fresh = bpy.data.materials.new("Fresh")
    fresh.use_nodes = True
    none, new = conv.convert(None), conv.convert(fresh)
    for field in ("base_color", "metallic", "roughness", "ior", "specular",
                  "specular_ior_level", "transmission", "coat_weight", "sheen_weight"):
        np.testing.assert_allclose(getattr(none, field), getattr(new, field), rtol=1e-6,
                                   err_msg=field)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world_color(bpy, sc, (0.3, 0.35, 0.4))
    sun_light(bpy, sc, (math.radians(35), 0, math.radians(30)), energy=3.0)
    bpy.ops.mesh.primitive_plane_add(size=10)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -5, 2.5), (math.radians(67), 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 32, 24, 100
    sc.render.engine = "CYCLES"
    cycles_plain(sc, 64, 12)
    ref = render_luminance(bpy, sc, tmp_path / "cycles.exr").mean()
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = 16
    ours = render_luminance(bpy, sc, tmp_path / "ours.exr").mean()
    assert ours / ref == pytest.approx(1.0, abs=0.012), ours / ref
