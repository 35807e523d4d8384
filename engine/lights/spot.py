"""Spot light: a point light (optionally with a radius) masked by Cycles' smoothstep cone,
the cone stretched by the light object's scale (Light.cone_frame, engine/scene.py)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from .emission import f64, aim_direction, concentric_disk, emit_uniform, put, to_world, uniform_cone
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

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        cos_half = math.cos(self.spot_size / 2.0)
        return emit_spot(f64(self.pos), f64(self.dir), float(self.radius), f64(self.intensity),
                         f64(self.spot_frame), cos_half,
                         (1.0 - cos_half) * self.spot_blend, float(self.spot_cos_bound),
                         *aim.arrays, aimed, key, first, n, float(count), *out.arrays, start)

    def _aim_radii(self, radii):
        # A spot's photons leave from a disk round its centre, shifted after their
        # direction is drawn: aim at spheres grown by that radius, or the directions
        # that reach a caster only from the disk's rim are never drawn (caustic lost).
        return radii + self.radius if self.radius > 0 else radii


@kernel
def spot_mask_at(frame, cos_half, width, w0, w1, w2):
    """scene.spot_mask(spot_cone_cos(w, frame), ...) for one direction w leaving the light:
    Cycles' smoothstep of the cosine to the (scaled) cone's axis."""
    l0 = frame[0, 0] * w0 + frame[0, 1] * w1 + frame[0, 2] * w2
    l1 = frame[1, 0] * w0 + frame[1, 1] * w1 + frame[1, 2] * w2
    l2 = frame[2, 0] * w0 + frame[2, 1] * w1 + frame[2, 2] * w2
    x = l2 / max(math.sqrt(l0 * l0 + l1 * l1 + l2 * l2), 1e-300) - cos_half
    if width <= 0:
        return 1.0 if x > 0 else 0.0
    f = min(max(x / width, 0.0), 1.0)
    return f * f * (3.0 - 2.0 * f)


@kernel
def emit_spot(pos, axis, radius, intensity, frame, cos_half, width, cos_bound, centers, radii,
              probs, cdf, aimed, key, first, n, count, o32, d32, d, power, slot, start):
    """Photons of a spot light: directions uniform in the cone round `axis` of cosine
    cos_bound (holding the whole, possibly scaled, lit cone), power intensity x mask x the
    cone's solid angle / count; with a radius each leaves from a disk across its direction.
    aimed: directions aimed at the spheres (grown by the radius: SpotLight._aim_radii),
    power intensity x mask / (count x aimed pdf). Dimensions: 0, 1 the direction, 2, 3 the
    disk; aimed: 0 the target, 3, 4 the direction, 5, 6 the disk."""
    j = start
    solid = 2.0 * math.pi * (1.0 - cos_bound)
    for i in range(n):
        s = first + i
        if not aimed:
            l0, l1, l2 = uniform_cone(emit_uniform(key, s, 0), emit_uniform(key, s, 1), cos_bound)
            d0, d1, d2 = to_world(l0, l1, l2, axis[0], axis[1], axis[2])
            w = solid / count
            k = 2
        else:
            d0, d1, d2, pdf_aim = aim_direction(centers, radii, probs, cdf, pos[0], pos[1], pos[2],
                                                emit_uniform(key, s, 0), emit_uniform(key, s, 3),
                                                emit_uniform(key, s, 4))
            w = 1.0 / (count * pdf_aim)
            k = 5
        w *= spot_mask_at(frame, cos_half, width, d0, d1, d2)
        o0, o1, o2 = pos[0], pos[1], pos[2]
        if radius > 0:
            x, y = concentric_disk(emit_uniform(key, s, k), emit_uniform(key, s, k + 1))
            t0, t1, t2 = to_world(x, y, 0.0, d0, d1, d2)
            o0, o1, o2 = o0 + radius * t0, o1 + radius * t1, o2 + radius * t2
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, intensity[0] * w,
                intensity[1] * w, intensity[2] * w, s)
    return j
