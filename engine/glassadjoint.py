"""Photons at smooth glass with a bent shading normal: the adjoint of Cycles' glass.

Cycles' glass closure reflects and refracts the camera-side direction w about
N' = ensure_valid_specular_reflection(Ng, w, Ns) (kernel/closure/bsdf_util.h;
principled.valid_reflection_normal): Ns itself, or, where the mirror direction of w about
Ns would not rise min(0.9 w.Ng, 0.01) over the surface, Ns turned towards Ng until it
does. N' depends on w, so sampling about a normal chosen from the photon's side (pbrt's
rule) is not the adjoint. A photon arriving along d (s = -d) must leave along every w
that Cycles sends to s, with power times the flux ratio of that map:

    weight = f_w * J * |w.Ng| / |s.Ng|,   J = |d omega_w / d omega_s|

(f_w: Cycles' Fresnel reflectance or transmittance at that hit). Three kinds of w:

- the mirror direction of s about Ns, where Cycles does not turn N for it (J = 1);
- the refraction of d about Ns, where Cycles does not turn N for it
  (J = (eta_s / eta_w)^2 |s.Ns| / |w.Ns|, Snell's solid-angle law);
- refractions about a turned normal: N(phi) = cos(phi) x + sin(phi) Ng in the plane of Ns
  and Ng (x: Ns's unit tangential part) on w's side; w(phi) = the refraction of d about
  N(phi); a solution where Cycles turns N for w(phi) to N(phi) itself (a 1-D root search
  over phi, bisection) with J from two perturbed arrivals (finite differences).

Cycles' turned-normal reflections send every w of a solid angle into the one band of
directions min(0.9 w.Ng, 0.01) over the surface, which no photon arrives from (a set of
no solid angle): they have no photon counterpart and are left out (docs/accuracy.md,
smoothglass43). A photon none of the three kinds serves is dropped, as Cycles has no
path through there.
"""
from __future__ import annotations

import math

import numpy as np

from .closures import principled as pr
from .closures.fresnel import schlick_remap
from .jit import kernel

_SCAN = 256       # phi samples over a right angle between Ns and Ng (sign changes)
_BISECT = 56      # bisection steps of a root (to float64 resolution)
_EPS = 1e-5       # arrival perturbation of the finite-difference Jacobian (radians)
_BRACKET = 2e-3   # phi bracket around a root for the perturbed solves
MAX_W = 6         # candidate directions per hit (mirror, refraction, turned refractions)
_RISE = 0.01      # Cycles' height over the surface a mirror direction must keep (bsdf_util.h)
_GUARD = 1e-6     # photon_surfaces' guard: an arrival this close to below n takes Ng
_MARGIN = 1e-6    # radians kept from each bound below (rounding of the two rules)


@kernel
def turn_possible(d0, d1, d2, n0, n1, n2, g0, g1, g2, eta):
    """False where Cycles keeps Ns for every direction its glass sends to this arrival:
    the adjoint's only candidates are then the mirror and the refraction about Ns, and
    candidates needs no root search (turned=False gives the same rows).

    d: the photon's unit direction; n, g: unit (unguarded) shading and geometric
    normals on the arrival side; eta = eta_to / eta_from. A cheap sufficient bound, no
    root search: with beta the angle between n and g, every normal N' Cycles could turn to
    lies on the arc from n to g, so (1) the mirror direction w of s = -d about n is never
    turned where s.Ng >= 0.01 (its mirror about n is s); (2) if the arrival's angle to
    every N' on the arc (>= max(angle(s, n), angle(s, g)) - beta) is past the critical
    angle, nothing refracts; else (3) a refraction w about any N' leaves at most
    theta_t = asin(sin(max(angle(s, n), angle(s, g))) / eta) from N' (the angle to a
    point of a geodesic arc shorter than pi, both cosines positive, is largest at an end),
    so w's mirror about Ns is at most theta_t + 3 beta from Ng and rises >= 0.01 over
    the surface where theta_t + 3 beta <= acos(0.01): Cycles turns no such w.
    True (the adjoint needed) otherwise, and for arrivals below n (photonkernels' guard)
    or within 0.01 of grazing."""
    sg = -(d0 * g0 + d1 * g1 + d2 * g2)
    cs = -(d0 * n0 + d1 * n1 + d2 * n2)
    if not (sg >= _RISE and cs > _GUARD):
        return True
    beta = math.acos(min(n0 * g0 + n1 * g1 + n2 * g2, 1.0))
    widest = math.acos(min(min(sg, cs), 1.0))
    r = 1.0 / eta
    narrowest = max(widest - beta - _MARGIN, 0.0)
    if r * math.sin(narrowest) >= 1.0:
        return False  # total internal reflection about every N': the mirror alone
    st = r * math.sin(widest)
    if st >= 1.0:
        return True
    return math.asin(st) + 3.0 * beta + _MARGIN > math.acos(_RISE)


@kernel
def refract_dir(dx, dy, dz, nx, ny, nz, r):
    """(ok, t) the refraction of unit direction d at a surface whose unit normal n faces
    it (d.n < 0), r = eta_from / eta_to; ok False for total internal reflection or
    d arriving from below n."""
    c = -(dx * nx + dy * ny + dz * nz)
    if c <= 0.0:
        return False, 0.0, 0.0, 0.0
    s2 = r * r * (1.0 - c * c)
    if s2 >= 1.0:
        return False, 0.0, 0.0, 0.0
    k = r * c - math.sqrt(1.0 - s2)
    return True, r * dx + k * nx, r * dy + k * ny, r * dz + k * nz


@kernel
def _turned_angle(nq, gq, xq, phi_n, w0, w1, w2):
    """(valid, raised, psi): the angle in the (x, Ng) plane of the normal Cycles takes for
    the camera-side direction w on side Q (nq, gq: its shading and geometric normals)."""
    if w0 * gq[0] + w1 * gq[1] + w2 * gq[2] <= 0.0:
        return False, False, 0.0
    raised, p0, p1, p2 = pr.valid_reflection_normal(nq[0], nq[1], nq[2], gq[0], gq[1],
                                                    gq[2], w0, w1, w2)
    if not raised:
        return True, False, phi_n
    return True, True, math.atan2(p0 * gq[0] + p1 * gq[1] + p2 * gq[2],
                                  p0 * xq[0] + p1 * xq[1] + p2 * xq[2])


@kernel
def _w_of(d0, d1, d2, xq, gq, phi, r):
    """(ok, w) the refraction of d about N(phi) (on side Q; the photon meets -N)."""
    c, s = math.cos(phi), math.sin(phi)
    n0, n1, n2 = c * xq[0] + s * gq[0], c * xq[1] + s * gq[1], c * xq[2] + s * gq[2]
    return refract_dir(d0, d1, d2, -n0, -n1, -n2, r)


@kernel
def _residual(d0, d1, d2, nq, gq, xq, phi_n, phi, r):
    """(valid, e, w): e = (Cycles' turned angle for w(phi)) - phi (0 at a solution with
    raised True; an unturned w gives phi_n - phi < 0)."""
    ok, w0, w1, w2 = _w_of(d0, d1, d2, xq, gq, phi, r)
    if not ok:
        return False, 0.0, 0.0, 0.0, 0.0
    valid, raised, psi = _turned_angle(nq, gq, xq, phi_n, w0, w1, w2)
    if not valid:
        return False, 0.0, 0.0, 0.0, 0.0
    return True, psi - phi, w0, w1, w2


@kernel
def _bisect(d0, d1, d2, nq, gq, xq, phi_n, lo, hi, e_lo, r):
    """A root of _residual in [lo, hi] (e_lo: its sign at lo; the sign differs at hi):
    (ok, phi)."""
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        if mid == lo or mid == hi:
            # lo and hi adjacent floats: every further step would evaluate one of them
            # again and change nothing (the same result, fewer evaluations).
            break
        valid, e, w0, w1, w2 = _residual(d0, d1, d2, nq, gq, xq, phi_n, mid, r)
        if not valid:
            return False, 0.0
        if (e > 0.0) == (e_lo > 0.0):
            lo, e_lo = mid, e
        else:
            hi = mid
    return True, 0.5 * (lo + hi)


@kernel
def _solve_near(d0, d1, d2, nq, gq, xq, phi_n, phi, r):
    """The root of _residual near phi for a slightly moved arrival d: (ok, w)."""
    b = _BRACKET
    for _ in range(5):  # narrower brackets near the edge of the refracting range
        lo = max(phi - b, phi_n)
        hi = min(phi + b, 0.5 * math.pi)
        b *= 0.1
        va, ea, a0, a1, a2 = _residual(d0, d1, d2, nq, gq, xq, phi_n, lo, r)
        vb, eb, b0, b1, b2 = _residual(d0, d1, d2, nq, gq, xq, phi_n, hi, r)
        if not (va and vb) or (ea > 0.0) == (eb > 0.0):
            continue
        ok, root = _bisect(d0, d1, d2, nq, gq, xq, phi_n, lo, hi, ea, r)
        if ok:
            return _w_of(d0, d1, d2, xq, gq, root, r)
    return False, 0.0, 0.0, 0.0


@kernel
def _jacobian(d0, d1, d2, w0, w1, w2, nq, gq, xq, phi_n, phi, r):
    """|d omega_w / d omega_s| at a turned-normal refraction, by finite differences."""
    # Two unit directions perpendicular to d.
    a0, a1, a2 = (1.0, 0.0, 0.0) if abs(d0) < 0.9 else (0.0, 1.0, 0.0)
    u0, u1, u2 = d1 * a2 - d2 * a1, d2 * a0 - d0 * a2, d0 * a1 - d1 * a0
    lu = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    u0, u1, u2 = u0 / lu, u1 / lu, u2 / lu
    v0, v1, v2 = d1 * u2 - d2 * u1, d2 * u0 - d0 * u2, d0 * u1 - d1 * u0
    pa0, pa1, pa2 = d0 + _EPS * u0, d1 + _EPS * u1, d2 + _EPS * u2
    la = math.sqrt(pa0 * pa0 + pa1 * pa1 + pa2 * pa2)
    pa0, pa1, pa2 = pa0 / la, pa1 / la, pa2 / la
    pb0, pb1, pb2 = d0 + _EPS * v0, d1 + _EPS * v1, d2 + _EPS * v2
    lb = math.sqrt(pb0 * pb0 + pb1 * pb1 + pb2 * pb2)
    pb0, pb1, pb2 = pb0 / lb, pb1 / lb, pb2 / lb
    oka, wa0, wa1, wa2 = _solve_near(pa0, pa1, pa2, nq, gq, xq, phi_n, phi, r)
    okb, wb0, wb1, wb2 = _solve_near(pb0, pb1, pb2, nq, gq, xq, phi_n, phi, r)
    if not (oka and okb):
        return 0.0
    ea0, ea1, ea2 = wa0 - w0, wa1 - w1, wa2 - w2
    eb0, eb1, eb2 = wb0 - w0, wb1 - w1, wb2 - w2
    c0, c1, c2 = ea1 * eb2 - ea2 * eb1, ea2 * eb0 - ea0 * eb2, ea0 * eb1 - ea1 * eb0
    fa0, fa1, fa2 = pa0 - d0, pa1 - d1, pa2 - d2
    fb0, fb1, fb2 = pb0 - d0, pb1 - d1, pb2 - d2
    h0, h1, h2 = fa1 * fb2 - fa2 * fb1, fa2 * fb0 - fa0 * fb2, fa0 * fb1 - fa1 * fb0
    den = math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    if not den > 0.0:
        return 0.0
    return math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / den


@kernel
def _fresnel_rgb(gprm, c, eta):
    """The glass lobe's reflectance per channel at arrival cosine c (principled._glass_F_s
    with the hit's F0 columns; eta: gprm's P_GLASS_ETA, the arrival side's)."""
    s = schlick_remap(c, eta)
    return (pr._glass_F_s(gprm[0, pr.P_GLASS_F0], s),
            pr._glass_F_s(gprm[0, pr.P_GLASS_F0 + 1], s),
            pr._glass_F_s(gprm[0, pr.P_GLASS_F0 + 2], s))


@kernel
def _put(out, k, w0, w1, w2, gprm, col, a0, a1, a2, f, transmitted):
    """Writes candidate row k (direction w; weights: gprm's colour columns col.. times
    a (Fresnel reflectance or transmittance per channel) times f): returns k + 1."""
    out[k, 0], out[k, 1], out[k, 2] = w0, w1, w2
    out[k, 3] = gprm[0, col] * a0 * f
    out[k, 4] = gprm[0, col + 1] * a1 * f
    out[k, 5] = gprm[0, col + 2] * a2 * f
    out[k, 6] = transmitted
    return k + 1


@kernel
def candidates(gprm, d, n, g, out, turned):
    """Every direction Cycles' smooth glass sends to a photon's arrival (module doc).

    gprm (1, N_PACK): the hit's packed glass columns (photonkernels.smooth_glass_at);
    d (3,) the photon's unit direction of travel; n, g (3,) unit shading (unguarded) and
    geometric normals on the arrival side (d.g < 0). Writes rows of out (MAX_W, 7): the
    leaving direction w (3), per-channel weights (3: weight / (eta_s / eta_w)^2 for a
    refraction, the factor photonkernels.scatter applies itself) and 1.0 for a refraction
    (0.0: reflection). turned False: the mirror and the refraction about n only, no
    root search (where turn_possible is False there is no turned-normal one to find).
    Returns the row count."""
    eta = gprm[0, pr.P_GLASS_ETA]  # eta_to / eta_from (the arrival side's)
    r = 1.0 / eta
    d0, d1, d2 = d[0], d[1], d[2]
    sg = -(d0 * g[0] + d1 * g[1] + d2 * g[2])
    if not sg > 0.0:
        return 0
    cs = -(d0 * n[0] + d1 * n[1] + d2 * n[2])
    k = 0
    # Side Q (across the surface): its normals.
    nq = np.empty(3)
    gq = np.empty(3)
    xq = np.empty(3)
    for c in range(3):
        nq[c], gq[c] = -n[c], -g[c]
    dot = nq[0] * gq[0] + nq[1] * gq[1] + nq[2] * gq[2]
    for c in range(3):
        xq[c] = nq[c] - dot * gq[c]
    lx = math.sqrt(xq[0] * xq[0] + xq[1] * xq[1] + xq[2] * xq[2])
    if cs > 0.0:
        F0, F1, F2 = _fresnel_rgb(gprm, cs, eta)
        # The mirror direction about n, where Cycles keeps n for it.
        w0, w1, w2 = d0 + 2.0 * cs * n[0], d1 + 2.0 * cs * n[1], d2 + 2.0 * cs * n[2]
        wg = w0 * g[0] + w1 * g[1] + w2 * g[2]
        if wg > 0.0:
            raised, p0, p1, p2 = pr.valid_reflection_normal(n[0], n[1], n[2], g[0], g[1],
                                                            g[2], w0, w1, w2)
            if not raised:
                k = _put(out, k, w0, w1, w2, gprm, pr.P_GLASS_RW, F0, F1, F2, wg / sg, 0.0)
        # The refraction about n, where Cycles keeps n for it.
        ok, w0, w1, w2 = refract_dir(d0, d1, d2, n[0], n[1], n[2], r)
        if ok:
            wg = w0 * gq[0] + w1 * gq[1] + w2 * gq[2]
            wn = abs(w0 * n[0] + w1 * n[1] + w2 * n[2])
            if wg > 0.0 and wn > 0.0:
                raised, p0, p1, p2 = pr.valid_reflection_normal(nq[0], nq[1], nq[2], gq[0],
                                                                gq[1], gq[2], w0, w1, w2)
                if not raised:
                    f = cs * wg / (sg * wn)  # J without (eta_s / eta_w)^2
                    k = _put(out, k, w0, w1, w2, gprm, pr.P_GLASS_TW, 1.0 - F0, 1.0 - F1,
                             1.0 - F2, f, 1.0)
    if not (turned and lx > 1e-9):
        return k  # n == +-g: nothing to turn
    for c in range(3):
        xq[c] /= lx
    phi_n = math.atan2(dot, nq[0] * xq[0] + nq[1] * xq[1] + nq[2] * xq[2])
    # Refractions about a turned normal: roots of the residual over (phi_n, pi / 2].
    # Samples denser towards Ng (the refraction is often total there but for a sliver).
    # As many samples as the span between Ns and Ng needs (_SCAN over a right angle, at
    # least 16): a finely tessellated ball's normals bend a degree or two.
    span = 0.5 * math.pi - phi_n
    scan = max(16, int(_SCAN * span / (0.5 * math.pi)) + 1)
    prev_ok = False
    prev_e = 0.0
    prev_phi = 0.0
    for i in range(1, scan + 1):
        q = 1.0 - i / scan
        phi = 0.5 * math.pi - span * q * q * q
        valid, e, w0, w1, w2 = _residual(d0, d1, d2, nq, gq, xq, phi_n, phi, r)
        if valid and not prev_ok and i > 1:
            # Entering the refracting range: start the sign test at its edge.
            lo, hi = prev_phi, phi
            for _ in range(_BISECT):
                mid = 0.5 * (lo + hi)
                vm, em, m0, m1, m2 = _residual(d0, d1, d2, nq, gq, xq, phi_n, mid, r)
                if vm:
                    hi, prev_e = mid, em
                else:
                    lo = mid
            prev_ok, prev_phi = hi != phi, hi
        if valid and prev_ok and (e > 0.0) != (prev_e > 0.0) and k < MAX_W:
            ok, root = _bisect(d0, d1, d2, nq, gq, xq, phi_n, prev_phi, phi, prev_e, r)
            if ok:
                vr, er, w0, w1, w2 = _residual(d0, d1, d2, nq, gq, xq, phi_n, root, r)
                if vr and abs(er) < 1e-7:
                    J = _jacobian(d0, d1, d2, w0, w1, w2, nq, gq, xq, phi_n, root, r)
                    cr, sr = math.cos(root), math.sin(root)
                    # The photon meets -N(root): its arrival cosine there.
                    c_in = (d0 * (cr * xq[0] + sr * gq[0]) + d1 * (cr * xq[1] + sr * gq[1])
                            + d2 * (cr * xq[2] + sr * gq[2]))
                    wg = w0 * gq[0] + w1 * gq[1] + w2 * gq[2]
                    if J > 0.0 and c_in > 0.0:
                        F0, F1, F2 = _fresnel_rgb(gprm, min(c_in, 1.0), eta)
                        f = J * wg / (sg * r * r)
                        k = _put(out, k, w0, w1, w2, gprm, pr.P_GLASS_TW, 1.0 - F0,
                                 1.0 - F1, 1.0 - F2, f, 1.0)
        prev_ok, prev_e, prev_phi = valid, e, phi
    return k


@kernel
def pick(out, k, u):
    """Chooses one of candidates' k rows with probability proportional to its largest
    channel weight: (ok, w (3), per-channel weights divided by that probability (3),
    transmitted)."""
    total = 0.0
    for i in range(k):
        total += max(out[i, 3], max(out[i, 4], out[i, 5]))
    if not total > 0.0:
        return False, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, False
    x = u * total
    acc = 0.0
    j = k - 1
    for i in range(k):
        acc += max(out[i, 3], max(out[i, 4], out[i, 5]))
        if x < acc:
            j = i
            break
    p = max(out[j, 3], max(out[j, 4], out[j, 5])) / total
    return (True, out[j, 0], out[j, 1], out[j, 2], out[j, 3] / p, out[j, 4] / p,
            out[j, 5] / p, out[j, 6] > 0.5)
