"""Cycles' Filter Glossy on window glass (engine/blurredpassage.py, docs/compatibility.md
"fgslab49"): the stored table of T_blur / T_sharp, its Monte Carlo against an independent
estimate of one rough interface, and shadow rays through a slab at Filter Glossy 1."""
import math

import numpy as np
import pytest

from engine import blurredpassage as bp
from engine.filterglossy import blur_alpha


def _interface_independent(cos_o, alpha, eta, n=200_000, seed=7):
    """The energy one single-scattering GGX dielectric interface (Cycles' microfacet
    glass, no energy compensation) refracts from a direction at cos_o: microfacet normals
    drawn from D(h) cos_h (not the visible normals the engine samples), each refracting
    with (1 - F(o.h)) and weighted by G2 |o.h| / (cos_o cos_h) (Walter et al. 2007 with
    Smith's height-correlated G2 = 1 / (1 + Lambda_o + Lambda_i))."""
    rng = np.random.default_rng(seed)
    u1, u2 = rng.random(n), rng.random(n)
    a2 = alpha * alpha
    tan2 = a2 * u1 / (1.0 - u1)
    ch = 1.0 / np.sqrt(1.0 + tan2)
    sh = np.sqrt(1.0 - ch * ch)
    ph = 2.0 * math.pi * u2
    h = np.stack([sh * np.cos(ph), sh * np.sin(ph), ch], axis=1)
    o = np.array([math.sqrt(1.0 - cos_o * cos_o), 0.0, cos_o])
    c = h @ o
    ok = c > 0.0
    g = eta * eta - 1.0 + c * c
    sg = np.sqrt(np.maximum(g, 0.0))
    A = (sg - c) / (sg + c)
    B = (c * (sg + c) - 1.0) / (c * (sg - c) + 1.0)
    F = np.where(g > 0.0, 0.5 * A * A * (1.0 + B * B), 1.0)
    # refract -o through h
    k = c / eta - np.sqrt(np.maximum(1.0 - (1.0 - c * c) / (eta * eta), 0.0))
    wi = -o[None, :] / eta + k[:, None] * h
    ok &= (wi[:, 2] < 0.0) & (g > 0.0) & ((wi * h).sum(axis=1) < 0.0)

    def lam(z):
        t2 = np.maximum(1.0 / (z * z) - 1.0, 0.0)
        return 0.5 * (np.sqrt(1.0 + a2 * t2) - 1.0)

    G2 = 1.0 / (1.0 + lam(cos_o) + lam(np.abs(wi[:, 2])))
    w = np.where(ok, (1.0 - F) * G2 * np.abs(c) / (cos_o * ch), 0.0)
    return float(w.mean())


@pytest.mark.parametrize("cos_o,alpha", [(1.0, 0.2), (0.8, 0.41), (0.5, 0.45), (0.3, 0.5)])
def test_one_rough_interface_matches_an_independent_estimate(cos_o, alpha):
    ours = bp.slab_mc(cos_o, alpha, 1.5, n=100_000, seed=3, update_pdf=False,
                      interfaces=1)
    ref = _interface_independent(cos_o, alpha, 1.5)
    assert ours == pytest.approx(ref, rel=0.01)
    assert ours < 1.0 - bp._fresnel(np.array(cos_o), 1.5)  # single scattering loses light


def test_table_is_one_without_blur_and_falls_with_alpha():
    tab = bp.table()
    assert tab.shape == (len(bp.IOR), len(bp.COS), len(bp.ALPHA))
    assert np.all(tab[:, :, 0] == 1.0)
    c = np.linspace(0.05, 1.0, 17)
    assert np.all(bp.factor_lookup(c, np.zeros_like(c), np.full_like(c, 1.5)) == 1.0)
    # Falling with alpha from cos 0.15 on; nearer grazing a rough interface lets more
    # through than the smooth one's Fresnel (up to 1.57x at cos 0.05, where little light
    # arrives).
    steep = bp.COS >= 0.15 - 1e-9
    assert np.all(np.diff(tab[:, steep, :], axis=2) < 0.0)
    assert np.all((tab[:, steep] > 0.15) & (tab[:, steep] <= 1.0))


@pytest.mark.parametrize("cos_in,alpha,ior", [(1.0, 0.4, 1.5), (0.7, 0.45, 1.5),
                                              (0.55, 0.3, 1.33)])
def test_table_reads_the_slab_monte_carlo(cos_in, alpha, ior):
    """Between grid points (trilinear) against a fresh Monte Carlo there (another
    seed)."""
    mc = bp.slab_mc(cos_in, alpha, ior, n=60_000, seed=11) / float(bp.sharp_slab(cos_in, ior))
    assert float(bp.factor_lookup(cos_in, alpha, ior)) == pytest.approx(mc, rel=0.02)


def test_shadow_ray_through_slab_takes_the_factor_at_filter_glossy_1():
    """A floor under a 1 cm slab and a sun at 30 degrees: at Filter Glossy 1 its direct
    light is the smooth slab's times factor_lookup at the sun's cosine and the blur of the
    floor's Lambert pdf towards it; at 0 (and with the switch off) the smooth slab's."""
    from test_transparent_flat_glass import _sun_under
    from test_transparent_shadows import _floor_hits
    from engine.integrator import Counters, direct_irradiance
    th = math.radians(30.0)
    sun = (math.sin(th), 0.0, -math.cos(th))
    out = {}
    for fg, on in ((0.0, True), (1.0, True), (1.0, False)):
        was = bp.CYCLES_BLUR
        bp.CYCLES_BLUR = on
        try:
            ctx = _sun_under("slab", sun, cycles_filter_glossy=fg, photon_mapping=False)
            hit = _floor_hits(ctx, 300, half=0.3)
            E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
        finally:
            bp.CYCLES_BLUR = was
        out[(fg, on)] = float(E[:, 0].mean())
    c = math.cos(th)
    f = float(bp.factor_lookup(c, blur_alpha(1.0, c / math.pi), 1.5))
    assert out[(1.0, False)] == out[(0.0, True)]
    assert out[(1.0, True)] == pytest.approx(out[(0.0, True)] * f, rel=1e-6)  # (float32 rays)
    assert f < 0.85
