"""Compiled stages of the shadow rays through single-plane glass panes (engine/panelight.py
describes what they compute; issue 13: what runs between two Embree calls is compiled).

One pass per stage over a batch of shading points, writing compacted arrays for the next
Embree call instead of numpy's per-step array passes (the numpy cost about nine tenths of
pane_irradiance: panespeed32 in docs/performance.md):

  sun_directions      a sun sample's direction in its cone (uniform in solid angle)
  world_strategies    a world sample's strategy (MAP / OUTSIDE / INSIDE / AREA) and the
                      point's shares, the first coordinate rescaled within its share, the
                      OUTSIDE / INSIDE cosine directions and the AREA points' directions
  first_rays          per pane: refraction (either way), the receiver's and the plane's
                      tests, the closest-hit rays towards the pane (compacted)
  second_rays         per pane: the closest hits that are the pane at the plane, the
                      occlusion rays on from just past it (float32, Embree's layout)
  sun_accumulate      E += T (eta_i / eta_t)^2 cos_i / cos_t (N . w_t) E_sun trans / count
  world_accumulate    E += T L (N . w_t) / pdf_mixture trans / count

Each replaces numpy code line for line, in the same arithmetic order (products and sums
left to right as numpy evaluates them), so the results match numpy's except where numpy's
3-vector dot products (matmul through BLAS, which may fuse multiply-adds) round differently
in the last bit; the Fresnel table lookup is np.interp's own formula and search.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up
from .lights.emission import pick, to_world

_MAP, _OUTSIDE, _INSIDE, _AREA = 0, 1, 2, 3   # panelight's strategy indices


@kernel
def sun_directions(u1, u2, a, bu, bv, cos_half, w):
    """w (N,3) <- directions uniform in solid angle within the cone of cos_half about unit
    a (3,) (bu, bv (3,) its frame) from uniform numbers u1, u2 (N,)."""
    for i in range(len(u1)):
        z = 1.0 - u1[i] * (1.0 - cos_half)
        r = math.sqrt(max(0.0, 1.0 - z * z))
        phi = 2.0 * math.pi * u2[i]
        c = r * math.cos(phi)
        s = r * math.sin(phi)
        for j in range(3):
            w[i, j] = c * bu[j] + s * bv[j] + z * a[j]


@kernel
def _cosine_direction(u1, u2, n0, n1, n2, out, i):
    """out[i] <- a cosine-distributed direction about unit (n0, n1, n2) (Malley's method,
    in lights.emission.to_world's frame)."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    out[i, 0], out[i, 1], out[i, 2] = to_world(r * math.cos(phi), r * math.sin(phi),
                                               math.sqrt(max(0.0, 1.0 - u1)), n0, n1, n2)


@kernel
def world_strategies(x, u2, shares, adapt, adapt_min, inside_tilt, p, ns, pane_n, centres, areas,
                     tri_v0, tri_e1, tri_e2, tri_cdf, tri_k, one_below,
                     S, strat, a, wc, on_k):
    """Per point i of x, u2 (N,) (uniform numbers; x picks the strategy): S (N,4) <- the
    point's shares (shares (4,), summing to 1; with adapt, OUTSIDE's and AREA's together
    split by the panes' projected solid angle over pi, clipped to [adapt_min,
    1 - adapt_min]: A cos_pane cos_n / (pi d^2) from each pane's centre (pane_n,
    centres (K,3), areas (K,)), summed; and inside_tilt x the largest |sin 2 theta| over
    the panes, theta between ns and a pane's normal, moved from them to INSIDE: a tilted
    receiver sees directions OUTSIDE cannot draw, N . w <= 0 < N . w_t, which only AREA's
    small share covered, as rare bright samples), strat (N,) <- the strategy, a (N,) <- x rescaled
    within its share (< 1), wc (N,3) <- OUTSIDE's outside / INSIDE's inside cosine
    direction about ns, AREA's unit direction towards a point uniform over the panes'
    triangles (v0, e1, e2 (M,3), area CDF (M,), pane tri_k (M,); Shirley's square-root
    map), on_k (N,) <- that point's pane (-1 for the other strategies). MAP rows' wc stay
    zero (panelight.pane_irradiance fills w from the map)."""
    K = len(areas)
    r_split = shares[_OUTSIDE] + shares[_AREA]
    for i in range(len(x)):
        Si = S[i]
        for j in range(4):
            Si[j] = shares[j]
        if adapt:
            q = 0.0
            for k in range(K):
                v0 = centres[k, 0] - p[i, 0]
                v1 = centres[k, 1] - p[i, 1]
                v2 = centres[k, 2] - p[i, 2]
                d2 = max(v0 * v0 + v1 * v1 + v2 * v2, 1e-300)
                inv = 1.0 / math.sqrt(d2)
                cp = abs(v0 * pane_n[k, 0] + v1 * pane_n[k, 1] + v2 * pane_n[k, 2]) * inv
                cn = max(v0 * ns[i, 0] + v1 * ns[i, 1] + v2 * ns[i, 2], 0.0) * inv
                q += areas[k] * cp * cn / (math.pi * d2)
            q = min(max(q, adapt_min), 1.0 - adapt_min)
            tilt = 0.0
            for k in range(K):
                c = abs(ns[i, 0] * pane_n[k, 0] + ns[i, 1] * pane_n[k, 1]
                        + ns[i, 2] * pane_n[k, 2])
                tilt = max(tilt, 2.0 * c * math.sqrt(max(1.0 - c * c, 0.0)))
            moved = min(inside_tilt * tilt, r_split)
            Si[_INSIDE] = shares[_INSIDE] + moved
            Si[_OUTSIDE] = (r_split - moved) * q
            Si[_AREA] = (r_split - moved) * (1.0 - q)
        # np.cumsum of the shares, then the count of tops at or below x (capped)
        top = 0.0
        cnt = 0
        for j in range(4):
            top = top + Si[j]
            if x[i] >= top:
                cnt += 1
        s = min(cnt, _AREA)
        below = 0.0
        for j in range(s + 1):
            below = below + Si[j]
        below = below - Si[s]
        strat[i] = s
        ai = (x[i] - below) / max(Si[s], 1e-300)
        ai = min(max(ai, 0.0), one_below)
        a[i] = ai
        on_k[i] = -1
        wc[i, 0] = 0.0
        wc[i, 1] = 0.0
        wc[i, 2] = 0.0
        if s == _OUTSIDE or s == _INSIDE:
            _cosine_direction(ai, u2[i], ns[i, 0], ns[i, 1], ns[i, 2], wc, i)
        elif s == _AREA:
            # the triangle: np.searchsorted(cdf, ai, 'right'), ai rescaled within its bin
            j = pick(tri_cdf, ai)
            c0 = tri_cdf[j - 1] if j > 0 else 0.0
            r1 = min(max((ai - c0) / max(tri_cdf[j] - c0, 1e-300), 0.0), 1.0)
            sq = math.sqrt(r1)
            f1 = sq * (1.0 - u2[i])
            f2 = sq * u2[i]
            y0 = tri_v0[j, 0] + f1 * tri_e1[j, 0] + f2 * tri_e2[j, 0] - p[i, 0]
            y1 = tri_v0[j, 1] + f1 * tri_e1[j, 1] + f2 * tri_e2[j, 1] - p[i, 1]
            y2 = tri_v0[j, 2] + f1 * tri_e1[j, 2] + f2 * tri_e2[j, 2] - p[i, 2]
            norm = max(math.sqrt(y0 * y0 + y1 * y1 + y2 * y2), 1e-300)
            wc[i, 0] = y0 / norm
            wc[i, 1] = y1 / norm
            wc[i, 2] = y2 / norm
            on_k[i] = tri_k[j]


@kernel
def first_rays(p, ns, ng, offset, w0, wc, inside, on_k, k, n, c, ior, lo, hi, scale,
               idx, w, cos_i, cos_t, eta2, side, cr, o, d, t_plane, tmax):
    """Pane k (unit winding normal n (3,), a point c (3,) on it, IOR ior, padded bounds lo,
    hi (3,)) for the points p, ns, ng (N,3), offset (N,): the outside direction w0 (N,3),
    or where inside (N,) bool the inside direction wc (N,3) refracted back out (none at
    total internal reflection); on_k (N,) the pane a row must meet (-1: any). Keeps the
    rows whose receiver lies on the far side of the plane from w and faces w_t (shading
    and geometric normal), whose ray from p + offset ng along w_t crosses the plane ahead
    within lo..hi; writes them compacted: idx (M,) the row, w, the outside direction,
    cos_i, cos_t, eta2 = (eta_i / eta_t)^2, side (0 from outside), cr = N . w_t, the
    closest-hit ray o, d (M,3) and tmax (M,) just past the plane at t_plane (M,).
    Returns M. (panelight.refract_sun and panelight._through.)"""
    m = 0
    inv_ior = 1.0 / ior
    for i in range(len(p)):
        if on_k[i] >= 0 and on_k[i] != k:
            continue  # an AREA point on another pane: that pane's
        if inside[i]:
            # refract_sun(-wc): light arriving from the receiver's side, back out
            v0, v1, v2 = -wc[i, 0], -wc[i, 1], -wc[i, 2]
            dn = v0 * n[0] + v1 * n[1] + v2 * n[2]
            eta = inv_ior if dn > 0.0 else ior
            ci = abs(dn)
            s2 = eta * eta * max(1.0 - ci * ci, 0.0)
            if not (s2 < 1.0 and ci > 0.0):
                continue
            ct = math.sqrt(max(1.0 - s2, 0.0))
            sg = 1.0 if dn > 0.0 else -1.0
            f = eta * ci - ct
            # w = -(refract_sun's -tdir) = tdir = eta (-v) + f ns
            x0 = eta * (-v0) + f * (sg * n[0])
            x1 = eta * (-v1) + f * (sg * n[1])
            x2 = eta * (-v2) + f * (sg * n[2])
        else:
            x0, x1, x2 = w0[i, 0], w0[i, 1], w0[i, 2]
        dn = x0 * n[0] + x1 * n[1] + x2 * n[2]
        sd = 0 if dn > 0.0 else 1
        eta = inv_ior if sd == 0 else ior
        ci = abs(dn)
        s2 = eta * eta * max(1.0 - ci * ci, 0.0)
        if not (s2 < 1.0 and ci > 0.0):
            continue
        ct = math.sqrt(max(1.0 - s2, 0.0))
        if inside[i]:
            t0, t1, t2 = wc[i, 0], wc[i, 1], wc[i, 2]
        else:
            sg = 1.0 if dn > 0.0 else -1.0
            f = eta * ci - ct
            t0 = -(eta * (-x0) + f * (sg * n[0]))
            t1 = -(eta * (-x1) + f * (sg * n[1]))
            t2 = -(eta * (-x2) + f * (sg * n[2]))
        h = (p[i, 0] - c[0]) * n[0] + (p[i, 1] - c[1]) * n[1] + (p[i, 2] - c[2]) * n[2]
        if not (h < 0.0 if sd == 0 else h > 0.0):
            continue
        cri = t0 * ns[i, 0] + t1 * ns[i, 1] + t2 * ns[i, 2]
        cgi = t0 * ng[i, 0] + t1 * ng[i, 1] + t2 * ng[i, 2]
        if not (cri > 0.0 and cgi > 0.0):
            continue
        o0 = p[i, 0] + offset[i] * ng[i, 0]
        o1 = p[i, 1] + offset[i] * ng[i, 1]
        o2 = p[i, 2] + offset[i] * ng[i, 2]
        num = (c[0] - o0) * n[0] + (c[1] - o1) * n[1] + (c[2] - o2) * n[2]
        den = t0 * n[0] + t1 * n[1] + t2 * n[2]
        if den == 0.0:
            continue
        tp = num / den
        if not (math.isfinite(tp) and tp > 0.0):
            continue
        y0 = o0 + tp * t0
        y1 = o1 + tp * t1
        y2 = o2 + tp * t2
        if not (lo[0] <= y0 <= hi[0] and lo[1] <= y1 <= hi[1] and lo[2] <= y2 <= hi[2]):
            continue
        idx[m] = i
        w[m, 0], w[m, 1], w[m, 2] = x0, x1, x2
        cos_i[m], cos_t[m], eta2[m], side[m], cr[m] = ci, ct, eta * eta, sd, cri
        o[m, 0], o[m, 1], o[m, 2] = o0, o1, o2
        d[m, 0], d[m, 1], d[m, 2] = t0, t1, t2
        t_plane[m] = tp
        tmax[m] = tp * (1.0 + 1e-3) + 1e-6 * scale
        m += 1
    return m


@kernel
def second_rays(t_hit, prim, tri_pane, k, t_plane, o, d, side, w, n, scale,
                keep, o32, d32, t32):
    """The closest hits (t_hit, prim (M,)) of first_rays' rays o, d (M,3) that are pane k
    (tri_pane (T,) each triangle's pane) at the plane's distance t_plane (M,): keep (M2,)
    <- their rows among the M, o32 <- the plane point lifted just past it on the light's
    side (side (M,) 0: n's side), d32 <- the outside direction w (M,3), t32 <- float32 max
    (Embree's layout). Returns M2."""
    m = 0
    big = np.float32(3.4028234663852886e38)
    for i in range(len(t_hit)):
        pr = prim[i]
        if pr < 0 or tri_pane[pr] != k:
            continue
        tp = t_plane[i]
        if not abs(t_hit[i] - tp) <= 1e-3 * tp + 1e-5 * scale:
            continue
        y0 = o[i, 0] + tp * d[i, 0]
        y1 = o[i, 1] + tp * d[i, 1]
        y2 = o[i, 2] + tp * d[i, 2]
        lift = 1e-6 * scale + 4e-7 * max(abs(y0), abs(y1), abs(y2))
        sg = 1.0 if side[i] == 0 else -1.0
        keep[m] = i
        o32[m, 0] = np.float32(y0 + lift * (sg * n[0]))
        o32[m, 1] = np.float32(y1 + lift * (sg * n[1]))
        o32[m, 2] = np.float32(y2 + lift * (sg * n[2]))
        d32[m, 0] = np.float32(w[i, 0])
        d32[m, 1] = np.float32(w[i, 1])
        d32[m, 2] = np.float32(w[i, 2])
        t32[m] = big
        m += 1
    return m


@kernel
def _interp_T(T, s, ch, x, grid):
    """np.interp(x, grid, T[s, :, ch]) for a uniform grid of [0, 1]: numpy's search
    (grid[j] <= x < grid[j + 1]) and formula (slope (y1 - y0) / (g1 - g0) times x - g0,
    plus y0)."""
    R = len(grid)
    if not x > grid[0]:
        return T[s, 0, ch]
    if x >= grid[R - 1]:
        return T[s, R - 1, ch]
    j = min(max(int(x * (R - 1)), 0), R - 2)
    while j > 0 and grid[j] > x:
        j -= 1
    while j < R - 2 and grid[j + 1] <= x:
        j += 1
    if grid[j] == x:
        return T[s, j, ch]
    y0 = T[s, j, ch]
    y1 = T[s, j + 1, ch]
    slope = (y1 - y0) / (grid[j + 1] - grid[j])
    r = slope * (x - grid[j]) + y0
    if math.isnan(r):
        r = slope * (x - grid[j + 1]) + y1
        if math.isnan(r) and y0 == y1:
            r = y0
    return r


@kernel
def sun_accumulate(E, idx, keep, cos_i, cos_t, eta2, side, cr, T, grid, trans, rgb, count):
    """E[idx[keep[r]]] += T(cos_i) (eta2 cos_i / max(cos_t, 1e-12) cr / count) trans[r]
    rgb for each kept row r (keep (M2,), trans (M2,3) the shadow rays' transmittance;
    T (2, R, 3) the pane's table on grid (R,))."""
    for r in range(len(keep)):
        i = keep[r]
        ci = cos_i[i]
        f = eta2[i] * ci / max(cos_t[i], 1e-12) * cr[i] / count
        row = idx[i]
        for ch in range(3):
            Tc = _interp_T(T, side[i], ch, ci, grid)
            E[row, ch] += f * Tc * trans[r, ch] * rgb[ch]


@kernel
def world_accumulate(E, idx, keep, w, cos_i, cos_t, eta2, side, cr, t_plane, S, ns,
                     env_pdf, use_map, area, T, grid, trans, L, count):
    """E[idx[keep[r]]] += T(cos_i) L cr / pdf trans / count for each kept row r, the
    mixture's pdf per sr of inside directions
        S_in cr / pi + (S_out max(N . w, 0) / pi + S_map p_map(w)) cos_t / (eta2 cos_i)
        + S_area t^2 / (area cos_t)
    (cos_t clamped to 1e-12; use_map: add env_pdf (M2,); area > 0: add AREA's; 0 where
    the pdf is not positive). S (N,4) the points' shares, L (M2,3) the world's radiance
    along w, trans (M2,3) the shadow rays' transmittance."""
    for r in range(len(keep)):
        i = keep[r]
        row = idx[i]
        ci = cos_i[i]
        ct = max(cos_t[i], 1e-12)
        cri = cr[i]
        dn = w[i, 0] * ns[row, 0] + w[i, 1] * ns[row, 1] + w[i, 2] * ns[row, 2]
        p_out = S[row, _OUTSIDE] * max(dn, 0.0) / math.pi
        if use_map:
            p_out = p_out + S[row, _MAP] * env_pdf[r]
        pdf = S[row, _INSIDE] * cri / math.pi + p_out * ct / (eta2[i] * ci)
        if area > 0.0:
            tp = t_plane[i]
            pdf = pdf + S[row, _AREA] * tp * tp / (area * ct)
        g = (cri / max(pdf, 1e-300) if pdf > 0.0 else 0.0) / count
        for ch in range(3):
            Tc = _interp_T(T, side[i], ch, ci, grid)
            E[row, ch] += g * Tc * trans[r, ch] * L[r, ch]


@register_warm_up
def _warm_up():
    """Compile (or load) every kernel here on tiny inputs of a render's types."""
    n = 2
    f8 = np.zeros(n)
    v3 = np.full((n, 3), 0.5)
    i8 = np.zeros(n, np.int64)
    b1 = np.zeros(n, np.bool_)
    a3 = np.array([0.0, 0.0, 1.0])
    w = np.empty((n, 3))
    sun_directions(f8, f8, a3, a3, a3, 0.9, w)
    S = np.empty((n, 4))
    world_strategies(f8, f8, np.full(4, 0.25), True, 0.02, 0.1, v3, v3, v3[:1], v3[:1],
                     np.ones(1), v3, v3, v3, np.ones(n), i8, 0.5, S, i8.copy(), f8.copy(),
                     np.empty((n, 3)), i8.copy())
    first_rays(v3, v3, v3, f8, v3, v3, b1, i8, 0, a3, a3, 1.5, a3, a3, 1.0,
               i8.copy(), np.empty((n, 3)), f8.copy(), f8.copy(), f8.copy(), i8.copy(),
               f8.copy(), np.empty((n, 3)), np.empty((n, 3)), f8.copy(), f8.copy())
    second_rays(f8, i8 - 1, i8, 0, f8, v3, v3, i8, v3, a3, 1.0, i8.copy(),
                np.empty((n, 3), np.float32), np.empty((n, 3), np.float32),
                np.empty(n, np.float32))
    T = np.ones((2, 3, 3))
    grid = np.linspace(0.0, 1.0, 3)
    sun_accumulate(np.zeros((n, 3)), i8, i8, f8 + 0.5, f8 + 0.5, f8 + 1.0, i8, f8 + 1.0,
                   T, grid, np.ones((n, 3)), a3, 1.0)
    world_accumulate(np.zeros((n, 3)), i8, i8, v3, f8 + 0.5, f8 + 0.5, f8 + 1.0, i8,
                     f8 + 1.0, f8 + 1.0, np.full((n, 4), 0.25), v3, f8, True, 1.0, T, grid,
                     np.ones((n, 3)), np.ones((n, 3)), 1.0)
