"""Alpha cut-outs from Blender node trees (addon/materials.py): an image's Alpha into
Principled Alpha, and a Mix Shader of a Transparent BSDF whose factor is a texture, export
a per-hit alpha node (engine Material.alpha_texture) that reads the image's alpha at the
hit's UV, without a warning; what is still approximated warns."""
import numpy as np
import pytest
from blender_helpers import convert_material
from blender_helpers import node_material as _material

pytestmark = pytest.mark.blender


def _image(bpy, name, n=4):
    """Alpha 1 in the image's left half (u < 0.5), 0 in the right."""
    img = bpy.data.images.new(name, n, n, alpha=True, float_buffer=True)
    px = np.ones((n, n, 4), np.float32)
    px[:, n // 2:, 3] = 0.0
    img.pixels.foreach_set(px.ravel())
    return img


class _Geo:
    """Just enough of engine.geometry.Geometry for a UV lookup: one triangle whose UV at
    barycentrics (u, v) is (u, v)."""

    def uvs(self, prim, u, v):
        return np.stack([u, v], axis=1)


def _alpha_at(mat, us):
    u = np.asarray(us, np.float64)
    return mat.alpha * mat.alpha_texture.evaluate(_Geo(), np.zeros(len(u), np.int64), u,
                                                  np.full(len(u), 0.5))


def test_image_alpha_into_principled_alpha_is_a_cutout(fresh_scene, bpy_addon):
    bpy = bpy_addon
    m, nt, out = _material(bpy, "Leaf")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "leaf")
    tex.interpolation = "Closest"
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    nt.links.new(tex.outputs["Alpha"], p.inputs["Alpha"])
    nt.links.new(p.outputs[0], out.inputs["Surface"])
    mat = convert_material(m)
    assert mat.alpha_texture is not None and not mat.warnings
    a = np.asarray(_alpha_at(mat, [0.2, 0.8]), np.float64)
    assert np.allclose(a, [1.0, 0.0])


@pytest.mark.parametrize("transparent_first", [True, False])
def test_mix_with_transparent_by_a_texture_is_a_cutout(fresh_scene, bpy_addon,
                                                       transparent_first):
    bpy = bpy_addon
    m, nt, out = _material(bpy, "LeafMix")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "leafmix")
    tex.interpolation = "Closest"
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    t = nt.nodes.new("ShaderNodeBsdfTransparent")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(tex.outputs["Alpha"], mix.inputs[0])
    nt.links.new(t.outputs[0], mix.inputs[1 if transparent_first else 2])
    nt.links.new(d.outputs[0], mix.inputs[2 if transparent_first else 1])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    mat = convert_material(m)
    assert mat.alpha_texture is not None and not mat.warnings
    # Factor 1 picks the second shader: the diffuse side's coverage is fac or 1 - fac.
    expect = [1.0, 0.0] if transparent_first else [0.0, 1.0]
    assert np.allclose(_alpha_at(mat, [0.2, 0.8]), expect)
    assert np.allclose(mat.base_color, d.inputs["Color"].default_value[:3])


def test_mix_of_two_surfaces_by_a_texture_mixes_per_hit(fresh_scene, bpy_addon):
    """Two opaque surfaces mixed by a texture: the lobe parameters per hit (Diffuse +
    Glossy: the glossy share is the factor; docs/textures.md); with an emissive side the
    factor's own value, warned."""
    bpy = bpy_addon
    m, nt, out = _material(bpy, "TwoSurfaces")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "mask")
    a = nt.nodes.new("ShaderNodeBsdfDiffuse")
    b = nt.nodes.new("ShaderNodeBsdfGlossy")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(tex.outputs["Alpha"], mix.inputs[0])
    nt.links.new(a.outputs[0], mix.inputs[1])
    nt.links.new(b.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    mat = convert_material(m)
    assert mat.alpha_texture is None and mat.alpha == 1.0
    assert not any("mixes two surfaces by a texture" in w for w in mat.warnings)
    assert set(mat.scalar_textures) == {"metallic"} and mat.node == "glossy"
    e = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(e.outputs[0], mix.inputs[1])
    mat = convert_material(m)
    assert any("mixes two surfaces by a texture" in w for w in mat.warnings)
