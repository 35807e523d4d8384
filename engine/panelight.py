"""Sunlight and the world's light through single-plane glass panes by next-event
estimation (issue 14: pane31 for suns, paneworld32 for the world).

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

The world (paneworld32: Background colour, Environment Texture, Sky Texture's map) is
the same with one difference: its light arrives from every direction, so each sample
picks an inside direction w_t by one of four strategies and weights it by one-sample MIS
(pane_irradiance; the shares: WORLD_SHARES, measured). The radiance along w_t is
T(theta_i) L_world(w) (w the outside direction it refracts from; the photons' convention),
and a pdf over outside directions becomes one over inside directions by the Jacobian

    d w_t / d w_i = (eta_i / eta_t)^2 cos(theta_i) / cos(theta_t)

(Snell's law sin t = eta sin i differentiated: cos t dtheta_t = eta cos i dtheta_i, the
azimuth unchanged, and dw = sin theta dtheta dphi; Veach 1997, sec. 5.2; pbrt-v4
sec. 9.5.2). Under a horizontal pane a white world gives E = pi L <T> / n^2, <T> the
cosine-weighted mean of T over the hemisphere (tests/test_pane_world.py).

Accounting (nothing counted twice, nothing lost), per path that reaches the world through
a pane as its first scatter:
  - the diffuse lobe at a camera hit, and the irradiance of the gathers' and regathers'
    direct light: these shadow rays (the ordinary world shadow rays stop at the pane);
  - the photons: a world photon refracted by a pane as its first scatter is direct-kind
    (photonkernels.F_PANE, as a sun's): the caustic map no longer holds it, the gather
    map does (the final-gather rays read it one bounce later, as any direct light);
  - final-gather rays that pass the pane and miss everything read nothing (gather_indirect
    keeps hits only), so they add no world light of their own;
  - a camera path's rough reflective lobes: their continuation through the pane (a delta
    refraction, pdf infinite) meets the world with MIS weight 1, as before; these shadow
    rays are added to the diffuse lobe only, so the two do not overlap.
Lamps (point, spot, area, mesh lights) through a pane stay caustic (their photons too).

The per-sample stages between pane_irradiance's Embree calls are kernels in
engine/panekernels.py (panespeed32); this module keeps their description.
"""
from __future__ import annotations

import math

import numpy as np

from . import panekernels as pkk
from . import photonkernels as pk
from . import raymaterials
from .parallel import once_on
from .sampling import orthonormal_basis
from .lights import packing as lpk

# Off: every pane stays caustic, as before (for A/B measurements: bench/bench_window_pane.py).
ENABLED = True
# Off: the world's light through a pane stays caustic, as before paneworld32 (the suns'
# does not), for A/B measurements.
WORLD_ENABLED = True
# A world sample through the panes picks one of four strategies (pane_irradiance;
# one-sample MIS, balance heuristic) with these probabilities: MAP the environment map's
# own distribution outside, OUTSIDE the cosine hemisphere about the shading normal
# outside, both refracted in through the pane; INSIDE the cosine hemisphere inside, AREA
# a point uniform over the panes' area (a portal), both refracted back out. A constant
# world has no map. Per point, OUTSIDE's and AREA's shares together are split by the
# panes' projected solid angle over pi (Panes.kernel_arrays, clipped to [ADAPT_MIN,
# 1 - ADAPT_MIN]): OUTSIDE's samples all pass under a skylight, AREA's under a small
# window. Measured (pixel noise of the Direct pass at 4 spp, paneworld32 in
# docs/accuracy.md): a 1.2 x 1.0 m window in a 4 x 3 m room, white world: OUTSIDE alone
# 1.85, AREA alone 0.19, half each 0.34, split by the projection 0.22; a floor 1 m under a
# 6 m skylight: OUTSIDE alone 0.036, AREA alone 1.36, half each 0.127, split 0.060. With
# a map, MAP's share trades a bright spot's noise against a flat sky's in a small
# window: MAP 0.5 / 0.6 / 0.7 / 0.8, the rest split: skylight with a bright texel
# 0.335 / 0.293 / 0.233 / 0.202, the room under a sky without a sun 0.61 / 0.82 / 0.92 /
# 1.22 (with a 17-degree bright patch 2.3-2.6 throughout: its penumbra). INSIDE wastes
# the directions beyond the critical angle (56 % of them under a horizontal pane) and
# never won as a constant share: it takes a share only on receivers tilted to a pane (INSIDE_TILT).
MAP, OUTSIDE, INSIDE, AREA = 0, 1, 2, 3
WORLD_SHARES_ENV = (0.6, 0.2, 0.0, 0.2)
WORLD_SHARES = (0.0, 0.5, 0.0, 0.5)
WORLD_ADAPT = True
ADAPT_MIN = 0.02
# Per point, this share x |sin 2 theta| (theta: the shading normal against a pane's, the
# largest over the panes) moves from OUTSIDE and AREA to INSIDE. A receiver tilted to a
# pane sees directions w_t with N . w <= 0 < N . w_t, which OUTSIDE cannot draw; only
# AREA's share (as low as ADAPT_MIN) covered them, as rare bright samples (review32: a
# point with N 45 degrees to a horizontal pane, 200k samples: std/mean a sample 5.40,
# max/mean 744; with this 1.39, 32). Floors and walls (N along or across the pane's normal,
# where OUTSIDE draws every direction) keep their shares (their 0.18 would be 0.30 with a
# constant INSIDE share of 0.1).
INSIDE_TILT = 0.1
# The most pane planes that take shadow rays; the rest stay caustic (largest first).
MAX_PANES = 4
# A pane's triangles lie within this share of the scene's extent of its plane.
PLANE_TOL = 1e-5
# Transmittance table resolution over cos(theta_i) in [0, 1] (np.interp between rows).
T_ROWS = 2049

_T_GRID = np.linspace(0.0, 1.0, T_ROWS)  # the tables' cos(theta_i) rows
ONE_BELOW = float(np.nextafter(1.0, 0.0))
_NO_PANE_TRI = np.zeros(0, np.int64)
_NO_ROWS = np.zeros(0, np.int64)
_NO_TRANS = np.zeros((0, 3))
_EMPTY = np.zeros(0)


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
        # float64 (panekernels.first_rays' types; the values as found)
        self.lo, self.hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)


def _toward_sun(light):
    """(3,) unit direction towards sun `light`'s centre (a RegionEmitter: its .light), or
    None for a light without one."""
    inner = getattr(light, "light", light)
    d = np.asarray(getattr(inner, "dir", (0.0, 0.0, 0.0)), np.float64)
    norm = float(np.linalg.norm(d))
    return -d / norm if norm > 0.0 else None


class Panes:
    """The scene's NEE panes: `panes` (list of Pane), `pane_tri` (T,) int64 the pane index
    of every triangle row (-1: none), the suns they serve (`suns`: Light objects) and the
    world light (`world`: the WorldLight, or None when it takes no shadow rays);
    `lights`: the suns and the world, the lights whose light through a pane is direct."""

    def __init__(self, panes, pane_tri, suns, world=None, geo=None):
        self.panes = panes
        self.pane_tri = pane_tri
        self.suns = suns
        self.world = world
        self.lights = list(suns) + ([world] if world is not None else [])
        # The panes' triangles for the world's AREA strategy (kernel_arrays): corners
        # v0, edges e1, e2 (M,3), pane index (M,), area CDF (M,) and total area (m^2).
        self.area = 0.0
        if geo is not None and panes:
            rows = np.concatenate([q.rows for q in panes])
            self.tri_v0 = np.asarray(geo.v0[rows], np.float64)
            self.tri_e1 = np.asarray(geo.e1[rows], np.float64)
            self.tri_e2 = np.asarray(geo.e2[rows], np.float64)
            self.tri_k = np.concatenate([np.full(len(q.rows), k, np.int64)
                                         for k, q in enumerate(panes)])
            a = 0.5 * np.linalg.norm(np.cross(self.tri_e1, self.tri_e2), axis=1)
            self.area = float(a.sum())
            mid = self.tri_v0 + (self.tri_e1 + self.tri_e2) / 3.0
            self.areas = [float(a[self.tri_k == k].sum()) for k in range(len(panes))]
            self.centres = [(mid[self.tri_k == k] * a[self.tri_k == k, None]).sum(axis=0)
                            / max(self.areas[k], 1e-300) for k in range(len(panes))]
            self.tri_cdf = np.cumsum(a) / max(self.area, 1e-300)

    def kernel_arrays(self) -> tuple:
        """The world strategies' pane arrays for panekernels.world_strategies, C-contiguous
        float64 / int64: pane normals (K,3), area-weighted centres (K,3), areas (K,) (the
        projected solid angle that splits OUTSIDE's and AREA's shares: A cos_pane cos_n /
        (pi d^2) from each pane's centre, summed; a heuristic for the shares only, never a
        weight), and the triangles v0, e1, e2 (M,3), area CDF (M,), pane (M,) (AREA's
        points, uniform over the area: the triangle by the CDF, the number rescaled within
        its bin; Shirley's square-root map, pbrt-v4 SampleUniformTriangle; density
        1 / self.area per m^2). Without area: empty ones (AREA and the split unused)."""
        got = getattr(self, "_kernel_arrays", None)
        if got is None:
            if self.area > 0.0:
                got = tuple(np.ascontiguousarray(x) for x in (
                    np.array([q.n for q in self.panes], np.float64),
                    np.array(self.centres, np.float64), np.array(self.areas, np.float64),
                    self.tri_v0, self.tri_e1, self.tri_e2, self.tri_cdf, self.tri_k))
            else:
                z3 = np.zeros((0, 3))
                got = (z3, z3, np.zeros(0), z3, z3, z3, np.zeros(0), np.zeros(0, np.int64))
            self._kernel_arrays = got
        return got

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

    def serves(self, light) -> bool:
        """Whether `light` (or the light a RegionEmitter wraps) is a sun or the world whose
        shadow rays refract through the panes."""
        # (visual importance wraps a light in a RegionEmitter: its .light is the sun)
        inner = getattr(light, "light", light)
        return any(inner is s for s in self.lights)

    def world_share(self, pane) -> float:
        """The share of a white world's light that `pane` lets through to a receiver
        facing it under it (green channel): (eta_i / eta_t)^2 times the cosine-weighted
        hemispherical mean of T from outside, 2 int_0^1 T(mu) mu dmu (E = pi L that,
        the photons' convention: docs/units.md "Refraction"). For the effect report."""
        T = pane.T[0, :, 1]
        return float(2.0 * np.trapz(T * _T_GRID, _T_GRID) / pane.ior ** 2)

    def photon_tri(self, light) -> np.ndarray:
        """pane_tri for photons of `light` (a sun or the world: the table; any other
        light, a lamp: empty, its light through a pane stays caustic)."""
        return self.pane_tri if self.serves(light) else _NO_PANE_TRI


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
    not a slab: window_triangles has those), while the scene has a sun or a world light
    whose shadow rays are sampled, no shared instances, and no light tree (each light is
    sampled on its own). At most MAX_PANES,
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
    world = next((li for li in lights if getattr(li, "kind", None) == "WORLD"
                  and int(li.ray_kinds) & SHADOW and li.shadow_sampled
                  and WORLD_ENABLED), None)
    if not suns and world is None:
        return None
    if not ENABLED:
        return None
    flat = pk.flat_glass_materials(table)
    if not len(flat) or not flat[geo.material].any():
        return None
    limit = pk.flat_thickness_limits(geo)
    window = pk.window_triangles(geo, flat, limit)
    # (a pane that shadow rays see as another material, Light Path's Is Shadow Ray, is
    # crossed by them as that material says: engine/raymaterials.py)
    on = flat[geo.material] & ~window & ~raymaterials.differs(table, SHADOW)[geo.material]
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
    return Panes(panes, np.ascontiguousarray(pane_tri), [lights[i] for i in suns], world,
                 geo)


def panes_for(ctx):
    """The context's Panes (or None), found once and kept on it."""
    return once_on(ctx, "_panes",
                   lambda: find_panes(ctx.geo, ctx.table, ctx.lights, ctx.settings))


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


class _Rays:
    """first_rays' compacted rows for N points (engine/panekernels.py): idx (row), w (the
    outside direction), cos_i, cos_t, eta2, side, cr (N . w_t), the closest-hit rays o, d,
    t_plane, tmax; reused by each pane and sample of one pane_irradiance call."""

    def __init__(self, N):
        self.idx, self.side = np.empty(N, np.int64), np.empty(N, np.int64)
        self.w, self.o, self.d = np.empty((N, 3)), np.empty((N, 3)), np.empty((N, 3))
        self.cos_i, self.cos_t, self.eta2, self.cr, self.t_plane, self.tmax = (
            np.empty(N) for _ in range(6))


def _through(ctx, panes, k, pane, p, ns, ng, offset, w0, wc, inside, on_k, shadow, scale,
             buf, used=None):
    """The rows of points p (N,3) whose light from outside direction w reaches them along
    inside direction w_t through pane k: w = w0 (N,3), w_t its refraction, or where inside
    (N,) w_t = wc (N,3), w its refraction back out; on_k (N,) the pane a row must meet
    (-1: any). The receiver on the far side of the plane from w, facing w_t; the first
    surface along w_t this pane, at the plane; the ray on from just past the plane along
    w unoccluded (transparent shadows: ctx.shadow). Fills buf (panekernels.first_rays)
    and returns (keep (M2,) int64 the lit rows of buf, trans (M2,3) the shadows'
    transmittance, rays traced)."""
    from .geometry import SHADOW
    M = pkk.first_rays(p, ns, ng, offset, w0, wc, inside, on_k, k, pane.n, pane.c,
                       float(pane.ior), pane.lo, pane.hi, scale, buf.idx, buf.w, buf.cos_i,
                       buf.cos_t, buf.eta2, buf.side, buf.cr, buf.o, buf.d, buf.t_plane,
                       buf.tmax)
    if not M:
        return _NO_ROWS, _NO_TRANS, 0
    # First surface along w_t: this pane, at the plane (past the transparent passes
    # before it: _past_passes).
    t_hit, prim, _, _ = ctx.accel.intersect(buf.o[:M], buf.d[:M], buf.tmax[:M], cls=SHADOW)
    t_hit, prim, before, n_rays = _past_passes(ctx, shadow, buf, M, t_hit, prim, scale, used)
    keep = np.empty(M, np.int64)
    o32, d32 = np.empty((M, 3), np.float32), np.empty((M, 3), np.float32)
    t32 = np.empty(M, np.float32)
    # Past the plane on the light's side, clear of the pane.
    M2 = pkk.second_rays(np.ascontiguousarray(t_hit, np.float64),
                         np.ascontiguousarray(prim, np.int64), panes.pane_tri, k,
                         buf.t_plane, buf.o, buf.d, buf.side, buf.w, pane.n, scale,
                         keep, o32, d32, t32)
    if not M2:
        return _NO_ROWS, _NO_TRANS, M + n_rays
    keep, o32, d32, t32 = keep[:M2], o32[:M2], d32[:M2], t32[:M2]
    blocked = np.empty(M2, np.bool_)
    keep_t = t32.copy()
    ctx.accel.occluded_into(o32, d32, t32, blocked, cls=SHADOW)
    trans = np.ones((M2, 3))
    trans[blocked] = 0.0
    if shadow is not None and blocked.any():
        bl = np.nonzero(blocked)[0]
        # (the ray on crosses the transparent surfaces its point's camera path left)
        trans[bl] = shadow.transmittance(
            o32[bl], d32[bl], keep_t[bl], cls=SHADOW,
            used=None if used is None else np.take(used, np.take(buf.idx, keep[bl])))
    if before is not None:
        trans *= before[keep]
    return keep, trans, M + n_rays + M2


def _past_passes(ctx, shadow, buf, M, t_hit, prim, scale, used):
    """_through's first rays (buf.o, buf.d, buf.t_plane, buf.tmax (M,)) whose closest hit
    (t_hit, prim (M,)) is a transparent pass (ShadowTransmittance.transparent_materials:
    a cut-out card, a Transparent BSDF) short of the pane's plane: their transmittance
    (ctx.shadow's walk, (1 - alpha) x tint, 0 past an opaque surface or the path's
    transparent limit; no flat passage: a slab before the pane makes its photons
    caustic) to just short of the plane, and their closest hit from there on. Light
    through a pane, then cut-outs, is the receiver's direct light as through cut-outs
    alone (docs/design.md, Transparent shadows; its photons stay direct:
    photonkernels.F_PANE_PLANE); before, a card between the pane and the floor stopped
    these rays and the light rested on the caustic map (docs/accuracy.md "passages56").
    Returns (t_hit (M,) float64, prim (M,) int64, transmittance (M,3) or None for none,
    rays traced)."""
    from .geometry import SHADOW
    t_hit = np.asarray(t_hit, np.float64)
    prim = np.asarray(prim, np.int64)
    if shadow is None:
        return t_hit, prim, None, 0
    mat_pass = once_on(ctx, "_pane_passes", lambda: np.asarray(
        shadow.transparent_materials(ctx.table), bool))
    if not mat_pass.any():
        return t_hit, prim, None, 0
    tp = buf.t_plane[:M]
    t_end = tp * (1.0 - 1e-3) - 1e-6 * scale  # (short of second_rays' band about the plane)
    hit = prim >= 0
    rows = np.flatnonzero(hit & (t_hit < t_end))
    if len(rows):
        # (the material a shadow ray meets there: Light Path's Is Shadow Ray variants,
        # shared instances' own rows, as ShadowTransmittance reads them)
        pr = prim[rows]
        if shadow.shared:
            hr, (tab,) = ctx.geo.hit_tables(pr, "material")
            mats = np.take(raymaterials.remap_rows(ctx.table, SHADOW, tab), hr)
        else:
            mats = np.take(shadow.tri_material, pr)
        rows = rows[mat_pass[mats]]
    if not len(rows):
        return t_hit, prim, None, 0
    o, d, te = buf.o[rows], buf.d[rows], t_end[rows]
    trans = shadow.transmittance(
        o.astype(np.float32), d.astype(np.float32), te.astype(np.float32), cls=SHADOW,
        passages=np.zeros(len(rows), np.int64),
        used=None if used is None else np.take(used, np.take(buf.idx, rows)))
    t_hit, prim = t_hit.copy(), prim.copy()
    prim[rows] = -1
    go = np.flatnonzero(trans.max(axis=1) > 0.0)
    n_rays = len(rows)
    if len(go):
        r = rows[go]
        t2, p2, _, _ = ctx.accel.intersect(np.ascontiguousarray(o[go] + d[go] * te[go, None]),
                                           np.ascontiguousarray(d[go]),
                                           np.ascontiguousarray(buf.tmax[r] - te[go]),
                                           cls=SHADOW)
        p2 = np.asarray(p2, np.int64)
        prim[r] = p2
        t_hit[r] = np.where(p2 >= 0, np.asarray(t2, np.float64) + te[go], np.inf)
        n_rays += len(go)
    before = np.ones((M, 3))
    before[rows] = trans
    return t_hit, prim, before, n_rays


def pane_irradiance(ctx, panes, p, ns, ng, offset, samples, counters=None, used=None):
    """(N,3) irradiance at points p (N,3) (shading normals ns, geometric normals ng on the
    lit side, origin offsets offset (N,)) from the suns' and the world's samples among
    `samples` (integrator.light_sample_list entries) through the panes. Each sample's
    shadow rays: a closest-hit query along the inside direction w_t that must meet the
    pane at the plane's distance (it is the first surface), then an occlusion query from
    just past the plane along the outside direction w (transparent shadows: ctx.shadow).

    A sun sample: w from the sun's cone, w_t its refraction; weight (module docstring)
    E_sun T (eta_i / eta_t)^2 cos_i / cos_t (N . w_t).

    A world sample: one-sample MIS (Veach 1997, sec. 9.2.4; balance heuristic) of four
    strategies over inside directions w_t, one number choosing (an environment's third
    number, else u1) with the point's shares S (WORLD_SHARES, OUTSIDE's and AREA's split
    by the panes' projected solid angle: Panes.kernel_arrays):
      MAP      w from the map's own distribution (Environment.sample, pdf p_map(w) per sr
               outside), w_t its refraction through each pane in turn
      OUTSIDE  w cosine-distributed about the shading normal (pdf max(N . w, 0) / pi),
               refracted in alike
      INSIDE   w_t cosine-distributed about the shading normal, pdf (N . w_t) / pi, w its
               refraction back out of the pane (total internal reflection: none)
      AREA     w_t towards a point uniform over the panes' area A (a portal), pdf
               t^2 / (A cos_t) per sr (t the distance to the plane, cos_t w_t's cosine to
               the pane's normal), refracted back out alike
    An outside pdf p(w) is p(w) / (d w_t / d w) per sr inside, with (Snell:
    sin t = eta sin i, so cos t dtheta_t = eta cos i dtheta_i, dphi unchanged)
        d w_t / d w = sin t dtheta_t dphi / (sin i dtheta_i dphi)
                    = (eta_i / eta_t)^2 cos_i / cos_t
    (Veach 1997, sec. 5.2, eq. 5.4; pbrt-v4 sec. 9.5.2). The radiance along w_t is
    T L_world(w) (radiance invariant across the interface, as Cycles and the photons:
    docs/units.md "Refraction"), so each pane's term is
        T(cos_i) L(w) (N . w_t) / sum_s S_s p_s(w_t)
    at a direction whose first surface is that pane. A w_t meets one pane first, so
    summing the panes' terms counts each direction once (an AREA point on another pane
    counts for that pane only).
    used: (N,) int64 the transparent bounces each point's camera path made (None: 0):
    the rays on from the panes cross Light Paths > Max Bounces > Transparent minus that
    many transparent surfaces (Cycles' continuation through the pane carries the path's
    transparent_bounce).
    Returns (E, rays traced)."""
    N = len(p)
    if used is not None:
        used = np.ascontiguousarray(used, np.int64)
    E = np.zeros((N, 3))
    if N == 0 or panes is None:
        return E, 0
    from .lights.packing import pack_lights
    codes, params, _ = ctx.packed_lights or pack_lights(ctx.lights)
    shadow = getattr(ctx, "shadow", None)
    links = getattr(ctx, "links", None)
    rays = 0
    scale = max(float(ctx.geo.extent), 1e-9)
    p, ns, ng, offset = (np.ascontiguousarray(a, np.float64) for a in (p, ns, ng, offset))
    # The stages between Embree's calls are kernels (engine/panekernels.py): one pass each,
    # into these buffers (first_rays' compacted rows, at most N).
    buf = _Rays(N)
    no_k = np.full(N, -1, np.int64)
    not_inside = np.zeros(N, np.bool_)
    for li, traced, count, u1, u2, sel in samples:
        if li < 0:
            continue
        if codes[li] == lpk.CODE_SUN:
            q = params[li]
            a = -q[lpk.DIR:lpk.DIR + 3]
            a = a / np.linalg.norm(a)
            bu, bv = orthonormal_basis(a)
            w = np.empty((N, 3))
            pkk.sun_directions(np.ascontiguousarray(u1, np.float64),
                               np.ascontiguousarray(u2, np.float64), a, bu, bv,
                               float(q[lpk.COS_HALF]), w)
            rgb = np.ascontiguousarray(q[lpk.RGB:lpk.RGB + 3], np.float64)
            for k, pane in enumerate(panes.panes):
                if links is not None and not links.lights_hit(li, ctx.geo, pane.rows[:1])[0]:
                    # Light Linking: the sun's light through a pane is the pane's (Cycles
                    # counts a sun met through the glass only if it lights the object the
                    # path last bounced from, the pane: light_link_receiver_forward), so
                    # a sun that does not light the pane gives nothing through it, and one
                    # that does lights every receiver behind it.
                    continue
                keep, trans, n_rays = _through(ctx, panes, k, pane, p, ns, ng, offset, w, w,
                                               not_inside, no_k, shadow, scale, buf, used)
                rays += n_rays
                if len(keep):
                    pkk.sun_accumulate(E, buf.idx, keep, buf.cos_i, buf.cos_t, buf.eta2,
                                       buf.side, buf.cr, pane.T, _T_GRID, trans, rgb,
                                       float(count))
        elif codes[li] == lpk.CODE_WORLD and panes.world is not None:
            world = panes.world
            env = world.environment
            shares = np.asarray(WORLD_SHARES_ENV if env is not None else WORLD_SHARES,
                                np.float64)
            # The strategy by one number, which then gives the first coordinate rescaled
            # within its share: an environment's third number (stratified with u1, not
            # independent of it: integrator.mesh_light_numbers; directlight.sample_lights
            # does the same), else u1 itself.
            x = np.ascontiguousarray(sel if env is not None and sel is not None else u1,
                                     np.float64)
            if not panes.area > 0.0:
                shares = np.where(np.arange(4) == AREA, 0.0, shares)
            shares = shares / shares.sum()
            b = np.ascontiguousarray(u2, np.float64)
            # Each point's shares S (N,4) (WORLD_ADAPT: OUTSIDE and AREA split by the
            # panes' projected solid angle at the point, Panes.kernel_arrays: a skylight over
            # the point, OUTSIDE; a window across the room, AREA, a portal), its strategy,
            # the first coordinate within its share, wc: OUTSIDE's w, INSIDE's and AREA's
            # w_t (AREA: towards a point uniform over the panes' area, on pane on_k).
            S, strat, a = np.empty((N, 4)), np.empty(N, np.int64), np.empty(N)
            wc, on_k = np.empty((N, 3)), np.empty(N, np.int64)
            pkk.world_strategies(x, b, shares, bool(WORLD_ADAPT and panes.area > 0.0),
                                 ADAPT_MIN, INSIDE_TILT, p, ns, *panes.kernel_arrays(),
                                 ONE_BELOW,
                                 S, strat, a, wc, on_k)
            # w0: MAP's and OUTSIDE's w (the map's sample: the environment's own code)
            by_map = np.nonzero(strat == MAP)[0]
            w0 = wc
            if len(by_map):
                w0 = wc.copy()
                w0[by_map] = env.sample(a[by_map], b[by_map])[0]
            inside = (strat == INSIDE) | (strat == AREA)  # samples of w_t: refracted out
            use_map = bool(shares[MAP] > 0.0)
            for k, pane in enumerate(panes.panes):
                # The outside direction: the map's or the outside cosine sample, or the
                # inside sample (cosine, or towards a point on a pane) refracted back out.
                keep, trans, n_rays = _through(ctx, panes, k, pane, p, ns, ng, offset, w0,
                                               wc, inside, on_k, shadow, scale, buf, used)
                rays += n_rays
                if not len(keep):
                    continue
                wk = buf.w[keep]
                # The mixture's pdf per sr of inside directions (outside pdfs through the
                # Jacobian cos_t / (eta2 cos_i); AREA's t^2 / (A cos_t), cos_t the inside
                # direction's cosine to the pane, A all the panes' area): world_accumulate.
                env_pdf = (np.ascontiguousarray(env.pdf(wk), np.float64) if use_map
                           else _EMPTY)
                L = (env.radiance(wk) if env is not None else
                     np.broadcast_to(np.asarray(world.radiance, np.float64), (len(keep), 3)))
                pkk.world_accumulate(E, buf.idx, keep, buf.w, buf.cos_i, buf.cos_t,
                                     buf.eta2, buf.side, buf.cr, buf.t_plane, S, ns, env_pdf,
                                     use_map, float(panes.area), pane.T, _T_GRID, trans,
                                     np.ascontiguousarray(L, np.float64), float(count))
    if counters is not None:
        counters.shadow_rays += rays
    return E, rays
