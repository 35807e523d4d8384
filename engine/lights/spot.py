"""Spot light: a point light (optionally with a radius) masked by Cycles' smoothstep cone,
the cone stretched by the light object's scale (Light.cone_frame, engine/scene.py)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from .emission import (TWO_PI, Aim, f64, _cone_cos, concentric_disk, emit_uniform, pick, put,
                       to_world, uniform_cone)
from ..scene import SPOT, spot_bounding_cos, spot_cone_cos, spot_mask
from . import packing as pk
from .point import PointLight, spot_mask_at


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

    def _falloff_plain(self, axis):
        return self._spot(axis)

    def _spot_params(self):
        cos_half = math.cos(self.spot_size / 2.0)
        return f64(self.spot_frame), cos_half, (1.0 - cos_half) * self.spot_blend

    def _emit_plain(self, aim, aimed, key, first, n, count, out, start):
        cos_half = math.cos(self.spot_size / 2.0)
        return emit_spot(f64(self.pos), f64(self.dir), float(self.radius), f64(self.intensity),
                         f64(self.spot_frame), cos_half,
                         (1.0 - cos_half) * self.spot_blend, float(self.spot_cos_bound),
                         *aim.arrays, aimed, key, first, n, float(count), *out.arrays, start)

    def aim(self, centers, radii) -> Aim:
        """Aim at the casters' bounding spheres (grown by the radius: _aim_radii) where
        they lie inside the spot's cone: spot_aim (a sphere's cone or the spot's, the
        narrower; a sphere wholly outside the spot's cone is never aimed at)."""
        return spot_aim(centers, self._aim_radii(radii), self.pos, self.dir,
                        float(self.spot_cos_bound))

    def _aim_radii(self, radii):
        # A spot's photons leave from a disk round its centre, shifted after their
        # direction is drawn: aim at spheres grown by that radius, or the directions
        # that reach a caster only from the disk's rim are never drawn (caustic lost).
        return radii + self.radius if self.radius > 0 else radii


def spot_aim(centers, radii, pos, axis, cos_bound) -> Aim:
    """Aim of a spot at spheres (centers (K,3), radii (K,)) from its centre pos along
    axis, whose light stays in the cone of cosine cos_bound round it. Each sphere's
    directions are drawn uniformly in the narrower of two cones (spot_aim_direction): the
    cone the sphere subtends, or the spot's, whose directions outside the sphere reach
    no caster (and those of the sphere outside the spot carry no power). The sphere is
    chosen in proportion to that cone's solid angle, never when the two cones do not
    overlap (its directions would all carry no power). All zero: the Aim emits nothing.
    (A spot under a mirror once aimed at the mirror's whole bounding sphere round it: 6 %
    of its photons carried power, tests/test_mirror_caustic.py.)"""
    centers = np.asarray(centers, np.float64).reshape(-1, 3)
    radii = np.asarray(radii, np.float64)
    axis = np.asarray(axis, np.float64) / max(float(np.linalg.norm(axis)), 1e-300)
    to_c = centers - np.asarray(pos, np.float64)
    dist = np.linalg.norm(to_c, axis=1)
    inside = dist <= radii
    sin_s = np.clip(radii / np.maximum(dist, 1e-300), 0.0, 1.0)
    half_s = np.where(inside, math.pi, np.arcsin(sin_s))
    cos_c = np.clip(to_c @ axis / np.maximum(dist, 1e-300), -1.0, 1.0)
    half_b = math.acos(min(max(cos_bound, -1.0), 1.0))
    overlap = inside | (np.arccos(cos_c) < half_s + half_b)
    omega_s = 2.0 * math.pi * (1.0 - np.where(inside, -1.0, np.sqrt(1.0 - sin_s ** 2)))
    omega = np.minimum(omega_s, 2.0 * math.pi * (1.0 - cos_bound))
    w = np.where(overlap, np.maximum(omega, 1e-12), 0.0)
    return Aim(centers, radii, w / w.sum() if w.sum() > 0 else w)


@kernel
def aim_cones(centers, radii, probs, cos_bound, o0, o1, o2):
    """The aim cones of the spheres (centers (K,3), radii (K,)) from the fixed origin o,
    computed once for all of a call's photons (the spot's aimed photons all leave from
    its centre): (K, 7) rows of (the sphere's cone: _cone_cos' cosine, distance and
    vector o -> c; 1 where the spot's cone (cos_bound) is the narrower, else 0; probs[k]
    / that aim cone's solid angle, the sphere's share of the aimed pdf)."""
    K = centers.shape[0]
    out = np.empty((K, 7))
    for k in range(K):
        ck, dk, k0, k1, k2 = _cone_cos(centers[k, 0], centers[k, 1], centers[k, 2], radii[k],
                                       o0, o1, o2)
        spot = cos_bound > ck  # the spot's cone is the narrower
        omega = TWO_PI * (1.0 - cos_bound) if spot else TWO_PI * (1.0 - ck)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = ck, dk, k0, k1, k2
        out[k, 5] = 1.0 if spot else 0.0
        out[k, 6] = probs[k] / omega
    return out


@kernel
def spot_aim_direction(centers, radii, probs, cdf, axis, cos_bound, o0, o1, o2, us, u1, u2):
    """A direction from o aimed at one of the spheres (chosen by us from cdf) inside the
    spot's cone (spot_aim): uniform in the narrower of the sphere's cone and the spot's
    (u1, u2); and its aimed pdf (1/sr), the mixture over every sphere whose aim cone holds
    it (sphere k contributes probs[k] / its aim cone's solid angle); 0 where no sphere is
    aimed at or the direction lies in no sphere's cone (it meets no caster: no power,
    so the aimed photons hold the directions towards the spheres, as aim_direction's)."""
    return aimed_direction(aim_cones(centers, radii, probs, cos_bound, o0, o1, o2), probs,
                           cdf, axis, cos_bound, us, u1, u2)


@kernel
def aimed_direction(cones, probs, cdf, axis, cos_bound, us, u1, u2):
    """spot_aim_direction with the spheres' aim cones from its origin given (aim_cones):
    the same directions and pdf, bit for bit (the same operations, each sphere's done
    once per call instead of twice per photon)."""
    j = pick(cdf, us)
    ck, dk, t0, t1, t2 = cones[j, 0], cones[j, 1], cones[j, 2], cones[j, 3], cones[j, 4]
    if cos_bound > ck:
        l0, l1, l2 = uniform_cone(u1, u2, cos_bound)
        d0, d1, d2 = to_world(l0, l1, l2, axis[0], axis[1], axis[2])
    else:
        ds = max(dk, 1e-300)
        l0, l1, l2 = uniform_cone(u1, u2, ck)
        d0, d1, d2 = to_world(l0, l1, l2, t0 / ds, t1 / ds, t2 / ds)
    in_spot = d0 * axis[0] + d1 * axis[1] + d2 * axis[2] >= cos_bound
    aimed = 0.0
    towards = False
    for k in range(cones.shape[0]):
        in_sphere = (d0 * cones[k, 2] + d1 * cones[k, 3] + d2 * cones[k, 4]
                     >= cones[k, 0] * cones[k, 1])
        inside = in_spot if cones[k, 5] != 0.0 else in_sphere
        towards = towards or in_sphere
        if inside and probs[k] > 0.0:
            aimed += cones[k, 6]
    return d0, d1, d2, aimed if towards else 0.0


@kernel
def emit_spot(pos, axis, radius, intensity, frame, cos_half, width, cos_bound, centers, radii,
              probs, cdf, aimed, key, first, n, count, o32, d32, d, power, slot, start):
    """Photons of a spot light: directions uniform in the cone round `axis` of cosine
    cos_bound (holding the whole, possibly scaled, lit cone), power intensity x mask x the
    cone's solid angle / count; with a radius each leaves from a disk across its direction.
    aimed: directions aimed at the spheres (grown by the radius: SpotLight._aim_radii)
    where they lie in the spot's cone (spot_aim_direction), power intensity x mask /
    (count x aimed pdf). Dimensions: 0, 1 the direction, 2, 3 the
    disk; aimed: 0 the target, 3, 4 the direction, 5, 6 the disk."""
    j = start
    solid = 2.0 * math.pi * (1.0 - cos_bound)
    # Every aimed direction leaves from the centre: the spheres' cones from there, once.
    cones = aim_cones(centers, radii, probs, cos_bound, pos[0], pos[1], pos[2])
    for i in range(n):
        s = first + i
        if not aimed:
            l0, l1, l2 = uniform_cone(emit_uniform(key, s, 0), emit_uniform(key, s, 1), cos_bound)
            d0, d1, d2 = to_world(l0, l1, l2, axis[0], axis[1], axis[2])
            w = solid / count
            k = 2
        else:
            d0, d1, d2, pdf_aim = aimed_direction(cones, probs, cdf, axis, cos_bound,
                                                  emit_uniform(key, s, 0),
                                                  emit_uniform(key, s, 3),
                                                  emit_uniform(key, s, 4))
            w = 1.0 / (count * pdf_aim) if pdf_aim > 0.0 else 0.0
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
