"""Map Range (Float and Vector), Blackbody and Wave Texture in Blender node trees (addon/materials.py): a tree
of constants folds to its value (also on lobe parameters that must be one constant), a
texture-driven one is evaluated per hit; a node the add-on does not take falls back to
the socket's own value, and the warning names that value (new-user trial s22: Roughness
fell back to 0.5 with a warning that did not say so)."""
import numpy as np
import pytest
from blender_helpers import convert_material as _convert
from blender_helpers import node_material as _material

pytestmark = pytest.mark.blender




def _principled(nt, out):
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    nt.links.new(p.outputs[0], out.inputs["Surface"])
    return p


def test_constant_map_range_into_roughness_and_ior_folds(fresh_scene, bpy_addon):
    m, nt, out = _material(bpy_addon, "Folded")
    p = _principled(nt, out)
    mr = nt.nodes.new("ShaderNodeMapRange")
    mr.inputs["Value"].default_value = 0.25
    mr.inputs["To Min"].default_value = 0.2
    mr.inputs["To Max"].default_value = 0.6
    nt.links.new(mr.outputs["Result"], p.inputs["Roughness"])
    ior = nt.nodes.new("ShaderNodeMapRange")
    ior.interpolation_type = "SMOOTHSTEP"
    ior.inputs["Value"].default_value = 0.5
    ior.inputs["To Min"].default_value = 1.3
    ior.inputs["To Max"].default_value = 1.7
    nt.links.new(ior.outputs["Result"], p.inputs["IOR"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    assert mat.roughness == pytest.approx(0.3)
    assert not mat.scalar_textures
    assert mat.ior == pytest.approx(1.5)


def test_blackbody_into_emission_colour(fresh_scene, bpy_addon):
    from engine.shadernodes import blackbody_rec709
    m, nt, out = _material(bpy_addon, "Hot")
    e = nt.nodes.new("ShaderNodeEmission")
    bb = nt.nodes.new("ShaderNodeBlackbody")
    bb.inputs["Temperature"].default_value = 1500.0
    nt.links.new(bb.outputs["Color"], e.inputs["Color"])
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    want = np.maximum(blackbody_rec709([1500.0])[0], 0.0)
    assert np.allclose(np.asarray(mat.emission) / np.max(mat.emission),
                       want / want.max(), atol=1e-6)


def test_wave_through_map_range_into_roughness_is_per_hit(fresh_scene, bpy_addon):
    m, nt, out = _material(bpy_addon, "Waves")
    p = _principled(nt, out)
    wave = nt.nodes.new("ShaderNodeTexWave")
    mr = nt.nodes.new("ShaderNodeMapRange")
    mr.interpolation_type = "STEPPED"
    nt.links.new(wave.outputs["Fac" if "Fac" in wave.outputs else "Factor"],
                 mr.inputs["Value"])
    nt.links.new(mr.outputs["Result"], p.inputs["Roughness"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    node = mat.scalar_textures["roughness"]
    assert type(node).__name__ == "MapRange" and node.kind == "STEPPED"
    assert type(node.inputs["Value"]).__name__ == "Wave"


def test_unsupported_node_warning_names_the_value_used(fresh_scene, bpy_addon):
    """An IES Texture (not read) and a Geometry node's Normal on a BSDF's Normal input
    (not read there): the warning names the material, the input, the node and the value
    used instead."""
    m, nt, out = _material(bpy_addon, "Fallback")
    p = _principled(nt, out)
    p.inputs["Roughness"].default_value = 0.5
    ies = nt.nodes.new("ShaderNodeTexIES")   # not taken
    nt.links.new(ies.outputs["Fac"], p.inputs["Roughness"])
    geometry = nt.nodes.new("ShaderNodeNewGeometry")   # not taken
    nt.links.new(geometry.outputs["Normal"], p.inputs["Normal"])
    mat = _convert(m)
    assert mat.roughness == pytest.approx(0.5)
    assert any("material 'Fallback': Roughness of 'Principled BSDF': node 'IES "
               "Texture' (TEX_IES) not supported, using 0.5 (the socket's own "
               "value)" in w for w in mat.warnings), mat.warnings
    assert any("material 'Fallback'" in w and "'Geometry'" in w and "NEW_GEOMETRY" in w
               for w in mat.warnings), mat.warnings


def test_bevel_node_is_read_with_its_chained_normal(fresh_scene, bpy_addon):
    """A Bevel on a BSDF's Normal (engine/bevel.py), its Radius and Samples, and a Bump on
    its own Normal input (the normal it offsets)."""
    m, nt, out = _material(bpy_addon, "Rounded")
    p = _principled(nt, out)
    bevel = nt.nodes.new("ShaderNodeBevel")
    bevel.samples = 6
    bevel.inputs["Radius"].default_value = 0.02
    bump = nt.nodes.new("ShaderNodeBump")
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], bevel.inputs["Normal"])
    nt.links.new(bevel.outputs["Normal"], p.inputs["Normal"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    b = mat.normal_map
    assert type(b).__name__ == "Bevel" and b.samples == 6
    assert b.radius == pytest.approx(0.02) and type(b.normal).__name__ == "Bump"


def test_ambient_occlusion_outputs_share_one_node(fresh_scene, bpy_addon):
    """The Ambient Occlusion node is read per hit (engine/ambientocclusion.py): its AO
    output into Roughness and its Color output into Base Color share one OcclusionCore
    (one set of rays a hit), with the node's Samples, Distance, Inside and Only Local."""
    m, nt, out = _material(bpy_addon, "Dirt")
    p = _principled(nt, out)
    ao = nt.nodes.new("ShaderNodeAmbientOcclusion")
    ao.samples, ao.inside, ao.only_local = 7, True, True
    ao.inputs["Distance"].default_value = 0.25
    ao.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    nt.links.new(ao.outputs["AO"], p.inputs["Roughness"])
    nt.links.new(ao.outputs["Color"], p.inputs["Base Color"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    core = mat.scalar_textures["roughness"]
    assert type(core).__name__ == "OcclusionCore"
    assert (core.samples, core.inside, core.only_local) == (7, True, True)
    assert core.distance == pytest.approx(0.25) and core.normal is None
    assert type(mat.texture).__name__ == "AmbientOcclusion" and mat.texture.core is core
    assert np.allclose(mat.texture.color, (0.2, 0.4, 0.6))


def test_vector_map_range_folds_into_base_color(fresh_scene, bpy_addon):
    """A Vector Map Range of constants (Stepped, per component) folds to Cycles' value."""
    from engine.shadernodes import vector_map_range
    m, nt, out = _material(bpy_addon, "VectorRange")
    p = _principled(nt, out)
    vec = nt.nodes.new("ShaderNodeMapRange")
    vec.data_type = "FLOAT_VECTOR"
    vec.interpolation_type = "STEPPED"
    ins = {i.identifier: i for i in vec.inputs}   # the Vector inputs share the Float's names
    ins["Vector"].default_value = (0.3, 0.55, 0.9)
    ins["To_Min_FLOAT3"].default_value = (0.1, 0.2, 0.0)
    ins["To_Max_FLOAT3"].default_value = (0.9, 0.6, 0.5)
    nt.links.new(vec.outputs["Vector"], p.inputs["Base Color"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    want = vector_map_range((0.3, 0.55, 0.9), 0.0, 1.0, (0.1, 0.2, 0.0), (0.9, 0.6, 0.5), 4.0,
                            kind="STEPPED")
    assert np.allclose(mat.base_color, want), (mat.base_color, want)
    assert np.allclose(want, [0.1 + 0.8 * 0.25, 0.2 + 0.4 * 0.5, 0.5])


def test_constant_math_and_curve_trees_fold(fresh_scene, bpy_addon):
    """Math, Gamma, Color Ramp and RGB Curves fed only by constants are evaluated once at
    export: an IOR (which must be one constant) from a Math node, a Base Color from a
    Gamma of a constant colour, and no per-hit texture left."""
    m, nt, out = _material(bpy_addon, "FoldedMath")
    p = _principled(nt, out)
    add = nt.nodes.new("ShaderNodeMath")
    add.operation = "MULTIPLY_ADD"
    add.inputs[0].default_value, add.inputs[1].default_value = 0.5, 0.9
    add.inputs[2].default_value = 1.0
    nt.links.new(add.outputs[0], p.inputs["IOR"])
    g = nt.nodes.new("ShaderNodeGamma")
    g.inputs["Color"].default_value = (0.5, 0.25, 1.0, 1.0)
    g.inputs["Gamma"].default_value = 2.0
    nt.links.new(g.outputs[0], p.inputs["Base Color"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    assert mat.ior == pytest.approx(1.45)
    assert np.allclose(mat.base_color, (0.25, 0.0625, 1.0))
    assert mat.texture is None and not mat.scalar_textures


def test_a_node_tree_the_converter_cannot_read_falls_back_with_a_warning(
        fresh_scene, bpy_addon, monkeypatch):
    """An exception while reading a material's tree (s33: White Noise's W socket, absent
    by name in 3D, failed the whole render) renders the material as its viewport colour,
    warned with the material's name, and the render goes on."""
    from addon import materials
    m, nt, out = _material(bpy_addon, "Unreadable")
    _principled(nt, out)
    m.diffuse_color = (0.2, 0.4, 0.6, 1.0)

    def broken(self, *args, **kw):
        raise KeyError('bpy_prop_collection[key]: key "W" not found')
    monkeypatch.setattr(materials.MaterialConverter, "_shader", broken)
    monkeypatch.setattr(materials, "RAISE_UNREADABLE_TREES", False)  # (the conftest's)
    mat = _convert(m)
    assert np.allclose(mat.base_color, (0.2, 0.4, 0.6))
    assert any("'Unreadable'" in w and "could not be read" in w and "KeyError" in w
               and "test_blender_node_values.py:" in w for w in mat.warnings), mat.warnings


@pytest.mark.parametrize("case", ["missing file", "no image"])
def test_an_image_that_cannot_load_is_magenta_as_in_cycles(fresh_scene, bpy_addon, case):
    """An Image Texture whose file is missing, or that has no image, renders magenta (1, 0,
    1) as Cycles' TEX_IMAGE_MISSING colour, with one warning saying so (newuser40: it read
    0.8 grey under two contradicting warnings)."""
    bpy = bpy_addon
    m, nt, out = _material(bpy, "Lost")
    p = _principled(nt, out)
    tex = nt.nodes.new("ShaderNodeTexImage")
    if case == "missing file":
        img = bpy.data.images.new("gone", 4, 4)
        img.source, img.filepath = "FILE", "//nowhere/does_not_exist.png"
        tex.image = img
    nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    mat = _convert(m)
    # Looked up anywhere (UVs 0..1 and beyond): magenta.
    uvs = np.array([[0.3, 0.6], [0.0, 0.0], [1.7, -2.2]])
    np.testing.assert_allclose(mat.texture.sample(uvs), np.tile([1.0, 0.0, 1.0], (3, 1)))
    told = [w for w in mat.warnings if "magenta" in w]
    assert len(told) == 1 and not [w for w in mat.warnings if "not supported" in w]


def test_a_muted_node_passes_its_input_through_as_blender(fresh_scene, bpy_addon):
    """A muted colour or value node passes the input its internal link joins to the used
    output (Cycles' proxies for a muted node's internal links), silently: newuser41's
    muted Hue/Saturation on an RGB blue read as "not supported" and the Base Color's own
    red; a muted Math on Roughness read 0.5 instead of its input 0.05. Inside a node group
    too; an output with no internal link, or whose passed input is unlinked (a value typed
    into the muted node), leaves the socket its own value (Cycles' remove_proxy_nodes;
    newuser41b)."""
    bpy = bpy_addon
    m, nt, out = _material(bpy, "Muted")
    p = _principled(nt, out)
    p.inputs["Base Color"].default_value = (0.8, 0.2, 0.2, 1.0)
    rgb = nt.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.1, 0.2, 0.9, 1.0)
    hs = nt.nodes.new("ShaderNodeHueSaturation")
    hs.inputs["Hue"].default_value = 0.2
    nt.links.new(rgb.outputs[0], hs.inputs["Color"])
    nt.links.new(hs.outputs[0], p.inputs["Base Color"])
    math = nt.nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY"
    value = nt.nodes.new("ShaderNodeValue")
    value.outputs[0].default_value = 0.05
    nt.links.new(value.outputs[0], math.inputs[0])
    math.inputs[1].default_value = 10.0
    nt.links.new(math.outputs[0], p.inputs["Roughness"])
    unmuted = _convert(m)
    assert unmuted.roughness == pytest.approx(0.5)
    assert not np.allclose(unmuted.base_color, (0.1, 0.2, 0.9))
    hs.mute = math.mute = True
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    np.testing.assert_allclose(mat.base_color, (0.1, 0.2, 0.9), rtol=1e-6)
    assert mat.roughness == pytest.approx(0.05)
    # Inside a group: a muted Invert passes its Color (the group's input) through.
    group = bpy.data.node_groups.new("Tint", "ShaderNodeTree")
    group.interface.new_socket("Color", in_out="INPUT", socket_type="NodeSocketColor")
    group.interface.new_socket("Color", in_out="OUTPUT", socket_type="NodeSocketColor")
    gin, gout = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    inv = group.nodes.new("ShaderNodeInvert")
    group.links.new(gin.outputs[0], inv.inputs["Color"])
    group.links.new(inv.outputs[0], gout.inputs[0])
    inv.mute = True
    g = nt.nodes.new("ShaderNodeGroup")
    g.node_tree = group
    nt.links.new(rgb.outputs[0], g.inputs[0])
    nt.links.new(g.outputs[0], p.inputs["Base Color"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    np.testing.assert_allclose(mat.base_color, (0.1, 0.2, 0.9), rtol=1e-6)
    # A value typed into the muted node's passed input is not passed on (Cycles drops a
    # proxy with an unlinked input): the consumer's own value.
    hs2 = nt.nodes.new("ShaderNodeHueSaturation")
    hs2.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    hs2.mute = True
    nt.links.new(hs2.outputs[0], p.inputs["Base Color"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    np.testing.assert_allclose(mat.base_color, (0.8, 0.2, 0.2), rtol=1e-6)
    # A muted node whose output has no internal link: the socket's own value, no warning.
    tex = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(tex.outputs["Fac"], p.inputs["Metallic"])
    p.inputs["Metallic"].default_value = 0.25
    tex.mute = True
    if not any(link.to_socket.identifier == tex.outputs["Fac"].identifier
               for link in tex.internal_links):
        mat = _convert(m)
        assert not mat.warnings, mat.warnings
        assert mat.metallic == pytest.approx(0.25)
