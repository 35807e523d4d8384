"""Shader AOVs through the add-on against live Cycles 5.0: View Layer > Shader AOV passes
(a Value and a Color one) written by a ball's AOV Output nodes (a constant mask, the
Generated coordinates as colour), the floor writing none. Before s40 the passes were
registered empty and warned."""
import numpy as np
import pytest

from blender_helpers import (cheap, cycles_plain, principled_material, read_layers,
                             render_exr)
from tools.canonical_mesh import primitive_uv_sphere_add

pytestmark = pytest.mark.blender


def _scene(bpy):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    cheap(scene, width=64, height=48, spp=16)
    bpy.ops.mesh.primitive_plane_add(size=10)
    bpy.context.object.data.materials.append(principled_material(bpy, "floor", (0.5,) * 3, 1))
    primitive_uv_sphere_add(radius=1, location=(0, 0, 1))
    ball = principled_material(bpy, "ball", (0.8, 0.3, 0.2), 0.5)
    nt = ball.node_tree
    mask = nt.nodes.new("ShaderNodeOutputAOV")
    mask.aov_name = "Mask"
    mask.inputs["Value"].default_value = 1.0
    grad = nt.nodes.new("ShaderNodeOutputAOV")
    grad.aov_name = "Grad"
    coord = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coord.outputs["Generated"], grad.inputs["Color"])
    bpy.context.object.data.materials.append(ball)
    bpy.ops.object.light_add(type="SUN")
    bpy.context.object.data.energy = 3.0
    bpy.ops.object.camera_add(location=(0, -6, 2), rotation=(np.radians(80), 0, 0))
    scene.camera = bpy.context.object
    layer = scene.view_layers[0]
    for name, kind in (("Mask", "VALUE"), ("Grad", "COLOR")):
        aov = layer.aovs.add()
        aov.name, aov.type = name, kind
    return scene


def test_shader_aovs_match_cycles(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = _scene(bpy)
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 16, 12)
    cyc = read_layers(render_exr(bpy, scene, tmp_path / "cycles.exr", multilayer=True))
    scene.render.engine = "PHOTONMAP"
    ours = read_layers(render_exr(bpy, scene, tmp_path / "ours.exr", multilayer=True))
    from addon import engine
    assert not [w for w in engine.last_render["warnings"] if "AOV" in w]
    assert ours["Mask"].shape[2] == 1 and ours["Grad"].shape[2] == 4
    for name in ("Mask", "Grad"):
        # Means within 1 % (pixels the ball's rim crosses differ by sampling).
        np.testing.assert_allclose(ours[name].mean(axis=(0, 1)), cyc[name].mean(axis=(0, 1)),
                                   rtol=0.01, atol=1e-3)
    inside = (cyc["Mask"][..., 0] == 1.0) & (ours["Mask"][..., 0] == 1.0)
    # Outside: 2 pixels or more from any pixel Cycles' ball touches (the pixel filters'
    # footprints differ at the rim).
    near = cyc["Mask"][..., 0] > 0.0
    for _ in range(2):
        grown = near.copy()
        grown[1:] |= near[:-1]
        grown[:-1] |= near[1:]
        grown[:, 1:] |= near[:, :-1]
        grown[:, :-1] |= near[:, 1:]
        near = grown
    outside = ~near
    assert inside.sum() > 300 and outside.sum() > 1500
    assert not ours["Mask"][outside].any() and not ours["Grad"][outside].any()
    # Inside the ball: Generated, a smooth function of the hit: per pixel within the
    # spread of the hits a pixel covers (16 samples each).
    np.testing.assert_allclose(ours["Grad"][inside], cyc["Grad"][inside], atol=0.03)
