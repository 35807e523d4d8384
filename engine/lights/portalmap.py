"""Light portals sampled by the environment map seen through them (portalenv35, issue 14).

pbrt-v4's PortalImageInfiniteLight (src/pbrt/lights.h ImageFromRender / RenderFromImage /
ImageBounds, lights.cpp; its WindowedPiecewiseConstant2D in util/sampling.h), used here as
one strategy of the world light's shadow rays (engine/lights/world.py), not as a light of
its own: the world keeps its light from every direction and the portal only says where
to look for it.

Parameterization. A portal is a rectangle s + a ex + b ey, a, b in [0, 1], ex orthogonal
to ey; its frame x = ex / |ex|, y = ey / |ey|, z = +-(x cross y), turned out of the room
(against the portal's normal, which points in). A direction w with w.z > 0 has image
coordinates

    u = 1/2 + atan2(w.x, w.z) / pi,    v = 1/2 + atan2(w.y, w.z) / pi      (u, v in (0, 1))

From a point p on the room side (d = s - p, d.z > 0) the directions through the
rectangle are exactly the axis-aligned window

    u in [1/2 + atan(d.x / d.z) / pi, 1/2 + atan((d.x + |ex|) / d.z) / pi], v alike

(the tangent of each angle is linear along the rectangle), so one table over (u, v),
shared by every point, restricted to each point's window, is a distribution over the
portal as that point sees it. Jacobian (pbrt-v4's duv_dw, the solid angle per unit
(u, v) area):

    J(w) = d omega / du dv = pi^2 (1 - w.x^2)(1 - w.y^2) / w.z
         = pi^2 (1 + tan^2 alpha)(1 + tan^2 beta) / (1 + tan^2 alpha + tan^2 beta)^(3/2)

Table. N x N cells over the unit square, f = the mean over S x S points of a cell of
luminance(L(w)) x J(w) (pbrt-v4's Image::GetSamplingDistribution(duv_dw)), L the world's
radiance as the lookups read it (environment.env_radiance), so the integral of f over a
point's window is the luminance of the radiance integrated over the portal's solid angle
there (the portal's share of the map, in sr x radiance). A summed-area table of f / N^2
(SAT[i, j] = the integral over rows < i, columns < j; bilinear between its entries: the
exact integral of the piecewise-constant f, pbrt-v4's SummedAreaTable::Integral) gives
any window's integral I(p) in four lookups.

Sampling at p (pbrt-v4's WindowedPiecewiseConstant2D::Sample): a portal k with
probability I_k / sum I over the portals seen; in its window a column by the window's
marginal (binary search over the columns, linear within one: the marginal is constant
across a column), then a row by that column's conditional over the window's rows, linear
within the cell. pdf in (u, v) f_k(cell) / I_k; per steradian, summed over the seen
portals the direction crosses (their windows overlap when portals overlap as seen from p):

    pdf(w) = sum_k [w in window_k(p)] f_k(u_k(w), v_k(w)) / (sum_j I_j x J_k(w))

exact for every point (the table is the same for all; only the window changes), so the
one-sample MIS of world.py and WorldLight.pdf(wi, ns, p) (the continuation's MIS weight)
use it as they used the uniform solid angle's n(w) / Omega.

Why pbrt-v4's and not Cycles' (kernel/light/background.h background_portal_sample): Cycles
picks a seen portal uniformly and a direction uniform in its solid angle (the spherical
rectangle, as lightportal34 does), ignoring the map; its map strategy (mixed in by
portal_sampling_pdf) then finds a sun seen through the window only as often as the map's
own share and the portal finds it by chance: the sun through a window was ~20 % noisier per
sample with a map than with a uniform sky (docs/accuracy.md, "lightportal34"). Sampling
in proportion to the map within the window finds it with the portal's share.

The table's resolution (table_size): N = 4 x the map's rows (a cell at the portal's
centre a quarter of a texel wide: a sun's edge crosses few of the cells it covers), a
power of two in PORTAL_TABLE_MIN..PORTAL_TABLE_MAX, S x S = 2 x 2 points a cell. What the
table misses (a sun smaller than its points' spacing) only costs noise: the cosine and
map x cosine strategies keep a share everywhere, so every direction with light keeps a
non-zero pdf.
"""
from __future__ import annotations

import hashlib
import math
import weakref
from collections import OrderedDict

import numpy as np

from ..jit import kernel
from . import packing as pk
from .environment import env_radiance

PI = math.pi
# The table's cells per side: PORTAL_TABLE_PER_ROW x the map's rows, a power of two in
# PORTAL_TABLE_MIN..PORTAL_TABLE_MAX; PORTAL_TABLE_SUB x PORTAL_TABLE_SUB points a cell.
# Measured (tests/test_light_portal_shadows.py's room, a 128 x 256 map with a sun of
# radius 1.5 degrees 8 degrees from the zenith seen through the opening; per-sample
# std/mean of the floor's irradiance under it, shares 0.1-0.95; the map's own strategies
# alone 0.561): N = 128 0.971, 256 0.519, 512 0.315 (S = 4: 0.310), 1024 0.217; the
# cells a sun's edge crosses are what is left. Cost: 16 (2 N + 1)^2 bytes a portal, built
# at ~85 ns a point (N = 1024, S = 2: 1.4 s).
PORTAL_TABLE_MIN = 64
PORTAL_TABLE_MAX = 1024
PORTAL_TABLE_PER_ROW = 4
PORTAL_TABLE_SUB = 2


def table_size(map_height: int) -> tuple[int, int]:
    """(N, S): the portal table's cells per side and points per cell side for an
    equirectangular map of map_height rows (module docstring)."""
    n = PORTAL_TABLE_MIN
    while n < PORTAL_TABLE_PER_ROW * map_height and n < PORTAL_TABLE_MAX:
        n *= 2
    return n, PORTAL_TABLE_SUB


# Tables kept between prepares (portals36): a re-render, a progressive pass or a second
# prepare of the same portals under the same map reuses them (0.2-1.4 s a portal to
# build); at most PORTAL_TABLE_KEPT sets (16 (2 N + 1)^2 bytes a portal, 67 MB at N 1024).
# One: the set a render uses stays for the next render (in Blender's process too), and
# no second set doubles that (up to ~270 MB with four portals at N 1024).
PORTAL_TABLE_KEPT = 1
_kept: OrderedDict = OrderedDict()
_map_keys: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
# Portal tables built (one a portal) since the process started: tests read it.
tables_built = 0


def map_key(environment) -> bytes:
    """A digest of what an environment's tables read (its stored texels, their scale,
    rotation and lookup code), once per Environment object."""
    key = _map_keys.get(environment)
    if key is None:
        h = hashlib.blake2b(digest_size=16)
        h.update(np.ascontiguousarray(environment.stored).view(np.uint8).ravel())
        for a in (environment.scale, environment.rotation):
            h.update(np.ascontiguousarray(a, np.float64).tobytes())
        h.update(repr((int(environment.interp_code), environment.stored.shape,
                       str(environment.stored.dtype))).encode())
        key = h.digest()
        _map_keys[environment] = key
    return key


def portal_tables(environment, rects: np.ndarray):
    """build_portal_tables' (f, sat), kept: the same portal rectangles (the same bytes)
    under a map of the same content at the same table size are not built again."""
    rects = np.ascontiguousarray(rects, np.float64).reshape(-1, 4, 3)
    key = (rects.tobytes(), map_key(environment), table_size(environment.height))
    hit = _kept.get(key)
    if hit is not None:
        _kept.move_to_end(key)
        return hit
    tables = build_portal_tables(environment, rects)
    _kept[key] = tables
    while len(_kept) > PORTAL_TABLE_KEPT:
        _kept.popitem(last=False)
    return tables


def build_portal_tables(environment, rects: np.ndarray):
    """The tables of portals rects (K,4,3) (corner s, edges ex, ey, unit normal into the
    room; WorldLight.portal_rects) under `environment` (an engine Environment):
    (f (K,N,N) float64 the function per cell (luminance x sr per unit (u, v) area; row
    index v, column index u), sat (K,N+1,N+1) float64 its summed-area table of f / N^2)."""
    rects = np.ascontiguousarray(rects, np.float64).reshape(-1, 4, 3)
    K = len(rects)
    n, sub = table_size(environment.height)
    f = np.zeros((K, n, n))
    global tables_built
    tables_built += K
    for k in range(K):
        fill_table(environment.rotation, environment.stored, int(environment.interp_code),
                   np.ascontiguousarray(environment.scale, np.float64), rects[k], sub, f[k])
    sat = np.zeros((K, n + 1, n + 1))
    sat[:, 1:, 1:] = np.cumsum(np.cumsum(f / (n * n), axis=1), axis=2)
    return f, sat


@kernel
def rect_frame(s, ex, ey, nrm):
    """The portal's frame (module docstring): (x0, x1, x2, y0, y1, y2, z0, z1, z2, |ex|,
    |ey|), z out of the room (against nrm)."""
    exl = math.sqrt(ex[0] * ex[0] + ex[1] * ex[1] + ex[2] * ex[2])
    eyl = math.sqrt(ey[0] * ey[0] + ey[1] * ey[1] + ey[2] * ey[2])
    exs = max(exl, 1e-300)
    eys = max(eyl, 1e-300)
    x0, x1, x2 = ex[0] / exs, ex[1] / exs, ex[2] / exs
    y0, y1, y2 = ey[0] / eys, ey[1] / eys, ey[2] / eys
    z0, z1, z2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
    if z0 * nrm[0] + z1 * nrm[1] + z2 * nrm[2] > 0.0:
        z0, z1, z2 = -z0, -z1, -z2
    return x0, x1, x2, y0, y1, y2, z0, z1, z2, exl, eyl


@kernel
def fill_table(R, stored, interp, scale, rect, sub, f):
    """f (N,N): the table of one portal rect (4,3) (module docstring), S = sub."""
    n = f.shape[0]
    x0, x1, x2, y0, y1, y2, z0, z1, z2, _, _ = rect_frame(rect[0], rect[1], rect[2], rect[3])
    inv = 1.0 / (sub * sub)
    for r in range(n):
        for c in range(n):
            acc = 0.0
            for i in range(sub):
                tb = math.tan(PI * ((r + (i + 0.5) / sub) / n - 0.5))
                for j in range(sub):
                    ta = math.tan(PI * ((c + (j + 0.5) / sub) / n - 0.5))
                    q = 1.0 + ta * ta + tb * tb
                    ln = math.sqrt(q)
                    w0 = (ta * x0 + tb * y0 + z0) / ln
                    w1 = (ta * x1 + tb * y1 + z1) / ln
                    w2 = (ta * x2 + tb * y2 + z2) / ln
                    L0, L1, L2 = env_radiance(R, stored, interp, scale, w0, w1, w2)
                    lum = max(L0 * 0.2126 + L1 * 0.7152 + L2 * 0.0722, 0.0)
                    acc += lum * (PI * PI * (1.0 + ta * ta) * (1.0 + tb * tb) / (q * ln))
            f[r, c] = acc * inv


@kernel
def _sat_at(sat, k, x, y):
    """The integral of portal k's f over [0, x] x [0, y] (x, y in [0, 1]): the summed-area
    table interpolated bilinearly (exact for the piecewise-constant f)."""
    n = sat.shape[1] - 1
    X = min(max(x, 0.0), 1.0) * n
    Y = min(max(y, 0.0), 1.0) * n
    c = min(int(X), n - 1)
    r = min(int(Y), n - 1)
    fx = X - c
    fy = Y - r
    return ((1.0 - fy) * ((1.0 - fx) * sat[k, r, c] + fx * sat[k, r, c + 1])
            + fy * ((1.0 - fx) * sat[k, r + 1, c] + fx * sat[k, r + 1, c + 1]))


@kernel
def window_integral(sat, k, u0, u1, v0, v1):
    """The integral of portal k's f over [u0, u1] x [v0, v1]."""
    return (_sat_at(sat, k, u1, v1) - _sat_at(sat, k, u0, v1) - _sat_at(sat, k, u1, v0)
            + _sat_at(sat, k, u0, v0))


@kernel
def _sat_edge(sat, k, c, y):
    """The integral of portal k's f over [0, c/N] x [0, y] (c an integer column edge)."""
    n = sat.shape[1] - 1
    Y = min(max(y, 0.0), 1.0) * n
    r = min(int(Y), n - 1)
    fy = Y - r
    return (1.0 - fy) * sat[k, r, c] + fy * sat[k, r + 1, c]


@kernel
def _column_at(sat, k, c, y):
    """The integral of portal k's f over column c ([c/N, (c+1)/N]) x [0, y]."""
    return _sat_edge(sat, k, c + 1, y) - _sat_edge(sat, k, c, y)


@kernel
def portal_window(q, b, p0, p1, p2):
    """The window (u0, u1, v0, v1) of the portal at row slot b (packing.PORTAL0 + k
    PORTAL_STRIDE) seen from p; u0 = u1 = 0 where p is not on its room side."""
    x0, x1, x2, y0, y1, y2, z0, z1, z2, exl, eyl = rect_frame(
        q[b:b + 3], q[b + 3:b + 6], q[b + 6:b + 9], q[b + 9:b + 12])
    d0, d1, d2 = q[b] - p0, q[b + 1] - p1, q[b + 2] - p2
    dz = d0 * z0 + d1 * z1 + d2 * z2
    if not dz > 0.0:
        return 0.0, 0.0, 0.0, 0.0
    a = (d0 * x0 + d1 * x1 + d2 * x2) / dz
    c = (d0 * y0 + d1 * y1 + d2 * y2) / dz
    return (0.5 + math.atan(a) / PI, 0.5 + math.atan(a + exl / dz) / PI,
            0.5 + math.atan(c) / PI, 0.5 + math.atan(c + eyl / dz) / PI)


@kernel
def portal_masses(q, sat, p0, p1, p2, om, mass):
    """mass (MAX_PORTALS,): each seen portal's (om[k] > 0: world.portal_shares) window
    integral I_k at p (0 for the others); returns their sum."""
    tot = 0.0
    for k in range(int(q[pk.PORTAL_N])):
        mass[k] = 0.0
        if not om[k] > 0.0:
            continue
        u0, u1, v0, v1 = portal_window(q, pk.PORTAL0 + pk.PORTAL_STRIDE * k, p0, p1, p2)
        if u1 > u0 and v1 > v0:
            m = window_integral(sat, k, u0, u1, v0, v1)
            if m > 0.0:
                mass[k] = m
                tot += m
    return tot


@kernel
def portal_map_pdf(q, pf, p0, p1, p2, w0, w1, w2, mass, tot, pick, pr, pc):
    """Solid-angle pdf (1/sr) of direction w from p under the map-weighted portal
    sampling (module docstring; mass, tot: portal_masses at p): the sum over the portals
    with mass whose window holds w. pick >= 0: w was drawn in portal pick's cell (pr, pc),
    counted there without the window test (rounding at the window's edge)."""
    if not tot > 0.0:
        return 0.0
    n = pf.shape[1]
    out = 0.0
    for k in range(int(q[pk.PORTAL_N])):
        if not mass[k] > 0.0:
            continue
        b = pk.PORTAL0 + pk.PORTAL_STRIDE * k
        x0, x1, x2, y0, y1, y2, z0, z1, z2, _, _ = rect_frame(
            q[b:b + 3], q[b + 3:b + 6], q[b + 6:b + 9], q[b + 9:b + 12])
        wz = w0 * z0 + w1 * z1 + w2 * z2
        if not wz > 0.0:
            continue
        wx = w0 * x0 + w1 * x1 + w2 * x2
        wy = w0 * y0 + w1 * y1 + w2 * y2
        if k == pick:
            r, c = pr, pc
        else:
            u = 0.5 + math.atan2(wx, wz) / PI
            v = 0.5 + math.atan2(wy, wz) / PI
            u0, u1, v0, v1 = portal_window(q, b, p0, p1, p2)
            if not (u0 <= u <= u1 and v0 <= v <= v1):
                continue
            r = min(int(v * n), n - 1)
            c = min(int(u * n), n - 1)
        jac = PI * PI * (1.0 - wx * wx) * (1.0 - wy * wy) / wz
        if jac > 0.0:
            out += pf[k, r, c] / (tot * jac)
    return out


@kernel
def portal_map_sample(q, pf, sat, p0, p1, p2, x, u2, mass, tot):
    """A direction from p by the map-weighted portal sampling (module docstring): the
    portal by x in [0, 1) over mass (portal_masses at p), x rescaled within it the
    window's column and u2 the row. Returns (w0, w1, w2, pdf per sr: portal_map_pdf);
    pdf 0 where nothing could be drawn (a window of no mass)."""
    acc = 0.0
    pick = -1
    xt = x * tot
    for k in range(int(q[pk.PORTAL_N])):
        if not mass[k] > 0.0:
            continue
        pick = k
        if xt < acc + mass[k]:
            break
        acc += mass[k]
    if pick < 0:
        return 0.0, 0.0, 1.0, 0.0
    k = pick
    n = pf.shape[1]
    b = pk.PORTAL0 + pk.PORTAL_STRIDE * k
    u0, u1, v0, v1 = portal_window(q, b, p0, p1, p2)
    I = mass[k]
    t = min(max(xt - acc, 0.0), I)
    # Column: the largest c whose left edge's cumulative (within the window) is <= t;
    # at a column's edge the summed-area table is interpolated in v alone.
    left = _sat_at(sat, k, u0, v1) - _sat_at(sat, k, u0, v0)
    lo = min(int(u0 * n), n - 1)
    hi = min(int(u1 * n), n - 1)
    while lo < hi:
        mid = (lo + hi + 1) >> 1
        if _sat_edge(sat, k, mid, v1) - _sat_edge(sat, k, mid, v0) - left <= t:
            lo = mid
        else:
            hi = mid - 1
    c = lo
    xa = max(c / n, u0)
    xb = min((c + 1) / n, u1)
    Aa = window_integral(sat, k, u0, xa, v0, v1)
    Ab = window_integral(sat, k, u0, xb, v0, v1)
    if not Ab > Aa:
        return 0.0, 0.0, 1.0, 0.0
    u = min(max(xa + (t - Aa) / (Ab - Aa) * (xb - xa), xa), xb)
    # Row: that column's conditional over the window's rows.
    base = _column_at(sat, k, c, v0)
    t2 = u2 * (_column_at(sat, k, c, v1) - base)
    lo = min(int(v0 * n), n - 1)
    hi = min(int(v1 * n), n - 1)
    while lo < hi:
        mid = (lo + hi + 1) >> 1
        if _column_at(sat, k, c, mid / n) - base <= t2:
            lo = mid
        else:
            hi = mid - 1
    r = lo
    ya = max(r / n, v0)
    yb = min((r + 1) / n, v1)
    Ba = _column_at(sat, k, c, ya) - base
    Bb = _column_at(sat, k, c, yb) - base
    if not Bb > Ba:
        return 0.0, 0.0, 1.0, 0.0
    v = min(max(ya + (t2 - Ba) / (Bb - Ba) * (yb - ya), ya), yb)
    x0, x1, x2, y0, y1, y2, z0, z1, z2, _, _ = rect_frame(
        q[b:b + 3], q[b + 3:b + 6], q[b + 6:b + 9], q[b + 9:b + 12])
    ta = math.tan(PI * (u - 0.5))
    tb = math.tan(PI * (v - 0.5))
    ln = math.sqrt(1.0 + ta * ta + tb * tb)
    w0 = (ta * x0 + tb * y0 + z0) / ln
    w1 = (ta * x1 + tb * y1 + z1) / ln
    w2 = (ta * x2 + tb * y2 + z2) / ln
    return w0, w1, w2, portal_map_pdf(q, pf, p0, p1, p2, w0, w1, w2, mass, tot, k, r, c)
