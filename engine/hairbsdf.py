"""Principled Hair BSDF on the hair's tubes: a partly transparent Principled surface.

The engine has no fibre closure: hair renders as smooth triangle tubes (engine/hair.py).
A Principled Hair BSDF (Chiang et al. 2016, "A Practical and Controllable Hair and Fur
Model for Production Path Tracing"; Cycles' bsdf_principled_hair_chiang.h; pbrt-v3's
HairBSDF derives the same model) renders on them as a Principled dielectric (its
specular layer stands for the R lobe) that lets part of the light pass straight
through with a tint (a Transparent share), so that the tube's two walls scatter back to
the lit side and pass on forward what the fibre does.

The parameters become the absorption coefficient sigma_a (per unit fibre radius) as
Cycles' svm_node_closure_bsdf (kernel/svm/closure.h, CLOSURE_BSDF_HAIR_CHIANG_ID) makes
it: Absorption Coefficient as it is; Melanin m and Melanin Redness r as concentrations
-log(1 - m (1 + 2 (Random - 0.5) Random Color)) split into eumelanin (1 - r) and
pheomelanin (r) times their absorption spectra, plus the Tint's sigma; Direct Coloring
(and the Tint) by bsdf_principled_hair_sigma_from_reflectance(colour, radial roughness)
= (ln colour / s(radial roughness))^2 (kernel/closure/bsdf_util.h).

The fibre's albedo. For a ray leaving (or, reciprocally, arriving) at longitudinal angle
theta and offset h across the fibre, the Chiang lobes' energies are (hair_attenuation)
A_R = f, A_TT = (1 - f)^2 T, A_TRT = A_TT f T, A_TRRT+ = A_TRT f T / (1 - f T) with
f = Fresnel(cos theta cos gamma_i, eta), sin gamma_i = h, and the internal transmittance
T = exp(-sigma_a 2 cos gamma_t / cos theta_t) (sin theta_t = sin theta / eta,
sin gamma_t = h cos theta / sqrt(eta^2 - sin^2 theta)). Each lobe's M_p N_p integrates
to 1 over the sphere of directions (Cycles' eval returns f |cos theta_i|), so the fibre
scatters A(h, theta) = f + (1 - f)^2 T / (1 - f T) of what it intercepts (Cycles'
bsdf_principled_hair_albedo comments the same sum), independent of the roughnesses.
`fibre_albedo` averages it over the fibre's width (h uniform in -1..1, as rays strike a
fibre) and over directions of uniform incident radiance (sin theta uniform, weighted by
the fibre's projected width cos theta): the fibre's white-furnace albedo.

Back and forward. TRT leaves near the incident side and TT near the straight-through
direction (Chiang's N_p about delta_phi = 2 p gamma_t - 2 gamma_i + p pi, M_p about
theta_o = -theta_i), the residual's N_p is uniform: the fibre scatters back
A_R + A_TRT + A_TRRT+ / 2 and forward A_TT + A_TRRT+ / 2 (`back_and_forward`). A wall
that reflects r and passes tau, twice in series, reflects r + tau^2 r / (1 - r^2) and
passes tau^2 / (1 - r^2) (`wall` inverts this, r at least A_R: the front wall keeps the
whole R lobe). The wall's material (`surface`): a Transparent share 1 - alpha of tint
tau / (1 - alpha), alpha = 1 - max tau, over a Principled share alpha whose specular
layer reflects A_R / alpha of uniform light (Specular IOR Level, `specular_level`) and
whose diffuse base makes up the rest of r. A diffuse tube of the fibre's whole albedo
instead sent back what the strand passes on: a sparse tuft 2.5x Cycles' brightness.

What this leaves out (warned): TT passes straight through (not spread over Chiang's
forward lobe), so light does not diffuse through a dense groom as it does in Cycles;
the back wall's internal reflection stands for TRT without its second absorption (the
lit side of dark hair is up to A_R (1 + T) / R too bright); the TRT highlight's colour
and shift, the Offset tilt, Radial Roughness' azimuthal lobe shapes; the Huang model's
elliptic cross-section (Aspect Ratio).
"""
from __future__ import annotations

import copy
import functools
import threading
import weakref

import numpy as np

from .shadernodes import ShadingGeometry, _eval, fresnel_dielectric_cos

# Cycles' bsdf_principled_hair_sigma_from_concentration absorption spectra (per unit
# concentration, linear Rec.709 RGB; Bitterli's fit of d'Eon et al. 2011).
EUMELANIN_SIGMA = np.array([0.506, 0.841, 1.653])
PHEOMELANIN_SIGMA = np.array([0.343, 0.733, 1.924])
# The node's defaults (Blender 5.0: ShaderNodeBsdfHairPrincipled).
DEFAULT_IOR = 1.55
PARAMETRIZATIONS = ("ABSORPTION", "MELANIN", "COLOR")


def albedo_roughness_scale(radial_roughness):
    """Cycles' bsdf_principled_hair_albedo_roughness_scale: the s(beta_n) in
    sigma_a = (ln colour / s)^2 (Chiang et al. 2016, eq. 9's fit), a polynomial in the
    azimuthal (radial) roughness."""
    x = np.asarray(radial_roughness, np.float64)
    return (((((0.245 * x) + 5.574) * x - 10.73) * x + 2.532) * x - 0.215) * x + 5.969


def sigma_from_reflectance(color, radial_roughness):
    """Direct Coloring: sigma_a (..., 3) of a colour (..., 3) at a radial roughness
    (scalar or (...,)), as Cycles' bsdf_principled_hair_sigma_from_reflectance; colour 0
    absorbs everything (inf), colour 1 nothing."""
    c = np.maximum(np.asarray(color, np.float64), 0.0)
    s = np.asarray(albedo_roughness_scale(radial_roughness), np.float64)
    if s.ndim:
        s = s[..., None]
    with np.errstate(divide="ignore"):
        sigma = np.log(c) / s
    return sigma * sigma


def sigma_from_melanin(melanin, redness, tint, radial_roughness, random=0.0,
                       random_color=0.0):
    """Melanin parametrization (svm_node_closure_bsdf, PIGMENT_CONCENTRATION): melanin m
    randomised by the strand's Random (m (1 + 2 (random - 0.5) clamp(Random Color, 0, 1))),
    mapped to a concentration -ln(max(1 - m, 1e-4)), split by Melanin Redness r into
    eumelanin (1 - r) and pheomelanin (r); plus the Tint's sigma_from_reflectance.
    Scalars or (...,) arrays; tint (..., 3). Returns sigma_a (..., 3)."""
    m = np.asarray(melanin, np.float64) * (
        1.0 + 2.0 * (np.asarray(random, np.float64) - 0.5)
        * np.clip(np.asarray(random_color, np.float64), 0.0, 1.0))
    m = -np.log(np.maximum(1.0 - m, 1e-4))
    r = np.asarray(redness, np.float64)
    eu, pheo = m * (1.0 - r), m * r
    sigma = (np.asarray(eu)[..., None] * EUMELANIN_SIGMA
             + np.asarray(pheo)[..., None] * PHEOMELANIN_SIGMA)
    return sigma + sigma_from_reflectance(tint, radial_roughness)


def lobe_energies(sigma_a, h, sin_theta, eta=DEFAULT_IOR):
    """The Chiang lobes' energies (Cycles' hair_attenuation) at fibre offset h and
    longitudinal angle sin_theta (arrays broadcasting together; sigma_a (..., 3) against
    them with a trailing channel axis). Returns (A_R (...,), A_TT, A_TRT, A_TRRT+ (..., 3))."""
    h = np.asarray(h, np.float64)
    st = np.asarray(sin_theta, np.float64)
    ct = np.sqrt(np.maximum(1.0 - st * st, 0.0))
    cg = np.sqrt(np.maximum(1.0 - h * h, 0.0))
    f = fresnel_dielectric_cos(ct * cg, eta)
    ct_t = np.sqrt(np.maximum(1.0 - (st / eta) ** 2, 0.0))
    sg_t = h * ct / np.sqrt(eta * eta - st * st)
    cg_t = np.sqrt(np.maximum(1.0 - sg_t * sg_t, 0.0))
    sigma = np.asarray(sigma_a, np.float64)
    with np.errstate(invalid="ignore"):
        T = np.exp(-sigma * (2.0 * cg_t / ct_t)[..., None])
    T = np.nan_to_num(T, nan=0.0)
    fc = f[..., None]
    tt = (1.0 - fc) ** 2 * T
    trt = tt * T * fc
    rest = trt * T * fc / (1.0 - T * fc)
    return f, tt, trt, rest


@functools.lru_cache(maxsize=16)
def _quadrature(n=48):
    """Gauss-Legendre nodes and weights on 0..1 (h and sin theta: both lobes' energies
    are even in each)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def fibre_albedo(sigma_a, eta=DEFAULT_IOR, n=48):
    """The fibre's white-furnace albedo: the lobe energies averaged over h uniform on the
    width and over sin theta uniform weighted by cos theta (the projected width).
    sigma_a (..., 3). Returns (total (..., 3), the R lobe's share (scalar), TT, TRT and
    TRRT+ (..., 3) each)."""
    x, w = _quadrature(n)
    h, st = np.meshgrid(x, x, indexing="ij")
    wt = (w[:, None] * w[None, :]) * np.sqrt(1.0 - st * st)
    wt = (wt / wt.sum()).ravel()
    sigma = np.asarray(sigma_a, np.float64)
    f, tt, trt, rest = lobe_energies(sigma[..., None, :], h.ravel(), st.ravel(), eta)
    a_r = float(f @ wt)
    a_tt, a_trt, a_res = (np.einsum("...kc,k->...c", x_, wt) for x_ in (tt, trt, rest))
    return a_r + a_tt + a_trt + a_res, a_r, a_tt, a_trt, a_res


# sigma_a is tabulated over t = sigma / (1 + sigma) in 0..1 (0: clear, 1: opaque).
TABLE_SIZE = 1025


@functools.lru_cache(maxsize=16)
def _albedo_table(eta):
    t = np.linspace(0.0, 1.0, TABLE_SIZE)
    with np.errstate(divide="ignore"):
        sigma = t / (1.0 - t)
    sigma = np.repeat(sigma[:, None], 3, axis=1)
    _, a_r, a_tt, a_trt, a_res = fibre_albedo(sigma, eta)
    return t, a_r, a_tt[:, 0], a_trt[:, 0], a_res[:, 0]


def back_and_forward(sigma_a, eta=DEFAULT_IOR, r_weight=1.0, tt_weight=1.0,
                     trt_weight=1.0):
    """What the fibre scatters back to the side the light comes from and forward past
    it, of what it intercepts (white-furnace averages, tabulated linearly in
    t = sigma / (1 + sigma) at 1025 steps): back = A_R + A_TRT + A_TRRT+ / 2, forward =
    A_TT + A_TRRT+ / 2 (TRT leaves near the incident side, TT near the straight-through
    direction, the residual's N_p is uniform in azimuth). The weights are Huang's
    Reflection / Transmission / Secondary Reflection factors (1 for Chiang; the residual
    goes with TRT). sigma_a (..., 3) -> (A_R scalar, back (..., 3), forward (..., 3))."""
    t_tab, a_r, tt_tab, trt_tab, res_tab = _albedo_table(round(float(eta), 6))
    s = np.maximum(np.asarray(sigma_a, np.float64), 0.0)
    with np.errstate(invalid="ignore"):
        t = np.where(np.isinf(s), 1.0, s / (1.0 + s))
    tt, trt, res = (np.interp(t, t_tab, x) for x in (tt_tab, trt_tab, res_tab))
    a_r = a_r * r_weight
    return a_r, a_r + trt_weight * (trt + 0.5 * res), tt_weight * tt + trt_weight * 0.5 * res


def wall(sigma_a, eta=DEFAULT_IOR, r_weight=1.0, tt_weight=1.0, trt_weight=1.0):
    """Reflectance r and straight-through transmittance tau (..., 3) of one wall of the
    tube such that its two walls (light passes the front, then the back, bouncing
    between them) reflect and transmit what the fibre scatters back and forward
    (back_and_forward): R = r + tau^2 r / (1 - r^2), T = tau^2 / (1 - r^2), so
    r = R / (1 + T), tau = sqrt(T (1 - r^2)) (the slab of two equal layers); r is kept
    at least A_R, the R lobe's share, which the front wall alone reflects (the back
    wall's reflection stands for TRT; where R / (1 + T) < A_R the tube reflects
    A_R (1 + T) > R: dark, thin-walled hair a little too bright on its lit side)."""
    a_r, back, fwd = back_and_forward(sigma_a, eta, r_weight, tt_weight, trt_weight)
    r = np.maximum(back / (1.0 + fwd), a_r)
    return r, np.sqrt(np.maximum(fwd * (1.0 - r * r), 0.0))


def surface(sigma_a, eta=DEFAULT_IOR, r_weight=1.0, tt_weight=1.0, trt_weight=1.0):
    """The tube's material for sigma_a (..., 3): (alpha (...,), transparent tint
    (..., 3), diffuse base (..., 3), specular layer's albedo E (...,)). The wall passes
    (1 - alpha) x tint straight through, alpha = 1 - max tau (as opaque as the colour
    allows; at least A_R); its Principled share alpha keeps the whole R lobe in its
    specular layer, alpha E = A_R, and its diffuse base makes up the rest of the wall's
    reflectance r: alpha (E + (1 - E) rho) = r, rho = (r - A_R) / (alpha - A_R) clipped
    to 0..1."""
    a_r, _, _ = back_and_forward(np.zeros(3), eta, r_weight, tt_weight, trt_weight)
    r, tau = wall(sigma_a, eta, r_weight, tt_weight, trt_weight)
    alpha = np.clip(1.0 - np.max(tau, axis=-1), max(a_r, 1e-6), 1.0)
    opaque = alpha >= 1.0
    tint = np.where(opaque[..., None], 1.0,
                    tau / np.where(opaque, 1.0, 1.0 - alpha)[..., None])
    rho = np.clip((r - a_r) / np.maximum(alpha - a_r, 1e-6)[..., None], 0.0, 1.0)
    return alpha, np.minimum(tint, 1.0), rho, np.minimum(a_r / alpha, 1.0)


def tube_fresnel(eta):
    """A smooth dielectric tube's reflectance of uniform light: Fresnel averaged as
    fibre_albedo averages the R lobe (h uniform, sin theta uniform by cos theta)."""
    return fibre_albedo(np.full(3, np.inf), eta)[1]


@functools.lru_cache(maxsize=1)
def _fresnel_table():
    etas = np.geomspace(1.0001, 1e4, 400)
    return etas, np.array([tube_fresnel(e) for e in etas])


def specular_level(albedo, eta=DEFAULT_IOR):
    """The Principled Specular IOR Level (F0 x 2 level, Cycles' Principled v2) that
    gives the tube's specular layer the reflectance `albedo` (scalar or array) of
    uniform light (tube_fresnel of the IOR whose F0 that is), for a layer of IOR eta."""
    etas, fres = _fresnel_table()
    e = np.interp(np.clip(np.asarray(albedo, np.float64), fres[0], fres[-1]), fres, etas)
    f0 = ((e - 1.0) / (e + 1.0)) ** 2
    return 0.5 * f0 / (((eta - 1.0) / (eta + 1.0)) ** 2)


# The share of a Gaussian's mass within its half width at half maximum (1.1774 sigma).
_HWHM_SHARE = 0.7610


def specular_roughness(roughness):
    """The Principled (GGX) roughness whose reflected lobe holds as much of its energy
    within the Chiang R lobe's half width at half maximum as the R lobe does (76 %, a
    Gaussian's): Cycles maps hair roughness beta to the lobe's standard deviation
    0.726 beta + 0.812 beta^2 + 3.7 beta^20 (bsdf_hair_chiang_setup), HWHM = 1.1774 of
    it; GGX puts t^2 / (alpha^2 + t^2) of its half vectors within tan theta_h = t
    (alpha = roughness^2), the reflected direction turning twice as far. (Matching the
    half widths instead leaves GGX's long tails twice as wide: a dense dark groom read
    1.54 of Cycles against 1.36 with this.) Within 0.06 of beta for hair roughness
    0.2-0.5."""
    b = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0)
    std = 0.726 * b + 0.812 * b * b + 3.7 * b ** 20
    hwhm = np.minimum(1.1774 * std, 0.5 * np.pi - 1e-3)
    alpha = np.tan(0.5 * hwhm) * np.sqrt((1.0 - _HWHM_SHARE) / _HWHM_SHARE)
    return np.clip(np.sqrt(alpha), 0.0, 1.0)


def node_sigma(parametrization, color, melanin, redness, tint, absorption,
               radial_roughness, random=0.0, random_color=0.0):
    """sigma_a (..., 3) of the node's parametrization ('ABSORPTION', 'MELANIN', 'COLOR')
    from its inputs (constants or per-hit arrays), as svm_node_closure_bsdf."""
    if parametrization == "ABSORPTION":
        return np.asarray(absorption, np.float64)
    if parametrization == "MELANIN":
        return sigma_from_melanin(melanin, redness, tint, radial_roughness, random,
                                  random_color)
    return sigma_from_reflectance(color, radial_roughness)


class HairColor:
    """A Principled Hair BSDF's tube material per hit (engine/shadernodes.py node
    protocol: evaluate(geo, prim, u, v)): its inputs (constants or colour nodes; `random`
    the strand's Curves Info Random or the node's Random input) to sigma_a by
    node_sigma, the radial roughness randomised by Random Roughness as Cycles does
    (x (1 + 2 (random - 0.5) Random Roughness)), then `surface`: output COLOR the diffuse
    base (N, 3), ALPHA the opaque share (N,), LEVEL the Specular IOR Level (N,).

    The three outputs are one node (addon/materials.py: the material's texture, alpha
    texture and Specular IOR Level; `with_output` makes the others), which the shading
    of a batch of hits asks in turn: they share one evaluation of `surface` for the
    batch (_LastBatch), not three (sigma_a and the tube's walls took half a hair
    render's time, s37)."""

    def __init__(self, parametrization, color, melanin, redness, tint, absorption,
                 radial_roughness, random_roughness, random, random_color, eta,
                 r_weight=1.0, tt_weight=1.0, trt_weight=1.0, output="COLOR"):
        if parametrization not in PARAMETRIZATIONS:
            raise ValueError(f"hair parametrization {parametrization!r}: expected one of "
                             f"{PARAMETRIZATIONS}")
        self.parametrization = parametrization
        self.color, self.melanin, self.redness, self.tint = color, melanin, redness, tint
        self.absorption, self.radial_roughness = absorption, radial_roughness
        self.random_roughness, self.random, self.random_color = (random_roughness, random,
                                                                 random_color)
        if output not in ("COLOR", "ALPHA", "LEVEL"):
            raise ValueError(f"hair output {output!r}: expected COLOR, ALPHA or LEVEL")
        self.eta, self.output = float(eta), output
        self.weights = (float(r_weight), float(tt_weight), float(trt_weight))
        self._last = _LastBatch()  # shared by with_output's copies

    def with_output(self, output) -> "HairColor":
        """This node's `output` ('COLOR', 'ALPHA', 'LEVEL'), sharing its evaluations."""
        if output not in ("COLOR", "ALPHA", "LEVEL"):
            raise ValueError(f"hair output {output!r}: expected COLOR, ALPHA or LEVEL")
        other = copy.copy(self)
        other.output = output
        return other

    def sigma(self, geo, prim, u, v):
        """sigma_a (N, 3) at the hits."""

        def one(x):
            return _eval(x, geo, prim, u, v, 1)

        def three(x):
            return _eval(x, geo, prim, u, v, 3)
        random = one(self.random)
        radial = one(self.radial_roughness) * (
            1.0 + 2.0 * (random - 0.5) * one(self.random_roughness))
        p = self.parametrization
        sigma = node_sigma(p, three(self.color) if p == "COLOR" else None,
                           one(self.melanin), one(self.redness), three(self.tint),
                           three(self.absorption) if p == "ABSORPTION" else None,
                           radial, random, one(self.random_color))
        return sigma

    def evaluate(self, geo, prim, u, v):
        alpha, _, rho, spec = self._last.get(
            geo, prim, u, v,
            lambda: surface(self.sigma(geo, prim, u, v), self.eta, *self.weights))
        if self.output == "ALPHA":
            return alpha
        if self.output == "LEVEL":
            return specular_level(spec, self.eta)
        return rho


class _LastBatch:
    """The last batch of hits one thread evaluated a HairColor node at, and the value:
    get(geo, prim, u, v, compute) returns it again for the same hits (equal prim, u, v
    and, seen from a ray, equal view: ShadingGeometry's n, wi, backfacing, over the same
    Geometry), else compute() kept in its place. Per thread (engine/parallel.py's workers
    shade their own batches at once); pickled and copied empty (a scene sent to a Dask
    worker, the export's copies), shared where the node's outputs share it."""

    def __init__(self):
        self._local = threading.local()

    def __getstate__(self):
        return {}

    def __setstate__(self, state):
        self._local = threading.local()

    def get(self, geo, prim, u, v, compute):
        base = geo._geo if isinstance(geo, ShadingGeometry) else geo
        key = [np.asarray(x) for x in (prim, u, v)]
        if isinstance(geo, ShadingGeometry):
            key += [np.asarray(x) for x in (geo.n, geo.wi, geo.backfacing)]
        last = getattr(self._local, "last", None)
        if (last is not None and last[0]() is base and len(last[1]) == len(key)
                and all(np.array_equal(a, b) for a, b in zip(last[1], key))):
            return last[2]
        value = compute()
        try:  # (held weakly: a render's Geometry is not kept alive by a worker thread)
            ref = weakref.ref(base) if base is not None else (lambda: None)
        except TypeError:
            return value
        self._local.last = (ref, [a.copy() for a in key], value)
        return value
