"""Cycles' Filter Glossy on window glass: the light a blurred flat passage keeps.

At Filter Glossy > 0 Cycles blurs the smooth slab a path meets after a diffuse bounce
(engine/filterglossy.py): both refractions become single-scattering GGX glass of alpha
blur_alpha(FG, min_ray_pdf), with the energy compensation of the unblurred (smooth)
closure, i.e. none (`bsdf_blur`'s "TODO: Recompute energy preservation after blur?").
Such an interface loses light (the masking-shadowing term, refracted samples that leave
on the wrong side), the more the rougher and the more oblique. Our shadow rays cross a
window passage with the smooth slab's transmittance (shadowtransmittance._crossing);
with the switch CYCLES_BLUR on (off by default), a shadow ray from a diffuse hit D
crossing a passage takes in addition

    factor(cos_in, alpha, ior) = T_blur(cos_in, alpha) / T_sharp(cos_in)

where cos_in is the ray's cosine to the slab's normal, alpha the blur of D's pdf towards
the light, T_blur the energy a slab of two such rough interfaces transmits from that
direction (Monte Carlo with engine/closures/ggx.glass_sample, Cycles' sampling of its
microfacet glass: weight G2 / G1, reflect or refract by the microfacet's Fresnel; inner
reflections followed up to MAX_REFLECTIONS, Cycles' default Max Bounces > Glossy; the
second interface's alpha from min(pdf_D, the first refraction's pdf) at Filter Glossy 1,
as Cycles updates min_ray_pdf) and T_sharp the smooth slab's with the same inner
reflections, (1 - F)^2 / (1 - F^2) in the limit. The table (slab_factor_table) is made once
by `python -m engine.blurredpassage` (seeded) into blurredpassage.npz and read by
trilinear interpolation (passage_factor, a kernel; factor_lookup over arrays). Photons
that leave a passage take the same factor (photonkernels.scatter's passage_blur) at the
blur of cos / pi to the glass's normal, for the diffuse hit they will light.

Not modelled: the direction spread of the blurred slab (second order at window sizes:
a light's radiance is taken along the shadow ray's direction), Filter Glossy other than
1 for the second interface's alpha (the table's first interface is exact at any Filter
Glossy), and D's pdf is the Lambert lobe's cos / pi, not a Principled hit's one-sample MIS
pdf. docs/compatibility.md "fgslab49".
"""
from __future__ import annotations

import math
import os

import numpy as np

from .closures import tables
from .jit import kernel, register_warm_up

# Emulate Cycles' blurred window glass at Filter Glossy > 0 (False: shadow rays and
# photons cross a passage with the smooth slab's transmittance, as before fgslab49).
# Off by default: within 3 % of Cycles for panels and a sun at the zenith, but a sun at
# 45 degrees 1.058 and a white world 1.047 (the split's chains' extra light), and the
# pane-on-a-sill ceiling 0.76 (1.00 off); docs/compatibility.md "fgslab49".
CYCLES_BLUR = False

# Cycles' default Light Paths > Max Bounces > Glossy: the inner reflections followed.
MAX_REFLECTIONS = 4

_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "blurredpassage.npz")
# The table's axes: cos_in at the slab, the first interface's alpha (blur_alpha's range
# 0..0.5), the glass's IOR.
COS = np.linspace(0.0, 1.0, 21)
ALPHA = np.linspace(0.0, 0.5, 11)
IOR = np.array([1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.8, 2.0, 2.5])


def _fresnel(cos_i, eta):
    """Unpolarised dielectric Fresnel reflectance (numpy), eta = n_t / n_i."""
    from .closures.fresnel import fresnel_dielectric
    return np.array([fresnel_dielectric(float(c), float(eta)) for c in np.ravel(cos_i)]
                    ).reshape(np.shape(cos_i))


def sharp_slab(cos_in, ior, reflections=MAX_REFLECTIONS):
    """The smooth slab's transmittance from a direction at cos_in (scalar or array) to the
    slab's normal: (1 - F)^2 sum_k F^(2k) over the inner reflection pairs k the limit
    allows (the exit's Fresnel equals the entry's for parallel faces)."""
    F = _fresnel(np.asarray(cos_in, np.float64), ior)
    pairs = reflections // 2
    return (1.0 - F) ** 2 * sum(F ** (2 * k) for k in range(pairs + 1))


def slab_mc(cos_in, alpha, ior, n=20000, seed=0, reflections=MAX_REFLECTIONS, fg=1.0,
            update_pdf=True, interfaces=2):
    """Monte Carlo of the energy a slab of two single-scattering GGX interfaces (IOR ior,
    parallel, normal +z) transmits from a direction at cos_in (> 0) entering from below:
    the mean over n seeded paths of the product of glass_sample's weights along the paths
    that leave through the far face, a path taking at most `reflections` inner
    reflections. alpha: the first interface's; with update_pdf the later ones' is
    blur_alpha(fg, min(pdf_D, the pdfs sampled so far)) with pdf_D = fg (1 - 4 alpha^2)
    (the pdf that gives alpha), else alpha throughout. interfaces 1: the first
    interface alone (the energy it refracts). Returns a float."""
    from .closures import ggx
    from .filterglossy import blur_alphas
    rng = np.random.default_rng(seed)
    s = math.sqrt(max(1.0 - cos_in * cos_in, 0.0))
    w = np.tile([s, 0.0, cos_in], (n, 1))       # world direction, travelling
    weight = np.ones(n)
    min_pdf = np.full(n, fg * (1.0 - 4.0 * alpha * alpha) if alpha > 0 else np.inf)
    a = np.full(n, float(alpha))
    inside = np.zeros(n, np.bool_)
    refl = np.zeros(n, np.int64)
    live = np.ones(n, np.bool_)
    out = 0.0
    for _ in range(2 + 2 * reflections + 2):
        idx = np.flatnonzero(live)
        if len(idx) == 0:
            break
        wi = w[idx]
        sg = np.sign(wi[:, 2])
        # The arriving side's normal is -sign(w_z) z: wo = -w in that frame.
        wo = np.stack([-wi[:, 0], -wi[:, 1], np.abs(wi[:, 2])], axis=1)
        eta = np.where(inside[idx], 1.0 / ior, ior)
        u = rng.random((len(idx), 3))
        d, wt, pdf, refr = ggx.glass_sample_np(wo, a[idx], eta, u[:, 0], u[:, 1], u[:, 2])
        new = np.stack([d[:, 0], d[:, 1], -sg * d[:, 2]], axis=1)
        weight[idx] *= wt
        dead = wt <= 0.0
        if update_pdf:
            mp = np.minimum(min_pdf[idx], np.where(np.isfinite(pdf) & (pdf > 0), pdf, np.inf))
            min_pdf[idx] = mp
            a[idx] = np.where(np.isfinite(mp), blur_alphas(fg, mp), a[idx])
        was_in = inside[idx]
        # Out through the far face: transmitted; out through the near one: lost.
        exit_top = refr & (was_in | (interfaces == 1)) & (new[:, 2] > 0) & ~dead
        out += weight[idx[exit_top]].sum()
        lost = dead | (refr & (was_in | (interfaces == 1))) | (~refr & ~was_in)
        refl[idx[~refr]] += 1
        lost |= refl[idx] > reflections
        inside[idx] = np.where(refr, ~was_in, was_in)
        w[idx] = new
        live[idx[lost]] = False
    return out / n


def make_table(n=20000, seed=1) -> np.ndarray:
    """(len(IOR), len(COS), len(ALPHA)) factor T_blur / T_sharp; alpha 0 exactly 1, cos 0
    the grazing limit taken from the next row (the factor's value there is unused: no
    light arrives at grazing incidence)."""
    tab = np.ones((len(IOR), len(COS), len(ALPHA)))
    for i, ior in enumerate(IOR):
        for j, c in enumerate(COS[1:], start=1):
            ts = float(sharp_slab(c, ior))
            for k, al in enumerate(ALPHA[1:], start=1):
                # (one seed per cos and IOR: the alphas share their numbers, so the
                # row is smooth in alpha)
                tab[i, j, k] = slab_mc(c, al, ior, n, seed + 1000 * i + j) / ts
        tab[i, 0] = tab[i, 1]
    return tab


_TABLE = None


def table() -> np.ndarray:
    """The stored table (blurredpassage.npz), loaded once."""
    global _TABLE
    if _TABLE is None:
        with np.load(_PATH) as z:
            _TABLE = np.asarray(z["factor"], np.float64)
    return _TABLE


@kernel
def _cell(grid, x):
    """(i, f): x's cell in the increasing grid (clamped to its ends) and its fraction."""
    n = grid.shape[0]
    x = min(max(x, grid[0]), grid[n - 1])
    i = 0
    while i < n - 2 and grid[i + 1] <= x:
        i += 1
    return i, (x - grid[i]) / (grid[i + 1] - grid[i])


@kernel
def passage_factor(tab, ior_grid, cos_in, alpha, ior):
    """T_blur / T_sharp of one window passage from the table tab (len(IOR), len(COS),
    len(ALPHA)) (ior_grid its IOR axis; COS and ALPHA uniform over 0..1 and 0..0.5):
    trilinear at |cos_in|, alpha and ior; 1.0 where alpha <= 0 (no blur)."""
    if not alpha > 0.0:
        return 1.0
    # (The IOR axis is not uniform: its cell is found here; the closures' trilinear
    # lookup takes it as given.)
    i, fi = _cell(ior_grid, ior)
    k, fk = tables._coord(min(alpha, 0.5) / 0.5, tab.shape[2])
    return tables.lookup3_at(tab, i, fi, min(abs(cos_in), 1.0), k, fk)


@kernel
def _factor_many(tab, ior_grid, cos_in, alpha, ior, out):
    for i in range(out.shape[0]):
        out[i] = passage_factor(tab, ior_grid, cos_in[i], alpha[i], ior[i])


def factor_lookup(cos_in, alpha, ior) -> np.ndarray:
    """T_blur / T_sharp at cos_in (|cosine| of the ray to the slab's normal), alpha (the
    first interface's blur alpha, 0..0.5; 0: 1 exactly) and ior (clamped to 1.1..2.5),
    numpy-broadcast: passage_factor over them (trilinear in the stored table). Returns
    float64 of the broadcast shape."""
    cos_in, alpha, ior = np.broadcast_arrays(np.asarray(cos_in, np.float64),
                                             np.asarray(alpha, np.float64),
                                             np.asarray(ior, np.float64))
    out = np.empty(cos_in.shape)
    _factor_many(table(), IOR, np.array(cos_in, np.float64).ravel(),
                 np.array(alpha, np.float64).ravel(), np.array(ior, np.float64).ravel(),
                 out.reshape(-1))
    return out


@register_warm_up
def _warm_up():
    _factor_many(np.ones((2, 2, 2)), np.array([1.0, 2.0]), np.ones(1), np.full(1, 0.3),
                 np.full(1, 1.5), np.empty(1))


if __name__ == "__main__":
    import sys
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20000
    np.savez_compressed(_PATH, factor=make_table(n), cos=COS, alpha=ALPHA, ior=IOR)
    print(f"wrote {_PATH}")
