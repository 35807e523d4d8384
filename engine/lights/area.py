"""Area light: a rectangle or ellipse emitting one-sided uniform radiance P/(pi A) along
its -Z axis (the light's `dir`), optionally narrowed by Blender's spread (Cycles'
kernel/light/area.h); a sheared object transform keeps a parallelogram."""
from __future__ import annotations

import math

import numpy as np

from ..sampling import concentric_disk, cosine_hemisphere, dot, to_world
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

    def points(self, u1, u2):
        """Uniform points on the rectangle or ellipse."""
        if self.shape == DISK:
            x, yy = concentric_disk(u1, u2)
            x, yy = x * self.size_x / 2, yy * self.size_y / 2
        else:
            x, yy = (u1 - 0.5) * self.size_x, (u2 - 0.5) * self.size_y
        # du, dv: the dual basis of (u, v) in the light's plane (= u, v unless sheared),
        # so that p.u and p.v span the region the intersection test accepts.
        return self.pos + x[:, None] * self.du + yy[:, None] * self.dv

    def _emit(self, n, rng, u1, u2, u3, u4):
        o = self.points(u1, u2)
        if self.spread < math.pi:
            # Cosine-distributed inside the spread cone (a disk of radius sin h under
            # the hemisphere): pdf cos a / (pi sin^2 h); the radiance's cos a f(a) / pi
            # over that pdf leaves the weight f(a) sin^2 h (mean 1: flux kept).
            sin_h = math.sin(0.5 * self.spread)
            x, yy = concentric_disk(u3, u4)
            x, yy = x * sin_h, yy * sin_h
            local = np.stack([x, yy, np.sqrt(np.maximum(1.0 - x * x - yy * yy, 0.0))], 1)
            d = to_world(local, np.broadcast_to(self.dir, (n, 3)))
            w = spread_attenuation(local[:, 2], self.spread) * sin_h * sin_h
            return o, d, (self.flux / n)[None, :] * w[:, None]
        d = to_world(cosine_hemisphere(u3, u4), np.broadcast_to(self.dir, (n, 3)))
        return o, d, np.broadcast_to(self.flux / n, (n, 3)).copy()

    def _aim_origins(self, n, rng, u1, u2):
        return self.points(u1, u2), None, self.pos, None

    def _aimed_photons(self, n, rng, o, d, normal, state, aimed):
        cos = dot(d, self.dir)
        pdf_nat = np.maximum(cos, 0.0) / math.pi * spread_attenuation(cos, self.spread)
        return o, d, (self.flux / n)[None, :] * (pdf_nat / aimed)[:, None]

    def intersect(self, o, d, tmax):
        """One-sided: a ray must travel against the emission to see the light."""
        n = len(o)
        denom = dot(d, self.dir)
        facing = denom < -1e-12
        t = np.where(facing, dot(self.pos - o, self.dir) / np.where(facing, denom, -1.0), np.inf)
        hitp = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - self.pos
        x, y = dot(hitp, self.u) / (self.size_x / 2), dot(hitp, self.v) / (self.size_y / 2)
        inside = (x * x + y * y <= 1.0) if self.shape == DISK else ((np.abs(x) <= 1) & (np.abs(y) <= 1))
        mask = facing & inside & (t > 0) & (t < tmax)
        L = np.broadcast_to(self.radiance, (n, 3))
        if self.spread < math.pi:
            L = L * spread_attenuation(-denom, self.spread)[:, None]
        return mask, t, L
