"""The paper's scenes render with the effects they are about."""

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, cornell_box
from engine.scenefile import load_scene
from helpers import ROOT

FAST = dict(photons=40000, caustic_photons=40000, spp=4)


@pytest.fixture(scope="module")
def box_film():
    return cornell_box(96, 72).render(RenderSettings(**FAST))


def test_figure3_scene_file_renders_finite():
    scene, overrides = load_scene(f"{ROOT}/scenes/figure3.toml")
    scene.width, scene.height = 80, 60
    film = scene.render(RenderSettings(photons=20000, caustic_photons=20000, spp=2))
    img = film.combined
    assert img.shape == (60, 80, 3) and np.isfinite(img).all()
    # The red sphere is red: centre pixel dominated by the red channel.
    c = img[25:35, 35:45].mean(axis=(0, 1))
    assert c[0] > 3 * c[1]


def test_figure6_box_is_finite_and_passes_sum_to_combined(box_film):
    f = box_film
    for name, buf in f.passes().items():
        if name != "depth":
            assert np.isfinite(buf).all(), name
    total = f.direct + f.indirect + f.caustic + f.specular + f.emission
    np.testing.assert_allclose(f.combined, total, rtol=1e-6)
    assert f.indirect.mean() > 0.05 * f.direct.mean()


def test_colour_bleeding_from_the_green_wall(box_film):
    """The white floor near the green wall is greener than near the red wall."""
    ind = box_film.indirect
    h, w = ind.shape[:2]
    ceiling = ind[: h // 8]
    left, right = ceiling[:, w // 8: w // 3], ceiling[:, 2 * w // 3: 7 * w // 8]
    ratio_left = left[..., 1].mean() / left[..., 0].mean()
    ratio_right = right[..., 1].mean() / right[..., 0].mean()
    assert ratio_left > 1.3 * ratio_right


def caustic_scene(res=64):
    """Glass ball lit by a point light from the side: a focused caustic on the floor."""
    s = PaperScene(width=res, height=res)
    s.add_plane((0, 0, 0), (0, 0, 1), 6, "white_diffuse", name="floor")
    s.add_sphere((0, 0, 1.0), 0.5, "glass", name="ball")
    s.add_point_light((2, 0, 5), power=800)
    s.set_camera((0, -4, 5), (-0.3, 0, 0), view_angle=40)
    return s


def test_caustic_under_glass_sphere_is_brighter_than_surroundings():
    s = caustic_scene()
    film = s.render(RenderSettings(photons=20000, caustic_photons=100000, spp=4))
    cau = film.caustic
    assert cau.max() > 0
    # Where the caustic map is brightest, the image must beat its neighbourhood ring.
    lum = film.combined.mean(axis=2)
    i, j = np.unravel_index(np.argmax(cau.mean(axis=2)), cau.shape[:2])
    ring = np.concatenate([lum[max(i - 12, 0):i - 6, :].ravel(), lum[i + 6:i + 12, :].ravel()])
    assert lum[i, j] > 2 * np.median(ring)
    # And the caustic is where optics puts it: about (-0.5, 0, 0) on the floor, inside
    # the ball's shadow (light from (2,0,5) through the centre (0,0,1)).
    assert film.direct[i, j].mean() < 0.5 * lum[i, j]


def test_caustics_off_removes_caustic_light():
    s = caustic_scene(32)
    film = s.render(RenderSettings(photons=5000, caustic_photons=5000, spp=1, caustics=False))
    assert film.caustic.max() == 0.0


def test_ray_tracing_only_has_no_indirect_light():
    """Paper Fig. 5b: with photon mapping off the ceiling (lit only indirectly) is black."""
    s = cornell_box(48, 36, glass_sphere=False)
    rt = s.render(RenderSettings(photon_mapping=False, spp=2))
    pm = s.render(RenderSettings(photons=20000, spp=2))
    top = (slice(0, 2), slice(18, 30))  # the ceiling: the downward light cannot reach it
    assert rt.combined[top].max() == 0.0
    assert rt.indirect.max() == 0.0 and rt.caustic.max() == 0.0
    assert pm.combined[top].mean() > 0.01


def test_show_photons_shows_the_photon_hit_view():
    s = cornell_box(48, 36)
    f = s.render(RenderSettings(photons=5000, caustic_photons=2000, spp=1, show_photons=True))
    hits = np.any(f.photon_hits > 0, axis=2)
    assert 0.02 < hits.mean() < 0.9
    np.testing.assert_array_equal(f.combined, f.photon_hits)  # dots on black, no render
