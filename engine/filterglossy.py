"""Cycles' Filter Glossy (Light Paths > Clamping > Filter Glossy): the per-hit lobe blur.

Cycles widens every microfacet lobe a path meets after a bounce of small pdf
(surface_shader_prepare_closures, kernel/integrator/surface_shader.h): blur_pdf =
min_ray_pdf / Filter Glossy; where it is below 1 every GGX closure's alpha is raised to
max(alpha, 0.5 sqrt(1 - blur_pdf)) (bsdf_blur, bsdf_microfacet_blur). Diffuse, sheen and
translucent closures stay; the layer weights and the multiple-scattering compensation
keep the unblurred roughness (Cycles' TODO in bsdf_blur). docs/compatibility.md,
"filterglossy45".
"""
from __future__ import annotations

import math

import numpy as np

from .closures import principled as pr
from .jit import kernel, register_warm_up


@kernel
def blur_alpha(filter_glossy, min_pdf):
    """The GGX alpha Filter Glossy raises a lobe to at a hit whose camera-side path has
    the smallest bounce pdf min_pdf (1/sr; inf: none yet): 0.5 sqrt(1 - min_pdf /
    filter_glossy) where that ratio is below 1, else 0 (no blur; filter_glossy <= 0:
    off). The formula of effects.filter_glossy_alpha (Cycles' surface_shader_prepare_closures)."""
    if not filter_glossy > 0.0:
        return 0.0
    ratio = min_pdf / filter_glossy
    if not ratio < 1.0:
        return 0.0
    return 0.5 * math.sqrt(max(0.0, 1.0 - ratio))


@kernel
def raise_alphas(prm, i, blur):
    """Raise packed hit row i's microfacet alphas (principled.setup's P_SPEC_ALPHA,
    P_METAL_ALPHA, P_GLASS_ALPHA, P_COAT_ALPHA, and the anisotropic P_AX, P_AY where
    set: P_AX > 0) to at least blur (Cycles' bsdf_microfacet_blur: alpha = max(alpha,
    blur)); every other column stays. Called after principled.setup, so the layer
    albedos keep the unblurred roughness, as Cycles' do. blur <= 0: no change."""
    if not blur > 0.0:
        return
    for col in (pr.P_SPEC_ALPHA, pr.P_METAL_ALPHA, pr.P_GLASS_ALPHA, pr.P_COAT_ALPHA):
        if prm[i, col] < blur:
            prm[i, col] = blur
    if prm[i, pr.P_AX] > 0.0:
        if prm[i, pr.P_AX] < blur:
            prm[i, pr.P_AX] = blur
        if prm[i, pr.P_AY] < blur:
            prm[i, pr.P_AY] = blur


@register_warm_up
def _warm_up():
    prm = np.zeros((1, pr.N_PACK))
    raise_alphas(prm, 0, blur_alpha(1.0, 0.3))
