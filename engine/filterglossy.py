"""Cycles' Filter Glossy (Light Paths > Clamping > Filter Glossy, `scene.cycles.blur_glossy`)
on our paths: the lobes a path meets after a bounce of low pdf widen.

What Cycles does (docs/compatibility.md "filterglossy45", Blender 5.0's
`kernel/integrator/surface_shader.h`, `surface_shader_prepare_closures`): every path keeps
min_ray_pdf, the smallest one-sample MIS pdf of the directions it continued in so far
(1/sr; FLT_MAX at the camera; a transparent pass leaves it; a singular sample, a mirror
or smooth glass, reports 1e6). At each hit, right after the shader is set up,

    blur_pdf = min_ray_pdf / Filter Glossy,
    if blur_pdf < 1: every microfacet closure's alpha_x, alpha_y = max(alpha, 0.5 sqrt(1 - blur_pdf))

and a blurred smooth lobe then takes light sampling (SD_BSDF_HAS_EVAL). The closures'
albedo estimates, layering weights and multiscatter compensation were computed before,
at the unblurred roughness (its `bsdf_blur` TODO), so they stay.

- `blur_alpha(filter_glossy, min_pdf)`: the blur alpha of one hit (0: none), a scalar
  kernel; `blur_alphas` the same over arrays (effects.filter_glossy_alpha calls it).
- `raise_alphas(prm, i, blur)`: a packed hit's blurrable alphas raised to blur, after
  principled.setup (camerakernels.hit_closures / shade_lobes / surface_lobes);
  `raise_alphas_rows` over every row (glossysplit's gather chains).
- `mis_pdf`: Cycles' one-sample MIS pdf of a continued direction from our lobe choice's
  pdf (integrator.continue_specular's want_pdf), the number min_ray_pdf takes.
- `PathBlur`: a camera path's min_ray_pdf through integrator._trace_paths.
"""
from __future__ import annotations

import math

import numpy as np

from .closures import principled as pr
from .jit import kernel, register_warm_up

# The blurrable alphas of a packed hit (principled's P_* columns) and each one's lobe
# weight columns (RGB): a lobe without weight is left as set up (0), as Cycles blurs only
# the closures a shader made.
_BLURRED = ((pr.P_SPEC_ALPHA, pr.P_SPEC_W, pr.P_SPEC_W),
            (pr.P_METAL_ALPHA, pr.P_METAL_W, pr.P_METAL_W),
            (pr.P_GLASS_ALPHA, pr.P_GLASS_RW, pr.P_GLASS_TW),
            (pr.P_COAT_ALPHA, pr.P_COAT_W, pr.P_COAT_W))
NO_BLUR = np.zeros(0)  # the kernels' blur argument where nothing blurs


@kernel
def blur_alpha(filter_glossy, min_pdf):
    """The GGX alpha (Cycles' alpha = roughness^2) to which Filter Glossy `filter_glossy`
    (>= 0; 0: off) raises the microfacet lobes of a hit reached with min_ray_pdf `min_pdf`
    (1/sr): 0.5 sqrt(1 - min_pdf / filter_glossy) where that ratio is below 1, else 0
    (Cycles' surface_shader_prepare_closures; NaN: 0). At Filter Glossy 1 after a Lambert
    bounce (pdf cos / pi): 0.41 (normal) to 0.5 (grazing)."""
    if not filter_glossy > 0.0:
        return 0.0
    ratio = min_pdf / filter_glossy
    if not ratio < 1.0:
        return 0.0
    return 0.5 * math.sqrt(min(max(1.0 - ratio, 0.0), 1.0))


@kernel
def _blur_alphas(fg, pdf, out):
    for i in range(out.shape[0]):
        out[i] = blur_alpha(fg[i], pdf[i])


def blur_alphas(filter_glossy, min_pdf) -> np.ndarray:
    """blur_alpha over arrays (numpy broadcasting of the two): float64 of their shape."""
    fg, pdf = np.broadcast_arrays(np.asarray(filter_glossy, np.float64),
                                  np.asarray(min_pdf, np.float64))
    out = np.empty(fg.shape)
    # (copies: broadcast_arrays' views made numba warn, FutureWarning, at every call)
    _blur_alphas(np.array(fg, np.float64).ravel(), np.array(pdf, np.float64).ravel(),
                 out.reshape(-1))
    return out


@kernel
def raise_alphas(prm, i, blur):
    """Raise packed hit i's microfacet alphas (prm (N, principled.N_PACK)) to at least
    blur (Cycles' bsdf_microfacet_blur: alpha = max(blur, alpha)): the dielectric
    specular layer, the metal, the glass (reflection and refraction: one closure) and the
    coat (P_SPEC_ALPHA, P_METAL_ALPHA, P_GLASS_ALPHA, P_COAT_ALPHA), each only where its
    lobe has a weight, and the anisotropic alpha_x, alpha_y (P_AX, P_AY) where set
    (P_AX > 0). Sheen, the diffuse base and the translucent lobe have no alpha and stay,
    as Cycles' do; so do every weight and albedo set up before (call after
    principled.setup). blur <= 0 (or NaN) changes nothing; a NaN alpha stays NaN."""
    if not blur > 0.0:
        return
    for k in range(4):
        a_col, w_col, w2_col = _BLURRED[k]
        if (prm[i, w_col] != 0.0 or prm[i, w_col + 1] != 0.0 or prm[i, w_col + 2] != 0.0
                or prm[i, w2_col] != 0.0 or prm[i, w2_col + 1] != 0.0
                or prm[i, w2_col + 2] != 0.0):
            if prm[i, a_col] < blur:
                prm[i, a_col] = blur
    if prm[i, pr.P_AX] > 0.0:
        if prm[i, pr.P_AX] < blur:
            prm[i, pr.P_AX] = blur
        if prm[i, pr.P_AY] < blur:
            prm[i, pr.P_AY] = blur


@kernel
def raise_alphas_rows(prm, blur):
    """raise_alphas on every row i of prm (N, principled.N_PACK) to blur[i] (N,)."""
    for i in range(prm.shape[0]):
        raise_alphas(prm, i, blur[i])


def mis_pdf(pdf_choice, q, psum, w_diffuse, cos_i) -> np.ndarray:
    """Cycles' one-sample MIS pdf (1/sr) of continued directions, the number its
    min_ray_pdf takes (surface_shader_bsdf_sample_closure -> _surface_shader_bsdf_eval_mis:
    sum_c pdf_c(wi) sample_weight_c / sum_c sample_weight_c over every BSDF closure of the
    hit, the diffuse one and the Transparent BSDF's included), from our continuation's.

    pdf_choice (K,): continue_specular's want_pdf, the pdf under our lobe choice,
    sum_l sel_l pdf_l(wi) with sel_l = p_l / psum x q over the non-diffuse lobes (inf
    where the lobe has no density: a mirror, smooth glass, a pass); q (K,) the survival
    probability and psum (K,) the sum of the lobe weights p (choose_lobes, the pass
    lobe's included) of each continued ray's hit; w_diffuse (K,) the diffuse lobe's
    weight there (its albedo's mean channel, as Cycles'), cos_i (K,) the continued
    direction's
    cosine to the shading normal (the Lambert lobe's pdf is max(cos_i, 0) / pi). Returns
    (sum_l p_l pdf_l + w_diffuse cos_i / pi) / (psum + w_diffuse) where pdf_choice is
    finite and q > 0, inf elsewhere (Cycles' 1e6 for singular samples: never a minimum).

    The non-diffuse lobes' weights p differ from Cycles' sample weights in the channel
    they reduce: ours are each lobe's estimated albedo's max channel (choose_lobes),
    Cycles' its average (bsdf_alloc's fabsf(average(weight)) x
    average(bsdf_microfacet_estimate_albedo)). They agree for grey lobes (a dielectric
    specular layer, a coat) and for a hit of one lobe (a metal: the ratio is 1 either
    way); a coloured metal or sheen beside a diffuse base leans a little to itself. With
    the diffuse weight's max channel too, a red plastic's pdf read 0.70 of Cycles'
    (median) and 11 % of its blur decisions at Filter Glossy 1 flipped; with its mean,
    none of principled_spheres' materials differ (docs/compatibility.md "fgcamera46")."""
    pdf_choice = np.asarray(pdf_choice, np.float64)
    q = np.asarray(q, np.float64)
    ok = np.isfinite(pdf_choice) & (q > 0)
    qs = np.where(ok, q, 1.0)
    lobes = np.where(ok, pdf_choice, 0.0) * np.asarray(psum, np.float64) / qs
    wd = np.maximum(np.asarray(w_diffuse, np.float64), 0.0)
    lam = wd * np.maximum(np.asarray(cos_i, np.float64), 0.0) / math.pi
    den = np.asarray(psum, np.float64) + wd
    with np.errstate(invalid="ignore", divide="ignore"):
        out = (lobes + lam) / den
    return np.where(ok & (den > 0), out, np.inf)


class PathBlur:
    """Filter Glossy along a batch of camera paths (integrator._trace_paths): each path's
    min_ray_pdf (N,) from inf, lowered after each continued bounce by the continued
    direction's mis_pdf (a transparent pass leaves it: its pdf is inf), and the blur alpha
    of each path's next hit. None (for_settings) where Filter Glossy is 0: nothing runs."""

    def __init__(self, filter_glossy: float, n: int):
        self.fg = float(filter_glossy)
        self.min_pdf = np.full(n, np.inf)

    @classmethod
    def for_settings(cls, settings, n: int):
        fg = float(getattr(settings, "cycles_filter_glossy", 0.0) or 0.0)
        return cls(fg, n) if BLUR_CAMERA_PATHS and fg > 0 else None

    def blur(self) -> np.ndarray:
        """(N,) the blur alpha of each path's hit, or NO_BLUR where none blurs."""
        if not np.isfinite(self.min_pdf).any():
            return NO_BLUR
        b = blur_alphas(self.fg, self.min_pdf)
        return b if (b > 0).any() else NO_BLUR

    def take(self, rows):
        self.min_pdf = np.take(self.min_pdf, rows)

    def continued(self, keep, pdf_choice, q, psum, w_diffuse, ns, d):
        """After a bounce: the continued rays (keep (K,) rows of the hits, d (K,3) their
        directions, pdf_choice (K,) continue_specular's) lower their path's minimum by
        mis_pdf; q, psum, w_diffuse (N,) and ns (N,3) are the hits'."""
        keep = np.asarray(keep, np.int64)
        m = np.take(self.min_pdf, keep)
        fin = np.flatnonzero(np.isfinite(pdf_choice))
        if len(fin):
            r = keep[fin]
            n = np.take(ns, r, axis=0)
            dd = np.asarray(d)[fin]
            cos_i = n[:, 0] * dd[:, 0] + n[:, 1] * dd[:, 1] + n[:, 2] * dd[:, 2]
            p = mis_pdf(np.asarray(pdf_choice)[fin], np.take(q, r), np.take(psum, r),
                        np.take(w_diffuse, r), cos_i)
            m[fin] = np.minimum(m[fin], p)
        self.min_pdf = m


# Camera paths blur by Filter Glossy (PathBlur; False: never, as before fgcamera46).
BLUR_CAMERA_PATHS = True


@register_warm_up
def _warm_up():
    blur_alpha(1.0, 0.3)
    _blur_alphas(np.ones(1), np.ones(1), np.empty(1))
    raise_alphas(np.zeros((1, pr.N_PACK)), 0, 0.5)
    raise_alphas_rows(np.zeros((1, pr.N_PACK)), np.full(1, 0.5))
