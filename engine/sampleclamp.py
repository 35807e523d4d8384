"""Cycles' Light Paths > Clamping: each camera sample's light contributions capped.

Cycles (kernel/film/light_passes.h, film_clamp_light) scales every contribution L a path
writes to the film (L * throughput, RGB) so that |R| + |G| + |B| <= limit, keeping its
colour: L *= limit / sum when sum > limit; limit is sample_clamp_direct for light that
reaches the path's first surface (Cycles' bounce 0: a shadow ray from the first hit, or an
emitter / the world met by the camera ray or by the first hit's scattered ray) and
sample_clamp_indirect for everything after a further bounce. scene/integrator.cpp turns the
UI value v into limit = 3 v (the kernel sums three channels), and v = 0 into no limit.

Here the same limits apply to the camera pass's contributions (engine/integrator.py
_trace_paths): per camera sample and per contribution (an emitter or background hit, a
hit's direct light, its caustic estimate, its final gather (the mean of its rays; each
ray apart, its lookups and regathers and its chain's light, as Cycles clamps each path,
with integrator.CLAMP_PER_GATHER_RAY, on by default), its secondary caustic), with
the camera chain's bent bounces standing for Cycles' bounce. A caustic, glow or
secondary photon-map estimate is a smooth average of photons, each the end of a path
Cycles samples as one bright path (the camera's diffuse bounce, the specular chain
reversed, the emitter), so Clamp Indirect weighs each photon as that path is clamped
(engine/photonclamp.py: w_p = min(1, Q x limit / |tp x albedo x L_p|_1), L_p the
radiance the photon's path carries, which the photon pass keeps while the clamp is on, Q
the share of the limit Cycles' Russian roulette leaves that path, roulette_share), then
holds the estimate as a whole as well; where the estimate is taken for one sample of a block and
weighed up by the block's length, it is clamped before the weighing (as each of the
block's samples would be). The final gather's lookups are clamped as their ray's whole.

Where our camera path splits at glass and Cycles' chooses (integrator.SPLIT_GLASS_HITS:
the first glass hits continue both the reflection and the refraction, each weighted by
its Fresnel share C_b, where Cycles takes branch b with probability P_b and throughput
C_b / P_b), Cycles clamps the chosen path's whole value, so its expected contribution
is sum_b P_b min(C_b / P_b, L) = sum_b min(C_b, P_b L): each split branch is clamped
at P_b x the limit, and every later contribution of that path at the limit times the
product of the P_b it took (its clamp scale). P_b is the probability Cycles' glass
sampling gives that half (bsdf_microfacet.h, bsdf_microfacet_sample: pdf_reflect =
average(reflectance) / average(reflectance + transmittance) at the sampled microfacet
normal; the Fresnel reflectance on smooth clear glass; camerakernels.glass_both_share).
Clamping tp x rgb at scale x limit is clamping (tp / scale) x rgb at the limit: the
callers pass split_throughput(tp, scale) as the clamp's tp. Unclamped (a branch under
its share of the limit) nothing changes; a split branch over it loses what Cycles'
clamp takes from the samples that choose it (docs/accuracy.md, splitclamp46).
"""
from __future__ import annotations

import numpy as np

# Cycles' kernel limit per UI unit: the sum of three channels is compared.
CHANNELS = 3.0
# A glass split's halves clamped at their Cycles probability x the limit (above; False:
# each half at the whole limit, which let a split bottle through glass read ~1.15x
# Cycles, docs/accuracy.md newuser46).
SPLIT_SCALE = True


def limits(settings) -> tuple[float, float]:
    """(direct, indirect) limits on a contribution's |R| + |G| + |B| (radiance, W sr^-1 m^-2
    per sample, before exposure) from settings.clamp_direct / clamp_indirect (Cycles' UI
    values): 3 x the value, inf for 0 (off). Cycles' scene/integrator.cpp device_update."""
    return tuple(CHANNELS * v if v > 0 else np.inf
                 for v in (settings.clamp_direct, settings.clamp_indirect))


def enabled(settings) -> bool:
    """Either clamp is on."""
    return settings.clamp_direct > 0 or settings.clamp_indirect > 0


def bounce_limits(settings, bounces) -> np.ndarray | float:
    """The limit for each contribution from its Cycles bounce: bounces (K,) int64 (0:
    direct, > 0: indirect) -> (K,) float64. Both limits equal: that scalar."""
    direct, indirect = limits(settings)
    if direct == indirect:
        return direct
    return np.where(np.asarray(bounces) > 0, indirect, direct)


def clamp(rgb, tp=None, rows=None, limit=np.inf) -> np.ndarray:
    """rgb (K,3) scaled per row so that the contribution tp[rows] * rgb (tp (N,3) path
    throughput, None: 1; rows (K,) int64 into tp, None: row k is tp's k) has |R| + |G| + |B|
    at most limit (scalar or (K,)). Non-finite rows become 0, as Cycles' ensure_finite.
    Returns a new array when any row changes, rgb itself otherwise (bits kept)."""
    rgb = np.asarray(rgb, np.float64)
    if len(rgb) == 0:
        return rgb
    c = rgb if tp is None else (tp if rows is None else np.take(tp, rows, axis=0)) * rgb
    s = np.abs(c).sum(axis=1)
    cap = np.asarray(limit, np.float64)
    finite = np.isfinite(s)
    over = ~finite | (s > cap)
    if not over.any():
        return rgb
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(finite, np.where(s > cap, cap / s, 1.0), 0.0)
        out = rgb * scale[:, None]
    out[~finite] = 0.0  # (inf * 0 would be NaN)
    return out


def split_throughput(tp, scale):
    """The throughput the clamp reads for paths with clamp scale `scale` ((N,) float64,
    the product of the Cycles probabilities P_b of the glass halves each path took where
    it split; None: 1 for every path): tp / scale (N,3), so clamp(rgb,
    split_throughput(tp, scale), rows, limit) holds tp[rows] * rgb to limit x
    scale[rows]. tp itself (the same bits) where scale is None."""
    return tp if scale is None else tp / scale[:, None]
