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
