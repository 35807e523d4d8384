"""Emission inside homogeneous media (engine/volumeemission.py): along a segment of length
S in a medium of extinction sigma_t emitting e (W/m^2/sr per m) a path adds
e (1 - exp(-sigma_t S)) / sigma_t per channel (e S where sigma_t = 0), times its
throughput at the segment's start (Cycles' volume_emission_integrate). Analytic checks: a
camera looking through an emitting slab (pure emission, absorbing, absorbing and
scattering, in front of an emitting floor), the world volume's glow to infinity and to a
black floor, a lamp seen through an object's medium, and a floor lit only by a glowing box
(its final gather alone) against a numerical integral of the box's glow."""
import math

import numpy as np
import pytest

from engine import RenderSettings, WorldMedium
from engine.api import PaperScene
from engine.geometry import MaterialTable
from engine.media import EMISSION_ONLY_SIGMA, NO_SIGMA, absorption_table
from engine.render import render
from engine.scene import Material, SceneError
from engine.volumeemission import emission_integral, emission_table

EMIT = np.array([0.6, 0.9, 1.5])  # W/m^2/sr per m
SIGMA_A = np.array([0.5, 1.0, 2.0])  # 1/m
SIGMA_S = np.array([0.3, 0.2, 0.1])


def _mean(film):
    return np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)


def _glow(S, sigma_t, e=EMIT):
    sigma_t = np.asarray(sigma_t, np.float64)
    safe = np.where(sigma_t > 0, sigma_t, 1.0)
    return np.where(sigma_t > 0, e * -np.expm1(-sigma_t * S) / safe, e * S)


def test_material_table_and_the_integral():
    with pytest.raises(SceneError, match="volume_emission"):
        Material("bad", volume_emission=(-1.0, 0.0, 0.0))
    glow = Material("glow", volume_only=True, volume_emission=EMIT)
    fog = Material("fog", volume_only=True, absorption=SIGMA_A, volume_emission=EMIT)
    table = MaterialTable.build([Material("a"), glow, fog])
    np.testing.assert_array_equal(emission_table(table), [[0, 0, 0], EMIT, EMIT])
    # A medium that only emits is a medium (extinction > 0) that dims nothing.
    sigma = absorption_table(table)
    np.testing.assert_array_equal(sigma, [[0, 0, 0], [EMISSION_ONLY_SIGMA] * 3, SIGMA_A])
    assert math.exp(-EMISSION_ONLY_SIGMA * 1e6) == 1.0
    assert emission_table(MaterialTable.build([Material("a")])).shape == (0, 3)
    assert absorption_table(MaterialTable.build([Material("a")])) is NO_SIGMA
    # e (1 - exp(-sigma S)) / sigma, e S at sigma 0 and its expansion below depth 1e-5.
    assert emission_integral(2.0, 0.5, 3.0) == pytest.approx(2.0 * (1 - math.exp(-1.5)) / 0.5)
    assert emission_integral(2.0, 0.0, 3.0) == pytest.approx(6.0)
    assert emission_integral(2.0, EMISSION_ONLY_SIGMA, 3.0) == pytest.approx(6.0, rel=1e-15)
    assert emission_integral(2.0, 1e-7, 3.0) == pytest.approx(6.0 * (1 - 1.5e-7), rel=1e-12)


def _slab_scene(sigma_a, sigma_s, floor_emission=0.0):
    """An emitting volume-only slab (2 x 2 m, 0.5 m thick, centred at z 1) over a black
    floor at z 0 that emits floor_emission (grey), seen from z 3 straight down (view
    angle 2 degrees: every ray crosses the slab within 1 + 2e-4 of its thickness). No
    lamp: the slab's scattering has nothing to scatter."""
    s = PaperScene(6, 6)
    s.add_material(Material("floor", (0.0, 0.0, 0.0), emission=(floor_emission,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "floor", name="floor")
    s.add_box((0, 0, 1.0), (2.0, 2.0, 0.5),
              Material("slab", volume_only=True, absorption=sigma_a, scattering=sigma_s,
                       volume_emission=EMIT), name="slab")
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), view_angle=2.0)
    return s


def _scattered_glow(sigma_t, sigma_s, d=0.5, n_s=64, n_dir=20_000):
    """The slab's glow scattered once towards the camera along its central ray (isotropic
    phase): integral_0^d T(s) sigma_s mean_w[e (1 - exp(-sigma_t l(w))) / sigma_t] ds,
    l(w) the chord from the point to the slab's boundary along w (midpoint rule in s, a
    Fibonacci sphere of directions)."""
    lo, hi = np.array([-1.0, -1.0, 0.75]), np.array([1.0, 1.0, 1.25])
    k = np.arange(n_dir) + 0.5
    z = 1.0 - 2.0 * k / n_dir
    phi = math.pi * (1.0 + 5.0 ** 0.5) * k
    r = np.sqrt(1.0 - z * z)
    w = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    total = np.zeros(3)
    for s in (np.arange(n_s) + 0.5) / n_s * d:
        x = np.array([0.0, 0.0, 1.25 - s])
        with np.errstate(divide="ignore"):
            t = np.where(w > 0, (hi - x) / w, (lo - x) / w)
        chord = np.min(np.where(w != 0, t, np.inf), axis=1)
        glow = _glow(chord[:, None], sigma_t).mean(axis=0)
        total += np.exp(-sigma_t * s) * sigma_s * glow * d / n_s
    return total


@pytest.mark.parametrize("kind", ["emission", "absorbing", "scattering", "over-a-lamp"])
def test_a_camera_looking_through_an_emitting_slab(kind):
    """The slab's glow e (1 - exp(-sigma_t d)) / sigma_t (e d for pure emission), plus an
    emitting floor behind it dimmed by exp(-sigma_t d), within 0.1 %; a scattering slab
    adds its glow scattered once towards the camera (Cycles at Volume bounces 0; by
    quadrature, _scattered_glow), the sum within 1 % at 256 spp."""
    d = 0.5
    sigma_a = np.zeros(3) if kind == "emission" else SIGMA_A
    sigma_s = SIGMA_S if kind == "scattering" else np.zeros(3)
    floor = 2.0 if kind == "over-a-lamp" else 0.0
    spp = 256 if kind == "scattering" else 4
    film = render(_slab_scene(sigma_a, sigma_s, floor),
                  RenderSettings(workers=1, spp=spp, photon_mapping=False, seed=1))
    sigma_t = sigma_a + sigma_s
    expect = _glow(d, sigma_t) + floor * np.exp(-sigma_t * d)
    if kind == "scattering":
        expect = expect + _scattered_glow(sigma_t, sigma_s)
    np.testing.assert_allclose(_mean(film), expect, rtol=1e-2 if kind == "scattering"
                               else 1e-3)


def _world_scene(floor: bool):
    """A camera at z 2 in an emitting, absorbing world volume, looking straight down at
    a black floor at z 0 (floor) or up into the empty sky (a small black card beside
    the view: the scene needs a triangle)."""
    s = PaperScene(6, 6, background=(3.0, 3.0, 3.0))
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    if floor:
        s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "black", name="floor")
        s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), view_angle=2.0)
    else:
        s.add_plane((5, 5, 0), (0, 0, 1), 0.5, "black", name="card")
        s.set_camera((0, 0, 2.0), (0, 0, 4.0), up=(0, 1, 0), view_angle=2.0)
    s.world_medium = WorldMedium(absorption=SIGMA_A, emission=EMIT)
    return s


@pytest.mark.parametrize("floor", [True, False], ids=["to-the-floor", "to-infinity"])
def test_the_world_volume_glows_along_camera_rays(floor):
    """2 m of the world's glow to a black floor, e (1 - exp(-2 sigma_a)) / sigma_a, or
    e / sigma_a to infinity (the background beyond reads black); within 0.1 %."""
    film = render(_world_scene(floor),
                  RenderSettings(workers=1, spp=4, photon_mapping=False, seed=1))
    expect = _glow(2.0, SIGMA_A) if floor else EMIT / SIGMA_A
    np.testing.assert_allclose(_mean(film), expect, rtol=1e-3)


def _lamp_in_fog_scene(world: bool):
    """A 1 m square area light at z 0.5 facing the camera, visible to camera rays, inside
    an absorbing, emitting volume-only box (3 x 3 x 2 m, z -0.5 .. 1.5) or the world
    volume; the camera at z 3 looks straight down at it."""
    from engine.scene import Light
    s = PaperScene(6, 6)
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    s.add_plane((0, 0, -2.0), (0, 0, 1), 6.0, "black", name="floor")
    if world:
        s.world_medium = WorldMedium(absorption=SIGMA_A, emission=EMIT)
    else:
        s.add_box((0, 0, 0.5), (3.0, 3.0, 2.0),
                  Material("fog", volume_only=True, absorption=SIGMA_A,
                           volume_emission=EMIT), name="fog")
    s.add_light(Light("lamp", kind="AREA", position=(0, 0, 0.5), direction=(0, 0, 1),
                      size_x=1.0, size_y=1.0, power=10.0, visible_camera=True))
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), view_angle=2.0)
    return s


@pytest.mark.parametrize("world", [False, True], ids=["object-medium", "world-volume"])
def test_a_lamp_seen_inside_a_medium_is_dimmed_and_the_medium_glows(world):
    """The lamp's radiance P / (pi A) through the medium's length in front of it (1 m in
    the box, 2.5 m in the world volume: exp(-sigma_a s)) plus the medium's glow on that
    segment and, the lamp being transparent as in Cycles (integrator_shade_light_forward:
    the ray goes on past it; mis51), on as much again behind it to the box's floor or
    the black floor: the glow of 2 s; in the box the 1.5 m of clear air above it add
    nothing."""
    film = render(_lamp_in_fog_scene(world),
                  RenderSettings(workers=1, spp=4, photon_mapping=False, seed=1))
    s = 2.5 if world else 1.0
    expect = 10.0 / math.pi * np.exp(-SIGMA_A * s) + _glow(2.0 * s, SIGMA_A)
    np.testing.assert_allclose(_mean(film), expect, rtol=2e-3)


BOX_LO = np.array([-0.5, -0.5, 0.5])
BOX_HI = np.array([0.5, 0.5, 1.0])
BOX_EMIT = np.array([2.0, 3.0, 4.0])
BOX_SIGMA = np.array([0.0, 1.0, 3.0])


def _floor_glow_quadrature(p, n=(40, 40, 20)):
    """(3,) irradiance at floor point p (3,) (normal +z) from the box's glow: the volume
    integral of e exp(-sigma_a l_in) cos(theta) / r^2 over the box (l_in the distance the
    light travels inside the box towards p), midpoint rule."""
    axes = [BOX_LO[i] + (np.arange(n[i]) + 0.5) * (BOX_HI[i] - BOX_LO[i]) / n[i]
            for i in range(3)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    dV = np.prod((BOX_HI - BOX_LO) / n)
    v = x - p
    r = np.linalg.norm(v, axis=1)
    u = v / r[:, None]
    # The ray from p towards x enters the box at t_in (slab method).
    with np.errstate(divide="ignore"):
        inv = 1.0 / u
    t0 = (BOX_LO - p) * inv
    t1 = (BOX_HI - p) * inv
    t_in = np.max(np.minimum(t0, t1), axis=1)
    l_in = r - np.maximum(t_in, 0.0)
    w = (u[:, 2] / r ** 2 * dV)[:, None]
    return (w * BOX_EMIT * np.exp(-np.outer(l_in, BOX_SIGMA))).sum(axis=0)


def _glowing_box_scene(wall=False):
    """A white floor (0.8) lit only by a glowing, absorbing volume-only box (1 x 1 x 0.5
    m, z 0.5 .. 1), seen beside the box by an orthographic camera (0.8 m square centred
    at x = 1.3) looking straight down: no lamp, no photon. wall: a white wall at x = 2
    beside it (the floor's gather rays end there: the glow's second bounce)."""
    s = PaperScene(8, 8)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    if wall:
        s.add_plane((2.0, 0, 1.0), (-1, 0, 0), 4.0, "white_diffuse", name="wall")
    s.add_box((BOX_LO + BOX_HI) / 2, BOX_HI - BOX_LO,
              Material("glow", volume_only=True, absorption=BOX_SIGMA,
                       volume_emission=BOX_EMIT), name="glow")
    s.set_camera((1.3, 0, 3.0), (1.3, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=0.8)
    return s


def test_a_floor_lit_only_by_a_glowing_box_matches_the_integral():
    """The floor's radiance 0.8 / pi x the box's glow irradiance (final-gather rays alone:
    no lamp, no photon map), the image's mean against the quadrature's at the pixel
    centres within 1 % per channel (8 x 8 pixels x 1024 spp; measured over seeds 0-5:
    1.001-1.002, std 0.0014)."""
    film = render(_glowing_box_scene(), RenderSettings(workers=1, spp=1024, seed=3))
    xs = 1.3 + (np.arange(8) + 0.5) / 8 * 0.8 - 0.4
    E = np.mean([_floor_glow_quadrature(np.array([x, y, 0.0])) for x in xs for y in xs
                 - 1.3], axis=0)
    albedo = np.asarray(PaperScene().materials["white_diffuse"].base_color)
    np.testing.assert_allclose(_mean(film), albedo / math.pi * E, rtol=0.01)


def test_the_world_volume_glows_on_a_floor_under_it():
    """An infinite floor (30 m) in an absorbing, emitting world volume: every gather ray
    escapes upwards through it and brings e / sigma_a, so the floor reads 0.5 e /
    sigma_a (grey 0.5; orthographic camera 1 m above, its own segment adding
    e (1 - exp(-sigma_a)) / sigma_a and dimming the floor by exp(-sigma_a)); within 1 %
    at 256 spp (no lamp, no photon)."""
    s = PaperScene(8, 8)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "grey", name="floor")
    s.set_camera((0, 0, 1.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    s.world_medium = WorldMedium(absorption=SIGMA_A, emission=EMIT)
    film = render(s, RenderSettings(workers=1, spp=256, seed=2))
    expect = 0.5 * EMIT / SIGMA_A * np.exp(-SIGMA_A) + _glow(1.0, SIGMA_A)
    np.testing.assert_allclose(_mean(film), expect, rtol=0.01)


def test_the_same_image_for_any_worker_count_and_the_report():
    from engine.render import prepare_context
    settings = dict(spp=8, seed=3, photons=20_000)
    a, b = (render(_glowing_box_scene(wall=True), RenderSettings(workers=w, **settings))
            for w in (1, 2))
    np.testing.assert_array_equal(np.asarray(a.combined), np.asarray(b.combined))
    # The wall's light on the floor (the glow's second bounce, gathered from the
    # floor's gather ends on the wall) brightens it.
    c = render(_glowing_box_scene(), RenderSettings(workers=1, **settings))
    assert np.all(_mean(a) > 1.02 * _mean(c))
    scene = _glowing_box_scene()
    ctx = prepare_context(scene, RenderSettings(workers=1))
    assert not [w for w in scene.warnings if "black" in w]  # (no lamp, but a glow)
    lines = [x for x in ctx.plan.report() if "volume emission" in x]
    assert lines and "'glow'" in lines[0] and "gather" in lines[0]


def test_scene_file_keys(tmp_path):
    from engine.scenefile import load_scene
    path = tmp_path / "glow.toml"
    path.write_text("""
[camera]
position = [0, -5, 1]
look_at = [0, 0, 0]
[materials.glow]
volume_only = true
volume_emission = [1.0, 0.5, 0.25]
[world_medium]
absorption = [0.1, 0.2, 0.3]
emission = [0.01, 0.02, 0.03]
""")
    scene, _ = load_scene(str(path))
    np.testing.assert_allclose(scene.materials["glow"].volume_emission, [1.0, 0.5, 0.25])
    np.testing.assert_allclose(scene.world_medium.emission, [0.01, 0.02, 0.03])
