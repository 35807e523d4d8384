"""Next-event estimation with MIS on rough lobes under a spot light with a radius (issue 14
names "area, spot, point and mesh lights and the world"; tests/test_glossy_light_sampling.py
covers the others). A rough metal / dielectric floor under a spot of radius 0.3 m whose
cone (and its blend ring) covers the floor the camera sees: light sampling weighted by the
power heuristic against the lobes' own sampling must give the continuation's mean (both
unbiased) with far less noise, and a spot without a radius (a delta light, seen by
shadow rays only) must light the highlight without sampling noise."""

import numpy as np
import pytest

from engine.api import PaperScene
from engine.scene import Material
from engine.settings import RenderSettings
from helpers import assert_mis_matches_continuation

MATERIALS = {
    "metal": Material("metal", (0.9, 0.7, 0.5), metallic=1.0, roughness=0.35),
    "dielectric": Material("dielectric", (0.3, 0.3, 0.3), specular=1.0, roughness=0.3),
}


def _scene(material, radius, blend=0.3):
    # The camera and light of test_glossy_light_sampling's floor, the light a spot aimed
    # at the floor's mirror point of the camera (so the highlight is in view).
    s = PaperScene(width=24, height=24)
    s.add_material(material)
    s.add_plane((0, 0, 0), (0, 0, 1), 12.0, material.name, name="floor")
    s.add_spot_light((1.0, 0.0, 1.5), look_at=(0.2, 0.0, 0.0), power=300.0,
                     spot_size_degrees=100.0, blend=blend, radius=radius)
    s.set_camera((-2.5, 0.0, 2.0), (0.3, 0.0, 0.0), up=(0, 0, 1), view_angle=40.0)
    return s


def _render(scene, spp, seed):
    film = scene.render(RenderSettings(spp=spp, photon_mapping=False, seed=seed, workers=1))
    return film.combined.astype(np.float64)


@pytest.mark.parametrize("mat", sorted(MATERIALS))
def test_spot_with_radius_mis_matches_continuation_with_less_noise(mat, request):
    scene = _scene(MATERIALS[mat], radius=0.3)
    mis, mis2 = _render(scene, 64, 1), _render(scene, 64, 2)
    request.getfixturevalue("continuation_only")
    cont, cont2 = _render(scene, 64, 1), _render(scene, 64, 2)
    assert_mis_matches_continuation(mis, mis2, cont, cont2, 0.4)


def test_spot_without_radius_is_seen_by_shadow_rays_only():
    """A delta spot: no sampled direction can meet it, so the highlight is shadow rays'
    alone and another seed moves only the pixel jitter."""
    scene = _scene(MATERIALS["metal"], radius=0.0)
    a, b = _render(scene, 4, 1), _render(scene, 4, 2)
    assert a.mean() > 0.05
    assert abs(a.mean() - b.mean()) < 0.01 * a.mean()
