"""Single scattering in homogeneous media, seen by the camera: fog in a box lit by lamps.

A medium (engine/media.py) with a scattering coefficient sigma_s (Material.scattering,
(3,) 1/m) scatters light into every camera segment that crosses it. Along a segment of
length S inside the medium, with the path's throughput beta at its start, the radiance
added is (the volume rendering equation's single-scattering term; Cycles:
intern/cycles/kernel/integrator/shade_volume.h, homogeneous media)

    L_s = beta  integral_0^S  T(s) sigma_s  L_in(x(s))  ds,
    L_in(x) = integral_sphere  p(wo, wi)  L_light(x, wi)  T_shadow(x, wi)  dwi,

T(s) = exp(-sigma_t s) per channel (sigma_t = sigma_a + sigma_s, media.absorption_table)
and p the Henyey-Greenstein phase function of the material's anisotropy g (Cycles'
phase_henyey_greenstein, intern/cycles/kernel/closure/volume_util.h):
p = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5), cos = d . wi for a ray along d and light
arriving from wi (g > 0: forward scattering, the glow around a light seen through fog).

One distance a segment (sample_segments): s drawn from the exponential of the channels'
mean extinction truncated to [0, S] (pbrt-v4's ratio-free homogeneous sampling, its pdf
exact) or, for a share of the segments set by their optical depth against the lamps'
peaks (adaptive_share) when point, spot or area lights light part of them,
equiangularly towards one of them (Kulla & Fajardo 2012, "Importance Sampling
Techniques for Path Tracing in Participating Media": the 1 / r^2 near a lamp sampled
where it peaks, widened by a lamp's radius or an area light's size) over the part of
the segment it can light (a spot's cone, an area light's front side and spread:
lit_interval, as Cycles' spot_light_valid_ray_segment and area_light_valid_ray_segment),
the pdf the strategies' mixture; the estimate T(s) sigma_s / pdf(s) per channel. The
camera segments' numbers are stratified over the pixel's samples. At that point the lights are
sampled as at a surface (engine/directlight.py sample_lights, every light kind, the light
tree), with the point's "normal" the ray's direction and its opposite in two halves
(the surface's cosine, which sample_lights folds into its irradiance, divided out again;
each half an unbiased estimate of its hemisphere's light), shadow rays through the
scene's transparent surfaces and media (shadowtransmittance: a shadow ray leaves the fog
through the box's back face and keeps exp(-sigma_t distance); one that meets no surface
lies wholly in the fog, a lamp inside it, and keeps exp(-sigma_t length)), and weighted
by the phase function (accumulate_phase). The surface behind keeps T(S) (media.attenuated).

Volume bounces (Cycles' Light Paths > Volume bounces, default 0): from the first scatter
point the path scatters on inside the medium that many more times (CameraScattering.walk:
a Henyey-Greenstein direction, a distance in the segment to the next surface, the lamps'
light at each point), the medium-only part of multiple scattering.

Emitting media (engine/volumeemission.py): the glow scattered towards the ray is the
emission along one more phase-sampled segment from each scatter point (walk), as Cycles'
path collects it after its last volume bounce.

Limits (docs/compatibility.md, Volume scattering): the lamps' light only (and the
glow's), at points inside the medium. Photons and final-gather rays are dimmed by the extinction but do not scatter
in the medium (the fog's glow after a second scatter onto the surfaces, and the surfaces'
light scattered in the fog, are missing: measured in docs/accuracy.md, volscatter36); a
walk whose distance falls beyond its segment ends there. Seeded: the numbers come from the camera path's own
stream (integrator._trace_paths), so an image is the same for any worker count.
"""
from __future__ import annotations

import math

import numpy as np

from . import media, volumeemission, worldmedium
from .media import segment_medium
from .directlight import DirectLightBuffers, NO_HROWS, NO_ROWS, NO_ROWS3, sample_lights
from .jit import kernel, register_warm_up
from .lights import packing as pk
from .lights.packing import pack_lights
from .lights.selection import empty_tree

FOUR_PI = 4.0 * math.pi
# Equiangular sampling towards point, spot and area lights for part of the segments'
# distances (sample_segments); False: the exponential alone (docs/accuracy.md,
# volscatter36). The module switches below are read at each render / call (none is
# compiled into the kernels): bench/bench_fog_area_cycles.py measures each against
# Cycles (docs/accuracy.md, fog37).
EQUIANGULAR = True
EQUIANGULAR_AREA = True  # area lights among them (fog37; False: point / spot only)
MAX_EQUIANGULAR = 8  # the strongest point / spot / area lights it aims at
# The exponential strategy's share of a segment's distances when equiangular lights light
# part of it: adaptive_share, the optical depth tau against rho, how far the equiangular
# pdf departs from uniform over the segment (equiangular_gain), clamped to
# [EXP_SHARE_THIN, EXP_SHARE_THICK] (fog37 measured it against a share set by the optical
# depth alone, s36's fixed 1/2, docs/accuracy.md; that switch is gone since s38). It never
# reaches 0: the exponential is the only strategy for the sun, the world, mesh lights and
# the lamps beyond MAX_EQUIANGULAR, and it covers what the lit intervals clip away.
EXP_SHARE_THIN = 0.1
EXP_SHARE_THICK = 0.9
# An area light is aimed at its centre with its peak widened by AREA_WIDEN x sqrt(A / pi)
# (a Lambertian disk of radius R gives a point on its axis at distance z light in
# proportion to R^2 / (z^2 + R^2)); fog37 measured aiming at a point drawn uniformly on
# it, as Cycles aims at its light sample, noisier (that switch is gone since s38).
AREA_WIDEN = 1.0
EQ_RADIUS = True  # a lamp's radius widens its equiangular peak (_equiangular)
# The camera segments' distance numbers (the strategy's choice and the distance)
# stratified over a pixel's samples (the camera pass's ("volume",) dimension,
# integrator._trace_paths); False: drawn at random.
STRATIFIED = True


def scattering_tables(table):
    """(sigma_t (M,3), sigma_s (M,3), g (M,)) float64 of the material table, or None when
    no material scatters (then nothing in this module runs)."""
    scat = getattr(table, "scattering", None)
    if scat is None:
        return None
    scat = np.ascontiguousarray(scat, np.float64).reshape(-1, 3)
    if not np.any(scat > 0):
        return None
    g = getattr(table, "anisotropy", None)
    g = (np.zeros(len(scat)) if g is None
         else np.clip(np.ascontiguousarray(g, np.float64), -0.999, 0.999))
    return media.absorption_table(table), scat, np.ascontiguousarray(g)


@kernel
def hg_phase(cos_theta, g):
    """Henyey-Greenstein phase function (1/sr) at cos_theta = d . wi (Cycles'
    phase_henyey_greenstein; isotropic 1 / 4 pi at g = 0)."""
    t = 1.0 + g * g - 2.0 * g * cos_theta
    return (1.0 - g * g) / (FOUR_PI * t * math.sqrt(max(t, 1e-300)))


@kernel
def _equiangular(ox, oy, oz, dx, dy, dz, S, cx, cy, cz, radius):
    """(t0, D, theta_a, theta_b) of equiangular sampling (Kulla & Fajardo 2012) on the
    segment o + s d, s in [0, S] (d unit), towards the point c: t0 the foot of c on the
    line, D its distance (floored), theta_a, theta_b the angles of the segment's ends.
    A lamp of radius r > 0 gives D = sqrt(dist^2 + r^2): the pdf 1 / (D^2 + x^2) then
    follows a soft-falloff lamp's I / (d^2 + r^2) (engine/lights/point.py), which stays
    finite where the ray passes within r of its centre; aimed at the centre alone, a ray
    passing at distance D << r drew its distances in a peak of width D, the light's
    spread over r, and the weights reached pi I / D (fog37: the rare bright samples of
    the god ray's cone)."""
    t0 = (cx - ox) * dx + (cy - oy) * dy + (cz - oz) * dz
    qx, qy, qz = ox + t0 * dx - cx, oy + t0 * dy - cy, oz + t0 * dz - cz
    D = max(math.sqrt(qx * qx + qy * qy + qz * qz + radius * radius), 1e-9)
    return t0, D, math.atan2(-t0, D), math.atan2(S - t0, D)


# eq rows (equiangular lights): position 0-2 (an area light's centre), the spot's or
# area light's axis 3-5 (the direction it emits along), the cosine of its bounding cone
# 6 (<= 0: a point light, an area light of spread 180 degrees, or a cone too wide to
# clip), the apex's pull-back along the axis 7 (a spot of radius r emits from a disk: the
# cone through its rim; an area light of spread < 180: the cone through its outline),
# 8: 1 for an area light (lit only in front of its plane; aimed at its centre), its
# edges 9-11 and 12-14 (size_x u, size_y v), 15: 1 for a disk / ellipse, 16: a point or
# spot light's radius (_equiangular widens its peak by it).
EQ_COLUMNS = 17
NO_POINTS = np.zeros((0, EQ_COLUMNS))  # no equiangular lights


@kernel
def equiangular_gain(ox, oy, oz, ux, uy, uz, S, a, b, cx, cy, cz, radius):
    """How far equiangular sampling towards c (radius: _equiangular's widening) over the
    lit part [a, b] of the segment o + s u, s in [0, S], departs from uniform sampling of
    the segment: the log-range of its pdf 1 / (D^2 + x^2) over [a, b] plus
    log(S / (b - a)) (what clipping to the lit part gains). adaptive_share sets it
    against the exponential's own log-range, the optical depth."""
    ta, D, tha, thb = _equiangular(ox + ux * a, oy + uy * a, oz + uz * a, ux, uy, uz,
                                   b - a, cx, cy, cz, radius)
    xa, xb = -ta, (b - a) - ta
    near = 0.0 if xa <= 0.0 <= xb else min(abs(xa), abs(xb))
    far = max(abs(xa), abs(xb))
    return math.log((D * D + far * far) / (D * D + near * near)) + math.log(S / (b - a))


@kernel
def adaptive_share(tau, rho, n_lit, lo, hi):
    """The exponential's share when lights light part of the segment (n_lit > 0; else
    1): tau / (tau + rho), the optical depth tau (the log-range of the exponential's
    pdf) against rho (equiangular_gain's, the largest over the lights), clamped to
    [lo, hi]; 1/2 when both are about 0 (both strategies all but uniform)."""
    if n_lit == 0:
        return 1.0
    if not tau + rho > 1e-3:
        return 0.5
    return min(max(tau / (tau + rho), lo), hi)


@kernel
def lit_interval(ox, oy, oz, ux, uy, uz, S, eq, j):
    """(a, b) the part of the segment o + s u, s in [0, S] (u unit), that light row j of
    eq (EQ_COLUMNS) can light: all of it for a point light, else where the segment is
    inside the spot's bounding cone (apex pulled back by eq[j, 7]); for an area light
    (eq[j, 8] = 1) the part in front of its plane, inside the cone that bounds its
    spread when it has one; a > b: none. As Cycles clips a ray segment before
    equiangular sampling (kernel/light/spot.h spot_light_valid_ray_segment,
    kernel/light/area.h area_light_valid_ray_segment)."""
    a, b = _cone_interval(ox, oy, oz, ux, uy, uz, S, eq, j)
    if eq[j, 8] > 0.0 and b > a:
        # In front of the area light's plane: (x - pos) . axis > 0.
        h0 = ((ox - eq[j, 0]) * eq[j, 3] + (oy - eq[j, 1]) * eq[j, 4]
              + (oz - eq[j, 2]) * eq[j, 5])
        hu = ux * eq[j, 3] + uy * eq[j, 4] + uz * eq[j, 5]
        if hu > 0.0:
            a = max(a, -h0 / hu)
        elif hu < 0.0:
            b = min(b, -h0 / hu)
        elif not h0 > 0.0:
            return S, 0.0
    return a, b


@kernel
def _cone_interval(ox, oy, oz, ux, uy, uz, S, eq, j):
    """lit_interval's cone part ((0, S) without a cone, eq[j, 6] <= 0). The cone's
    forward nappe is convex, so the inside of a line is one interval: the segment is cut
    at the roots of the cone's quadric and the apex plane, and the pieces whose
    midpoints are inside are joined."""
    c = eq[j, 6]
    if not c > 0.0:
        return 0.0, S
    ax, ay, az = eq[j, 3], eq[j, 4], eq[j, 5]
    px = eq[j, 0] - ax * eq[j, 7]
    py = eq[j, 1] - ay * eq[j, 7]
    pz = eq[j, 2] - az * eq[j, 7]
    wx, wy, wz = ox - px, oy - py, oz - pz
    wa = wx * ax + wy * ay + wz * az
    ua = ux * ax + uy * ay + uz * az
    wu = wx * ux + wy * uy + wz * uz
    ww = wx * wx + wy * wy + wz * wz
    c2 = c * c
    qa = ua * ua - c2
    qb = 2.0 * (wa * ua - c2 * wu)
    qc = wa * wa - c2 * ww
    cuts = np.empty(5)
    cuts[0] = 0.0
    cuts[1] = S
    nc = 2
    if abs(qa) > 1e-12:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            r = math.sqrt(disc)
            cuts[nc] = (-qb - r) / (2.0 * qa)
            cuts[nc + 1] = (-qb + r) / (2.0 * qa)
            nc += 2
    elif abs(qb) > 1e-12:
        cuts[nc] = -qc / qb
        nc += 1
    if abs(ua) > 1e-12:
        cuts[nc] = -wa / ua
        nc += 1
    cs = np.sort(cuts[:nc])
    a, b = S, 0.0
    for k in range(nc - 1):
        s0 = min(max(cs[k], 0.0), S)
        s1 = min(max(cs[k + 1], 0.0), S)
        if not s1 > s0:
            continue
        sm = 0.5 * (s0 + s1)
        h = wa + sm * ua
        if h > 0.0 and h * h >= c2 * (ww + 2.0 * sm * wu + sm * sm):
            a = min(a, s0)
            b = max(b, s1)
    return a, b


@kernel
def sample_segments(rows, material, e1, e2, sigma_t, sigma_s, medium, o, d, t, u, u_pick,
                    eq_pos, share_thin, share_thick, src, p, w, seg_m):
    """One in-scattering point per camera segment inside a scattering medium.

    rows (n,) int64 the triangle each ray met (< 0: none), material (T,) int32, e1, e2
    (T,3) edges; medium (n,) int64 each ray's medium (-1: not known: the segment was inside
    the medium of the object whose back face it ends on, media.segment_medium's rule); o,
    d (n,3) the rays, t (n,) their hit distances in units of |d|; u, u_pick (n,) uniform
    numbers. The distance s: from the exponential of the channels' mean extinction
    truncated to the segment, or (eq_pos (K,EQ_COLUMNS), K > 0: the point, spot and area
    lights, each aimed at its position, an area light's centre) with probability
    1 - adaptive_share(tau, rho, lit, share_thin, share_thick) equiangular towards one of
    the lights that can light part of the segment (lit_interval: a spot's cone, an area
    light's front side and spread), picked uniformly, over that part only (Kulla &
    Fajardo 2012), its pdf the mixture of the exponential and those lights' (one-sample
    MIS, balance heuristic: each light's 1 / r^2 peak is sampled where it is; no such
    light: the exponential alone). Writes,
    compacted over the segments in a medium with sigma_s > 0: src (K,) the ray, p (K,3)
    the point, w (K,3) T(s) sigma_s / pdf(s), seg_m (K,) the medium. Returns the count."""
    k = 0
    n_eq = eq_pos.shape[0]
    lo = np.empty(max(n_eq, 1))
    hi = np.empty(max(n_eq, 1))
    for i in range(rows.shape[0]):
        r = rows[i]
        if r < 0:
            continue
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        m = segment_medium(e1, e2, r, material[r], medium[i], sigma_t, dx, dy, dz)
        if m < 0:
            continue
        s0, s1, s2 = sigma_s[m, 0], sigma_s[m, 1], sigma_s[m, 2]
        if not (s0 > 0.0 or s1 > 0.0 or s2 > 0.0):
            continue
        dl = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not dl > 0.0:
            continue
        S = max(t[i], 0.0) * dl
        if not S > 0.0:
            continue
        ux, uy, uz = dx / dl, dy / dl, dz / dl
        t0, t1, t2 = sigma_t[m, 0], sigma_t[m, 1], sigma_t[m, 2]
        sb = (t0 + t1 + t2) / 3.0  # the sampling extinction: the channels' mean
        tau = sb * S
        thin = not tau > 1e-6
        one_minus = 0.0 if thin else -math.expm1(-tau)
        # The lights that can light part of the segment, and those parts.
        n_lit = 0
        rho = 0.0
        for j in range(n_eq):
            a, b = lit_interval(o[i, 0], o[i, 1], o[i, 2], ux, uy, uz, S, eq_pos, j)
            lo[j], hi[j] = a, b
            if b > a:
                n_lit += 1
                rho = max(rho, equiangular_gain(o[i, 0], o[i, 1], o[i, 2], ux, uy, uz, S, a,
                                                b, eq_pos[j, 0], eq_pos[j, 1], eq_pos[j, 2],
                                                eq_pos[j, 16]))
        # the exponential's share of the mixture
        share = adaptive_share(tau, rho, n_lit, share_thin, share_thick)
        up = u_pick[i]
        if up < share:
            # Exponential truncated to [0, S]: s = -ln(1 - u (1 - e^-tau)) / sb (an
            # optically thin segment: uniform, its limit).
            s = u[i] * S if thin else -math.log1p(-u[i] * one_minus) / sb
        else:
            pick = min(int((up - share) / (1.0 - share) * n_lit), n_lit - 1)
            j = 0
            for jj in range(n_eq):
                if hi[jj] > lo[jj]:
                    if pick == 0:
                        j = jj
                        break
                    pick -= 1
            a = lo[j]
            ta, D, tha, thb = _equiangular(o[i, 0] + ux * a, o[i, 1] + uy * a,
                                           o[i, 2] + uz * a, ux, uy, uz, hi[j] - a,
                                           eq_pos[j, 0], eq_pos[j, 1], eq_pos[j, 2],
                                           eq_pos[j, 16])
            s = a + ta + D * math.tan(tha + u[i] * (thb - tha))
        s = min(max(s, 0.0), S)
        pdf = share * (1.0 / S if thin else sb * math.exp(-sb * s) / one_minus)
        for j in range(n_eq):
            a = lo[j]
            if not (hi[j] > a and a <= s <= hi[j]):
                continue
            ta, D, tha, thb = _equiangular(o[i, 0] + ux * a, o[i, 1] + uy * a,
                                           o[i, 2] + uz * a, ux, uy, uz, hi[j] - a,
                                           eq_pos[j, 0], eq_pos[j, 1], eq_pos[j, 2],
                                           eq_pos[j, 16])
            if thb > tha:
                x = s - a - ta
                pdf += (1.0 - share) / n_lit * D / ((thb - tha) * (D * D + x * x))
        if not pdf > 0.0:
            continue
        src[k] = i
        p[k, 0] = o[i, 0] + ux * s
        p[k, 1] = o[i, 1] + uy * s
        p[k, 2] = o[i, 2] + uz * s
        w[k, 0] = math.exp(-t0 * s) * s0 / pdf
        w[k, 1] = math.exp(-t1 * s) * s1 / pdf
        w[k, 2] = math.exp(-t2 * s) * s2 / pdf
        seg_m[k] = m
        k += 1
    return k


@kernel
def accumulate_phase(L, contrib, row, kidx, ray, ksamples, blocked, m_all, wdir, nrm, wo,
                     g, n, clear, t_ray, d_ray, sigma_t):
    """L[row mod n] += contrib / (nrm . wdir) x phase(wo . wdir, g) x visible / samples,
    entry by entry (sample order): sample_lights' irradiance at a point whose "normal"
    nrm (2n,3) was the ray's direction (rows < n) or its opposite (rows >= n), the
    cosine divided out and the Henyey-Greenstein phase (hg_phase) of the ray direction wo
    (n,3) unit and g (n,) applied. L (n,3): the in-scattered radiance L_in.
    A shadow ray the first OCCLUDED query found clear (clear (R,)) met no surface on its
    way (t_ray (R,) its length in units of |d_ray| (R,3)): it lies wholly inside the
    point's medium (sigma_t (n,3) its extinction) and keeps exp(-sigma_t length) (a lamp
    inside the fog); a ray that crossed surfaces took its media from
    ShadowTransmittance's back-face rule (it left the point's medium through one)."""
    for j in range(m_all):
        r = ray[j]
        if r >= 0 and blocked[r]:
            continue
        i = row[j]
        c = nrm[i, 0] * wdir[j, 0] + nrm[i, 1] * wdir[j, 1] + nrm[i, 2] * wdir[j, 2]
        if not c > 0.0:
            continue
        h = i % n
        cos_t = wo[h, 0] * wdir[j, 0] + wo[h, 1] * wdir[j, 1] + wo[h, 2] * wdir[j, 2]
        f = hg_phase(cos_t, g[h]) / (c * ksamples[kidx[j]])
        f0 = f1 = f2 = f
        if r >= 0 and clear[r]:
            dl = math.sqrt(float(d_ray[r, 0]) ** 2 + float(d_ray[r, 1]) ** 2
                           + float(d_ray[r, 2]) ** 2)
            s = float(t_ray[r]) * dl
            f0 = f * math.exp(-sigma_t[h, 0] * s)
            f1 = f * math.exp(-sigma_t[h, 1] * s)
            f2 = f * math.exp(-sigma_t[h, 2] * s)
        L[h, 0] += contrib[j, 0] * f0
        L[h, 1] += contrib[j, 1] * f1
        L[h, 2] += contrib[j, 2] * f2


def in_scattered(ctx, p, wo, g, sigma_t, rng, counters=None, buffers=None,
                 world_sigma=None, sets=None, packed=None) -> np.ndarray:
    """(n,3) the light L_in (W / m^2 sr, radiance units) the lamps scatter at points p
    (n,3) towards -wo (wo (n,3) unit: the camera ray's direction), through the phase
    function of anisotropy g (n,), from one sample of each light (light_sample_list's
    numbers, rng) with shadow rays (transparent surfaces and media crossed:
    ctx.shadow; inside the points' own medium, extinction sigma_t (n,3): a shadow ray
    that meets no surface keeps exp(-sigma_t length), accumulate_phase). world_sigma
    (n,3): the world volume's extinction at the points in it (engine/worldmedium.py; 0
    elsewhere): a shadow ray that crossed transparent surfaces keeps exp(-sigma_t length)
    of it too (directlight.direct_light's world_sigma); None: none. sets (n,): the
    points' receiver sets (Light Linking, lightlinking.LightLinks.volume_sets), each
    set's points lit by its own lamps (packed: the lights as one set sees them); None:
    every lamp."""
    from .directlight import _dim_in_medium
    links = getattr(ctx, "links", None)
    if links is not None and sets is not None and len(p):
        base = ctx.packed_lights or pack_lights(ctx.lights)
        L = np.zeros((len(p), 3))
        for s in np.unique(sets):
            sel = np.nonzero(sets == s)[0]
            L[sel] = in_scattered(ctx, p[sel], wo[sel], g[sel], sigma_t[sel], rng, counters,
                                  buffers, None if world_sigma is None else world_sigma[sel],
                                  packed=links.packed_for(base, int(s)))
        return L
    from .integrator import SHADOW, light_sample_list, selector_for
    n = len(p)
    L = np.zeros((n, 3))
    if n == 0:
        return L
    samples = light_sample_list(ctx, n, rng)
    if not samples:
        return L
    packed = packed or ctx.packed_lights or pack_lights(ctx.lights)
    codes, params, mesh = packed
    chosen = selector_for(ctx, False)
    tree = ((*empty_tree(), np.ones(len(codes), np.bool_)) if chosen is None else chosen[1])
    # The two halves: "normal" +wo, then -wo, at the same points and numbers.
    nrm = np.ascontiguousarray(np.concatenate([wo, -wo]), np.float64)
    p2 = np.ascontiguousarray(np.concatenate([p, p]), np.float64)
    zeros = np.zeros(2 * n)
    hit_arrays = (p2, nrm, NO_ROWS3, nrm, zeros, NO_ROWS, NO_ROWS, NO_ROWS3, nrm)
    buf = buffers or DirectLightBuffers()
    shadow = getattr(ctx, "shadow", None)
    wo = np.ascontiguousarray(wo, np.float64)
    g = np.ascontiguousarray(g, np.float64)
    K = len(samples)
    klight = np.array([s[0] for s in samples], np.int64)
    ktrace = np.array([s[1] for s in samples], np.bool_)
    ksamples = np.array([float(s[2]) for s in samples])
    U1 = np.ascontiguousarray(np.tile(np.stack([s[3] for s in samples]), (1, 2)))
    U2 = np.ascontiguousarray(np.tile(np.stack([s[4] for s in samples]), (1, 2)))
    if any(s[5] is not None for s in samples):
        SEL = np.ascontiguousarray(np.tile(np.stack(
            [np.zeros(n) if s[5] is None else s[5] for s in samples]), (1, 2)))
    else:
        SEL = np.zeros((K, 1))
    buf.ensure(K * 2 * n)
    m_all, m_rays = sample_lights(*hit_arrays, codes, params, *mesh, *tree, klight, ktrace,
                                  U1, U2, SEL, buf.contrib, buf.row, buf.kidx, buf.ray,
                                  buf.o32, buf.d32, buf.t32, buf.wdir, buf.lpdf, NO_ROWS,
                                  NO_HROWS, NO_ROWS3)
    blocked = buf.blocked[:m_rays]
    t_keep = buf.t32[:m_rays].copy()  # (Embree overwrites the distances)
    clear = np.zeros(m_rays, np.bool_)
    if m_rays:
        ctx.accel.occluded_into(buf.o32[:m_rays], buf.d32[:m_rays], buf.t32[:m_rays], blocked,
                                cls=SHADOW)
        np.logical_not(blocked, out=clear)
        if shadow is not None:
            shadow.pass_blocked(buf.o32[:m_rays], buf.d32[:m_rays], t_keep, blocked,
                                buf.contrib, buf.ray, m_all, SHADOW)
            if world_sigma is not None:
                # (the rays that crossed surfaces: blocked by the first query, not now;
                # the two halves' rows index the points twice)
                _dim_in_medium(buf, m_all, clear | blocked, t_keep,
                               np.concatenate([world_sigma, world_sigma]))
        if counters is not None:
            counters.shadow_rays += m_rays
    het = getattr(ctx, "hetero", None)
    if het is not None and het.fields and clear.any():
        # The rays that met no surface (a lamp inside the fog) through a medium with a
        # density texture: ratio tracking's correction (engine/heterogeneous.py); the
        # rays that crossed surfaces took theirs in shadow.pass_blocked.
        from .shadowtransmittance import scale_entries
        r = np.flatnonzero(clear)
        ray_trans = np.ones((m_rays, 3))
        ray_trans[r] = het.correction(buf.o32[r], buf.d32[r], t_keep[r], salt=4)
        scale_entries(buf.contrib, buf.ray, m_all, ray_trans)
    accumulate_phase(L, buf.contrib, buf.row, buf.kidx, buf.ray, ksamples, blocked, m_all,
                     buf.wdir, nrm, wo, g, n, clear, t_keep, buf.d32[:m_rays],
                     np.ascontiguousarray(sigma_t, np.float64))
    return L


def sample_hg(d, g, u1, u2) -> np.ndarray:
    """(n,3) unit directions drawn by the Henyey-Greenstein phase function of g (n,)
    about the propagation directions d (n,3) unit (cos = d . w_new, hg_phase's
    convention; pbrt-v4's SampleHenyeyGreenstein, Cycles' henyey_greenstein_sample), from
    u1, u2 (n,) uniform: phase / pdf = 1."""
    g = np.asarray(g, np.float64)
    iso = np.abs(g) < 1e-3
    gs = np.where(iso, 1.0, g)
    sq = (1.0 - gs * gs) / (1.0 - gs + 2.0 * gs * u1)
    cos_t = np.where(iso, 1.0 - 2.0 * u1, (1.0 + gs * gs - sq * sq) / (2.0 * gs))
    cos_t = np.clip(cos_t, -1.0, 1.0)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * math.pi * u2
    # An orthonormal frame about d (Duff et al. 2017, "Building an Orthonormal Basis").
    sign = np.where(d[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + d[:, 2])
    b = d[:, 0] * d[:, 1] * a
    t1 = np.stack([1.0 + sign * d[:, 0] ** 2 * a, sign * b, -sign * d[:, 0]], axis=1)
    t2 = np.stack([b, sign + d[:, 1] ** 2 * a, -d[:, 1]], axis=1)
    w = (sin_t * np.cos(phi))[:, None] * t1 + (sin_t * np.sin(phi))[:, None] * t2 \
        + cos_t[:, None] * d
    return np.ascontiguousarray(w / np.linalg.norm(w, axis=1, keepdims=True))


def equiangular_rows(lights, codes, params, rows) -> np.ndarray:
    """(K, EQ_COLUMNS) float64 sample_segments' equiangular lights: the packed light
    rows `rows` (point, spot or area; lights, codes, params as pack_lights gave them). A
    spot carries its axis and bounding cone (SpotLight.spot_cos_bound, an elliptical
    cone's circular bound) widened by 1e-3 rad, the apex pulled back by radius /
    sin(angle) so the cone holds the light's disk; a point light, or a cone of 90 degrees
    or more, cosine -1 (not clipped); both their radius (column 16: _equiangular's
    widened peak). An area light carries its emitting axis, its edges
    and shape and, with a spread below 180 degrees,
    the cone of half the spread (widened 1e-3 rad) whose apex lies behind the light by
    its largest extent / tan(spread / 2): every ray leaving the light within the spread
    stays inside it (Cycles' area_light_valid_ray_segment; its light's radiance at angle
    a from the axis, spread_attenuation, is 0 from a = spread / 2 on)."""
    out = np.zeros((len(rows), EQ_COLUMNS))
    out[:, 6] = -1.0
    for k, r in enumerate(rows):
        out[k, 0:3] = params[r, pk.POS:pk.POS + 3]
        if codes[r] == pk.CODE_AREA:
            _area_row(out[k], lights[r], params[r])
            continue
        out[k, 16] = max(float(params[r, pk.RADIUS]), 0.0) if EQ_RADIUS else 0.0
        if codes[r] != pk.CODE_SPOT:
            continue
        light = lights[r]
        axis = np.asarray(getattr(light, "dir", np.zeros(3)), np.float64)
        n = float(np.linalg.norm(axis))
        angle = math.acos(min(max(float(getattr(light, "spot_cos_bound", -1.0)), -1.0),
                              1.0)) + 1e-3
        if not n > 0 or angle >= 0.5 * math.pi - 1e-3:
            continue
        out[k, 3:6] = axis / n
        out[k, 6] = math.cos(angle)
        out[k, 7] = float(getattr(light, "radius", 0.0)) / math.sin(angle)
    return np.ascontiguousarray(out)


def _area_row(row, light, q):
    """equiangular_rows' row (EQ_COLUMNS,) of an area light (packed row q)."""
    axis = q[pk.DIR:pk.DIR + 3] / max(float(np.linalg.norm(q[pk.DIR:pk.DIR + 3])), 1e-300)
    sx, sy = float(q[pk.SIZE_X]), float(q[pk.SIZE_Y])
    disk = bool(q[pk.IS_DISK])
    row[3:6] = axis
    row[8] = 1.0
    row[9:12] = sx * q[pk.U:pk.U + 3]
    row[12:15] = sy * q[pk.V:pk.V + 3]
    row[15] = 1.0 if disk else 0.0
    row[16] = AREA_WIDEN * math.sqrt(max(float(q[pk.AREA_]), 0.0) / math.pi)
    spread = float(getattr(light, "spread", math.pi))
    half = 0.5 * spread + 1e-3
    if spread < math.pi - 1e-6 and half < 0.5 * math.pi - 1e-3 and spread > 1e-5:
        extent = 0.5 * (max(sx, sy) if disk else math.hypot(sx, sy))
        row[6] = math.cos(half)
        row[7] = extent / math.tan(half)


class CameraScattering:
    """The camera paths' single scattering for one render context (None from
    for_context when no material scatters)."""

    def __init__(self, ctx, tables):
        self.ctx = ctx
        self.sigma_t, self.sigma_s, self.g = tables
        # Cycles' Light Paths > Volume bounces: the scatters after the first (walk).
        self.bounces = int(getattr(ctx.settings, "volume_bounces", 0) or 0)
        # The world volume's row (engine/worldmedium.py; -1: none).
        self.world_row = worldmedium.medium_row(ctx)
        # Emitting media (engine/volumeemission.py; None: none): their glow scattered
        # towards the ray (walk).
        self.glow = volumeemission.MediumEmission.for_context(ctx)
        # The point, spot and area lights for equiangular sampling (sample_segments;
        # the strongest MAX_EQUIANGULAR by emitted power; none: exponential alone).
        self.eq_pos = NO_POINTS
        if EQUIANGULAR and ctx.lights:
            codes, params, _ = ctx.packed_lights or pack_lights(ctx.lights)
            kinds = (codes == pk.CODE_POINT) | (codes == pk.CODE_SPOT)
            if EQUIANGULAR_AREA:
                kinds |= codes == pk.CODE_AREA
            rows = np.flatnonzero(kinds)
            if len(rows):
                power = np.array([_power(ctx.lights[r], params[r]) for r in rows])
                rows = rows[np.argsort(-power, kind="stable")[:MAX_EQUIANGULAR]]
                self.eq_pos = equiangular_rows(ctx.lights, codes, params, rows)

    def _world_sigma(self, seg_m):
        """(K,3) the world volume's extinction at the points in it (media seg_m (K,)),
        0 at the others, or None without a world volume or transparent shadows."""
        if self.world_row < 0 or getattr(self.ctx, "shadow", None) is None:
            return None
        return np.where((np.asarray(seg_m) == self.world_row)[:, None],
                        self.sigma_t[self.world_row][None, :], 0.0)

    def _link_sets(self, seg_m):
        """Light Linking: the receiver sets of points in media seg_m (None: no links)."""
        links = getattr(self.ctx, "links", None)
        return (None if links is None
                else links.volume_sets(self.ctx.geo, seg_m, self.world_row))

    @classmethod
    def for_context(cls, ctx):
        tables = scattering_tables(ctx.table)
        return None if tables is None else cls(ctx, tables)

    def radiance(self, prim, o, d, t, medium, rng, counters=None, uv=None):
        """(src (K,) int64, L (K,3)): the radiance scattered towards the ray's origin
        along the segments of the rays src of o, d (n,3) (t (n,) in units of |d|, ending
        on triangles prim (n,), in media medium (n,) int64, -1: not known) that lie in a
        scattering medium, one distance sample each (sample_segments) and one sample of
        each light there (in_scattered); per unit of throughput at the segment's start.
        rng: the numbers (n distances, then the light samples'); uv: (u, u_pick) (n,)
        each, the distances' numbers stratified over a pixel's samples (the camera
        pass's ("volume",) dimension), None: drawn from rng."""
        n = len(prim)
        if n == 0:
            return np.zeros(0, np.int64), np.zeros((0, 3))
        src, pts, w, seg_m, u_src = self._scatter_points(prim, o, d, t, medium, rng, uv)
        if len(src) == 0:
            return np.zeros(0, np.int64), np.zeros((0, 3))
        het = getattr(self.ctx, "hetero", None)
        if het is not None and het.fields:
            # Density textures (engine/heterogeneous.py): the distance drawn again along
            # the majorant grid (from the same number), its weight from the ratio-tracked
            # T(s) and the field at the point.
            pts, w = het.scatter(np.take(np.asarray(o, np.float64), src, axis=0),
                                 np.take(np.asarray(d, np.float64), src, axis=0),
                                 np.take(np.asarray(t, np.float64), src), pts, seg_m, w,
                                 u_src)
        wo = np.take(np.asarray(d, np.float64), src, axis=0)
        wo = wo / np.linalg.norm(wo, axis=1, keepdims=True)
        Lin = in_scattered(self.ctx, pts, wo, self.g[seg_m], self.sigma_t[seg_m], rng,
                           counters, world_sigma=self._world_sigma(seg_m),
                           sets=self._link_sets(seg_m))
        L = Lin * w
        if self.bounces > 0 or self.glow is not None:
            self.walk(L, pts, wo, w, seg_m, rng, counters)
        return src, L

    def _scatter_points(self, prim, o, d, t, medium, rng, uv=None):
        """One distance sample on each ray's segment (sample_segments; rays src of o, d
        (n,3), t (n,) in units of |d|, ending on triangles prim (n,), in media medium
        (n,)): (src (K,) int64, points (K,3), weights (K,3), media (K,), the distances'
        numbers (K,)) for the K that scatter, in order. rng: n pairs of numbers."""
        rows, (material, e1, e2) = self.ctx.geo.hit_tables(prim, "material", "e1", "e2")
        n = len(prim)
        src = np.empty(n, np.int64)
        pts = np.empty((n, 3))
        w = np.empty((n, 3))
        seg_m = np.empty(n, np.int64)
        u, u_pick = rng.random((2, n)) if uv is None else (np.ascontiguousarray(uv[0]),
                                                             np.ascontiguousarray(uv[1]))
        k = sample_segments(np.ascontiguousarray(rows, np.int64),
                            np.ascontiguousarray(material, np.int32),
                            np.ascontiguousarray(e1, np.float64),
                            np.ascontiguousarray(e2, np.float64), self.sigma_t, self.sigma_s,
                            np.ascontiguousarray(medium, np.int64),
                            np.ascontiguousarray(o, np.float64),
                            np.ascontiguousarray(d, np.float64),
                            np.ascontiguousarray(t, np.float64), u, u_pick,
                            self.eq_pos, float(EXP_SHARE_THIN), float(EXP_SHARE_THICK),
                            src, pts, w, seg_m)
        return src[:k], pts[:k], w[:k], seg_m[:k], u[src[:k]]

    def walk(self, L, pts, wo, beta, seg_m, rng, counters=None):
        """Volume bounces: from each first scatter point pts (K,3) (the path arriving
        along wo (K,3), weight beta (K,3), in medium seg_m (K,)) the path scatters on
        inside the medium up to self.bounces more times: a direction by the
        Henyey-Greenstein phase (sample_hg: its weight phase / pdf is 1), the segment to
        the next surface, a distance in it (sample_segments; a path whose distance falls
        beyond the medium's segment ends), the lamps' light there (in_scattered) and the
        light of the surface the segment ends on (segment_end_light) added to L (K,3) in
        place.
        In emitting media (self.glow) each of those segments adds its glow, and so does
        one more segment from the last scatter point (Cycles' path goes on from its last
        volume bounce to collect that segment's emission: PATH_RAY_TERMINATE_AFTER_VOLUME;
        at Volume bounces 0 that segment alone: the glow scattered once)."""
        idx = np.arange(len(pts))
        x, d_in, m, beta = pts, wo, seg_m, beta
        last = self.bounces if self.glow is not None else self.bounces - 1
        for step in range(last + 1):
            if len(idx) == 0:
                return
            u1, u2 = rng.random((2, len(idx)))
            d_new = sample_hg(d_in, self.g[m], u1, u2)
            t, prim, u, v = self.ctx.accel.intersect(x, d_new)
            if self.glow is not None:
                # (an escape through the world volume: its length to 1e-13, d_new unit)
                t_e = (t if self.world_row < 0 else
                       np.where(np.asarray(prim) == -1, worldmedium.far_length(self.ctx), t))
                s_e, Le = self.glow.along(prim, d_new, t_e, m, o=x)
                if len(s_e):
                    L[idx[s_e]] += beta[s_e] * Le
            if step == self.bounces:
                return  # the segment after the last bounce: its glow alone
            rows, Ls = self.segment_end_light(x, d_new, t, prim, u, v, m)
            if len(rows):
                L[idx[rows]] += beta[rows] * Ls
            src, p2, w2, m2, u2 = self._scatter_points(prim, x, d_new, t, m, rng)
            het = getattr(self.ctx, "hetero", None)
            if het is not None and het.fields and len(src):
                # (density textures: as radiance's first scatter, engine/heterogeneous.py)
                p2, w2 = het.scatter(x[src], d_new[src], np.take(np.asarray(t, np.float64),
                                                                 src), p2, m2, w2, u2)
            idx, x, d_in, m = idx[src], p2, d_new[src], m2
            beta = beta[src] * w2
            if len(src) == 0:
                return
            Lin = in_scattered(self.ctx, x, d_in, self.g[m], self.sigma_t[m], rng, counters,
                               world_sigma=self._world_sigma(m), sets=self._link_sets(m))
            L[idx] += beta * Lin

    def segment_end_light(self, x, d, t, prim, u, v, m):
        """(rows (K,), L (K,3)): the light a walk segment (from x (n,3) along d (n,3), hit
        t, prim, u, v (n,), in media m (n,)) takes from the surface it ends on, for the
        rows that take any: none here (engine/volumewalk.py's subclass adds the surfaces'
        light)."""
        return np.zeros(0, np.int64), np.zeros((0, 3))

    def add(self, acc, target, pix, prim, o, d, t, medium, tp, rng, counters=None, uv=None):
        """radiance()'s light into pass `target` of the Accumulator acc at pixels pix (n,),
        weighted by the throughput tp (n,3) at the segment's start. Returns the segments
        lit. uv: radiance's."""
        src, L = self.radiance(prim, o, d, t, medium, rng, counters, uv)
        if len(src):
            acc.add(target, pix, L, np.ascontiguousarray(tp, np.float64), src)
        return len(src)


def _power(light, q) -> float:
    """A light's emitted power for ranking the equiangular lights (W, summed over RGB)."""
    flux = getattr(light, "photon_flux", None)
    if flux is None:
        flux = getattr(light, "flux", None)
    if flux is None:
        return float(np.sum(q[pk.RGB:pk.RGB + 3]))
    return float(np.sum(flux))


@register_warm_up
def _warm_up():
    """Compile (or load) the kernels on one segment through a unit triangle."""
    e1 = np.array([[1.0, 0.0, 0.0]])
    e2 = np.array([[0.0, 1.0, 0.0]])
    one = np.ones((1, 3))
    d = np.array([[0.0, 0.0, 1.0]])
    out = np.empty((1, 3))
    u2 = np.random.default_rng(0).random((2, 1))
    spot = np.zeros((2, EQ_COLUMNS))
    spot[0, :8] = [0.5, 0.0, 0.5, 0.0, 0.0, -1.0, 0.7, 0.1]
    spot[1, :9] = [0.0, 0.0, 0.5, 0.0, 0.0, -1.0, -1.0, 0.0, 1.0]
    spot[1, 9], spot[1, 13] = 0.5, 0.5
    for eq in (NO_POINTS, spot):
        sample_segments(np.zeros(1, np.int64), np.zeros(1, np.int32), e1, e2, one, one,
                        np.full(1, -1, np.int64), np.zeros((1, 3)), d, np.ones(1), u2[0],
                        u2[1], eq, 0.5, 0.5, np.empty(1, np.int64), out, np.empty((1, 3)),
                        np.empty(1, np.int64))
    accumulate_phase(np.zeros((1, 3)), one, np.zeros(1, np.int64), np.zeros(1, np.int64),
                     np.zeros(1, np.int64), np.ones(1), np.zeros(1, np.bool_), 1, d,
                     np.concatenate([d, -d]), d, np.zeros(1), 1, np.ones(1, np.bool_),
                     np.ones(1, np.float32), np.ones((1, 3), np.float32), one)
    hg_phase(0.5, 0.3)
