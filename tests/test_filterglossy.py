"""Cycles' Filter Glossy on camera paths (engine/filterglossy.py, fgcamera46): the blur
alpha's formula, the per-hit raise of the packed microfacet alphas (only those columns,
after the set-up: albedos, weights and lobe choice unchanged), a blur of zeros giving
the same bits, the MIS pdf min_ray_pdf takes, and the camera paths' bookkeeping."""
import dataclasses
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.bsdf import closures, surface_hit
from engine.camerakernels import hit_closures, shade_lobes
from engine.closures import principled as pr
from engine.effects import filter_glossy_alpha
from engine.filterglossy import (NO_BLUR, PathBlur, blur_alpha, blur_alphas, mis_pdf,
                                 raise_alphas)
from engine.integrator import lobe_choice
from engine.render import prepare_context
from engine.sampling import uniform_sphere
from engine.scene import Material

ALPHAS = [pr.P_SPEC_ALPHA, pr.P_METAL_ALPHA, pr.P_GLASS_ALPHA, pr.P_COAT_ALPHA, pr.P_AX,
          pr.P_AY]
WEIGHTS = {pr.P_SPEC_ALPHA: [pr.P_SPEC_W], pr.P_METAL_ALPHA: [pr.P_METAL_W],
           pr.P_GLASS_ALPHA: [pr.P_GLASS_RW, pr.P_GLASS_TW], pr.P_COAT_ALPHA: [pr.P_COAT_W]}


def test_blur_alpha_is_cycles_formula_and_the_effects_report_s():
    fg = np.array([1.0, 1.0, 1.0, 0.5, 0.0, 10.0, 1.0, 0.3, 1.0])
    pdf = np.array([1 / np.pi, 0.0, 1.0, 0.6, 0.1, 3.0, np.inf, 0.1, np.nan])
    want = np.where((fg > 0) & (pdf / np.where(fg > 0, fg, 1) < 1),
                    0.5 * np.sqrt(np.clip(1 - pdf / np.where(fg > 0, fg, 1), 0, 1)), 0.0)
    got = blur_alphas(fg, pdf)
    assert np.array_equal(got, want)
    assert np.array_equal(filter_glossy_alpha(fg, pdf), want)
    assert [blur_alpha(f, p) for f, p in zip(fg, pdf)] == list(want)
    # After a Lambert bounce at Filter Glossy 1: 0.41 (normal) to 0.5 (grazing).
    assert abs(got[0] - 0.5 * math.sqrt(1 - 1 / math.pi)) < 1e-15 and got[1] == 0.5
    assert got[2] == 0.0 and got[4] == 0.0 and got[6] == 0.0 and got[8] == 0.0
    assert blur_alphas(1.0, [[0.2, 0.5]]).shape == (1, 2)


def _box():
    """The Cornell box with its smooth glass sphere, a layered back wall (specular, coat,
    sheen), a rough metal block, an anisotropic smooth metal floor."""
    s = cornell_box(8, 6, glass_sphere=True)
    s.add_material(Material("layered", (0.6, 0.3, 0.2), specular=1.0, roughness=0.4,
                            coat_weight=0.8, coat_roughness=0.1, sheen_weight=1.0))
    s.add_material(Material("rough_metal", (0.9, 0.7, 0.3), metallic=1.0, roughness=0.3))
    s.add_material(Material("brushed", (0.8, 0.8, 0.8), metallic=1.0, roughness=0.2,
                            anisotropic=0.8))
    for mesh in s.meshes:
        new = {"back": "layered", "block": "rough_metal",
               "floor": "brushed"}.get(getattr(mesh, "name", ""))
        if new is not None:
            mesh.materials = [new for _ in mesh.materials]
    return s


@pytest.fixture(scope="module")
def box_hits():
    ctx = prepare_context(_box(), RenderSettings(workers=1))
    rng = np.random.default_rng(3)
    lo, hi = ctx.geo.bounds
    n = 6000
    o = lo + (hi - lo) * (0.1 + 0.8 * rng.random((n, 3)))
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    return ctx, surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[k])


def _hit_closures(table, hit, blur):
    n = len(hit.mat)
    prm, alb = np.empty((n, pr.N_PACK)), np.empty((n, pr.N_LOBES, 3))
    hit_closures(hit.ns, hit.ng, hit.wo, hit.mat, table.closure_params, False, hit.base,
                 hit.front, np.ascontiguousarray(table.alpha, np.float64), np.zeros(0),
                 prm, alb, blur)
    return prm, alb


def test_raise_alphas_changes_only_the_weighted_alphas(box_hits):
    ctx, hit = box_hits
    n = len(hit.mat)
    blur = np.random.default_rng(1).random(n) * 0.5
    blur[::7] = 0.0
    prm0, alb0 = _hit_closures(ctx.table, hit, NO_BLUR)
    # The anisotropic floor carries alpha_x, alpha_y (set up before the blur).
    aniso = prm0[:, pr.P_AX] > 0
    assert aniso.any()
    prm1, alb1 = _hit_closures(ctx.table, hit, blur)
    assert np.array_equal(alb0, alb1)  # albedos (lobe choice, layering) unblurred
    others = [c for c in range(pr.N_PACK) if c not in ALPHAS]
    assert np.array_equal(prm0[:, others], prm1[:, others])
    for col, wcols in WEIGHTS.items():
        has = np.zeros(n, bool)
        for w in wcols:
            has |= (prm0[:, w:w + 3] != 0).any(axis=1)
        want = np.where(has, np.maximum(prm0[:, col], blur), prm0[:, col])
        assert np.array_equal(prm1[:, col], want), col
        assert has.any() and (prm1[:, col] > prm0[:, col]).any(), col
    for col in (pr.P_AX, pr.P_AY):
        want = np.where(aniso, np.maximum(prm0[:, col], blur), prm0[:, col])
        assert np.array_equal(prm1[:, col], want)
    # The same kernel per row (the one camerakernels calls).
    prm2 = prm0.copy()
    for i in range(n):
        raise_alphas(prm2, i, blur[i])
    assert np.array_equal(prm2, prm1)


@pytest.mark.parametrize("want_glossy", [True, False])
def test_zero_blur_gives_the_same_bits_and_a_blurred_mirror_is_glossy(box_hits, want_glossy):
    ctx, hit = box_hits
    n = len(hit.mat)
    tp = np.ascontiguousarray(10.0 ** (-3.0 * np.random.default_rng(2).random((n, 3))))

    def fused(blur):
        out = (np.full((n, pr.N_PACK), np.nan), np.full((n, pr.N_LOBES), np.nan),
               np.full(n, np.nan), np.full((n, pr.N_LOBES - 1), np.nan), np.full(n, np.nan),
               np.zeros(n, np.bool_), np.zeros(n, np.int64), np.full((n, 3), np.nan))
        k = shade_lobes(hit.ns, hit.ng, hit.wo, hit.mat, ctx.table.closure_params, False,
                        hit.base, hit.front, np.ascontiguousarray(ctx.table.alpha, np.float64),
                        np.zeros(0), tp, want_glossy, *out, blur, False)
        return out, k

    (a, ka), (b, kb) = fused(NO_BLUR), fused(np.zeros(n))
    assert ka == kb
    for x, y in zip(a, b):
        assert np.array_equal(x, y, equal_nan=True)
    # A blur of 0.45 everywhere: the smooth glass sphere's rows turn glossy (a rough
    # reflection: light sampling), the lobe choice stays; the prm equals hit_closures'.
    (c, kc), _ = fused(np.full(n, 0.45)), None
    glass = np.take(ctx.table.closure_params[:, pr.M_TRANS], hit.mat) > 0
    assert glass.any()
    if want_glossy:
        assert not a[5][glass].any() and c[5][glass].all()
    for x, y in zip(a[1:5], c[1:5]):  # sel, q, p, psum
        pick = np.isfinite(a[4]) & (a[4] > 0)
        assert np.array_equal(np.asarray(x)[pick], np.asarray(y)[pick], equal_nan=True)
    prm_h, _ = _hit_closures(ctx.table, hit, np.full(n, 0.45))
    setup = ~np.isnan(c[0][:, 0])
    assert np.array_equal(c[0][setup], prm_h[setup])


def test_surface_hit_lobes_passes_the_blur(box_hits):
    from engine.bsdf import plain_surfaces, surface_hit_lobes
    ctx, hit = box_hits
    assert plain_surfaces(ctx.table)
    from helpers import rays_from_inside
    prim, u, v, d = rays_from_inside(ctx, 3000, 4)
    n = len(prim)
    tp = np.ones((n, 3))

    def run(blur):
        out = (np.full((n, pr.N_PACK), np.nan), np.full((n, pr.N_LOBES), np.nan),
               np.full((n, pr.N_LOBES - 1), np.nan), np.full(n, np.nan), np.full(n, np.nan),
               np.zeros(n, np.bool_), np.zeros(n, np.int64), np.zeros((n, 3)))
        h, k = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp, True, out, blur=blur)
        return h, out, k
    h0, o0, k0 = run(None)
    hz, oz, kz = run(np.zeros(n))
    assert k0 == kz
    for x, y in zip(o0, oz):
        assert np.array_equal(x, y, equal_nan=True)
    blur = np.full(n, 0.3)
    hb, ob, kb = run(blur)
    prm_h, _ = _hit_closures(ctx.table, dataclasses.replace(h0, prm=None, lobe_albedo=None),
                             blur)
    assert np.array_equal(ob[0], prm_h)


def test_mis_pdf_is_the_one_sample_mixture_over_every_lobe(box_hits):
    """mis_pdf from the lobe choice's pdf (bsdf_pdf under sel, Russian roulette included)
    equals sum_l p_l pdf_l(wi) + w_d cos / pi over psum + w_d, each lobe's pdf taken alone
    (bsdf_pdf with that lobe's sel 1)."""
    ctx, hit = box_hits
    n = len(hit.mat)
    prm, alb = closures(ctx.table, dataclasses.replace(hit, prm=None, lobe_albedo=None))
    rng = np.random.default_rng(9)
    tp = np.ascontiguousarray(10.0 ** (-2.0 * rng.random((n, 3))))
    sel, q, p, psum = lobe_choice(alb, tp)
    wi = uniform_sphere(rng.random(n), rng.random(n))
    wi = np.where((np.sum(wi * hit.ns, axis=1) < 0)[:, None], -wi, wi)  # reflections
    ok = (psum > 0) & (q > 0)
    pdf_sel = np.empty(n)
    pr.bsdf_pdf_many(prm, np.where(ok[:, None], sel, 0.0), hit.ns, hit.wo, wi, pdf_sel)
    w_d = alb[:, 0].max(axis=1)
    cos_i = np.sum(wi * hit.ns, axis=1)
    got = mis_pdf(np.where(ok, pdf_sel, np.inf), q, psum, w_d, cos_i)
    lobes = np.zeros(n)
    for lobe in range(1, pr.N_LOBES):
        one = np.zeros_like(sel)
        one[:, lobe] = 1.0
        pl = np.empty(n)
        pr.bsdf_pdf_many(prm, one, hit.ns, hit.wo, wi, pl)
        w = p[:, lobe - 1] if lobe not in (pr.L_GLASS_R, pr.L_GLASS_T) else 0.0
        lobes += w * pl
    # (the glass lobe's reflection: bsdf_pdf weighs it by sel_R + sel_T)
    one = np.zeros_like(sel)
    one[:, pr.L_GLASS_R] = 1.0
    pg = np.empty(n)
    pr.bsdf_pdf_many(prm, one, hit.ns, hit.wo, wi, pg)
    lobes += (p[:, pr.L_GLASS_R - 1] + p[:, pr.L_GLASS_T - 1]) * pg
    want = (lobes + w_d * np.maximum(cos_i, 0) / np.pi) / (psum + w_d)
    assert ok.sum() > n // 4
    assert np.allclose(got[ok], want[ok], rtol=1e-9, atol=0)
    assert np.isinf(got[~ok]).all()
    # A metal alone: the choice's pdf over q (no other lobe to mix with).
    metal = ok & (np.take(ctx.table.closure_params[:, pr.M_METALLIC], hit.mat) == 1) & (
        np.take(ctx.table.closure_params[:, pr.M_ALPHA], hit.mat) == 1)
    assert metal.any()
    assert np.allclose(got[metal], pdf_sel[metal] / q[metal], rtol=1e-12)


def test_path_blur_keeps_the_smallest_continued_pdf():
    b = PathBlur(1.0, 4)
    assert len(b.blur()) == 0  # camera rays: min_ray_pdf inf, nothing blurs
    ns = np.tile([0.0, 0.0, 1.0], (4, 1))
    d = np.tile([0.0, 0.0, 1.0], (3, 1))
    one = np.ones(4)
    # Hit 0 continued twice (a split), hit 2 through a pass (inf), hit 3 with pdf 4.
    b.continued(np.array([0, 0, 2, 3]), np.array([0.5, 2.0, np.inf, 4.0]), one, one,
                np.zeros(4), ns, np.vstack([d, d[:1]]))
    assert np.array_equal(b.min_pdf, [0.5, 2.0, np.inf, 4.0])
    blur = b.blur()
    assert np.array_equal(blur, blur_alphas(1.0, [0.5, 2.0, np.inf, 4.0]))
    assert blur[0] == 0.5 * math.sqrt(0.5) and not blur[1:].any()
    b.take(np.array([3, 0]))
    # A Lambert weight beside the lobe: (p pdf + w_d cos / pi) / (p + w_d).
    b.continued(np.array([0, 1]), np.array([4.0, 8.0]), np.ones(2), np.ones(2),
                np.array([1.0, 0.0]), ns[:2], d[:2])
    assert np.allclose(b.min_pdf, [(4.0 + 1 / np.pi) / 2, 0.5])
    assert PathBlur.for_settings(RenderSettings(), 3) is None  # Filter Glossy 0: off


def test_camera_paths_blur_a_mirror_seen_in_a_rough_metal():
    """A smooth mirror block seen in a rough metal floor (roughness 0.5: most of its
    reflections have pdf < 1) in the Cornell box: with Filter Glossy 1 the block's hits
    after the floor's bounce are rough (light sampling, a wide lobe), so pixels change,
    by little on average; a Filter Glossy so small that no pdf falls below it gives the
    bits of 0 (the bookkeeping draws no numbers)."""
    s = cornell_box(24, 18, glass_sphere=False)
    s.add_material(Material("rough_metal", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.5))
    s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    for mesh in s.meshes:
        new = {"floor": "rough_metal", "block": "mirror"}.get(getattr(mesh, "name", ""))
        if new is not None:
            mesh.materials = [new for _ in mesh.materials]
    base = RenderSettings(workers=1, spp=4, photon_mapping=False, seed=1)
    img0 = s.render(base).combined
    tiny = s.render(dataclasses.replace(base, cycles_filter_glossy=1e-12)).combined
    one = s.render(dataclasses.replace(base, cycles_filter_glossy=1.0)).combined
    assert np.array_equal(img0, tiny)
    changed = (img0 != one).any(axis=2)
    assert np.all(np.isfinite(one)) and 0 < changed.sum() < changed.size // 4
    assert abs(one.mean() / img0.mean() - 1) < 0.02
