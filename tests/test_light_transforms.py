"""Light object transforms read as Cycles reads them (engine side; the Blender tests in
tests/blender/test_blender_fidelity.py compare renders with Cycles)."""
import math

import numpy as np

from engine.geometry import prepare
from engine.lights import prepare_lights
from engine.scene import Light, spot_cone_fraction, spot_cone_fraction_frame
from helpers import top_down_plane


def _prepared(light):
    s = top_down_plane()
    s.add_light(light)
    s.validate()
    geo, table = prepare(s)
    return prepare_lights(s, geo, table)[0]


def test_round_spot_frame_changes_nothing():
    plain = Light("s", "SPOT", spot_size=math.radians(50), spot_blend=0.3)
    framed = Light("s", "SPOT", spot_size=math.radians(50), spot_blend=0.3,
                   spot_frame=np.diag([0.5, 0.5, -0.5]))  # uniform scale 2: round
    np.testing.assert_allclose(framed.flux, plain.flux, rtol=2e-3)
    frac = spot_cone_fraction_frame(plain.spot_size, plain.spot_blend, plain.cone_frame,
                                    plain.direction)
    assert abs(frac / spot_cone_fraction(plain.spot_size, plain.spot_blend) - 1) < 2e-3


def test_scaled_spot_photons_carry_its_flux():
    """Photons of a spot stretched 2 x 0.5 (Cycles: scale (2, 0.5, 1)) carry the flux of
    its elliptical cone, and every photon leaves inside that cone."""
    frame = np.stack([np.array([1.0, 0, 0]) / 2.0, np.array([0, 1.0, 0]) / 0.5,
                      np.array([0, 0, -1.0])])
    light = Light("s", "SPOT", power=100.0, position=(0, 0, 3), direction=(0, 0, -1),
                  spot_size=math.radians(40), spot_blend=0.0, spot_frame=frame)
    pl = _prepared(light)
    o, d, power = pl.emit(400_000, np.random.default_rng(1))
    np.testing.assert_allclose(power.sum(axis=0), light.flux, rtol=0.01)
    lit = power[:, 0] > 0
    # Inside the cone: (tan_x / 2)^2 + (tan_y / 0.5)^2 <= tan(20 deg)^2.
    tx, ty = d[lit, 0] / -d[lit, 2], d[lit, 1] / -d[lit, 2]
    assert np.all((tx / 2) ** 2 + (ty / 0.5) ** 2 <= math.tan(math.radians(20)) ** 2 * 1.0001)
    assert tx.max() > 1.9 * math.tan(math.radians(20))  # it does reach the stretched rim


def test_sheared_area_light_is_cycles_parallelogram():
    """Shear (axes 60 degrees apart): points fill |p.u| <= a/2, |p.v| <= b/2, area
    a b / sin 60, flux P / sin 60 (Cycles keeps the radiance P / (pi a b))."""
    v = np.array([math.cos(math.radians(60)), math.sin(math.radians(60)), 0.0])
    light = Light("a", "AREA", power=50.0, position=(0, 0, 2), direction=(0, 0, -1),
                  size_x=1.0, size_y=0.5, skew_axis_v=v)
    s60 = math.sin(math.radians(60))
    assert abs(light.area - 0.5 / s60) < 1e-9
    np.testing.assert_allclose(light.flux, 50.0 / s60)
    pl = _prepared(light)
    np.testing.assert_allclose(pl.radiance, 50.0 / (math.pi * 0.5))
    # The photons' origins (float32, as handed to Embree: 1e-6 is their rounding here).
    p = pl.emit(20_000, np.random.default_rng(2))[0] - pl.pos
    pu, pv = p @ pl.u, p @ pl.v
    assert np.abs(pu).max() <= 0.5 + 1e-6 and np.abs(pv).max() <= 0.25 + 1e-6
    assert np.abs(pu).max() > 0.49 and np.abs(pv).max() > 0.24
    # Every sampled point is accepted by the light's own intersection test (seen in mirrors).
    o = pl.pos + p + np.array([0, 0, -1.0])
    mask, _, _ = pl.intersect(o, np.tile([0, 0, 1.0], (len(p), 1)), np.full(len(p), 10.0))
    assert mask.mean() > 0.999
