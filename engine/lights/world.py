"""World: the background as a light at infinity (Cycles' kernel/light/background.h).

Two forms:
  constant     a non-black background colour: uniform radiance `background`, sampled for
               shadow rays by the cosine hemisphere around the shading normal
  environment  an equirectangular image (engine/lights/environment.py): shadow rays use
               one-sample multiple importance sampling (balance heuristic) of the map
               times the cosine to the shading normal's cluster (the environment's
               cosine-weighted distributions, picked with probability ENV_MAP_FRACTION)
               and the cosine hemisphere, so a small bright sun in the map, the dim, wide
               sky and the directions the cluster's cosine misses are all sampled, and no
               sample goes below the surface's horizon; photons leave a disk beyond the
               scene's bounding sphere with directions from the map's own 2D
               piecewise-constant distribution.

`background_radiance` gives the radiance of rays that escape the scene (camera rays that
miss, specular continuations); `WorldLight.pdf` the solid-angle pdf of the shadow-ray
strategy, for multiple importance sampling against BSDF-sampled rays that escape.

Light portals (lightportal34, issue 14): with Cycles light portals in the scene
(engine.scene.LightPortal: rectangles, or the ellipses inscribed in them (round: Disk /
Ellipse portals, portals36), over the openings a room's sky light enters by) a world
shadow ray at a point on a portal's room side picks, with probability s_p, a direction
through the portals it sees (a portal by its solid angle omega_k; a rectangle's
direction uniform in its solid angle, pbrt-v4's SampleSphericalRectangle,
lights/area.spherical_rectangle: pdf_k = 1 / omega_k; a round portal's through a point
uniform over its ellipse, as Cycles' background_portal_sample: pdf_k = r^2 / (A cos), its
omega_k that of its inscribed ROUND_SIDES-gon), else the strategies above (cosine; map x
cosine and cosine), one-sample MIS (balance heuristic) over the mixture

    pdf(w) = (1 - s_p) pdf_before(w) + s_p sum_k [w crosses k] (omega_k / Omega) pdf_k(w)

(Omega = sum omega_k; n(w) / Omega for rectangles, n(w) the number crossed; Cycles'
background_light_sample mixes its portal and map sampling alike by portal_sampling_pdf;
Veach 1997, sec. 9.2.4). The share s_p per point is 1 - Phi / pi, Phi the portals'
projected solid angle, the share of the cosine strategy's samples that pass them
(panelight's AREA / OUTSIDE split alike): each outline (a round portal's ROUND_SIDES-gon)
clipped to the point's tangent plane, then Lambert's formula (projected_solid_angle;
portals36: before, Phi = sum omega_k cos(N, centre_k)^+, which read s_p 0.9 1 cm under an
opening and counted a portal half below the horizon whole or not at all;
PORTAL_RULE_CENTRE keeps it for A/B), clipped to [PORTAL_SHARE_LO, PORTAL_SHARE_HI] (an
environment map sampled uniformly through the portals: PORTAL_SHARE_ENV_*; by the map:
PORTAL_SHARE_MAP_*); s_p = 0 where no portal is seen (the point outside all of them, no
part of them above its tangent plane, or a solid angle under
MIN_SPHERICAL_SOLID_ANGLE): the shadow rays as before there. The continuation's MIS weight
(integrator.mis_light_pdf: WorldLight.pdf with the origin point) uses the same mixture
(portal_pdfs), so nothing is counted twice. Portals beyond MAX_PORTALS (the largest by
area kept) and sheared ones (spherical_rectangle's omega 0) are left out.

With an environment map (portalenv35) the portal strategy samples the map as seen through
the portals instead of their solid angle uniformly (engine/lights/portalmap.py: pbrt-v4's
PortalImageInfiniteLight, a table per portal over its rectangle's parameterization
restricted to the point's window; kept between prepares, portalmap.portal_tables): a portal by the luminance integral I_k of the map
through it, a direction in proportion to the map there, pdf p_map(w) (portalmap's
formula, exact per point) in place of n(w) / Omega; the same seen portals, share s_p
(bounds PORTAL_SHARE_MAP_LO / HI) and mixture. A constant world keeps
the uniform solid angle (there the two agree: a constant map's per-sample noise is the
constant world's, and the spherical rectangle is exact without a table), and so does a
scene with a round portal (WorldLight.by_map).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from ..sampling import dot
from .emission import (f64, aim_origin, concentric_disk, disk_origin, emit_uniform, put,
                       uniform_sphere)
from .environment import env_sample_texel, texel_radiance
from . import packing as pk
from .area import MIN_SPHERICAL_SOLID_ANGLE, spherical_rectangle
from .base import InfiniteLight
from .portalmap import portal_tables, portal_map_pdf, portal_map_sample, portal_masses

WORLD = "WORLD"
# Probability that a shadow ray of an environment-mapped world samples the map's
# cosine-weighted distribution (else the cosine hemisphere); directlight.sample_lights
# uses the same constant. (0.5 with the map's plain distribution until issue 14: the
# case-3 HDRI scene's floor, direct light per sample, docs/performance.md; 0.75 until the
# map's texels were sampled by their interpolated luminance (environment.texel_warp): then
# the map x cosine alone has a per-sample relative variance of 0.001 at a floor under a
# 2-degree sun of 1200, and the cosine share is what is left: the mixture's 0.106 at 0.75,
# 0.019 at 0.9, 0.006 at 0.95; at normals off their cluster's centre, where the cluster's
# cosine misses part of the hemisphere, 0.15-0.20 / 0.05-0.07 / 0.04-0.06, and low suns
# favour 0.9 (0.010 against 0.018 at 0.95).)
ENV_MAP_FRACTION = 0.9
# Light portals (lightportal34): the bounds of the portal strategy's share s_p where a
# portal is seen (module docstring), for a constant world and for an environment map
# sampled through the portals by the map (portalenv35), and (PORTAL_SHARE_ENV_*) for an
# environment map with the portals sampled uniformly in solid angle (lightportal34;
# PORTAL_MAP_SAMPLING off). The ceiling keeps a share for the cosine strategy's
# samples, which find the light of openings without a portal; with a map sampled
# uniformly through the portals, for the map's, which find a sun seen through the
# opening. Measured
# (tests/test_light_portal_shadows.py's room, 1 x 1 m roof opening, per-sample
# std/mean of the floor's irradiance at a point 2 m under it / one 2.6 m off to the side;
# cosine alone 3.63 / 8.49): uniform sky, bounds 0.1-0.9 0.32 / 0.34, 0.1-0.95 0.27 /
# 0.24, 0.05-0.5 0.94 / 1.00. A map (0.4 sky, 0.1 ground, a texel of 60 17 degrees from
# the zenith, seen through the opening from the first point; map x cosine and cosine
# alone 1.88 / 9.52; the texel moved out of view 5.10 / 10.5): 0.1-0.9 2.61 / 0.34 (hidden
# 0.33 / 0.34), 0.2-0.7 2.25 / 0.66 (0.64 / 0.66), 0.1-0.6 2.13 / 0.82 (0.80 / 0.82).
# The portals sampled by the map (portalenv35; the same texel in view / out of view;
# a 128 x 256 map with a sun of radius 1.5 degrees 8 degrees from the zenith in view of
# the first point / in view of the second / of neither; map x cosine and cosine alone
# 0.56 / 1.36 / 6.26): 0.1-0.9 0.64 / 0.34 (0.33 / 0.34), sun 0.33 / 0.37 / 0.33,
# 0.1-0.95 0.62 / 0.24 (0.27 / 0.24), sun 0.32 / 0.31 / 0.28; 0.2 or 0.5 for the floor
# the same (the projected solid angle is small there): the constant world's bounds, whose
# ceiling keeps the share for openings without a portal.
# A map sampled through the portals by the map (portalenv35) took 0.2-0.7 in s35: the
# new-user trial's daylit room (a wall window with a Portal, a 256 x 128 HDRI with a sun
# of 9324, a 1024-spp Cycles reference) read relMSE 0.0350 with 0.1-0.9 (0.0274 with the
# portals sampled in solid angle). portals36: the daylit room's Portal is turned a quarter (1.0 m wide in its 1.2 m wide
# window, 0.1 m over the wall above and below), so the sky through the window's two
# uncovered strips is found only by the cosine and map strategies' share (its highest
# samples): that, not the sun, is what a large share starved. A scene with a portal
# whose opening reaches past it (lights.portal_leaks) takes PORTAL_SHARE_LEAK_*. relMSE
# seed 0 / seed 1 (pixels over 2x): as made, no shadow-ray portals 0.0250 / 0.0235 (73 /
# 54), 0.2-0.7 0.0259 / 0.0246, 0.1-0.9 0.0350, leaky 0.1-0.5 0.0240 / 0.0228 (63 / 48);
# the Portal fitted to the window: none 0.0207 / 0.0203, 0.2-0.7 0.0178 / 0.0176, 0.1-0.9
# 0.0177 / 0.0175, per sample at its dark floor corner 24.1 / 0.69 / 0.39 and the sun
# patch 0.545 / 0.312 / 0.232; under the roof opening (above) 0.1-0.9 0.327 sun in view,
# 0.318 sky against 0.356 / 0.622 at 0.2-0.7: a fitted portal under a map takes 0.1-0.9
# again. (The share rule's exact projected solid angle changes nothing on these floors:
# 1 - Phi / pi is under 0.7 only within ~0.5 m of a window; the daylit film is
# bit-identical to the centre estimate's.)
PORTAL_SHARE_LO = 0.1
PORTAL_SHARE_HI = 0.9
PORTAL_SHARE_MAP_LO = 0.1
PORTAL_SHARE_MAP_HI = 0.9
PORTAL_SHARE_ENV_LO = 0.2
PORTAL_SHARE_ENV_HI = 0.7
PORTAL_SHARE_LEAK_LO = 0.1
PORTAL_SHARE_LEAK_HI = 0.5
# The share rule (q[PORTAL_RULE], module docstring): 1 - Phi / pi with Phi the portals'
# exact projected solid angle (portals36: each outline clipped to the tangent plane,
# Lambert's formula); with Phi estimated from each portal's centre, om_k cos(N, c_k)^+
# (lightportal34 to portalenv35, for A/B measurements); or the ceiling wherever a portal
# is seen.
PORTAL_RULE_EXACT, PORTAL_RULE_CENTRE, PORTAL_RULE_CEILING = 0, 1, 2
PORTAL_RULE = PORTAL_RULE_EXACT
# A round portal's outline for its projected solid angle (the share) and its selection
# weight om_k: the inscribed ROUND_SIDES-gon (97 % of the ellipse's area; any weight is
# unbiased, the pdf being the sampler's own).
ROUND_SIDES = 16
# Off: an environment map's portal strategy is uniform in the portals' solid angle, as
# before portalenv35 (for A/B measurements: bench/bench_light_portal.py).
PORTAL_MAP_SAMPLING = True
_ONE_BELOW = float(np.nextafter(1.0, 0.0))


@kernel
def portal_vertex(q, b, j, nv):
    """Vertex j of the outline of the portal at row slot b (packing.PORTAL0 + k
    PORTAL_STRIDE), nv vertices: a rectangle's corners s, s + ex, s + ex + ey, s + ey
    (nv 4), or the nv-gon inscribed in a round portal's ellipse (the one inscribed in
    the rectangle)."""
    if nv == 4:
        fa = 1.0 if (j == 1 or j == 2) else 0.0
        fb = 1.0 if j >= 2 else 0.0
    else:
        a = 2.0 * math.pi * j / nv
        fa = 0.5 + 0.5 * math.cos(a)
        fb = 0.5 + 0.5 * math.sin(a)
    return (q[b] + fa * q[b + 3] + fb * q[b + 6], q[b + 1] + fa * q[b + 4] + fb * q[b + 7],
            q[b + 2] + fa * q[b + 5] + fb * q[b + 8])


@kernel
def _lambert_edge(a0, a1, a2, b0, b1, b2, s0, s1, s2):
    """Lambert's term of the polygon edge from a to b (vectors from the point):
    angle(a, b) x (s . unit(a x b)) (Arvo 1995, "Applications of irradiance tensors")."""
    c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    cl = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if not cl > 0.0:
        return 0.0
    return math.atan2(cl, a0 * b0 + a1 * b1 + a2 * b2) * (c0 * s0 + c1 * s1 + c2 * s2) / cl


@kernel
def projected_solid_angle(q, b, nv, p0, p1, p2, s0, s1, s2):
    """The projected solid angle (sr) of the portal at row slot b (nv outline vertices,
    portal_vertex) seen from p with unit normal s: the outline clipped to the half-space
    above p's tangent plane (Sutherland-Hodgman, streamed edge by edge), then Lambert's
    formula Phi = |1/2 sum_i angle(v_i, v_i+1) (s . unit(v_i x v_i+1))| over the clipped
    polygon's edges (Arvo 1995; pbrt's and Cycles' polygon form factors). 0 when no part
    of it is above the plane."""
    acc = 0.0
    first = True
    f0 = f1 = f2 = 0.0
    l0 = l1 = l2 = 0.0
    y0, y1, y2 = portal_vertex(q, b, nv - 1, nv)
    a0, a1, a2 = y0 - p0, y1 - p1, y2 - p2
    ha = a0 * s0 + a1 * s1 + a2 * s2
    for j in range(nv):
        y0, y1, y2 = portal_vertex(q, b, j, nv)
        c0, c1, c2 = y0 - p0, y1 - p1, y2 - p2
        hc = c0 * s0 + c1 * s1 + c2 * s2
        # Sutherland-Hodgman against the plane h = 0 for the edge a -> c: up to two
        # points out (the crossing, then c when c is above), each closing an edge of the
        # clipped polygon with the point before it.
        for out in range(2):
            if out == 0:
                if (ha > 0.0) == (hc > 0.0):
                    continue
                t = ha / (ha - hc)
                e0, e1, e2 = a0 + t * (c0 - a0), a1 + t * (c1 - a1), a2 + t * (c2 - a2)
            else:
                if not hc > 0.0:
                    continue
                e0, e1, e2 = c0, c1, c2
            if first:
                f0, f1, f2 = e0, e1, e2
                first = False
            else:
                acc += _lambert_edge(l0, l1, l2, e0, e1, e2, s0, s1, s2)
            l0, l1, l2 = e0, e1, e2
        a0, a1, a2, ha = c0, c1, c2, hc
    if first:
        return 0.0
    acc += _lambert_edge(l0, l1, l2, f0, f1, f2, s0, s1, s2)
    return 0.5 * abs(acc)


@kernel
def polygon_solid_angle(q, b, nv, p0, p1, p2):
    """The solid angle (sr) of the nv-gon outline of the portal at row slot b seen from
    p: the fan of triangles from its centre, each by Van Oosterom and Strackee (1983)."""
    c0 = q[b] + 0.5 * (q[b + 3] + q[b + 6]) - p0
    c1 = q[b + 1] + 0.5 * (q[b + 4] + q[b + 7]) - p1
    c2 = q[b + 2] + 0.5 * (q[b + 5] + q[b + 8]) - p2
    cl = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    y0, y1, y2 = portal_vertex(q, b, nv - 1, nv)
    a0, a1, a2 = y0 - p0, y1 - p1, y2 - p2
    al = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    tot = 0.0
    for j in range(nv):
        y0, y1, y2 = portal_vertex(q, b, j, nv)
        d0, d1, d2 = y0 - p0, y1 - p1, y2 - p2
        dl = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        trip = abs(c0 * (a1 * d2 - a2 * d1) + c1 * (a2 * d0 - a0 * d2)
                   + c2 * (a0 * d1 - a1 * d0))
        den = (cl * al * dl + (c0 * a0 + c1 * a1 + c2 * a2) * dl
               + (c0 * d0 + c1 * d1 + c2 * d2) * al + (a0 * d0 + a1 * d1 + a2 * d2) * cl)
        tot += 2.0 * math.atan2(trip, den)
        a0, a1, a2, al = d0, d1, d2, dl
    return tot


@kernel
def portal_shares(q, p0, p1, p2, s0, s1, s2, om):
    """The portals of world parameter row q (packing.PORTAL_*) seen from point p with
    shading normal s: writes om (MAX_PORTALS,) each portal's solid angle (sr; a round
    portal's that of its ROUND_SIDES-gon, its selection weight; 0 where it is not seen:
    p not on its room side, no part of it above p's tangent plane, or under
    MIN_SPHERICAL_SOLID_ANGLE) and returns (Omega = sum om (sr), the portal strategy's
    share s_p (module docstring: q[PORTAL_RULE]) clipped to q's [PORTAL_LO, PORTAL_HI];
    0 where Omega is 0)."""
    tot = 0.0
    phi = 0.0
    rule = int(q[pk.PORTAL_RULE])
    for k in range(int(q[pk.PORTAL_N])):
        b = pk.PORTAL0 + pk.PORTAL_STRIDE * k
        om[k] = 0.0
        c0 = q[b] + 0.5 * (q[b + 3] + q[b + 6])
        c1 = q[b + 1] + 0.5 * (q[b + 4] + q[b + 7])
        c2 = q[b + 2] + 0.5 * (q[b + 5] + q[b + 8])
        if not (p0 - c0) * q[b + 9] + (p1 - c1) * q[b + 10] + (p2 - c2) * q[b + 11] > 0.0:
            continue  # outside (or in) the opening's plane: light from it cannot come in
        nv = ROUND_SIDES if q[b + pk.PORTAL_ROUND] != 0.0 else 4
        ph = projected_solid_angle(q, b, nv, p0, p1, p2, s0, s1, s2)
        if not ph > 0.0:
            continue  # (no part of it above the horizon)
        if nv == 4:
            o = spherical_rectangle(p0, p1, p2, q[b], q[b + 1], q[b + 2], q[b + 3],
                                    q[b + 4], q[b + 5], q[b + 6], q[b + 7], q[b + 8], 0.5,
                                    0.5, False)[0]
        else:
            o = polygon_solid_angle(q, b, nv, p0, p1, p2)
        if not o >= MIN_SPHERICAL_SOLID_ANGLE:
            continue
        om[k] = o
        tot += o
        if rule == PORTAL_RULE_CENTRE:
            d0, d1, d2 = c0 - p0, c1 - p1, c2 - p2
            dl = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            phi += o * max((d0 * s0 + d1 * s1 + d2 * s2) / max(dl, 1e-300), 0.0)
        else:
            phi += ph
    if not tot > 0.0:
        return 0.0, 0.0
    share = q[pk.PORTAL_HI] if rule == PORTAL_RULE_CEILING else 1.0 - phi / math.pi
    return tot, min(max(share, q[pk.PORTAL_LO]), q[pk.PORTAL_HI])


@kernel
def portal_crossing(q, b, p0, p1, p2, w0, w1, w2):
    """Where the ray p + t w (t > 0, w unit) crosses the portal at row slot b (a
    rectangle s + a ex + b ey, a, b in [0, 1], ex orthogonal to ey, or a round portal's
    inscribed ellipse): (t, |w . (ex x ey)|), t 0 where it does not."""
    ex0, ex1, ex2 = q[b + 3], q[b + 4], q[b + 5]
    ey0, ey1, ey2 = q[b + 6], q[b + 7], q[b + 8]
    n0, n1, n2 = ex1 * ey2 - ex2 * ey1, ex2 * ey0 - ex0 * ey2, ex0 * ey1 - ex1 * ey0
    den = w0 * n0 + w1 * n1 + w2 * n2
    if den == 0.0:
        return 0.0, 0.0
    t = ((q[b] - p0) * n0 + (q[b + 1] - p1) * n1 + (q[b + 2] - p2) * n2) / den
    if not t > 0.0:
        return 0.0, 0.0
    x0, x1, x2 = p0 + t * w0 - q[b], p1 + t * w1 - q[b + 1], p2 + t * w2 - q[b + 2]
    fa = (x0 * ex0 + x1 * ex1 + x2 * ex2) / (ex0 * ex0 + ex1 * ex1 + ex2 * ex2)
    fb = (x0 * ey0 + x1 * ey1 + x2 * ey2) / (ey0 * ey0 + ey1 * ey1 + ey2 * ey2)
    if q[b + pk.PORTAL_ROUND] != 0.0:
        if not (2.0 * fa - 1.0) ** 2 + (2.0 * fb - 1.0) ** 2 <= 1.0:
            return 0.0, 0.0
    elif not (0.0 <= fa <= 1.0 and 0.0 <= fb <= 1.0):
        return 0.0, 0.0
    return t, abs(den)


@kernel
def _portal_term(q, b, t, cosa, om_k, tot):
    """One portal's part (om_k / tot) pdf_k(w) of the uniform portal strategy's pdf
    (1/sr): 1 / tot for a rectangle (uniform in its solid angle om_k); a round portal's
    point uniform over its ellipse's area A = pi/4 |ex||ey|, pdf_k = t^2 / (A cos) =
    t^2 / (pi/4 |w . (ex x ey)|) (cosa, portal_crossing's)."""
    if q[b + pk.PORTAL_ROUND] == 0.0:
        return 1.0 / tot
    if not cosa > 0.0:
        return 0.0
    return om_k / tot * t * t / (0.25 * math.pi * cosa)


@kernel
def portal_uniform_pdf(q, p0, p1, p2, w0, w1, w2, om, tot, skip):
    """The uniform portal strategy's pdf (1/sr) of unit direction w from p, summed over
    the portals seen (om[k] > 0, k != skip) that the ray crosses (portal_crossing,
    _portal_term)."""
    out = 0.0
    for k in range(int(q[pk.PORTAL_N])):
        if k == skip or not om[k] > 0.0:
            continue
        b = pk.PORTAL0 + pk.PORTAL_STRIDE * k
        t, cosa = portal_crossing(q, b, p0, p1, p2, w0, w1, w2)
        if t > 0.0:
            out += _portal_term(q, b, t, cosa, om[k], tot)
    return out


@kernel
def portal_sample(q, p0, p1, p2, x, u2, om, tot):
    """A direction from p through the portals seen (portal_shares' om, tot): the portal
    by x in [0, 1) over om, x rescaled within it and u2 a rectangle's spherical
    rectangle numbers (uniform in its solid angle) or a round portal's point uniform
    over its ellipse (Shirley-Chiu). Returns (w0, w1, w2, pdf per sr: the sum over the
    portals w crosses, portal_uniform_pdf); pdf 0 where no direction was found."""
    acc = 0.0
    pick = -1
    xt = x * tot
    for k in range(int(q[pk.PORTAL_N])):
        if not om[k] > 0.0:
            continue
        pick = k
        if xt < acc + om[k]:
            break
        acc += om[k]
    if pick < 0:
        return 0.0, 0.0, 1.0, 0.0
    xr = min(max((xt - acc) / om[pick], 0.0), _ONE_BELOW)
    b = pk.PORTAL0 + pk.PORTAL_STRIDE * pick
    if q[b + pk.PORTAL_ROUND] != 0.0:
        dx, dy = concentric_disk(xr, u2)
        fa, fb = 0.5 + 0.5 * dx, 0.5 + 0.5 * dy
        o = 1.0
        y0 = q[b] + fa * q[b + 3] + fb * q[b + 6]
        y1 = q[b + 1] + fa * q[b + 4] + fb * q[b + 7]
        y2 = q[b + 2] + fa * q[b + 5] + fb * q[b + 8]
    else:
        o, y0, y1, y2 = spherical_rectangle(p0, p1, p2, q[b], q[b + 1], q[b + 2], q[b + 3],
                                            q[b + 4], q[b + 5], q[b + 6], q[b + 7],
                                            q[b + 8], xr, u2, True)
    v0, v1, v2 = y0 - p0, y1 - p1, y2 - p2
    dl = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if not (o > 0.0 and dl > 0.0):
        return 0.0, 0.0, 1.0, 0.0
    w0, w1, w2 = v0 / dl, v1 / dl, v2 / dl
    ex0, ex1, ex2 = q[b + 3], q[b + 4], q[b + 5]
    ey0, ey1, ey2 = q[b + 6], q[b + 7], q[b + 8]
    cosa = abs(w0 * (ex1 * ey2 - ex2 * ey1) + w1 * (ex2 * ey0 - ex0 * ey2)
               + w2 * (ex0 * ey1 - ex1 * ey0))
    own = _portal_term(q, b, dl, cosa, om[pick], tot)
    if not own > 0.0:
        return 0.0, 0.0, 1.0, 0.0
    return w0, w1, w2, own + portal_uniform_pdf(q, p0, p1, p2, w0, w1, w2, om, tot, pick)


@kernel
def portal_choice(q, pt_sat, p0, p1, p2, s0, s1, s2, om, mass):
    """The portal strategy at point p with shading normal s: (its normaliser, s_p).
    Uniform in solid angle (q[PORTAL_MAP] 0): portal_shares (om, Omega, s_p). By the map
    (portalmap.py): also each seen portal's mass (MAX_PORTALS,) (portal_masses, the
    tables' summed-area tables pt_sat) and their sum in place of Omega; s_p 0 where no
    seen portal has any (a black map through them)."""
    tot, sp = portal_shares(q, p0, p1, p2, s0, s1, s2, om)
    if q[pk.PORTAL_MAP] != 0.0 and sp > 0.0:
        m = portal_masses(q, pt_sat, p0, p1, p2, om, mass)
        if not m > 0.0:
            return 0.0, 0.0
        return m, sp
    return tot, sp


@kernel
def portal_draw(q, pt_f, pt_sat, p0, p1, p2, x, u2, om, mass, tot):
    """A direction of the portal strategy (portal_choice's om, mass, tot at p) for
    numbers x, u2 in [0, 1): (w0, w1, w2, pdf per sr)."""
    if q[pk.PORTAL_MAP] != 0.0:
        return portal_map_sample(q, pt_f, pt_sat, p0, p1, p2, x, u2, mass, tot)
    return portal_sample(q, p0, p1, p2, x, u2, om, tot)


@kernel
def portal_density(q, pt_f, p0, p1, p2, w0, w1, w2, om, mass, tot):
    """The portal strategy's solid-angle pdf (1/sr) of unit direction w from p
    (portal_choice's om, mass, tot there)."""
    if q[pk.PORTAL_MAP] != 0.0:
        return portal_map_pdf(q, pt_f, p0, p1, p2, w0, w1, w2, mass, tot, -1, 0, 0)
    return portal_uniform_pdf(q, p0, p1, p2, w0, w1, w2, om, tot, -1)


@kernel
def portal_pdfs(q, pt_f, pt_sat, p, ns, w, share, pdf):
    """For points p (N,3), shading normals ns (N,3) and unit directions w (N,3): share
    (N,) the portal strategy's s_p there and pdf (N,) its solid-angle pdf of w (1/sr;
    portal_choice, portal_density; pt_f, pt_sat: the portal tables, packing.pack_lights)."""
    om = np.zeros(pk.MAX_PORTALS)
    mass = np.zeros(pk.MAX_PORTALS)
    for i in range(p.shape[0]):
        tot, sp = portal_choice(q, pt_sat, p[i, 0], p[i, 1], p[i, 2], ns[i, 0], ns[i, 1],
                                ns[i, 2], om, mass)
        share[i] = sp
        pdf[i] = 0.0
        if sp > 0.0:
            pdf[i] = portal_density(q, pt_f, p[i, 0], p[i, 1], p[i, 2], w[i, 0], w[i, 1],
                                    w[i, 2], om, mass, tot)


def background_radiance(scene, d: np.ndarray) -> np.ndarray:
    """Radiance (N,3) of the world seen along directions d (N,3) of rays that escape the
    scene (unit or not; re-centring does not change directions): the environment map
    when the scene has one, else the constant background colour."""
    env = getattr(scene, "environment", None)
    if env is not None:
        return env.radiance(d)
    bg = np.asarray(scene.background, np.float64)
    return np.broadcast_to(bg, (len(d), 3))


class WorldLight(InfiniteLight):
    kind = WORLD
    declared = False
    environment = None
    # Light portals for the shadow rays (set_portals): (K,4,3) corner s, edges ex, ey and
    # the normal into the room, re-centred; K = 0 without.
    portal_rects = np.zeros((0, 4, 3))
    # (K,) True for a round portal (Disk / Ellipse: the ellipse inscribed in its rect).
    portal_round = np.zeros(0, bool)
    # The names of the portals whose opening reaches past them (lights.portal_leaks): the
    # share takes PORTAL_SHARE_LEAK_* then.
    portal_leaks: list = []
    _portal_tables = None

    def set_portals(self, portals, offset) -> None:
        """Take the scene's light portals (engine.scene.LightPortal list) for the shadow
        rays (module docstring), re-centred by geo.offset (3,): the MAX_PORTALS largest
        (by area), each as corner c0, edges c1 - c0, c3 - c0 and its normal, and whether
        it is round."""
        off = np.asarray(offset, np.float64)
        rects = []
        for lp in portals or ():
            c = np.asarray(lp.corners, np.float64) - off
            ex, ey = c[1] - c[0], c[3] - c[0]
            rnd = bool(getattr(lp, "round", False))
            area = float(np.linalg.norm(np.cross(ex, ey))) * (math.pi / 4 if rnd else 1.0)
            if area > 0.0:
                rects.append((area, np.stack([c[0], ex, ey, lp.normal]), rnd))
        rects.sort(key=lambda r: -r[0])
        rects = rects[:pk.MAX_PORTALS]
        self.portal_rects = (np.array([r[1] for r in rects], np.float64).reshape(-1, 4, 3))
        self.portal_round = np.array([r[2] for r in rects], bool)
        self._portal_tables = None

    @property
    def by_map(self) -> bool:
        """Whether the portal strategy samples the environment map seen through the
        portals (portalmap.py): a map, PORTAL_MAP_SAMPLING on and no round portal (the
        tables are over a rectangle's directions; restricted to an ellipse their pdf
        would need each point's window integral over it, so round portals sample their
        area uniformly, and the rectangles their solid angle, under a map too)."""
        return (self.environment is not None and len(self.portal_rects) > 0
                and PORTAL_MAP_SAMPLING and not self.portal_round.any())

    @property
    def portal_tables(self):
        """(f, sat) of portalmap.build_portal_tables for the portals under the
        environment map (kept between prepares: portalmap.portal_tables), or None (not
        by_map)."""
        if not self.by_map:
            return None
        if self._portal_tables is None:
            self._portal_tables = portal_tables(self.environment, self.portal_rects)
        return self._portal_tables

    @classmethod
    def from_background(cls, scene, common):
        """The world light of the scene, or None (black background, or not a light)."""
        if not scene.background_is_light:
            return None
        radius = common["scene_radius"]
        env = getattr(scene, "environment", None)
        if env is not None:
            if env.is_black:
                return None
            return cls("world", radiance=env.average(), environment=env,
                       photon_flux=env.integral() * math.pi * radius ** 2,
                       radius=0.0, cos_half_angle=1.0, **common)
        bg = np.asarray(scene.background, np.float64)
        if not np.any(bg > 0):
            return None
        return cls("world", radiance=bg,
                   photon_flux=bg * math.pi * radius ** 2 * 4.0 * math.pi,
                   radius=0.0, cos_half_angle=1.0, **common)

    @property
    def needs_choice(self) -> bool:
        # (the strategy: map, cosine or, with portals, the portals)
        return self.environment is not None or len(self.portal_rects) > 0

    @property
    def portal_share_bounds(self) -> tuple:
        """(lo, hi) of the portal strategy's share s_p (module constants): the leaky
        bounds when an opening reaches past a portal (portal_leaks), else by the world."""
        if self.portal_leaks:
            return PORTAL_SHARE_LEAK_LO, PORTAL_SHARE_LEAK_HI
        if self.by_map:
            return PORTAL_SHARE_MAP_LO, PORTAL_SHARE_MAP_HI
        if self.environment is not None:
            return PORTAL_SHARE_ENV_LO, PORTAL_SHARE_ENV_HI
        return PORTAL_SHARE_LO, PORTAL_SHARE_HI

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code.
        The environment's arrays travel beside the rows (pack_lights)."""
        row[pk.RGB:pk.RGB + 3] = self.radiance
        if self.environment is not None:
            row[pk.ENV_ON] = 1.0
            row[pk.ENV_INTERP] = self.environment.interp_code
            row[pk.ENV_FRAME:pk.ENV_FRAME + 9] = self.environment.rotation.ravel()
        K = len(self.portal_rects)
        if K:
            row[pk.PORTAL_N] = K
            by_map = self.by_map
            row[pk.PORTAL_MAP] = 1.0 if by_map else 0.0
            row[pk.PORTAL_RULE] = PORTAL_RULE
            row[pk.PORTAL_LO], row[pk.PORTAL_HI] = self.portal_share_bounds
            slots = np.zeros((K, pk.PORTAL_STRIDE))
            slots[:, :12] = self.portal_rects.reshape(K, 12)
            slots[:, pk.PORTAL_ROUND] = self.portal_round
            row[pk.PORTAL0:pk.PORTAL0 + pk.PORTAL_STRIDE * K] = slots.ravel()
        return pk.CODE_WORLD

    def pdf(self, wi: np.ndarray, ns: np.ndarray, p: np.ndarray | None = None) -> np.ndarray:
        """Solid-angle pdf (N,) (1/sr) with which this light's shadow-ray sampling
        (directlight.sample_lights) picks unit directions wi (N,3) towards the world at
        shading points with shading normals ns (N,3): cos(wi, ns)^+ / pi for a constant
        world; ENV_MAP_FRACTION x the environment's cosine-weighted pdf at ns + (1 -
        ENV_MAP_FRACTION) x cos^+ / pi with an environment map. Multiply by the light's selection probability
        (engine/lights/selection.py) for the full light-sampling pdf of a BSDF-sampled ray
        that escapes (power or balance heuristic, pbrt-v4's PathIntegrator).
        With light portals, p (N,3) the (re-centred) points the directions leave: the
        mixture (1 - s_p) that + s_p p_portal(w) (module docstring: n(w) / Omega, or the
        map-weighted portalmap pdf with an environment map); p is required then
        (ValueError)."""
        wi = np.asarray(wi, np.float64).reshape(-1, 3)
        cos_pdf = np.maximum(dot(wi, np.asarray(ns, np.float64).reshape(-1, 3)), 0.0) / math.pi
        if self.environment is None:
            before = cos_pdf
        else:
            before = (ENV_MAP_FRACTION * self.environment.cosine_pdf(wi, ns)
                      + (1.0 - ENV_MAP_FRACTION) * cos_pdf)
        if not len(self.portal_rects):
            return before
        if p is None:
            raise ValueError("WorldLight.pdf: the points are needed with light portals")
        row = np.zeros(pk.P)
        self.pack(row)
        c = np.ascontiguousarray
        share, pp = np.empty(len(wi)), np.empty(len(wi))
        tables = self.portal_tables or (np.zeros((1, 1, 1)), np.zeros((1, 2, 2)))
        portal_pdfs(row, *tables, c(np.asarray(p, np.float64).reshape(-1, 3)),
                    c(np.asarray(ns, np.float64).reshape(-1, 3)), c(wi), share, pp)
        return (1.0 - share) * before + share * pp

    def seen_at_infinity(self, d):
        return None  # the background itself: background_radiance

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        env = self.environment
        if env is None:
            none = np.zeros((1, 1, 3), np.float32)
            arrays = (np.eye(3), none, none, np.ones(3), 0, np.array([0.0, 1.0]),
                      np.array([[0.0, 1.0]]), np.zeros((1, 1), np.float32))
        else:
            rows, cols, pdf_uv = env.distribution
            arrays = (env.rotation, env.pixels, env.stored, env.scale, int(env.interp_code),
                      rows, cols, pdf_uv)
        return emit_world(env is not None, *arrays, f64(self.photon_flux), f64(self.center),
                          float(self.scene_radius), *aim.arrays, aimed, key,
                          first, n, float(count), *out.arrays, start)


@kernel
def emit_world(env_on, rotation, pixels, stored, scale, interp, rows, cols, pdf_uv, flux,
               center, R, centers, radii, probs, cdf, aimed, key, first, n, count, o32, d32,
               d, power, slot, start):
    """Photons of the world. A constant background: directions uniform over the sphere,
    each flux / count (flux: the radiance through the natural disk of radius R from every
    direction). An environment map (env_on; its rotation, radiance texels, interpolation
    and distribution: environment.py): directions from the map's distribution, power
    L / pdf x pi R^2 / count (pixels: its linear texels, which the distribution samples;
    stored, scale: what its lookup reads, Environment.stored / scale; L read at the drawn
    point of its texel, environment.texel_radiance). Photons travel
    against the sampled direction, from the natural disk (emission.disk_origin) or,
    aimed, a caster's shadow disk (emission.aim_origin). Dimensions: 0, 1 the direction,
    2, 3 the origin; aimed: 2 the target, 3, 4 the origin."""
    j = start
    f0, f1, f2 = flux[0] / count, flux[1] / count, flux[2] / count
    area = math.pi * R * R
    for i in range(n):
        s = first + i
        u1 = emit_uniform(key, s, 0)
        u2 = emit_uniform(key, s, 1)
        if env_on:
            w0, w1, w2, pdf, ti, tj, fx, fy = env_sample_texel(rotation, pixels, interp, rows,
                                                                 cols, pdf_uv, u1, u2)
            # The radiance at the drawn point of its texel, not looked up again through
            # the direction (texel_radiance: the same value up to rounding).
            L0, L1, L2 = texel_radiance(stored, interp, scale, ti, tj, fx, fy)
            inv = 1.0 / max(pdf, 1e-300) if pdf > 0 else 0.0
            g = inv * area / count
            p0, p1, p2 = L0 * g, L1 * g, L2 * g
            d0, d1, d2 = -w0, -w1, -w2
        else:
            d0, d1, d2 = uniform_sphere(u1, u2)
            p0, p1, p2 = f0, f1, f2
        if not aimed:
            o0, o1, o2 = disk_origin(center, R, d0, d1, d2, emit_uniform(key, s, 2),
                                     emit_uniform(key, s, 3))
        else:
            o0, o1, o2, w = aim_origin(center, R, centers, radii, probs, cdf, d0, d1, d2,
                                       emit_uniform(key, s, 2), emit_uniform(key, s, 3),
                                       emit_uniform(key, s, 4))
            p0, p1, p2 = p0 * w, p1 * w, p2 * w
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, p0, p1, p2, s)
    return j


@register_warm_up
def _warm_up():
    """Compile (or load) the light portals' kernels outside directlight.sample_lights:
    the portal tables under a map and WorldLight.pdf's portal_pdfs (the continuation's
    MIS weight) for a map and for a constant world."""
    from ..scene import LightPortal
    from .environment import Environment
    portal = LightPortal("portal", [(-0.5, -0.5, 1.0), (0.5, -0.5, 1.0), (0.5, 0.5, 1.0),
                                    (-0.5, 0.5, 1.0)], (0.0, 0.0, -1.0))
    common = dict(center=np.zeros(3), scene_radius=2.0, radius=0.0, cos_half_angle=1.0,
                  photon_flux=np.ones(3), radiance=np.ones(3))
    w = np.array([[0.0, 0.0, 1.0]])
    for env in (Environment(np.ones((2, 4, 3))), None):
        light = WorldLight("world", environment=env, **common)
        light.set_portals([portal], np.zeros(3))
        light.pdf(w, w, np.zeros((1, 3)))
