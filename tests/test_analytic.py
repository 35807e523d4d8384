"""Direct lighting against closed-form values (Cycles units, docs/design.md, Units (Cycles))."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.scene import Light
from helpers import pixel_to_world, rect_corner_factor, rel_err, top_down_plane

DIRECT_ONLY = dict(photon_mapping=False, max_depth=0)


def test_point_light_over_plane_matches_inverse_square_law():
    rho, P, h, view = 0.5, 1000.0, 2.0, 4.0
    s = top_down_plane(rho, view=view)
    s.add_point_light((0.3, -0.2, h), power=P)
    film = s.render(RenderSettings(spp=4, **DIRECT_ONLY))
    x, y = pixel_to_world(s, view)
    r2 = (x - 0.3) ** 2 + (y + 0.2) ** 2 + h * h
    cos = h / np.sqrt(r2)
    expected = rho * (P / (4 * math.pi)) * cos / r2 / math.pi  # L = rho I cos / (pi d^2)
    img = film.combined[..., 1]
    for (i, j) in [(32, 32), (10, 50), (60, 5), (0, 0), (45, 20)]:
        assert rel_err(img[i, j], expected[i, j]) < 0.01, (i, j, img[i, j], expected[i, j])
    assert np.isfinite(film.combined).all()


def test_sun_on_plane_gives_rho_E_cos_over_pi():
    rho, E = 0.6, 3.0
    s = top_down_plane(rho)
    theta = math.radians(30)
    s.add_sun(direction=(math.sin(theta), 0, -math.cos(theta)), strength=E)
    film = s.render(RenderSettings(spp=1, **DIRECT_ONLY))
    expected = rho * E * math.cos(theta) / math.pi
    assert np.allclose(film.combined, expected, rtol=1e-3)


def test_spot_light_inside_cone_and_in_blend_region():
    rho, P, h, view = 0.5, 1000.0, 2.0, 4.0
    s = top_down_plane(rho, view=view)
    size, blend = math.radians(60), 0.5
    s.add_light(Light("spot", "SPOT", P, position=(0, 0, h), direction=(0, 0, -1),
                      spot_size=size, spot_blend=blend))
    film = s.render(RenderSettings(spp=4, **DIRECT_ONLY))
    x, y = pixel_to_world(s, view)
    r2 = x * x + y * y + h * h
    cos = h / np.sqrt(r2)
    cos_half = math.cos(size / 2)
    f = np.clip((cos - cos_half) / ((1 - cos_half) * blend), 0, 1)
    mask = f * f * (3 - 2 * f)
    expected = rho * P / (4 * math.pi) * cos / r2 / math.pi * mask
    img = film.combined[..., 0]
    centre = (32, 32)
    assert rel_err(img[centre], expected[centre]) < 0.01
    # A pixel in the blend region (0 < mask < 1) and one outside the cone.
    blend_px = np.argwhere((mask > 0.3) & (mask < 0.7))[0]
    assert rel_err(img[tuple(blend_px)], expected[tuple(blend_px)]) < 0.03
    outside = np.argwhere(mask == 0)[0]
    assert img[tuple(outside)] < 1e-3 * img[centre]


@pytest.mark.parametrize("disk", [False, True])
def test_area_light_irradiance_matches_form_factor(disk):
    rho, P, h, a = 0.5, 200.0, 1.0, 1.0
    s = top_down_plane(rho, res=16, view=0.1)  # a small patch under the light's centre
    s.add_rect_area_light((0, 0, h), (a, a), power=P, disk=disk)
    film = s.render(RenderSettings(spp=256, light_samples=4, seed=3, **DIRECT_ONLY))
    if disk:
        area = math.pi * a * a / 4
        R = a / 2
        E_over_L = math.pi * R * R / (R * R + h * h)
    else:
        area = a * a
        E_over_L = 4 * rect_corner_factor(a / 2, a / 2, h)
    L = P / (math.pi * area)
    expected = rho / math.pi * L * E_over_L
    assert rel_err(film.combined.mean(), expected) < 0.01


def test_area_light_is_one_sided():
    s = top_down_plane(0.5)
    s.add_rect_area_light((0, 0, 1), (1, 1), power=100, direction=(0, 0, 1))  # faces away
    film = s.render(RenderSettings(spp=2, **DIRECT_ONLY))
    assert film.combined.max() == 0.0


def _spread_irradiance_reference(P, a, h, spread, xs):
    """Irradiance at floor points (x, 0, 0) under an a x a area light at height h facing
    down, by midpoint quadrature over the light (200 x 200 cells) of
    L f(angle) cos_r cos_l / d^2 (Cycles' spread, docs/units.md)."""
    from engine.scene import spread_attenuation
    m = 200
    c = (np.arange(m) + 0.5) / m * a - a / 2
    ly, lx = np.meshgrid(c, c, indexing="ij")
    L = P / (math.pi * a * a)
    out = []
    for x in xs:
        dx, dy, dz = lx - x, ly, np.full_like(lx, h)
        d2 = dx * dx + dy * dy + dz * dz
        cos = dz / np.sqrt(d2)       # same at receiver (normal +z) and light (normal -z)
        f = spread_attenuation(cos, spread)
        out.append(float((L * f * cos * cos / d2).sum() * (a / m) ** 2))
    return np.array(out)


@pytest.mark.parametrize("spread_deg", [30.0, 90.0])
def test_area_light_spread_matches_cycles_soft_box(spread_deg):
    """Blender's area `spread`: radiance scaled by Cycles' soft-box attenuation; lit patch
    narrower and brighter on the axis, same flux."""
    rho, P, h, a, view, res = 0.5, 100.0, 1.0, 0.5, 2.0, 32
    s = top_down_plane(rho, res=res, view=view)
    s.add_light(Light("soft box", "AREA", P, position=(0, 0, h), direction=(0, 0, -1),
                      size_x=a, size_y=a, spread=math.radians(spread_deg)))
    film = s.render(RenderSettings(spp=64, light_samples=4, seed=2, **DIRECT_ONLY))
    px = view / res
    row = res // 2  # the row just below the axis
    for j in (16, 18, 20, 23, 26, 30):
        # The film averages over the pixel: so does the reference (5 x 5 points).
        sub = (np.arange(5) + 0.5) / 5 * px
        xs, ys = np.meshgrid(j * px - view / 2 + sub, view / 2 - row * px - sub)
        e = rho / math.pi * _spread_irradiance_reference(
            P, a, h, math.radians(spread_deg), np.hypot(xs, ys).ravel()).mean()
        g = float(film.combined[row, j, 1])
        assert abs(g - e) <= 0.03 * e + 0.005 * P / (a * a), (j, g, e)


def test_spread_attenuation_keeps_the_flux():
    """f(a) integrated with cos a over the hemisphere is pi for every spread (Cycles'
    normalisation), so the light's power does not depend on its spread."""
    from engine.scene import spread_attenuation
    a = (np.arange(200000) + 0.5) / 200000 * (math.pi / 2)
    for deg in (2.0, 10.0, 45.0, 120.0, 180.0):
        f = spread_attenuation(np.cos(a), math.radians(deg))
        integral = float((f * np.cos(a) * np.sin(a)).sum() * (math.pi / 2) / len(a) * 2 * math.pi)
        assert rel_err(integral, math.pi) < 2e-3, (deg, integral)


def test_light_with_cast_shadow_off_lights_through_objects():
    """Blender's light 'Cast Shadow' off: direct light ignores occluders (as in Cycles)."""
    rho, P, h, view = 0.5, 1000.0, 2.0, 4.0
    results = {}
    for casts in (True, False):
        s = top_down_plane(rho, view=view)
        s.add_light(Light("bulb", "POINT", P, position=(0, 0, h), cast_shadow=casts))
        s.add_plane((0, 0, 1.0), (0, 0, 1), 1.0, "matte", name="blocker")  # 1 m card above
        results[casts] = s.render(RenderSettings(spp=1, **DIRECT_ONLY)).combined[..., 0]
    x, y = pixel_to_world(s, view)
    r2 = x * x + y * y + h * h
    expected = rho * P / (4 * math.pi) * (h / np.sqrt(r2)) / r2 / math.pi
    # The card (+-0.5 m, 1 m below the light) shadows the floor out to +-1 m; the camera
    # looks straight down, so the floor is seen between 0.5 and 1 m: the shadow's rim.
    m = np.maximum(np.abs(x), np.abs(y))
    rim = (m > 0.6) & (m < 0.95)
    assert results[True][rim].max() == 0.0
    assert results[False][rim].mean() == pytest.approx(expected[rim].mean(), rel=0.01)
    assert results[False][rim].min() > 0.9 * expected[rim].min()
    outside = m > 1.1
    np.testing.assert_allclose(results[True][outside], results[False][outside])
