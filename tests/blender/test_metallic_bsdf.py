"""The Metallic BSDF node (Blender 4.3+) as Cycles renders it: F82 mode is the Principled
metal lobe with the Edge Tint as its Specular Tint; Physical Conductor the F82-tint
Fresnel matching Cycles' fresnel_conductor at 0 and ~82 degrees (addon/materials.py
_metallic). Brightness against Cycles: the feature matrix's closure_metallic_bsdf
(1.001 / block error 0.044) and closure_metallic_conductor (1.006 / 0.086)."""
import numpy as np
import pytest

from blender_helpers import convert_material

pytestmark = pytest.mark.blender


def _metallic(bpy, **inputs):
    m = bpy.data.materials.new("metal")
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    node = nt.nodes.new("ShaderNodeBsdfMetallic")
    for k, v in inputs.items():  # fresnel_type, distribution
        setattr(node, k, v)
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return m, node


def test_f82_mode_is_the_principled_metal_lobe(fresh_scene, bpy_addon):
    bpy = bpy_addon
    m, node = _metallic(bpy)
    node.inputs["Base Color"].default_value = (0.95, 0.65, 0.35, 1.0)
    node.inputs["Edge Tint"].default_value = (0.4, 0.7, 1.0, 1.0)
    node.inputs["Roughness"].default_value = 0.35
    node.inputs["Anisotropy"].default_value = 0.5
    mat = convert_material(m)
    assert mat.metallic == 1.0 and mat.roughness == pytest.approx(0.35)
    np.testing.assert_allclose(mat.base_color, (0.95, 0.65, 0.35), rtol=1e-6)
    np.testing.assert_allclose(mat.specular_tint, (0.4, 0.7, 1.0), rtol=1e-6)
    assert mat.anisotropic == pytest.approx(0.5) and mat.multiscatter
    assert not [w for w in mat.warnings if "Metallic" in w or "not supported" in w]
    node.distribution = "GGX"
    node.inputs["Thin Film Thickness"].default_value = 300.0
    mat = convert_material(m)
    assert not mat.multiscatter
    assert [w for w in mat.warnings if "Thin Film" in w]


def test_physical_conductor_matches_the_conductor_fresnel(fresh_scene, bpy_addon):
    """Gold's n, k: F0 the conductor's at normal incidence, the F82-tint curve within
    0.025 of fresnel_conductor at every angle."""
    bpy = bpy_addon
    from addon.materials import conductor_f82_tint, fresnel_conductor
    m, node = _metallic(bpy, fresnel_type="PHYSICAL_CONDUCTOR")
    n, k = np.array([0.18, 0.42, 1.37]), np.array([3.42, 2.35, 1.77])
    node.inputs["IOR"].default_value = tuple(n)
    node.inputs["Extinction"].default_value = tuple(k)
    mat = convert_material(m)
    f0, tint = conductor_f82_tint(n, k)
    np.testing.assert_allclose(mat.base_color, f0, rtol=1e-6)
    np.testing.assert_allclose(mat.specular_tint, tint, rtol=1e-6)
    np.testing.assert_allclose(f0, fresnel_conductor(1.0, n, k), rtol=1e-12)
    mu = np.linspace(0.0, 1.0, 201)[:, None]
    schlick = f0 + (1.0 - f0) * (1.0 - mu) ** 5
    b = (f0 + (1.0 - f0) * (6.0 / 7.0) ** 5) * 7.0 / (6.0 / 7.0) ** 6 * (1.0 - tint)
    model = schlick - b * mu * (1.0 - mu) ** 6
    assert np.abs(model - fresnel_conductor(mu, n, k)).max() < 0.025
    at82 = 1.0 / 7.0  # the model's anchor: exact there
    s82 = f0 + (1.0 - f0) * (1.0 - at82) ** 5
    np.testing.assert_allclose(s82 - b * at82 * (1.0 - at82) ** 6,
                               fresnel_conductor(at82, n, k), rtol=1e-9)
