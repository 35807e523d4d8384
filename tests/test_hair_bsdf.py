"""Principled Hair BSDF parameters and the fibre albedo (engine/hairbsdf.py).

The parametrizations against Cycles' formulas written out here (kernel/svm/closure.h
and kernel/closure/bsdf_util.h); the lobe energies' sum against a numerical integral
over the sphere of the Chiang lobes as Cycles evaluates them
(bsdf_principled_hair_chiang.h: longitudinal_scattering, azimuthal_scattering)."""
import math

import numpy as np
import pytest
from scipy.special import i0e

from engine import hairbsdf as hb


def cycles_scale(x):
    return (((((0.245 * x) + 5.574) * x - 10.73) * x + 2.532) * x - 0.215) * x + 5.969


def test_direct_coloring_sigma_is_cycles_sigma_from_reflectance():
    colour = np.array([0.8, 0.1, 0.05])
    for beta in (0.0, 0.3, 0.7, 1.0):
        want = (np.log(colour) / cycles_scale(beta)) ** 2
        np.testing.assert_allclose(hb.sigma_from_reflectance(colour, beta), want, rtol=1e-12)
    # The node's default colour at the default radial roughness 0.3.
    np.testing.assert_allclose(
        hb.sigma_from_reflectance((0.017513, 0.005763, 0.002059), 0.3),
        (np.log([0.017513, 0.005763, 0.002059]) / 5.969 ** 0 / cycles_scale(0.3)) ** 2)
    assert np.all(hb.sigma_from_reflectance(np.ones(3), 0.3) == 0.0)
    assert np.all(np.isinf(hb.sigma_from_reflectance(np.zeros(3), 0.3)))


def test_melanin_sigma_is_cycles_concentration_mapping():
    eu_c = np.array([0.506, 0.841, 1.653])
    pheo_c = np.array([0.343, 0.733, 1.924])
    for m, r in ((0.5, 0.5), (0.8, 1.0), (0.2, 0.0), (0.99995, 0.3)):
        conc = -math.log(max(1.0 - m, 1e-4))
        want = conc * (1 - r) * eu_c + conc * r * pheo_c
        np.testing.assert_allclose(hb.sigma_from_melanin(m, r, np.ones(3), 0.3), want,
                                   rtol=1e-12)
    # Tint adds its sigma_from_reflectance; Random Color scales melanin by
    # 1 + 2 (random - 0.5) Random Color (clamped to 0..1).
    tint = np.array([0.9, 0.5, 0.5])
    np.testing.assert_allclose(
        hb.sigma_from_melanin(0.4, 0.2, tint, 0.5, random=0.9, random_color=1.5),
        -math.log(1 - 0.4 * 1.8) * (0.8 * eu_c + 0.2 * pheo_c)
        + (np.log(tint) / cycles_scale(0.5)) ** 2, rtol=1e-12)
    # Per-hit arrays broadcast: (N,) melanin and random, (N, 3) tint.
    s = hb.sigma_from_melanin(np.array([0.3, 0.6]), 0.5, np.ones((2, 3)), 0.3,
                              random=np.array([0.0, 1.0]), random_color=0.5)
    assert s.shape == (2, 3)
    np.testing.assert_allclose(s[1], hb.sigma_from_melanin(0.9, 0.5, np.ones(3), 0.3))


def _mp(sin_i, cos_i, sin_o, cos_o, v):
    """Cycles' longitudinal_scattering (d'Eon et al. 2011), in logs for any v."""
    a = cos_i * cos_o / v
    log_i0 = np.log(i0e(a)) + a
    return np.exp(log_i0 - sin_i * sin_o / v - 1.0 / v - np.log(v)
                  - np.log1p(-np.exp(-2.0 / v)))


def _np(phi, p, s, gamma_o, gamma_t):
    """Cycles' azimuthal_scattering: the trimmed logistic about delta_phi."""
    x = np.mod(phi - (2 * p * gamma_t - 2 * gamma_o + p * np.pi) + np.pi, 2 * np.pi) - np.pi
    e = np.exp(-np.abs(x) / s)
    logistic = e / (s * (1 + e) ** 2)

    def cdf(y):
        return 1.0 / (1.0 + np.exp(-y / s))
    return logistic / (cdf(np.pi) - cdf(-np.pi))


@pytest.mark.parametrize("beta,beta_n", [(0.3, 0.3), (0.15, 0.6), (0.6, 0.2)])
def test_lobe_energies_are_the_integral_of_the_chiang_lobes(beta, beta_n):
    """For a fixed view (theta_o, h), the integral over all directions of Cycles' Chiang
    eval (sum of A_p M_p N_p, f |cos theta_i| already) equals the sum of the lobe
    energies that fibre_albedo averages: every lobe's M_p N_p integrates to 1."""
    eta = 1.55
    sigma = np.array([0.05, 0.4, 2.0])
    v = (0.726 * beta + 0.812 * beta ** 2 + 3.7 * beta ** 20) ** 2
    s = (0.265 * beta_n + 1.194 * beta_n ** 2 + 5.372 * beta_n ** 22) * math.sqrt(np.pi / 8)
    th = np.linspace(-np.pi / 2, np.pi / 2, 601)
    ph = np.linspace(-np.pi, np.pi, 801)
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    sin_i, cos_i = np.sin(TH), np.cos(TH)
    for theta_o, h in ((0.0, 0.0), (0.5, 0.6), (-1.0, -0.3)):
        sin_o, cos_o = math.sin(theta_o), math.cos(theta_o)
        f, tt, trt, rest = hb.lobe_energies(sigma, h, sin_o, eta)
        gamma_o = math.asin(h)
        gamma_t = math.asin(h * cos_o / math.sqrt(eta ** 2 - sin_o ** 2))
        total = np.zeros(3)
        for p, ap, vp in ((0, np.full(3, float(f)), v), (1, tt, 0.25 * v), (2, trt, 4 * v)):
            lobe = _mp(sin_i, cos_i, sin_o, cos_o, vp) * _np(PH, p, s, gamma_o, gamma_t)
            total += ap * np.trapz(np.trapz(lobe * cos_i, ph, axis=1), th)
        res = _mp(sin_i, cos_i, sin_o, cos_o, 4 * v) / (2 * np.pi)
        total += rest * np.trapz(np.trapz(res * cos_i, ph, axis=1), th)
        want = f + tt + trt + rest
        np.testing.assert_allclose(total, want, rtol=0.01)
        # Cycles' closed form of the sum (bsdf_principled_hair_albedo's comment).
        T = np.exp(-sigma * 2 * math.cos(gamma_t) / math.sqrt(1 - (sin_o / eta) ** 2))
        np.testing.assert_allclose(want, (T * (1 - 2 * f) + f) / (1 - f * T), rtol=1e-9)


def test_fibre_albedo_is_the_average_over_width_and_directions():
    """fibre_albedo's quadrature against a fine midpoint sum of the lobe energies over
    h in 0..1 and sin theta in 0..1 weighted by cos theta; clear hair scatters all it
    intercepts, opaque hair only its R lobe (~0.099 at IOR 1.55)."""
    sigma = np.array([0.0, 0.3, 1.5])
    x = (np.arange(400) + 0.5) / 400
    H, S = np.meshgrid(x, x, indexing="ij")
    f, tt, trt, rest = hb.lobe_energies(sigma, H, S)
    w = np.sqrt(1 - S * S)[..., None]
    want = ((f[..., None] + tt + trt + rest) * w).sum(axis=(0, 1)) / w.sum()
    total, a_r, a_tt, a_trt, a_res = hb.fibre_albedo(sigma)
    np.testing.assert_allclose(total, want, rtol=2e-3)
    np.testing.assert_allclose(total, a_r + a_tt + a_trt + a_res)
    assert total[0] == pytest.approx(1.0, abs=1e-9)
    opaque = hb.fibre_albedo(np.full(3, np.inf))[0]
    np.testing.assert_allclose(opaque, a_r)
    assert 0.09 < a_r < 0.11


def _two_walls(r, tau):
    """Back and forward shares of two equal walls in series (the slab formula)."""
    return r + tau ** 2 * r / (1 - r ** 2), tau ** 2 / (1 - r ** 2)


@pytest.mark.parametrize("sigma", [[0.0, 0.0, 0.0], [0.05, 0.3, 1.2], [0.7, 1.3, 2.8],
                                   [2.0, 5.0, np.inf], [0.01, 0.02, 0.03]])
def test_tube_walls_scatter_back_and_forward_what_the_fibre_does(sigma):
    """The material (alpha, tint, diffuse base, specular albedo E) gives the tube's two
    walls the fibre's forward share exactly and its back share where the walls can (a
    wall reflects at least the R lobe, alpha E = A_R: the lit side then reflects
    A_R (1 + T)); a wall reflects alpha (E + (1 - E) rho) and passes (1 - alpha) tint.
    Nearly clear hair, whose wall cannot be that opaque and pass tau, passes a little
    less (clear: 0.820 for 0.829)."""
    sigma = np.array(sigma)
    a_r, back, fwd = hb.back_and_forward(sigma)
    total = hb.fibre_albedo(np.where(np.isinf(sigma), 1e30, sigma))[0]
    np.testing.assert_allclose(back + fwd, total, atol=2e-3)
    alpha, tint, rho, spec = hb.surface(sigma)
    assert 0.0 < alpha <= 1.0 and np.all((0 <= tint) & (tint <= 1))
    assert alpha * spec == pytest.approx(a_r)
    r = alpha * (spec + (1 - spec) * rho)
    tau = (1 - alpha) * tint
    b2, f2 = _two_walls(r, tau)
    exact = 1.0 - np.max(hb.wall(sigma)[1]) >= a_r
    np.testing.assert_allclose(f2, fwd, atol=1e-3 if exact else 0.01)
    np.testing.assert_allclose(b2, np.maximum(back, a_r * (1 + fwd)), atol=1e-3)
    # The highlight keeps the share alpha: the most opaque wall the colour allows.
    assert np.max(tau) == pytest.approx(1 - alpha) or not exact


def test_specular_level_gives_the_tube_its_r_lobe():
    """specular_level(E): F0 x 2 level is the F0 of an IOR whose tube-averaged Fresnel
    is E (level 0.5 at the layer's own IOR's albedo)."""
    e0 = hb.tube_fresnel(1.55)
    assert hb.specular_level(e0, 1.55) == pytest.approx(0.5, rel=1e-3)
    f0 = ((1.55 - 1) / 2.55) ** 2
    for e in (0.15, 0.3, 0.6):
        level = hb.specular_level(e, 1.55)
        f0_new = 2 * level * f0
        eta = (1 + math.sqrt(f0_new)) / (1 - math.sqrt(f0_new))
        assert hb.tube_fresnel(eta) == pytest.approx(e, rel=2e-3)


def test_back_and_forward_shares():
    """Clear hair scatters everything; opaque hair only reflects its R lobe; Huang's
    lobe factors scale their lobes (the residual goes with TRT)."""
    a_r, back, fwd = hb.back_and_forward(np.zeros(3))
    np.testing.assert_allclose(back + fwd, 1.0, atol=2e-3)
    a_r2, back2, fwd2 = hb.back_and_forward(np.full(3, np.inf))
    np.testing.assert_allclose(back2, a_r) and np.testing.assert_allclose(fwd2, 0.0)
    sigma = np.array([0.2, 0.6, 1.5])
    _, a_r, a_tt, a_trt, a_res = hb.fibre_albedo(sigma)
    r, b, f = hb.back_and_forward(sigma, r_weight=0.5, tt_weight=2.0, trt_weight=0.0)
    assert r == pytest.approx(0.5 * a_r)
    np.testing.assert_allclose(b, 0.5 * a_r, atol=1e-9)
    np.testing.assert_allclose(f, 2.0 * a_tt, rtol=2e-3)


def test_hair_material_per_hit_follows_the_strands_random():
    """HairColor per hit: Melanin randomised by each strand's Random (a node here), and
    Random Roughness through the Direct Coloring's radial roughness, as Cycles; outputs
    the diffuse base, the opaque share and the Specular IOR Level of `surface`."""
    class Random:
        def evaluate(self, geo, prim, u, v):
            return np.array([0.0, 0.5, 1.0])
    prim, u = np.zeros(3, np.int64), np.zeros(3)
    args = ("MELANIN", None, 0.5, 0.3, np.ones(3), None, 0.3, 0.0, Random(), 0.6, 1.55)
    alpha = hb.HairColor(*args, output="ALPHA").evaluate(None, prim, u, u)
    level = hb.HairColor(*args, output="LEVEL").evaluate(None, prim, u, u)
    rho = hb.HairColor(*args).evaluate(None, prim, u, u)
    assert alpha.shape == level.shape == (3,) and rho.shape == (3, 3)
    for k, r in enumerate((0.0, 0.5, 1.0)):
        a, _, want_rho, spec = hb.surface(hb.sigma_from_melanin(0.5, 0.3, np.ones(3), 0.3,
                                                                r, 0.6))
        assert alpha[k] == pytest.approx(float(a))
        assert level[k] == pytest.approx(float(hb.specular_level(spec)))
        np.testing.assert_allclose(rho[k], want_rho)
    # More melanin, less passes: the darker strands are the more opaque.
    assert alpha[0] < alpha[1] < alpha[2]
    node = hb.HairColor("COLOR", np.array([0.5, 0.2, 0.1]), 0.8, 1.0, np.ones(3), None,
                        0.4, 0.5, Random(), 0.0, 1.55, output="ALPHA")
    got = node.evaluate(None, prim, u, u)
    want = hb.surface(hb.sigma_from_reflectance([0.5, 0.2, 0.1], 0.4 * 1.5))[0]
    assert got[2] == pytest.approx(float(want))
    node = hb.HairColor("ABSORPTION", None, 0.8, 1.0, np.ones(3), np.array([0.2, 0.5, 1.0]),
                        0.3, 0.0, 0.0, 0.0, 1.55)
    np.testing.assert_allclose(node.evaluate(None, prim[:1], u[:1], u[:1])[0],
                               hb.surface(np.array([0.2, 0.5, 1.0]))[2])
    with pytest.raises(ValueError):
        hb.HairColor("PIGMENT", None, 0, 0, 0, 0, 0, 0, 0, 0, 1.55)


def test_specular_roughness_holds_the_r_lobes_share_within_its_half_width():
    """GGX of the returned roughness puts 76 % of its half vectors (a Gaussian's share
    within its HWHM) within half the R lobe's HWHM, 1.1774 x Cycles' longitudinal
    standard deviation; 0 stays a mirror, rougher hair a rougher layer."""
    beta = np.array([0.0, 0.1, 0.3, 0.5])
    r = hb.specular_roughness(beta)
    alpha = r * r
    t = np.tan(0.5 * 1.1774 * (0.726 * beta + 0.812 * beta ** 2 + 3.7 * beta ** 20))
    share = t[1:] ** 2 / (alpha[1:] ** 2 + t[1:] ** 2)
    np.testing.assert_allclose(share, math.erf(1.1774 / math.sqrt(2)), rtol=1e-3)
    assert r[0] == 0.0 and np.all(np.diff(r) > 0) and hb.specular_roughness(1.0) < 1.0
    np.testing.assert_allclose(hb.specular_roughness([0.2, 0.3, 0.5]), [0.2, 0.3, 0.5],
                               atol=0.065)


class _CountingRandom:
    """A Random input that counts its evaluations (module level: pickled)."""
    calls = 0

    def evaluate(self, geo, prim, u, v):
        _CountingRandom.calls += 1
        return np.linspace(0.0, 1.0, len(prim))


def test_the_nodes_three_outputs_share_one_evaluation_of_a_batch():
    """The material's texture (COLOR), alpha texture (ALPHA) and Specular IOR Level
    (LEVEL) are one node (HairColor.with_output): the shading of a batch of hits asks
    each in turn, with fresh arrays of the same hits; sigma_a and `surface` run once for
    the three (they were three: half a hair render's time), per thread, and the values
    are those of separate nodes."""
    import pickle
    import threading

    from engine.shadernodes import ShadingGeometry

    Random = _CountingRandom
    Random.calls = 0
    args = ("MELANIN", None, 0.5, 0.3, np.ones(3), None, 0.3, 0.2, Random(), 0.6, 1.55)
    colour = hb.HairColor(*args)
    nodes = [colour, colour.with_output("ALPHA"), colour.with_output("LEVEL")]
    prim, u, v = np.arange(5), np.linspace(0.1, 0.5, 5), np.full(5, 0.2)
    n = np.tile([0.0, 0.0, 1.0], (5, 1))

    def view(wi_z=1.0):  # a batch's view, built anew as the shading does (rows(sel))
        return ShadingGeometry(None, n.copy(), np.tile([0.0, 0.6, wi_z], (5, 1)),
                               np.zeros(5, bool))
    got = [node.evaluate(view(), prim.copy(), u.copy(), v.copy()) for node in nodes]
    assert Random.calls == 1
    for node, value in zip(nodes, got):
        alone = hb.HairColor(*args, output=node.output).evaluate(view(), prim, u, v)
        np.testing.assert_array_equal(value, alone)
    Random.calls = 0
    nodes[1].evaluate(view(), prim, u + 0.1, v)  # other hits: evaluated
    nodes[2].evaluate(view(0.8), prim, u + 0.1, v)  # seen from elsewhere: evaluated
    nodes[0].evaluate(view(0.8), prim, u + 0.1, v)  # the same again: kept
    assert Random.calls == 2
    # Another thread shades its own batches: its first ask is its own evaluation.
    thread = threading.Thread(target=nodes[0].evaluate, args=(view(0.8), prim, u + 0.1, v))
    thread.start()
    thread.join()
    assert Random.calls == 3
    # A scene sent to a worker (pickled): the outputs still share, nothing carried over.
    copies = pickle.loads(pickle.dumps(nodes))
    Random.calls = 0
    for node in copies:
        node.evaluate(view(), prim, u, v)
    assert copies[0]._last is copies[1]._last and Random.calls == 1
    with pytest.raises(ValueError):
        colour.with_output("TINT")
