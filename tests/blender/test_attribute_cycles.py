"""Attribute node (type Geometry) and Color Attribute node by name against Cycles, texel
by texel (issue 14): a mesh's float, 2-D vector (a UV map), vector and colour attributes
on its points, corners and faces, each output (Color / Vector, Fac, Alpha) as Cycles'
svm_node_attr gives it. They read the socket's own value before.

Names that are Cycles' standard attribute names ("heat", "generated", "uv", ...) read
Cycles' standard attribute, whatever the mesh holds under that name.

The harness of test_color_nodes_cycles.py (an emissive plane whose colour is the node
under test, lifted by LIFT so values below 0 show; 16 samples near each pixel's centre in
both renderers), on a grid of 16 x 1 quads carrying seeded random attributes."""
import numpy as np
import pytest

from test_color_nodes_cycles import LIFT, H, W, _plane_scene

pytestmark = pytest.mark.blender


def _attribute_node(name, output, node="ShaderNodeAttribute"):
    def build(nodes, links):
        a = nodes.new(node)
        if node == "ShaderNodeAttribute":
            a.attribute_type, a.attribute_name = "GEOMETRY", name
        else:
            a.layer_name = name
        return a.outputs[output]
    return build


def _uv_map_node(name, image=False):
    """UV Map node naming a map other than the render one (alone, or placing a
    generated 8 x 8 colour grid image)."""
    def build(nodes, links):
        uv = nodes.new("ShaderNodeUVMap")
        uv.uv_map = name
        if not image:
            return uv.outputs["UV"]
        import bpy
        img = bpy.data.images.new("Grid", 8, 8, float_buffer=True)
        img.colorspace_settings.name = "Non-Color"
        px = np.random.default_rng(5).uniform(0.1, 1.0, (8 * 8, 4)).astype(np.float32)
        px[:, 3] = 1.0
        img.pixels.foreach_set(px.ravel())
        img.update()
        img.pack()
        tex = nodes.new("ShaderNodeTexImage")
        tex.image, tex.interpolation = img, "Linear"
        links.new(uv.outputs["UV"], tex.inputs["Vector"])
        return tex.outputs["Color"]
    return build


def _absent_alphas(nodes, links):
    """Alpha of an attribute the mesh lacks: 1 from the Attribute node, 0 from the Color
    Attribute node (svm_node_attr / svm_node_vertex_color), summed with 0.5 x their sum
    on a varying factor (so the case varies along the plane)."""
    a = _attribute_node("absent", "Alpha")(nodes, links)
    b = _attribute_node("absent", "Alpha", "ShaderNodeVertexColor")(nodes, links)
    w = _attribute_node("warmth", "Factor")(nodes, links)
    add = nodes.new("ShaderNodeMath")
    add.operation = "MULTIPLY_ADD"
    add.inputs[1].default_value = 0.5
    links.new(b, add.inputs[0])
    links.new(w, add.inputs[2])
    total = nodes.new("ShaderNodeMath")
    total.operation = "ADD"
    links.new(a, total.inputs[0])
    links.new(add.outputs[0], total.inputs[1])
    return total.outputs[0]


# (attribute name, data type, domain) added to the grid, values seeded per element.
ATTRIBUTES = [("warmth", "FLOAT", "POINT"), ("heat", "FLOAT", "POINT"),
              ("flow", "FLOAT_VECTOR", "CORNER"), ("tint", "FLOAT_COLOR", "POINT"), ("paint", "BYTE_COLOR", "CORNER"),
              ("cell", "FLOAT", "FACE"), ("mask", "INT", "FACE")]

CASES = {
    "float_point_fac": _attribute_node("warmth", "Factor"),
    "float_point_color": _attribute_node("warmth", "Color"),
    "vector_corner_vector": _attribute_node("flow", "Vector"),
    "vector_corner_fac": _attribute_node("flow", "Factor"),
    "colour_point_color": _attribute_node("tint", "Color"),
    "colour_point_alpha": _attribute_node("tint", "Alpha"),
    "colour_point_fac": _attribute_node("tint", "Factor"),
    "byte_colour_corner_color": _attribute_node("paint", "Color"),
    "float_face_fac": _attribute_node("cell", "Factor"),
    "int_face_fac": _attribute_node("mask", "Factor"),
    "uv_map_by_name_vector": _attribute_node("Second", "Vector"),
    "uv_map_by_name_fac": _attribute_node("Second", "Factor"),
    # Cycles' standard names read its standard attributes, not the mesh's: a mesh has no
    # volume "heat" (0 everywhere: checked by the range below being the lift's) and its
    # "generated" is the texture space, read as the Texture Coordinate node's.
    "generated_by_name_vector": _attribute_node("generated", "Vector"),
    "uv_by_name_fac": _attribute_node("uv", "Factor"),
    "color_attribute_node_by_name": _attribute_node("paint", "Color", "ShaderNodeVertexColor"),
    "color_attribute_node_alpha": _attribute_node("tint", "Alpha", "ShaderNodeVertexColor"),
    "absent_alphas": _absent_alphas,
    "uv_map_node_by_name": _uv_map_node("Second"),
    "uv_map_node_through_image": _uv_map_node("Second", image=True),
}


def _grid(bpy):
    """Replace the harness' plane by a 2 x 2 m grid of 16 x 1 quads with its material and
    the ATTRIBUTES, plus a second UV map 'Second'."""
    plane = bpy.context.object
    mat = plane.data.materials[0]
    bpy.data.objects.remove(plane)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=16, y_subdivisions=1, size=2.0)
    ob = bpy.context.object
    me = ob.data
    me.materials.append(mat)
    rng = np.random.default_rng(14)
    for name, kind, domain in ATTRIBUTES:
        a = me.attributes.new(name, kind, domain)
        n = len(a.data)
        if kind in ("FLOAT", "INT"):
            vals = rng.uniform(-0.5, 1.5, n) if kind == "FLOAT" else rng.integers(0, 3, n)
            a.data.foreach_set("value", vals.astype(np.float32 if kind == "FLOAT" else np.int32))
        elif kind == "FLOAT_VECTOR":
            a.data.foreach_set("vector", rng.uniform(-0.8, 1.2, 3 * n).astype(np.float32))
        else:
            a.data.foreach_set("color", rng.uniform(0.0, 1.0, 4 * n).astype(np.float32))
    uv = me.uv_layers.new(name="Second")
    xy = np.array([me.vertices[lp.vertex_index].co[:2] for lp in me.loops])
    uv.data.foreach_set("uv", np.stack([0.3 + 0.25 * xy[:, 0] ** 2, 0.5 - 0.3 * xy[:, 0]],
                                       1).astype(np.float32).ravel())
    me.update()
    return ob


@pytest.mark.parametrize("case", sorted(CASES))
def test_attribute_matches_cycles_texel_by_texel(fresh_scene, bpy_addon, tmp_path, case):
    bpy = bpy_addon
    scene = fresh_scene
    _plane_scene(bpy, scene, CASES[case], LIFT)
    _grid(bpy)
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3] - LIFT
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3] - LIFT
    assert ours.shape == (H, W, 3)
    row_o, row_r = ours.mean(axis=0), ref.mean(axis=0)
    err = np.abs(row_o - row_r)
    print(f"{case}: max |ours - Cycles| {err.max():.5f}, Cycles range "
          f"{row_r.min():.3f} .. {row_r.max():.3f}")
    assert np.all(np.isfinite(ours))
    assert np.ptp(row_r) > 0.05  # the attribute varies along the plane
    assert np.all(err <= 0.005 + 0.005 * np.abs(row_r)), np.argwhere(
        err > 0.005 + 0.005 * np.abs(row_r))[:5]


def test_cycles_standard_name_reads_cycles_attribute_not_the_mesh_one(fresh_scene, bpy_addon,
                                                                      tmp_path):
    """An Attribute node named 'heat' reads Cycles' volume heat (absent on a mesh: 0), not
    the mesh's float attribute 'heat' (ATTRIBUTES), in both renderers."""
    bpy = bpy_addon
    scene = fresh_scene
    _plane_scene(bpy, scene, _attribute_node("heat", "Color"), LIFT)
    _grid(bpy)
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3] - LIFT
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3] - LIFT
    assert np.abs(ref).max() < 1e-4 and np.abs(ours).max() < 1e-4


def _islands(bpy):
    """Replace the harness' plane by one mesh of islands along x: strips of 1 to 3 quads
    (vertices listed in a shuffled order, so which vertex the disjoint set keeps as an
    island's root matters), 20 quads in all, with the harness' material."""
    plane = bpy.context.object
    mat = plane.data.materials[0]
    bpy.data.objects.remove(plane)
    rng = np.random.default_rng(34)
    verts, faces, x = [], [], -1.0
    for n in (1, 2, 3, 1, 2, 1, 3, 2, 1, 2, 1, 1):
        order = rng.permutation(2 * (n + 1))  # this strip's vertices, shuffled
        base = len(verts)
        pos = [None] * (2 * (n + 1))
        for i in range(n + 1):
            for j, y in enumerate((-0.5, 0.5)):
                pos[order[2 * i + j]] = (x + i * 2.0 / 20.0, y, 0.0)
        verts += pos
        for i in range(n):
            a, b, c, d = 2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1
            faces.append((base + int(order[a]), base + int(order[b]), base + int(order[c]),
                          base + int(order[d])))
        x += n * 2.0 / 20.0
    me = bpy.data.meshes.new("Islands")
    me.from_pydata(verts, [], faces)
    me.update()
    me.materials.append(mat)
    ob = bpy.data.objects.new("Islands", me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


@pytest.mark.parametrize("source", ["geometry", "attribute"])
def test_random_per_island_matches_cycles(fresh_scene, bpy_addon, tmp_path, source):
    """Geometry > Random Per Island (and the Attribute node of its standard name): Cycles'
    hash of each island's disjoint-set root, one value per island, identical texel by
    texel."""
    bpy = bpy_addon
    scene = fresh_scene

    def build(nodes, links):
        if source == "geometry":
            return nodes.new("ShaderNodeNewGeometry").outputs["Random Per Island"]
        return _attribute_node("random_per_island", "Color")(nodes, links)
    _plane_scene(bpy, scene, build, LIFT)
    _islands(bpy)
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3] - LIFT
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3] - LIFT
    row_o, row_r = ours.mean(axis=0), ref.mean(axis=0)
    print(source, np.round(row_r[::4, 0], 4).tolist(), np.abs(row_o - row_r).max())
    assert len(np.unique(np.round(row_r[:, 0], 3))) >= 8  # the islands differ
    assert np.abs(row_o - row_r).max() < 0.002
