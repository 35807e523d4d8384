"""Cycles' Clamp Indirect on photon-map estimates: each photon clamped as the path it is.

A caustic (glow, secondary) estimate at a camera hit sums photons, each the end of a path
Cycles would sample as one bright path: the camera's diffuse bounce, the specular chain
reversed, the emitter. Cycles (kernel/film/light_passes.h, film_clamp_light) scales that
path's contribution C = tp x albedo x L_p (tp the camera path's throughput, albedo the
diffuse lobe's f x pi, L_p = Le x T the radiance along the photon's last segment: the
emitter's radiance Le times the chain's throughput T) so that |C|_1 <= limit. The
estimate here weighs photon p by

    w_p = min(1, Q x limit / |tp x albedo x L_p|_1)

with Q the share of the limit Cycles' Russian roulette leaves such a path on average
(roulette_share; docs/accuracy.md, "clampray53", "clampphoton54" and "roulette54"). L_p is not the photon's flux
(which shrinks with the photon count): flux = L_p x cos / (pdf_pos pdf_dir N) x prod
1/q_i (q_i the roulette's pick probabilities, eta^2 at refractions), so the photon pass
keeps c = |L|_1 / |flux|_1 per ray (photonkernels._scatter's clamp / nx_clamp: set at
emission by emission_ratios, divided by each scatter's scale, kept by a copy passing
behind a surface its kinds do not see; a volume scatter multiplies it by its roulette's
survival probability, photonmedium.PhotonScattering.flights) and stores |L_p|_1 =
c x |flux|_1 (Photons.radiance, float32). L_p has the flux's colour, so
|tp x albedo x L_p|_1 = |L_p|_1 x sum_c(tp_c albedo_c flux_c) / |flux|_1.

Lights: area, spot and point lights with a radius (Cycles' sphere / disk lights) and a
sun with an angle: Le as their own intersect / seen_at_infinity give it; the world:
the background's radiance along the photon's direction; emissive meshes: the radiance
of the triangle each photon left (emitted_triangles). Delta lights (a point or spot of
radius 0, a sun of angle 0): Cycles cannot sample a caustic path that ends on them, so
no clamp (|L_p|_1 = 0, w = 1). Grouped lights (lights/group.py) take each member's; a
visual-importance RegionEmitter none (CLAMP_REGION_PHOTONS: its light's when on).
Not followed: a flat passage's path state and a Soft Falloff light's first-hit scale
(photons._soft_falloff_at_first_hit) keep c as it was.
"""
from __future__ import annotations

import math

import numpy as np

from . import sampleclamp
from .photonlayout import decode_power
from .photonkernels import B_TOTAL
from .meshphotons import emitted_triangles

# Per-photon Clamp Indirect (above). False: the estimates are clamped as a whole only
# (sampleclamp: each sample's estimate), the photon pass keeps no radiance.
PER_PHOTON = True
# A visual-importance RegionEmitter's photons take their light's |Le| (True) or keep
# no clamp (False, as before clampleft55 gave them one). Off: |Le| of a small sun (Le =
# E / its solid angle) over-clamps the glow photons whose first scatter is a rough lobe,
# where Cycles reaches the sun by next-event estimation and clamps tp x f x E cos, not
# tp x Le: with it on, tests/blender/test_hair_cycles.py's tuft (a 0.5-degree sun, hair
# of roughness 0.6) read blocks 0.908 of clamped Cycles (0.92 its bound). The natural
# photons of such a light are over-clamped the same way (s55 note: next to fix).
CLAMP_REGION_PHOTONS = False
# The limit x Cycles' Russian roulette share along the photon's path (roulette_share);
# False: the whole limit (Cycles with Min Light Bounces past the path's length).
ROULETTE = True


def keeps_radiance(settings) -> bool:
    """Whether the photon pass keeps each photon's |L|_1: PER_PHOTON and Clamp Indirect
    on (a finite limit)."""
    return PER_PHOTON and np.isfinite(sampleclamp.limits(settings)[1])


def emitted_radiance(light, o, d, slot=None, key=None) -> np.ndarray:
    """(M,) float64 |Le|_1 (W sr^-1 m^-2, summed over RGB) of the light `light` along
    photons leaving o (M,3) in unit directions d (M,3): the radiance a Cycles path
    meeting the light along -d reads (0: a delta light or one not handled, module
    docstring). slot (M,) and key: the photons' emission slots and key, which a mesh
    light of several radiances needs (emitted_triangles; without them: 0 there)."""
    from .scene import AREA, POINT, SPOT, SUN, spread_attenuation
    from .lights.mesh import MESH
    from .lights.world import WORLD
    m = len(d)
    zero = np.zeros(m)
    from .visualimportance import RegionEmitter
    if isinstance(light, RegionEmitter):
        if not CLAMP_REGION_PHOTONS:
            return zero
        light = light.light  # (aimed at a region: its light's photons)
    kind = getattr(light, "kind", None)
    d = np.asarray(d, np.float64)
    if kind == SUN:
        if not light.has_size:
            return zero
        return np.full(m, float(np.abs(light.sun_radiance).sum()))
    if kind == WORLD:
        env = light.environment
        if env is not None:
            return np.abs(env.radiance(-d)).sum(axis=1)
        return np.full(m, float(np.abs(np.asarray(light.radiance, np.float64)).sum()))
    if kind in (POINT, SPOT):
        if not light.radius > 0:
            return zero
        # A ray from beyond the light back along -d: the radiance its shape (sphere or
        # facing disk) shows that way, the spot's mask included (PointLight.intersect).
        r = float(light.radius)
        start = np.asarray(light.pos, np.float64)[None, :] + d * (4.0 * r)
        mask, _, L = light.intersect(start, -d, np.full(m, 8.0 * r))
        return np.where(mask, np.abs(np.asarray(L, np.float64)).sum(axis=1), 0.0)
    if kind == AREA:
        # (the photon left the light's front: its radiance along d, Cycles' spread
        # attenuation at the angle to the light's axis; no ray needed, which far from the
        # origin could miss the light by float32 rounding)
        Le = float(np.abs(np.asarray(light.radiance, np.float64)).sum())
        if light.spread < math.pi:
            cos_a = d @ np.asarray(light.dir, np.float64)
            return Le * spread_attenuation(cos_a, light.spread)
        return np.full(m, Le)
    if kind == MESH:
        sums = np.abs(np.asarray(light.tri_L, np.float64)).sum(axis=1)
        if len(sums) and np.allclose(sums, sums[0], rtol=1e-6, atol=0.0):
            return np.full(m, float(sums[0]))
        if slot is None or key is None or not len(sums):
            return zero
        return sums[emitted_triangles(light, key, slot)]
    return zero


def emission_ratios(light, o, d, power, slot, key=None) -> np.ndarray:
    """(M,) float64 c = |Le|_1 / |power|_1 (0 where no power) of the photons just
    emitted (photonkernels._scatter's clamp): origins o (M,3), unit directions d (M,3),
    power (M,3) W, emission slots (M,) int, key: the emission key (uint64; a mesh light
    of several radiances needs it, emitted_radiance)."""
    slot = np.asarray(slot, np.int64)
    if not len(slot):
        return np.zeros(0)
    flux = np.abs(np.asarray(power, np.float64)).sum(axis=1)
    if hasattr(light, "counts") and hasattr(light, "lights"):
        # A LightGroup (lights/group.py): each member's photons take the slots after the
        # members' before it, in order.
        Le, lo = np.zeros(len(slot)), 0
        for member, c in zip(light.lights, light.counts):
            sel = np.flatnonzero((slot >= lo) & (slot < lo + c))
            Le[sel] = emitted_radiance(member, np.asarray(o)[sel], np.asarray(d)[sel],
                                       slot[sel], key)
            lo += c
    else:
        Le = emitted_radiance(light, o, d, slot, key)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(flux > 0, Le / flux, 0.0)
    return np.where(np.isfinite(c), c, 0.0)


def roulette_share(scale, chain) -> np.ndarray:
    """(...) float64 Q: the share of the limit a Cycles path along a photon keeps on
    average once its Russian roulette is counted. Cycles (kernel/integrator/path_state.h,
    path_state_continuation_probability) continues a path at each hit past bounce
    min_light_bounces (0) with q = min(1, sqrt(max throughput)) and divides the
    throughput by q (shade_surface.h, integrate_surface) before the light further on is
    clamped: the clamped value L' = min(L / Q, limit) survives with probability Q = prod
    q, so on average min(L, Q x limit). After the camera's diffuse bounce the throughput
    is t0 = max(scale) (the camera path's throughput x albedo); each of the photon's
    `chain` (...) scatters back to the light is a hit, and along a white chain (smooth
    clear glass: Cycles' Fresnel pick keeps the throughput) the i-th takes q_i =
    t^(2^-i): Q = t0^(1 - 2^-chain), 1 where t0 >= 1 (docs/accuracy.md
    "### roulette54": measured against Cycles with the roulette off). scale (..., 3)
    broadcast against chain."""
    t0 = np.max(np.abs(np.asarray(scale, np.float64)), axis=-1)
    k = np.asarray(chain, np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = np.where((t0 > 0.0) & (t0 < 1.0), t0 ** (1.0 - np.exp2(-k)), 1.0)
    return np.where(np.isfinite(q), q, 1.0)


def photon_weights(radiance, power, scale, limit, chain=None) -> np.ndarray:
    """(...) float64 w_p = min(1, Q x limit / |scale x L_p|_1) for photons with |L_p|_1
    `radiance` (...) and flux `power` (..., 3) (L_p of the flux's colour) at rows whose
    clamp throughput x albedo is `scale` (..., 3) (broadcast); limit: Clamp Indirect's
    (sampleclamp.limits); chain (...): each photon's scatters since the light (Q:
    roulette_share; None: Q = 1). |L_p|_1 = 0 or no flux: 1."""
    power = np.asarray(power, np.float64)
    flux = np.abs(power).sum(axis=-1)
    c = np.abs(np.asarray(scale, np.float64) * power).sum(axis=-1)
    if chain is not None and ROULETTE:
        limit = limit * roulette_share(scale, chain)
    with np.errstate(divide="ignore", invalid="ignore"):
        contrib = np.where(flux > 0, np.asarray(radiance, np.float64) * c / flux, 0.0)
        w = np.where(contrib > limit, limit / contrib, 1.0)
    return np.where(np.isfinite(w), w, 1.0)


def list_weights(pmap, read, qrows, slots, scale, limit):
    """Clamp Indirect's photon_weights over an estimate's read lists, for
    photonvisibility._visible_sums: read = (count, photons) (photonvisibility.
    _estimate_read's lists, (L,) and (L, W)), qrows (Q,) the rows of the block whose
    lists slots (Q,) are whole, scale (B,3) each row's clamp throughput x albedo, limit
    Clamp Indirect's. Returns None where no listed photon is over the limit (every
    weight 1: the estimates keep their bits), else (rows (V,), slots (V,), clamp_w (L,
    W) float64): the rows with some photon over the limit, their lists, and each listed
    photon's w_p (1 past a list's count and for lists not in slots)."""
    radiance = pmap.photons.radiance
    if radiance is None or not len(qrows):
        return None
    count, photons = read
    c = np.take(count, slots)
    width = int(c.max()) if len(c) else 0
    if width == 0:
        return None
    lists = np.take(photons, slots, axis=0)[:, :width]
    inside = np.arange(width)[None, :] < c[:, None]
    ph = np.where(inside, lists, 0)
    pw = pmap.photons.power
    pw = decode_power(pw[ph.reshape(-1)]) if pw.dtype == np.uint8 else \
        pw[ph.reshape(-1)].astype(np.float64)
    pw = pw.reshape(len(qrows), width, 3)
    bounces = getattr(pmap.photons, "bounces", None)
    chain = None if bounces is None else bounces[ph, B_TOTAL]
    w = photon_weights(radiance[ph], pw, np.take(scale, qrows, axis=0)[:, None, :], limit,
                       chain)
    w = np.where(inside, w, 1.0)
    over = np.flatnonzero((w < 1.0).any(axis=1))
    if not len(over):
        return None
    clamp_w = np.ones(photons.shape)
    clamp_w[np.asarray(slots, np.int64)[:, None], np.arange(width)[None, :]] = w
    return (np.asarray(qrows, np.int64)[over], np.asarray(slots, np.int64)[over], clamp_w)
