"""Caustic photons of an area light aimed only where its one-sided emission goes
(engine/lights/area.py area_aim_weights, area_aim_direction; issue 14): a sphere wholly
behind the light is never aimed at, a light inside a sphere (a mirror or a room's bounding
sphere round it) emits its natural directions; the power the aimed photons carry into each
sphere equals what natural emission sends there. Solid-angle aiming stored 43 % of the
aimed photons with a sphere behind the light and 50 % from inside a sphere."""
import math

import numpy as np
import pytest

from engine.lights.area import area_aim_weights
from engine.scene import Light
from test_photon_emission import _light
from test_spot_aim import _emit, _power_into_sphere


def _area(spread=None, disk=False):
    kw = {} if spread is None else dict(spread=spread)
    if disk:
        kw["shape"] = "DISK"
    return _light(Light("a", "AREA", 100.0, position=(0, 0, 3), direction=(0, 0, -1),
                        size_x=1.0, size_y=0.5, **kw))


# Spheres relative to the light's centre (the prepared light is re-centred); it emits
# down -Z. (spheres, least share of the aimed photons that carry power)
CASES = {
    "front only": (_area, [((0.3, 0.1, -1.8), 0.4)], 0.99),
    "front and behind": (_area, [((0.3, 0.1, -1.8), 0.4), ((0.0, 0.5, 1.5), 0.4)], 0.99),
    "front and level beside": (_area, [((0.3, 0.1, -1.8), 0.4), ((2.5, 0.0, 0.0), 0.5)], 0.95),
    "inside a sphere": (_area, [((0.0, 0.0, -1.0), 4.0)], 0.99),
    "inside one, another below": (_area, [((0.0, 0.0, -1.0), 4.0), ((0.5, 0.0, -2.5), 0.3)],
                                  0.99),
    "spread 60 deg, disk": (lambda: _area(spread=math.radians(60), disk=True),
                            [((0.3, 0.1, -1.8), 0.4), ((0.6, 0.0, -1.8), 0.4),
                             ((0.0, 0.0, -1.0), 4.0)], 0.9),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_aimed_area_photons_carry_the_natural_power_into_each_sphere(case):
    make, spheres, stored = CASES[case]
    light = make()
    centers = np.array([light.pos + np.array(c) for c, _ in spheres])
    radii = np.array([r for _, r in spheres])
    natural = _emit(light, 2_000_000, 11)
    n_aim = 400_000
    aimed = _emit(light, n_aim, 12, (centers, radii))
    for c, r in zip(centers, radii):
        want = _power_into_sphere(*natural, c, r)
        got = _power_into_sphere(*aimed, c, r)
        if want.sum() == 0:
            assert got.sum() == 0
            continue
        # (~1 % noise each where a sphere takes a tenth of the flux)
        np.testing.assert_allclose(got, want, rtol=0.03)
    assert len(aimed[0]) >= stored * n_aim, (case, len(aimed[0]) / n_aim)


def test_sphere_behind_the_light_is_never_aimed_at():
    light = _area()
    centers = np.array([light.pos + np.array(c) for c in
                        ((0.0, 0.0, -2.0), (0.0, 0.0, 1.0), (3.0, 0.0, 0.35))])
    radii = np.array([0.4, 0.5, 0.4])
    probs = area_aim_weights(centers, radii, light.pos, light.dir, light.spread).probs
    assert probs[1] == 0.0  # wholly behind the emitting side
    assert 0.0 < probs[2] < 0.05 * probs[0]  # barely in front: little of the power
    np.testing.assert_allclose(probs.sum(), 1.0)
    # Every sphere behind: no aimed photon carries power (and nothing divides by zero).
    o, d, power = _emit(light, 1000, 5, (centers[1:2], radii[1:2]))
    assert len(o) == 0


def test_aim_weights_follow_the_power_sent_into_each_sphere():
    """The quadrature's shares against the natural photons' power shares (three spheres
    in front at different angles): within 10 % of each (the weights are taken from the
    light's centre; a 1 x 0.5 m light 2 m from a sphere sees it from other angles at its
    corners: 6 % here. Any positive weights keep the power unbiased, above)."""
    light = _area()
    spheres = [((0.3, 0.1, -1.8), 0.4), ((1.5, 0.0, -1.0), 0.4), ((-2.0, 1.0, -0.5), 0.6)]
    centers = np.array([light.pos + np.array(c) for c, _ in spheres])
    radii = np.array([r for _, r in spheres])
    natural = _emit(light, 2_000_000, 11)
    want = np.array([_power_into_sphere(*natural, c, r).sum() for c, r in zip(centers, radii)])
    probs = area_aim_weights(centers, radii, light.pos, light.dir, light.spread).probs
    np.testing.assert_allclose(probs, want / want.sum(), rtol=0.1)
