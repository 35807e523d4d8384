"""World light from an equirectangular environment map (engine/lights/environment.py,
engine/lights/world.py): the sampling distribution, analytic irradiance, escaped rays,
photon emission, the scene file. Cycles comparisons: tools/feature_matrix.py, world_*."""
import math

import numpy as np
import pytest

from engine import Environment, RenderSettings
from engine.api import PaperScene
from engine.geometry import prepare
from engine.lights import WorldLight, prepare_lights
from engine.scene import euler_rotation
from engine.scene import Camera
from engine.scenefile import SceneFileError, load_scene
from helpers import random_environment, sphere_grid, top_down_plane

DIRECT_ONLY = dict(photon_mapping=False, max_depth=0)




@pytest.mark.parametrize("rotation", [None, euler_rotation((0.0, 0.0, 0.0))])
def test_pdf_integrates_to_one_over_the_sphere(rotation):
    env = random_environment(rotation=rotation)
    # pdf x sin(theta) is constant on each texel: cell midpoints of a grid 4x finer than
    # the texels integrate it exactly (to the float32 rounding of the stored pdf).
    d, sin_t, cell = sphere_grid(4 * env.height, 4 * env.width)
    total = float(np.sum(env.pdf(d) * sin_t) * cell)
    assert abs(total - 1.0) < 1e-6, total


def test_pdf_integrates_to_one_when_rotated():
    env = random_environment(rotation=euler_rotation((0.4, -0.3, 1.1)))
    d, sin_t, cell = sphere_grid(400, 800)  # no longer texel-aligned: a fine quadrature
    total = float(np.sum(env.pdf(d) * sin_t) * cell)
    assert abs(total - 1.0) < 2e-3, total


def test_samples_follow_their_pdf():
    env = random_environment(rotation=euler_rotation((0.2, 0.5, -0.7)))
    rng = np.random.default_rng(0)
    n = 200_000
    wi, pdf = env.sample(rng.random(n), rng.random(n))
    assert np.allclose(np.linalg.norm(wi, axis=1), 1.0)
    assert np.allclose(pdf, env.pdf(wi), rtol=1e-9)
    # Every direction with radiance has pdf > 0 (the filtered distribution covers the
    # bilinear lookup's spread), so radiance / pdf estimates the integral without bias.
    d, sin_t, cell = sphere_grid(200, 400)
    L = env.radiance(d)
    assert np.all(env.pdf(d)[L.max(axis=1) > 0] > 0)
    estimate = (env.radiance(wi) / pdf[:, None]).mean(axis=0)
    quadrature = (L * (sin_t * cell)[:, None]).sum(axis=0)
    assert np.allclose(estimate, quadrature, rtol=0.02), (estimate, quadrature)
    # The sampled texel frequencies match pdf_uv / (H W).
    rows, cols, pdf_uv = env.distribution
    tex = wi @ env.rotation.T
    u = (0.5 - np.arctan2(tex[:, 1], tex[:, 0]) / (2 * math.pi)) % 1.0
    i = np.minimum((np.arccos(np.clip(tex[:, 2], -1, 1)) / math.pi * env.height).astype(int),
                   env.height - 1)
    j = np.minimum((u * env.width).astype(int), env.width - 1)
    freq = np.bincount(i * env.width + j, minlength=env.height * env.width) / n
    expected = (pdf_uv / pdf_uv.sum()).ravel()
    big = expected > 0.005
    assert np.allclose(freq[big], expected[big], rtol=0.1)


def test_integral_is_the_sum_of_texel_radiance_times_solid_angle():
    env = Environment(np.full((6, 10, 3), 0.25), strength=2.0)
    assert np.allclose(env.integral(), 4 * math.pi * 0.5)
    assert np.allclose(env.average(), 0.5)


def test_equirectangular_orientation_is_blenders():
    """u = 0.5 - atan2(y, x) / 2pi, v = 1 - acos(z) / pi (checked against Cycles 5.0):
    +X looks at the image centre, +Y at u = 0.25, +Z at the top row."""
    h, w = 8, 16
    px = np.zeros((h, w, 3))
    px[:, :, 0] = (np.arange(w) + 0.5)[None, :] / w
    px[:, :, 1] = 1.0 - (np.arange(h) + 0.5)[:, None] / h
    env = Environment(px, interpolation="Closest")
    got = env.radiance(np.array([[1.0, 0, 0.01], [0, 1.0, 0.01], [0, -1.0, 0.01],
                                 [0, 0.01, 1.0]]))
    assert np.allclose(got[:3, 0], [0.5 + 0.5 / w, 0.25 + 0.5 / w, 0.75 + 0.5 / w])
    assert got[3, 1] == pytest.approx(1 - 0.5 / h)
    # A Mapping rotation of +90 degrees about Z shows at +X what +Y showed before.
    turned = Environment(px, rotation=euler_rotation((0, 0, math.pi / 2)), interpolation="Closest")
    assert np.allclose(turned.radiance(np.array([[1.0, 0, 0.01]])), got[1])


def test_uniform_environment_lights_a_diffuse_plane_with_pi_L():
    """A uniform world of radiance L: irradiance pi L on an open plane, radiance rho L."""
    rho, L = 0.5, 0.8
    s = top_down_plane(rho, res=16)
    s.environment = Environment(np.full((16, 32, 3), L))
    film = s.render(RenderSettings(spp=64, seed=1, **DIRECT_ONLY))
    assert abs(film.combined.mean() / (rho * L) - 1.0) < 0.01, film.combined.mean()


def _one_texel_env(h, w, i, j, Ls, rotation=None):
    px = np.zeros((h, w, 3))
    px[i, j] = Ls
    return Environment(px, rotation=rotation, interpolation="Closest")


def _texel_irradiance(h, w, i, Ls):
    """Irradiance on an upward plane from texel row i of radiance Ls (exact integral of
    cos(theta) over the texel's solid angle)."""
    th0, th1 = math.pi * i / h, math.pi * (i + 1) / h
    return Ls * (2 * math.pi / w) * (math.sin(th1) ** 2 - math.sin(th0) ** 2) / 2


@pytest.mark.parametrize("i", [1, 5])
def test_one_bright_texel_gives_the_irradiance_of_its_solid_angle(i):
    rho, h, w, Ls = 0.5, 16, 32, 50.0
    s = top_down_plane(rho, res=16)
    s.environment = _one_texel_env(h, w, i, 7, Ls)
    film = s.render(RenderSettings(spp=64, seed=2, **DIRECT_ONLY))
    expected = rho * _texel_irradiance(h, w, i, Ls) / math.pi
    assert abs(film.combined.mean() / expected - 1.0) < 0.02
    # Half the shadow rays sample the map, whose distribution finds the texel; the other
    # half (cosine) rarely do: pixel noise stays well below that of cosine sampling
    # alone (which would need ~1 / (texel solid angle) samples to see it once).
    assert film.combined[..., 0].std() < 0.2 * expected


def test_rotation_turns_the_light_source():
    """A texel below the horizon lights nothing; a Mapping rotation of 180 degrees about X
    brings it overhead (texture direction = R @ world direction)."""
    rho, h, w, Ls = 0.5, 16, 32, 50.0
    s = top_down_plane(rho, res=8)
    s.environment = _one_texel_env(h, w, h - 3, 4, Ls)
    dark = s.render(RenderSettings(spp=8, seed=2, **DIRECT_ONLY)).combined
    assert dark.max() == 0.0
    s.environment = _one_texel_env(h, w, h - 3, 4, Ls, rotation=euler_rotation((math.pi, 0, 0)))
    lit = s.render(RenderSettings(spp=64, seed=2, **DIRECT_ONLY)).combined
    expected = rho * _texel_irradiance(h, w, 2, Ls) / math.pi  # mirrored row h-3 -> 2
    assert abs(lit.mean() / expected - 1.0) < 0.03


def _sky_scene(env, transparent=False):
    s = PaperScene(24, 16)
    s.add_plane((0, 0, -50), (0, 0, 1), 1.0, "white_diffuse", name="speck")
    s.camera = Camera(position=(0, 0, 0), rotation=np.array(
        [[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]]).T, fov=math.radians(60))  # looks along +X
    s.environment = env
    return s


def test_camera_rays_that_miss_see_the_map_and_film_transparent_hides_it():
    px = np.zeros((8, 16, 3))
    px[..., 0] = np.linspace(0.1, 1.0, 16)[None, :]
    px[..., 1] = np.linspace(0.2, 0.9, 8)[:, None]
    env = Environment(px, strength=2.0)
    s = _sky_scene(env)
    st = RenderSettings(spp=16, seed=0, photon_mapping=False)
    film = s.render(st)
    # The pixel's mean radiance equals the map's over the pixel: compare with the map at
    # many jittered directions through the same pixels.
    cam = s.camera
    rng = np.random.default_rng(1)
    hw, hh = cam.half_extents(s.width, s.height)
    jy, jx = np.mgrid[0:s.height, 0:s.width]
    acc = np.zeros((s.height, s.width, 3))
    for _ in range(64):
        sx = (jx + rng.random(jx.shape)) / s.width * 2 - 1
        sy = 1 - (jy + rng.random(jy.shape)) / s.height * 2
        d = (sx[..., None] * hw * cam.rotation[:, 0] + sy[..., None] * hh * cam.rotation[:, 1]
             - cam.rotation[:, 2])
        acc += env.radiance(d.reshape(-1, 3)).reshape(acc.shape)
    expected = acc / 64
    assert np.allclose(film.combined, expected, rtol=0.03, atol=0.01)
    assert np.allclose(film.alpha, 0.0)
    hidden = s.render(RenderSettings(spp=4, seed=0, photon_mapping=False,
                                     film_transparent=True))
    assert hidden.combined.max() == 0.0 and np.allclose(hidden.alpha, 0.0)


def test_world_photons_carry_the_maps_flux():
    s = top_down_plane(0.5, res=8)
    s.environment = random_environment()
    geo, table = prepare(s)
    world = [li for li in prepare_lights(s, geo, table) if isinstance(li, WorldLight)][0]
    R = world.scene_radius
    assert np.allclose(world.photon_flux, s.environment.integral() * math.pi * R * R)
    rng = np.random.default_rng(5)
    o, d, power = world.emit(200_000, rng)
    assert np.allclose(power.sum(axis=0), world.photon_flux, rtol=0.02)
    # Photons travel against the sampled directions, from a disk beyond the scene.
    assert np.all(np.linalg.norm(o - world.center, axis=1) >= R * 1.99)
    # The sun (where the interpolated radiance exceeds 10): the photons arriving from it
    # carry its share of the map's flux, and most photons come from it. (Within a texel
    # the photons follow the interpolated luminance: their powers are nearly equal, so
    # the single most powerful photon no longer marks the sun.)
    env = s.environment
    dirs, sin_t, dA = sphere_grid(720, 1440)
    L = env.radiance(dirs)
    in_sun = L[:, 0] > 10
    share = (L[in_sun] * sin_t[in_sun, None]).sum(0) / (L * sin_t[:, None]).sum(0)
    from_sun = env.radiance(-d)[:, 0] > 10
    assert np.allclose(power[from_sun].sum(0) / power.sum(0), share, rtol=0.02)
    assert from_sun.mean() > 0.5


def test_environment_renders_deterministically_with_photons():
    s = top_down_plane(0.5, res=8)
    s.add_sphere((0, 0, 0.5), 0.5, "white_diffuse")
    s.environment = random_environment()
    st = RenderSettings(spp=2, photons=2000, seed=9)
    a = s.render(st).combined
    b = s.render(st).combined
    assert np.array_equal(a, b) and np.isfinite(a).all() and a.mean() > 0


@pytest.mark.parametrize("bad, match", [
    (dict(pixels=np.full((4, 8, 3), np.nan)), "NaN"),
    (dict(pixels=-np.ones((4, 8, 3))), "negative"),
    (dict(pixels=np.ones((4, 8, 2))), "HxWx3"),
    (dict(strength=-1.0), "strength"),
    (dict(rotation=np.diag([1.0, 1.0, 2.0])), "rotation"),
    (dict(interpolation="Cubic"), "interpolation"),
])
def test_bad_environment_input_is_refused_naming_the_argument(bad, match):
    kw = dict(pixels=np.ones((4, 8, 3)), name="sky.exr")
    kw.update(bad)
    pixels = kw.pop("pixels")
    with pytest.raises(ValueError, match=match) as e:
        Environment(pixels, **kw)
    assert "sky.exr" in str(e.value)


def test_scene_file_environment(tmp_path):
    px = np.zeros((8, 16, 3), np.float32)
    px[1, 3] = 40.0
    np.save(tmp_path / "sky.npy", px)
    text = """
[render]
width = 8
height = 8
[camera]
position = [0, -4, 3]
look_at = [0, 0, 0]
[environment]
image = "sky.npy"
strength = 2
rotation = [0, 0, 90]
interpolation = "closest"
[[objects]]
type = "plane"
center = [0, 0, 0]
size = 4
"""
    (tmp_path / "s.toml").write_text(text)
    scene, render = load_scene(str(tmp_path / "s.toml"))
    env = scene.environment
    assert env.interpolation == "Closest" and np.allclose(env.strength, 2.0)
    assert np.allclose(env.rotation, euler_rotation((0, 0, math.pi / 2)))
    assert np.allclose(env.pixels.max(), 80.0)
    (tmp_path / "bad.toml").write_text(text.replace('"sky.npy"', '"nope.exr"'))
    with pytest.raises(SceneFileError, match="image: file 'nope.exr' not found"):
        load_scene(str(tmp_path / "bad.toml"))
    (tmp_path / "bad2.toml").write_text(text.replace("strength = 2", "strenght = 2"))
    with pytest.raises(SceneFileError, match="strenght"):
        load_scene(str(tmp_path / "bad2.toml"))


def test_api_set_environment_from_an_array_and_a_file(tmp_path):
    s = top_down_plane(0.5, res=4)
    px = np.full((4, 8, 3), 0.5, np.float32)
    env = s.set_environment(px, strength=2.0, rotation_degrees=(0, 0, 90))
    assert s.environment is env and np.allclose(env.pixels, 1.0)
    assert np.allclose(env.rotation, euler_rotation((0, 0, math.pi / 2)))
    np.save(tmp_path / "sky.npy", px)
    env = s.set_environment(str(tmp_path / "sky.npy"), interpolation="Closest")
    assert env.name.endswith("sky.npy") and env.interpolation == "Closest"
