"""Energy bookkeeping of the photon pass and the renderer."""
import math

import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.photons import DIRECT, trace_photons
from engine.render import Context
from engine.accel import Accel
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.scene import Material


def closed_box(albedo, power=100.0):
    s = PaperScene(width=32, height=24)
    s.add_material(Material("wall", (albedo,) * 3))
    s.add_box((0, 0, 1), (2, 2, 2), "wall", name="room")
    # Box faces point outward; the light sits inside, so photons hit the inner sides.
    s.add_point_light((0.1, -0.2, 1.1), power=power)
    s.set_camera((0, -0.9, 1), (0, 0, 1), view_angle=90)
    return s


def shoot(scene, settings):
    scene.validate()
    geo, table = prepare(scene)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, settings, geo, table, accel, lights)
    return trace_photons(ctx, lights, allocate_photons(lights, settings.photons), False, 1)


def test_stored_power_is_bounded_by_emitted_power():
    albedo, P = 0.8, 100.0
    # chunk_size < photons: power must not depend on how the photons are batched.
    ph = shoot(closed_box(albedo, P), RenderSettings(photons=20000, max_photon_depth=50,
                                                      chunk_size=3000))
    first_hits = ph.power[ph.kind == DIRECT].astype(np.float64).sum(axis=0)
    # Every photon of a closed box lands once as a first hit: exactly the emitted power.
    assert np.allclose(first_hits, P, rtol=1e-6)
    total = ph.power.astype(np.float64).sum(axis=0)
    assert np.all(total <= P / (1 - albedo) * 1.02)
    assert np.all(total >= P * 1.5)  # bounces really happened
    assert np.isfinite(ph.power).all() and (ph.power >= 0).all()


def test_black_albedo_gives_no_indirect_light():
    s = closed_box(0.0)
    film = s.render(RenderSettings(photons=5000, spp=2))
    assert film.indirect.max() == 0.0
    assert film.caustic.max() == 0.0
    assert film.combined.max() == 0.0  # black walls reflect nothing at all


def test_doubling_light_power_doubles_the_image():
    a = closed_box(0.5, 50.0).render(RenderSettings(photons=5000, spp=2, seed=4))
    b = closed_box(0.5, 100.0).render(RenderSettings(photons=5000, spp=2, seed=4))
    assert a.combined.mean() > 0
    np.testing.assert_allclose(b.combined, 2 * a.combined, rtol=1e-4, atol=1e-7)


def test_area_light_spread_emits_its_flux():
    """Photons of an area light with a narrow spread carry the same total power, all
    inside the spread cone."""
    from engine.geometry import prepare
    from engine.lights import prepare_lights
    from engine.scene import Light
    from helpers import top_down_plane
    s = top_down_plane(0.5)
    s.add_light(Light("soft box", "AREA", 80.0, position=(0, 0, 1), direction=(0, 0, -1),
                      size_x=0.5, size_y=0.5, spread=math.radians(40)))
    geo, table = prepare(s.scene if hasattr(s, "scene") else s)
    light = prepare_lights(s.scene if hasattr(s, "scene") else s, geo, table)[0]
    o, d, power = light.emit(200_000, np.random.default_rng(1))
    np.testing.assert_allclose(power.sum(axis=0), light.flux, rtol=0.01)
    assert np.all(-d[:, 2] >= math.cos(math.radians(20)) - 1e-9)
