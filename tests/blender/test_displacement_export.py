"""Material Output > Displacement in the add-on (addon/materials.py _displacement): Cycles'
"Bump Only" (the default method) and "Displacement and Bump" bump the shading normal by the
displacement's height along the normal (engine/displacement.py), under the BSDF's own Bump
node; a BSDF's Normal Map keeps its normal; "Displacement Only" and "Displacement and
Bump" move the vertices (Material.displacement); Tangent-space vector displacement is
warned. The rendered match with Cycles: tools/feature_matrix.py
texture_displacement_bump and texture_displacement_under_bump (test_feature_matrix.py)."""
import pytest
from blender_helpers import convert_material as _convert
from blender_helpers import node_material as _material

pytestmark = pytest.mark.blender


def _displaced(bpy, name, method="BUMP", normal=None, height="noise"):
    """A Diffuse BSDF material whose Displacement is a Displacement node of a Noise
    Texture (or a constant height); normal: None, "bump", "bevel" or "normal_map" into
    the BSDF."""
    m, nt, out = _material(bpy, name)
    m.displacement_method = method
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    disp = nt.nodes.new("ShaderNodeDisplacement")
    if height == "noise":
        noise = nt.nodes.new("ShaderNodeTexNoise")
        nt.links.new(noise.outputs["Fac"], disp.inputs["Height"])
    else:
        disp.inputs["Height"].default_value = height
    nt.links.new(disp.outputs[0], out.inputs["Displacement"])
    if normal == "bump":
        b = nt.nodes.new("ShaderNodeBump")
        wave = nt.nodes.new("ShaderNodeTexWave")
        nt.links.new(wave.outputs["Fac"], b.inputs["Height"])
        nt.links.new(b.outputs["Normal"], d.inputs["Normal"])
    elif normal == "bevel":
        b = nt.nodes.new("ShaderNodeBevel")
        nt.links.new(b.outputs["Normal"], d.inputs["Normal"])
    elif normal == "normal_map":
        nm = nt.nodes.new("ShaderNodeNormalMap")
        img = nt.nodes.new("ShaderNodeTexImage")
        img.image = bpy.data.images.new("flat_normals", 4, 4)
        img.image.colorspace_settings.name = "Non-Color"
        nt.links.new(img.outputs["Color"], nm.inputs["Color"])
        nt.links.new(nm.outputs["Normal"], d.inputs["Normal"])
    return m


def test_bump_only_bumps_the_normal_without_a_warning(fresh_scene, bpy_addon):
    from engine import displacement as dp
    from engine.bump import Bump
    mat = _convert(_displaced(bpy_addon, "BumpOnly"))
    assert not mat.warnings, mat.warnings
    assert isinstance(mat.normal_map, dp.DisplacedNormals)
    assert isinstance(mat.normal_map.bump, Bump) and mat.normal_map.then is None
    height = mat.normal_map.bump.height
    assert isinstance(height, dp.DisplacementHeight)
    assert isinstance(height.displacement, dp.Displacement)
    assert height.displacement.space == "OBJECT"  # the node's default
    assert mat.normal_map.bump.distance == 1.0 and mat.normal_map.bump.strength == 1.0


def test_bump_and_bevel_nodes_go_under_the_displacement_a_normal_map_replaces_it(
        fresh_scene, bpy_addon):
    from engine import displacement as dp
    from engine.bump import Bump
    from engine.normalmap import NormalMap
    chained = _convert(_displaced(bpy_addon, "Chained", normal="bump"))
    assert isinstance(chained.normal_map, dp.DisplacedNormals)
    assert isinstance(chained.normal_map.then, Bump)
    bevelled = _convert(_displaced(bpy_addon, "Bevelled", normal="bevel"))
    from engine.bevel import Bevel
    assert isinstance(bevelled.normal_map, dp.DisplacedNormals)
    assert isinstance(bevelled.normal_map.then, Bevel)  # its Normal: sd->N, displaced
    mapped = _convert(_displaced(bpy_addon, "Mapped", normal="normal_map"))
    assert isinstance(mapped.normal_map, NormalMap)  # Cycles: built from the vertex normal


def test_methods_that_move_the_surface_set_the_material_displacement(fresh_scene, bpy_addon):
    """Displacement Only: the vertices move (Material.displacement), no bump; Displacement
    and Bump: both; a constant height moves a truly displaced surface (an offset along
    the normal) but bumps nothing. The moved render: test_true_displacement_cycles.py."""
    from engine import displacement as dp
    only = _convert(_displaced(bpy_addon, "TrueOnly", method="DISPLACEMENT"))
    assert only.normal_map is None and not only.warnings, only.warnings
    assert isinstance(only.displacement, dp.Displacement)
    assert only.displacement_method == "DISPLACEMENT" and dp.moves_vertices(only)
    both = _convert(_displaced(bpy_addon, "Both", method="BOTH"))
    assert isinstance(both.normal_map, dp.DisplacedNormals) and not both.warnings
    assert isinstance(both.displacement, dp.Displacement) and both.displacement_method == "BOTH"
    flat = _convert(_displaced(bpy_addon, "Offset", method="DISPLACEMENT", height=0.7))
    assert flat.normal_map is None and dp.moves_vertices(flat)
    bump = _convert(_displaced(bpy_addon, "BumpOnly2"))
    assert bump.displacement is None and not dp.moves_vertices(bump)


def test_constant_displacement_makes_no_bump(fresh_scene, bpy_addon):
    mat = _convert(_displaced(bpy_addon, "Flat", height=0.7))
    assert mat.normal_map is None and not mat.warnings, mat.warnings


def test_vector_displacement_world_read_tangent_warned(fresh_scene, bpy_addon):
    from engine import displacement as dp
    for space in ("WORLD", "OBJECT", "TANGENT"):
        m, nt, out = _material(bpy_addon, f"Vector{space}")
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        nt.links.new(d.outputs[0], out.inputs["Surface"])
        vd = nt.nodes.new("ShaderNodeVectorDisplacement")
        vd.space = space
        noise = nt.nodes.new("ShaderNodeTexNoise")
        nt.links.new(noise.outputs["Color"], vd.inputs["Vector"])
        nt.links.new(vd.outputs[0], out.inputs["Displacement"])
        mat = _convert(m)
        if space == "TANGENT":
            assert mat.normal_map is None
            assert any("Tangent space is not supported" in w for w in mat.warnings), \
                mat.warnings
        else:
            assert not mat.warnings, mat.warnings
            vec = mat.normal_map.bump.height.displacement
            assert isinstance(vec, dp.VectorDisplacement) and vec.space == space


def test_a_texture_straight_into_displacement_is_its_vector(fresh_scene, bpy_addon):
    from engine import displacement as dp
    m, nt, out = _material(bpy_addon, "Straight")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], out.inputs["Displacement"])
    mat = _convert(m)
    assert not mat.warnings, mat.warnings
    assert isinstance(mat.normal_map, dp.DisplacedNormals)
    assert not isinstance(mat.normal_map.bump.height.displacement,
                          (dp.Displacement, dp.VectorDisplacement))


def test_adaptive_subdivision_is_warned_and_the_render_levels_used(fresh_scene, bpy_addon):
    """Cycles dices a mesh whose last Subdivision modifier is adaptive to its pixel size;
    Blender hands the exporter the modifier's render levels: warned, naming the object."""
    bpy = bpy_addon
    from addon import export
    from addon.core import load_engine
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=2, y_subdivisions=2)
    ob = bpy.context.object
    ob.name = "Terrain"
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 2
    from blender_helpers import looking_down_camera
    looking_down_camera(bpy, fresh_scene, 3.0)
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=8)
    assert not [w for w in out.warnings if "Adaptive" in w]
    mod.use_adaptive_subdivision = True
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=8)
    assert any("object 'Terrain': Adaptive Subdivision is not made" in w
               and "render levels (2)" in w for w in out.warnings), out.warnings
    assert sum(len(m.faces) for m in out.meshes) == 2 * 16 * 4  # 4 quads, 2 levels
