"""Sun: irradiance `strength` W/m^2 from a disk of angular diameter `angle` (Cycles'
kernel/light/distant.h); radiance strength / (pi sin^2(angle/2)) seen in the disk."""
from __future__ import annotations

import math

import numpy as np

from ..sampling import dot, to_world, uniform_cone
from ..scene import SUN
from . import packing as pk
from .base import InfiniteLight


class SunLight(InfiniteLight):
    kind = SUN

    @classmethod
    def from_scene(cls, light, geo, common):
        kw = cls.scene_params(light, geo, common)
        rgb = light.power * light.color
        radius = common["scene_radius"]
        half = light.angle / 2.0
        cos_half = math.cos(half)
        solid = 2.0 * math.pi * (1.0 - cos_half)
        kw.update(irradiance=rgb, cos_half_angle=cos_half,
                  sun_radiance=rgb / max(math.pi * math.sin(half) ** 2, 1e-300) if half > 0 else rgb,
                  photon_flux=rgb * math.pi * radius ** 2, solid_angle=solid)
        return cls(light.name, **kw)

    @property
    def has_size(self) -> bool:
        return self.cos_half_angle < 1.0

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code."""
        row[pk.DIR:pk.DIR + 3] = self.dir
        row[pk.RGB:pk.RGB + 3] = self.irradiance
        row[pk.COS_HALF] = self.cos_half_angle
        return pk.CODE_SUN

    def _directions(self, n, u1, u2):
        return to_world(uniform_cone(u1, u2, self.cos_half_angle), np.broadcast_to(self.dir, (n, 3)))

    def seen_at_infinity(self, d):
        """Radiance of the sun disk (angle > 0) along escaping directions d (N,3)."""
        if self.cos_half_angle >= 1.0:
            return None
        inside = dot(d, -self.dir) >= self.cos_half_angle
        return inside[:, None] * self.sun_radiance[None, :]
