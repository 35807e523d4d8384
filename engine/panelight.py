"""Sunlight through single-plane glass panes by next-event estimation (issue 14).

A window modelled as one plane of smooth glass bends the light for good: the room lies on
the glass side of a single interface. A sun's light is parallel, so the refracted
direction through a flat pane is unique and a shadow ray can follow it exactly: from the
shading point back along the refracted direction to the pane's plane (the first surface
it meets must be that pane), then on towards the sun (transparent shadows beyond, as for
any shadow ray). Before, that light came from the caustic photon map alone: blotchy.

Weight of one sun sample (direction w towards the sun, inside its cone) through a pane of
normal n (docs/units.md, "Refraction"; docs/design.md, Transparent shadows, panes):
a parallel beam of irradiance E_perp crossing the plane brings E_perp cos(theta_i) T per
unit area of the plane (T: the smooth interface's transmittance, shadowtransmittance.
_crossing, the photons' mean refraction weight), and leaves along the refracted direction
w_t, whose cross-section is cos(theta_t) per unit area; the convention shared with the
photons (radiance invariant, as Cycles: a refracted photon's power takes
(eta_i / eta_t)^2) multiplies it by (eta_i / eta_t)^2. A receiver with normal N gets

    E = E_sun T(cos theta_i) (eta_i / eta_t)^2 cos(theta_i) / cos(theta_t) max(N . w_t, 0).

The sun's angle: each sampled direction of its cone is refracted on its own.

Photons (photonkernels._scatter, pane_tri): a sun's photon whose first scatter is the
smooth refraction through a pane of this set keeps its path's kind (direct), as through a
flat passage; a second pane crossing, a transparent pass after it or any other scatter
makes it what it was before (caustic). So the caustic map no longer holds the light these
shadow rays carry, and the gather map gets it as direct photons (final gathering).

Only the diffuse lobe takes this light (and the irradiance of direct_irradiance without
a BSDF): a camera path's rough reflective lobes keep finding the sun through the pane by
their continuation (a delta refraction: full weight, integrator._trace_paths), as before.
"""
from __future__ import annotations

import math
import threading

import numpy as np

from . import photonkernels as pk
from .lights import packing as lpk

# Off: every pane stays caustic, as before (for A/B measurements: bench/bench_window_pane.py).
ENABLED = True
# The most pane planes that take shadow rays; the rest stay caustic (largest first).
MAX_PANES = 4
# A pane's triangles lie within this share of the scene's extent of its plane.
PLANE_TOL = 1e-5
# Transmittance table resolution over cos(theta_i) in [0, 1] (np.interp between rows).
T_ROWS = 2049

_T_GRID = np.linspace(0.0, 1.0, T_ROWS)  # the tables' cos(theta_i) rows
_lock = threading.Lock()
_NO_PANE_TRI = np.zeros(0, np.int64)


class Pane:
    """One pane plane: unit winding normal n (3,), a point c (3,) on it, its triangle rows,
    material m, IOR, object name and T[side] (2, T_ROWS, 3): the smooth interface's RGB
    transmittance from outside (side 0, arriving against n) and from inside (side 1)
    against cos(theta_i) on a uniform grid of [0, 1]; lo, hi (3,): its padded bounds (a
    shadow ray whose plane crossing lies outside cannot meet it: pane_irradiance skips
    its closest-hit query)."""

    def __init__(self, name, n, c, rows, m, ior, T, lo, hi):
        self.name, self.n, self.c, self.rows, self.m, self.ior, self.T = (
            name, n, c, rows, m, ior, T)
        self.lo, self.hi = lo, hi


def _toward_sun(light):
    """(3,) unit direction towards sun `light`'s centre (a RegionEmitter: its .light), or
    None for a light without one."""
    inner = getattr(light, "light", light)
    d = np.asarray(getattr(inner, "dir", (0.0, 0.0, 0.0)), np.float64)
    norm = float(np.linalg.norm(d))
    return -d / norm if norm > 0.0 else None


class Panes:
    """The scene's NEE panes: `panes` (list of Pane), `pane_tri` (T,) int64 the pane index
    of every triangle row (-1: none), and the suns they serve (`suns`: Light objects)."""

    def __init__(self, panes, pane_tri, suns):
        self.panes = panes
        self.pane_tri = pane_tri
        self.suns = suns

    def total_reflections(self, light) -> list:
        """[(pane name, incidence deg, critical deg, ior)] for the panes that reflect all of
        sun `light`'s central direction: it meets them from their glass side (against
        the winding normal) beyond the critical angle asin(1 / ior). A plane rotated into
        a wall with its normal into the room does that to a sun higher than the critical
        angle, in Cycles too: the room stays dark (pane31's bench)."""
        w = _toward_sun(light)
        if w is None:
            return []
        out = []
        for pane in self.panes:
            dn = float(w @ pane.n)
            if dn >= 0.0 or not pane.ior > 1.0:
                continue  # from the air side (or no denser side): refracted in
            critical = math.degrees(math.asin(1.0 / pane.ior))
            incidence = math.degrees(math.acos(min(-dn, 1.0)))
            if incidence > critical:
                out.append((pane.name, incidence, critical, pane.ior))
        return out

    def bend(self, light, pane) -> tuple | None:
        """(incidence deg, refracted deg, radiance factor) of sun `light`'s central
        direction through `pane` (off its normal), or None where it does not pass (total
        internal reflection, grazing): the radiance factor T (eta_i / eta_t)^2 of the
        photons' convention (docs/units.md "Refraction"), for the effect report."""
        w = _toward_sun(light)
        if w is None:
            return None
        _, cos_i, cos_t, eta2, side, ok = refract_sun(w[None, :], pane.n, pane.ior)
        if not ok[0]:
            return None
        T = np.interp(cos_i[0], _T_GRID, pane.T[int(side[0]), :, 1])  # green channel
        return (math.degrees(math.acos(min(cos_i[0], 1.0))),
                math.degrees(math.acos(min(cos_t[0], 1.0))), float(T * eta2[0]))

    def photon_tri(self, light) -> np.ndarray:
        """pane_tri for photons of `light` (a sun: the table; any other light: empty, its
        light through a pane stays caustic)."""
        # (visual importance wraps a light in a RegionEmitter: its .light is the sun)
        inner = getattr(light, "light", light)
        return self.pane_tri if any(inner is s for s in self.suns) else _NO_PANE_TRI


def _transmittance_table(glass, m):
    from .shadowtransmittance import _crossing
    mu = _T_GRID
    T = np.zeros((2, T_ROWS, 3))
    out = np.empty(3)
    for side in range(2):
        for i, c in enumerate(mu):
            out[:] = 1.0
            _crossing(glass, m, side, float(c), out)
            T[side, i] = out
    return T


def find_panes(geo, table, lights, settings=None):
    """Panes or None: objects wholly of smooth glass (photonkernels.flat_glass_materials,
    one material), all their triangles in one plane with one winding (single-plane glass,
    not a slab: window_triangles has those), while the scene has a sun, no shared
    instances, and no light tree (each sun is sampled on its own). At most MAX_PANES,
    largest area first. settings (RenderSettings or None): method 'local' has no
    shadow rays and no refraction, so no panes."""
    if geo.count == 0 or getattr(geo, "shared", None) is not None:
        return None
    if settings is not None and getattr(settings, "method", None) == "local":
        return None  # (its direct light is unoccluded: a pane's light would add to it)
    from .geometry import SHADOW
    from .lights.selection import SAMPLE_ALL_UP_TO
    if len(lights) > SAMPLE_ALL_UP_TO:
        return None  # the light tree picks one light per shadow ray: no sun of its own
    # Suns whose shadow rays are sampled (integrator.light_sample_list takes them).
    suns = [i for i, li in enumerate(lights) if getattr(li, "kind", None) == "SUN"
            and int(li.ray_kinds) & SHADOW and li.shadow_sampled]
    if not suns:
        return None
    if not ENABLED:
        return None
    flat = pk.flat_glass_materials(table)
    if not len(flat) or not flat[geo.material].any():
        return None
    limit = pk.flat_thickness_limits(geo)
    window = pk.window_triangles(geo, flat, limit)
    on = flat[geo.material] & ~window
    cand = []
    tol = PLANE_TOL * max(float(geo.extent), 1e-9)
    oid_all = np.asarray(geo.object_id)
    for oid in np.unique(oid_all[on]):
        tris = np.nonzero(oid_all == oid)[0]
        if not np.all(on[tris]):
            continue
        mats = np.unique(geo.material[tris])
        if len(mats) != 1:
            continue
        cross = np.cross(geo.e1[tris], geo.e2[tris])
        area = np.linalg.norm(cross, axis=1)
        big = int(np.argmax(area))
        if not area[big] > 0:
            continue
        n = cross[big] / area[big]
        ok = area > 0
        if np.any((cross[ok] @ n) < pk.FLAT_COS * area[ok]):
            continue  # not one plane, or mixed winding
        c = geo.v0[tris[big]]
        corners = np.concatenate([geo.v0[tris], geo.v0[tris] + geo.e1[tris],
                                  geo.v0[tris] + geo.e2[tris]])
        if np.max(np.abs((corners - c) @ n)) > tol:
            continue
        cand.append((0.5 * float(area.sum()), int(oid), n, c, tris, int(mats[0]),
                     corners.min(axis=0), corners.max(axis=0)))
    if not cand:
        return None
    cand.sort(key=lambda x: -x[0])
    from .shadowtransmittance import glass_crossings
    glass = glass_crossings(table.closure_params, table.base_color)
    panes = []
    pane_tri = np.full(geo.count, -1, np.int64)
    pad = 1e-4 * max(float(geo.extent), 1e-9)
    for k, (_, oid, n, c, tris, m, lo, hi) in enumerate(cand[:MAX_PANES]):
        panes.append(Pane(geo.object_names[oid], np.asarray(n, np.float64),
                          np.asarray(c, np.float64), tris, m, float(table.ior[m]),
                          _transmittance_table(glass, m), lo - pad, hi + pad))
        pane_tri[tris] = k
    return Panes(panes, np.ascontiguousarray(pane_tri), [lights[i] for i in suns])


def panes_for(ctx):
    """The context's Panes (or None), found once and kept on it."""
    got = getattr(ctx, "_panes", False)
    if got is not False:
        return got
    with _lock:
        got = getattr(ctx, "_panes", False)
        if got is False:
            got = find_panes(ctx.geo, ctx.table, ctx.lights, ctx.settings)
            ctx._panes = got
    return got


def _frame(a):
    """Two unit vectors perpendicular to unit a (3,)."""
    t = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, t)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


def refract_sun(w, n, ior):
    """Refraction of sunlight arriving from directions w (N,3) (unit, towards the sun)
    through a plane of unit winding normal n (3,) and IOR ior: (w_t (N,3) the unit
    direction towards the pane from the far side, cos_i, cos_t, eta2 = (eta_i / eta_t)^2,
    side (N,) int 0 from outside / 1 from inside, ok (N,) bool: not grazing, no total
    internal reflection)."""
    dn = w @ n
    side = np.where(dn > 0.0, 0, 1)
    eta = np.where(side == 0, 1.0 / ior, ior)  # eta_i / eta_t
    cos_i = np.abs(dn)
    s2 = eta * eta * np.maximum(1.0 - cos_i * cos_i, 0.0)
    ok = (s2 < 1.0) & (cos_i > 0.0)
    cos_t = np.sqrt(np.maximum(1.0 - s2, 0.0))
    ns = np.where(dn[:, None] > 0.0, n, -n)   # the normal on the light's side
    # travel direction -w refracted: T = eta I + (eta cos_i - cos_t) N (pbrt's Refract)
    tdir = eta[:, None] * (-w) + (eta * cos_i - cos_t)[:, None] * ns
    return -tdir, cos_i, cos_t, eta * eta, side, ok


def pane_irradiance(ctx, panes, p, ns, ng, offset, samples, counters=None):
    """(N,3) irradiance at points p (N,3) (shading normals ns, geometric normals ng on the
    lit side, origin offsets offset (N,)) from the suns' samples among `samples`
    (integrator.light_sample_list entries) through the panes. Each sample's shadow rays:
    a closest-hit query along w_t that must meet the pane at the plane's distance (it is
    the first surface), then an occlusion query from just past the plane towards the sun
    (transparent shadows: ctx.shadow). Returns (E, rays traced)."""
    from .geometry import SHADOW
    N = len(p)
    E = np.zeros((N, 3))
    if N == 0 or panes is None:
        return E, 0
    from .lights.packing import pack_lights
    codes, params, _ = ctx.packed_lights or pack_lights(ctx.lights)
    accel = ctx.accel
    shadow = getattr(ctx, "shadow", None)
    rays = 0
    tri_pane = panes.pane_tri
    scale = max(float(ctx.geo.extent), 1e-9)
    for li, traced, count, u1, u2, _sel in samples:
        if li < 0 or codes[li] != lpk.CODE_SUN:
            continue
        q = params[li]
        a = -q[lpk.DIR:lpk.DIR + 3]
        a = a / np.linalg.norm(a)
        cos_half = q[lpk.COS_HALF]
        z = 1.0 - u1 * (1.0 - cos_half)
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        phi = 2.0 * math.pi * u2
        bu, bv = _frame(a)
        w = ((r * np.cos(phi))[:, None] * bu + (r * np.sin(phi))[:, None] * bv
             + z[:, None] * a)
        rgb = q[lpk.RGB:lpk.RGB + 3]
        for k, pane in enumerate(panes.panes):
            wt, cos_i, cos_t, eta2, side, ok = refract_sun(w, pane.n, pane.ior)
            # The receiver on the far side of the plane from the sun, facing w_t.
            h = (p - pane.c) @ pane.n
            far = np.where(side == 0, h < 0.0, h > 0.0)
            cr = np.einsum("ij,ij->i", wt, ns)
            cg = np.einsum("ij,ij->i", wt, ng)
            go = ok & far & (cr > 0.0) & (cg > 0.0)
            idx = np.nonzero(go)[0]
            if not len(idx):
                continue
            o = p[idx] + offset[idx, None] * ng[idx]
            d = wt[idx]
            t_plane = ((pane.c - o) @ pane.n) / (d @ pane.n)
            good = np.isfinite(t_plane) & (t_plane > 0.0)
            y = o + np.where(good, t_plane, 0.0)[:, None] * d
            good &= np.all((y >= pane.lo) & (y <= pane.hi), axis=1)  # within its bounds
            idx, o, d, t_plane = idx[good], o[good], d[good], t_plane[good]
            if not len(idx):
                continue
            # First surface along w_t: this pane, at the plane.
            t_hit, prim, _, _ = accel.intersect(o, d, t_plane * (1.0 + 1e-3) + 1e-6 * scale,
                                                cls=SHADOW)
            rays += len(idx)
            hit = (prim >= 0) & (np.take(tri_pane, np.maximum(prim, 0)) == k)
            hit &= np.abs(t_hit - t_plane) <= 1e-3 * t_plane + 1e-5 * scale
            idx, o, d, t_plane = idx[hit], o[hit], d[hit], t_plane[hit]
            if not len(idx):
                continue
            y = o + t_plane[:, None] * d
            wk = w[idx]
            # Past the plane on the sun's side, clear of the pane.
            sn = np.where(side[idx, None] == 0, pane.n, -pane.n)
            lift = 1e-6 * scale + 4e-7 * np.max(np.abs(y), axis=1)
            y2 = y + lift[:, None] * sn
            o32 = np.ascontiguousarray(y2, np.float32)
            d32 = np.ascontiguousarray(wk, np.float32)
            t32 = np.full(len(idx), np.finfo(np.float32).max, np.float32)
            blocked = np.empty(len(idx), np.bool_)
            keep_t = t32.copy()
            accel.occluded_into(o32, d32, t32, blocked, cls=SHADOW)
            rays += len(idx)
            trans = np.ones((len(idx), 3))
            trans[blocked] = 0.0
            if shadow is not None and blocked.any():
                b = np.nonzero(blocked)[0]
                trans[b] = shadow.transmittance(o32[b], d32[b], keep_t[b], cls=SHADOW)
            ci, ct = cos_i[idx], cos_t[idx]
            sd = side[idx]
            T = np.empty((len(idx), 3))
            for s in (0, 1):
                m_ = sd == s
                if m_.any():
                    for c in range(3):
                        T[m_, c] = np.interp(ci[m_], _T_GRID, pane.T[s, :, c])
            f = eta2[idx] * ci / np.maximum(ct, 1e-12) * cr[idx] / count
            E[idx] += (f[:, None] * T * trans) * rgb[None, :]
    if counters is not None:
        counters.shadow_rays += rays
    return E, rays
