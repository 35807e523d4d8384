"""Shader node groups read through as Cycles flattens them (addon/nodegroups.py): a group
giving a colour, a group wrapping a Principled BSDF with its inputs exposed, groups inside
groups, values carried across a boundary with Blender's conversions, warnings naming the
group, Normal Maps inside groups, a world built from a group; against live Cycles. Before
s40 a Group node was 'not supported' (newuser40: white cubes where Cycles showed a blue
checker and red plastic)."""
import math

import numpy as np
import pytest

from blender_helpers import block_means, cycles_and_ours, sun_light, world_color

pytestmark = pytest.mark.blender


class _AtPoints:
    """A Geometry stand-in whose Generated / Object coordinates are given points."""

    def __init__(self, points):
        self.points = points
        self.offset = np.zeros(3)

    def coordinates(self, name, prim, u, v):
        return self.points[prim]

    def hit_points(self, prim, u, v):
        return self.points[prim]

    def uvs(self, prim, u, v):
        return np.zeros((len(prim), 2))


def _convert(bpy, mat):
    from addon.core import load_engine
    from addon.materials import MaterialConverter
    return MaterialConverter(load_engine()).convert(mat)


def _group(bpy, name, inputs=(), outputs=()):
    """A shader node group with the given (name, socket type) interface items and its
    Group Input / Output nodes: (tree, group input, group output)."""
    tree = bpy.data.node_groups.new(name, "ShaderNodeTree")
    for sock, kind in inputs:
        tree.interface.new_socket(sock, in_out="INPUT", socket_type=kind)
    for sock, kind in outputs:
        tree.interface.new_socket(sock, in_out="OUTPUT", socket_type=kind)
    return tree, tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")


def _material_with_group(bpy, name, tree):
    """A material whose Surface is a Group node of tree (its first output)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    node = nt.nodes.new("ShaderNodeGroup")
    node.node_tree = tree
    node.name = "Wrapper"
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat, node


def test_a_wrapped_principled_takes_the_group_nodes_inputs(fresh_scene, bpy_addon):
    """A group wrapping a Principled BSDF whose Base Color and Roughness are group inputs:
    the Group node's own input values reach the BSDF (a Float input into the colour
    socket as grey, Blender's conversion); a texture linked outside the group too."""
    bpy = bpy_addon
    tree, gin, gout = _group(bpy, "Plastic", [("Tint", "NodeSocketColor"),
                                              ("Rough", "NodeSocketFloat"),
                                              ("Grey", "NodeSocketFloat")],
                             [("BSDF", "NodeSocketShader")])
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    tree.links.new(gin.outputs["Tint"], bsdf.inputs["Base Color"])
    tree.links.new(gin.outputs["Rough"], bsdf.inputs["Roughness"])
    tree.links.new(bsdf.outputs[0], gout.inputs[0])
    mat, node = _material_with_group(bpy, "Wrapped", tree)
    node.inputs["Tint"].default_value = (0.7, 0.2, 0.1, 1.0)
    node.inputs["Rough"].default_value = 0.35
    m = _convert(bpy, mat)
    np.testing.assert_allclose(m.base_color, (0.7, 0.2, 0.1), rtol=1e-6)
    assert m.roughness == pytest.approx(0.35)
    assert not m.warnings, m.warnings
    # The Float input carried into the colour socket: grey.
    tree.links.new(gin.outputs["Grey"], bsdf.inputs["Base Color"])
    node.inputs["Grey"].default_value = 0.4
    np.testing.assert_allclose(_convert(bpy, mat).base_color, (0.4, 0.4, 0.4), rtol=1e-6)
    # A texture linked into the Group node's input outside: the BSDF's texture.
    checker = mat.node_tree.nodes.new("ShaderNodeTexChecker")
    mat.node_tree.links.new(checker.outputs["Color"], node.inputs["Grey"])
    assert _convert(bpy, mat).texture is not None


def test_groups_inside_groups_and_warnings_name_the_path(fresh_scene, bpy_addon):
    """An outer group feeding a checker through an inner group's Multiply into a
    Principled BSDF (newuser40's nested case) converts to that texture; a node the
    converter does not know inside the inner group is named 'Outer/Inner/Node'."""
    bpy = bpy_addon
    inner, iin, iout = _group(bpy, "InnerTint", [("Color", "NodeSocketColor")],
                              [("Color", "NodeSocketColor")])
    mix = inner.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    mix.inputs[7].default_value = (0.2, 0.4, 1.0, 1.0)
    inner.links.new(iin.outputs[0], mix.inputs[6])
    inner.links.new(mix.outputs[2], iout.inputs[0])
    outer, _oin, oout = _group(bpy, "OuterShader", (), [("Shader", "NodeSocketShader")])
    checker = outer.nodes.new("ShaderNodeTexChecker")
    group = outer.nodes.new("ShaderNodeGroup")
    group.node_tree, group.name = inner, "Inner"
    bsdf = outer.nodes.new("ShaderNodeBsdfPrincipled")
    outer.links.new(checker.outputs["Color"], group.inputs[0])
    outer.links.new(group.outputs[0], bsdf.inputs["Base Color"])
    outer.links.new(bsdf.outputs[0], oout.inputs[0])
    mat, node = _material_with_group(bpy, "Nested", outer)
    node.name = "Outer"
    m = _convert(bpy, mat)
    assert not m.warnings, m.warnings
    # The same nodes without groups: the same colours at any point.
    flat = bpy.data.materials.new("Flat")
    flat.use_nodes = True
    ft = flat.node_tree
    fchecker = ft.nodes.new("ShaderNodeTexChecker")
    fmix = ft.nodes.new("ShaderNodeMix")
    fmix.data_type, fmix.blend_type = "RGBA", "MULTIPLY"
    fmix.inputs["Factor"].default_value = 1.0
    fmix.inputs[7].default_value = (0.2, 0.4, 1.0, 1.0)
    ft.links.new(fchecker.outputs["Color"], fmix.inputs[6])
    ft.links.new(fmix.outputs[2], ft.nodes["Principled BSDF"].inputs["Base Color"])
    want = _convert(bpy, flat).texture
    points = np.random.default_rng(3).uniform(-1.0, 1.0, (64, 3))
    at = _AtPoints(points)
    idx = np.arange(64)
    got = np.asarray(m.texture.evaluate(at, idx, np.zeros(64), np.zeros(64)))
    np.testing.assert_allclose(got, np.asarray(want.evaluate(at, idx, np.zeros(64),
                                                             np.zeros(64))))
    assert len(np.unique(got.round(6), axis=0)) == 2  # both checker colours met
    # An unsupported node inside the inner group: the warning gives its path.
    density = inner.nodes.new("ShaderNodeTexIES")  # (a lamp's node: warned in materials)
    density.name = "Dots"
    inner.links.new(density.outputs["Fac"], mix.inputs[7])
    warned = [w for w in _convert(bpy, mat).warnings if "Outer/Inner/Dots" in w]
    assert len(warned) == 1, _convert(bpy, mat).warnings


def test_normal_maps_inside_groups_get_tangents_and_worlds_read_groups(fresh_scene,
                                                                        bpy_addon):
    bpy = bpy_addon
    from addon import export
    tree, gin, gout = _group(bpy, "Bumpy", (), [("Normal", "NodeSocketVector")])
    nmap = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(nmap.outputs[0], gout.inputs[0])
    mat = bpy.data.materials.new("Tiles")
    mat.use_nodes = True
    grp = mat.node_tree.nodes.new("ShaderNodeGroup")
    grp.node_tree = tree
    mat.node_tree.links.new(grp.outputs[0],
                            mat.node_tree.nodes["Principled BSDF"].inputs["Normal"])
    bpy.ops.mesh.primitive_plane_add()
    ob = bpy.context.object
    ob.data.materials.append(mat)
    assert export._uses_tangent_normal_maps(ob)
    # A world whose Background sits in a group with its Strength exposed.
    world = bpy.data.worlds.new("Grouped")
    bpy.context.scene.world = world
    wt = world.node_tree
    for n in list(wt.nodes):
        if n.type == "BACKGROUND":
            wt.nodes.remove(n)
    sky, skin, skout = _group(bpy, "Sky", [("Strength", "NodeSocketFloat")],
                              [("Background", "NodeSocketShader")])
    bg = sky.nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = (0.2, 0.4, 0.8, 1.0)
    sky.links.new(skin.outputs[0], bg.inputs["Strength"])
    sky.links.new(bg.outputs[0], skout.inputs[0])
    node = wt.nodes.new("ShaderNodeGroup")
    node.node_tree = sky
    node.inputs[0].default_value = 2.5
    wt.links.new(node.outputs[0], next(n for n in wt.nodes
                                       if n.type == "OUTPUT_WORLD").inputs["Surface"])
    from addon.core import load_engine
    from addon.world import export_worlds
    warnings = []
    (background, env), seen = export_worlds(load_engine(), world, warnings)
    np.testing.assert_allclose(background, (0.5, 1.0, 2.0), rtol=1e-6)
    assert env is None and seen is None and not warnings


def test_grouped_materials_match_cycles(bpy_addon, tmp_path):
    """newuser40's groups_single: a colour group (a blue checker) into Base Color and a
    group wrapping red plastic, under a sun: as Cycles renders them."""
    bpy = bpy_addon
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world_color(bpy, sc, (0.3, 0.35, 0.4))
    sun_light(bpy, sc, (math.radians(35), 0, math.radians(30)), energy=3.0)
    bpy.ops.mesh.primitive_plane_add(size=10)
    tint, _gin, gout = _group(bpy, "TintGroup", (), [("Color", "NodeSocketColor")])
    checker = tint.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 8.0
    checker.inputs["Color1"].default_value = (0.1, 0.3, 0.9, 1.0)
    tint.links.new(checker.outputs["Color"], gout.inputs[0])
    mat = bpy.data.materials.new("ColourGroup")
    mat.use_nodes = True
    g = mat.node_tree.nodes.new("ShaderNodeGroup")
    g.node_tree = tint
    mat.node_tree.links.new(g.outputs[0],
                            mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    bpy.ops.mesh.primitive_cube_add(size=0.9, location=(-1, 0, 0.45))
    bpy.context.object.data.materials.append(mat)
    red, _rin, rout = _group(bpy, "RedPlastic", (), [("Shader", "NodeSocketShader")])
    bsdf = red.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.9, 0.1, 0.1, 1.0)
    red.links.new(bsdf.outputs[0], rout.inputs[0])
    mat2, _node = _material_with_group(bpy, "ShaderGroup", red)
    bpy.ops.mesh.primitive_cube_add(size=0.9, location=(1, 0, 0.45))
    bpy.context.object.data.materials.append(mat2)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -5, 2.5), (math.radians(67), 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 64, 48, 100
    ours, ref = cycles_and_ours(bpy, sc, tmp_path, cycles_spp=128, ours_spp=16)
    from addon import engine
    assert not [w for w in engine.last_render["warnings"] if "GROUP" in w]
    whole = ours.mean() / ref.mean()
    ratio = block_means(ours, 16) / block_means(ref, 16)
    assert 0.985 < whole < 1.015, whole
    assert 0.95 < ratio.min() and ratio.max() < 1.05, np.round(ratio, 3)
