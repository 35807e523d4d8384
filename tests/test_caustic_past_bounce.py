"""The caustic estimate at hits past a bounce (issue 14: the metal balls' speckles).

A camera sample's first hit lies within its pixel, as does its image in a mirror or
through glass, so the caustic estimate (a smooth kernel average) is taken for
CAUSTIC_SAMPLES_PER_PIXEL of a pixel's samples and weighted up. Past a rough (glossy)
bounce one pixel's samples land all over the reflected surface, so that stride would only
multiply the estimate's noise (issue 14's gold ball reflecting the glass ball's focus:
relMSE noise 3.0e-2 -> 0.9e-2, docs/accuracy_time_principled_spheres.md, seventh round):
every sample reached through a rough lobe takes its own estimate.

The scene is tests/test_mirror_caustic.py's: a spot light under a perfect mirror lights a
diffuse floor only by the mirror's image (a closed form). Here the camera also looks up
at the mirror, or at a rough mirror in its place, and so sees the floor past one bounce.
"""
import math

import numpy as np
import pytest

from engine import RenderSettings, jit
from engine.api import PaperScene
from engine.integrator import CAUSTIC_SAMPLES_PER_PIXEL
from engine.photonmap import PhotonMap
from engine.scene import Camera, Light, Material
from helpers import pixel_to_world

RHO, R, P = 0.5, 0.9, 1000.0
H, h = 3.0, 1.0          # mirror height, spot height (m)
VIEW, RES = 4.0, 32      # orthographic view (m), pixels
SPP = 2 * CAUSTIC_SAMPLES_PER_PIXEL  # first hits take the estimate at every second sample


def _scene(view_mirror, roughness=0.0):
    s = PaperScene(width=RES, height=RES)
    s.add_material(Material("matte", (RHO,) * 3))
    s.add_material(Material("mirror", (R,) * 3, metallic=1.0, roughness=roughness,
                            node="glossy"))
    s.add_plane((0, 0, 0), (0, 0, 1), 12.0, "matte", name="floor")
    s.add_plane((0, 0, H), (0, 0, -1), 8.0, "mirror", name="mirror")
    s.add_light(Light("spot", "SPOT", P, position=(0, 0, h), direction=(0, 0, 1),
                      spot_size=math.radians(60), spot_blend=0.0))
    # Straight down at the floor, or straight up at the mirror (which shows the floor
    # below the same point: the image is the floor's, mirrored top to bottom).
    rot = np.diag([1.0, -1.0, -1.0]) if view_mirror else np.eye(3)
    s.camera = Camera(position=(0, 0, 0.5), rotation=rot, kind="ORTHO", ortho_scale=VIEW)
    return s


def _render(view_mirror, monkeypatch, roughness=0.0):
    """(film, rows the caustic map was asked for)."""
    jit.ensure_compiled()  # its warm-up asks a small map first
    rows = []
    original = PhotonMap.irradiance

    def counted(self, p, *args, **kwargs):
        rows.append(len(p))
        return original(self, p, *args, **kwargs)

    monkeypatch.setattr(PhotonMap, "irradiance", counted)
    s = _scene(view_mirror, roughness)
    film = s.render(RenderSettings(spp=SPP, photons=0, caustic_photons=100_000,
                                   indirect="off", seed=2, workers=1))
    return film, sum(rows)


def _expected():
    x, y = pixel_to_world(_scene(False), VIEW)
    z_image = 2 * H - h
    d2 = x * x + y * y + z_image * z_image
    return x, y, RHO / math.pi * R * P / (4 * math.pi) * (z_image / np.sqrt(d2)) / d2


@pytest.mark.parametrize("view_mirror, roughness, per_pixel", [
    (False, 0.0, CAUSTIC_SAMPLES_PER_PIXEL), (True, 0.0, CAUSTIC_SAMPLES_PER_PIXEL),
    (True, 0.3, SPP)])
def test_caustic_estimates_per_sample(view_mirror, roughness, per_pixel, monkeypatch):
    """Seen directly or in a perfect mirror, the floor takes a caustic estimate at
    CAUSTIC_SAMPLES_PER_PIXEL of each pixel's samples; seen in a rough mirror, at every
    sample that reaches the floor (the mirrors cover the view; a few rough reflections
    leave sideways or end by Russian roulette: 32,080 of 32,768 here)."""
    film, rows = _render(view_mirror, monkeypatch, roughness)
    if roughness == 0:
        assert rows == RES * RES * per_pixel
    else:
        assert 0.95 * RES * RES * per_pixel <= rows <= RES * RES * per_pixel
    if roughness == 0:
        assert float(film.direct.max()) == 0.0  # no direct light reaches the floor


@pytest.mark.parametrize("view_mirror", [False, True])
def test_floor_in_the_mirror_books_the_caustic(view_mirror, monkeypatch):
    """The mirror's image of the floor is R times the floor's closed form, as the floor
    seen directly is 1 x it (the weights of either sampling of the estimate are right)."""
    film, _ = _render(view_mirror, monkeypatch)
    x, y, expected = _expected()
    img = (film.specular if view_mirror else film.caustic)[..., 1].astype(np.float64)
    inner = x * x + y * y < 1.5 ** 2  # symmetric: the mirrored image's disc is the same
    ratio = img[inner].mean() / expected[inner].mean() / (R if view_mirror else 1.0)
    assert abs(ratio - 1) < 0.02, ratio
