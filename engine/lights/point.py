"""Point light (Blender's Point, optionally with a radius): intensity P/(4 pi) W/sr;
with a radius it is a disk of that radius through its centre facing the shading point,
both for shadow rays and for rays that meet it (Cycles' point light with Soft Falloff, its
default: kernel/light/point.h)."""
from __future__ import annotations

import math

import numpy as np

from ..sampling import cosine_hemisphere, dot, to_world, uniform_sphere
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

    def _emit(self, n, rng, u1, u2, u3, u4):
        if self.radius > 0:
            s = uniform_sphere(u1, u2)
            o = self.pos + self.radius * s
            d = to_world(cosine_hemisphere(u3, u4), s)
        else:
            o = np.broadcast_to(self.pos, (n, 3)).copy()
            d = uniform_sphere(u1, u2)
        return o, d, np.broadcast_to(self.flux / n, (n, 3)).copy()

    def _aim_origins(self, n, rng, u1, u2):
        if self.radius > 0:
            normal = uniform_sphere(u1, u2)
            return self.pos + self.radius * normal, normal, self.pos, None
        return np.broadcast_to(self.pos, (n, 3)).copy(), None, self.pos, None

    def _aimed_photons(self, n, rng, o, d, normal, state, aimed):
        if normal is not None:  # a radius: cosine-distributed from the sphere's surface
            pdf_nat = np.maximum(dot(d, normal), 0.0) / math.pi
        else:
            pdf_nat = np.full(n, 1.0 / (4.0 * math.pi))
        return o, d, (self.flux / n)[None, :] * (pdf_nat / aimed)[:, None]

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
