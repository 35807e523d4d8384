"""Export round trip: depsgraph -> engine Scene (geometry, instances, lights, materials)."""
import math

import numpy as np
import pytest

from blender_helpers import cheap

pytestmark = pytest.mark.blender


def _mesh_object(bpy, name, verts, faces, location=(0, 0, 0), collection=None):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    obj = bpy.data.objects.new(name, me)
    obj.location = location
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def _cube(bpy, name, location):
    v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return _mesh_object(bpy, name, v, f, location)


def _light(bpy, name, kind, location, rotation=(0, 0, 0), scale=(1, 1, 1), **props):
    ld = bpy.data.lights.new(name, kind)
    for k, v in props.items():
        setattr(ld, k, v)
    obj = bpy.data.objects.new(name, ld)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _material(bpy, name, shader, viewport=(0.1, 0.2, 0.3, 1.0)):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    n = nt.nodes.new(shader)
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    m.diffuse_color = viewport
    return m, n


def build_scene(bpy):
    scene = bpy.context.scene
    # 1. A cube with a Subdivision modifier: 6 quads -> 24 quads -> 48 triangles.
    cube = _cube(bpy, "Cube", (1.0, 2.0, 3.0))
    mod = cube.modifiers.new("Subdiv", "SUBSURF")
    mod.levels = mod.render_levels = 1
    toon, node = _material(bpy, "ToonMat", "ShaderNodeBsdfToon")
    node.name = "My Toon"
    node.inputs["Color"].default_value = (0.7, 0.4, 0.2, 1.0)
    cube.data.materials.append(toon)
    # 2. A collection (not in the scene) holding a 1x1 quad, instanced twice.
    coll = bpy.data.collections.new("Inst")
    _mesh_object(bpy, "Quad", [(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)],
                 [(0, 1, 2, 3)], collection=coll)
    for name, loc, scale in (("EmptyA", (5, 0, 0), 2.0), ("EmptyB", (-5, 0, 0), 1.0)):
        e = bpy.data.objects.new(name, None)
        e.instance_type = "COLLECTION"
        e.instance_collection = coll
        e.location = loc
        e.scale = (scale, scale, scale)
        scene.collection.objects.link(e)
    # 3. Lights: scaled rectangle, disk, spot.
    _light(bpy, "Rect", "AREA", (0, 0, 5), scale=(2, 3, 1), energy=100.0, shape="RECTANGLE",
           size=1.0, size_y=0.5)
    _light(bpy, "Disk", "AREA", (0, 3, 5), energy=50.0, shape="DISK", size=0.8)
    _light(bpy, "Spot", "SPOT", (0, -3, 4), rotation=(math.radians(30), 0, 0), energy=300.0,
           spot_size=math.radians(40), spot_blend=0.2, shadow_soft_size=0.1,
           color=(1.0, 0.5, 0.25), use_soft_falloff=False)
    cd = bpy.data.cameras.new("Cam")
    cam = bpy.data.objects.new("Cam", cd)
    cam.location = (0, -10, 3)
    cam.rotation_euler = (math.radians(80), 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def test_export_round_trip(fresh_scene, bpy_addon):
    bpy = bpy_addon
    build_scene(bpy)
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out, info = export.export_scene(pm, depsgraph, width=64, height=48)

    meshes = {m.name: m for m in out.meshes}
    assert sum(len(m.faces) for m in out.meshes) == 48 + 2 + 2 == info["triangles"]
    cube = meshes["Cube"]
    assert len(cube.faces) == 48
    np.testing.assert_allclose(cube.vertices.mean(axis=0), (1, 2, 3), atol=1e-5)
    # The instances are placements without copies: their world-space copies as the
    # engine builds them when it expands them (Mesh.expanded).
    inst = sorted((m.expanded() for m in out.meshes if m.name != "Cube"),
                  key=lambda m: m.vertices[0, 0])
    assert len(inst) == 2 and all("Quad" in m.name for m in inst)
    b, a = inst  # x < 0 first
    np.testing.assert_allclose(a.vertices.min(axis=0), (4, -1, 0), atol=1e-6)
    np.testing.assert_allclose(a.vertices.max(axis=0), (6, 1, 0), atol=1e-6)
    np.testing.assert_allclose(b.vertices.mean(axis=0), (-5, 0, 0), atol=1e-6)

    lights = {light.name: light for light in out.lights}
    rect, disk, spot = lights["Rect"], lights["Disk"], lights["Spot"]
    assert rect.kind == "AREA" and rect.shape == "RECTANGLE"
    assert rect.size_x == pytest.approx(2.0) and rect.size_y == pytest.approx(1.5)
    assert rect.power == pytest.approx(100.0)
    np.testing.assert_allclose(rect.direction, (0, 0, -1), atol=1e-6)
    np.testing.assert_allclose(rect.flux, (100, 100, 100), rtol=1e-6)  # Cycles: P = flux
    assert disk.shape == "DISK" and disk.size_x == pytest.approx(0.8)
    assert disk.area == pytest.approx(math.pi / 4 * 0.64)
    assert spot.kind == "SPOT" and spot.power == pytest.approx(300.0)
    assert spot.spot_size == pytest.approx(math.radians(40))
    assert spot.spot_blend == pytest.approx(0.2) and spot.radius == pytest.approx(0.1)
    assert spot.soft_falloff is False  # Soft Falloff off: a sphere (engine/lights/point.py)
    np.testing.assert_allclose(spot.color, (1.0, 0.5, 0.25))
    np.testing.assert_allclose(spot.direction, (0, math.sin(math.radians(30)),
                                                -math.cos(math.radians(30))), atol=1e-6)
    np.testing.assert_allclose(spot.position, (0, -3, 4))

    cam = out.camera
    np.testing.assert_allclose(cam.position, (0, -10, 3))
    assert cam.fov == pytest.approx(2 * math.atan(36 / (2 * 50)))

    warnings = out.all_warnings()
    hits = [w for w in warnings if "ToonMat" in w and "My Toon" in w]
    assert len(hits) == 1, warnings
    assert "approximated by a Diffuse BSDF of its Color" in hits[0], hits
    # Its own colour, not the viewport colour (0.1, 0.2, 0.3).
    np.testing.assert_allclose(out.materials["ToonMat"].base_color, (0.7, 0.4, 0.2), atol=1e-6)


def test_render_reports_export_warning(fresh_scene, bpy_addon):
    bpy = bpy_addon
    scene = build_scene(bpy)
    cheap(scene, width=40, height=30, pct=100, spp=1, photons=2000, caustic_photons=500)
    from addon import engine
    events = []
    listener = (lambda event, value: events.append((event, value)))
    engine.status_listeners.append(listener)
    try:
        bpy.ops.render.render()
    finally:
        engine.status_listeners.remove(listener)
    assert engine.last_render["width"] == 40 and engine.last_render["height"] == 30
    assert any("My Toon" in w for w in engine.last_render["warnings"])
    # Said before the render, not after it, and once.
    names = [e for e, _ in events]
    toon = [i for i, (e, v) in enumerate(events) if e == "warning" and "My Toon" in str(v)]
    assert len(toon) == 1 and toon[0] < names.index("film"), names
    assert any(e == "progress" for e in names[toon[0] + 1:names.index("film")]), names


def test_materials_and_texture(fresh_scene, bpy_addon):
    bpy = bpy_addon
    quad = _mesh_object(bpy, "Q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2, 3)])
    quad.data.uv_layers.new(name="UVMap")
    m, p = _material(bpy, "Tex", "ShaderNodeBsdfPrincipled")
    img = bpy.data.images.new("checker", 4, 2)  # byte image, sRGB
    px = np.zeros((2, 4, 4), np.float32)
    px[0, :, :] = (1.0, 0.0, 0.0, 1.0)   # bottom row red
    px[1, :, :] = (0.5, 0.5, 0.5, 1.0)   # top row sRGB 0.5
    img.pixels.foreach_set(px.reshape(-1))
    tex = m.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    m.node_tree.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    p.inputs["Metallic"].default_value = 0.25
    p.inputs["Roughness"].default_value = 0.3
    p.inputs["Emission Strength"].default_value = 2.0
    p.inputs["Emission Color"].default_value = (1.0, 0.5, 0.0, 1.0)
    quad.data.materials.append(m)
    # A glass / transparent mix and an emission material.
    g = bpy.data.materials.new("GlassMix")
    nt = g.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = 1.33
    transp = nt.nodes.new("ShaderNodeBsdfTransparent")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.25
    nt.links.new(glass.outputs[0], mix.inputs[1])
    nt.links.new(transp.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])

    from addon.core import load_engine
    from addon.materials import MaterialConverter
    conv = MaterialConverter(load_engine())
    t = conv.convert(m)
    # Stored values kept (8-bit sRGB: Cycles filters those and converts after).
    assert t.texture.pixels.shape == (2, 4, 4) and t.texture.srgb
    assert (t.texture.extension, t.texture.interpolation) == ("REPEAT", "Linear")
    np.testing.assert_allclose(t.texture.pixels[1, 0, :3], (1, 0, 0), atol=1e-3)  # bottom
    np.testing.assert_allclose(t.texture.pixels[0, 0, :3], (0.5,) * 3, atol=3e-3)  # row last
    np.testing.assert_allclose(t.texture.sample(np.array([[0.125, 0.75]])), [(0.2140,) * 3],
                               atol=3e-3)  # sRGB decoded at the lookup
    assert t.metallic == pytest.approx(0.25) and t.roughness == pytest.approx(0.3)
    np.testing.assert_allclose(t.emission, (2.0, 1.0, 0.0), atol=1e-6)
    gm = conv.convert(g)
    assert gm.transmission == pytest.approx(1.0) and gm.ior == pytest.approx(1.33)
    assert gm.alpha == pytest.approx(0.75)
    assert not t.warnings and not gm.warnings


def test_bad_light_power_warns_once_and_render_goes_on(fresh_scene, bpy_addon):
    """A NaN or negative light power is skipped with one warning naming the light; the
    other lights still render the scene."""
    bpy = bpy_addon
    scene = build_scene(bpy)
    bad = _light(bpy, "NanLamp", "POINT", (0, 0, 4), energy=100.0)
    neg = _light(bpy, "NegLamp", "POINT", (1, 0, 4), energy=100.0)
    bad.data.energy = float("nan")
    neg.data.energy = -50.0
    cheap(scene, width=40, height=30, pct=100, spp=1, photons=2000, caustic_photons=500)
    from addon import engine
    bpy.ops.render.render()
    warnings = engine.last_render["warnings"]
    for name, what in (("NanLamp", "finite"), ("NegLamp", "negative")):
        hits = [w for w in warnings if f"'{name}'" in w]
        assert len(hits) == 1 and what in hits[0], warnings
    assert engine.last_render.get("error") is None
    assert engine.last_render["width"] == 40


def test_nan_vertices_warn_once_without_numpy_noise(fresh_scene, bpy_addon):
    """A mesh with NaN and infinite vertices: one warning naming it, the faces dropped,
    and no numpy RuntimeWarning from the export's transform (newuser41 saw
    "export.py: RuntimeWarning: invalid value encountered in matmul" first)."""
    import warnings as pywarnings
    bpy = bpy_addon
    _mesh_object(bpy, "NaNMesh", [(0, 0, 0), (1, 0, 0), (float("nan"), 1, 0),
                                  (0, float("inf"), 1)], [(0, 1, 2), (0, 1, 3)],
                 location=(0.2, 0.1, 0.0))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    bpy.context.scene.collection.objects.link(cam)
    cam.location = (0, -5, 1)
    cam.rotation_euler = (math.radians(80), 0, 0)
    bpy.context.scene.camera = cam
    from addon import export
    from addon.core import load_engine
    with pywarnings.catch_warnings():
        pywarnings.simplefilter("error", RuntimeWarning)
        scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                       width=8, height=6)
    assert [m for m in scene.meshes if m.name == "NaNMesh"]


def test_instances_share_a_prototype(fresh_scene, bpy_addon):
    """Geometry placed more than once (the quad, instanced twice by a collection) gets
    one engine Prototype with each placement's matrix; the cube, placed once, none. The
    engine records the two placements as instances (engine/instancing.py)."""
    bpy = bpy_addon
    build_scene(bpy)
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    from engine.geometry import prepare
    out, _ = export.export_scene(pm, bpy.context.evaluated_depsgraph_get(), width=64, height=48)
    quads = sorted((m for m in out.meshes if "Quad" in m.name), key=lambda m: m.matrix[0, 3])
    cube = next(m for m in out.meshes if m.name == "Cube")
    assert cube.prototype is None and cube.matrix is None
    assert quads[0].prototype is quads[1].prototype is not None
    # Records, not copies: the placements keep no world-space vertices (Mesh.place).
    assert all(m.vertices is None and m.instance_matches() for m in quads)
    assert quads[0].faces is quads[0].prototype.faces
    np.testing.assert_allclose(quads[1].matrix[:, 3], (5, 0, 0), atol=1e-6)
    np.testing.assert_allclose(np.diag(quads[1].matrix[:, :3]), (2, 2, 2), atol=1e-6)
    out.validate()
    geo, _ = prepare(out)
    assert geo.instances.count == 2 and len(geo.instances.static) == 48


@pytest.mark.parametrize("name", ["geometry_collection_instance", "geometry_vertex_instancing",
                                  "geometry_nodes_instances"])
def test_instancing_cases_traced_two_level_match_cycles(bpy_addon, monkeypatch, name):
    """The feature matrix's instancing scenes, exported as placements without copies
    (Mesh.place) and traced two-level with shared tables (engine/instancing.py,
    engine/sharedrows.py; the budget forced to 0), pass against Cycles as expanded."""
    import os
    import sys
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "tools"))
    import feature_matrix as fm
    from engine import resources, visibility
    built = []
    original = visibility.InstanceAccel

    def counting(*args, **kwargs):
        built.append(1)
        return original(*args, **kwargs)

    from engine.scene import Mesh
    placed = []
    place = Mesh.place.__func__

    def recording(cls, *args, **kwargs):
        placed.append(1)
        return place(cls, *args, **kwargs)

    monkeypatch.setattr(resources, "INSTANCE_BUDGET_FRACTION", 0.0)
    monkeypatch.setattr(visibility, "InstanceAccel", counting)
    monkeypatch.setattr(Mesh, "place", classmethod(recording))
    img, _, warnings = fm.render_ours(name)
    assert built, "the scene was not traced two-level"
    # The export wrote placements (records on a shared prototype), not world copies.
    assert len(placed) >= 2, "the instances were exported as copies"
    s = fm.score(fm.blocks(img), fm.load_references()[name], fm.CASES[name].block)
    assert not fm.verdict(fm.CASES[name], s, warnings), s


def test_viewport_export_writes_instance_records(fresh_scene, bpy_addon):
    """export_viewport writes collection instances as placements on one prototype (no
    world-space copies), keeps them while nothing changes and places a moved instancer's
    again from the kept prototype."""
    bpy = bpy_addon
    build_scene(bpy)
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    cache = export.ViewportExport(pm)
    camera = pm.Camera.look_at((0, -10, 3), (0, 0, 0))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out, info = export.export_viewport(cache, depsgraph, camera, 32, 24)
    quads = [m for m in out.meshes if "Quad" in m.name]
    assert len(quads) == 2 and all(m.vertices is None for m in quads)
    assert quads[0].prototype is quads[1].prototype
    again, info = export.export_viewport(cache, depsgraph, camera, 32, 24,
                                         export.ViewportUpdates())
    assert sorted(m.name for m in again.meshes if "Quad" in m.name) == \
        sorted(m.name for m in quads) and not info["geometry_changed"]
    bpy.data.objects["EmptyA"].location.x = 7.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    moved, info = export.export_viewport(cache, depsgraph, camera, 32, 24,
                                         export.ViewportUpdates())
    mq = sorted((m for m in moved.meshes if "Quad" in m.name), key=lambda m: m.matrix[0, 3])
    np.testing.assert_allclose(mq[1].matrix[:, 3], (7, 0, 0), atol=1e-6)
    assert mq[1].prototype is quads[0].prototype and mq[1].vertices is None
    moved.validate()


def _bulb_colour(bpy, setup):
    """Export a scene of one Point light set up by setup(light): its engine colour and
    the export's warnings."""
    from addon import export
    from addon.core import load_engine
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    light = bpy.data.lights.new("Bulb", "POINT")
    light.energy = 100.0
    ob = bpy.data.objects.new("Bulb", light)
    scene.collection.objects.link(ob)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    setup(light)
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=6)
    return np.asarray(out.lights[0].color, np.float64), list(out.warnings)


def test_light_node_blackbody_is_the_light_temperature(fresh_scene, bpy_addon):
    """A bulb coloured by a Blackbody node (2700 K) in its light node tree gets the colour
    Blender's own light Temperature (2700 K) gives it - Cycles renders both alike
    (measured: floor R/B 8.11 both ways, /tmp/newuser23/repro_light_blackbody.py, a one-off
    script, not kept) - and
    an Emission's constant Color and Strength scale it; no 'not supported' warning."""
    bpy = bpy_addon

    def temperature(light):
        light.use_temperature = True
        light.temperature = 2700.0

    def node(light, strength=1.0, color=None):
        light.use_nodes = True
        nt = light.node_tree
        emit = nt.nodes["Emission"]
        emit.inputs["Strength"].default_value = strength
        if color is None:
            bb = nt.nodes.new("ShaderNodeBlackbody")
            bb.inputs["Temperature"].default_value = 2700.0
            nt.links.new(bb.outputs[0], emit.inputs["Color"])
        else:
            emit.inputs["Color"].default_value = (*color, 1.0)

    want, w0 = _bulb_colour(bpy, temperature)
    got, w1 = _bulb_colour(bpy, node)
    assert want[0] > 4 * want[2]  # warm
    np.testing.assert_allclose(got, want, rtol=1e-4)
    assert not [w for w in w0 + w1 if "node tree" in w], w0 + w1
    tinted, w2 = _bulb_colour(bpy, lambda L: node(L, 2.0, (1.0, 0.5, 0.25)))
    np.testing.assert_allclose(tinted, [2.0, 1.0, 0.5], rtol=1e-6)
    assert not w2


def _export_before_a_camera(bpy, scene):
    """Export the scene (16 x 12) seen by a camera 6 m in front of the origin."""
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, -6, 0)
    cam.rotation_euler = (math.pi / 2, 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    from addon import export
    from addon.core import load_engine
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=16, height=12)
    return out


def test_subsurface_exports_the_walk_of_a_constant_and_a_textured_colour(fresh_scene,
                                                                         bpy_addon):
    """A Principled with Subsurface Weight (a skin, a candle) exports Cycles' random-walk
    BSSRDF (engine/subsurfacewalk.py: weight, colour, Radius x Scale, the IOR, anisotropy,
    roughness) without a warning; its diffuse base is the stand-in the photons see,
    Cycles' thick-slab albedo of its Base Color (s25 mixpale). With a texture on Base
    Color it walks too (ssstex41: the colour node evaluated at each walk's entry), still
    without a warning, and so does a texture on Subsurface Radius; a texture on
    Subsurface Scale is warned (its socket's value)."""
    bpy = bpy_addon
    obj = _cube(bpy, "Candle", (0, 0, 0))
    mat = bpy.data.materials.new("Wax")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    p = mat.node_tree.nodes["Principled BSDF"]
    p.inputs["Subsurface Weight"].default_value = 1.0
    p.inputs["Subsurface Anisotropy"].default_value = 0.3
    obj.data.materials.append(mat)
    other = _cube(bpy, "Soap", (3, 0, 0))
    tex_mat = bpy.data.materials.new("Soap")
    if bpy.app.version < (5, 0, 0):
        tex_mat.use_nodes = True
    nt = tex_mat.node_tree
    q = nt.nodes["Principled BSDF"]
    q.inputs["Subsurface Weight"].default_value = 1.0
    nt.links.new(nt.nodes.new("ShaderNodeTexChecker").outputs["Color"], q.inputs["Base Color"])
    other.data.materials.append(tex_mat)
    third = _cube(bpy, "Marble", (-3, 0, 0))
    radius_mat = bpy.data.materials.new("Marble")
    if bpy.app.version < (5, 0, 0):
        radius_mat.use_nodes = True
    rt = radius_mat.node_tree
    r = rt.nodes["Principled BSDF"]
    r.inputs["Subsurface Weight"].default_value = 1.0
    noise = rt.nodes.new("ShaderNodeTexNoise")
    rt.links.new(noise.outputs["Color"], r.inputs["Subsurface Radius"])
    rt.links.new(noise.outputs["Fac"], r.inputs["Subsurface Scale"])
    third.data.materials.append(radius_mat)
    out = _export_before_a_camera(bpy, fresh_scene)
    warned = out.all_warnings()
    assert not [w for w in warned if "Subsurface Weight" in w or "'Soap'" in w
                or "Subsurface Radius" in w], warned
    scale_warn = [w for w in warned if "Subsurface Scale" in w]
    assert len(scale_warn) == 1 and scale_warn[0].startswith("material 'Marble'"), warned
    soap = out.materials["Soap"].subsurface
    assert soap is not None and soap.color_node is not None and soap.weight_node is None
    marble = out.materials["Marble"].subsurface
    assert marble.color_node is None and marble.radius_node is not None
    # Base Color 0.8 (the default): Cycles' random walk reflects 0.7896 of the light on a
    # thick slab (engine/subsurface.py, measured by bench/bench_subsurface_albedo.py).
    wax = out.materials["Wax"]
    np.testing.assert_allclose(wax.base_color, [0.7896] * 3, atol=1e-4)
    sp = wax.subsurface
    assert sp is not None and not sp.textured
    assert sp.weight == 1.0 and sp.anisotropy == pytest.approx(0.3)
    np.testing.assert_allclose(sp.color, [0.8] * 3, atol=1e-6)
    radius = np.array(p.inputs["Subsurface Radius"].default_value[:3])
    np.testing.assert_allclose(sp.radius, radius * p.inputs["Subsurface Scale"].default_value,
                               rtol=1e-6)
    assert sp.ior == pytest.approx(p.inputs["IOR"].default_value, rel=1e-6)
    assert sp.roughness == pytest.approx(p.inputs["Roughness"].default_value, rel=1e-6)


def test_subsurface_node_with_a_textured_colour_walks(fresh_scene, bpy_addon):
    """The Subsurface Scattering node with a texture on Color exports the walk (weight 1,
    the colour node evaluated per hit at each walk's entry; ssstex41) without a warning;
    its table colour is the per-hit stand-in (engine/subsurface.SubsurfaceColor)."""
    bpy = bpy_addon
    from blender_helpers import node_material
    obj = _cube(bpy, "Marble", (0, 0, 0))
    m, nt, out_node = node_material(bpy, "MarbleSSS")
    sss = nt.nodes.new("ShaderNodeSubsurfaceScattering")
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Color"], sss.inputs["Color"])
    nt.links.new(sss.outputs[0], out_node.inputs["Surface"])
    obj.data.materials.append(m)
    out = _export_before_a_camera(bpy, fresh_scene)
    assert not [w for w in out.all_warnings() if "MarbleSSS" in w], out.all_warnings()
    mat = out.materials["MarbleSSS"]
    sp = mat.subsurface
    assert sp is not None and sp.weight == 1.0 and sp.color_node is not None
    assert sp.weight_node is None
    assert type(mat.texture).__name__ == "SubsurfaceColor"


def test_a_mix_of_two_subsurface_sides_warns_that_it_does_not_walk(fresh_scene, bpy_addon):
    """A Mix Shader of two subsurface Principled BSDFs: the mix carries no random walk
    (one walk per material; its subsurface part renders as the stand-in), said once,
    naming the material and the node (ssstex41 found it silent). One subsurface side
    walks since s42 (tests/blender/test_subsurface_walk_cycles.py)."""
    bpy = bpy_addon
    from blender_helpers import node_material
    obj = _cube(bpy, "Wax", (0, 0, 0))
    m, nt, out_node = node_material(bpy, "WaxMix")
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Subsurface Weight"].default_value = 1.0
    g = nt.nodes.new("ShaderNodeBsdfPrincipled")
    g.inputs["Subsurface Weight"].default_value = 1.0
    g.inputs["Base Color"].default_value = (0.2, 0.3, 0.9, 1.0)
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.name = "Coat mix"
    mix.inputs["Fac"].default_value = 0.3
    nt.links.new(p.outputs[0], mix.inputs[1])
    nt.links.new(g.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out_node.inputs["Surface"])
    obj.data.materials.append(m)
    out = _export_before_a_camera(bpy, fresh_scene)
    hits = [w for w in out.all_warnings() if "'WaxMix'" in w and "subsurface" in w]
    assert len(hits) == 1 and "'Coat mix'" in hits[0], out.all_warnings()


def _diffuse_translucent_mix(bpy, name, fac, diffuse_rgb, translucent_rgb):
    """A material: Mix Shader (factor fac) of a Diffuse BSDF and a Translucent BSDF."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*diffuse_rgb, 1.0)
    trans = nt.nodes.new("ShaderNodeBsdfTranslucent")
    trans.inputs["Color"].default_value = (*translucent_rgb, 1.0)
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = fac
    nt.links.new(diffuse.outputs[0], mix.inputs[1])
    nt.links.new(trans.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def test_translucent_bsdf_exports_as_diffuse_transmission(fresh_scene, bpy_addon):
    """A Translucent BSDF (a lamp shade) exports as the translucent lobe of its Color,
    without a warning (s29 it rendered as a Diffuse BSDF: the lamp stayed dark inside its
    shade, the room at 0.82 of Cycles); a Mix of a Diffuse BSDF and a Translucent BSDF
    keeps both colours and the factor as the translucent share."""
    bpy = bpy_addon
    obj = _cube(bpy, "Shade", (0, 0, 0))
    mat, node = _material(bpy, "ShadeCloth", "ShaderNodeBsdfTranslucent")
    node.inputs["Color"].default_value = (0.9, 0.8, 0.6, 1.0)
    obj.data.materials.append(mat)
    paper = _cube(bpy, "Paper", (3, 0, 0))
    paper.data.materials.append(_diffuse_translucent_mix(bpy, "Paper", 0.3, (0.2, 0.4, 0.6),
                                                         (0.7, 0.5, 0.1)))
    out = _export_before_a_camera(bpy, fresh_scene)
    assert not [w for w in out.all_warnings() if "ShadeCloth" in w or "Paper" in w], \
        out.all_warnings()
    shade = out.materials["ShadeCloth"]
    assert shade.translucent == 1.0 and shade.translucent_color is None
    np.testing.assert_allclose(shade.base_color, (0.9, 0.8, 0.6), atol=1e-6)
    m = out.materials["Paper"]
    assert m.translucent == pytest.approx(0.3)
    np.testing.assert_allclose(m.translucent_color, (0.7, 0.5, 0.1), atol=1e-6)
    np.testing.assert_allclose(m.base_color, (0.2, 0.4, 0.6), atol=1e-6)


def test_translucent_mixed_by_a_texture_uses_the_factors_value_and_says_so(fresh_scene,
                                                                           bpy_addon):
    """Per-hit mixing of a Translucent BSDF is not supported: the factor's own value
    stands and the warning says so (no silent loss of the translucency)."""
    bpy = bpy_addon
    obj = _cube(bpy, "Leaf", (0, 0, 0))
    mat = _diffuse_translucent_mix(bpy, "LeafMix", 0.4, (0.8, 0.8, 0.8), (0.8, 0.8, 0.8))
    nt = mat.node_tree
    mix = next(n for n in nt.nodes if n.type == "MIX_SHADER")
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], mix.inputs[0])
    obj.data.materials.append(mat)
    out = _export_before_a_camera(bpy, fresh_scene)
    hits = [w for w in out.all_warnings() if "LeafMix" in w]
    assert len(hits) == 1 and "per-hit mixing of translucency is not supported" in hits[0], \
        out.all_warnings()
    assert out.materials["LeafMix"].translucent == pytest.approx(0.4)


def test_render_visibility_leaves_out_what_a_final_render_does(fresh_scene):
    """A viewport depsgraph (bpy.context.evaluated_depsgraph_get(), the teaching images'
    and scripts') holds objects and lights disabled in renders; exported with
    render_visibility they stay out, as from F12's depsgraph (s34: the day room's
    render-disabled floor lamp lit a script's export 16x brighter than F12)."""
    import bpy
    from addon import export
    from addon.core import load_engine
    scene = fresh_scene
    _cube(bpy, "Shown", (0, 0, 0))
    _cube(bpy, "NotRendered", (3, 0, 0)).hide_render = True
    off = bpy.data.collections.new("OffInRenders")
    off.hide_render = True
    scene.collection.children.link(off)
    hidden_in_coll = _cube(bpy, "InOffCollection", (6, 0, 0))
    scene.collection.objects.unlink(hidden_in_coll)
    off.objects.link(hidden_in_coll)
    # A source collection excluded from the view layer, instanced twice: its objects
    # render through the shown instancer (not through the one disabled in renders); an
    # instanced object disabled in renders stays out.
    src = bpy.data.collections.new("Source")
    scene.collection.children.link(src)
    for name, hide in (("Part", False), ("HiddenPart", True)):
        o = _cube(bpy, name, (0, 5, 0))
        scene.collection.objects.unlink(o)
        src.objects.link(o)
        o.hide_render = hide
    scene.view_layers[0].layer_collection.children["Source"].exclude = True
    for name, hide in (("Instancer", False), ("HiddenInstancer", True)):
        empty = bpy.data.objects.new(name, None)
        empty.instance_type, empty.instance_collection = "COLLECTION", src
        empty.hide_render = hide
        scene.collection.objects.link(empty)
    _light(bpy, "Lamp", "POINT", (0, 0, 4), energy=100.0)
    _light(bpy, "LampNotRendered", "POINT", (0, 0, 5), energy=100.0).hide_render = True
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, -10, 2)
    scene.collection.objects.link(cam)
    scene.camera = cam
    pm = load_engine()
    dg = bpy.context.evaluated_depsgraph_get()

    def names(render_visibility):
        s, _ = export.export_scene(pm, dg, width=8, height=8,
                                   render_visibility=render_visibility)
        return [m.name for m in s.meshes], [li.name for li in s.lights]

    meshes, lights = names(True)
    joined = " ".join(meshes)
    assert "Shown" in meshes and lights == ["Lamp"], (meshes, lights)
    for gone in ("NotRendered", "InOffCollection", "HiddenPart", "HiddenInstancer"):
        assert gone not in joined, (gone, meshes)
    assert sum("Part" in m for m in meshes) == 1, meshes  # through "Instancer" only
    # Without it the viewport depsgraph's content, as the rendered viewport shows it.
    meshes, lights = names(False)
    assert "LampNotRendered" in lights and "NotRendered" in meshes, (meshes, lights)


def test_cycles_light_portal_is_a_portal_not_a_light(fresh_scene, bpy_addon):
    """An Area light with Cycles' Portal on emits nothing in Cycles: it exports as an
    engine LightPortal (its rectangle and its -Z, into the room), not a light; before
    portal34 it became a 10 W area light. A Disk portal exports as a round LightPortal
    (Cycles' is_round; left out with a warning before portals36), its square the disk's
    bounding one; an Ellipse takes its two sizes."""
    from addon import export
    from addon.core import load_engine
    bpy = bpy_addon
    scene = fresh_scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    ob = _light(bpy, "Window", "AREA", (1.0, 2.0, 3.0), rotation=(math.pi, 0, 0),
                scale=(2.0, 1.0, 1.0), shape="RECTANGLE", size=1.0, size_y=0.5, energy=10.0)
    ob.data.cycles.is_portal = True
    disk = _light(bpy, "Round", "AREA", (0.0, 0.0, 3.0), shape="DISK", size=1.0)
    disk.data.cycles.is_portal = True
    oval = _light(bpy, "Oval", "AREA", (0.0, 0.0, 4.0), shape="ELLIPSE", size=1.0,
                  size_y=0.4)
    oval.data.cycles.is_portal = True
    _light(bpy, "Lamp", "POINT", (0.0, 0.0, 1.0), energy=5.0)
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=6)
    assert [li.name for li in out.lights] == ["Lamp"]
    assert sorted(p.name for p in out.portals) == ["Oval", "Round", "Window"]
    by = {p.name: p for p in out.portals}
    assert not by["Window"].round and by["Round"].round and by["Oval"].round
    for name, half in (("Round", (0.5, 0.5)), ("Oval", (0.5, 0.2))):
        c = by[name].corners
        np.testing.assert_allclose(c.max(axis=0)[:2], half, atol=1e-6)
        np.testing.assert_allclose(c.min(axis=0)[:2], (-half[0], -half[1]), atol=1e-6)
    assert not any("light portal" in w for w in out.warnings)
    p = by["Window"]
    np.testing.assert_allclose(p.normal, (0.0, 0.0, 1.0), atol=1e-6)  # -Z turned over
    lo, hi = p.corners.min(axis=0), p.corners.max(axis=0)
    np.testing.assert_allclose(lo, (0.0, 1.75, 3.0), atol=1e-6)  # 2 x 0.5 m round (1, 2, 3)
    np.testing.assert_allclose(hi, (2.0, 2.25, 3.0), atol=1e-6)
    # A portal of size zero: left out, warned (Cycles lights the room far darker with it).
    flat = _light(bpy, "Flat", "AREA", (0.0, 0.0, 5.0), shape="SQUARE", size=0.0)
    flat.data.cycles.is_portal = True
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=6)
    assert "Flat" not in [p.name for p in out.portals]
    assert any("light portal 'Flat': its size is zero" in w for w in out.warnings), out.warnings


def test_light_and_shadow_linking_warn_naming_the_light_and_collection(fresh_scene,
                                                                        bpy_addon):
    """Light Linking / Shadow Linking (Blender 4.0+) were dropped silently (s37): one
    warning for what is not rendered (an emitting object's Shadow Linking), naming the
    object and the collection; a lamp's Light and Shadow Linking and an object's Light
    Linking render (linking38: no warning); unlinked lights say nothing."""
    bpy = bpy_addon
    from blender_helpers import export_warnings
    build_scene(bpy)
    key = _light(bpy, "KeyLamp", "POINT", (0, 0, 4), energy=100.0)
    _light(bpy, "FillLamp", "POINT", (1, 0, 4), energy=100.0)
    glow = _cube(bpy, "GlowCube", (3, 0, 1))
    assert not [w for w in export_warnings(bpy) if "Linking" in w]
    lit = bpy.data.collections.new("LitOnly")
    blockers = bpy.data.collections.new("Blockers")
    key.light_linking.receiver_collection = lit
    key.light_linking.blocker_collection = blockers
    glow.light_linking.receiver_collection = lit
    assert not [w for w in export_warnings(bpy) if "Linking" in w]
    glow.light_linking.blocker_collection = blockers
    warnings = [w for w in export_warnings(bpy) if "Linking" in w]
    assert warnings == [
        "object 'GlowCube': Shadow Linking (collection 'Blockers') is not supported; every "
        "object casts its shadows"], warnings


def test_text_and_instances_are_named_by_their_objects(fresh_scene, bpy_addon):
    """A bevelled Text exports as 'Text#0' (Blender 5 hands its triangles over as an
    instance of itself) without the 'zero-area faces' warning its caps used to raise, a
    mesh's degenerate faces still warn; instances are numbered per instancer and object,
    not after other objects' instances (newuser40: 'Text/Text#360')."""
    bpy = bpy_addon
    from addon import export
    from addon.core import load_engine
    bpy.ops.object.text_add(location=(0, 0, 0))
    text = bpy.context.object
    text.data.extrude, text.data.bevel_depth = 0.1, 0.02
    me = bpy.data.meshes.new("Flat")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0)], [], [(0, 1, 2), (0, 1, 3)])
    flat = bpy.data.objects.new("Flat", me)
    bpy.context.scene.collection.objects.link(flat)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, -8, 2)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    for view in (False, True):
        depsgraph = bpy.context.evaluated_depsgraph_get()
        pm = load_engine()
        if view:
            out = export.export_viewport(export.ViewportExport(pm), depsgraph,
                                         pm.Camera.look_at((0, -8, 2), (0, 0, 0)), 16, 12)[0]
        else:
            out = export.export_scene(pm, depsgraph, width=16, height=12)[0]
        names = [m.name for m in out.meshes]
        assert "Text#0" in names or "Text" in names, names
        warned = [w for w in out.all_warnings() if "zero-area" in w]
        assert len(warned) == 1 and "'Flat'" in warned[0], warned
