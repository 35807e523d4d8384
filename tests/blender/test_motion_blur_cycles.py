"""Render > Motion Blur against live Cycles (engine/motionblur.py, addon/engine.py
_render_motion_blur): the scene exported at time steps over the shutter (RenderEngine
.frame_set), each rendered whole, averaged.

A red ball (r 0.5) moving 3 m in x over two frames (linear keys), rendered at frame 1
with Shutter 0.5 centred on it (it sweeps 0.75 m while the shutter is open), a sun, a grey
floor, 96 x 48. Measured: the brightness profile across the streak (8 rows through the
ball) within 0.014 of Cycles 256 spp at every column (mean 0.003), the whole image 1.007;
the camera panning past a still ball the same way.

Cycles' side (its column profiles across the streak and the image means; 256 and 128 spp,
seed 0: the same numbers every run) is stored in tests/references/motion_blur_cycles.json
(this file run as a script writes it); the slow test_stored_motion_blur_profiles_are_cycles_now
renders it again live."""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import (ROOT, assert_stored_means_are_now, cycles_plain,
                             render_luminance, render_exr, stored_cycles_means, sun_light,
                             world_color)

sys.path.insert(0, os.path.join(ROOT, "example_blends"))
import make_blends as mb  # noqa: E402
from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402

pytestmark = pytest.mark.blender
REF_PATH = os.path.join(ROOT, "tests", "references", "motion_blur_cycles.json")
BAND = slice(20, 28)  # 8 rows through the ball (96 x 48)


def _material(bpy, name, rgb):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    m.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*rgb, 1.0)
    return m


def _scene(bpy, move="ball"):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 96, 48, 100
    floor = bpy.data.meshes.new("Floor")
    floor.from_pydata([(-10, -10, 0), (10, -10, 0), (10, 10, 0), (-10, 10, 0)], [],
                      [(0, 1, 2, 3)])
    floor.materials.append(_material(bpy, "Grey", (0.5, 0.5, 0.5)))
    sc.collection.objects.link(bpy.data.objects.new("Floor", floor))
    primitive_uv_sphere_add(radius=0.5, location=(0, 0, 0.5))
    ball = bpy.context.active_object
    ball.name = "Ball"
    ball.data.materials.append(_material(bpy, "Red", (0.8, 0.1, 0.05)))
    bpy.ops.object.shade_smooth()
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.rotation_euler = (math.radians(75), 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    cam.location = (0, -6, 2.0)
    mover, axis_from, axis_to = ((ball, (-1.5, 0, 0.5), (1.5, 0, 0.5)) if move == "ball"
                                 else (cam, (-1.5, -6, 2.0), (1.5, -6, 2.0)))
    mover.location = axis_from
    mover.keyframe_insert("location", frame=0)
    mover.location = axis_to
    mover.keyframe_insert("location", frame=2)
    mb.linear_keys(mover)
    sc.frame_set(1)
    sun_light(bpy, sc, (math.radians(30), math.radians(20), 0), energy=3.0)
    world_color(bpy, sc, (0.1, 0.1, 0.1))
    sc.render.use_motion_blur = True
    sc.render.motion_blur_shutter = 0.5
    return sc


@pytest.mark.parametrize("move", ["ball", pytest.param("camera", marks=pytest.mark.slow)])
def test_a_moving_ball_streaks_as_in_cycles(bpy_addon, tmp_path, move):
    bpy = bpy_addon
    sc = _scene(bpy, move)
    cycles_plain(sc, 256, 12)  # the add-on reads its Light Paths
    stored = stored_cycles_means(REF_PATH)[move]
    pc, ref_mean = stored[:-1], stored[-1]  # the band's column profile, the image's mean
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = 32
    sc.photonmap.motion_blur_steps = 8
    from addon import engine
    ours = render_luminance(bpy, sc, tmp_path / "ours.exr")
    st = engine.last_render["stats"]
    assert st["motion_blur_steps"] == 8
    np.testing.assert_allclose(st["motion_blur_times"], 0.75 + 0.5 * (np.arange(8) + 0.5) / 8)
    assert sc.frame_current == 1 and sc.frame_subframe == 0.0  # the frame restored
    assert not [w for w in engine.last_render["warnings"] if "motion" in w]
    assert np.isfinite(ours).all()
    po = ours[BAND].mean(0)
    assert np.abs(po - pc).max() < 0.03, np.round(np.c_[po, pc][::4], 3)
    assert 0.98 < ours.mean() / ref_mean < 1.02
    # The streak is there: the still's ball is sharp, darker in its middle columns.
    sc.render.use_motion_blur = False
    still = render_luminance(bpy, sc, tmp_path / "still.exr")[BAND].mean(0)
    assert np.abs(still - pc).max() > 0.08


def test_motion_blur_says_what_it_does_not_follow(bpy_addon, tmp_path):
    """Nothing moving: one render, said in the effect report; a Rolling Shutter and
    Progressive are named in warnings."""
    bpy = bpy_addon
    sc = _scene(bpy)
    bpy.data.objects["Ball"].animation_data_clear()
    sc.render.engine = "PHOTONMAP"
    sc.render.resolution_x, sc.render.resolution_y = 24, 12
    sc.photonmap.spp = 2
    sc.photonmap.photons = sc.photonmap.caustic_photons = 20_000
    sc.cycles.rolling_shutter_type = "TOP"
    from addon import engine
    render_exr(bpy, sc, str(tmp_path / "still.exr"))
    st = engine.last_render["stats"]
    assert st["motion_blur_steps"] == 1
    assert any(e.startswith("motion blur: off") for e in st["effects"])
    assert [w for w in engine.last_render["warnings"] if "Rolling Shutter" in w]
    sc.photonmap.progressive = True
    sc.photonmap.max_passes = 1
    render_exr(bpy, sc, str(tmp_path / "progressive.exr"))
    assert [w for w in engine.last_render["warnings"]
            if w.startswith("motion blur is not rendered with progressive")]


@pytest.mark.parametrize("after", [1, 60])
def test_a_cancel_during_motion_blur_restores_the_frame(bpy_addon, tmp_path, after):
    """Esc during the time steps (the first poll: during the first export; later: a few
    steps in): the render ends cancelled, nothing raised, the frame restored."""
    bpy = bpy_addon
    sc = _scene(bpy)
    sc.render.engine = "PHOTONMAP"
    sc.render.resolution_x, sc.render.resolution_y = 24, 12
    sc.photonmap.spp = 8
    sc.photonmap.photons = sc.photonmap.caustic_photons = 20_000
    sc.photonmap.motion_blur_steps = 8
    from addon import engine
    polls = {"n": 0}

    def hook():
        polls["n"] += 1
        return polls["n"] > after

    engine.test_break_hook = hook
    try:
        render_exr(bpy, sc, str(tmp_path / "cancelled.exr"))
    finally:
        engine.test_break_hook = None
    assert engine.last_render.get("cancelled"), engine.last_render.get("error")
    assert not engine.last_render.get("error")
    assert sc.frame_current == 1 and sc.frame_subframe == 0.0


def test_an_object_with_its_motion_blur_off_stays_at_the_frame(bpy_addon, tmp_path):
    """Object > Motion Blur off on the moving ball (Cycles' per-object use_motion_blur):
    both engines render it sharp at the frame's position; nothing else moves, so ours
    renders once."""
    bpy = bpy_addon
    sc = _ball_blur_off(bpy)
    cycles_plain(sc, 128, 12)  # the add-on reads its Light Paths
    pc = stored_cycles_means(REF_PATH)["ball's motion blur off"]  # rows 10:14's profile
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = 16
    from addon import engine
    ours = render_luminance(bpy, sc, tmp_path / "ours.exr")
    assert engine.last_render["stats"]["motion_blur_steps"] == 1
    po = ours[10:14].mean(0)
    assert np.abs(po - pc).max() < 0.04, np.round(np.c_[po, pc], 3)


def _ball_blur_off(bpy):
    """_scene at 48 x 24 with the moving ball's Object > Motion Blur off."""
    sc = _scene(bpy)
    bpy.data.objects["Ball"].cycles.use_motion_blur = False
    sc.render.resolution_x, sc.render.resolution_y = 48, 24
    return sc


def _cycles_profiles(bpy, tmp_path):
    """Cycles' side, rendered now: per moving object the band's column profile (96) and
    the image's mean after it; the still ball's rows 10:14 profile (48)."""
    out = {}
    for move in ("ball", "camera"):
        sc = _scene(bpy, move)
        sc.render.engine = "CYCLES"
        cycles_plain(sc, 256, 12)
        ref = render_luminance(bpy, sc, tmp_path / f"cycles_{move}.exr")
        out[move] = [*ref[BAND].mean(0).tolist(), float(ref.mean())]
    sc = _ball_blur_off(bpy)
    sc.render.engine = "CYCLES"
    cycles_plain(sc, 128, 12)
    out["ball's motion blur off"] = render_luminance(
        bpy, sc, tmp_path / "cycles_off.exr")[10:14].mean(0).tolist()
    return out


@pytest.mark.slow
def test_stored_motion_blur_profiles_are_cycles_now(bpy_addon, tmp_path):
    """The stored profiles are what this Blender's Cycles renders (3 renders)."""
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_profiles(bpy_addon, tmp_path))


def test_auto_steps_follow_the_streaks_length(bpy_addon, tmp_path):
    """Steps 0 (Auto, the default): the ball sweeps 0.75 m at ~6 m, ~16 pixels of the
    96-pixel image (39.6 degrees across): about 6 steps of 3 pixels; the report says so.
    Twice as wide an image: about twice the steps."""
    bpy = bpy_addon
    sc = _scene(bpy)
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = 4
    sc.photonmap.photons = sc.photonmap.caustic_photons = 20_000
    assert sc.photonmap.motion_blur_steps == 0
    from addon import engine
    render_exr(bpy, sc, str(tmp_path / "auto.exr"))
    st = engine.last_render["stats"]
    line = [e for e in st["effects"] if e.startswith("motion blur: on")]
    assert 4 <= st["motion_blur_steps"] <= 10, st["motion_blur_steps"]
    assert len(line) == 1 and "Steps Auto" in line[0], line
    n = st["motion_blur_steps"]
    sc.render.resolution_x, sc.render.resolution_y = 192, 96
    render_exr(bpy, sc, str(tmp_path / "auto2.exr"))
    assert 1.7 * n <= engine.last_render["stats"]["motion_blur_steps"] <= 2.3 * n + 1
    assert sc.frame_current == 1 and sc.frame_subframe == 0.0


if __name__ == "__main__":  # write the stored profiles: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_profiles, cycles_samples=[256, 128], seed=0)
