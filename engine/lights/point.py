"""Point light (Blender's Point, optionally with a radius): intensity P/(4 pi) W/sr.

With a radius r its radiance is I / (pi r^2) (Cycles' eval_fac x strength) on one of two
shapes, as Blender's "Soft Falloff" (Light.soft_falloff) picks (Cycles'
kernel/light/point.h; `is_sphere` = not use_soft_falloff):
- Soft Falloff on (Blender's default): a disk of radius r through the centre facing the
  shading point, both for shadow rays and for rays that meet it. A point at distance d
  receives I / (d^2 + r^2) face-on: the light fades where it nearly touches a surface.
- Soft Falloff off: a sphere of radius r. Shadow rays sample the cone of directions it
  subtends uniformly (pdf 1 / (2 pi (1 - cos a)), sin a = r / d), rays meet the sphere;
  a point receives I / d^2 face-on, as from a point, however close (from inside the
  sphere: cosine-distributed directions, pi L).
Photons leave the sphere's surface cosine-distributed in both cases; with Soft Falloff
their power at the first hit takes d^2 / (d^2 + r^2), so that they too give I / (d^2 +
r^2) (engine/photons.py soft_falloff_sources: the two differ within a few radii of the
light, which is where a lamp shade lies: 1.19x Cycles without it)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from ..sampling import dot
from .emission import (cosine_hemisphere, f64, emit_uniform, put, to_world, aim_direction,
                       uniform_sphere)
from ..scene import POINT
from . import packing as pk
from .base import Light


class PointLight(Light):
    kind = POINT

    @classmethod
    def from_scene(cls, light, geo, common):
        kw = cls.scene_params(light, geo, common)
        kw.update(cls.extra_params(light))
        intensity = light.power * light.color / (4.0 * math.pi)
        kw.update(intensity=intensity, flux=light.flux, photon_flux=light.flux,
                  soft_falloff=bool(light.soft_falloff))
        return cls(light.name, **kw)

    @staticmethod
    def extra_params(light) -> dict:
        return {}

    @property
    def has_size(self) -> bool:
        return self.radius > 0

    @property
    def has_surface(self) -> bool:
        return self.radius > 0

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code."""
        row[pk.POS:pk.POS + 3] = self.pos
        row[pk.RGB:pk.RGB + 3] = self.intensity
        row[pk.RADIUS] = self.radius
        row[pk.SPHERE] = 1.0 if self.is_sphere else 0.0
        return pk.CODE_POINT

    @property
    def is_sphere(self) -> bool:
        """True: a sphere of the light's radius (Soft Falloff off), not the facing disk."""
        return self.radius > 0 and not getattr(self, "soft_falloff", True)

    def _falloff(self, axis):
        """Directional factor of the emitted intensity along unit directions axis (N,3)
        leaving the light; 1 for a point light."""
        return None

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        return emit_point(f64(self.pos), float(self.radius), f64(self.flux),
                          *aim.arrays, aimed, key, first, n, float(count), *out.arrays, start)

    def intersect(self, o, d, tmax):
        """A light with a radius, met by rays (o, d (N,3), tmax (N,)): (mask, t, radiance
        I / (pi r^2) x the spot mask). With Soft Falloff it is a disk of radius r through
        its centre facing the ray's origin: the shape its shadow rays sample
        (directlight.sample_lights) and Cycles' point_light_intersect. (A sphere met by
        the continuation had a rim of directions, relative width ~ r^2 / distance^2, that
        the disk's shadow rays never pick: those paths took the full light without
        multiple importance sampling, single-sample sparkles on glossy surfaces.) Without
        it, the sphere (ray_sphere_intersect); a spot's mask is then read along the ray,
        and only from outside the sphere (Cycles' spot_light_sample_from_intersection)."""
        if self.radius <= 0:
            return super().intersect(o, d, tmax)
        n = len(o)
        if self.is_sphere:
            rel = o - self.pos
            t = sphere_hit(rel, d, self.radius)
            mask = t < tmax
            inside = np.einsum("ij,ij->i", rel, rel) <= self.radius ** 2
        else:
            # One compiled pass (intersect_disk), the numpy stage's arithmetic.
            tm = f64(np.broadcast_to(np.asarray(tmax, np.float64), (n,)))
            mask, t = np.empty(n, np.bool_), np.empty(n)
            intersect_disk(f64(o), f64(d), tm, f64(self.pos), float(self.radius ** 2), mask, t)
            inside = np.zeros(n, bool)
        L = np.broadcast_to(self.intensity / (math.pi * self.radius ** 2), (n, 3))
        f = self._falloff(-d)
        if f is not None:
            L = L * np.where(inside, 1.0, f)[:, None]
        return mask, t, L


@kernel
def intersect_disk(o, d, tmax, pos, radius2, mask, t):
    """PointLight.intersect with Soft Falloff for rays o, d (N,3) up to tmax (N,): the
    disk of squared radius radius2 through pos facing each ray's origin. Writes mask (N,)
    (the ray meets the disk before tmax) and t (N,) (the distance to the disk's plane
    along the ray, inf where the ray does not travel towards the centre). The numpy
    stage's arithmetic operation for operation (np.linalg.norm sums x^2 + y^2 then + z^2,
    np.einsum's dot products (x + z) + y; np.maximum keeps a NaN), so the same bits
    (tests/test_soft_falloff.py)."""
    for i in range(o.shape[0]):
        r0, r1, r2 = o[i, 0] - pos[0], o[i, 1] - pos[1], o[i, 2] - pos[2]
        dist = math.sqrt((r0 * r0 + r1 * r1) + r2 * r2)
        ds = 1e-300 if dist < 1e-300 else dist
        a0, a1, a2 = r0 / ds, r1 / ds, r2 / ds
        d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
        toward = -((d0 * a0 + d2 * a2) + d1 * a1)
        front = toward > 1e-12
        ti = dist / (toward if front else 1.0)
        h0, h1, h2 = ti * d0 + r0, ti * d1 + r1, ti * d2 + r2
        mask[i] = (front and dist > 0 and ti < tmax[i]
                   and (h0 * h0 + h2 * h2) + h1 * h1 <= radius2)
        t[i] = ti if front else np.inf


@register_warm_up
def _warm_up():
    one = np.ones((1, 3))
    intersect_disk(one, -one, np.ones(1), np.zeros(3), 0.25, np.empty(1, np.bool_),
                   np.empty(1))


def sphere_light_pdf(light, o, d, ns):
    """Solid-angle pdf (N,) of a sphere light's shadow rays (directlight's
    _sphere_light_sample) for directions d (N,3) from points o (N,3): uniform over the
    cone the sphere subtends from outside (1 / (2 pi (1 - cos a))), cos / pi round the
    shading normals ns (N,3) from inside (Cycles' sphere_light_pdf). Directions that miss
    the sphere get the cone's pdf too: callers ask only for rays that met it."""
    rel = o - light.pos
    x = light.radius ** 2 / np.maximum(np.einsum("ij,ij->i", rel, rel), 1e-300)
    outside = x < 1.0
    xo = np.minimum(x, 1.0)
    one_minus_cos = xo / (1.0 + np.sqrt(1.0 - xo))
    cone = 1.0 / (2.0 * math.pi * np.maximum(one_minus_cos, 1e-300))
    if ns is None:
        return cone
    return np.where(outside, cone, np.maximum(dot(d, ns), 0.0) / math.pi)


def sphere_hit(rel, d, radius):
    """Distance (N,) along unit directions d (N,3) from points rel (N,3, relative to a
    sphere's centre) to the sphere of `radius` (the far side from inside), inf where the
    ray misses it or it lies behind."""
    b = dot(rel, d)
    c = np.einsum("ij,ij->i", rel, rel) - radius * radius
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    near, far = -b - root, -b + root
    t = np.where(near > 0, near, far)
    return np.where((disc >= 0) & (t > 0), t, np.inf)


@kernel
def emit_point(pos, radius, flux, centers, radii, probs, cdf, aimed, key, first, n, count,
               o32, d32, d, power, slot, start):
    """Photons of a point light of flux `flux` (3,) W, radius `radius` (a sphere emitting
    cosine-distributed from its surface: each point's radiance is the same): uniform over
    the sphere of directions without radius. aimed: directions aimed at the spheres
    (centers, radii; emission.aim_direction), weighted by natural pdf / aimed pdf.
    Dimensions: 0, 1 the point on the sphere (or the direction), 2, 3 the direction;
    aimed: 0 the target, 1, 2 the point, 3, 4 the direction."""
    j = start
    f0, f1, f2 = flux[0] / count, flux[1] / count, flux[2] / count
    for i in range(n):
        s = first + i
        o0, o1, o2 = pos[0], pos[1], pos[2]
        a0 = a1 = a2 = 0.0
        w = 1.0
        if not aimed:
            a0, a1, a2 = uniform_sphere(emit_uniform(key, s, 0), emit_uniform(key, s, 1))
            if radius > 0:
                o0, o1, o2 = pos[0] + radius * a0, pos[1] + radius * a1, pos[2] + radius * a2
                l0, l1, l2 = cosine_hemisphere(emit_uniform(key, s, 2), emit_uniform(key, s, 3))
                d0, d1, d2 = to_world(l0, l1, l2, a0, a1, a2)
            else:
                d0, d1, d2 = a0, a1, a2
        else:
            if radius > 0:
                a0, a1, a2 = uniform_sphere(emit_uniform(key, s, 1), emit_uniform(key, s, 2))
                o0, o1, o2 = pos[0] + radius * a0, pos[1] + radius * a1, pos[2] + radius * a2
            d0, d1, d2, pdf_aim = aim_direction(centers, radii, probs, cdf, o0, o1, o2,
                                                emit_uniform(key, s, 0), emit_uniform(key, s, 3),
                                                emit_uniform(key, s, 4))
            if radius > 0:
                pdf_nat = max(d0 * a0 + d1 * a1 + d2 * a2, 0.0) / math.pi
            else:
                pdf_nat = 1.0 / (4.0 * math.pi)
            w = pdf_nat / pdf_aim
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, f0 * w, f1 * w, f2 * w, s)
    return j
