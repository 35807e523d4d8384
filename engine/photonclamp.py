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
visual-importance RegionEmitter its light's.
Not followed: a flat passage's path state and a Soft Falloff light's first-hit scale
(photons._soft_falloff_at_first_hit) keep c as it was.

The light's first scatter (issue 14, docs/accuracy.md "clampnee56"). At the photon's
first hit x off a lobe with a density (diffuse, rough glossy or glass, sheen,
translucent), Cycles' path arriving at x from the photon's next vertex (direction wo)
reaches the light along wi = -d by two strategies, combined by the power heuristic
(kernel/integrator/shade_surface.h: integrate_surface_direct_light, its
light_sample_mis_weight_nee; the BSDF ray that meets the light: shade_light.h /
shade_background.h, light_sample_mis_weight_forward; kernel/light/common.h,
power_heuristic): next-event estimation with pdf p_l (the light's solid-angle pdf at x
x its pick probability) and weight w_l = p_l^2 / (p_l^2 + p_b^2), and BSDF sampling with
p_b (the closures' MIS pdf of wi given wo) and w_b = 1 - w_l. Each sample's value is
clamped on its own (kernel/film/light_passes.h, film_write_direct_light and
film_write_emission_or_background: film_clamp_light per contribution). With g = |tp x
f x Le x cos|_1 (the path's contribution density at wi) the expected clamped
contribution per unit solid angle is

    p_l min(g w_l / p_l, limit) + p_b min(g w_b / p_b, limit) = g x W,
    W = min(a, r x) + min(1 - a, x),  a = w_l,  r = p_l / p_b,  x = limit p_b / g

(mis_clamped_share). Without the pair (Cycles by BSDF sampling alone) it is g x min(1,
x): what w_p gives for c after the scatter as before, whose |L_p| stands for Le f cos /
p_b (L takes the lobe's f cos / pdf). W is concave and piecewise linear in x, 1 for
large x, (1 + r) x for small x (both strategies clamped): a single weight min(1, x / k)
equals it in both regimes with k = p_b / (p_l + p_b) (nee_share): c after the first
scatter is multiplied by k (photonkernels._scatter, light_pdf), i.e. L_p = Le f cos /
(p_l + p_b), the balance heuristic's value. Where one strategy is clamped and the other
not it gives more than W (e.g. r = 3: 0.8 for W = 0.7 at x = 0.2); exact at r = 1 and
as r -> 0 or inf. A 0.5-degree sun (p_l = 1 / Omega ~ 5e4 sr^-1) takes k
~ p_b Omega: L_p ~ E f cos, finite, as Cycles' light samples clamp it. Later scatters
keep c / scale: the path's other vertices (towards the camera) are BSDF-sampled by
Cycles, one strategy only; a delta lobe (smooth mirror or glass) at x keeps c too: there
Cycles reaches the light by BSDF sampling alone. Approximations: p_b is reverse_pdf's
(the lobes' albedo maxima as their pick weights, the diffuse weight's mean); the lobe's
own f cos / pdf stands for the material's f cos / p_b (exact for one lobe; a Transparent
share or a second lobe makes it differ); p_l (light_pdfs) is our camera side's light
pdf (integrator.mis_light_pdf) x the pick of a light tree over the lights Cycles
samples (cycles_light_pick: our tree's pmf, whatever the camera side does, which gives
each light its own shadow rays up to SAMPLE_ALL_UP_TO lights), the world's with the
hit's geometric normal for its shading normal; emissive meshes, lights whose shadow
rays do not see surfaces (no SHADOW visibility) and a world of constant colour without
portals (Cycles switches its light samples off: cycles_samples_world) keep c.
"""
from __future__ import annotations

import math

import numpy as np

from . import sampleclamp
from .meshphotons import emitted_triangles

# Per-photon Clamp Indirect (above). False: the estimates are clamped as a whole only
# (sampleclamp: each sample's estimate), the photon pass keeps no radiance.
PER_PHOTON = True
# A photon's first scatter off a lobe with a density takes Cycles' light-sample strategy
# there into its c (nee_share, photonkernels._scatter's light_pdf; docs/accuracy.md
# "clampnee56"); False: c as that scatter's BSDF sample alone (over-clamps the glow of
# small bright lights).
NEE_FIRST_SCATTER = True
# The limit x Cycles' Russian roulette share along the photon's path (roulette_share);
# False: the whole limit (Cycles with Min Light Bounces past the path's length).
ROULETTE = True
# Cycles' Light Paths > Min Light Bounces (no roulette at path bounce <= it + 1:
# roulette_share); the add-on does not read it, Blender's default.
MIN_LIGHT_BOUNCES = 0


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


def mis_clamped_share(x, p_light, p_bsdf) -> np.ndarray:
    """(...) float64 W: the share of a path's contribution density g at a light-adjacent
    vertex that Cycles keeps in expectation when it reaches the light there by light
    sampling (pdf p_light) and BSDF sampling (p_bsdf), power-heuristic weighted, each
    sample clamped to the limit on its own: W = min(a, r x) + min(1 - a, x), a = p_l^2 /
    (p_l^2 + p_b^2), r = p_l / p_b, x = limit x p_b / g (module docstring). Broadcast;
    p_bsdf > 0."""
    x = np.asarray(x, np.float64)
    pl = np.asarray(p_light, np.float64)
    pb = np.asarray(p_bsdf, np.float64)
    a = pl * pl / (pl * pl + pb * pb)
    return np.minimum(a, pl / pb * x) + np.minimum(1.0 - a, x)


def nee_share(p_light, p_bsdf) -> np.ndarray:
    """(...) float64 k = p_b / (p_l + p_b): the factor on c = |L|_1 / |flux|_1 at a
    photon's first scatter off a lobe with a density (photonkernels._scatter's light_pdf):
    min(1, x / k) equals mis_clamped_share where both strategies are clamped and where
    neither is (module docstring). p_light <= 0 (no light sample): 1."""
    pl = np.maximum(np.asarray(p_light, np.float64), 0.0)
    pb = np.asarray(p_bsdf, np.float64)
    return pb / (pl + pb)


def light_pdfs(ctx, light, x, wi, ng, slot=None) -> np.ndarray:
    """(M,) float64 p_l: the solid-angle pdf (1/sr) with which the camera side's shadow
    rays at points x (M,3) sample unit directions wi (M,3) towards `light` (the photons'
    light: a Light, a LightGroup, whose members take their slots in order, or a
    RegionEmitter, its light's), times the probability that Cycles' light tree picks it
    there (cycles_light_pick's LightSelector.pmf with normals ng; 1 for a lone light):
    Cycles' p_l of the next-event strategy at a photon's first scatter (module
    docstring). ng (M,3): the hits' normals (the world's cosine sampling and the tree's
    orientation bound). 0: a light not sampled that way (delta lights, emissive meshes,
    lights whose shadow rays are off, a world of constant colour without portals, which
    Cycles does not light-sample: cycles_samples_world; Cycles' pair does not apply, c
    kept)."""
    x = np.asarray(x, np.float64).reshape(-1, 3)
    wi = np.asarray(wi, np.float64).reshape(-1, 3)
    ng = np.asarray(ng, np.float64).reshape(-1, 3)
    m = len(x)
    if hasattr(light, "counts") and hasattr(light, "lights"):
        out, lo = np.zeros(m), 0
        s = np.asarray(slot, np.int64)
        for member, c in zip(light.lights, light.counts):
            sel = np.flatnonzero((s >= lo) & (s < lo + c))
            if len(sel):
                out[sel] = light_pdfs(ctx, member, x[sel], wi[sel], ng[sel])
            lo += c
        return out
    from .visualimportance import RegionEmitter
    if isinstance(light, RegionEmitter):
        light = light.light
    from .geometry import SHADOW
    from .integrator import mis_light_pdf
    from .lights.world import WORLD
    from .scene import AREA, POINT, SPOT, SUN
    kind = getattr(light, "kind", None)
    if not m or not int(getattr(light, "ray_kinds", 0)) & SHADOW:
        return np.zeros(m)
    if kind == SUN:
        if not light.has_size:
            return np.zeros(m)
        pdf = np.full(m, 1.0 / light.solid_angle)
    elif kind == WORLD:
        if not cycles_samples_world(light):
            return np.zeros(m)
        pdf = light.pdf(wi, ng, x)
    elif kind in (POINT, SPOT):
        if not light.radius > 0:
            return np.zeros(m)
        pdf = mis_light_pdf(light, x, wi, np.full(m, np.inf))
    elif kind == AREA:
        # (the distance along wi to the light's plane: mis_light_pdf's t)
        n_l = np.asarray(light.dir, np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((np.asarray(light.pos, np.float64) - x) @ n_l) / (wi @ n_l)
        t = np.where(np.isfinite(t) & (t > 0.0), t, np.inf)
        pdf = np.where(np.isfinite(t), mis_light_pdf(light, x, wi, np.where(
            np.isfinite(t), t, 1.0)), 0.0)
    else:
        return np.zeros(m)
    pick = cycles_light_pick(ctx) if ctx is not None else None
    if pick is not None:
        idx = [k for k, other in enumerate(ctx.lights) if other is light]
        pdf = pdf * (pick.pmf(x, ng, idx[0]) if idx else 1.0)
    return np.where(np.isfinite(pdf) & (pdf > 0.0), pdf, 0.0)


def cycles_samples_world(light) -> bool:
    """Whether Cycles takes light samples of this world: only where it varies (an
    environment map) or has light portals. A constant colour's background light is
    switched off (scene/light.cpp test_enabled_lights, "Background MIS has been
    disabled"), so BSDF rays alone reach it."""
    return (getattr(light, "environment", None) is not None
            or len(getattr(light, "portal_rects", ())) > 0)


def cycles_light_pick(ctx):
    """A LightSelector over the lights Cycles' light tree picks among for one light
    sample (the lights shadow rays see, without a world Cycles does not sample:
    cycles_samples_world), whether or not our camera side gives each its own shadow rays
    (lights.selection.SAMPLE_ALL_UP_TO); None with one light or none (its pick is 1).
    Built once per context."""
    from .geometry import SHADOW
    from .lights.selection import LightSelector
    from .lights.world import WORLD
    cache = ctx.light_selectors
    if "cycles_pick" in cache:
        return cache["cycles_pick"]
    members = [li for li, light in enumerate(ctx.lights)
               if light.ray_kinds & SHADOW and light.shadow_sampled
               and not (light.kind == WORLD and not cycles_samples_world(light))]
    pick = LightSelector(ctx.lights, members) if len(members) > 1 else None
    cache["cycles_pick"] = pick
    return pick


def roulette_share(scale, chain, bounce=0) -> np.ndarray:
    """(...) float64 Q: the share of the limit a Cycles path along a photon keeps on
    average once its Russian roulette is counted. Cycles (kernel/integrator/
    intersect_closest.h, integrator_intersect_terminate, and path_state.h,
    path_state_continuation_probability) plays the roulette at each surface hit, before
    that hit is shaded (so before its next-event estimation), with q = min(1, sqrt(max
    throughput)), and divides the throughput by q (shade_surface.h, integrate_surface)
    before any light further on is clamped: the clamped value L' = min(L / Q, limit)
    survives with probability Q = prod q, so on average min(L, Q x limit). A hit that
    meets a light or the background plays none (shade_light / shade_background), nor does
    a hit at path bounce <= Min Light Bounces + 1 (scene/integrator.cpp stores
    kintegrator->min_bounce = min_bounce + 1; the camera's first hit is bounce 0): with
    Blender's default Min Light Bounces 0 the camera's first two hits play none. After the
    camera's diffuse bounce at path bounce `bounce` (...) (the camera chain's bounces
    before it, B_TOTAL: 0 at the camera's first hits) the throughput is t0 = max(scale)
    (the camera path's throughput x albedo); the photon's `chain` (...) scatters back to
    the light are the path's hits at bounces bounce + 1 .. bounce + chain, the first free
    = max(0, MIN_LIGHT_BOUNCES + 1 - bounce) of them without roulette, and along a white
    chain (smooth clear glass: Cycles' Fresnel pick keeps the throughput) the i-th played
    takes q_i = t0^(2^-i): Q = t0^(1 - 2^-(chain - free)), 1 where t0 >= 1 or chain <=
    free (docs/accuracy.md "### roulette54", "### roulette56"). The reading vertex's own
    roulette and the camera side's before it are not counted (its throughput is the
    camera path's; through clear glass ~1: q = 1). scale (..., 3) broadcast against chain
    and bounce."""
    t0 = np.max(np.abs(np.asarray(scale, np.float64)), axis=-1)
    free = np.maximum(MIN_LIGHT_BOUNCES + 1 - np.asarray(bounce, np.float64), 0.0)
    k = np.maximum(np.asarray(chain, np.float64) - free, 0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = np.where((t0 > 0.0) & (t0 < 1.0), t0 ** (1.0 - np.exp2(-k)), 1.0)
    return np.where(np.isfinite(q), q, 1.0)


def photon_weights(radiance, power, scale, limit, chain=None, bounce=0) -> np.ndarray:
    """(...) float64 w_p = min(1, Q x limit / |scale x L_p|_1) for photons with |L_p|_1
    `radiance` (...) and flux `power` (..., 3) (L_p of the flux's colour) at rows whose
    clamp throughput x albedo is `scale` (..., 3) (broadcast); limit: Clamp Indirect's
    (sampleclamp.limits); chain (...): each photon's scatters since the light (Q:
    roulette_share, with the rows' camera path bounce `bounce`; None: Q = 1). |L_p|_1 = 0
    or no flux: 1."""
    power = np.asarray(power, np.float64)
    flux = np.abs(power).sum(axis=-1)
    c = np.abs(np.asarray(scale, np.float64) * power).sum(axis=-1)
    if chain is not None and ROULETTE:
        limit = limit * roulette_share(scale, chain, bounce)
    with np.errstate(divide="ignore", invalid="ignore"):
        contrib = np.where(flux > 0, np.asarray(radiance, np.float64) * c / flux, 0.0)
        w = np.where(contrib > limit, limit / contrib, 1.0)
    return np.where(np.isfinite(w), w, 1.0)
