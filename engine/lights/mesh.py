"""Emissive meshes as one light: every triangle with emission, chosen by area x
brightness (a CDF over triangles), each emitting its radiance from both sides."""
from __future__ import annotations

import math

import numpy as np

from ..geometry import emissive_triangles
from ..jit import kernel
from ..rayoffset import _offset_row, _point_error
from ..sampling import luminance
from .emission import (f64, aim_direction, aim_weights, cosine_hemisphere, emit_uniform, pick, put,
                       to_world)
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

    def aim(self, centers, radii):
        """Aimed from the emitting triangles' mean corner (emission.aim_weights)."""
        return aim_weights(centers, radii, self.v0.mean(axis=0))

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        return emit_mesh(f64(self.v0), f64(self.e1), f64(self.e2), f64(self.tri_ng),
                         f64(self.tri_L), f64(self.tri_area), f64(self.prob), f64(self.cdf),
                         f64(self.round32), f64(self.tilt32), *aim.arrays, aimed, key, first,
                         n, float(count), *out.arrays, start)


@kernel
def emit_mesh(v0, e1, e2, ng, L, area, prob, cdf, round32, tilt32, centers, radii, probs,
              aimed_cdf, aimed, key, first, n, count, o32, d32, d, power, slot, start):
    """Photons of the emissive triangles (v0, e1, e2, unit normals ng (T,3), radiance L
    (T,3), area (T,), chosen with probabilities prob / CDF cdf (T,) by area x brightness):
    a uniform point, a side, a cosine-distributed direction; power 2 pi area L /
    (prob count) (both sides emit). aimed: directions aimed at the spheres (centers, radii,
    probs, aimed_cdf), power area L |cos| / (prob count aimed pdf). Each origin leaves its
    triangle along ng by the rounding-error bound of the point (engine/rayoffset.py): from
    the triangle itself, Embree can report it again at t ~ 0 and the photon lands on its own
    emitter from the wrong side (measured: a third of a furnace room's photons).
    Dimensions: 0 the triangle, 1, 2 the point, 3, 4 the direction, 5 the side (aimed: the
    target)."""
    j = start
    for i in range(n):
        s = first + i
        t = pick(cdf, emit_uniform(key, s, 0))
        sq = math.sqrt(emit_uniform(key, s, 1))
        b1 = 1.0 - sq
        b2 = emit_uniform(key, s, 2) * sq
        y0 = v0[t, 0] + b1 * e1[t, 0] + b2 * e2[t, 0]
        y1 = v0[t, 1] + b1 * e1[t, 1] + b2 * e2[t, 1]
        y2 = v0[t, 2] + b1 * e1[t, 2] + b2 * e2[t, 2]
        g0, g1, g2 = ng[t, 0], ng[t, 1], ng[t, 2]
        if not aimed:
            side = 1.0 if emit_uniform(key, s, 5) < 0.5 else -1.0
            l0, l1, l2 = cosine_hemisphere(emit_uniform(key, s, 3), emit_uniform(key, s, 4))
            d0, d1, d2 = to_world(l0, l1, l2, g0 * side, g1 * side, g2 * side)
            w = 2.0 * math.pi * area[t] / (prob[t] * count)
        else:
            d0, d1, d2, pdf_aim = aim_direction(centers, radii, probs, aimed_cdf, y0, y1, y2,
                                                emit_uniform(key, s, 5), emit_uniform(key, s, 3),
                                                emit_uniform(key, s, 4))
            w = area[t] * abs(d0 * g0 + d1 * g1 + d2 * g2) / (prob[t] * count * pdf_aim)
        ex = _point_error(v0, e1, e2, round32, t, b1, b2, y0, y1, y2, 0)
        ey = _point_error(v0, e1, e2, round32, t, b1, b2, y0, y1, y2, 1)
        ez = _point_error(v0, e1, e2, round32, t, b1, b2, y0, y1, y2, 2)
        off = _offset_row(ex, ey, ez, v0, e1, e2, t, g0, g1, g2, y0, y1, y2, tilt32[t])
        if d0 * g0 + d1 * g1 + d2 * g2 < 0.0:
            off = -off
        j = put(o32, d32, d, power, slot, j, y0 + off * g0, y1 + off * g1, y2 + off * g2,
                d0, d1, d2, L[t, 0] * w, L[t, 1] * w, L[t, 2] * w, s)
    return j
