"""Emissive meshes as one light: every triangle with emission, each emitting its radiance
from both sides (Cycles' Emission closure emits from both faces too; only a material's
Emission Sampling set to Front or Back restricts its light sampling to one).

Photons leave a triangle chosen by area x brightness (a CDF over triangles: the power
split). Shadow rays choose the triangle by its importance at the shading point instead:
every emissive triangle is a leaf of the light's own light tree (triangle_tree; its
bounds, normal and power as Cycles' kernel/light/tree.h and pbrt-v4's
TriangleLight::Bounds), walked by lights/selection.select_light, so triangles far away or
seen edge-on are rarely picked; triangle_pmf gives the same probability for multiple
importance sampling where a BSDF ray meets an emitter."""
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

    def triangle_tree(self):
        """(tree_f, tree_i, leaf_of) of the light tree over this light's triangles
        (selection.build_tree; LIGHT = the triangle's row in v0 ...): leaf bounds the
        triangle's box, its normal with cos theta_o = 1 and cos theta_e = 0 (emission
        reaches the hemisphere), two-sided, power 2 pi area luminance(L) (area alone
        when every triangle is black). Built once, on first use."""
        tree = getattr(self, "_triangle_tree", None)
        if tree is None:
            from .selection import build_tree
            a, b, c = self.v0, self.v0 + self.e1, self.v0 + self.e2
            lo = np.minimum(np.minimum(a, b), c)
            hi = np.maximum(np.maximum(a, b), c)
            area = np.asarray(self.tri_area, float)
            phi = 2.0 * math.pi * area * luminance(np.asarray(self.tri_L, float))
            if not phi.sum() > 0:
                phi = area.copy()
            T = len(area)
            tree = build_tree(lo, hi, np.asarray(self.tri_ng, float), np.ones(T),
                              np.zeros(T), phi, np.ones(T, bool))
            self._triangle_tree = tree
        return tree

    def triangle_pmf(self, p, n, tri):
        """Probability (N,) that a shadow ray from point p (N,3) with shading normal n
        (N,3) picks triangle tri (N,) int (rows of v0 ...): the triangle tree's walk
        (directlight.sample_lights), without the choice of this light among others."""
        from .selection import pmf_each
        tf, ti, leaf_of = self.triangle_tree()
        p, n = (np.ascontiguousarray(x, np.float64).reshape(-1, 3) for x in (p, n))
        out = np.empty(len(p))
        pmf_each(p, n, np.ascontiguousarray(tri, np.int64), tf, ti, leaf_of, out)
        return out

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
