"""Emission inside homogeneous media: glowing fog, a lantern's glow, a neon haze, fire boxes.

A medium (engine/media.py) may emit: e (3,) W m^-2 sr^-1 per metre of ray, the same in
every direction (Material.volume_emission; the world volume's WorldMedium.emission). Along
a segment of length S inside it, with the path's throughput beta at the segment's start,
the radiance added is

    L_e = beta integral_0^S T(s) e ds = beta e (1 - exp(-sigma_t S)) / sigma_t

per channel, T(s) = exp(-sigma_t s) and sigma_t the medium's extinction
(media.absorption_table); an optical depth sigma_t S below 1e-5 takes the second-order
expansion e S (1 - sigma_t S / 2), e S where sigma_t = 0 (Cycles:
volume_emission_integrate, intern/cycles/kernel/integrator/shade_volume.h, integrated
over the whole segment for a homogeneous volume, volume_integrate_homogeneous).

Cycles samples no light from volume emission: surfaces see it through their indirect
(BSDF-sampled) paths. Here every camera-path segment adds it (to a surface, to a lamp it
meets, escaping through the world volume: integrator._trace_paths), and so does every
final-gather and regather ray's segment (integrator.gather_indirect): a floor under a
glowing box is lit through the gather, which runs for that even without a photon map
(glows). In a medium that also scatters, the glow scattered once towards the ray is
added too: from each segment's in-scattering point (engine/volumescatter.py) one
direction drawn by the phase function and the glow along it to the next surface
(CameraScattering.walk), as Cycles' path, which at its default Volume bounces 0 goes on
from its scatter point along one more segment and collects that segment's emission
(PATH_RAY_TERMINATE_AFTER_VOLUME). Photons are not emitted from media: the gather's own
segments carry the glow's first diffuse bounce and level 0's gather ends gather it once
more (its second: gather_indirect's glow_only); later bounces are missing (a white
corner ~10 % dark, docs/accuracy.md volemit38).

A medium with a density, emission or albedo texture (engine/heterogeneous.py,
engine/volumefields.py) keeps its homogeneous stand-in here; MediumEmission.along hands
the segments in such a medium to volumefields.MediumTextures.integrate, which replaces
the closed form by an unbiased estimate along the fields (volemit40).
"""
from __future__ import annotations

import math

import numpy as np

from . import media
from .jit import kernel, register_warm_up
from .media import segment_medium

NO_EMISSION = np.zeros((0, 3))  # no medium emits: nothing to do
# Below this optical depth the integral takes its second-order expansion (Cycles' 1e-5).
THIN_DEPTH = 1e-5


def emission_table(table) -> np.ndarray:
    """(M,3) float64 the media's emission (W/m^2/sr per m) of the material table's rows
    (MaterialTable.volume_emission; the world volume's row carries the world's), or
    NO_EMISSION (0 rows) when no medium emits."""
    emit = getattr(table, "volume_emission", None)
    if emit is None:
        return NO_EMISSION
    emit = np.ascontiguousarray(emit, np.float64).reshape(-1, 3)
    if not np.any(emit > 0):
        return NO_EMISSION
    return emit


def glows(ctx) -> bool:
    """Whether some medium of ctx's table emits (then the final gather runs for its
    light even without a photon map: integrator._photon_terms)."""
    return emission_table(ctx.table).shape[0] > 0


@kernel
def emission_integral(e, sigma_t, S):
    """integral_0^S exp(-sigma_t s) e ds for one channel: e (1 - exp(-sigma_t S)) /
    sigma_t, or its expansion e S (1 - sigma_t S / 2) below an optical depth of
    THIN_DEPTH (Cycles' volume_emission_integrate)."""
    tau = sigma_t * S
    if tau > THIN_DEPTH:
        return e * -math.expm1(-tau) / sigma_t
    return e * S * (1.0 - 0.5 * tau)


@kernel
def segment_emission(rows, material, e1, e2, sigma, emit, medium, d, t, src, L):
    """The emission along each ray's last segment: rows (n,) int64 the triangle each ray
    met (< 0: none: a lamp or the world, whose medium must be known), material (T,)
    int32, e1, e2 (T,3) the triangles' edges; medium (n,) int64 each ray's medium (-1:
    not known: media.segment_medium's back-face rule); d (n,3) the directions, t (n,)
    the segment lengths in units of |d| (not finite: skipped); sigma (M,3)
    media.absorption_table, emit (M,3) emission_table. Writes src (K,) the rays whose segment lay in an emitting medium and
    L (K,3) their emitted radiance per unit throughput; returns K."""
    k = 0
    for i in range(rows.shape[0]):
        r = rows[i]
        m_hit = material[r] if r >= 0 else 0
        m = segment_medium(e1, e2, r, m_hit, medium[i], sigma, d[i, 0], d[i, 1],
                           d[i, 2])
        if m < 0:
            continue
        if not (emit[m, 0] > 0.0 or emit[m, 1] > 0.0 or emit[m, 2] > 0.0):
            continue
        S = max(t[i], 0.0) * math.sqrt(d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1]
                                       + d[i, 2] * d[i, 2])
        if not S < math.inf:
            continue  # (a ray that met nothing in an object's medium: an open mesh)
        for c in range(3):
            L[k, c] = emission_integral(emit[m, c], sigma[m, c], S)
        src[k] = i
        k += 1
    return k


class MediumEmission:
    """The emitting media of one render context (None from for_context when none
    emits): the emission along rays' segments."""

    def __init__(self, ctx, emit):
        self.ctx = ctx
        self.sigma = media.absorption_table(ctx.table)
        self.emit = emit

    @classmethod
    def for_context(cls, ctx):
        emit = emission_table(ctx.table)
        return None if emit.shape[0] == 0 else cls(ctx, emit)

    def along(self, prim, d, t, medium, o=None):
        """(src (K,) int64, L (K,3)): the radiance emitted towards each ray's origin
        along its segment (segment_emission) for the rays src of prim (n,) (the triangles
        met; < 0: a lamp or the world, the medium then read from `medium`), d (n,3), t
        (n,) in units of |d|, medium (n,) int64; per unit of throughput at the segment's
        start. o (n,3): the segments' origins, which textured media need (their fields
        are integrated along the segment: engine/volumefields.py); None: a scene
        without them."""
        n = len(prim)
        src = np.empty(n, np.int64)
        L = np.empty((n, 3))
        if n == 0:
            return src, L
        rows, (material, e1, e2) = self.ctx.geo.hit_tables(prim, "material", "e1", "e2")
        k = segment_emission(np.ascontiguousarray(rows, np.int64),
                             np.ascontiguousarray(material, np.int32),
                             np.ascontiguousarray(e1, np.float64),
                             np.ascontiguousarray(e2, np.float64), self.sigma, self.emit,
                             np.ascontiguousarray(medium, np.int64),
                             np.ascontiguousarray(d, np.float64),
                             np.ascontiguousarray(t, np.float64), src, L)
        src, L = src[:k], L[:k]
        textures = getattr(getattr(self.ctx, "hetero", None), "textures", None)
        if textures is not None and k:
            if o is None:
                raise ValueError("MediumEmission.along: textured media need the segments' "
                                 "origins o")
            textures.integrate(o, d, t, src, L, self.sigma)
        return src, L


@register_warm_up
def _warm_up():
    """Compile (or load) the kernel on one segment leaving a unit triangle."""
    e1 = np.array([[1.0, 0.0, 0.0]])
    e2 = np.array([[0.0, 1.0, 0.0]])
    one = np.ones((1, 3))
    segment_emission(np.zeros(1, np.int64), np.zeros(1, np.int32), e1, e2, one, one,
                     np.full(1, -1, np.int64), np.array([[0.0, 0.0, 1.0]]), np.ones(1),
                     np.empty(1, np.int64), np.empty((1, 3)))
