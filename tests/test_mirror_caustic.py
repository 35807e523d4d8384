"""Light that reaches a surface only by way of a mirror (issue 13/14, Figure 7's mirror
floor): the caustic map against the closed form of the light's mirror image.

A spot light at height h points up at a perfect mirror (constant reflectance R, Glossy
node) at height H; a diffuse floor at z = 0 below it sees no direct light, only the spot's
image at height 2H - h pointing down: E = R I cos' / d'^2 with I = P / (4 pi) inside the
cone, d' and cos' measured from the image. Indirect light is off (the floor would see its
own image), so the floor's radiance rho E / pi is the caustic pass alone. The caustic
photons are aimed at the mirror (the default) or shot at the whole scene: both must book
the same power. A 5 % deficit of Figure 7 was once sought here; the caustic pass books
the mirror's light exactly (docs/accuracy_time_figure7_mirror.md).
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.scene import Camera, Light, Material
from helpers import pixel_to_world

RHO, R, P = 0.5, 0.9, 1000.0
H, h = 3.0, 1.0          # mirror height, spot height (m)
VIEW, RES = 4.0, 48      # orthographic view (m), pixels


def _scene():
    s = PaperScene(width=RES, height=RES)
    s.add_material(Material("matte", (RHO,) * 3))
    s.add_material(Material("mirror", (R,) * 3, metallic=1.0, roughness=0.0, node="glossy"))
    s.add_plane((0, 0, 0), (0, 0, 1), 12.0, "matte", name="floor")
    s.add_plane((0, 0, H), (0, 0, -1), 8.0, "mirror", name="mirror")
    s.add_light(Light("spot", "SPOT", P, position=(0, 0, h), direction=(0, 0, 1),
                      spot_size=math.radians(60), spot_blend=0.0))
    # Looking straight down from below the spot: the floor only.
    s.camera = Camera(position=(0, 0, 0.5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=VIEW)
    return s


@pytest.mark.parametrize("aim", [True, False])
def test_floor_lit_by_a_mirror_image_of_the_light(aim):
    s = _scene()
    film = s.render(RenderSettings(spp=4, photons=0, caustic_photons=200_000,
                                   indirect="off", aim_caustics=aim, seed=1))
    x, y = pixel_to_world(s, VIEW)
    z_image = 2 * H - h
    d2 = x * x + y * y + z_image * z_image
    cos = z_image / np.sqrt(d2)
    expected = RHO / math.pi * R * P / (4 * math.pi) * cos / d2
    img = film.combined[..., 1].astype(np.float64)
    assert float(film.direct.max()) == 0.0  # no direct light reaches the floor
    inner = x * x + y * y < 1.5 ** 2          # well inside the cone (radius 2.9 m)
    ratio = img[inner].mean() / expected[inner].mean()
    assert abs(ratio - 1) < 0.02, ratio
    # And across it: the ring 1-1.5 m out as the middle.
    ring = inner & (x * x + y * y > 1.0)
    assert abs(img[ring].mean() / expected[ring].mean() - 1) < 0.03
