"""Images Cycles keeps stored sRGB-encoded (an 8-bit sRGB image, or a float file tagged
sRGB as Blender 5's Image.save() writes): the lookup interpolates the encoded texels and
decodes after (Cycles' svm_image_texture: color_srgb_to_linear_v4 after the
interpolation, no clipping above 1), for the world's Environment Texture
(engine/lights/environment.py) and an Image Texture (engine/textures.py); the map's
sampling stays unbiased (issue 14, newuser32's day room: its sky's horizon band 1.105 of
Cycles when decoded first). Live Cycles: tests/blender/test_srgb_float_cycles.py."""
import math

import numpy as np
import pytest

from engine import Environment
from engine.imageio import srgb_decode, srgb_encode
from engine.textures import ImageTexture
from helpers import sphere_grid


def _direction(theta, u):
    """World direction at polar angle theta and image coordinate u (no rotation)."""
    phi = 2.0 * math.pi * (0.5 - u)
    return np.array([[math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi),
                      math.cos(theta)]])


def test_lookup_interpolates_the_encoded_texels_then_decodes():
    # 2 x 4 map; row 0's first two texels store 0.2 and 5.0 (encoded; 5.0 decodes to 43).
    # Row 0's centre (theta 45 deg), halfway between the two columns' centres (u = 1/4):
    # the interpolated encoded value is 2.6, decoded ((2.6 + 0.055) / 1.055)^2.4 = 9.161,
    # times the strength 2: 18.32 (decoded first: (0.0331 + 42.97) / 2 x 2 = 43.0).
    px = np.full((2, 4, 3), 0.5, np.float32)
    px[0, 0] = 0.2
    px[0, 1] = 5.0
    env = Environment(px, strength=2.0, srgb=True)
    got = env.radiance(_direction(math.pi / 4, 0.25))[0]
    assert got == pytest.approx([2.0 * 9.1611] * 3, rel=1e-4)
    assert got[0] == pytest.approx(2.0 * ((2.6 + 0.055) / 1.055) ** 2.4, rel=1e-5)
    # at a texel's centre both orders agree: the texel decoded, times the strength
    centre = env.radiance(_direction(math.pi / 4, 0.375))[0]
    assert centre[0] == pytest.approx(2.0 * ((5.0 + 0.055) / 1.055) ** 2.4, rel=1e-5)
    # the same texels stored linear (decoded first): the mean of the decoded texels
    lin = Environment(srgb_decode(px), strength=2.0)
    assert lin.radiance(_direction(math.pi / 4, 0.25))[0, 0] == pytest.approx(
        srgb_decode(0.2) + srgb_decode(5.0), rel=1e-5)


def test_closest_lookup_of_an_srgb_map_is_the_decoded_texel():
    px = np.random.default_rng(1).random((4, 8, 3)).astype(np.float32) * 3.0
    env = Environment(px, strength=(1.0, 2.0, 0.5), interpolation="Closest", srgb=True)
    d, _, _ = sphere_grid(16, 32)
    want = Environment(srgb_decode(px), strength=(1.0, 2.0, 0.5), interpolation="Closest")
    assert np.allclose(env.radiance(d), want.radiance(d), rtol=1e-6)


def test_decode_is_cycles_color_srgb_to_linear():
    c = np.array([-0.5, 0.0, 0.02, 0.04045, 0.5, 1.0, 5.7546])
    want = [0.0, 0.0, 0.02 / 12.92, ((0.04045 + 0.055) / 1.055) ** 2.4,
            ((0.5 + 0.055) / 1.055) ** 2.4, 1.0, ((5.7546 + 0.055) / 1.055) ** 2.4]
    assert np.allclose(srgb_decode(c), want, rtol=1e-12, atol=0)
    x = np.array([0.0, 0.001, 0.2, 1.0, 60.0])
    assert np.allclose(srgb_decode(srgb_encode(x)), x, rtol=1e-12, atol=1e-15)


def _sun_sky(h=16, w=32):
    """Encoded (h, w, 3): a gradient sky over a dim ground and a 2 x 2 texel sun of
    encoded 5 (linear 43)."""
    t = np.clip(np.cos((np.arange(h) + 0.5) / h * math.pi), 0.0, None)[:, None, None]
    px = np.broadcast_to(0.3 + 0.5 * t * np.array([0.6, 0.8, 1.0]), (h, w, 3)).copy()
    px[h // 2:] = (0.35, 0.3, 0.25)
    px[4:6, 9:11] = (5.0, 4.8, 4.5)
    return px.astype(np.float32)


def _sphere_integral(env, n=8):
    """RGB integral of env.radiance over the sphere, midpoint rule n x n per texel."""
    d, sin_t, dA = sphere_grid(env.height * n, env.width * n)
    return (env.radiance(d) * sin_t[:, None]).sum(0) * dA


def test_pdf_integrates_to_one_and_matches_the_sampled_pdf():
    env = Environment(_sun_sky(), strength=1.5, srgb=True)
    d, sin_t, dA = sphere_grid(env.height * 8, env.width * 8)
    assert (env.pdf(d) * sin_t).sum() * dA == pytest.approx(1.0, rel=2e-3)
    rng = np.random.default_rng(7)
    wi, pdf = env.sample(rng.random(20_000), rng.random(20_000))
    assert np.allclose(env.pdf(wi), pdf, rtol=1e-9)


def test_map_estimator_is_unbiased_for_an_srgb_map():
    # E[L / pdf] over the map's own samples = the integral of the decoded-after radiance
    # (its distribution follows the decoded texels' interpolation: close, not equal).
    env = Environment(_sun_sky(), strength=1.5, srgb=True)
    want = _sphere_integral(env)
    rng = np.random.default_rng(3)
    n = 400_000
    wi, pdf = env.sample(rng.random(n), rng.random(n))
    est = env.radiance(wi) / pdf[:, None]
    got = est.mean(0)
    err = est.std(0) / math.sqrt(n)
    assert np.all(np.abs(got - want) < 4 * err + 1e-3 * want)
    assert np.all(err < 0.003 * want)   # the distribution follows the radiance closely
    # decoding after is what the lookup does: below the decoded-first integral here
    assert np.all(want < _sphere_integral(Environment(srgb_decode(_sun_sky()), 1.5)))


def test_cosine_estimator_and_photons_are_unbiased_for_an_srgb_map():
    from engine.lights import WorldLight, prepare_lights
    from engine.geometry import prepare
    from helpers import top_down_plane
    env = Environment(_sun_sky(), strength=1.5, srgb=True)
    # irradiance of an upward surface: the integral of L cos+ over the sphere
    d, sin_t, dA = sphere_grid(env.height * 8, env.width * 8)
    want = (env.radiance(d) * (sin_t * np.maximum(d[:, 2], 0.0))[:, None]).sum(0) * dA
    rng = np.random.default_rng(11)
    n = 400_000
    ns = np.array([0.0, 0.0, 1.0])
    wi, pdf = env.cosine_sample(rng.random(n), rng.random(n), ns)
    assert np.allclose(env.cosine_pdf(wi, ns), pdf, rtol=1e-9)
    ok = pdf > 0
    est = np.zeros((n, 3))
    est[ok] = env.radiance(wi[ok]) * np.maximum(wi[ok, 2], 0.0)[:, None] / pdf[ok, None]
    assert np.all(np.abs(est.mean(0) - want) < 4 * est.std(0) / math.sqrt(n) + 1e-3 * want)
    # photons (emit_world: the map's samples, power L / pdf x pi R^2 / count): their
    # total power is the flux of the decoded-after radiance through the disk
    s = top_down_plane(0.5, res=8)
    s.environment = env
    geo, table = prepare(s)
    world = [li for li in prepare_lights(s, geo, table) if isinstance(li, WorldLight)][0]
    R = world.scene_radius
    _, _, power = world.emit(200_000, np.random.default_rng(5))
    assert np.allclose(power.sum(0), _sphere_integral(env) * math.pi * R * R, rtol=0.01)


def test_image_texture_decodes_float_srgb_values_above_one_after_interpolating():
    # a 1 x 2 texture storing encoded 0.2 and 5.0: halfway between the texel centres the
    # lookup reads decode(2.6) = 9.161 (the old clip to [0, 1] gave decode(0.6) = 0.318)
    px = np.array([[[0.2, 0.2, 0.2, 1.0], [5.0, 5.0, 5.0, 1.0]]], np.float32)
    tex = ImageTexture(px, srgb=True, extension="EXTEND")
    got = tex.sample(np.array([[0.5, 0.5]]))[0]
    assert got == pytest.approx([((2.6 + 0.055) / 1.055) ** 2.4] * 3, rel=1e-6)
    # at the texel centres: the decoded texels
    ends = tex.sample(np.array([[0.25, 0.5], [0.75, 0.5]]))[:, 0]
    assert ends == pytest.approx([((0.2 + 0.055) / 1.055) ** 2.4,
                                  ((5.0 + 0.055) / 1.055) ** 2.4], rel=1e-6)


def test_a_pickle_from_before_srgb_maps_looks_up_its_linear_texels():
    import pickle
    env = Environment(np.random.default_rng(2).random((4, 8, 3)), strength=1.7)
    state = dict(env.__dict__)
    for k in ("stored", "scale", "srgb"):
        del state[k]
    old = Environment.__new__(Environment)
    old.__setstate__(state)
    d, _, _ = sphere_grid(8, 16)
    assert np.array_equal(old.radiance(d), env.radiance(d))
    again = pickle.loads(pickle.dumps(Environment(_sun_sky(), srgb=True)))
    assert again.srgb and again.stored is not again.pixels
    assert np.array_equal(again.radiance(d), Environment(_sun_sky(), srgb=True).radiance(d))
