"""Area light: a rectangle or ellipse emitting one-sided uniform radiance P/(pi A) along
its -Z axis (the light's `dir`), optionally narrowed by Blender's spread (Cycles'
kernel/light/area.h); a sheared object transform keeps a parallelogram."""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from .emission import (TWO_PI, Aim, f64, _cone_cos, _misses, aim_weights, concentric_disk,
                       cosine_hemisphere, emit_uniform, pick, put, to_world, uniform_cone)
from ..scene import AREA, DISK, spread_attenuation
from . import packing as pk
from .base import Light


class AreaLight(Light):
    kind = AREA

    @classmethod
    def from_scene(cls, light, geo, common):
        if light.area <= 0:
            return None
        kw = cls.scene_params(light, geo, common)
        flux = light.flux
        kw.update(area=light.area, flux=flux, radiance=flux / (math.pi * light.area),
                  photon_flux=flux)
        return cls(light.name, **kw)

    has_surface = True

    def aim(self, centers, radii) -> Aim:
        """Aim at bounding spheres (centers (K,3), radii (K,)) by the power the light sends
        into each (area_aim_weights): a sphere wholly behind the one-sided emitter, or
        outside its spread, is never aimed at (solid-angle weights wasted those photons
        as spot lights once did: tests/test_area_aim.py)."""
        return area_aim_weights(centers, radii, self.pos, self.dir, self.spread)

    def _spread_rect(self) -> bool:
        """A rectangle with a narrow spread samples only the part that reaches the point
        (_sample_spread_rect); a sheared one samples it whole."""
        return bool(self.spread < math.pi and self.shape != DISK and np.allclose(self.du, self.u)
                    and np.allclose(self.dv, self.v))

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code."""
        for slot, value in ((pk.POS, self.pos), (pk.DIR, self.dir), (pk.U, self.u),
                            (pk.V, self.v), (pk.DU, self.du), (pk.DV, self.dv),
                            (pk.RGB, self.radiance)):
            row[slot:slot + 3] = value
        row[pk.SIZE_X], row[pk.SIZE_Y], row[pk.AREA_] = self.size_x, self.size_y, self.area
        row[pk.IS_DISK] = self.shape == DISK
        row[pk.SPREAD_RECT] = self._spread_rect()
        # spread_attenuation (engine/scene.py) is 1 from pi - 1e-6 on.
        row[pk.SPREAD_ON] = self.spread < math.pi - 1e-6
        h = 0.5 * self.spread
        row[pk.TAN_H] = math.tan(h)
        row[pk.SPREAD_NORM] = (1.0 / (math.tan(h) - h) if h > 0.05 else 3.0 / h ** 3) if h > 0 else 0.0
        return pk.CODE_AREA

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        h = 0.5 * self.spread
        # spread_attenuation (engine/scene.py) is 1 from pi - 1e-6 on; below pi the
        # directions are drawn inside the spread cone.
        norm = (1.0 / (math.tan(h) - h) if h > 0.05 else 3.0 / h ** 3) if h > 0 else 0.0
        return emit_area(f64(self.pos), f64(self.dir), f64(self.du), f64(self.dv),
                         float(self.size_x),
                         float(self.size_y), self.shape == DISK, self.spread < math.pi,
                         self.spread < math.pi - 1e-6, math.sin(h), math.tan(h), norm,
                         f64(self.flux), *aim.arrays, aimed, key, first, n,
                         float(count), *out.arrays, start)

    def intersect(self, o, d, tmax):
        """One-sided: a ray must travel against the emission to see the light. One
        compiled pass (intersect_area)."""
        n = len(o)
        tmax = np.asarray(tmax, np.float64)
        tmax = np.full(n, float(tmax)) if tmax.ndim == 0 else np.ascontiguousarray(tmax)
        mask, t, denom = np.empty(n, np.bool_), np.empty(n), np.empty(n)
        intersect_area(f64(o), f64(d), tmax, f64(self.pos), f64(self.dir), f64(self.u),
                       f64(self.v), float(self.size_x / 2), float(self.size_y / 2),
                       self.shape == DISK, mask, t, denom)
        L = np.broadcast_to(self.radiance, (n, 3))
        if self.spread < math.pi:
            L = L * spread_attenuation(-denom, self.spread)[:, None]
        return mask, t, L


@kernel
def intersect_area(o, d, tmax, pos, axis, u, v, half_x, half_y, disk, mask, t, denom):
    """AreaLight.intersect for rays o, d (N,3) up to tmax (N,): writes mask (N,) (the ray
    meets the emitting side inside the rectangle / ellipse of half sizes half_x, half_y
    spanned by the unit u, v round pos, before tmax), t (N,) (inf where the ray does not
    travel against axis) and denom (N,) = d . axis. The arithmetic of the numpy stage it
    replaced, operation for operation (its dot products as np.einsum sums three terms:
    (x + z) + y), so the same bits."""
    for i in range(o.shape[0]):
        dn = (d[i, 0] * axis[0] + d[i, 2] * axis[2]) + d[i, 1] * axis[1]
        denom[i] = dn
        facing = dn < -1e-12
        ti = np.inf
        if facing:
            q0, q1, q2 = pos[0] - o[i, 0], pos[1] - o[i, 1], pos[2] - o[i, 2]
            ti = ((q0 * axis[0] + q2 * axis[2]) + q1 * axis[1]) / dn
        t[i] = ti
        s = ti if math.isfinite(ti) else 0.0
        h0 = (o[i, 0] + s * d[i, 0]) - pos[0]
        h1 = (o[i, 1] + s * d[i, 1]) - pos[1]
        h2 = (o[i, 2] + s * d[i, 2]) - pos[2]
        x = ((h0 * u[0] + h2 * u[2]) + h1 * u[1]) / half_x
        y = ((h0 * v[0] + h2 * v[2]) + h1 * v[1]) / half_y
        inside = (x * x + y * y <= 1.0) if disk else (abs(x) <= 1 and abs(y) <= 1)
        mask[i] = facing and inside and ti > 0 and ti < tmax[i]


@register_warm_up
def _warm_up():
    one = np.ones((1, 3))
    for disk in (False, True):
        intersect_area(one, -one, np.ones(1), np.zeros(3), np.array([0.0, 0.0, -1.0]),
                       np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), 0.5, 0.5, disk,
                       np.empty(1, np.bool_), np.empty(1), np.empty(1))
    rect_solid_angles(-one, np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]),
                      np.empty(1))


@kernel
def spread_factor(on, tan_h, norm, cos_a):
    """scene.spread_attenuation for one cosine (on: spread below pi - 1e-6)."""
    if not on:
        return 1.0
    c = max(cos_a, 1e-12)
    tan_a = math.sqrt(max(1.0 - c * c, 0.0)) / c
    if cos_a > 0:
        return max((tan_h - tan_a) * norm, 0.0)
    return 0.0


@kernel
def emit_area(pos, axis, du, dv, size_x, size_y, disk, narrow, spread_on, sin_h, tan_h, norm,
              flux, centers, radii, probs, cdf, aimed, key, first, n, count,
              o32, d32, d, power, slot, start):
    """Photons of an area light (rectangle or ellipse size_x x size_y spanned by du, dv
    round pos; one-sided along axis) of flux `flux` (3,) W: uniform points, cosine-
    distributed directions; narrow (spread < pi): cosine-distributed inside the spread
    cone (a disk of radius sin h under the hemisphere, pdf cos a / (pi sin^2 h)), weighted
    f(a) sin^2 h (mean 1: the flux is kept). aimed: directions aimed at the spheres,
    weighted by the natural pdf cos a f(a) / pi over the aimed pdf (area_aim_direction).
    Dimensions: 0, 1 the
    point, 2, 3 the direction; aimed: 0 the target, 1, 2 the point, 3, 4 the direction."""
    j = start
    f0, f1, f2 = flux[0] / count, flux[1] / count, flux[2] / count
    k = 1 if aimed else 0
    for i in range(n):
        s = first + i
        u1 = emit_uniform(key, s, k)
        u2 = emit_uniform(key, s, k + 1)
        if disk:
            x, y = concentric_disk(u1, u2)
            x, y = x * size_x / 2, y * size_y / 2
        else:
            x, y = (u1 - 0.5) * size_x, (u2 - 0.5) * size_y
        # du, dv: the dual basis of (u, v) in the light's plane (= u, v unless sheared),
        # so that p.u and p.v span the region the intersection test accepts.
        o0 = pos[0] + x * du[0] + y * dv[0]
        o1 = pos[1] + x * du[1] + y * dv[1]
        o2 = pos[2] + x * du[2] + y * dv[2]
        if not aimed:
            u3 = emit_uniform(key, s, 2)
            u4 = emit_uniform(key, s, 3)
            if narrow:
                a, b = concentric_disk(u3, u4)
                a, b = a * sin_h, b * sin_h
                c = math.sqrt(max(1.0 - a * a - b * b, 0.0))
                w = spread_factor(spread_on, tan_h, norm, c) * sin_h * sin_h
            else:
                a, b, c = cosine_hemisphere(u3, u4)
                w = 1.0
            d0, d1, d2 = to_world(a, b, c, axis[0], axis[1], axis[2])
        else:
            d0, d1, d2, pdf_aim = area_aim_direction(centers, radii, probs, cdf, axis, narrow,
                                                     sin_h, o0, o1, o2, emit_uniform(key, s, 0),
                                                     emit_uniform(key, s, 3),
                                                     emit_uniform(key, s, 4))
            cos = d0 * axis[0] + d1 * axis[1] + d2 * axis[2]
            w = max(cos, 0.0) / math.pi * spread_factor(spread_on, tan_h, norm, cos) / pdf_aim
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, f0 * w, f1 * w, f2 * w, s)
    return j


# Directions of a fixed 16 x 16 stratified grid over a unit cone (cos from 1 to cos_max),
# for the aim weights' quadrature.
_AIM_GRID = (np.arange(16) + 0.5) / 16.0


def area_aim_weights(centers, radii, pos, axis, spread) -> Aim:
    """Aim of a one-sided area light (centre pos (3,), unit axis (3,), spread in radians)
    at spheres (centers (K,3), radii (K,)): each chosen in proportion to the natural
    power its centre sends into it, the integral of cos+(a) f(a) over the sphere's cone of
    directions (f: the spread's attenuation), by a 256-point quadrature over the cone (a
    light inside a sphere: its whole front hemisphere, pi). Zero for a sphere wholly
    behind the emitting side (or outside the spread), which no photon of the light
    reaches; solid-angle weights (emission.aim_weights) if every sphere gets zero."""
    centers = np.asarray(centers, np.float64).reshape(-1, 3)
    radii = np.asarray(radii, np.float64)
    axis = np.asarray(axis, np.float64)
    u1, u2 = np.meshgrid(_AIM_GRID, _AIM_GRID)
    u1, u2 = u1.ravel(), u2.ravel()
    w = np.zeros(len(radii))
    for k in range(len(radii)):
        t = centers[k] - pos
        dist = float(np.linalg.norm(t))
        if dist <= radii[k]:
            w[k] = math.pi * float(np.mean(spread_attenuation(np.sqrt(1.0 - u1), spread)))
            continue
        if float(t @ axis) + radii[k] <= 0.0:
            continue  # wholly behind the light's plane
        cos_max = math.sqrt(max(0.0, 1.0 - (radii[k] / dist) ** 2))
        z = 1.0 - u1 * (1.0 - cos_max)
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        n = t / dist
        # the cone's directions in an orthonormal frame round n
        a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        b1 = np.cross(n, a)
        b1 /= np.linalg.norm(b1)
        b2 = np.cross(n, b1)
        phi = 2.0 * math.pi * u2
        cos = (r * np.cos(phi)) * (b1 @ axis) + (r * np.sin(phi)) * (b2 @ axis) + z * (n @ axis)
        g = np.maximum(cos, 0.0) * spread_attenuation(cos, spread)
        w[k] = 2.0 * math.pi * (1.0 - cos_max) * float(np.mean(g))
    if not w.sum() > 0:
        return aim_weights(centers, radii, pos)
    return Aim(centers, radii, w / w.sum())


@kernel
def _natural_pdf(narrow, sin_h, cos):
    """pdf (1/sr) of emit_area's natural direction at cosine `cos` to the axis."""
    if cos <= 0.0:
        return 0.0
    if narrow:
        if 1.0 - cos * cos > sin_h * sin_h:
            return 0.0
        return cos / (math.pi * sin_h * sin_h)
    return cos / math.pi


@kernel
def area_aim_direction(centers, radii, probs, cdf, axis, narrow, sin_h, o0, o1, o2, us, u1, u2):
    """A direction from o (a point of the light) aimed at one of the spheres (chosen by us
    from cdf), and its aimed pdf (1/sr): the mixture over the spheres, sphere k adding
    probs[k] x its own pdf. Outside sphere k: uniform in its cone (u1, u2), as
    emission.aim_direction. From inside it every direction the light emits meets it, so
    its directions are the natural ones (cosine-distributed, inside the spread): half of
    a whole sphere's directions lay behind the one-sided emitter and carried nothing."""
    j = pick(cdf, us)
    cos_max, dist, t0, t1, t2 = _cone_cos(centers[j, 0], centers[j, 1], centers[j, 2],
                                          radii[j], o0, o1, o2)
    if cos_max < 0.0:
        if narrow:
            a, b = concentric_disk(u1, u2)
            a, b = a * sin_h, b * sin_h
            c = math.sqrt(max(1.0 - a * a - b * b, 0.0))
        else:
            a, b, c = cosine_hemisphere(u1, u2)
        d0, d1, d2 = to_world(a, b, c, axis[0], axis[1], axis[2])
    else:
        ds = max(dist, 1e-300)
        l0, l1, l2 = uniform_cone(u1, u2, cos_max)
        d0, d1, d2 = to_world(l0, l1, l2, t0 / ds, t1 / ds, t2 / ds)
    aimed = 0.0
    for k in range(centers.shape[0]):
        if _misses(centers, radii, k, o0, o1, o2, d0, d1, d2):
            continue  # outside sphere k (ck >= 0) and its cone: nothing added
        ck, dk, k0, k1, k2 = _cone_cos(centers[k, 0], centers[k, 1], centers[k, 2], radii[k],
                                       o0, o1, o2)
        if ck < 0.0:
            cos = d0 * axis[0] + d1 * axis[1] + d2 * axis[2]
            aimed += probs[k] * _natural_pdf(narrow, sin_h, cos)
        elif d0 * k0 + d1 * k1 + d2 * k2 >= ck * dk:
            aimed += probs[k] / (TWO_PI * (1.0 - ck))
    return d0, d1, d2, max(aimed, 1e-300)


# Shadow rays sample a rectangle uniformly in the solid angle it subtends (Urena, Fajardo
# and King 2013, "An Area-Preserving Parametrization for Spherical Rectangles"; pbrt-v4's
# SampleSphericalRectangle; Cycles' area.h), not at a uniform point of its area: a point
# 5 cm from a 1 x 1.2 m light had a relative s.d. of 7.1 a sample by area, 0.49 by solid
# angle (bench/bench_rect_light_sampling.py). Below this solid angle (sr) the light is
# small, area sampling is as good, and the parametrization's angles lose precision
# (pbrt-v4's MinSphericalSampleArea).
MIN_SPHERICAL_SOLID_ANGLE = 3e-4
ONE_BELOW_RECT = 1.0 - 2.0 ** -53  # keeps cu's square root off 0


@kernel
def _unit_cross(a0, a1, a2, b0, b1, b2):
    c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    n = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    n = n if n > 0.0 else 1.0
    return c0 / n, c1 / n, c2 / n


@kernel
def _angle_between(a0, a1, a2, b0, b1, b2):
    """The angle between unit vectors a and b, stable near 0 and pi (pbrt-v4's
    AngleBetween)."""
    if a0 * b0 + a1 * b1 + a2 * b2 < 0.0:
        s = math.sqrt((a0 + b0) ** 2 + (a1 + b1) ** 2 + (a2 + b2) ** 2) / 2.0
        return math.pi - 2.0 * math.asin(min(s, 1.0))
    s = math.sqrt((b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2) / 2.0
    return 2.0 * math.asin(min(s, 1.0))


@kernel
def spherical_rectangle(p0, p1, p2, s0, s1, s2, ex0, ex1, ex2, ey0, ey1, ey2, u1, u2,
                        sample):
    """The solid angle (sr) that the rectangle s + [0,1] ex + [0,1] ey (ex, ey
    orthogonal) subtends at p and, when sample, the point (y0, y1, y2) of it whose
    direction from p is uniform in that solid angle for u1, u2 in [0, 1) (pbrt-v4's
    SampleSphericalRectangle, Urena et al. 2013). Returns (omega, y0, y1, y2); omega 0
    where it is not defined (p in the rectangle's plane, a degenerate or sheared
    parallelogram): the caller samples the area instead."""
    exl = math.sqrt(ex0 * ex0 + ex1 * ex1 + ex2 * ex2)
    eyl = math.sqrt(ey0 * ey0 + ey1 * ey1 + ey2 * ey2)
    if not (exl > 0.0 and eyl > 0.0):
        return 0.0, s0, s1, s2
    rx0, rx1, rx2 = ex0 / exl, ex1 / exl, ex2 / exl
    ry0, ry1, ry2 = ey0 / eyl, ey1 / eyl, ey2 / eyl
    if abs(rx0 * ry0 + rx1 * ry1 + rx2 * ry2) > 1e-9:
        return 0.0, s0, s1, s2
    rz0, rz1, rz2 = rx1 * ry2 - rx2 * ry1, rx2 * ry0 - rx0 * ry2, rx0 * ry1 - rx1 * ry0
    d0, d1, d2 = s0 - p0, s1 - p1, s2 - p2
    x0 = d0 * rx0 + d1 * rx1 + d2 * rx2
    y0 = d0 * ry0 + d1 * ry1 + d2 * ry2
    z0 = d0 * rz0 + d1 * rz1 + d2 * rz2
    if z0 > 0.0:  # z towards p's side: the rectangle at z0 < 0
        rz0, rz1, rz2, z0 = -rz0, -rz1, -rz2, -z0
    if not z0 < -1e-12 * max(exl, eyl):
        return 0.0, s0, s1, s2
    x1, y1 = x0 + exl, y0 + eyl
    # The normals of the planes through p and each edge, and the internal angles.
    n00, n01, n02 = _unit_cross(x0, y0, z0, x1, y0, z0)
    n10, n11, n12 = _unit_cross(x1, y0, z0, x1, y1, z0)
    n20, n21, n22 = _unit_cross(x1, y1, z0, x0, y1, z0)
    n30, n31, n32 = _unit_cross(x0, y1, z0, x0, y0, z0)
    g0 = _angle_between(-n00, -n01, -n02, n10, n11, n12)
    g1 = _angle_between(-n10, -n11, -n12, n20, n21, n22)
    g2 = _angle_between(-n20, -n21, -n22, n30, n31, n32)
    g3 = _angle_between(-n30, -n31, -n32, n00, n01, n02)
    omega = g0 + g1 + g2 + g3 - 2.0 * math.pi
    if not (omega > 0.0 and omega < 2.0 * math.pi):
        return 0.0, s0, s1, s2
    if not sample:
        return omega, s0, s1, s2
    b0, b1 = n02, n22
    au = u1 * (g0 + g1 - 2.0 * math.pi) + (u1 - 1.0) * (g2 + g3)
    sin_au = math.sin(au)
    if sin_au == 0.0:
        return 0.0, s0, s1, s2
    fu = (math.cos(au) * b0 - b1) / sin_au
    cu = 1.0 / math.sqrt(fu * fu + b0 * b0)
    cu = min(max(math.copysign(cu, fu), -ONE_BELOW_RECT), ONE_BELOW_RECT)
    xu = -(cu * z0) / math.sqrt(max(1.0 - cu * cu, 1e-300))
    xu = min(max(xu, x0), x1)
    dd = math.sqrt(xu * xu + z0 * z0)
    h0 = y0 / math.sqrt(dd * dd + y0 * y0)
    h1 = y1 / math.sqrt(dd * dd + y1 * y1)
    hv = h0 + u2 * (h1 - h0)
    hv2 = hv * hv
    yv = hv * dd / math.sqrt(1.0 - hv2) if hv2 < 1.0 - 1e-12 else y1
    yv = min(max(yv, y0), y1)
    return (omega, p0 + xu * rx0 + yv * ry0 + z0 * rz0, p1 + xu * rx1 + yv * ry1 + z0 * rz1,
            p2 + xu * rx2 + yv * ry2 + z0 * rz2)



@kernel
def rect_solid_angles(o, s, ex, ey, out):
    """out (N,) = spherical_rectangle's solid angle (sr, 0 where undefined) of the
    rectangle s + [0,1] ex + [0,1] ey (3,) each at the points o (N,3): the light pdf of a
    continuation that met it (integrator.mis_light_pdf)."""
    for i in range(o.shape[0]):
        out[i] = spherical_rectangle(o[i, 0], o[i, 1], o[i, 2], s[0], s[1], s[2], ex[0],
                                     ex[1], ex[2], ey[0], ey[1], ey[2], 0.5, 0.5, False)[0]
