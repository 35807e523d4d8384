"""Point light (Blender's Point, optionally with a radius): intensity P/(4 pi) W/sr;
with a radius it is a disk of that radius through its centre facing the shading point,
both for shadow rays and for rays that meet it (Cycles' point light with Soft Falloff, its
default: kernel/light/point.h)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
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
        kw.update(intensity=intensity, flux=light.flux, photon_flux=light.flux)
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
        return pk.CODE_POINT

    def _falloff(self, axis):
        """Directional factor of the emitted intensity along unit directions axis (N,3)
        leaving the light; 1 for a point light."""
        return None

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        return emit_point(f64(self.pos), float(self.radius), f64(self.flux),
                          *aim.arrays, aimed, key, first, n, float(count), *out.arrays, start)

    def intersect(self, o, d, tmax):
        """A light with a radius is a disk of radius r through its centre facing the ray's
        origin, of radiance I / (pi r^2) (x the spot mask): the shape its shadow rays
        sample (directlight.sample_lights) and Cycles' point light with Soft Falloff (its
        default; kernel/light/point.h, point_light_intersect). A sphere met by the
        continuation had a rim of directions (relative width ~ r^2 / distance^2) that the
        disk's shadow rays never pick: those paths took the full light without multiple
        importance sampling, single-sample sparkles on glossy surfaces."""
        if self.radius <= 0:
            return super().intersect(o, d, tmax)
        n = len(o)
        axis = o - self.pos
        dist = np.linalg.norm(axis, axis=1)
        axis = axis / np.maximum(dist, 1e-300)[:, None]
        toward = -dot(d, axis)
        front = toward > 1e-12
        t = dist / np.where(front, toward, 1.0)
        on_disk = t[:, None] * d + o - self.pos
        mask = (front & (dist > 0) & (t < tmax)
                & (np.einsum("ij,ij->i", on_disk, on_disk) <= self.radius ** 2))
        t = np.where(front, t, np.inf)
        L = np.broadcast_to(self.intensity / (math.pi * self.radius ** 2), (n, 3))
        f = self._falloff(-d)
        if f is not None:
            L = L * f[:, None]
        return mask, t, L


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
