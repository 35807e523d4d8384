"""Camera walks in fog that go on to a surface (Volume bounces > 0; issue 14, volphotons38).

volumescatter.CameraScattering.walk scatters a camera path on inside a medium, each
scatter point lit by the lamps; a walk segment whose sampled distance falls beyond the
medium's segment ended there, and the light of the surface at its end (a floor lit under
the fog, the walls of a foggy room) was missing: Cycles' path goes on from the medium
point to that surface and takes its light. Here each walk segment from a scatter point
that may still go on (a scatter count below Volume bounces + 1, Cycles' per-path limit,
engine/photonmedium.py) adds, besides its in-segment scatter estimate (the same as
before), the surface term of the same direction deterministically (splitting the
segment's integral into its in-medium part and T(S) L_surface):
    L += beta x T(S) x L_surface(y, -d),
T(S) = exp(-sigma_t S) along the segment in the medium and, past a volume-only face
(the fog box's own boundary: a transparent pass), the outside medium's (the world
volume's, if any) up to the next surface. L_surface is the surface's diffuse radiance
from its total irradiance at the final-gather map (ctx.gather_map: every photon, direct
ones included, so the lamps' direct light, the indirect light and the fog's scattered
photons, engine/photonmedium.py), reflected by its diffuse lobe: wd E / pi, the same
estimate a final-gather ray's end takes. Surfaces without a diffuse lobe add nothing
(their glossy light through the fog is not followed); a lookup flagged as a boundary
(no gather point in range) adds nothing. Without photon mapping (no gather map) the walk is as before.

Seeded as the walk: the directions are the walk's own; the surface term draws no
number, so an image is the same for any worker count.
"""
from __future__ import annotations

import math

import numpy as np

from .bsdf import lobe_weights, surface_hit
from .volumescatter import CameraScattering

MAX_PASSES = 2  # volume-only faces passed on the way to a surface (leaving one fog box)


class WalkingScattering(CameraScattering):
    """CameraScattering whose walk adds the surface at each walk segment's end (its
    segment_end_light hook)."""

    def segment_end_light(self, x, d, t, prim, u, v, m):
        """The walk's hook (volumescatter.CameraScattering.walk): surface_light with the
        final-gather map (none without photon mapping)."""
        gmap = getattr(self.ctx, "gather_map", None)
        if gmap is None:
            return np.zeros(0, np.int64), np.zeros((0, 3))
        return self.surface_light(gmap, x, d, t, prim, u, v, m)

    def surface_light(self, gmap, x, d, t, prim, u, v, m):
        """(rows (K,), L (K,3)): T(S) x the diffuse radiance towards x of the surface each
        walk segment (from x (n,3) along d (n,3) unit, hit t (n,), triangles prim (n,),
        barycentrics u, v, in media m (n,)) ends on, past at most MAX_PASSES
        volume-only faces, for the K rows that reach a diffuse surface."""
        ctx = self.ctx
        n = len(prim)
        prim = np.asarray(prim, np.int64)
        T = np.exp(-self.sigma_t[m] * np.asarray(t, np.float64)[:, None])
        het = getattr(ctx, "hetero", None)
        if het is not None and het.fields:
            # Density textures: the stand-in's T(S) corrected (engine/heterogeneous.py).
            T = T * het.correction(x, d, np.where(prim >= 0, np.asarray(t, np.float64),
                                                  0.0), salt=7)
        rows = np.arange(n)
        d = np.asarray(d, np.float64)
        vo_table = getattr(ctx.table, "volume_only", None)
        t, u, v = (np.asarray(a, np.float64) for a in (t, u, v))
        for _ in range(MAX_PASSES):
            hit = prim >= 0
            rows, prim, t, u, v, T = rows[hit], prim[hit], t[hit], u[hit], v[hit], T[hit]
            if vo_table is None or not len(rows):
                break
            mat = surface_hit(ctx.geo, ctx.table, prim, u, v, d[rows]).mat
            through = np.asarray(vo_table)[mat]
            if not np.any(through):
                break
            k = np.flatnonzero(through)
            y = surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[rows[k]])
            o2 = y.p + d[rows[k]] * (np.abs(y.offset)[:, None] * 4.0 + 1e-6)
            t2, p2, u2, v2 = ctx.accel.intersect(o2, d[rows[k]])
            t2 = np.asarray(t2, np.float64)
            if self.world_row >= 0:
                T[k] *= np.exp(-self.sigma_t[self.world_row][None, :]
                               * np.where(np.asarray(p2) >= 0, t2, np.inf)[:, None])
            prim[k], t[k], u[k], v[k] = p2, t2, u2, v2
        hit = prim >= 0
        rows, prim, u, v, T = rows[hit], prim[hit], u[hit], v[hit], T[hit]
        if not len(rows):
            return rows, np.zeros((0, 3))
        y = surface_hit(ctx.geo, ctx.table, prim, u, v, d[rows])
        wd = np.asarray(lobe_weights(ctx.table, y)["diffuse"], np.float64)
        keep = np.flatnonzero(np.any(wd > 0.0, axis=1))
        if not len(keep):
            return rows[:0], np.zeros((0, 3))
        y = y.take(keep)
        from .integrator import hit_surfaces  # (integrator imports this module)
        E, boundary = gmap.lookup(np.asarray(y.p, np.float64), np.asarray(y.ng, np.float64),
                                  offset=np.asarray(y.offset, np.float64),
                                  surface=hit_surfaces(ctx, prim[keep]))[:2]
        Ls = wd[keep] * np.asarray(E, np.float64) / math.pi * T[keep]
        Ls[np.asarray(boundary, bool)] = 0.0
        return rows[keep], Ls
