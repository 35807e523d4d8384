"""Window panes and light portals as portals for the photons of the world and suns
(issues 13/14, portal34).

A room lit by the sky through its windows: the world's and suns' photons leave a disk
beyond the scene's bounding sphere (lights/world.py, lights/sun.py), aimed by visual
importance at spheres round the camera's lookups (visualimportance.py); those whose line
meets the room's walls from outside light nothing the camera reads. Here a share of such
a light's photons start on a portal instead (Bitterli et al. 2015, "Portal-Masked
Environment Map Sampling"; pbrt-v4's PortalImageInfiniteLight): a window pane
(panelight's single-plane glass) or a Cycles light portal over an opening
(engine.scene.LightPortal: an Area light with Portal on); a point x uniform over the
portals' area, a direction w towards the sky on the portal's outer side
(the world: the environment map's cosine-weighted distribution about the pane's outward
normal, mixed with the cosine (lights/world.ENV_MAP_FRACTION), a constant world the cosine
alone; a sun: its own cone), and the photon starts on the natural disk's plane upstream
of x, so whatever lies outside the window (an overhang) still shades it.

Measure and weight. A ray from infinity is a direction and a point of the disk's plane.
Natural emission has density p_nat(w) / (pi R^2) there; the portal's, for a ray whose
line crosses the panes k into the room,

    p_portal(w, y) = sum_k P_k p_k(w) / (A_k cos_k),

P_k the pane's probability, p_k the direction pdf it uses, A_k its area and cos_k the
cosine of the travel direction to its inward normal (a point uniform over the pane
projects to 1 / (A_k cos_k) per m^2 of the disk's plane). The photon's power is the
natural power x natural density / portal density:

    world:  L(w) / (count p_portal)       (one pane: L A cos / (count p(w)): a uniform sky
                                           L through an opening of area A facing up
                                           carries pi L A)
    sun:    E / (count sum_k P_k / (A_k cos_k))   (one pane: E A cos / count)

The portal part and the natural part split the rays between them (RegionEmitter's
scheme): the natural photons whose line crosses a pane into the room with p_portal > 0
are dropped, so the expected power anywhere is the light's own, and the light reaching
the room by other routes (an open side, a second window the panes do not cover, the
ground outside) keeps its natural photons. A share PORTAL_SHARE_MAX at most starts on
the panes, chosen per scene by what the camera's lookups see of the sky (portal_plan).

Pure numpy (no kernel: the light kernels recompile everything on an edit); the random
numbers are the photon slots' own (lights.emission.emission_uniforms), so the same seed
gives the same photons for any worker count.
"""
from __future__ import annotations

import math

import numpy as np

from .lights.base import InfiniteLight
from .lights.emission import emission_uniforms
from .sampling import cosine_hemisphere, luminance, to_world, uniform_cone

# Off: the world's and suns' photons are emitted as before portal34 (A/B benches).
ENABLED = True
# At most this share of a light's global photons starts on the portals; the rest are
# natural (minus those crossing a portal into the room): light by other routes.
PORTAL_SHARE_MAX = 0.9
# Portals are used when at least this share of the sky the camera's lookups see is seen
# through them (the rest directly: an open scene, an outdoor one).
PORTAL_MIN_SKY = 0.5
PORTAL_STREAM = 98  # the lookups' sky rays' seed stream
# A light portal crossed by at least this many of the lookups' sky rays, all of them
# along its normal (out of the room), is said to face out (facing_out_warning).
FACING_OUT_MIN_RAYS = 3
# A round light portal's photons start on the ROUND_SIDES-gon inscribed in its ellipse
# (99.4 % of its area; a triangle each, Portals.hits tests them one by one).
ROUND_SIDES = 32
# Emission numbers of a portal photon: 0 the triangle, 1, 2 the point, 3, 4 the
# direction, 5 the world's strategy (map x cosine or cosine).
DIMS = 6


class Portals:
    """The portals: window panes (panelight's) and Cycles light portals (openings,
    engine.scene.LightPortal), K of them: `names` (K,), inward unit normals n_in (K,3)
    (towards the room: a pane's side holding most of the camera's lookups, a light
    portal's own normal), areas (K,) m^2, their triangles v0, e1, e2 (M,3) (re-centred
    world space) with portal index tri_k (M,) and the area CDF over all of them tri_cdf
    (M,), the total area (m^2); `panes` how many of the K are panes (the first); `sky`
    the share of the lookups' sky seen through them."""

    def __init__(self, names, v0, e1, e2, tri_k, n_in, panes=0, sky=1.0):
        self.names = list(names)
        self.v0, self.e1, self.e2 = (np.ascontiguousarray(x, np.float64) for x in (v0, e1, e2))
        self.tri_k = np.asarray(tri_k, np.int64)
        self.n_in = np.asarray(n_in, np.float64).reshape(-1, 3)
        a = 0.5 * np.linalg.norm(np.cross(self.e1, self.e2), axis=1)
        self.areas = np.bincount(self.tri_k, weights=a, minlength=len(self.n_in))
        self.area = float(a.sum())
        self.tri_cdf = np.cumsum(a) / max(self.area, 1e-300)
        self.panes = int(panes)
        self.sky = float(sky)
        self.facing_out = []  # light portals seen only from their back: sky_through_portals

    def hits(self, o, d) -> np.ndarray:
        """(N,K) d . n_in_k where the line o + t d (t > 0) meets portal k, else 0
        (Moller-Trumbore per triangle; a line meets a plane once, so at most one of a
        portal's triangles counts but on a shared edge, a set of measure 0)."""
        N, K = len(o), len(self.areas)
        out = np.zeros((N, K))
        for m in range(len(self.v0)):
            e1, e2 = self.e1[m], self.e2[m]
            p = np.cross(d, e2)
            det = p @ e1
            ok = np.abs(det) > 1e-300
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
            s = o - self.v0[m]
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            v = np.einsum("ij,ij->i", q, d) * inv
            t = (q @ e2) * inv
            k = int(self.tri_k[m])
            c = d @ self.n_in[k]
            hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (c != 0)
            out[:, k] = np.where(hit, c, out[:, k])
        return out

    def crossings(self, o, d) -> np.ndarray:
        """(N,K) cos_k = d . n_in_k where the line o + t d (t > 0) crosses portal k into
        the room, else 0."""
        return np.maximum(self.hits(o, d), 0.0)


def portals_from(geo, panes, n_in_panes, light_portals) -> Portals | None:
    """Portals of the panes (panelight.Panes or None; their inward normals n_in_panes
    (K,3)) and the scene's light portals (engine.scene.LightPortal list: each rectangle
    two triangles, a round one the fan of its ROUND_SIDES-gon; re-centred by geo.offset), or None without any."""
    names, v0, e1, e2, k, n_in = [], [], [], [], [], []
    K = 0
    if panes is not None and panes.area > 0.0:
        names += [p.name for p in panes.panes]
        v0.append(panes.tri_v0)
        e1.append(panes.tri_e1)
        e2.append(panes.tri_e2)
        k.append(panes.tri_k)
        n_in += list(np.asarray(n_in_panes, np.float64).reshape(-1, 3))
        K = len(panes.panes)
    n_panes = K
    off = np.asarray(getattr(geo, "offset", np.zeros(3)), np.float64)
    for lp in light_portals or ():
        c = lp.corners - off
        if getattr(lp, "round", False):
            # A round portal (Disk / Ellipse): the fan of the ROUND_SIDES-gon inscribed
            # in its ellipse. The split stays exact: the natural photons crossing the
            # slivers between the polygon and the ellipse are kept (not on a portal).
            a = 2.0 * math.pi * np.arange(ROUND_SIDES + 1) / ROUND_SIDES
            rim = (c[0] + np.outer(0.5 + 0.5 * np.cos(a), c[1] - c[0])
                   + np.outer(0.5 + 0.5 * np.sin(a), c[3] - c[0]))
            centre = 0.5 * (c[0] + c[2])
            v0.append(np.repeat(centre[None], ROUND_SIDES, axis=0))
            e1.append(rim[:-1] - centre)
            e2.append(rim[1:] - centre)
            k.append(np.full(ROUND_SIDES, K))
        else:
            v0.append(np.array([c[0], c[0]]))
            e1.append(np.array([c[1] - c[0], c[2] - c[0]]))
            e2.append(np.array([c[2] - c[0], c[3] - c[0]]))
            k.append(np.array([K, K]))
        names.append(lp.name)
        n_in.append(lp.normal)
        K += 1
    if K == 0:
        return None
    return Portals(names, np.concatenate(v0), np.concatenate(e1), np.concatenate(e2),
                   np.concatenate(k), np.array(n_in), panes=n_panes)


def _disk_plane_origin(x, d, center, R):
    """The point upstream of x along -d on the natural disk's plane (emission.disk_origin:
    2 R before the scene's centre across d)."""
    t = np.einsum("ij,ij->i", x - center, d) + 2.0 * R
    return x - t[:, None] * d


class PortalEmitter:
    """A light at infinity (the world or a sun) that emits `share` of its photons from the
    portals (module docstring) and the rest naturally, minus the natural photons whose line
    crosses a portal into the room where the portal density is positive. Each chunk of n of
    the light's `count` photons carries n / count of its flux (RegionEmitter's contract)."""

    def __init__(self, light, portals: Portals, share: float):
        self.light = light
        self.portals = portals
        self.share = float(share)
        self.name = light.name
        self.ray_kinds = light.ray_kinds
        self.source = light.source
        self.photon_flux = light.photon_flux
        self.infinite = True
        self.is_sun = getattr(light, "kind", None) == "SUN"
        if self.is_sun:
            # Panes by their projected area across the sun's central direction (each > 0
            # only where that direction enters the room through it).
            c = self.portals.n_in @ np.asarray(light.dir, np.float64)
            w = self.portals.areas * np.maximum(c, 0.0)
            self.probs = w / w.sum() if w.sum() > 0 else np.zeros_like(w)
            # Triangles by area within their pane, panes by probs.
            a = np.diff(np.concatenate([[0.0], self.portals.tri_cdf])) * self.portals.area
            tw = a * (self.probs / np.maximum(self.portals.areas, 1e-300))[self.portals.tri_k]
            self.tri_cdf = np.cumsum(tw) / max(tw.sum(), 1e-300)
        else:
            self.probs = self.portals.areas / self.portals.area
            self.tri_cdf = self.portals.tri_cdf

    @staticmethod
    def aims(light, portals) -> bool:
        """Whether `light` can send photons into the room through the portals (a sun whose
        central direction enters through none cannot)."""
        if getattr(light, "kind", None) == "SUN":
            return bool(np.any(portals.n_in @ np.asarray(light.dir, np.float64) > 0))
        return True

    def split(self, n: int) -> int:
        a = int(round(self.share * n))
        if n >= 2 and 0.0 < self.share < 1.0:
            a = min(max(a, 1), n - 1)
        return min(max(a, 0), n)

    # ---------------------------------------------------------------- densities
    def _direction_pdfs(self, w):
        """(N,K) the direction pdf (1/sr) of pane k's portal photons at sky directions w
        (N,3) (towards the sky)."""
        P = self.portals
        s = -P.n_in  # outward normals
        cos = np.maximum(w @ s.T, 0.0)
        if self.is_sun:
            light = self.light
            ch = float(light.cos_half_angle)
            if ch >= 1.0:
                return np.ones_like(cos)  # a delta: the densities' common factor
            inside = (w @ -np.asarray(light.dir, np.float64)) >= ch
            return np.where(inside[:, None], 1.0 / (2.0 * math.pi * (1.0 - ch)), 0.0) \
                * np.ones_like(cos)
        env = self.light.environment
        if env is None:
            return cos / math.pi
        from .lights.world import ENV_MAP_FRACTION as f
        out = (1.0 - f) * cos / math.pi
        for k in range(len(s)):
            out[:, k] += f * env.cosine_pdf(w, np.broadcast_to(s[k], w.shape))
        return out

    def density(self, o, d, cos=None):
        """(N,) the portal's density (module docstring; per sr x m^2 of the disk's plane)
        of rays o + t d, 0 where none crosses a pane into the room with a positive pane
        probability. cos: their crossings (Portals.crossings) when known. The direction
        pdfs only at the rows that cross (most natural photons do not)."""
        if cos is None:
            cos = self.portals.crossings(o, d)
        on = (cos > 0) & (self.probs[None, :] > 0)
        out = np.zeros(len(o))
        rows = np.flatnonzero(on.any(axis=1))
        if len(rows):
            c, pdf = cos[rows], self._direction_pdfs(-d[rows])
            terms = np.where(on[rows], self.probs[None, :] * pdf
                             / (self.portals.areas[None, :] * np.where(c > 0, c, 1.0)), 0.0)
            out[rows] = terms.sum(axis=1)
        return out

    # ---------------------------------------------------------------- emission
    def emit_into(self, key, first: int, n: int, count: int, out, start: int) -> int:
        """Light.emit_into's contract: slots first .. first + n - 1, compacted rows from
        start, the chunk's expected power n / count of the flux; returns the next row."""
        a = self.split(n)
        j = start
        if a > 0:
            j = self._portal(key, first, a, a * count / n, out, j)
        if a < n:
            j0 = j
            j = self.light.emit_into(key, first + a, n - a, (n - a) * count / n, out, j0)
            if j > j0:
                o32, d32, d, power, slot = out.arrays
                keep = self.density(o32[j0:j].astype(np.float64), d[j0:j]) <= 0.0
                m = int(keep.sum())
                if m < j - j0:
                    for arr in (o32, d32, d, power, slot):
                        arr[j0:j0 + m] = arr[j0:j][keep]
                    j = j0 + m
        return j

    def emit_towards_into(self, key, first, n, count, targets, out, start):
        return self.light.emit_towards_into(key, first, n, count, targets, out, start)

    def _portal(self, key, first, n, count, out, start):
        """n photons from the panes into the rows from start (each a share 1 / count of
        the estimate); returns the next row."""
        light, P = self.light, self.portals
        slots = np.arange(first, first + n, dtype=np.int64)
        u = emission_uniforms(key, slots, DIMS)
        m = np.minimum(np.searchsorted(self.tri_cdf, u[:, 0], side="right"),
                       len(self.tri_cdf) - 1)
        s = np.sqrt(u[:, 1])
        x = P.v0[m] + ((1.0 - s)[:, None] * P.e1[m] + (u[:, 2] * s)[:, None] * P.e2[m])
        k = P.tri_k[m]
        outward = -P.n_in[k]
        if self.is_sun:
            axis = np.broadcast_to(np.asarray(light.dir, np.float64), (n, 3))
            d = to_world(uniform_cone(u[:, 3], u[:, 4], float(light.cos_half_angle)), axis)
            w = -d
            # (the direction pdf is in the density: the sun's E over its cone's solid
            # angle, E itself for a delta sun)
            ch = float(light.cos_half_angle)
            omega = 2.0 * math.pi * (1.0 - ch) if ch < 1.0 else 1.0
            L = np.broadcast_to(np.asarray(light.irradiance, np.float64) / omega, (n, 3))
        else:
            env = light.environment
            w = to_world(cosine_hemisphere(u[:, 3], u[:, 4]), outward)
            drawn = np.ones(n, bool)
            if env is not None:
                from .lights.world import ENV_MAP_FRACTION as f
                by_map = np.flatnonzero(u[:, 5] < f)
                if len(by_map):
                    w[by_map], pdf = env.cosine_sample(u[by_map, 3], u[by_map, 4],
                                                       outward[by_map])
                    # (pdf 0: the map's part has nothing to draw there, and its density
                    # is 0 in the mixture too: the sample carries nothing)
                    drawn[by_map] = pdf > 0
                L = env.radiance(w) * drawn[:, None]
            else:
                L = np.broadcast_to(np.asarray(light.radiance, np.float64), (n, 3))
            d = -w
        o = _disk_plane_origin(x, d, np.asarray(light.center, np.float64),
                               float(light.scene_radius))
        # The line through x crosses its own portal k (by construction: no test, which a
        # point on an edge may round outside of), the others where their test says so.
        cos_k = np.einsum("ij,ij->i", d, P.n_in[k])
        if len(P.areas) > 1:
            cos = P.crossings(o, d)
        else:
            cos = np.zeros((n, 1))
        cos[np.arange(n), k] = np.maximum(cos_k, 0.0)
        dens = self.density(o, d, cos)
        ok = (cos_k > 0) & (dens > 0) & np.all(np.isfinite(L), axis=1)
        power = np.where(ok[:, None], L / (count * np.where(ok, dens, 1.0))[:, None], 0.0)
        ok &= np.any(power > 0, axis=1)
        rows = np.flatnonzero(ok)
        j = start + len(rows)
        o32, d32, dd, pw, sl = out.arrays
        o32[start:j] = o[rows]
        d32[start:j] = d[rows]
        dd[start:j] = d[rows]
        pw[start:j] = power[rows]
        sl[start:j] = slots[rows]
        return j


def sky_through_portals(ctx, portals: Portals, pane_tri, points, normals):
    """The share of the sky that the lookups at points (N,3) with normals (N,3) see
    through the portals: one cosine ray each (seeded: settings' seed, PORTAL_STREAM). A
    ray that misses everything sees the sky: through a light portal if its line meets
    one on the way out (against its n_in), else directly; one whose first hit is a pane
    (pane_tri (T,): the pane of each triangle, -1 none) from the room's side and then
    misses sees it through that pane. None when no ray sees the sky."""
    if len(points) == 0:
        return None
    rng = np.random.default_rng([ctx.settings.seed, PORTAL_STREAM])
    u = rng.random((len(points), 2))
    d = to_world(cosine_hemisphere(u[:, 0], u[:, 1]), normals)
    scale = max(float(ctx.geo.extent), 1e-9)
    o = points + 1e-5 * scale * normals
    t, prim, _, _ = ctx.accel.intersect(o, d, np.full(len(o), np.inf))
    sky = prim < 0
    through = np.zeros(len(o), bool)
    if sky.any() and len(portals.n_in) > portals.panes:
        r = np.flatnonzero(sky)
        h = portals.hits(o[r], d[r])[:, portals.panes:]
        through[r] = (h < 0).any(axis=1)
        # A light portal the lookups' sky rays cross only along its normal faces out of
        # the room: it is never used (a Blender portal's arrow must point inwards).
        out_only = ((h > 0).sum(axis=0) >= FACING_OUT_MIN_RAYS) & ~(h < 0).any(axis=0)
        portals.facing_out = [portals.names[portals.panes + k]
                              for k in np.flatnonzero(out_only)]
    if pane_tri is not None:
        k = np.where(prim >= 0, pane_tri[np.maximum(prim, 0)], -1)
        on_pane = k >= 0
        on_pane[on_pane] = np.einsum("ij,ij->i", d[on_pane], portals.n_in[k[on_pane]]) < 0
        if on_pane.any():
            r = np.flatnonzero(on_pane)
            o2 = o[r] + (t[r] + 1e-5 * scale)[:, None] * d[r]
            _, p2, _, _ = ctx.accel.intersect(o2, d[r], np.full(len(r), np.inf))
            through[r] = p2 < 0
            sky[r] = p2 < 0
    seen = int(sky.sum())
    return None if seen == 0 else float(through.sum()) / seen


def facing_out_warning(names) -> str:
    """The warning for light portals that face out of the room (Portals.facing_out), or
    ''."""
    if not names:
        return ""
    many = len(names) > 1
    return (f"light portal{'s' if many else ''} " + ", ".join(f"'{n}'" for n in names)
            + f": {'they face' if many else 'it faces'} out of the room (the surfaces the "
            "camera sees meet the sky through it only from its back), so it helps no "
            "shadow ray or photon; turn it over so its arrow (the light's -Z) points "
            "into the room")


def portal_plan(ctx, emitters: list, counts: list, region=None):
    """The global shot's emitters with the world's and suns' photons started on the
    portals (window panes: panelight's; Cycles light portals: ctx.scene.portals) where
    the scene is a room lit through them: (emitters, counts, report sentence or "").
    region: visual importance's Region (its lookups), else the pre-pass runs here. Each
    light at infinity with power (a sun: whose direction enters through a portal) becomes
    a PortalEmitter with share min(sky, PORTAL_SHARE_MAX) when the share of the sky the
    lookups see through the portals, sky, is at least PORTAL_MIN_SKY; its count is
    kept. Portal emission only re-samples the light's rays (the kinds its photons take
    through a pane are the tracing's), so it needs no shadow rays of the light."""
    from .panelight import panes_for
    from .visualimportance import RegionEmitter, lookup_points
    if not ENABLED:
        return emitters, counts, ""
    panes = panes_for(ctx)
    if panes is not None and not panes.area > 0.0:
        panes = None
    light_portals = list(getattr(ctx.scene, "portals", None) or ())
    if panes is None and not light_portals:
        return emitters, counts, ""
    if region is not None and region.points is not None:
        pts, nrm = region.points, region.normals
    else:
        pts, nrm = lookup_points(ctx, normals=True)
    if len(pts) == 0:
        return emitters, counts, ""
    # A pane's room side: the side most lookups lie on.
    n_in = []
    for q in (panes.panes if panes is not None else ()):
        side = (pts - q.c) @ q.n
        n_in.append(q.n if np.sum(side > 0) >= np.sum(side < 0) else -q.n)
    portals = portals_from(ctx.geo, panes, np.array(n_in), light_portals)
    sky = sky_through_portals(ctx, portals, None if panes is None else panes.pane_tri,
                              pts, nrm)
    warn = facing_out_warning(portals.facing_out)
    plan_warnings = getattr(getattr(ctx, "plan", None), "warnings", None)
    if warn and plan_warnings is not None and warn not in plan_warnings:
        plan_warnings.append(warn)  # (told with the effect analysis' at the pass' end)
    names = ", ".join(f"'{x}'" for x in portals.names)
    what = ("window panes" if not light_portals else
            "light portals" if panes is None else "window panes and light portals")
    if sky is None or sky < PORTAL_MIN_SKY:
        seen = "none" if sky is None else f"{sky:.0%}"
        return emitters, counts, (f"photon portals: off - the sky the camera sees is mostly "
                                  f"not through the {what} {names} ({seen} through them): "
                                  "the world's and suns' photons start on the disc "
                                  "beyond the scene, as in a scene without windows")
    portals.sky = sky
    share = min(sky, PORTAL_SHARE_MAX)
    out, used = [], []
    for e in emitters:
        light = e.light if isinstance(e, RegionEmitter) else e
        if (isinstance(light, InfiniteLight) and PortalEmitter.aims(light, portals)
                and float(luminance(np.asarray(light.photon_flux, np.float64))) > 0):
            out.append(PortalEmitter(light, portals, share))
            used.append(light.name)
        else:
            out.append(e)
    if not used:
        return emitters, counts, ""
    who = ", ".join(f"'{u}'" for u in used)
    return out, counts, (f"photon portals: on - {share:.0%} of the photons of {who} start "
                         f"on the {what} {names} ({sky:.0%} of the sky the camera's "
                         "surfaces see is through them); the other "
                         f"{1 - share:.0%} start on the disc beyond the scene, as in a scene "
                         "without windows")
