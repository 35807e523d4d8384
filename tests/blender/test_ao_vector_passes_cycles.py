"""Cycles' Ambient Occlusion and Vector passes through the add-on (issue 14, passes41;
engine/aopass.py, engine/vectorpass.py, addon/motionvectors.py) against live Cycles 5.0
on a grey box on a floor under a sun and a grey world, 64 x 48: the box moving 0.1 m a
frame along x (the camera still), then the camera moving (the box still), then the box
growing by a shape key (deformation motion: its vertices' own displacements).

AO (World > Ambient Occlusion > Distance 1.5 m): 8 x 8 pixel blocks within 0.04 of
Cycles' (Cycles 64 spp, ours 32: the noise of both), the image mean within 1.5 %, the
background 0 in both. Vector (pixels a frame: to the previous frame, from the next):
where Cycles' pixel and its 8 neighbours agree within 0.05 px (no edge inside, where the
two renderers' samples fall apart in the pixel filter), ours within 0.05 px; the image
means within 2 % (of the mean size of the channel where it averages out).
"""
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cheap, cycles_plain, read_layers, render_exr

pytestmark = [pytest.mark.blender, pytest.mark.slow]

W, H = 64, 48
AO_DISTANCE = 1.5


def _scene(bpy, move):
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    grey = mb.material("grey", "principled", (0.6, 0.6, 0.6), roughness=1.0)
    mb.plane("Floor", 8, 8, grey)
    box = mb.box("Box", 1.0, 1.0, 1.0, grey, (0.0, 0.0, 0.5), (0, 0, 0))
    mb.set_world((0.2, 0.2, 0.2))
    mb.light("Sun", "SUN", (0, 0, 5), 3.0, look_at=(0.3, 0.2, 0))
    cam = mb.camera((0, -5.5, 2.6), (0, 0.6, 0.2))
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.use_compositing = False
    r.use_motion_blur = False
    vl = scene.view_layers[0]
    vl.use_pass_ambient_occlusion = True
    vl.use_pass_vector = True
    scene.world.light_settings.distance = AO_DISTANCE
    if move == "deform":  # a shape key growing the box 1.3 times about its base centre
        box.shape_key_add(name="Basis")
        key = box.shape_key_add(name="grow")
        for p in key.data:
            p.co = (p.co.x * 1.3, p.co.y * 1.3, (p.co.z + 0.5) * 1.3 - 0.5)
        key.value = 0.0
        key.keyframe_insert("value", frame=0)
        key.value = 1.0
        key.keyframe_insert("value", frame=2)
        moving = box.data.shape_keys
    else:
        moving = box if move == "box" else cam
        start = tuple(moving.location)
        step = (0.1, 0.0, 0.0) if move == "box" else (0.08, 0.05, 0.04)
        for frame in (0, 2):
            moving.location = tuple(s + (frame - 1) * d for s, d in zip(start, step))
            moving.keyframe_insert("location", frame=frame)
    action = moving.animation_data.action
    curves = getattr(action, "fcurves", None)
    if curves is None:  # Blender 5: the action's layered channels
        curves = [c for layer in action.layers for strip in layer.strips
                  for bag in strip.channelbags for c in bag.fcurves]
    for fc in curves:
        for k in fc.keyframe_points:
            k.interpolation = "LINEAR"
    scene.frame_set(1)
    return scene


@pytest.fixture(scope="module", params=["box", "camera", "deform"])
def renders(request, bpy_addon, tmp_path_factory):
    bpy = bpy_addon
    tmp = tmp_path_factory.mktemp("ao_vector")
    scene = _scene(bpy, request.param)
    out = {}
    for engine in ("CYCLES", "PHOTONMAP"):
        scene.render.engine = engine
        if engine == "CYCLES":
            cycles_plain(scene, 64, 4)
        else:
            cheap(scene, spp=32, photons=5_000, caustic_photons=500)
        out[engine] = read_layers(render_exr(bpy, scene, tmp / f"{engine}.exr",
                                             multilayer=True))
    return request.param, out


def _blocks(a, s=8):
    h, w = a.shape[:2]
    return a[:h // s * s, :w // s * s].reshape(h // s, s, w // s, s, -1).mean(axis=(1, 3))


def test_ambient_occlusion_pass_matches_cycles(renders):
    _, out = renders
    cyc, ours = out["CYCLES"]["Ambient Occlusion"], out["PHOTONMAP"]["Ambient Occlusion"]
    assert ours.shape == cyc.shape == (H, W, 3)
    assert np.allclose(ours[..., 0], ours[..., 2])  # grey: no colour of the surfaces
    diff = np.abs(_blocks(ours) - _blocks(cyc))
    assert diff.max() < 0.04, diff[..., 0].round(3)
    assert abs(ours.mean() / cyc.mean() - 1.0) < 0.015, (ours.mean(), cyc.mean())
    sky = slice(0, 6)  # (the top rows: the world above the floor's far edge)
    assert np.all(cyc[sky] == 0.0) and np.all(ours[sky] == 0.0)
    # Somewhere open (1) and somewhere occluded (the box's foot) in both.
    assert cyc.max() == 1.0 and ours.max() > 0.99
    assert (_blocks(cyc)[..., 0] < 0.8).any()


def test_vector_pass_matches_cycles(renders):
    move, out = renders
    cyc, ours = out["CYCLES"]["Vector"], out["PHOTONMAP"]["Vector"]
    assert ours.shape == cyc.shape == (H, W, 4)
    pad = np.pad(cyc, ((1, 1), (1, 1), (0, 0)), mode="edge")
    spread = np.zeros((H, W))
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            spread = np.maximum(spread, np.abs(pad[dy:dy + H, dx:dx + W] - cyc).max(axis=2))
    smooth = spread < 0.05
    assert smooth.mean() > 0.6
    err = np.abs(ours - cyc).max(axis=2)
    assert np.all(err[smooth] < 0.05), (err[smooth].max(), move)
    moving = np.abs(cyc).max(axis=2) > 0.5
    assert moving.sum() > (0.5 * H * W if move == "camera" else 20)
    for c in range(4):
        m_c, m_o = cyc[..., c].mean(), ours[..., c].mean()
        scale = max(abs(m_c), float(np.abs(cyc[..., c]).mean()))  # (a symmetric motion: 0)
        assert abs(m_o - m_c) <= 0.02 * scale + 1e-4, (c, m_o, m_c)


def test_vector_with_motion_blur_is_warned(bpy_addon, tmp_path):
    """Cycles makes the Vector pass with motion blur off only: with it on, the pass is
    named in the one 'does not make' warning and left as Blender fills it; AO is made
    either way."""
    import addon
    bpy = bpy_addon
    scene = _scene(bpy, "box")
    scene.render.engine = "PHOTONMAP"
    cheap(scene, width=16, height=12, spp=1, photons=2_000, caustic_photons=200)
    scene.render.use_motion_blur = True
    scene.photonmap.motion_blur_steps = 2
    seen = []
    listener = (lambda event, value: seen.append(value) if event == "warning" else None)
    addon.engine.status_listeners.append(listener)
    try:
        out = read_layers(render_exr(bpy, scene, tmp_path / "mb.exr", multilayer=True))
    finally:
        addon.engine.status_listeners.remove(listener)
        scene.render.use_motion_blur = False
    unmade = [w for w in seen if "does not make" in w]
    assert len(unmade) == 1 and addon.engine.VECTOR_WITH_BLUR in unmade[0], seen
    assert "Ambient Occlusion" not in unmade[0]
    assert np.all(out["Vector"] == out["Vector"].flat[0])  # (as Blender fills it: 10000)
    assert out["Ambient Occlusion"].max() > 0.9
