"""Rough glass on Cycles' raised normal (issue 14).

Cycles replaces a glossy closure's normal with valid_reflection_N where the interpolated
shading normal would mirror the view below the surface (bsdf_util.h,
maybe_ensure_valid_specular_reflection); its Principled transmission lobe and Glass BSDF
take that normal too, rough or smooth. Rough glass here samples, evaluates and takes the
pdf of its reflection and refraction in the raised normal's frame
(principled.raised_rough_glass; camerakernels.glass_both). Checked here, on hits whose
shading normal leans away from a grazing view (the raise applies):
- the sampled weight equals eval / pdf for the reflection (eval_reflection, bsdf_pdf)
  and the refraction (eval_transmission), and the pdfs integrate over the sphere to the
  share of samples the lobe keeps;
- the reflection is reciprocal: f(wo, wi) = f(wi, wo) about the raised normal;
- no NaN or inf at grazing views and shading normals that face away;
- where nothing is raised (ns == ng) the set-up leaves P_GN at zero and the lobe's
  sampling is the shading-normal frame's, bit for bit (the old bits).
"""
import math

import numpy as np
import pytest

from engine.camerakernels import _glass_both_local, glass_both, hit_closures
from engine.closures import principled as pr
from engine.geometry import closure_params
from engine.scene import Material


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _material(roughness, ior=1.5, node="principled"):
    return Material("rg", (1.0, 1.0, 1.0), transmission=1.0, roughness=roughness, ior=ior,
                    node=node, multiscatter=True)


def _hit(material, ns, ng, wo, front=True):
    """hit_closures on one hit: (params, prm (1, N_PACK)) with the raise applied."""
    params = closure_params([material])
    ns, ng, wo = (np.ascontiguousarray([x], np.float64) for x in (ns, ng, wo))
    prm = np.empty((1, pr.N_PACK))
    alb = np.empty((1, pr.N_LOBES, 3))
    hit_closures(ns, ng, wo, np.zeros(1, np.int64), params, False, np.ones((1, 3)),
                 np.full(1, front), params[:, pr.M_ALPHA].copy(), np.zeros(0), prm, alb,
                 np.zeros(0))
    return params, prm


# (ns, wo) pairs with ng = +z where the raise applies: ns leans 15 or 30 degrees away
# from a view 70 or 55 degrees off ng, so that the mirror of wo about ns falls 10 or 25
# degrees below the surface while ns . wo stays > 0 (as face_shading_normals keeps it).
RAISED = [
    (_unit([-math.sin(math.radians(15)), 0.0, math.cos(math.radians(15))]),
     _unit([math.sin(math.radians(70)), 0.0, math.cos(math.radians(70))])),
    (_unit([-math.sin(math.radians(30)), 0.05, math.cos(math.radians(30))]),
     _unit([math.sin(math.radians(55)), -0.1, math.cos(math.radians(55))])),
]
NG = np.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize("roughness", [0.1, 0.3, 0.6])
@pytest.mark.parametrize("case", range(len(RAISED)))
@pytest.mark.parametrize("front", [True, False])
def test_raised_rough_glass_sample_eval_pdf_agree(roughness, case, front):
    ns, wo1 = RAISED[case]
    _, prm = _hit(_material(roughness), ns, NG, wo1, front)
    assert pr.raised_rough_glass(prm, 0), "the test's hit should take the raised normal"
    rng = np.random.default_rng(11)
    n = 40000
    prm_n = np.repeat(prm, n, axis=0)
    nrm = np.tile(ns, (n, 1))
    wo = np.tile(wo1, (n, 1))
    d, w = np.empty((n, 3)), np.empty((n, 3))
    tr = np.empty(n, np.bool_)
    u = rng.random((3, n))
    pr.sample_lobes(prm_n, np.full(n, pr.L_GLASS_T, np.int64), nrm, wo, u[0], u[1], u[2],
                    d, w, tr)
    assert np.isfinite(d).all() and np.isfinite(w).all()
    kept = w[:, 0] > 0
    refl, refr = kept & ~tr, kept & tr
    # (From inside, at these views about the raised normal, most microfacets reflect
    # totally.)
    assert refl.sum() > 100 and refr.sum() > (100 if front else 0)
    sel = np.zeros((n, pr.N_LOBES))
    sel[:, pr.L_GLASS_T] = 1.0
    # The reflection: eval / pdf is the sampled weight.
    ev = np.empty((n, 3))
    pr.eval_reflection_many(prm_n, nrm, wo, d, ev)
    pdf = np.empty(n)
    pr.bsdf_pdf_many(prm_n, sel, nrm, wo, d, pdf)
    np.testing.assert_allclose(ev[refl] / pdf[refl, None], w[refl], rtol=1e-6)
    # The refraction: f_t |cos_i| / pdf is the sampled weight.
    et = np.empty((n, 4))
    pr.eval_transmission_many(prm_n, nrm, wo, d, et)
    np.testing.assert_allclose(et[refr, :3] / et[refr, 3:4], w[refr], rtol=1e-6)
    # Both pdfs over the sphere (uniform directions) = the share of samples kept.
    m = 400000
    z = 2.0 * rng.random(m) - 1.0
    phi = 2.0 * math.pi * rng.random(m)
    r = np.sqrt(1.0 - z * z)
    wi = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    prm_m = np.repeat(prm, m, axis=0)
    nrm_m, wo_m = np.tile(ns, (m, 1)), np.tile(wo1, (m, 1))
    sel_m = np.zeros((m, pr.N_LOBES))
    sel_m[:, pr.L_GLASS_T] = 1.0
    p_r, e_t = np.empty(m), np.empty((m, 4))
    pr.bsdf_pdf_many(prm_m, sel_m, nrm_m, wo_m, wi, p_r)
    pr.eval_transmission_many(prm_m, nrm_m, wo_m, wi, e_t)
    assert np.isfinite(p_r).all() and np.isfinite(e_t).all()
    # The refraction's pdf over the pairs the sampler makes: Cycles' eval (and ours) also
    # evaluates those whose half vector faces the wrong way, which light sampling alone
    # reads (tests/test_rough_glass_cycles_eval.py). h = -(wo + eta wi) turned to the
    # lobe's (raised) normal must see wo from its front and wi from its back.
    gn = np.array(pr.frame_world(*ns, *prm[0, pr.P_GN:pr.P_GN + 3]))
    h = -(wo1[None, :] + prm[0, pr.P_GLASS_ETA] * wi)
    h *= np.sign(h @ gn)[:, None]
    valid = (h @ wo1 > 0) & (np.einsum("ij,ij->i", h, wi) < 0)
    dens = (p_r + np.where(valid, e_t[:, 3], 0.0)) * 4.0 * math.pi
    integral, se = dens.mean(), dens.std() / math.sqrt(m)
    share = kept.mean()
    assert abs(integral - share) < 4.0 * se + 4.0 * math.sqrt(share * (1 - share) / n), (
        integral, share)


@pytest.mark.parametrize("roughness", [0.1, 0.3, 0.6])
def test_raised_rough_glass_reflection_is_reciprocal(roughness):
    ns, wo1 = RAISED[0]
    _, prm = _hit(_material(roughness), ns, NG, wo1)
    gn = prm[0, pr.P_GN:pr.P_GN + 3]
    rng = np.random.default_rng(5)
    o = np.array(pr.frame_local(*ns, *wo1))
    checked = 0
    for _ in range(300):
        i = _unit(rng.normal(size=3))
        # f = eval / cos about the lobe's normal (the raised one, P_GN in ns's frame).
        ci, co = i @ gn, o @ gn
        if ci <= 0.02 or co <= 0.0:
            continue
        f_oi = np.array(pr.eval_reflection(prm, 0, *o, *i)) / ci
        f_io = np.array(pr.eval_reflection(prm, 0, *i, *o)) / co
        # (wi below ns itself is outside eval_reflection's sheen gate only; glass is on.)
        np.testing.assert_allclose(f_oi, f_io, rtol=1e-9, atol=1e-14)
        checked += f_oi[0] > 0
    assert checked > 50


@pytest.mark.parametrize("roughness", [0.1, 0.6])
def test_no_nan_at_grazing_and_back_facing_shading_normals(roughness):
    """Shading normals leaning 5 to 60 degrees away from views that leave ns . wo just
    above 0 (down to face_shading_normals' 1e-6 floor), and views within 1e-3 degrees of
    grazing ng: every sample, eval and pdf is finite, and the raise applies where the
    mirror about ns falls below the surface."""
    rng = np.random.default_rng(2)
    mat = _material(roughness)
    raised = 0
    for lean in (-5.0, 5.0, 30.0, 60.0):  # (-5: towards the view, nothing raised)
        for margin in (10.0, 1.0, 1e-3):
            view = min(90.0 - lean - margin, 90.0 - 1e-3)
            ns = _unit([-math.sin(math.radians(lean)), 0.0, math.cos(math.radians(lean))])
            wo1 = _unit([math.sin(math.radians(view)), 0.0, math.cos(math.radians(view))])
            assert ns @ wo1 > 1e-6
            _, prm = _hit(mat, ns, NG, wo1)
            raised += pr.raised_rough_glass(prm, 0)
            n = 2000
            prm_n = np.repeat(prm, n, axis=0)
            nrm, wo = np.tile(ns, (n, 1)), np.tile(wo1, (n, 1))
            d, w = np.empty((n, 3)), np.empty((n, 3))
            u = rng.random((3, n))
            pr.sample_lobes(prm_n, np.full(n, pr.L_GLASS_R, np.int64), nrm, wo, u[0], u[1],
                            u[2], d, w, np.empty(n, np.bool_))
            assert np.isfinite(d).all() and np.isfinite(w).all(), (lean, view)
            ev, et, pdf = np.empty((n, 3)), np.empty((n, 4)), np.empty(n)
            sel = np.zeros((n, pr.N_LOBES))
            sel[:, pr.L_GLASS_R] = 1.0
            pr.eval_reflection_many(prm_n, nrm, wo, d, ev)
            pr.eval_transmission_many(prm_n, nrm, wo, d, et)
            pr.bsdf_pdf_many(prm_n, sel, nrm, wo, d, pdf)
            assert np.isfinite(ev).all() and np.isfinite(et).all() and np.isfinite(pdf).all()
            for k in range(0, n, 97):
                o = pr.frame_local(*ns, *wo1)
                both = glass_both(prm, 0, *o, u[0, k], u[1, k])
                assert all(math.isfinite(x) for x in both), (lean, view, both)
            assert (w[:, 0] > 0).mean() > 0.2, (lean, view)
    assert raised >= 6


@pytest.mark.parametrize("roughness", [0.1, 0.6])
def test_unraised_rough_glass_keeps_the_shading_normal_frame(roughness):
    """ns == ng (or a view the raise leaves alone): P_GN stays zero, the set-up's view
    cosine is ns . wo, and sampling (_glass_sample, glass_both), eval and pdf are the
    shading-normal frame's, bit for bit; a raised hit's differ (the frame is used)."""
    mat = _material(roughness)
    params = closure_params([mat])
    rng = np.random.default_rng(9)
    wo1 = _unit([0.5, 0.2, 0.8])
    for ns in (NG, _unit([0.2, 0.0, 1.0])):  # flat; smooth but not raised at this view
        _, prm = _hit(mat, ns, NG, wo1)
        assert not prm[0, pr.P_GN:pr.P_GN + 3].any()
        old, _ = pr.setup_np(params, np.zeros(1, np.int64), np.ones((1, 3)),
                             np.full(1, ns @ wo1), np.ones(1, np.bool_))
        np.testing.assert_array_equal(prm, old)
        o = pr.frame_local(*ns, *wo1)
        for _ in range(50):
            u1, u2, u3 = rng.random(3)
            assert pr._glass_sample(prm, 0, *o, u1, u2, u3) == pr._glass_sample_local(
                prm, 0, *o, u1, u2, u3)
            assert glass_both(prm, 0, *o, u1, u2) == _glass_both_local(prm, 0, *o, u1, u2)
    ns, wo1 = RAISED[0]
    _, prm = _hit(mat, ns, NG, wo1)
    o = pr.frame_local(*ns, *wo1)
    a = pr._glass_sample(prm, 0, *o, 0.3, 0.6, 0.9)
    b = pr._glass_sample_local(prm, 0, *o, 0.3, 0.6, 0.9)
    assert a[:3] != b[:3]
