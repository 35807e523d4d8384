"""Emissive meshes as one light: every triangle with emission, chosen by area x
brightness (a CDF over triangles), each emitting its radiance from both sides."""
from __future__ import annotations

import math

import numpy as np

from ..geometry import emissive_triangles
from ..rayoffset import origin_offset, triangle_point_error
from ..sampling import cosine_hemisphere, dot, luminance, offset_origin, to_world, uniform_triangle
from . import packing as pk
from .base import Light

MESH = "MESH"


class MeshLight(Light):
    kind = MESH
    declared = False

    @classmethod
    def from_geometry(cls, geo, table, common):
        """The light of all emissive triangles of geo, or None when there are none."""
        idx, L, area = emissive_triangles(geo, table)
        if not len(idx):
            return None
        weight = area * luminance(L)
        if weight.sum() <= 0:
            weight = area.copy()
        prob = weight / weight.sum()
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        flux = (2.0 * math.pi * area[:, None] * L).sum(axis=0)
        return cls("emissive meshes", v0=geo.v0[idx], e1=geo.e1[idx], e2=geo.e2[idx],
                   tri_ng=geo.ng[idx], tri_L=L, tri_area=area, prob=prob, cdf=cdf,
                   tri_index=idx, photon_flux=flux, flux=flux, radius=0.0,
                   round32=geo.round32[idx], tilt32=geo.tilt32[idx],
                   cos_half_angle=1.0, **common)

    needs_choice = True

    def pack(self, row) -> int:
        """The triangles travel as arrays (packing.pack_lights); returns the kind code."""
        return pk.CODE_MESH

    def _point(self, rng, u1, u2):
        """(triangle index, point, barycentrics b1, b2) on the emissive triangles, chosen
        by area x brightness."""
        tri = np.searchsorted(self.cdf, rng.random(len(u1)), side="right").clip(0, len(self.cdf) - 1)
        b1, b2 = uniform_triangle(u1, u2)
        return tri, self.v0[tri] + b1[:, None] * self.e1[tri] + b2[:, None] * self.e2[tri], b1, b2

    def _error(self, tri, b1, b2, y):
        """(N,3) rounding-error bound of points y on emissive triangles (engine/rayoffset.py)."""
        return triangle_point_error(self.v0[tri], self.e1[tri], self.e2[tri], self.round32[tri],
                                    b1, b2, y)

    def _offset(self, tri, b1, b2, y):
        """(N,) distance along the normal that takes a ray leaving y clear of its triangle
        (engine/rayoffset.py)."""
        return origin_offset(self._error(tri, b1, b2, y), self.v0[tri], self.e1[tri],
                             self.e2[tri], self.tri_ng[tri], y, self.tilt32[tri])

    def _emit(self, n, rng, u1, u2, u3, u4):
        tri, o, b1, b2 = self._point(rng, u1, u2)
        side = np.where(rng.random(n) < 0.5, 1.0, -1.0)[:, None]
        nrm = self.tri_ng[tri] * side
        d = to_world(cosine_hemisphere(u3, u4), nrm)
        power = (2.0 * math.pi * self.tri_area[tri] / (self.prob[tri] * n))[:, None] * self.tri_L[tri]
        # Leave the emitting surface: from a point on the triangle itself, Embree can
        # report the triangle again at t ~ 0 and the photon lands on its own emitter,
        # from the wrong side (measured: a third of a furnace room's photons).
        return offset_origin(o, nrm, d, self._offset(tri, b1, b2, o)), d, power

    def _aim_origins(self, n, rng, u1, u2):
        tri, o, b1, b2 = self._point(rng, u1, u2)
        return o, self.tri_ng[tri], self.v0.mean(axis=0), (tri, b1, b2)

    def _aimed_photons(self, n, rng, o, d, normal, state, aimed):
        tri, b1, b2 = state
        cos = np.abs(dot(d, normal))
        scale = self.tri_area[tri] * cos / (self.prob[tri] * n * aimed)
        return (offset_origin(o, normal, d, self._offset(tri, b1, b2, o)), d,
                self.tri_L[tri] * scale[:, None])
