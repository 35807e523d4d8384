"""Motion blur by shutter time steps (engine/motionblur.py): the shutter's times, the slices'
settings, and renders whose time-averaged image is known exactly."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.api import PaperScene
from engine.motionblur import (AUTO_MAX_STEPS, K_MIN, auto_steps, frame_and_subframe,
                               image_motion, pose_signature, render_motion_blur,
                               shutter_span, shutter_times, step_settings)
from engine.scene import Material


def test_shutter_times_are_the_slices_middles_where_blender_opens_the_shutter():
    # Blender's Position: CENTER (Cycles' default) puts the frame in the shutter's middle.
    np.testing.assert_allclose(shutter_times(10, 0.5, "CENTER", 4),
                               [9.8125, 9.9375, 10.0625, 10.1875])
    np.testing.assert_allclose(shutter_times(10, 0.5, "START", 2), [10.125, 10.375])
    np.testing.assert_allclose(shutter_times(10, 1.0, "END", 1), [9.5])
    for bad in (dict(position="MIDDLE"), dict(steps=0), dict(steps=2.5), dict(shutter=0.0),
                dict(shutter=float("nan"))):
        args = dict(frame=1, shutter=0.5, position="CENTER", steps=4) | bad
        with pytest.raises(ValueError):
            shutter_times(**args)


def test_frame_and_subframe_split_a_time_as_blender_frame_set_takes_it():
    assert frame_and_subframe(9.8125) == (9, 0.8125)
    assert frame_and_subframe(-0.25) == (-1, 0.75)
    assert frame_and_subframe(3.0) == (3, 0.0)


def test_slices_share_the_samples_and_keep_the_stills_search_reach():
    s = RenderSettings(spp=100, photons=400_000, caustic_photons=200_000, k_nearest=64,
                       seed=3, adaptive_threshold=0.01)
    a, b = step_settings(s, 0, 8), step_settings(s, 1, 8)
    assert a.spp == 13 and a.k_nearest == 8  # ceil(100 / 8); 64 / 8
    # k and the photons cut by one factor: the k-NN radius of the still's.
    assert a.photons / s.photons == pytest.approx(a.k_nearest / s.k_nearest)
    assert a.caustic_photons == 25_000 and a.adaptive_threshold == 0.0
    assert a.seed != b.seed and a.seed != s.seed
    # Past k / steps < K_MIN the neighbours stop at K_MIN (and the photons with them).
    c = step_settings(s, 0, 32)
    assert c.k_nearest == K_MIN and c.photons == 50_000
    assert step_settings(s, 0, 1).photons == s.photons


def _glow_scene(x_center, width=80, height=40, side=0.4):
    """An orthographic camera over an emissive plane of radiance 1 (x in [-1, 1], y in
    [-0.5, 0.5] in view) and a black square of `side` centred at (x_center, 0) over it."""
    s = PaperScene(width, height, background=(0.0, 0.0, 0.0))
    s.add_material(Material("black", (0.0, 0.0, 0.0), roughness=1.0, specular=0.0))
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "glow", name="glow")
    s.add_plane((x_center, 0, 0.3), (0, 0, 1), side, "black", name="square")
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=2.0)
    return s


def test_a_moving_square_blurs_into_the_shutters_trapezoid():
    """A black square (side a = 0.4) moving along x at 1 m a frame, shutter 0.5 frames
    centred on the frame: each point of the plane is hidden for the share of the shutter
    the square covers it, a trapezoid 0.8 deep from |x| = 0.05 out to 0 at 0.45. 16 time
    steps: within 1 / 16 (the steps) + the pixel filter of it, the square's darkness summed
    over the image exactly its area, the still's edge sharp."""
    a, speed, shutter, steps = 0.4, 1.0, 0.5, 16
    times = shutter_times(1.0, shutter, "CENTER", steps)
    settings = RenderSettings(spp=16, workers=1, seed=1, photon_mapping=False)
    film = render_motion_blur(lambda t: _glow_scene(speed * (t - 1.0), side=a), times,
                              settings)
    assert film.stats["motion_blur_steps"] == steps
    img = np.asarray(film.combined, np.float64)[..., 0]
    assert np.isfinite(img).all()
    x = (np.arange(80) + 0.5) / 80 * 2.0 - 1.0
    band = img[14:26].mean(0)  # rows well inside the square's y extent (|y| < 0.15)
    D = speed * shutter
    lo, hi = np.maximum(x - a / 2, -D / 2), np.minimum(x + a / 2, D / 2)
    covered = np.clip(hi - lo, 0.0, None) / D
    assert np.abs(band - (1.0 - covered)).max() < 1.0 / steps + 0.03, \
        np.round(np.c_[x, band, 1 - covered][::4], 3)
    # The darkness of the whole image: the square's area in every slice.
    pix = (2.0 / 80) ** 2
    assert (1.0 - img).sum() * pix == pytest.approx(a * a, rel=0.02)
    still = render(_glow_scene(0.0, side=a), settings)
    row = np.asarray(still.combined, np.float64)[..., 0][14:26].mean(0)
    assert row[(np.abs(x) < 0.18)].max() < 0.01 and row[np.abs(x) > 0.22].min() > 0.99


def test_nothing_moving_renders_the_still_once():
    calls = []

    def scene_at(t):
        calls.append(t)
        return _glow_scene(0.2, width=32, height=16)

    settings = RenderSettings(spp=4, workers=1, seed=2, photon_mapping=False)
    film = render_motion_blur(scene_at, shutter_times(1, 0.5, "CENTER", 8), settings)
    assert len(calls) == 2  # the shutter's first and last time, compared
    assert film.stats["motion_blur_steps"] == 1 and film.stats["motion_blur_still"]
    assert any(e.startswith("motion blur: off") for e in film.stats["effects"])
    still = render(_glow_scene(0.2, width=32, height=16), settings)
    np.testing.assert_array_equal(film.combined, still.combined)


def test_pose_signature_sees_a_moved_camera_and_light():
    a, b = _glow_scene(0.0), _glow_scene(0.0)
    assert pose_signature(a) == pose_signature(b)
    b.set_camera((0, 0.1, 2.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=2.0)
    assert pose_signature(a) != pose_signature(b)
    c = _glow_scene(0.0)
    c.add_light(_point_light((0, 0, 1)))
    d = _glow_scene(0.0)
    d.add_light(_point_light((0, 0.5, 1)))
    assert pose_signature(c) != pose_signature(d)


def _point_light(position):
    from engine.scene import Light
    return Light(kind="POINT", position=position, power=10.0)


def test_a_cancel_keeps_the_steps_done():
    n = {"asked": 0}

    def should_cancel():
        n["asked"] += 1
        return n["asked"] > 40  # well into the render, after a step or more

    settings = RenderSettings(spp=8, workers=1, seed=1, photon_mapping=False)
    film = render_motion_blur(lambda t: _glow_scene(t - 1.0, width=32, height=16),
                              shutter_times(1, 0.5, "CENTER", 8), settings,
                              should_cancel=should_cancel)
    assert film.stats["cancelled"]
    assert 1 <= film.stats["motion_blur_steps"] < 8
    assert np.isfinite(np.asarray(film.combined)).all()


def test_a_cancelled_export_keeps_the_steps_done():
    """scene_at raising parallel.Cancelled (the add-on's export, cancelled): after the
    first step the steps done make the film; on the first scene it propagates."""
    from engine.parallel import Cancelled
    asked = []

    def scene_at(t):
        asked.append(t)
        if len(asked) > 3:  # the first, the last (compared), the second: then Esc
            raise Cancelled("export cancelled")
        return _glow_scene(t - 1.0, width=32, height=16)

    settings = RenderSettings(spp=8, workers=1, seed=1, photon_mapping=False)
    film = render_motion_blur(scene_at, shutter_times(1, 0.5, "CENTER", 8), settings)
    assert film.stats["cancelled"] and film.stats["motion_blur_steps"] == 2

    def refuse(t):
        raise Cancelled("export cancelled")

    with pytest.raises(Cancelled):
        render_motion_blur(refuse, [1.0, 1.1], settings)


def test_one_step_says_so_and_renders_the_shutters_middle():
    """Steps 1 (newuser38: read "nothing moves" where things did): one render at the
    shutter's middle, the report says Steps is 1."""
    asked = []

    def scene_at(t):
        asked.append(t)
        return _glow_scene(t - 1.0, width=32, height=16)

    settings = RenderSettings(spp=4, workers=1, seed=2, photon_mapping=False)
    film = render_motion_blur(scene_at, shutter_times(1, 0.5, "CENTER", 1), settings)
    assert asked == [1.0]
    assert film.stats["motion_blur_steps"] == 1 and not film.stats["motion_blur_still"]
    line = [e for e in film.stats["effects"] if e.startswith("motion blur")]
    assert len(line) == 1 and "Steps is 1" in line[0], line


def test_auto_steps_follow_the_fastest_vertex_in_pixels():
    """The square moving 1 m a frame under an orthographic camera of 2 m across 80
    pixels (40 pixels a metre): over a 0.5-frame shutter it moves 20 pixels, 7 steps of
    at most 3 pixels; a camera moving with it sees no motion; a spinning square's path is the
    sum over the shutter's halves."""
    a, b = _glow_scene(-0.25), _glow_scene(0.25)
    assert image_motion(a, b) == pytest.approx(20.0, rel=1e-6)
    opens, closes = shutter_span(1.0, 0.5, "CENTER")
    assert (opens, closes) == (0.75, 1.25)
    steps, path = auto_steps(lambda t: _glow_scene(t - 1.0), opens, closes)
    assert steps == 7 and path == pytest.approx(20.0, rel=1e-6)

    def riding(t):
        s = _glow_scene(t - 1.0)
        s.set_camera((t - 1.0, 0, 2.0), (t - 1.0, 0, 0), up=(0, 1, 0), kind="ORTHO",
                     ortho_scale=2.0)
        return s

    # (the glowing plane moves in the image then: the square's own motion is 0, the
    # plane's 20 pixels)
    assert auto_steps(riding, opens, closes)[1] == pytest.approx(20.0, rel=1e-6)
    assert auto_steps(lambda t: _glow_scene(0.0), opens, closes) == (2, 0.0)
    fast = auto_steps(lambda t: _glow_scene(100.0 * (t - 1.0)), opens, closes)
    assert fast[0] == AUTO_MAX_STEPS
