"""Anisotropic metal and specular lobes in the closure set-up (engine/closures/
principled.py: aniso_alphas, set_tangents, eval / sample / pdf in the tangent frame) and
the tangent (engine/anisotropy.py)."""
import math

import numpy as np
import pytest

from engine.closures import principled as pr


def _metal(aniso=0.0, rot=0.0, node=pr.NODE_PRINCIPLED, rough=0.4, spec=0.0):
    p = np.zeros((1, pr.N_MAT))
    p[0, [pr.M_ALPHA, pr.M_METALLIC, pr.M_ROUGH, pr.M_IOR, pr.M_SPEC, pr.M_LEVEL]] = (
        1.0, 1.0 if spec == 0.0 else 0.0, rough, 1.5, spec, 0.5)
    p[0, pr.M_STINT:pr.M_STINT + 3] = 1.0
    p[0, pr.M_MULTI] = 1.0
    p[0, pr.M_NODE] = node
    p[0, pr.M_ANISO] = aniso
    p[0, pr.M_AROT] = rot
    return p


def _setup(params, n, cos_o, tangent, rot=0.0):
    prm, w = pr.setup_np(params, np.zeros(n, np.int64), np.full((n, 3), 0.8),
                         np.full(n, cos_o), np.ones(n, np.bool_))
    ns = np.tile([0.0, 0.0, 1.0], (n, 1))
    pr.set_tangents(prm, np.arange(n, dtype=np.int64), ns,
                    np.tile(np.asarray(tangent, float), (n, 1)), np.full(n, rot))
    return prm, w, ns


def test_alphas_as_cycles():
    a = 0.4 ** 2
    asp = math.sqrt(1 - 0.9 * 0.8)
    assert pr.aniso_alphas(pr.NODE_PRINCIPLED, 0.8, a) == pytest.approx((a / asp, a * asp))
    assert pr.aniso_alphas(pr.NODE_PRINCIPLED, -0.5, a) == (a, a)  # clamped to [0, 1]
    assert pr.aniso_alphas(pr.NODE_GLOSSY, 0.5, a) == pytest.approx((a * 0.5, a / 0.5))
    assert pr.aniso_alphas(pr.NODE_GLOSSY, -0.5, a) == pytest.approx((a / 0.5, a * 0.5))
    assert pr.aniso_alphas(pr.NODE_PRINCIPLED, 1.0, 0.81)[0] == 1.0  # clamped as Cycles


def test_isotropic_rows_unchanged_and_albedo_kept():
    """Anisotropic 0 packs no anisotropy; at 0.8 the lobe albedos (the energy tables read
    at sqrt(sqrt(alpha_x alpha_y)) = the roughness) equal the isotropic material's."""
    prm0, w0, _ = _setup(_metal(0.0), 1, 0.7, (1, 0, 0))
    prm1, w1, _ = _setup(_metal(0.8), 1, 0.7, (1, 0, 0))
    assert prm0[0, pr.P_AX] == 0.0 and prm0[0, pr.P_TAN] == 0.0
    assert prm1[0, pr.P_AX] > prm1[0, pr.P_AY] > 0.0
    np.testing.assert_allclose(w1, w0, rtol=1e-9)
    np.testing.assert_array_equal(prm1[:, :pr.P_AX], prm0[:, :pr.P_AX])


@pytest.mark.parametrize("spec", [0.0, 1.0])
def test_sample_eval_pdf_consistent(spec):
    """The metal (or specular) lobe's sampled weight is eval / pdf of bsdf_pdf for the
    same direction, and the pdf integrates (uniform-hemisphere Monte Carlo) to the share
    of samples that stay above the surface."""
    n = 20000
    rng = np.random.default_rng(5)
    prm, w, ns = _setup(_metal(0.8, 0.1, spec=spec), n, 0.6, (0.3, 1.0, 0.2))
    lobe = pr.L_SPEC if spec else pr.L_METAL
    wo = np.tile([math.sqrt(1 - 0.36), 0.0, 0.6], (n, 1))
    d, weight = np.empty((n, 3)), np.empty((n, 3))
    pr.sample_lobes(prm, np.full(n, lobe, np.int64), ns, wo, rng.random(n), rng.random(n),
                    rng.random(n), d, weight, np.empty(n, np.bool_))
    sel = np.zeros((n, pr.N_LOBES))
    sel[:, lobe] = 1.0
    pdf = np.empty(n)
    pr.bsdf_pdf_many(prm, sel, ns, wo, d, pdf)
    ev = np.empty((n, 3))
    pr.eval_reflection_many(prm, ns, wo, d, ev)
    ok = weight[:, 0] > 0
    np.testing.assert_allclose(weight[ok], ev[ok] / pdf[ok, None], rtol=1e-8)
    # pdf mass over the hemisphere
    z = rng.random(n)
    phi = 2 * np.pi * rng.random(n)
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    p2 = np.empty(n)
    pr.bsdf_pdf_many(prm, sel, ns, wo, wi, p2)
    mass = 2 * np.pi * p2.mean()
    assert abs(mass - ok.mean()) < 0.03, (mass, ok.mean())


def test_rotation_turns_the_tangent():
    """Rotation 0.25 (a quarter turn about the normal) is the tangent turned by 90
    degrees; the lobe then differs from rotation 0 (it is anisotropic)."""
    n = 500
    rng = np.random.default_rng(2)
    z = rng.random(n)
    phi = 2 * np.pi * rng.random(n)
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    wo = np.tile([0.5, 0.2, math.sqrt(1 - 0.29)], (n, 1))
    out = []
    for tangent, rot in (((1, 0, 0), 0.25), ((0, 1, 0), 0.0), ((1, 0, 0), 0.0)):
        prm, _, ns = _setup(_metal(0.8), n, 0.7, tangent, rot)
        prm[:, pr.P_GN:pr.P_GN + 3] = 0.0
        ev = np.empty((n, 3))
        pr.eval_reflection_many(prm, ns, wo, wi, ev)
        out.append(ev)
    np.testing.assert_allclose(out[0], out[1], rtol=1e-9, atol=1e-12)
    assert np.max(np.abs(out[2] - out[1])) > 0.1 * np.max(out[1])


def test_radial_tangent_fallback():
    """Without the exported tangent: (-(y - cy), x - cx, 0) about the object's bounding-box
    centre (Cycles' Tangent node, Radial Z, for an unrotated object)."""
    from types import SimpleNamespace
    from engine import anisotropy
    v0 = np.array([[1.0, 1.0, 0.0], [3.0, 1.0, 0.0]])
    e1 = np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    e2 = np.array([[0.0, 2.0, 0.0], [-2.0, 2.0, 0.0]])
    geo = SimpleNamespace(v0=v0, e1=e1, e2=e2, object_id=np.zeros(2, np.int32),
                          object_names=["plate"], corner_coordinates=None)
    t = anisotropy.hit_tangents(geo, np.array([0]), np.array([0.0]), np.array([0.0]),
                                np.array([[3.0, 2.0, 0.5]]))
    np.testing.assert_allclose(t, [[0.0, 1.0, 0.0]])
