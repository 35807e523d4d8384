"""A map light's photons read their radiance at the drawn point of its texel
(environment.texel_radiance), not through the direction again (docs/performance.md,
"worldemit54"): the sampling is env_sample's bit for bit, and the radiance is
env_radiance's along the drawn direction up to the direction's round trip's rounding
(Linear, sRGB-stored Linear, rotated maps), the texel itself for Closest."""
import math

import numpy as np
import pytest

from engine.lights.emission import EmissionBuffers
from engine.lights.environment import (Environment, env_radiance, env_sample,
                                       env_sample_texel, texel_radiance)
from test_photon_emission import _light

ROT = np.array([[0.5, -math.sqrt(3) / 2, 0.0], [math.sqrt(3) / 2, 0.5, 0.0], [0.0, 0.0, 1.0]])


def _map(interpolation, srgb=False, rotation=ROT, shape=(7, 12)):
    rng = np.random.default_rng(5)
    px = (rng.random(shape + (3,)) ** 3).astype(np.float32)
    px[2, 5] = 40.0  # a sun
    px[4, :3] = 0.0  # a black patch: weights and texels of 0
    return Environment(px, 1.3, rotation, interpolation, srgb=srgb)


CASES = [("Linear", False, ROT), ("Linear", True, ROT), ("Linear", False, None),
         ("Closest", False, ROT)]


@pytest.mark.parametrize("interp, srgb, rot", CASES)
def test_texel_sampling_is_env_sample_bit_for_bit(interp, srgb, rot):
    env = _map(interp, srgb, rot)
    rows, cols, pdf_uv = env.distribution
    rng = np.random.default_rng(1)
    for u1, u2 in rng.random((3000, 2)):
        got = env_sample_texel(env.rotation, env.pixels, env.interp_code, rows, cols, pdf_uv,
                               u1, u2)
        assert got[:4] == env_sample(env.rotation, env.pixels, env.interp_code, rows, cols,
                                     pdf_uv, u1, u2)
        i, j, fx, fy = got[4:]
        assert 0 <= i < env.height and 0 <= j < env.width and 0 <= fx <= 1 and 0 <= fy <= 1


@pytest.mark.parametrize("interp, srgb, rot", CASES)
def test_texel_radiance_is_the_lookup_along_the_drawn_direction(interp, srgb, rot):
    env = _map(interp, srgb, rot)
    rows, cols, pdf_uv = env.distribution
    rng = np.random.default_rng(2)
    same = n = 0
    for u1, u2 in rng.random((5000, 2)):
        d0, d1, d2, pdf, i, j, fx, fy = env_sample_texel(
            env.rotation, env.pixels, env.interp_code, rows, cols, pdf_uv, u1, u2)
        if not pdf > 0:
            continue
        got = np.array(texel_radiance(env.stored, env.interp_code, env.scale, i, j, fx, fy))
        want = np.array(env_radiance(env.rotation, env.stored, env.interp_code, env.scale,
                                     d0, d1, d2))
        n += 1
        if interp == "Closest":
            np.testing.assert_array_equal(got, env.pixels[i, j])
            same += np.array_equal(got, want)  # but where the round trip left the texel
        else:
            # relative to the texel's scale: a channel near 0 is a sum of cancelling
            # rounding only where a weight is nearly 0
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * want.max())
    assert n > 4000
    if interp == "Closest":
        assert same >= 0.999 * n


@pytest.mark.parametrize("interp", ["Linear", "Closest"])
def test_map_photons_carry_the_radiance_over_the_pdf_of_their_direction(interp):
    """Each photon's power is L / pdf x pi R^2 / count, L and pdf read through its
    direction (Environment.radiance, Environment.pdf) to rounding."""
    light = _light(env=_map(interp))
    env = light.environment
    n = 20_000
    out = EmissionBuffers(n)
    m = light.emit_into(np.uint64(7), 0, n, n, out, 0)
    _, _, d, power, _ = out.head(m)
    w = -d
    want = (env.radiance(w) / env.pdf(w)[:, None]
            * (math.pi * light.scene_radius ** 2 / n))
    ok = np.all(np.isclose(power, want, rtol=1e-8, atol=0.0), axis=1)
    # Closest: a direction on a texel's edge may look up the neighbour (its own texel's
    # value is what was drawn)
    assert ok.mean() >= (0.999 if interp == "Closest" else 1.0)
