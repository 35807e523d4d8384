"""Anisotropic GGX (engine/closures/ggx.py, *_aniso): the isotropic case, eval / sample /
pdf consistency, reciprocity and energy (Heitz 2014 / 2018; Cycles' bsdf_microfacet.h)."""
import numpy as np
import pytest

from engine.closures import ggx, tables


def _dirs(theta, phi):
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=-1)


def _uniform_hemisphere(n, rng):
    z = rng.random(n)
    phi = 2.0 * np.pi * rng.random(n)
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def test_isotropic_case_is_the_isotropic_lobe():
    rng = np.random.default_rng(1)
    n = 2000
    wo = _uniform_hemisphere(n, rng)
    wi = _uniform_hemisphere(n, rng)
    for a in (0.05, 0.3, 0.8):
        e0, p0, c0 = ggx.reflect_eval_np(wo, wi, a)
        e1, p1, c1 = ggx.reflect_eval_aniso_np(wo, wi, a, a)
        np.testing.assert_allclose(e1, e0, rtol=1e-10, atol=0)
        np.testing.assert_allclose(p1, p0, rtol=1e-10, atol=0)
        u1, u2 = rng.random(n), rng.random(n)
        d0, w0, q0, _ = ggx.reflect_sample_np(wo, a, u1, u2)
        d1, w1, q1, _ = ggx.reflect_sample_aniso_np(wo, a, a, u1, u2)
        np.testing.assert_allclose(d1, d0, atol=1e-12)
        np.testing.assert_allclose(w1, w0, rtol=1e-10)


@pytest.mark.parametrize("ax, ay, theta_o, phi_o", [(0.4, 0.08, 0.6, 0.3),
                                                    (0.05, 0.5, 1.2, 2.0),
                                                    (0.9, 0.3, 0.2, -1.0)])
def test_sampled_histogram_matches_pdf(ax, ay, theta_o, phi_o):
    """Sampled directions binned in (cos theta, phi) cells against the pdf integrated over
    each cell (midpoint rule on a fine sub-grid): within 3 sigma + 1e-3 of the total."""
    rng = np.random.default_rng(7)
    n = 400_000
    wo = np.tile(_dirs(np.array(theta_o), np.array(phi_o)), (n, 1))
    wi, w, pdf, _ = ggx.reflect_sample_aniso_np(wo, ax, ay, rng.random(n), rng.random(n))
    ok = w > 0
    nz, nphi = 12, 24
    cz = np.clip((wi[ok, 2] * nz).astype(int), 0, nz - 1)
    cp = ((np.arctan2(wi[ok, 1], wi[ok, 0]) % (2 * np.pi)) / (2 * np.pi) * nphi).astype(int)
    hist = np.bincount(cz * nphi + np.clip(cp, 0, nphi - 1), minlength=nz * nphi) / n
    # the pdf integrated per cell: solid angle = d(cos theta) d(phi)
    sub = 16
    z = (np.arange(nz * sub) + 0.5) / (nz * sub)
    ph = (np.arange(nphi * sub) + 0.5) / (nphi * sub) * 2 * np.pi
    Z, P = np.meshgrid(z, ph, indexing="ij")
    r = np.sqrt(1 - Z ** 2)
    wgrid = np.stack([r * np.cos(P), r * np.sin(P), Z], -1).reshape(-1, 3)
    _, p, _ = ggx.reflect_eval_aniso_np(np.tile(wo[:1], (len(wgrid), 1)), wgrid, ax, ay)
    cell = (1.0 / (nz * sub)) * (2 * np.pi / (nphi * sub))
    expect = (p * cell).reshape(nz, sub, nphi, sub).sum(axis=(1, 3)).reshape(-1)
    sigma = np.sqrt(expect / n)
    assert np.all(np.abs(hist - expect) < 4 * sigma + 2e-3), np.max(np.abs(hist - expect))
    # the pdf integrates to the share of samples above the horizon (the rest are lost)
    assert abs(expect.sum() - ok.mean()) < 3e-3
    # sample weight = eval / pdf
    e, p2, _ = ggx.reflect_eval_aniso_np(wo[ok][:2000], wi[ok][:2000], ax, ay)
    np.testing.assert_allclose(pdf[ok][:2000], p2, rtol=1e-9)
    np.testing.assert_allclose(w[ok][:2000], e / p2, rtol=1e-9)


def test_reciprocity():
    rng = np.random.default_rng(3)
    n = 5000
    wo = _uniform_hemisphere(n, rng)
    wi = _uniform_hemisphere(n, rng)
    e_oi, _, _ = ggx.reflect_eval_aniso_np(wo, wi, 0.5, 0.1)
    e_io, _, _ = ggx.reflect_eval_aniso_np(wi, wo, 0.5, 0.1)
    # eval holds f cos(wi): f(wo, wi) = f(wi, wo)
    np.testing.assert_allclose(e_oi / wi[:, 2], e_io / wo[:, 2], rtol=1e-9)


def test_stretch_direction():
    """alpha_x > alpha_y spreads the lobe along x (the tangent): at the same angle off the
    mirror direction the BSDF is larger towards +-x than towards +-y."""
    wo = np.array([[0.0, 0.0, 1.0]])
    off = 0.3
    tx = _dirs(np.array([off]), np.array([0.0]))
    ty = _dirs(np.array([off]), np.array([np.pi / 2]))
    ex, _, _ = ggx.reflect_eval_aniso_np(wo, tx, 0.4, 0.1)
    ey, _, _ = ggx.reflect_eval_aniso_np(wo, ty, 0.4, 0.1)
    assert ex[0] > 5 * ey[0]


@pytest.mark.parametrize("r, aniso", [(0.3, 0.8), (0.5, 0.5), (0.7, 1.0)])
def test_white_furnace(r, aniso):
    """The lobe's directional albedo E (mean sample weight, F = 1) is <= 1, and Cycles'
    compensation 1 / E_iso (the isotropic table at sqrt(sqrt(alpha_x alpha_y)) = the
    roughness, microfacet_ggx_preserve_energy) brings it within 6 % of 1 up to
    Anisotropic 0.8: the anisotropic lobe loses about what the isotropic one of the same
    roughness loses. (At Anisotropic 1, roughness 0.7 - alpha_x clamped to 1 - Cycles'
    compensation leaves 0.67..0.93: measured, docs/performance.md `aniso`.)"""
    aspect = np.sqrt(1 - 0.9 * aniso)
    a = r * r
    ax, ay = min(a / aspect, 1.0), a * aspect
    rough = np.sqrt(np.sqrt(ax * ay))
    rng = np.random.default_rng(11)
    n = 200_000
    for mu in (0.3, 0.7, 0.95):
        for phi in (0.0, 0.8):
            wo = np.tile(_dirs(np.array(np.arccos(mu)), np.array(phi)), (n, 1))
            _, w, _, _ = ggx.reflect_sample_aniso_np(wo, ax, ay, rng.random(n), rng.random(n))
            E = w.mean()
            assert E <= 1.0 + 3e-3
            comp = E / tables.ggx_E(rough, mu)
            if aniso <= 0.8:
                assert abs(comp - 1.0) < 0.06, (mu, phi, E, comp)
