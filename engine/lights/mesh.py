"""Emissive meshes as one light: every triangle with emission, each emitting its radiance
from both sides (Cycles' Emission closure emits from both faces too; only a material's
Emission Sampling set to Front or Back restricts its light sampling to one).

Photons leave a triangle chosen by area x brightness (a CDF over triangles: the power
split). Shadow rays choose the triangle by its importance at the shading point instead:
every emissive triangle is a leaf of the light's own light tree (triangle_tree; its
bounds, normal and power as Cycles' kernel/light/tree.h and pbrt-v4's
TriangleLight::Bounds), walked by lights/selection.select_light, so triangles far away or
seen edge-on are rarely picked; triangle_pmf gives the same probability for multiple
importance sampling where a BSDF ray meets an emitter.

A material's Emission Sampling (scene.emission_sides, Cycles' SD_MIS_FRONT / SD_MIS_BACK)
restricts which sides shadow rays sample: a one-sided triangle is a one-sided leaf of the
triangle tree (its normal the sampled side's, Cycles' light tree for one-sided
emitters) and the shadow-ray kernel takes no sample from its other side; a triangle of
no sampled side has no power in the tree (never chosen). The emission stays two-sided:
photons leave every emissive triangle from both sides, and the sides left out reach
surfaces through rays that meet them (unsampled_side: counted in full, no MIS)."""
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
BOTH_SIDES = 3  # scene.SIDE_FRONT | scene.SIDE_BACK


class MeshLight(Light):
    kind = MESH
    declared = False

    @classmethod
    def from_geometry(cls, geo, table, common, gathered=True):
        """The light of all emissive triangles of geo, or None when there are none.
        Shadow rays sample the sides of each triangle its material's Emission Sampling
        names (table.emission_sides), every side when not gathered (no final gathering:
        nothing else would bring the other sides' direct light to diffuse surfaces)."""
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
        if table.emission_sides is None or not gathered:
            sides = np.full(len(idx), BOTH_SIDES, np.int64)
        else:
            sides = np.ascontiguousarray(table.emission_sides[geo.material[idx]], np.int64)
        return cls("emissive meshes", v0=geo.v0[idx], e1=geo.e1[idx], e2=geo.e2[idx],
                   tri_ng=geo.ng[idx], tri_L=L, tri_area=area, prob=prob, cdf=cdf,
                   tri_index=idx, photon_flux=flux, flux=flux, radius=0.0,
                   round32=geo.round32[idx], tilt32=geo.tilt32[idx],
                   tri_sides=sides, cos_half_angle=1.0, **common)

    tri_sides = None  # (T,) int64 sides shadow rays sample (scene.emission_sides); None: both

    @property
    def shadow_sampled(self) -> bool:
        """Whether shadow rays sample any side of any triangle: with none (Emission
        Sampling None everywhere) the light takes no shadow ray at all and
        integrator.light_modes leaves it to the rays that meet it. Its photons still
        leave (Light.ray_kinds unchanged: a photon's first segment stands for a
        shadow or diffuse ray from the surface it lands on)."""
        return self.tri_sides is None or bool(np.any(self.tri_sides))

    def sides(self) -> np.ndarray:
        """(T,) int64 the sides of each triangle shadow rays sample (scene.SIDE_FRONT |
        scene.SIDE_BACK bits; 3 for every triangle when none were given)."""
        if self.tri_sides is None:
            return np.full(len(self.tri_area), BOTH_SIDES, np.int64)
        return np.ascontiguousarray(self.tri_sides, np.int64)

    def unsampled_side(self, tri, d) -> np.ndarray:
        """Whether rays of unit direction d (N,3) meeting triangles tri (N,) (rows of v0
        ...) arrive at a side shadow rays do not sample (N,) bool: its light there counts
        in full (Cycles' shade_surface: no MIS where the shader's SD_MIS_FRONT /
        SD_MIS_BACK flag for the side is unset). The front is the side ng points to."""
        if self.tri_sides is None:
            return np.zeros(len(tri), bool)
        s = np.asarray(self.tri_sides)[tri]
        front = np.einsum("ij,ij->i", d, np.asarray(self.tri_ng, float)[tri]) < 0
        return np.where(front, (s & 1) == 0, (s & 2) == 0)

    needs_choice = True

    def triangle_tree(self):
        """(tree_f, tree_i, leaf_of) of the light tree over this light's triangles
        (selection.build_tree; LIGHT = the triangle's row in v0 ...): leaf bounds the
        triangle's box, its normal with cos theta_o = 1 and cos theta_e = 0 (emission
        reaches the hemisphere), two-sided, power 2 pi area luminance(L) (area alone
        when every triangle is black). A one-sided triangle (tri_sides) takes the
        sampled side's normal, one-sided; a triangle of no sampled side power 0 (Cycles
        leaves it out of its light tree). Built once, on first use."""
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
            w = np.asarray(self.tri_ng, float)
            two = np.ones(T, bool)
            if self.tri_sides is not None and (self.sides() != BOTH_SIDES).any():
                s = self.sides()
                w = np.where((s == 2)[:, None], -w, w)  # back alone: the back's normal
                two = s == BOTH_SIDES
                sampled = s != 0
                phi = np.where(sampled, phi, 0.0)
                if not phi.sum() > 0:
                    phi = np.where(sampled, area, 0.0)
                if not phi.sum() > 0:
                    phi = area.copy()  # no sampled side: the tree is never walked
            tree = build_tree(lo, hi, w, np.ones(T), np.zeros(T), phi, two)
            self._triangle_tree = tree
        return tree

    def shadow_pdf(self, p, n, tri, t, cos_l):
        """Solid-angle pdf (N,) of this light's shadow rays from points p (N,3), shading
        normals n (N,3), towards triangle tri (N,) met at distance t (N,) with cosine
        |cos_l| (N,) at the triangle: the triangle's pmf (triangle_pmf) times 1 / its
        solid angle where it is sampled by solid angle (solid_angle_sampled), else
        t^2 / (area |cos_l|) (a uniform point): directlight.sample_lights' lpdf."""
        p = np.ascontiguousarray(p, np.float64).reshape(-1, 3)
        tri = np.asarray(tri, np.int64)
        pmf = self.triangle_pmf(p, n, tri)
        v0, e1, e2, ng = (np.asarray(x, np.float64)[tri] for x in
                          (self.v0, self.e1, self.e2, self.tri_ng))
        longest = np.maximum(np.maximum(np.einsum("ij,ij->i", e1, e1),
                                        np.einsum("ij,ij->i", e2, e2)),
                             np.einsum("ij,ij->i", e2 - e1, e2 - e1))
        h = np.einsum("ij,ij->i", ng, v0 - p)
        solid = longest > h * h
        with np.errstate(divide="ignore", invalid="ignore"):
            area_pdf = t * t / np.maximum(np.asarray(self.tri_area, float)[tri]
                                          * np.abs(cos_l), 1e-300)
            omega = triangle_solid_angle(p, v0, v0 + e1, v0 + e2)
            return pmf * np.where(solid, 1.0 / np.where(omega > 0, omega, np.inf), area_pdf)

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


# ---------------------------------------------------------------- shadow-ray sampling
# A chosen triangle is sampled by solid angle when it is large against its plane's
# distance from the shading point (longest edge^2 > distance^2, Cycles'
# triangle_light_sample): a uniform point then spreads its 1 / d^2 over a close, long
# triangle (a neon tube's strip 15 cm from a wall: relative variance ~3 a sample), while
# the spherical triangle's directions carry only the receiver's cosine. Small or distant
# triangles keep the uniform point (their solid angle loses precision in float64 well
# before the point does).


@kernel
def solid_angle_sampled(p0, p1, p2, v0, e1, e2, ng, t):
    """Whether shadow rays from point p sample triangle t of (v0, e1, e2 (T,3), unit
    normals ng (T,3)) by solid angle (True) or by a uniform point (False)."""
    a = e1[t, 0] ** 2 + e1[t, 1] ** 2 + e1[t, 2] ** 2
    b = e2[t, 0] ** 2 + e2[t, 1] ** 2 + e2[t, 2] ** 2
    c = ((e2[t, 0] - e1[t, 0]) ** 2 + (e2[t, 1] - e1[t, 1]) ** 2
         + (e2[t, 2] - e1[t, 2]) ** 2)
    h = (ng[t, 0] * (v0[t, 0] - p0) + ng[t, 1] * (v0[t, 1] - p1)
         + ng[t, 2] * (v0[t, 2] - p2))
    return max(max(a, b), c) > h * h


@kernel
def _unit(x, y, z):
    n = math.sqrt(x * x + y * y + z * z)
    if not n > 0:
        return 0.0, 0.0, 0.0, 0.0
    return x / n, y / n, z / n, n


@kernel
def _angle_between(a0, a1, a2, b0, b1, b2):
    """pbrt-v4 AngleBetween of unit vectors (stable near 0 and pi)."""
    if a0 * b0 + a1 * b1 + a2 * b2 < 0:
        d = math.sqrt((a0 + b0) ** 2 + (a1 + b1) ** 2 + (a2 + b2) ** 2)
        return math.pi - 2.0 * math.asin(min(d / 2.0, 1.0))
    d = math.sqrt((b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2)
    return 2.0 * math.asin(min(d / 2.0, 1.0))


@kernel
def spherical_triangle_sample(p0, p1, p2, v0, e1, e2, t, u0, u1):
    """A direction from p uniform in the solid angle of triangle t (v0, e1, e2 (T,3)):
    pbrt-v4's SampleSphericalTriangle (Arvo 1995, "Stratified sampling of spherical
    triangles"), numbers u0, u1 in [0, 1). Returns (w0, w1, w2, solid angle in sr);
    solid angle 0 when the triangle is degenerate as seen from p (no sample)."""
    a0, a1, a2, la = _unit(v0[t, 0] - p0, v0[t, 1] - p1, v0[t, 2] - p2)
    b0, b1, b2, lb = _unit(v0[t, 0] + e1[t, 0] - p0, v0[t, 1] + e1[t, 1] - p1,
                           v0[t, 2] + e1[t, 2] - p2)
    c0, c1, c2, lc = _unit(v0[t, 0] + e2[t, 0] - p0, v0[t, 1] + e2[t, 1] - p1,
                           v0[t, 2] + e2[t, 2] - p2)
    if not (la > 0 and lb > 0 and lc > 0):
        return 0.0, 0.0, 0.0, 0.0
    # normals of the great circles through the edges
    nab0, nab1, nab2, l1 = _unit(a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)
    nbc0, nbc1, nbc2, l2 = _unit(b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0)
    nca0, nca1, nca2, l3 = _unit(c1 * a2 - c2 * a1, c2 * a0 - c0 * a2, c0 * a1 - c1 * a0)
    if not (l1 > 0 and l2 > 0 and l3 > 0):
        return 0.0, 0.0, 0.0, 0.0
    alpha = _angle_between(nab0, nab1, nab2, -nca0, -nca1, -nca2)
    beta = _angle_between(nbc0, nbc1, nbc2, -nab0, -nab1, -nab2)
    gamma = _angle_between(nca0, nca1, nca2, -nbc0, -nbc1, -nbc2)
    a_pi = alpha + beta + gamma
    area = a_pi - math.pi
    if not area > 0:
        return 0.0, 0.0, 0.0, 0.0
    # the sub-triangle of area u0 x area: its third corner c' on the arc a..c
    ap_pi = math.pi + u0 * (a_pi - math.pi)
    cos_al, sin_al = math.cos(alpha), math.sin(alpha)
    sin_phi = math.sin(ap_pi) * cos_al - math.cos(ap_pi) * sin_al
    cos_phi = math.cos(ap_pi) * cos_al + math.sin(ap_pi) * sin_al
    k1 = cos_phi + cos_al
    k2 = sin_phi - sin_al * (a0 * b0 + a1 * b1 + a2 * b2)
    den = (k2 * sin_phi + k1 * cos_phi) * sin_al
    cos_bp = (k2 + (k2 * cos_phi - k1 * sin_phi) * cos_al) / den if den != 0.0 else 1.0
    cos_bp = min(max(cos_bp, -1.0), 1.0)
    sin_bp = math.sqrt(max(0.0, 1.0 - cos_bp * cos_bp))
    ca = c0 * a0 + c1 * a1 + c2 * a2
    g0, g1, g2, _ = _unit(c0 - ca * a0, c1 - ca * a1, c2 - ca * a2)
    cp0, cp1, cp2 = cos_bp * a0 + sin_bp * g0, cos_bp * a1 + sin_bp * g1, cos_bp * a2 + sin_bp * g2
    # then uniform in the arc b..c' by u1
    cos_t = 1.0 - u1 * (1.0 - (cp0 * b0 + cp1 * b1 + cp2 * b2))
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    cb = cp0 * b0 + cp1 * b1 + cp2 * b2
    h0, h1, h2, _ = _unit(cp0 - cb * b0, cp1 - cb * b1, cp2 - cb * b2)
    w0, w1, w2, _ = _unit(cos_t * b0 + sin_t * h0, cos_t * b1 + sin_t * h1,
                          cos_t * b2 + sin_t * h2)
    return w0, w1, w2, area


def triangle_solid_angle(p, a, b, c):
    """Solid angle (N,) in sr of triangles (a, b, c (N,3) corners) seen from p (N,3):
    Van Oosterom and Strackee (1983), tan(omega / 2) = |a.(b x c)| / (1 + a.b + b.c +
    c.a) for the unit vectors towards the corners."""
    def unit(x):
        return x / np.linalg.norm(x, axis=1, keepdims=True)
    a, b, c = unit(a - p), unit(b - p), unit(c - p)
    det = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    den = (1.0 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c)
           + np.einsum("ij,ij->i", c, a))
    return 2.0 * np.arctan2(det, den)
