"""A world that camera rays see differently from the rest (Scene.camera_background /
camera_environment: Cycles' Light Path Is Camera Ray in a world Mix Shader): camera rays,
and those passed on through transparent surfaces, see the camera world; the light, the
reflections and everything else see the scene's world."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.lights.environment import Environment
from engine.scene import Material, SceneError

SKY = (1.0, 1.0, 1.0)
SHOWN = (0.1, 0.2, 0.3)


def _scene(card=False, mirror=False, camera_world=True, card_alpha=0.0):
    """A grey floor (2 m) seen from above at an angle, sky in the image's top rows; the
    world SKY lights it. card: a fully transparent card over the image's left half;
    mirror: a mirror tilted to show the sky under the floor's right part."""
    s = PaperScene(width=32, height=24)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 2.0, "grey", name="floor")
    if card:
        s.add_material(Material("card", (0.8, 0.8, 0.8), alpha=card_alpha))
        s.add_plane((-0.6, -1.2, 0.9), (0, 1, 0), 1.2, "card", name="card")
    if mirror:
        s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
        s.add_plane((0.5, -0.3, 0.05), (0, -0.6, 0.8), 0.5, "mirror", name="mirror")
    s.background = SKY
    if camera_world:
        s.camera_background = SHOWN
    s.set_camera((0, -3, 1.2), (0, 0, 0.6), view_angle=50)
    return s


def _settings(**kw):
    return RenderSettings(**{**dict(spp=4, photons=20_000, caustic_photons=0, seed=3), **kw})


def test_the_camera_sees_its_world_and_the_light_is_the_scenes():
    """Sky pixels read SHOWN exactly; the floor, lit by SKY, is bitwise the render
    without a camera world (its light never reads the camera world)."""
    with_cam = _scene().render(_settings())
    without = _scene(camera_world=False).render(_settings())
    img, ref = with_cam.combined, without.combined
    sky = np.all(np.abs(ref - SKY) < 1e-6, axis=2)  # every sample met the sky
    same = np.all(img == ref, axis=2)  # no sample met the sky: the floor's light alone
    assert sky.sum() > 20 and same.sum() > 100
    np.testing.assert_allclose(img[sky], np.broadcast_to(SHOWN, img[sky].shape), rtol=1e-6)
    # elsewhere (edge pixels) each sample's sky traded for SHOWN, darker in every channel
    assert np.all(img <= ref + 1e-7)
    line = next(e for e in with_cam.stats["effects"] if e.startswith("world light"))
    assert "Is Camera Ray" in line
    assert "Is Camera Ray" not in next(e for e in without.stats["effects"]
                                       if e.startswith("world light"))


def test_through_a_transparent_card_the_camera_world_reflections_the_scenes():
    """A camera ray passed on through a transparent card is still a camera ray: the sky
    behind it reads SHOWN; a mirror's reflection of the sky is a reflected ray: SKY."""
    img = _scene(card=True, mirror=True).render(_settings(spp=8)).combined
    ref = _scene(mirror=True, camera_world=False).render(_settings(spp=8)).combined
    card = _scene(card=True, camera_world=False).render(_settings(spp=8)).combined
    sky = np.all(np.abs(ref - SKY) < 1e-6, axis=2)
    # the card covers part of the sky (its diffuse white would show if it were opaque)
    behind = sky & np.all(np.abs(card - SKY) < 1e-6, axis=2)
    assert sky.sum() > 20 and behind.sum() == sky.sum()
    opaque = _scene(card=True, camera_world=False, card_alpha=1.0).render(
        _settings(spp=8)).combined
    covered = sky & ~np.all(np.abs(opaque - SKY) < 1e-6, axis=2)
    assert covered.sum() > 20  # the sky pixels the card stands in front of
    np.testing.assert_allclose(img[sky], np.broadcast_to(SHOWN, img[sky].shape), rtol=1e-6)
    bright = img.mean(axis=2) > 0.85  # the mirror shows SKY (0.9 x 1.0), not SHOWN
    assert bright.sum() > 5


def test_bad_camera_worlds_are_refused_by_name():
    s = _scene()
    s.camera_background = (0.1, -1.0, 0.0)
    with pytest.raises(SceneError, match="camera_background"):
        s.validate()
    s = _scene()
    s.camera_environment = "sky.hdr"
    with pytest.raises(SceneError, match="camera_environment"):
        s.validate()
    s = _scene(camera_world=False)
    s.camera_environment = Environment(np.full((4, 8, 3), 0.25, np.float32))
    film = s.render(_settings(spp=1))
    img = film.combined
    assert np.sum(np.all(np.abs(img - 0.25) < 1e-5, axis=2)) > 20


def test_scene_file_camera_background(tmp_path):
    from engine.scenefile import load_scene
    path = tmp_path / "s.toml"
    path.write_text("background = [1, 1, 1]\ncamera_background = [0.1, 0.2, 0.3]\n"
                    "[camera]\nposition = [0, -3, 1.2]\nlook_at = [0, 0, 0.6]\n")
    scene, _settings_kw = load_scene(str(path))
    np.testing.assert_allclose(scene.camera_background, SHOWN)
    path.write_text("camera_background = [0.1, -1, 0.3]\n[camera]\nposition = [0, -3, 1]\n"
                    "look_at = [0, 0, 0]\n")
    with pytest.raises(Exception, match="camera_background"):
        load_scene(str(path))
