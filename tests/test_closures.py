"""GGX / Fresnel / Lambert closures (engine/closures/): invariants of each closure, no
renders. Numerical integrals use fixed seeds and enough samples for the tolerances."""
import math

import numpy as np
import pytest

from engine.bsdf import fresnel_dielectric as fresnel_np
from engine.closures import diffuse, fresnel, ggx, tables

N = 200_000


def _wo(mu):
    return np.array([math.sqrt(1.0 - mu * mu), 0.0, mu])


def _sphere(n, seed):
    rng = np.random.default_rng(seed)
    z = 1.0 - 2.0 * rng.random(n)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * rng.random(n)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _random_dirs(n, seed, upper=True):
    d = _sphere(n, seed)
    if upper:
        d[:, 2] = np.abs(d[:, 2])
    return d


@pytest.mark.parametrize("alpha", [0.05, 0.3, 1.0])
def test_reflection_reciprocal(alpha):
    wo = _random_dirs(2000, 1)
    wi = _random_dirs(2000, 2)
    e_oi, _, _ = ggx.reflect_eval_np(wo, wi, alpha)
    e_io, _, _ = ggx.reflect_eval_np(wi, wo, alpha)
    # f = eval / cos_i must not depend on which side is the viewer.
    np.testing.assert_allclose(e_oi / wi[:, 2], e_io / wo[:, 2], rtol=1e-10)


@pytest.mark.parametrize("alpha", [0.1, 0.5])
def test_refraction_reciprocal_up_to_eta_squared(alpha):
    """Walter et al.: f_t(wo, wi) / eta_i^2 is symmetric; Cycles' f_t omits the radiance
    1/eta^2 factor, so f_t(o, i) * eta_o^2 ... = f_t(i, o) * eta_i^2 in its convention:
    f(o->i, eta) / f(i->o, 1/eta) = eta^2 (eta = n_i / n_o)."""
    eta = 1.5
    wo = _random_dirs(2000, 3)
    wi = _random_dirs(2000, 4)
    wi[:, 2] = -wi[:, 2]
    _, t_oi, _ = ggx.glass_eval_np(wo, wi, alpha, eta)
    # the same pair seen from the other side: flip both into the frame where the new wo is up
    flip = np.array([1.0, 1.0, -1.0])
    _, t_io, _ = ggx.glass_eval_np(wi * flip, wo * flip, alpha, 1.0 / eta)
    assert np.array_equal(t_oi > 0, t_io > 0)  # the same pairs connect either way
    ok = (t_oi > 1e-6) & (t_io > 1e-6)
    assert ok.sum() > 300
    f_oi = t_oi[ok] / np.abs(wi[ok, 2])
    f_io = t_io[ok] / np.abs(wo[ok, 2])
    np.testing.assert_allclose(f_oi / f_io, eta * eta, rtol=1e-8)


@pytest.mark.parametrize("alpha", [0.1, 0.4, 1.0])
@pytest.mark.parametrize("mu", [0.1, 0.5, 0.95])
def test_reflection_pdf_integrates_and_energy_bounded(alpha, mu):
    """Over the sphere: int pdf = share of samples that stay above the surface (the rest
    are the lobe's lost energy, sampled then refused), and the albedo int eval <= 1 matches
    the sample-weight mean."""
    wi = _sphere(N, 5)
    wo = np.tile(_wo(mu), (N, 1))
    e, p, _ = ggx.reflect_eval_np(wo, wi, alpha)
    int_pdf = p.mean() * 4 * np.pi
    int_e = e.mean() * 4 * np.pi
    rng = np.random.default_rng(6)
    _, w, pdf, _ = ggx.reflect_sample_np(wo, alpha, rng.random(N), rng.random(N))
    valid = (w > 0).mean()
    assert int_pdf == pytest.approx(valid, abs=0.02)
    assert int_e <= 1.0 + 0.02
    assert w.mean() <= 1.0
    assert int_e == pytest.approx(w.mean(), abs=0.02)


@pytest.mark.parametrize("eta", [1.5, 1 / 1.5, 2.4])
@pytest.mark.parametrize("alpha", [0.1, 0.5])
def test_glass_sampling_matches_eval(eta, alpha):
    """Sampled weights equal eval / pdf; int pdf over the sphere = share of valid samples;
    glass never makes energy."""
    rng = np.random.default_rng(7)
    n = 50_000
    wo = np.tile(_wo(0.6), (n, 1))
    wi, w, pdf, refr = ggx.glass_sample_np(wo, alpha, eta, rng.random(n), rng.random(n),
                                           rng.random(n))
    er, et, p = ggx.glass_eval_np(wo, wi, alpha, eta)
    ok = w > 0
    np.testing.assert_allclose((er + et)[ok] / p[ok], w[ok], rtol=1e-8)
    np.testing.assert_allclose(p[ok], pdf[ok], rtol=1e-8)
    assert np.all(refr[ok] == (wi[ok, 2] < 0))
    wi = _sphere(N, 8)
    wo = np.tile(_wo(0.6), (N, 1))
    er, et, p = ggx.glass_eval_np(wo, wi, alpha, eta)
    assert p.mean() * 4 * np.pi == pytest.approx(ok.mean(), abs=0.03)
    assert (er + et).mean() * 4 * np.pi <= 1.0 + 0.02


def test_smooth_lobes_are_mirrors():
    wo = np.tile(_wo(0.6), (4, 1))
    wi, w, pdf, _ = ggx.reflect_sample_np(wo, 0.0, np.full(4, 0.3), np.full(4, 0.7))
    np.testing.assert_allclose(wi, wo * [-1, -1, 1])
    assert np.all(w == 1) and np.all(np.isinf(pdf))
    F = fresnel.fresnel_dielectric(0.6, 1.5)
    wi, w, pdf, refr = ggx.glass_sample_np(wo, 0.0, 1.5, 0.5, 0.5, np.array([0.0, 0.99, F - 1e-9,
                                                                            F + 1e-9]))
    assert list(refr) == [False, True, False, True]
    sin_t = 0.8 / 1.5
    np.testing.assert_allclose(wi[1], [-sin_t, 0.0, -math.sqrt(1 - sin_t ** 2)], atol=1e-12)


@pytest.mark.parametrize("rough", [0.2, 0.5, 0.8, 1.0])
@pytest.mark.parametrize("mu", [0.1, 0.4, 0.9])
def test_white_furnace_compensated_reflection(rough, mu):
    """Cycles' energy compensation: a white GGX lobe scaled by 1 / E(mu) reflects all light
    (albedo 1 within the tables' interpolation error), at every roughness."""
    rng = np.random.default_rng(9)
    wo = np.tile(_wo(mu), (N, 1))
    _, w, _, _ = ggx.reflect_sample_np(wo, rough * rough, rng.random(N), rng.random(N))
    scale = ggx.energy_factor(tables.ggx_E(rough, mu), tables.ggx_Eavg(rough), 1.0)
    assert w.mean() * scale == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize("rough", [0.3, 0.7, 1.0])
@pytest.mark.parametrize("eta", [1.1, 1.5, 2.4, 1 / 1.5])
def test_white_furnace_compensated_glass(rough, eta):
    rng = np.random.default_rng(10)
    mu = 0.7
    wo = np.tile(_wo(mu), (N, 1))
    _, w, _, _ = ggx.glass_sample_np(wo, rough * rough, eta, rng.random(N), rng.random(N),
                                     rng.random(N))
    E, E_avg = tables.glass_E(rough, mu, eta)
    assert w.mean() / E == pytest.approx(1.0, abs=0.015)


def test_compensation_saturates_coloured_fresnel():
    """Kulla & Conty: a coloured Fresnel gains less than 1/E (its multiple bounces lose
    energy again); white gains exactly 1/E; with no lost energy nothing changes."""
    E, Eavg = 0.6, 0.7
    assert ggx.energy_factor(E, Eavg, 1.0) == pytest.approx(1.0 / E)
    assert 1.0 < ggx.energy_factor(E, Eavg, 0.5) < 1.0 / E
    assert ggx.energy_factor(1.0, 1.0, 0.3) == pytest.approx(1.0)


def test_fresnel_dielectric_matches_numpy_stage():
    cos = np.linspace(0.0, 1.0, 41)
    for eta in (1.33, 1.5, 1 / 1.5, 2.4):
        ref = fresnel_np(cos, np.full_like(cos, eta))
        got = np.array([fresnel.fresnel_dielectric(c, eta) for c in cos])
        np.testing.assert_allclose(got, ref, atol=1e-12)


@pytest.mark.parametrize("eta", [1.1, 1.5, 2.4])
def test_fresnel_average_fit(eta):
    """Kulla & Conty's fit of 2 int F(mu) mu dmu, within 1 % absolute of the integral."""
    mu = (np.arange(20000) + 0.5) / 20000
    F = np.array([fresnel.fresnel_dielectric(m, eta) for m in mu])
    assert fresnel.fresnel_dielectric_Fss(eta) == pytest.approx((2 * F * mu).mean(), abs=0.01)


def test_f82_tint_hits_its_target_at_82_degrees():
    f0, tint = 0.9, 0.4
    b = fresnel.f82_tint_B(f0, tint)
    cos82 = 1.0 / 7.0
    schlick = f0 + (1 - f0) * (1 - cos82) ** 5
    assert fresnel.fresnel_f82(cos82, f0, b) == pytest.approx(schlick * tint)
    assert fresnel.fresnel_f82(1.0, f0, b) == pytest.approx(f0)
    assert fresnel.fresnel_f82(0.0, f0, b) == pytest.approx(1.0)
    assert fresnel.f82_tint_B(f0, 1.0) == 0.0
    mu = (np.arange(20000) + 0.5) / 20000
    F = np.array([fresnel.fresnel_f82(m, f0, b) for m in mu])
    assert fresnel.f82_Fss(f0, b) == pytest.approx((2 * F * mu).mean(), abs=2e-3)


def test_lambert():
    e, p = diffuse.lambert_eval(0.5, 0.3)
    assert e == pytest.approx(0.3 / math.pi) and p == pytest.approx(0.3 / math.pi)
    assert diffuse.lambert_eval(0.5, -0.3) == (0.0, 0.0)
    x, y, z, w, pdf = diffuse.lambert_sample(0.25, 0.1)
    assert x * x + y * y + z * z == pytest.approx(1.0) and w == 1.0
    assert pdf == pytest.approx(z / math.pi)
