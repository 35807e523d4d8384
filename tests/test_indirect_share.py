"""The gather count chosen from the indirect light's share (engine/render.py gather_count,
engine/visualimportance.py indirect_share; docs/accuracy_time_principled_spheres.md,
eighth round).

In a closed furnace whose walls emit Le and reflect rho, the incoming radiance is
Le / (1 - rho) everywhere, of which Le arrives straight from the walls' emission: the
indirect share of the irradiance is rho at every point, whatever the camera sees."""
import hashlib

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, box_mesh
from engine.render import GATHER_SHARE_FULL, gather_count
from engine.scene import Material


def furnace(rho, size=16, **settings):
    s = PaperScene(width=size, height=size)
    s.add_material(Material("glow", (rho,) * 3, emission=(1.0,) * 3))
    v, f = box_mesh((0, 0, 0), 2.0)
    s.add_triangles(v, f, "glow", name="furnace_box")
    s.set_camera((0, -0.5, 0), (0, 1, 0.1), view_angle=90)
    st = dict(photons=40_000, caustic_photons=0, spp=4, seed=1, workers=1)
    st.update(settings)
    return s.render(RenderSettings(**st))


def film_hash(film):
    h = hashlib.sha1()
    for name in ("direct", "indirect", "caustic", "specular", "emission", "alpha"):
        h.update(np.ascontiguousarray(getattr(film, name)).tobytes())
    return h.hexdigest()


def test_gather_count_follows_the_share():
    assert gather_count(2, None) == 2               # not measured: the setting
    assert gather_count(2, float("nan")) == 2
    assert gather_count(2, 0.0) == 1                # never fewer than one
    assert gather_count(2, 0.021) == 1              # issue 14's Principled spheres
    assert gather_count(2, GATHER_SHARE_FULL / 2) == 1
    assert gather_count(2, 0.051) == 2
    assert gather_count(2, 0.18) == 2               # small diffuse rooms
    assert gather_count(2, 0.42) == 2               # Figure 6 / 7 boxes
    assert gather_count(8, 0.025) == 2              # in proportion to the share
    assert gather_count(8, 0.05) == 4
    assert gather_count(8, 1.0) == 8                # never more than the setting
    assert gather_count(1, 0.001) == 1


@pytest.mark.parametrize("rho", [0.03, 0.5])
def test_furnace_share_is_its_albedo(rho):
    film = furnace(rho)
    share = film.stats["indirect_share"]
    assert abs(share - rho) < 0.05 * rho + 0.002, (rho, share)  # measured 0.7-2.2 %
    assert film.stats["gather_rays_used"] == gather_count(2, share)


def test_fewer_rays_are_the_image_of_the_lower_setting():
    """The rule changes only the gather count: a furnace of albedo 0.03 renders bitwise
    as with gather_rays=1 and the rule off, for 1 and 2 workers; at albedo 0.5 bitwise
    as with the rule off (2 rays)."""
    low = furnace(0.03)
    assert low.stats["gather_rays_used"] == 1
    assert film_hash(low) == film_hash(furnace(0.03, gather_rays=1, gather_by_share=False))
    assert film_hash(low) == film_hash(furnace(0.03, workers=2))
    high = furnace(0.5)
    assert high.stats["gather_rays_used"] == 2
    off = furnace(0.5, gather_by_share=False)
    assert "gather_rays_used" not in off.stats
    assert film_hash(high) == film_hash(off)
    assert any("1 of 2 ray(s)" in line for line in low.stats["effects"])
