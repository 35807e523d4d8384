"""GGX microfacet closures: reflection and glass (reflection + refraction), as Cycles.

Single scattering with Smith's height-correlated masking-shadowing G2 = 1 / (1 + Λo + Λi)
(Heitz 2014, eq. 72 for GGX's Λ), sampled from the distribution of visible normals (Heitz,
"Sampling the GGX Distribution of Visible Normals", JCGT 7(4), 2018): the sample weight is
F * G2 / G1(wo). Refraction follows Walter et al. 2007 without the 1/eta^2 radiance factor,
as Cycles (its bsdf_microfacet_eval: f*cos = T D G2 eta^2 |wo.h| |wi.h| / (cos_o (wo.h +
eta wi.h)^2)). Multiple scattering is compensated as Cycles does (microfacet_ggx_preserve_
energy): the lobe is scaled by 1 / E(mu_o) for the white lobe's directional albedo E, and a
coloured Fresnel adds Kulla & Conty's multi-bounce saturation (`energy_factor`).

Local frame: +z is the shading normal; wo (towards the viewer) has z > 0. alpha =
roughness^2 (Blender's roughness input). Vectors are passed as scalar components.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from .fresnel import fresnel_dielectric

# Below this alpha the lobe is a perfect mirror / refraction (sampled, never evaluated):
# Cycles' BSDF_ROUGHNESS_SQ_THRESH compares alpha^2 with a similar bound.
ALPHA_MIN = 1e-4


@kernel
def lambda_ggx(cos_n, alpha2):
    """Smith's Λ for GGX (Heitz 2014, eq. 72)."""
    c2 = cos_n * cos_n
    if c2 <= 0.0:
        return 1e30
    t2 = max(1.0 / c2 - 1.0, 0.0)
    return 0.5 * (math.sqrt(1.0 + alpha2 * t2) - 1.0)


@kernel
def d_ggx(cos_h, alpha2):
    """GGX normal distribution D(h) for cos_h = h.n."""
    c2 = min(cos_h * cos_h, 1.0)
    t = (1.0 - c2) + alpha2 * c2
    return alpha2 / (math.pi * t * t)


@kernel
def sample_vndf(ox, oy, oz, alpha, u1, u2):
    """A microfacet normal h from GGX's visible normals seen from wo (Heitz 2018): the
    isotropic case of sample_vndf_aniso (the same arithmetic with ax = ay = alpha)."""
    return sample_vndf_aniso(ox, oy, oz, alpha, alpha, u1, u2)


@kernel
def reflect_eval(ox, oy, oz, ix, iy, iz, alpha):
    """White (F = 1) single-scattering reflection: (f * cos_i, pdf of wi, wo.h).
    Zero where either direction is below the surface or the lobe is a mirror."""
    if oz <= 0.0 or iz <= 0.0 or alpha < ALPHA_MIN:
        return 0.0, 0.0, 1.0
    hx, hy, hz = ox + ix, oy + iy, oz + iz
    inv = 1.0 / math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx * inv, hy * inv, hz * inv
    a2 = alpha * alpha
    D = d_ggx(hz, a2)
    lo = lambda_ggx(oz, a2)
    li = lambda_ggx(iz, a2)
    common = D / oz * 0.25
    return common / (1.0 + lo + li), common / (1.0 + lo), ox * hx + oy * hy + oz * hz


@kernel
def reflect_sample(ox, oy, oz, alpha, u1, u2):
    """Sample wi of the white reflection lobe: (ix, iy, iz, weight = eval/pdf, pdf, wo.h).
    A mirror (alpha < ALPHA_MIN) returns pdf = inf and weight 1. weight 0: no valid sample."""
    if oz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 1.0
    if alpha < ALPHA_MIN:
        return -ox, -oy, oz, 1.0, np.inf, oz
    hx, hy, hz = sample_vndf(ox, oy, oz, alpha, u1, u2)
    c = ox * hx + oy * hy + oz * hz
    ix, iy, iz = 2.0 * c * hx - ox, 2.0 * c * hy - oy, 2.0 * c * hz - oz
    if iz <= 0.0:
        return ix, iy, iz, 0.0, 0.0, c
    a2 = alpha * alpha
    lo = lambda_ggx(oz, a2)
    li = lambda_ggx(iz, a2)
    pdf = d_ggx(hz, a2) / oz * 0.25 / (1.0 + lo)
    return ix, iy, iz, (1.0 + lo) / (1.0 + lo + li), pdf, c


# --- anisotropic GGX (Cycles' bsdf_microfacet.h with alpha_x != alpha_y) ----------------
# The tangent frame: x along the closure's tangent T (roughness alpha_x), y = N x T
# (alpha_y), z the normal. The isotropic kernels above are the alpha_x == alpha_y case;
# they stay as they are (the same bits for every isotropic material) and the closures call
# these only for a lobe with a tangent and alpha_x != alpha_y.


@kernel
def lambda_ggx_aniso(x, y, z, ax, ay):
    """Smith's Λ of anisotropic GGX for the unit direction (x, y, z) in the tangent frame
    (Heitz 2014, eq. 86: Λ with alpha^2 tan^2 -> (ax^2 x^2 + ay^2 y^2) / z^2)."""
    z2 = z * z
    if z2 <= 0.0:
        return 1e30
    a2t2 = (ax * ax * x * x + ay * ay * y * y) / z2
    return 0.5 * (math.sqrt(1.0 + a2t2) - 1.0)


@kernel
def d_ggx_aniso(hx, hy, hz, ax, ay):
    """Anisotropic GGX D(h) = 1 / (pi ax ay (hx^2/ax^2 + hy^2/ay^2 + hz^2)^2) for the unit
    half vector h in the tangent frame (Heitz 2014, eq. 85); ax == ay: d_ggx."""
    sx, sy = hx / ax, hy / ay
    t = sx * sx + sy * sy + hz * hz
    return 1.0 / (math.pi * ax * ay * t * t)


@kernel
def sample_vndf_aniso(ox, oy, oz, ax, ay, u1, u2):
    """A visible normal of anisotropic GGX in the tangent frame (Heitz 2018, listing 1):
    the view direction stretched by (ax, ay, 1), a point on the projected hemisphere
    (uniform disk, polar: the mapping is smooth, which Heitz's derivation assumes), the
    normal unstretched by them."""
    vx, vy, vz = ax * ox, ay * oy, oz
    inv = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx * inv, vy * inv, vz * inv
    lensq = vx * vx + vy * vy
    if lensq > 1e-7:
        il = 1.0 / math.sqrt(lensq)
        t1x, t1y, t1z = -vy * il, vx * il, 0.0
    else:
        t1x, t1y, t1z = 1.0, 0.0, 0.0
    t2x = vy * t1z - vz * t1y
    t2y = vz * t1x - vx * t1z
    t2z = vx * t1y - vy * t1x
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    p1 = r * math.cos(phi)
    p2 = r * math.sin(phi)
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * math.sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2
    p3 = math.sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0))
    hx = p1 * t1x + p2 * t2x + p3 * vx
    hy = p1 * t1y + p2 * t2y + p3 * vy
    hz = p1 * t1z + p2 * t2z + p3 * vz
    hx, hy, hz = ax * hx, ay * hy, max(hz, 0.0)
    inv = 1.0 / math.sqrt(hx * hx + hy * hy + hz * hz)
    return hx * inv, hy * inv, hz * inv


@kernel
def reflect_eval_aniso(ox, oy, oz, ix, iy, iz, ax, ay):
    """reflect_eval of anisotropic GGX, wo and wi in the tangent frame: (f * cos_i with
    F = 1, pdf of wi (visible normals), wo.h)."""
    if oz <= 0.0 or iz <= 0.0:
        return 0.0, 0.0, 1.0
    hx, hy, hz = ox + ix, oy + iy, oz + iz
    inv = 1.0 / math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx * inv, hy * inv, hz * inv
    D = d_ggx_aniso(hx, hy, hz, ax, ay)
    lo = lambda_ggx_aniso(ox, oy, oz, ax, ay)
    li = lambda_ggx_aniso(ix, iy, iz, ax, ay)
    common = D / oz * 0.25
    return common / (1.0 + lo + li), common / (1.0 + lo), ox * hx + oy * hy + oz * hz


@kernel
def reflect_sample_aniso(ox, oy, oz, ax, ay, u1, u2):
    """reflect_sample of anisotropic GGX in the tangent frame: (ix, iy, iz, weight =
    G2 / G1(wo), pdf, wo.h); weight 0: no valid sample."""
    if oz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 1.0
    hx, hy, hz = sample_vndf_aniso(ox, oy, oz, ax, ay, u1, u2)
    c = ox * hx + oy * hy + oz * hz
    ix, iy, iz = 2.0 * c * hx - ox, 2.0 * c * hy - oy, 2.0 * c * hz - oz
    if iz <= 0.0:
        return ix, iy, iz, 0.0, 0.0, c
    lo = lambda_ggx_aniso(ox, oy, oz, ax, ay)
    li = lambda_ggx_aniso(ix, iy, iz, ax, ay)
    pdf = d_ggx_aniso(hx, hy, hz, ax, ay) / oz * 0.25 / (1.0 + lo)
    return ix, iy, iz, (1.0 + lo) / (1.0 + lo + li), pdf, c


@kernel
def glass_eval(ox, oy, oz, ix, iy, iz, alpha, eta):
    """Dielectric glass lobe (reflection + refraction, real Fresnel), wo on the side of the
    normal, eta = n(other side) / n(wo's side): (f * |cos_i| reflected part, transmitted
    part, pdf of wi including the Fresnel lobe choice). Mirror-like (alpha < ALPHA_MIN): 0."""
    if oz <= 0.0 or alpha < ALPHA_MIN or iz == 0.0:
        return 0.0, 0.0, 0.0
    a2 = alpha * alpha
    transmit = iz < 0.0
    if transmit:
        hx, hy, hz = -(ox + eta * ix), -(oy + eta * iy), -(oz + eta * iz)
    else:
        hx, hy, hz = ox + ix, oy + iy, oz + iz
    ln = math.sqrt(hx * hx + hy * hy + hz * hz)
    if ln <= 0.0:
        return 0.0, 0.0, 0.0
    hx, hy, hz = hx / ln, hy / ln, hz / ln
    if hz < 0.0:
        hx, hy, hz = -hx, -hy, -hz
    ch_o = ox * hx + oy * hy + oz * hz
    ch_i = ix * hx + iy * hy + iz * hz
    if ch_o <= 0.0:
        return 0.0, 0.0, 0.0
    F = fresnel_dielectric(ch_o, eta)
    D = d_ggx(hz, a2)
    lo = lambda_ggx(oz, a2)
    li = lambda_ggx(abs(iz), a2)
    if transmit:
        if ch_i >= 0.0 or abs(eta - 1.0) < 1e-4:
            # the refracted direction must leave the microfacet's far side; index-matched
            # refraction is a straight line (sampled, never evaluated, as Cycles)
            return 0.0, 0.0, 0.0
        denom = ch_o + eta * ch_i
        common = D / oz * (eta * eta) * abs(ch_o * ch_i) / (denom * denom)
        return 0.0, (1.0 - F) * common / (1.0 + lo + li), (1.0 - F) * common / (1.0 + lo)
    common = D / oz * 0.25
    return F * common / (1.0 + lo + li), 0.0, F * common / (1.0 + lo)


@kernel
def glass_sample(ox, oy, oz, alpha, eta, u1, u2, u3):
    """Sample the glass lobe: (ix, iy, iz, weight = eval/pdf, pdf, refracted). The weight
    is G2/G1 (Fresnel cancels against the reflect/refract choice made with probability F).
    Smooth glass (alpha < ALPHA_MIN): pdf = inf, weight 1. weight 0: no valid sample."""
    if oz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, False
    smooth = alpha < ALPHA_MIN
    if smooth:
        hx, hy, hz = 0.0, 0.0, 1.0
    else:
        hx, hy, hz = sample_vndf(ox, oy, oz, alpha, u1, u2)
    c = ox * hx + oy * hy + oz * hz
    F = fresnel_dielectric(c, eta)
    if u3 < F:
        ix, iy, iz = 2.0 * c * hx - ox, 2.0 * c * hy - oy, 2.0 * c * hz - oz
        refr = False
        if iz <= 0.0:
            return ix, iy, iz, 0.0, 0.0, False
    else:
        # refract -wo through h: eta = n_t / n_i
        inv_eta = 1.0 / eta
        s2 = inv_eta * inv_eta * (1.0 - c * c)
        ct = math.sqrt(max(1.0 - s2, 0.0))
        k = inv_eta * c - ct
        ix, iy, iz = -inv_eta * ox + k * hx, -inv_eta * oy + k * hy, -inv_eta * oz + k * hz
        refr = True
        if iz >= 0.0:
            return ix, iy, iz, 0.0, 0.0, True
    if smooth or (refr and abs(eta - 1.0) < 1e-4):
        return ix, iy, iz, 1.0, np.inf, refr
    a2 = alpha * alpha
    lo = lambda_ggx(oz, a2)
    li = lambda_ggx(abs(iz), a2)
    D = d_ggx(hz, a2)
    if refr:
        ch_i = ix * hx + iy * hy + iz * hz
        denom = c + eta * ch_i
        pdf = (1.0 - F) * D / oz * (eta * eta) * abs(c * ch_i) / (denom * denom) / (1.0 + lo)
    else:
        pdf = F * D / oz * 0.25 / (1.0 + lo)
    return ix, iy, iz, (1.0 + lo) / (1.0 + lo + li), pdf, refr


@kernel
def energy_factor(E, E_avg, Fss):
    """Cycles' multiple-scattering compensation (microfacet_ggx_preserve_energy) as one
    factor on the single-scattering lobe for one colour channel: the white lobe is scaled by
    1/E (E: its directional albedo at mu_o), and a Fresnel whose average is Fss keeps Kulla
    & Conty's multi-bounce saturation: 1 + Fms (1 - E) / E, Fms = Fss E_avg / (1 - Fss (1 -
    E_avg)). With Fss = 1 this is 1 / E."""
    E = max(E, 1e-4)
    missing = (1.0 - E) / E
    Fms = Fss * E_avg / max(1.0 - Fss * (1.0 - E_avg), 1e-9)
    return 1.0 + Fms * missing


# --- numpy wrappers (tests, table generation, numpy stages) -------------------------------

@kernel
def _reflect_eval_many(wo, wi, alpha, out):
    for k in range(wo.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = reflect_eval(wo[k, 0], wo[k, 1], wo[k, 2],
                                                        wi[k, 0], wi[k, 1], wi[k, 2],
                                                        alpha[k])


@kernel
def _reflect_sample_many(wo, alpha, u1, u2, out):
    for k in range(wo.shape[0]):
        ix, iy, iz, w, pdf, c = reflect_sample(wo[k, 0], wo[k, 1], wo[k, 2], alpha[k], u1[k],
                                               u2[k])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4], out[k, 5] = ix, iy, iz, w, pdf, c


@kernel
def _glass_eval_many(wo, wi, alpha, eta, out):
    for k in range(wo.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = glass_eval(wo[k, 0], wo[k, 1], wo[k, 2],
                                                     wi[k, 0], wi[k, 1], wi[k, 2],
                                                     alpha[k], eta[k])


@kernel
def _glass_sample_many(wo, alpha, eta, u1, u2, u3, out):
    for k in range(wo.shape[0]):
        ix, iy, iz, w, pdf, refr = glass_sample(wo[k, 0], wo[k, 1], wo[k, 2], alpha[k],
                                                eta[k], u1[k], u2[k], u3[k])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = ix, iy, iz, w, pdf
        out[k, 5] = 1.0 if refr else 0.0


@kernel
def _reflect_eval_aniso_many(wo, wi, ax, ay, out):
    for k in range(wo.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = reflect_eval_aniso(wo[k, 0], wo[k, 1], wo[k, 2],
                                                              wi[k, 0], wi[k, 1], wi[k, 2],
                                                              ax[k], ay[k])


@kernel
def _reflect_sample_aniso_many(wo, ax, ay, u1, u2, out):
    for k in range(wo.shape[0]):
        ix, iy, iz, w, pdf, c = reflect_sample_aniso(wo[k, 0], wo[k, 1], wo[k, 2], ax[k],
                                                     ay[k], u1[k], u2[k])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4], out[k, 5] = ix, iy, iz, w, pdf, c


def _rows(n, *arrays):
    return [np.ascontiguousarray(np.broadcast_to(np.asarray(a, np.float64),
                                                 (n,) + np.shape(a)[1:] if np.ndim(a) > 1
                                                 else (n,))) for a in arrays]


def reflect_eval_np(wo, wi, alpha):
    """(N,3) local wo, wi, alpha (N,) or scalar -> (eval (N,), pdf (N,), wo.h (N,))."""
    wo = np.ascontiguousarray(wo, np.float64)
    n = len(wo)
    wi, = _rows(n, wi)
    alpha, = _rows(n, alpha)
    out = np.empty((n, 3))
    _reflect_eval_many(wo, wi, alpha, out)
    return out[:, 0], out[:, 1], out[:, 2]


def reflect_sample_np(wo, alpha, u1, u2):
    """-> (wi (N,3), weight (N,), pdf (N,), wo.h (N,))."""
    wo = np.ascontiguousarray(wo, np.float64)
    n = len(wo)
    alpha, u1, u2 = _rows(n, alpha, u1, u2)
    out = np.empty((n, 6))
    _reflect_sample_many(wo, alpha, u1, u2, out)
    return out[:, :3], out[:, 3], out[:, 4], out[:, 5]


def glass_eval_np(wo, wi, alpha, eta):
    """-> (reflected eval (N,), transmitted eval (N,), pdf (N,))."""
    wo = np.ascontiguousarray(wo, np.float64)
    n = len(wo)
    wi, = _rows(n, wi)
    alpha, eta = _rows(n, alpha, eta)
    out = np.empty((n, 3))
    _glass_eval_many(wo, wi, alpha, eta, out)
    return out[:, 0], out[:, 1], out[:, 2]


def glass_sample_np(wo, alpha, eta, u1, u2, u3):
    """-> (wi (N,3), weight (N,), pdf (N,), refracted (N,) bool)."""
    wo = np.ascontiguousarray(wo, np.float64)
    n = len(wo)
    alpha, eta, u1, u2, u3 = _rows(n, alpha, eta, u1, u2, u3)
    out = np.empty((n, 6))
    _glass_sample_many(wo, alpha, eta, u1, u2, u3, out)
    return out[:, :3], out[:, 3], out[:, 4], out[:, 5] > 0.5


def reflect_eval_aniso_np(wo, wi, ax, ay):
    """Anisotropic reflect_eval_np: (N,3) wo, wi in the tangent frame, ax, ay (N,) or
    scalars -> (eval (N,), pdf (N,), wo.h (N,))."""
    wo = np.ascontiguousarray(wo, np.float64)
    n = len(wo)
    wi, = _rows(n, wi)
    ax, ay = _rows(n, ax, ay)
    out = np.empty((n, 3))
    _reflect_eval_aniso_many(wo, wi, ax, ay, out)
    return out[:, 0], out[:, 1], out[:, 2]


def reflect_sample_aniso_np(wo, ax, ay, u1, u2):
    """Anisotropic reflect_sample_np -> (wi (N,3), weight (N,), pdf (N,), wo.h (N,))."""
    wo = np.ascontiguousarray(wo, np.float64)
    n = len(wo)
    ax, ay, u1, u2 = _rows(n, ax, ay, u1, u2)
    out = np.empty((n, 6))
    _reflect_sample_aniso_many(wo, ax, ay, u1, u2, out)
    return out[:, :3], out[:, 3], out[:, 4], out[:, 5]
