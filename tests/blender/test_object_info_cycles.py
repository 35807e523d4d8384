"""Object Info node against Cycles: Random (Cycles' random_number, the instance's
random_id / (2^32 - 1)), Color and Alpha (object.color), Object Index (pass_index), per
object and per instance (meshes sharing data are placed from one prototype). It fell
back to the socket's value before (a new user's scattered rocks all one colour).

Location (the object's origin) and Material Index (the material's pass index) too.

Eight emissive cubes in a row seen from above by an orthographic camera: four single
meshes and four linked duplicates; each cube's pixel colour within 0.002 of Cycles'.
"""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

N = 8


def _material(bpy, name, output):
    """Emission of Color Ramp(Object Info <output>) (a ramp makes Random visible in
    colour) or of the Color output itself."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    e = nt.nodes.new("ShaderNodeEmission")
    info = nt.nodes.new("ShaderNodeObjectInfo")
    if output == "Color":
        nt.links.new(info.outputs["Color"], e.inputs["Color"])
    else:
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (0.05, 0.1, 0.9, 1.0)
        ramp.color_ramp.elements[1].color = (0.95, 0.6, 0.1, 1.0)
        src = info.outputs[output]
        if output == "Location":  # x from -3.5 to 3.5 along the row, to 0.06 .. 0.94
            sep = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(src, sep.inputs[0])
            src = sep.outputs["X"]
            scale = nt.nodes.new("ShaderNodeMath")
            scale.operation = "MULTIPLY_ADD"
            scale.inputs[1].default_value = 1.0 / N
            scale.inputs[2].default_value = 0.5
            nt.links.new(src, scale.inputs[0])
            src = scale.outputs[0]
        if output in ("Object Index", "Material Index"):
            scale = nt.nodes.new("ShaderNodeMath")
            scale.operation = "DIVIDE"
            scale.inputs[1].default_value = float(N)
            nt.links.new(src, scale.inputs[0])
            src = scale.outputs[0]
        nt.links.new(src, ramp.inputs["Fac"])
        nt.links.new(ramp.outputs["Color"], e.inputs["Color"])
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    return m


def _row(bpy, scene, mat):
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.0, 0.0))
    shared = bpy.context.object
    shared.data.materials.append(mat)
    for i in range(N):
        if i % 2 == 0:
            ob = shared if i == 0 else bpy.data.objects.new(f"Linked{i}", shared.data)
            if i:
                scene.collection.objects.link(ob)
        else:
            bpy.ops.mesh.primitive_cube_add(size=0.8)
            ob = bpy.context.object
            ob.data.materials.append(mat)
        ob.location = (i - (N - 1) / 2.0, 0.0, 0.0)
        ob.color = (0.1 + 0.1 * i, 0.9 - 0.1 * i, 0.5, 1.0)
        ob.pass_index = i
    from blender_helpers import black_world, looking_down_camera
    looking_down_camera(bpy, scene, 5.0, ortho_scale=N)
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = 8 * N, 8
    scene.render.resolution_percentage = 100


def _cube_colours(bpy, scene, path, engine):
    from blender_helpers import render_pixel_centres
    img = render_pixel_centres(bpy, scene, path, engine, spp=4)[..., :3]
    # Each cube covers the middle of its 8-pixel column block.
    return np.array([img[2:6, 8 * i + 2:8 * i + 6].reshape(-1, 3).mean(axis=0)
                     for i in range(N)])


@pytest.mark.parametrize("output", ["Random", "Color", "Object Index", "Location"])
def test_object_info_matches_cycles_per_object(fresh_scene, bpy_addon, tmp_path, output):
    bpy = bpy_addon
    scene = fresh_scene
    _row(bpy, scene, _material(bpy, "Info", output))
    ours = _cube_colours(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _cube_colours(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(output, np.round(ours, 4).tolist(), np.round(ref, 4).tolist())
    assert np.ptp(ref[:, 0]) > 0.1  # the cubes differ
    assert np.abs(ours - ref).max() < 0.002, np.abs(ours - ref).max(axis=1)


def test_object_info_random_of_collection_instances_matches_cycles(fresh_scene, bpy_addon,
                                                                   tmp_path):
    """Instances (a collection instanced by empties) take the depsgraph's random_id."""
    bpy = bpy_addon
    scene = fresh_scene
    mat = _material(bpy, "Info", "Random")
    _row(bpy, scene, mat)
    coll = bpy.data.collections.new("Rock")
    src = bpy.data.objects.new("RockMesh", bpy.data.objects["Cube"].data)
    coll.objects.link(src)
    for ob in [o for o in scene.objects if o.type == "MESH"]:
        bpy.data.objects.remove(ob)
    for i in range(N):
        e = bpy.data.objects.new(f"Place{i}", None)
        e.instance_type, e.instance_collection = "COLLECTION", coll
        e.location = (i - (N - 1) / 2.0, 0.0, 0.0)
        scene.collection.objects.link(e)
    ours = _cube_colours(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _cube_colours(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(np.round(ours, 4).tolist(), np.round(ref, 4).tolist())
    assert np.ptp(ref[:, 0]) > 0.1
    assert np.abs(ours - ref).max() < 0.002, np.abs(ours - ref).max(axis=1)


def test_object_info_material_index_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """Material Index is the pass index of the material whose tree reads it (Cycles'
    shader_pass_id): each cube its own copy of the material, pass index i."""
    bpy = bpy_addon
    scene = fresh_scene
    mat = _material(bpy, "Info", "Material Index")
    _row(bpy, scene, mat)
    for i, ob in enumerate(sorted((o for o in scene.objects if o.type == "MESH"),
                                  key=lambda o: o.location.x)):
        m = mat.copy()
        m.pass_index = i
        ob.material_slots[0].link = "OBJECT"
        ob.material_slots[0].material = m
    ours = _cube_colours(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _cube_colours(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(np.round(ours, 4).tolist(), np.round(ref, 4).tolist())
    assert np.ptp(ref[:, 0]) > 0.1
    assert np.abs(ours - ref).max() < 0.002, np.abs(ours - ref).max(axis=1)


def _attribute_material(bpy, name, attribute, kind, output):
    """Emission of an Attribute node (type kind: OBJECT or INSTANCER) output, shown
    through a Mix Add of 4 (negative emission renders as 0 in the engine: a location's
    negative x stays visible, 0 stays apart from the black world)."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    e = nt.nodes.new("ShaderNodeEmission")
    a = nt.nodes.new("ShaderNodeAttribute")
    a.attribute_type, a.attribute_name = kind, attribute
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "ADD"
    mix.inputs["Factor"].default_value = 1.0
    mix.inputs[7].default_value = (4.0, 4.0, 4.0, 1.0)
    nt.links.new(a.outputs[output], mix.inputs[6])
    nt.links.new(mix.outputs[2], e.inputs["Color"])
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    return m


@pytest.mark.parametrize("attribute,output", [
    ("tint", "Color"), ("tint", "Factor"), ("tint", "Alpha"), ("color", "Color"),
    ("location", "Color"), ("[\"weight\"]", "Color")])
def test_object_attribute_matches_cycles(fresh_scene, bpy_addon, tmp_path, attribute,
                                         output):
    """Attribute node, type Object: the object's custom property (a 3- or 2-array, a
    number, a boolean; on the mesh data for one cube; absent on one: 0), an RNA path
    (color, location) or a quoted custom property path, as Blender hands them to Cycles
    (find_property_rgba)."""
    bpy = bpy_addon
    scene = fresh_scene
    _row(bpy, scene, _attribute_material(bpy, "ObAttr", attribute, "OBJECT", output))
    cubes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.location.x)
    values = [(0.9, 0.1, 0.4), 0.35, True, (0.2, 0.7), None, (0.5, 0.5, 0.1), 0.8, "data"]
    for i, (ob, val) in enumerate(zip(cubes, values)):
        ob["weight"] = 0.1 * i
        if val == "data":  # on the mesh (Linked6 shares cube 0's mesh: a fresh one)
            ob.data = ob.data.copy()
            ob.data["tint"] = (0.3, 0.9, 0.6)
        elif val is not None:
            ob["tint"] = val
    ours = _cube_colours(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _cube_colours(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(attribute, output, np.round(ours, 4).tolist(), np.round(ref, 4).tolist())
    assert np.ptp(ref) > 0.1
    assert np.abs(ours - ref).max() < 0.002, np.abs(ours - ref).max(axis=1)


def test_instancer_attribute_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """Attribute node, type Instancer: collection instances read their instancing
    empty's custom property (the instanced mesh object's where an empty has none)."""
    bpy = bpy_addon
    scene = fresh_scene
    mat = _attribute_material(bpy, "InstAttr", "tint", "INSTANCER", "Color")
    _row(bpy, scene, mat)
    coll = bpy.data.collections.new("Rock")
    src = bpy.data.objects.new("RockMesh", bpy.data.objects["Cube"].data)
    src["tint"] = (0.1, 0.2, 0.9)
    coll.objects.link(src)
    for ob in [o for o in scene.objects if o.type == "MESH"]:
        bpy.data.objects.remove(ob)
    for i in range(N):
        e = bpy.data.objects.new(f"Place{i}", None)
        e.instance_type, e.instance_collection = "COLLECTION", coll
        e.location = (i - (N - 1) / 2.0, 0.0, 0.0)
        if i % 3:
            e["tint"] = (0.1 * i, 0.9 - 0.1 * i, 0.4)
        scene.collection.objects.link(e)
    ours = _cube_colours(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _cube_colours(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(np.round(ours, 4).tolist(), np.round(ref, 4).tolist())
    assert np.ptp(ref[:, 0]) > 0.1
    assert np.abs(ours - ref).max() < 0.002, np.abs(ours - ref).max(axis=1)


@pytest.mark.parametrize("owner,output", [("view_layer", "Color"), ("scene", "Factor"),
                                          ("world", "Color"), ("none", "Alpha")])
def test_view_layer_attribute_matches_cycles(fresh_scene, bpy_addon, tmp_path, owner,
                                             output):
    """Attribute node, type View Layer: the view layer's property, else the scene's,
    else the world's (a custom property; none: 0, alpha 0), one value for every cube."""
    bpy = bpy_addon
    scene = fresh_scene
    _row(bpy, scene, _attribute_material(bpy, "LayerAttr", "mood", "VIEW_LAYER", output))
    target = {"view_layer": bpy.context.view_layer, "scene": scene, "world": scene.world,
              "none": None}[owner]
    if target is not None:
        target["mood"] = (0.7, 0.25, 0.55)
    ours = _cube_colours(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _cube_colours(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    print(owner, output, np.round(ours[0], 4).tolist(), np.round(ref[0], 4).tolist())
    assert np.abs(ref[0] - 4.0).max() > 0.1 or owner == "none"  # the property shows
    assert np.abs(ours - ref).max() < 0.002, np.abs(ours - ref).max(axis=1)
