"""Volume emission against Cycles (issue 14; engine/volumeemission.py, docs/compatibility.md
"volemit38"): a glowing volume-only box over a white floor, no lamp, black world, and a
glowing World Volume.

The box is a Principled Volume (Emission Strength x Emission Color; with and without
density, i.e. with absorption and scattering; its blackbody) or an Emission shader added
to a Volume Absorption; the Surface unlinked. Seen from the side: the box's own glow (the
camera's segments through it) and the floor beside and in front of it, which only the
glow lights (Cycles: its BSDF-sampled paths; ours: the final-gather rays, no photon).
5 x 5 block means within 3 % of Cycles.
"""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

EMISSION_COLOR = (1.0, 0.5, 0.2)


def _glow(bpy, name, kind):
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    if kind == "emission-shader":
        e = nt.nodes.new("ShaderNodeEmission")
        e.inputs["Color"].default_value = (*EMISSION_COLOR, 1.0)
        e.inputs["Strength"].default_value = 1.5
        a = nt.nodes.new("ShaderNodeVolumeAbsorption")
        a.inputs["Color"].default_value = (0.5, 0.7, 0.9, 1.0)
        a.inputs["Density"].default_value = 0.6
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(e.outputs[0], add.inputs[0])
        nt.links.new(a.outputs[0], add.inputs[1])
        nt.links.new(add.outputs[0], out.inputs["Volume"])
        return m
    v = nt.nodes.new("ShaderNodeVolumePrincipled")
    v.inputs["Density"].default_value = {"emission": 0.0, "scatter": 0.8,
                                         "blackbody": 0.3}[kind]
    v.inputs["Color"].default_value = (0.7, 0.7, 0.7, 1.0)
    if kind == "blackbody":
        v.inputs["Blackbody Intensity"].default_value = 1.0
        v.inputs["Temperature"].default_value = 2000.0
    else:
        v.inputs["Emission Strength"].default_value = 2.0
        v.inputs["Emission Color"].default_value = (*EMISSION_COLOR, 1.0)
    nt.links.new(v.outputs[0], out.inputs["Volume"])
    return m


def _render(bpy, scene, path, engine, spp):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    c = cycles_plain(scene, spp, 4)
    c.volume_bounces = 0
    if engine != "CYCLES":
        cheap(scene, spp=spp)
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3]


def _block(img, rc, r=2):
    y, x = rc
    return img[y - r:y + r + 1, x - r:x + r + 1].reshape(-1, 3).mean(axis=0)


def _base_scene(bpy):
    import os
    import sys
    from blender_helpers import ROOT, black_world, default_photonmap
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    default_photonmap(scene)
    mb.plane("Floor", 8, 8, mb.material("white", "diffuse", (0.8, 0.8, 0.8)))
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    scene.render.resolution_percentage = 100
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    return scene, mb


@pytest.mark.parametrize("kind", ["emission", "scatter", "blackbody", "emission-shader"])
def test_glowing_box_over_a_floor_matches_cycles(bpy_addon, tmp_path, kind):
    """The box seen directly, the floor in front of it and beside it (lit by the glow
    alone), and the image's sum: ours 256 spp against Cycles 1024, within 3 %."""
    bpy = bpy_addon
    from blender_helpers import convert_material, export_warnings, project
    scene, mb = _base_scene(bpy)
    mb.box("Glow", 1.2, 1.2, 0.8, _glow(bpy, "glow", kind), location=(0.0, 0.0, 0.8))
    mb.camera((0.0, -5.0, 1.6), (0.0, 0.0, 0.5), fov_deg=45.0)
    m = convert_material(bpy.data.materials["glow"])
    assert m.volume_only and not m.warnings, m.warnings
    assert np.all(m.volume_emission > 0)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 256)
    assert not [w for w in export_warnings(bpy) if "emission" in w]
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 1024)
    for where, point in (("box", (0.0, 0.0, 0.8)), ("floor in front", (0.0, -1.1, 0.0)),
                         ("floor beside", (1.2, -0.3, 0.0))):
        rc = project(bpy, scene, point)
        a, b = _block(ours, rc), _block(ref, rc)
        print(kind, where, a.round(4), b.round(4), (a / b).round(3))
        np.testing.assert_allclose(a, b, rtol=0.03, err_msg=where)
    ratio = ours.reshape(-1, 3).sum(axis=0) / ref.reshape(-1, 3).sum(axis=0)
    print(kind, "image sum ratio", ratio.round(4))
    np.testing.assert_allclose(ratio, 1.0, rtol=0.02)


def test_glowing_world_volume_matches_cycles(bpy_addon, tmp_path):
    """A World Volume (Principled Volume, Density 0.1, Emission Strength 0.05) over the
    white floor, no lamp: the floor lit by the glow of the half-space above it (rho e /
    sigma_t far from the floor's edges) and seen through 3-6 m of it, the sky its glow
    to infinity (e / sigma_t). Ours 256 spp against Cycles 1024: blocks within 3 %."""
    bpy = bpy_addon
    from blender_helpers import project
    scene, mb = _base_scene(bpy)
    world = scene.world
    nt = world.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_WORLD")
    v = nt.nodes.new("ShaderNodeVolumePrincipled")
    v.inputs["Density"].default_value = 0.1
    v.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    v.inputs["Emission Strength"].default_value = 0.05
    v.inputs["Emission Color"].default_value = (*EMISSION_COLOR, 1.0)
    nt.links.new(v.outputs[0], out.inputs["Volume"])
    mb.camera((0.0, -5.0, 1.6), (0.0, 0.0, 0.5), fov_deg=45.0)
    try:
        ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 256)
        ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 1024)
    finally:
        nt.nodes.remove(v)
    for where, point in (("floor near", (0.0, -1.0, 0.0)), ("floor far", (1.0, 1.5, 0.0))):
        rc = project(bpy, scene, point)
        a, b = _block(ours, rc), _block(ref, rc)
        assert np.all(np.isfinite(b)), (where, rc)
        print("world", where, a.round(4), b.round(4), (a / b).round(3))
        np.testing.assert_allclose(a, b, rtol=0.03, err_msg=where)
    sky = _block(ours, (5, 32)), _block(ref, (5, 32))
    print("world sky", sky[0].round(4), sky[1].round(4), (sky[0] / sky[1]).round(3))
    np.testing.assert_allclose(sky[0], sky[1], rtol=0.03)


def test_mixed_glow_and_an_emitting_world_volume_without_density(bpy_addon):
    """A Mix Shader of an Emission shader and a Volume Absorption weighs the emission by
    its factor (Cycles' closure weights); a World Volume that emits but has Density 0
    (an infinite glow that dims nothing) is warned and ignored, naming the world."""
    bpy = bpy_addon
    from blender_helpers import convert_material, export_warnings, node_material
    scene, mb = _base_scene(bpy)
    m, nt, out = node_material(bpy, "mixed glow")
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*EMISSION_COLOR, 1.0)
    e.inputs["Strength"].default_value = 2.0
    a = nt.nodes.new("ShaderNodeVolumeAbsorption")
    a.inputs["Density"].default_value = 1.0
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.25
    nt.links.new(e.outputs[0], mix.inputs[1])
    nt.links.new(a.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Volume"])
    conv = convert_material(m)
    np.testing.assert_allclose(conv.volume_emission, 0.75 * 2.0 * np.array(EMISSION_COLOR),
                               rtol=1e-6)
    world = scene.world
    wout = next(n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD")
    v = world.node_tree.nodes.new("ShaderNodeVolumePrincipled")
    v.inputs["Density"].default_value = 0.0
    v.inputs["Emission Strength"].default_value = 1.0
    world.node_tree.links.new(v.outputs[0], wout.inputs["Volume"])
    mb.camera((0.0, -5.0, 1.6), (0.0, 0.0, 0.5), fov_deg=45.0)
    try:
        warned = [w for w in export_warnings(bpy) if "World Volume" in w]
    finally:
        world.node_tree.nodes.remove(v)
    assert warned and f"'{world.name}'" in warned[0], warned
