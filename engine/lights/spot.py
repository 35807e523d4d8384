"""Spot light: a point light (optionally with a radius) masked by Cycles' smoothstep cone,
the cone stretched by the light object's scale (Light.cone_frame, engine/scene.py)."""
from __future__ import annotations

import math

import numpy as np

from ..sampling import concentric_disk, orthonormal_basis, to_world, uniform_cone
from ..scene import SPOT, spot_bounding_cos, spot_cone_cos, spot_mask
from . import packing as pk
from .point import PointLight


class SpotLight(PointLight):
    kind = SPOT

    @staticmethod
    def extra_params(light) -> dict:
        frame = light.cone_frame
        return dict(spot_frame=frame,
                    spot_cos_bound=spot_bounding_cos(light.spot_size, frame, light.direction))

    def _spot(self, w):
        """Spot mask for world directions w (N,3) leaving the light."""
        return spot_mask(spot_cone_cos(w, self.spot_frame), self.spot_size, self.spot_blend)

    def pack(self, row) -> int:
        super().pack(row)
        cos_half = math.cos(self.spot_size / 2.0)
        row[pk.SPOT_COS_HALF] = cos_half
        row[pk.SPOT_WIDTH] = (1.0 - cos_half) * self.spot_blend
        row[pk.SPOT_FRAME:pk.SPOT_FRAME + 9] = np.asarray(self.spot_frame, np.float64).ravel()
        return pk.CODE_SPOT

    def _falloff(self, axis):
        return self._spot(axis)

    def _emit(self, n, rng, u1, u2, u3, u4):
        cos_bound = self.spot_cos_bound  # holds the whole (scaled) cone
        local = uniform_cone(u1, u2, cos_bound)
        d = to_world(local, np.broadcast_to(self.dir, (n, 3)))
        solid = 2.0 * math.pi * (1.0 - cos_bound)
        mask = self._spot(d)
        power = self.intensity[None, :] * (mask * solid / n)[:, None]
        o = np.broadcast_to(self.pos, (n, 3)).copy()
        if self.radius > 0:
            x, yy = concentric_disk(u3, u4)
            t, b = orthonormal_basis(d)
            o = o + self.radius * (x[:, None] * t + yy[:, None] * b)
        return o, d, power

    def _aim_radii(self, radii):
        # A spot's photons leave from a disk round its centre, shifted after their
        # direction is drawn: aim at spheres grown by that radius, or the directions
        # that reach a caster only from the disk's rim are never drawn (caustic lost).
        return radii + self.radius if self.radius > 0 else radii

    def _aim_origins(self, n, rng, u1, u2):
        return np.broadcast_to(self.pos, (n, 3)).copy(), None, self.pos, None

    def _aimed_photons(self, n, rng, o, d, normal, state, aimed):
        mask = self._spot(d)
        if self.radius > 0:
            x, yy = concentric_disk(rng.random(n), rng.random(n))
            t, b = orthonormal_basis(d)
            o = o + self.radius * (x[:, None] * t + yy[:, None] * b)
        return o, d, self.intensity[None, :] * (mask / (n * aimed))[:, None]
