"""Thin-lens depth of field (issue 14, s26 dof): Cycles' camera_sample_perspective.

A ray through image point x (the pinhole direction (x, y, -1) at depth 1) starts on the
lens at l (radius A) and passes through the pinhole ray's point at the focus depth f, so
at depth z it meets x z + l (1 - z / f): seen through the pinhole image, a point at depth
z spreads over the circle of confusion of radius A |1/z - 1/f| (image plane at depth 1),
and a point on the plane of focus stays a point. An emitting half-plane's edge at depth
z, blurred by a uniform disk of that radius r, has the edge-spread profile

    E(s) = 1/2 + (s sqrt(r^2 - s^2) + r^2 asin(s / r)) / (pi r^2),   |s| <= r,

the disk's area on the lit side of a line at signed distance s from its centre."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.camerarays import aperture_point
from engine.integrator import camera_rays
from engine.scene import Camera, Material, SceneError

W, H = 48, 8
FOV = 20.0
APERTURE = 0.05
FOCUS = 4.0


def _spread(cam, z, n=20000, seed=1):
    """Where n lens rays through the centre of pixel (W/3, H/2) meet depth z, (n, 2)."""
    rng = np.random.default_rng(seed)
    px, py = np.full(n, W // 3), np.full(n, H // 2)
    half = np.full(n, 0.5)
    o, d, _ = camera_rays(cam, np.zeros(3), W, H, px, py, half, half, None, rng.random((2, n)))
    t = (o[:, 2] + z) / -d[:, 2]  # camera at the origin looking along -z
    return (o + t[:, None] * d)[:, :2], o


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_focal_plane_is_sharp_and_off_it_the_circle_of_confusion(kind):
    cam = Camera(position=(0.0, 0.0, 0.0), kind=kind, fov=math.radians(FOV), ortho_scale=2.0,
                 aperture_radius=APERTURE, focus_distance=FOCUS)
    p, o = _spread(cam, FOCUS)
    np.testing.assert_allclose(p, p[:1].repeat(len(p), 0), atol=1e-12)
    # The origins fill the lens (radius APERTURE about the pinhole origin).
    lens = o[:, :2] - (o[:, :2].mean(axis=0) if kind == "ORTHO" else 0.0)
    assert np.linalg.norm(lens, axis=1).max() == pytest.approx(APERTURE, rel=2e-3)
    for z in (1.5, 10.0):
        p, _ = _spread(cam, z)
        c = p.mean(axis=0)
        r = np.linalg.norm(p - c, axis=1)
        # World radius at depth z: A |1 - z / f| (persp: A z |1/z - 1/f|; ortho the same)
        want = APERTURE * abs(1.0 - z / FOCUS)
        assert r.max() == pytest.approx(want, rel=2e-3), (kind, z)
        # Uniform over the disk: mean radius 2/3 of it
        assert r.mean() == pytest.approx(2.0 / 3.0 * want, rel=0.01), (kind, z)


def test_pinhole_is_the_default_and_lens_numbers_change_nothing_there():
    cam = Camera(fov=math.radians(FOV))
    assert not cam.has_dof
    n = 64
    rng = np.random.default_rng(3)
    px, py = rng.integers(0, W, n), rng.integers(0, H, n)
    jx, jy = rng.random((2, n))
    a = camera_rays(cam, np.zeros(3), W, H, px, py, jx, jy)
    b = camera_rays(cam, np.zeros(3), W, H, px, py, jx, jy, None, rng.random((2, n)))
    for x, y in zip(a, b):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("blades,ratio", [(0, 1.0), (0, 2.0), (5, 1.0), (6, 1.5)])
def test_aperture_shape_is_uniform_over_its_area(blades, ratio):
    """Round or polygonal, squeezed by the ratio: the sample's mean is the centre and its
    second moment the shape's (disk: 1/4 per axis; n-gon of unit circumradius:
    (1/12)(1 + 2 cos^2(pi/n)) per axis, x divided by ratio)."""
    rng = np.random.default_rng(5)
    u = rng.random((2, 200000))
    rot = 0.3
    pts = np.array([aperture_point(a, b, blades, rot, 1.0 / ratio) for a, b in u.T])
    np.testing.assert_allclose(pts.mean(axis=0), 0.0, atol=3e-3)
    if blades == 0:
        second = 0.25
        assert np.hypot(pts[:, 0] * ratio, pts[:, 1]).max() <= 1.0 + 1e-12
    else:
        second = (1.0 + 2.0 * math.cos(math.pi / blades) ** 2) / 12.0
        # Inside the polygon whose edge middles lie at rot + k 2 pi / n, apothem cos(pi/n)
        q = pts * [ratio, 1.0]
        ang = rot + 2.0 * math.pi * np.arange(blades) / blades
        proj = q @ np.array([np.cos(ang), np.sin(ang)])
        assert proj.max() <= math.cos(math.pi / blades) + 1e-12
    assert np.mean((pts[:, 0] * ratio) ** 2) == pytest.approx(second, rel=0.01)
    assert np.mean(pts[:, 1] ** 2) == pytest.approx(second, rel=0.01)


def test_bad_lens_settings_are_refused():
    with pytest.raises(SceneError):
        Camera(aperture_radius=-1.0)
    with pytest.raises(SceneError):
        Camera(aperture_radius=0.1, focus_distance=0.0)
    assert Camera(aperture_blades=2).aperture_blades == 0  # < 3: round, as Cycles


def _edge_scene(z, focus, aperture):
    """An emitting half-plane (x > 0, radiance 1) at depth z facing the camera, black
    elsewhere (no world, no light): a vertical edge through the image centre."""
    s = PaperScene(W, H, background=(0.0, 0.0, 0.0))
    lamp = Material("lamp", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0))
    big = 4.0 * z
    v = np.array([[0.0, -big, -z], [big, -big, -z], [big, big, -z], [0.0, big, -z]])
    s.add_triangles(v, np.array([[0, 1, 2], [0, 2, 3]]), lamp, name="lamp")
    s.set_camera((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0), FOV,
                 aperture_radius=aperture, focus_distance=focus)
    return s


def _profile(s, spp=256, workers=1):
    film = s.render(RenderSettings(workers=workers, spp=spp, seed=1, photon_mapping=False,
                                   chunk_size=W * H * spp // 3))
    img = np.asarray(film.emission, np.float64)[..., 0]
    return img.mean(axis=0), img


def _esf(s, r):
    s = np.clip(s / r, -1.0, 1.0)
    return 0.5 + (s * np.sqrt(1.0 - s * s) + np.arcsin(s)) / math.pi


def test_rendered_edge_blurs_by_the_thin_lens_and_stays_sharp_in_focus():
    hw = math.tan(math.radians(FOV) / 2.0)
    px_per_unit = (W / 2.0) / hw
    z, focus, aperture = 2.0, 6.0, 0.15
    r = aperture * abs(1.0 / z - 1.0 / focus) * px_per_unit  # CoC radius in pixels
    assert 4.0 < r < W / 3
    prof, img = _profile(_edge_scene(z, focus, aperture))
    xs = np.arange(W) + 0.5 - W / 2.0
    # Each pixel the ESF averaged over its width (box filter, one pixel)
    sub = (np.arange(16) + 0.5) / 16 - 0.5
    want = _esf(xs[:, None] + sub[None, :], r).mean(axis=1)
    assert np.abs(prof - want).max() < 0.02, np.c_[prof, want]
    # Light is moved, not lost: the sum over the row is the pinhole's
    pin, _ = _profile(_edge_scene(z, focus, 0.0))
    assert prof.sum() == pytest.approx(pin.sum(), rel=0.01)
    # In focus: the pinhole's edge (one pixel wide)
    sharp, _ = _profile(_edge_scene(z, z, aperture))
    assert np.abs(sharp - pin).max() < 0.02
    assert np.count_nonzero((sharp > 0.02) & (sharp < 0.98)) <= 1


def test_same_image_for_any_worker_count():
    s = _edge_scene(2.0, 6.0, 0.15)
    _, a = _profile(s, spp=16, workers=1)
    _, b = _profile(s, spp=16, workers=2)
    assert np.array_equal(a, b)


def test_scene_file_keys(tmp_path):
    """[camera] aperture_radius, focus_distance (default: the look-at point's distance),
    aperture_blades, aperture_rotation (degrees), aperture_ratio; bad values refused."""
    import os

    from engine.scenefile import SceneFileError, load_scene
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    text = open(os.path.join(root, "scenes", "figure6.toml")).read()
    path = tmp_path / "dof.toml"
    path.write_text(text.replace("[camera]\n", "[camera]\naperture_radius = 0.02\n"
                                 "aperture_blades = 6\naperture_rotation = 30\n"
                                 "aperture_ratio = 1.5\n", 1))
    scene, _ = load_scene(str(path))
    cam = scene.camera
    assert cam.has_dof and cam.aperture_radius == 0.02 and cam.aperture_blades == 6
    assert cam.aperture_rotation == pytest.approx(math.radians(30.0))
    assert cam.aperture_ratio == 1.5
    look = -cam.rotation[:, 2]
    # The look-at point's distance (on the view axis: the camera aims at it)
    import tomllib
    c = tomllib.loads(text)["camera"]
    want = float(np.linalg.norm(np.subtract(c["look_at"], c["position"])))
    assert cam.focus_distance == pytest.approx(want)
    assert np.dot(look, np.subtract(c["look_at"], c["position"])) == pytest.approx(want)
    path.write_text(text.replace("[camera]\n", "[camera]\nfocus_distance = 2.5\n", 1))
    scene, _ = load_scene(str(path))
    assert scene.camera.focus_distance == 2.5 and not scene.camera.has_dof
    path.write_text(text.replace("[camera]\n", "[camera]\naperture_radius = -1\n"
                                 "focus_distance = 0\n", 1))
    with pytest.raises(SceneFileError) as e:
        load_scene(str(path))
    text_e = str(e.value)
    assert "aperture_radius" in text_e and "focus_distance" in text_e
