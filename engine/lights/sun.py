"""Sun: irradiance `strength` W/m^2 from a disk of angular diameter `angle` (Cycles'
kernel/light/distant.h); radiance strength / (pi sin^2(angle/2)) seen in the disk."""
from __future__ import annotations

import math

from ..jit import kernel
from ..sampling import dot
from .emission import f64, aim_origin, disk_origin, emit_uniform, put, to_world, uniform_cone
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

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        return emit_sun(f64(self.dir), float(self.cos_half_angle), f64(self.photon_flux),
                        f64(self.center),
                        float(self.scene_radius), *aim.arrays, aimed, key, first, n,
                        float(count), *out.arrays, start)

    def seen_at_infinity(self, d):
        """Radiance of the sun disk (angle > 0) along escaping directions d (N,3)."""
        if self.cos_half_angle >= 1.0:
            return None
        inside = dot(d, -self.dir) >= self.cos_half_angle
        return inside[:, None] * self.sun_radiance[None, :]


@kernel
def emit_sun(axis, cos_half, flux, center, R, centers, radii, probs, cdf, aimed, key, first,
             n, count, o32, d32, d, power, slot, start):
    """Photons of a sun: directions uniform in its disk's cone (cosine cos_half) round
    `axis`, each flux / count (flux: the irradiance through the natural disk of radius R),
    from the natural disk (emission.disk_origin) or, aimed, a caster's shadow disk
    (emission.aim_origin). Dimensions: 0, 1 the direction, 2, 3 the origin; aimed: 2 the
    target, 3, 4 the origin."""
    j = start
    f0, f1, f2 = flux[0] / count, flux[1] / count, flux[2] / count
    for i in range(n):
        s = first + i
        l0, l1, l2 = uniform_cone(emit_uniform(key, s, 0), emit_uniform(key, s, 1), cos_half)
        d0, d1, d2 = to_world(l0, l1, l2, axis[0], axis[1], axis[2])
        w = 1.0
        if not aimed:
            o0, o1, o2 = disk_origin(center, R, d0, d1, d2, emit_uniform(key, s, 2),
                                     emit_uniform(key, s, 3))
        else:
            o0, o1, o2, w = aim_origin(center, R, centers, radii, probs, cdf, d0, d1, d2,
                                       emit_uniform(key, s, 2), emit_uniform(key, s, 3),
                                       emit_uniform(key, s, 4))
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, f0 * w, f1 * w, f2 * w, s)
    return j
