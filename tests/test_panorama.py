"""Panoramic cameras (engine/panorama.py, Cycles' projection.h): each kind's image
coordinates to directions and back, the frame (the camera looks along its -z at the
map's centre, +z up), the lens' outside, clipping along the ray, and whole renders under
a uniform world (every pixel inside the lens sees the world's radiance). The match with
Cycles' images: tools/feature_matrix.py camera_pano_* (tests/blender/test_feature_matrix.py)."""
import math

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.integrator import camera_rays
from engine.panorama import KINDS, Panorama, directions_to_uv, panorama_direction
from engine.scene import Camera, Scene, SceneError

SETTINGS = dict(
    EQUIRECTANGULAR=dict(latitude_min=-1.0, latitude_max=1.2, longitude_min=-2.0,
                         longitude_max=2.5),
    FISHEYE_EQUIDISTANT=dict(fisheye_fov=math.radians(200)),
    FISHEYE_EQUISOLID=dict(fisheye_lens=8.0),
    CENTRAL_CYLINDRICAL=dict(cylindrical_range=(-2.0, 2.2, -0.7, 1.1),
                             cylindrical_radius=1.3),
)


@pytest.mark.parametrize("kind", KINDS)
def test_directions_map_back_to_their_image_coordinates(kind):
    pano = Panorama(kind=kind, **SETTINGS.get(kind, {}))
    p = pano.pack(64, 48, "AUTO")
    rng = np.random.default_rng(3)
    uv = 0.05 + 0.9 * rng.random((400, 2))
    d = np.array([panorama_direction(p, u, v) for u, v in uv])
    inside = np.linalg.norm(d, axis=1) > 0
    assert inside.sum() > 100
    back = directions_to_uv(p, d[inside])
    np.testing.assert_allclose(back, uv[inside], atol=2e-5)


def _pano_camera(kind="EQUIRECTANGULAR", **kw):
    """A panoramic camera looking along +y; kw: Panorama settings (the whole sphere for
    an equirectangular one by default)."""
    return Camera.look_at((0.5, -2.0, 1.0), (0.5, 3.0, 1.0), kind="PANO",
                          panorama=Panorama(kind=kind, **kw))


def test_equirectangular_centre_looks_ahead_and_top_looks_up():
    cam = _pano_camera()
    W, H = 64, 32
    p = cam.panorama.pack(W, H, "AUTO")
    px = np.array([W / 2, W / 2, 0.0, W / 4])
    py = np.array([H / 2, 0.0, H / 2, H / 2])
    o, d, tmax = camera_rays(cam, np.zeros(3), W, H, px, py, np.zeros(4), np.zeros(4))
    forward = -cam.rotation[:, 2]
    up = cam.rotation[:, 1]
    # centre: the look-at direction; the top edge: straight up; the left edge: behind
    assert p[0] == KINDS.index("EQUIRECTANGULAR")
    np.testing.assert_allclose(d[0], forward, atol=1e-9)
    np.testing.assert_allclose(d[1], up, atol=1e-9)
    np.testing.assert_allclose(d[2], -forward, atol=1e-9)
    # a quarter across from the left: the camera's left (phi = pi/2 in the frame)
    np.testing.assert_allclose(d[3], -cam.rotation[:, 0], atol=1e-9)
    assert np.all(tmax == np.inf)


def test_clip_distances_run_along_each_ray():
    cam = _pano_camera()
    cam.clip_start, cam.clip_end = 0.5, 20.0
    rng = np.random.default_rng(1)
    px, py = rng.random(50) * 64, rng.random(50) * 32
    o, d, tmax = camera_rays(cam, np.zeros(3), 64, 32, px, py, np.zeros(50), np.zeros(50))
    np.testing.assert_allclose(np.linalg.norm(o - cam.position, axis=1), 0.5, atol=1e-12)
    np.testing.assert_allclose(tmax, 19.5)


def test_outside_a_fisheye_the_ray_takes_no_light():
    cam = _pano_camera("FISHEYE_EQUIDISTANT", **SETTINGS["FISHEYE_EQUIDISTANT"])
    W, H = 60, 40
    py, px = np.mgrid[0:H, 0:W]
    o, d, tmax = camera_rays(cam, np.zeros(3), W, H, px.ravel() + 0.5, py.ravel() + 0.5,
                             np.zeros(W * H), np.zeros(W * H))
    r = np.hypot((px.ravel() + 0.5) / W - 0.5, (py.ravel() + 0.5) / H - 0.5) * 2
    assert np.all(tmax[r > 1.0 + 1e-9] == 0.0) and np.all(tmax[r < 1.0 - 1e-9] > 0)
    # 200 degrees: the circle's rim looks 100 degrees off the axis
    edge = np.argmin(np.abs(r - 1.0) + (tmax == 0))
    off = math.degrees(math.acos(np.clip(d[edge] @ -cam.rotation[:, 2], -1, 1)))
    assert abs(off - 100.0) < 4.0


@pytest.mark.parametrize("kind", ["EQUIRECTANGULAR", "FISHEYE_EQUISOLID", "MIRRORBALL"])
def test_uniform_world_fills_the_lens_with_its_radiance(kind):
    scene = Scene(camera=_pano_camera(kind), width=48, height=32,
                  background=(0.3, 0.5, 0.7))
    film = render(scene, RenderSettings(spp=4, seed=2, photons=0, caustic_photons=0))
    img = np.asarray(film.combined)[..., :3]
    L = np.array([0.3, 0.5, 0.7])
    # Each pixel: L times the share of its samples inside the lens (its rim's pixels a
    # part), so the image's mean is L times the lens' share of the image.
    share = img / L
    assert np.allclose(share, share[..., :1], atol=1e-6) and share.max() <= 1 + 1e-6
    p = scene.camera.panorama.pack(48, 32, "AUTO")
    g = (np.arange(400) + 0.5) / 400
    inside = np.mean([np.linalg.norm(panorama_direction(p, u, v)) > 0
                      for u in g[::4] for v in g[::4]])
    assert share.mean() == pytest.approx(inside, abs=0.02)
    full = np.isclose(share[..., 0], 1.0)
    assert full.mean() > (0.99 if kind == "EQUIRECTANGULAR" else 0.4)
    if kind != "EQUIRECTANGULAR":
        assert (share[..., 0] == 0).any()  # black outside the lens


def test_camera_validation_names_the_problem():
    cam = Camera(kind="PANO", panorama=dict(kind="FISHEYE_EQUIDISTANT", fisheye_fov=2.0))
    assert isinstance(cam.panorama, Panorama) and cam.panorama.fisheye_fov == 2.0
    assert Camera(kind="PANO").panorama.kind == "EQUIRECTANGULAR"
    assert Camera(kind="PERSP", panorama=Panorama()).panorama is None
    with pytest.raises(SceneError, match="panorama"):
        Camera(kind="PANO", panorama=dict(kind="STEREOGRAPHIC"))
    with pytest.raises(SceneError, match="panorama"):
        Camera(kind="PANO", panorama=dict(fisheye_lens=-1.0))


def test_depth_of_field_rays_meet_at_the_focus_distance():
    # Cycles' camera_sample_panorama: the lens lies across the pixel's direction, every
    # ray of a pixel passes the pinhole ray's point at the focus distance.
    cam = _pano_camera("FISHEYE_EQUISOLID")
    cam.aperture_radius, cam.focus_distance = 0.2, 3.0
    n = 64
    rng = np.random.default_rng(4)
    px, py = np.full(n, 20.3), np.full(n, 11.7)
    o0, d0, _ = camera_rays(cam, np.zeros(3), 48, 32, px, py, np.zeros(n), np.zeros(n))
    o, d, tmax = camera_rays(cam, np.zeros(3), 48, 32, px, py, np.zeros(n), np.zeros(n),
                             lens=(rng.random(n), rng.random(n)))
    focus = cam.position + 3.0 * d0[0]
    t = np.einsum("ij,ij->i", focus - o, d)
    np.testing.assert_allclose(o + t[:, None] * d, np.broadcast_to(focus, o.shape), atol=1e-9)
    spread = np.linalg.norm(o - cam.position, axis=1)
    assert spread.max() <= 0.2 + 1e-12 and spread.max() > 0.05
    np.testing.assert_allclose((o - cam.position) @ d0[0], 0.0, atol=1e-12)  # across it


def test_depth_pass_is_the_distance_to_the_camera():
    # Cycles' camera_z_depth of a panorama: the distance, not the depth along an axis.
    from engine.scene import Material, Mesh
    cam = _pano_camera()
    cx, cy, cz = cam.position
    v = np.array([[cx - 50, cy - 50, cz - 2.0], [cx + 50, cy - 50, cz - 2.0],
                  [cx + 50, cy + 50, cz - 2.0], [cx - 50, cy + 50, cz - 2.0]])
    scene = Scene(camera=cam, width=48, height=24,
                  meshes=[Mesh("floor", v, np.array([[0, 1, 2], [0, 2, 3]]))],
                  materials={"default": Material("default")})
    film = render(scene, RenderSettings(spp=1, seed=2, photons=0, caustic_photons=0,
                                        pixel_filter="box", filter_width=1.0))
    depth = np.asarray(film.depth)
    assert np.isinf(depth[:10]).all()  # the upper half sees no floor
    # The floor 2 m below at distance d is seen asin(2 / d) below the horizon: inside the
    # pixel's row of the equirectangular image (its sample lies somewhere in the pixel),
    # for every column, ahead and behind alike (a depth along the view axis would not).
    rows = np.arange(14, 24)
    lat = -np.degrees(np.arcsin(np.clip(2.0 / depth[rows], -1, 1)))
    row_of = (90.0 - lat) / 180.0 * 24
    assert np.all(row_of >= rows[:, None] - 1e-6) and np.all(row_of <= rows[:, None] + 1 + 1e-6)
