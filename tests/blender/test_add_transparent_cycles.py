"""An Add Shader with a Transparent BSDF against Cycles (issue 14: "Closures as Cycles
defines them ... Mix and Add", within 2 %; s44 addshader44).

Cycles sums every closure's weight, the Transparent BSDF's too (bsdf_transparent_setup
adds it to closure_transparent_extinction, which shadow rays take unclamped and camera
rays sample by its share of the summed weights): Add of a white Transparent BSDF and a
Diffuse BSDF passes all the light and reflects as the Diffuse BSDF alone. The export
averaged the transparent shares (0.27-0.65 x Cycles on a sphere in a grey world, warned).
And a camera path past a bounce limit still passes transparent surfaces in Cycles
(PATH_RAY_TERMINATE_AFTER_TRANSPARENT); ours stopped there (a Glossy BSDF seen through a
half-transparent sphere: 0.86 x Cycles at Max Bounces 0).

Scenes of bench/bench_add_shader_sweep.py: a smooth sphere filling an orthographic view
in a uniform grey world; a sunlit floor under a card. 24 x 24, ours 16 spp against
Cycles 128 (each case about a second).
"""
import math
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))), "bench"))
from bench_add_shader_sweep import CLOSURES, _node, join, sphere_scene  # noqa: E402
from bench_add_shader_sweep import render as _render, surface_material  # noqa: E402
from test_add_refraction_cycles import _check  # noqa: E402

pytestmark = pytest.mark.blender


_diffuse, _principled, _translucent = (CLOSURES[k] for k in ("diffuse", "principled",
                                                              "translucent"))


def _transparent(nd, rgb=(1.0, 1.0, 1.0)):
    return _node(nd, "ShaderNodeBsdfTransparent", Color=rgb)


def _white_glossy(nd):
    return _node(nd, "ShaderNodeBsdfGlossy", Color=(1.0, 1.0, 1.0), Roughness=0.25)


def _add(nd, ln, a, b):
    return join(nd, ln, a, b)


def _mix(nd, ln, fac, a, b):
    return join(nd, ln, a, b, fac)


def _sphere_scene(bpy, scene, build):
    sphere_scene(bpy, scene, surface_material(bpy, "Pair", build), 24)


# (build, Light Paths bounces). Before s44: 0.366 / 0.327-0.395 / 0.38-0.52 / 0.86.
SPHERE_CASES = {
    "add transparent+diffuse": (lambda nd, ln: _add(nd, ln, _transparent(nd), _diffuse(nd)),
                                8),
    "add orange transparent+principled": (
        lambda nd, ln: _add(nd, ln, _transparent(nd, (0.9, 0.7, 0.4)), _principled(nd)), 8),
    "add transparent+translucent": (
        lambda nd, ln: _add(nd, ln, _translucent(nd), _transparent(nd)), 8),
    # An Add inside a Mix: 0.7 x (transparent + diffuse) + 0.3 x diffuse passes 0.7.
    "mix(add transparent+diffuse, diffuse)": (
        lambda nd, ln: _mix(nd, ln, 0.3, _add(nd, ln, _transparent(nd), _diffuse(nd)),
                            _diffuse(nd)), 8),
    # Past the bounce limit the glossy lobe's reflected ray still passes the near side.
    "mix 0.5 transparent+glossy, bounces 0": (
        lambda nd, ln: _mix(nd, ln, 0.5, _transparent(nd), _white_glossy(nd)), 0),
}


@pytest.mark.parametrize("case", sorted(SPHERE_CASES))
def test_transparent_sums_on_a_sphere_in_a_grey_world_match_cycles(fresh_scene, bpy_addon,
                                                                   tmp_path, case):
    bpy = bpy_addon
    build, bounces = SPHERE_CASES[case]
    _sphere_scene(bpy, fresh_scene, build)
    ours = _render(bpy, fresh_scene, "PHOTONMAP", 16, tmp_path / "ours.exr", bounces)
    ref = _render(bpy, fresh_scene, "CYCLES", 128, tmp_path / "cycles.exr", bounces)
    assert ref.mean() > 0.1
    _check(ours, ref, case)


def test_floor_under_a_summed_card_gets_the_whole_sun_as_in_cycles(fresh_scene, bpy_addon,
                                                                   tmp_path):
    """A sunlit floor under a card of Add(white Transparent, grey Diffuse), seen from
    above through the card, direct light only: the shadow ray and the camera ray each
    pass the summed transparency 1 (the average passed 1/2 each: a floor at 1/4), and the
    card's top adds its diffuse reflection of the sun."""
    from blender_helpers import looking_down_camera, sun_light, world_color
    bpy = bpy_addon
    scene = fresh_scene
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=20)
    bpy.context.object.data.materials.append(surface_material(
        bpy, "Pair", lambda nd, ln: _diffuse(nd)))
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0.0, 0.0, 1.0))
    bpy.context.object.data.materials.append(surface_material(
        bpy, "Pair", lambda nd, ln: _add(nd, ln, _transparent(nd, (0.9, 0.8, 0.5)),
                                 _node(nd, "ShaderNodeBsdfDiffuse", Color=(0.3, 0.3, 0.3)))))
    sun_light(bpy, scene, (math.radians(20.0), 0.0, 0.0)).data.angle = 0.0
    world_color(bpy, scene, None, 0.0)
    looking_down_camera(bpy, scene, 5.0, ortho_scale=4.0)
    ours = _render(bpy, scene, "PHOTONMAP", 4, tmp_path / "ours.exr", 0,
                   photon_mapping=False)
    ref = _render(bpy, scene, "CYCLES", 16, tmp_path / "cycles.exr", 0)
    assert ref.mean() > 0.1
    _check(ours, ref, "floor under the card")


def test_add_with_transparent_exports_the_summed_pass(fresh_scene, bpy_addon):
    """The export's invariants: the pass transmits (1 - alpha) x tint = the Transparent
    BSDFs' summed colour, the surface alpha x closure weight = its summed weight; no
    warning where the alphas are constants. Add of two Transparent BSDFs would pass 2:
    clamped to 1, warned, naming the material."""
    from addon import export
    from addon.core import load_engine
    from blender_helpers import convert_material, looking_down_camera
    bpy = bpy_addon
    looking_down_camera(bpy, fresh_scene, 5.0, ortho_scale=4.0)

    def exported(build):
        return convert_material(surface_material(bpy, "Pair", build))

    m = exported(lambda nd, ln: _add(nd, ln, _transparent(nd), _diffuse(nd)))
    np.testing.assert_allclose((1.0 - m.alpha) * m.transparent_tint, 1.0)
    np.testing.assert_allclose(m.alpha * m.closure_weight, 1.0)
    np.testing.assert_allclose(m.base_color, 0.8)
    m = exported(lambda nd, ln: _add(nd, ln, _principled(nd), _transparent(nd, (0.9, 0.7, 0.4))))
    np.testing.assert_allclose((1.0 - m.alpha) * m.transparent_tint, (0.9, 0.7, 0.4))
    np.testing.assert_allclose(m.alpha * m.closure_weight, 1.0)
    m = exported(lambda nd, ln: _mix(nd, ln, 0.3, _add(nd, ln, _transparent(nd), _diffuse(nd)),
                                     _diffuse(nd)))
    np.testing.assert_allclose((1.0 - m.alpha) * m.transparent_tint, 0.7)
    np.testing.assert_allclose(m.alpha * m.closure_weight, 1.0)
    m = exported(lambda nd, ln: _add(nd, ln, _transparent(nd, (0.5, 0.5, 0.5)),
                                     _transparent(nd, (0.2, 0.4, 0.6))))
    np.testing.assert_allclose((1.0 - m.alpha) * m.transparent_tint, (0.7, 0.9, 1.0))
    bpy.ops.mesh.primitive_plane_add(size=2)
    bpy.context.object.data.materials.append(surface_material(
        bpy, "Pair", lambda nd, ln: _add(nd, ln, _transparent(nd), _transparent(nd))))
    bpy.context.object.data.materials.append(surface_material(
        bpy, "Pair", lambda nd, ln: _add(nd, ln, _transparent(nd), _diffuse(nd))))
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=8)
    warnings = out.all_warnings()  # (the materials' own, from their validation)
    assert any("clamped" in w and "Pair" in w for w in warnings), warnings
    assert not any("averaged" in w for w in warnings), warnings
