"""Light Paths > Max Bounces > Transparent along the whole path, against live Cycles
(issue 14, transparent48; tests/test_transparent_path_limit.py has the analytic cases).

Eight cards stacked as a staircase over a sunlit floor, seen from straight above: pixel
column j looks through the j + 1 top cards. Each card is a Mix Shader of a Transparent
BSDF (0.8) and a grey Diffuse BSDF (0.2). At Transparent 4 Cycles (path_state.h,
path_state_next; shade_surface.h) ends a camera path at the surface after its 4th pass
and lets a hit reached through k passes cast shadow rays through 4 - k more: the floor is
lit only beside 1-2 cards, card i (from the top) is shaded for i < 4 and lit for 2 i <= 4.
Before transparent48 ours crossed every card and gave each shadow ray all 4: columns
with 3-8 cards read 1.21-2.03x Cycles. Max Bounces 0 in both (direct light only: the
passes are no bounces). 8 x 8, Cycles 256 spp, ours 64 (a few seconds each).
"""
import math

import numpy as np
import pytest

from blender_helpers import (cycles_plain, default_cycles, default_photonmap, node_material,
                             read_rgba, render_exr, sun_light, black_world,
                             looking_down_camera)

pytestmark = pytest.mark.blender

T, CARDS, SUN, ALBEDO, PASS, GREY = 4, 8, 3.0, 0.8, 0.8, 0.5


def expected_columns(transparent=T):
    """(CARDS,) the radiance Cycles' rule gives column j (j + 1 cards over the floor)."""
    out = []
    for j in range(CARDS):
        k = j + 1
        L = 0.0
        for i in range(min(k, transparent)):  # card i, reached through i passes
            if 2 * i <= transparent:
                L += PASS ** (2 * i) * (1 - PASS) * GREY / math.pi * SUN
        if k < transparent and 2 * k <= transparent:  # the floor, through k passes
            L += PASS ** (2 * k) * ALBEDO / math.pi * SUN
        out.append(L)
    return np.array(out)


def _scene(bpy, scene):
    black_world(bpy, scene)
    floor, nt, out = node_material(bpy, "Floor")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1.0)
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    card, nt, out = node_material(bpy, "Card")
    tr = nt.nodes.new("ShaderNodeBsdfTransparent")
    df = nt.nodes.new("ShaderNodeBsdfDiffuse")
    df.inputs["Color"].default_value = (GREY, GREY, GREY, 1.0)
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 1.0 - PASS
    nt.links.new(tr.outputs[0], mix.inputs[1])
    nt.links.new(df.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=20.0)
    bpy.context.object.data.materials.append(floor)
    for i in range(CARDS):
        # Card i spans x from -1 + 0.25 i to 3: the columns right of its left edge.
        x0 = -1.0 + 0.25 * i
        bpy.ops.mesh.primitive_plane_add(size=1.0, location=((x0 + 3.0) / 2, 0.0,
                                                              1.0 + 0.1 * (CARDS - i)))
        ob = bpy.context.object
        ob.scale = (3.0 - x0, 4.0, 1.0)
        ob.data.materials.append(card)
    sun_light(bpy, scene, (0.0, 0.0, 0.0), energy=SUN)
    looking_down_camera(bpy, scene, 5.0, ortho_scale=2.0)
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100


def _columns(bpy, scene, path, engine):
    scene.render.engine = engine
    img = read_rgba(bpy, render_exr(bpy, scene, path))[..., :3]
    return img.mean(axis=(0, 2))


def test_stacked_cards_match_cycles_at_transparent_4(fresh_scene, bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene)
    c = default_cycles(scene)
    cycles_plain(scene, 256, 0)
    c.transparent_max_bounces = T
    # Samples near the pixels' centres (both engines): the columns do not blur together.
    c.pixel_filter_type, c.filter_width = "GAUSSIAN", 0.01
    pm = default_photonmap(scene)
    pm.spp, pm.photon_mapping = 64, False
    cyc = _columns(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    ours = _columns(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    want = expected_columns()
    # Cycles follows the rule (its noise: ~3 % a column at 256 spp)...
    np.testing.assert_allclose(cyc, want, rtol=0.06)
    # ... and so do we.
    np.testing.assert_allclose(ours, cyc, rtol=0.06)
