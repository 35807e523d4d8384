"""Cycles' clamp on camera paths that split at glass (engine/sampleclamp.py, split_throughput;
integrator.SPLIT_GLASS_HITS): Cycles takes glass branch b with probability P_b and
throughput C_b / P_b and clamps that one path, expecting sum_b P_b min(C_b / P_b, L) =
sum_b min(C_b, P_b L); ours continues every branch with C_b, so each is clamped at
P_b x L (and the path's later contributions at the product of its P_b)."""
import math

import numpy as np
import pytest

from engine import sampleclamp
from engine.scene import Material

from test_camera_glass import _expected_and_mask, _fresnel, _render, _slab_scene


def test_split_branches_clamped_at_their_share_give_the_chosen_paths_expectation():
    """For random RGB branch values C_b (K branches, sum of P_b 1) and limits L:
    sum_b clamp(C_b at P_b L) equals the expectation over Cycles' choice,
    sum_b P_b clamp(C_b / P_b at L), and exceeds it with every branch at L."""
    rng = np.random.default_rng(46)
    for k in (2, 3):
        for _ in range(200):
            C = rng.exponential(1.0, (k, 3)) * rng.choice([0.1, 1.0, 10.0])
            P = rng.dirichlet(np.ones(k))
            L = rng.uniform(0.1, 10.0)
            chosen = sum(P[b] * sampleclamp.clamp(C[b:b + 1] / P[b], None, None, L)[0]
                         for b in range(k))
            split = sampleclamp.clamp(C, None, None, L * P).sum(axis=0)
            np.testing.assert_allclose(split, chosen, rtol=1e-12)
            whole = sampleclamp.clamp(C, None, None, L).sum(axis=0)
            assert np.all(whole >= split * (1 - 1e-12))


def test_split_throughput_is_the_limit_times_the_scale():
    """clamp(rgb, tp / scale, rows, L) == clamp(rgb, tp, rows, L x scale[rows]); scale
    None: tp itself (the same bits)."""
    rng = np.random.default_rng(5)
    tp = rng.uniform(0.0, 2.0, (50, 3))
    scale = rng.uniform(0.01, 1.0, 50)
    rows = rng.integers(0, 50, 80)
    rgb = rng.exponential(2.0, (80, 3))
    a = sampleclamp.clamp(rgb, sampleclamp.split_throughput(tp, scale), rows, 3.0)
    b = sampleclamp.clamp(rgb, tp, rows, 3.0 * scale[rows])
    np.testing.assert_allclose(a, b, rtol=1e-12)
    assert sampleclamp.split_throughput(tp, None) is tp


@pytest.mark.parametrize("roughness", [0.0, 0.3])
def test_glass_both_share_is_cycles_reflection_probability(roughness):
    """glass_both_share's last value is the probability _glass_sample (Cycles'
    pdf_reflect = average reflectance / average(reflectance + transmittance) at the
    microfacet normal) takes the reflection with: its reflection weight over glass_both's;
    a smooth Glass BSDF seen from outside: the Fresnel reflectance."""
    from engine.camerakernels import glass_both, glass_both_share
    from engine.closures import principled as pr
    from engine.geometry import closure_params

    rng = np.random.default_rng(7)
    for node, base in (("glass", (1.0, 1.0, 1.0)), ("principled", (0.9, 0.5, 0.2))):
        m = Material("g", base, transmission=1.0, roughness=roughness, ior=1.5,
                     node=node, multiscatter=False)
        checked = 0
        for _ in range(100):
            mu = rng.uniform(0.05, 1.0)
            front = bool(rng.random() < 0.7)
            prm, _ = pr.setup_np(closure_params([m]), np.zeros(1, np.int64),
                                 np.full((1, 3), 0.6), np.full(1, mu), np.full(1, front))
            o = (math.sqrt(1.0 - mu * mu), 0.0, mu)
            u1, u2 = rng.random(2)
            share = glass_both_share(prm, 0, *o, u1, u2)
            assert share[:12] == glass_both(prm, 0, *o, u1, u2)
            p_r = share[12]
            assert 0.0 <= p_r <= 1.0
            refl = pr._glass_sample(prm, 0, *o, u1, u2, 0.0)
            if refl[3] > 0.0 and not refl[6]:
                assert share[3] / refl[3] == pytest.approx(p_r, rel=1e-9)
                checked += 1
            if roughness == 0.0 and node == "glass" and front:
                assert p_r == pytest.approx(_fresnel(mu), rel=1e-9)
        assert checked > 50


def _clamped_slab(theta_deg, clamp, split_scale, monkeypatch, spp=32):
    monkeypatch.setattr(sampleclamp, "SPLIT_SCALE", split_scale)
    s, n = _slab_scene(theta_deg, "transmit")
    cos_i, inside = _expected_and_mask(s, n)
    img = _render(s, spp=spp, clamp_direct=clamp, clamp_indirect=clamp)
    return img[inside].mean(axis=0), _fresnel(cos_i)[inside]


@pytest.mark.parametrize("theta_deg", [0.0, 45.0])
def test_slab_clamped_transmits_t_slab_times_the_limit(theta_deg, monkeypatch):
    """The world (radiance 1) behind a clear slab, both clamps at c = 0.5: each of
    Cycles' samples that crosses carries the world at throughput 1 (C_b / P_b = 1 on clear
    glass), clamped to c, and crosses with probability T_slab = (1 - F) / (1 + F): the
    pixel is T_slab x c (0.46 at 0 degrees). Each half clamped at the whole limit, the
    crossing (1 - F)^2 = 0.92 alone was cut to c: ~8 % brighter."""
    c = 0.5
    got, F = _clamped_slab(theta_deg, c, True, monkeypatch)
    expect = (c * (1.0 - F) / (1.0 + F)).mean()
    np.testing.assert_allclose(got, expect, rtol=0.005)
    old, _ = _clamped_slab(theta_deg, c, False, monkeypatch)
    assert old[0] > 1.05 * expect


def test_no_clamp_or_clamp_above_every_sample_changes_no_bit(monkeypatch):
    """Clamps off, or a limit over every sample's value: the split's scale changes
    nothing (bit for bit against the old bookkeeping)."""
    for kw in (dict(), dict(clamp_direct=5.0, clamp_indirect=5.0)):
        monkeypatch.setattr(sampleclamp, "SPLIT_SCALE", True)
        s, _ = _slab_scene(45.0, "transmit")
        a = _render(s, spp=4, **kw)
        monkeypatch.setattr(sampleclamp, "SPLIT_SCALE", False)
        b = _render(s, spp=4, **kw)
        assert np.array_equal(a, b), kw
