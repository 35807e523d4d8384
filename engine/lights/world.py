"""World: the background as a light at infinity (Cycles' kernel/light/background.h).

Two forms:
  constant     a non-black background colour: uniform radiance `background`, sampled for
               shadow rays by the cosine hemisphere around the shading normal
  environment  an equirectangular image (engine/lights/environment.py): shadow rays use
               one-sample multiple importance sampling (balance heuristic) of the map
               times the cosine to the shading normal's cluster (the environment's
               cosine-weighted distributions, picked with probability ENV_MAP_FRACTION)
               and the cosine hemisphere, so a small bright sun in the map, the dim, wide
               sky and the directions the cluster's cosine misses are all sampled, and no
               sample goes below the surface's horizon; photons leave a disk beyond the
               scene's bounding sphere with directions from the map's own 2D
               piecewise-constant distribution.

`background_radiance` gives the radiance of rays that escape the scene (camera rays that
miss, specular continuations); `WorldLight.pdf` the solid-angle pdf of the shadow-ray
strategy, for multiple importance sampling against BSDF-sampled rays that escape.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from ..sampling import dot
from .emission import f64, aim_origin, disk_origin, emit_uniform, put, uniform_sphere
from .environment import env_radiance, env_sample
from . import packing as pk
from .base import InfiniteLight

WORLD = "WORLD"
# Probability that a shadow ray of an environment-mapped world samples the map's
# cosine-weighted distribution (else the cosine hemisphere); directlight.sample_lights
# uses the same constant. (0.5 with the map's plain distribution until issue 14: the
# case-3 HDRI scene's floor, direct light per sample, docs/performance.md; 0.75 until the
# map's texels were sampled by their interpolated luminance (environment.texel_warp): then
# the map x cosine alone has a per-sample relative variance of 0.001 at a floor under a
# 2-degree sun of 1200, and the cosine share is what is left: the mixture's 0.106 at 0.75,
# 0.019 at 0.9, 0.006 at 0.95; at normals off their cluster's centre, where the cluster's
# cosine misses part of the hemisphere, 0.15-0.20 / 0.05-0.07 / 0.04-0.06, and low suns
# favour 0.9 (0.010 against 0.018 at 0.95).)
ENV_MAP_FRACTION = 0.9


def background_radiance(scene, d: np.ndarray) -> np.ndarray:
    """Radiance (N,3) of the world seen along directions d (N,3) of rays that escape the
    scene (unit or not; re-centring does not change directions): the environment map
    when the scene has one, else the constant background colour."""
    env = getattr(scene, "environment", None)
    if env is not None:
        return env.radiance(d)
    bg = np.asarray(scene.background, np.float64)
    return np.broadcast_to(bg, (len(d), 3))


class WorldLight(InfiniteLight):
    kind = WORLD
    declared = False
    environment = None

    @classmethod
    def from_background(cls, scene, common):
        """The world light of the scene, or None (black background, or not a light)."""
        if not scene.background_is_light:
            return None
        radius = common["scene_radius"]
        env = getattr(scene, "environment", None)
        if env is not None:
            if env.is_black:
                return None
            return cls("world", radiance=env.average(), environment=env,
                       photon_flux=env.integral() * math.pi * radius ** 2,
                       radius=0.0, cos_half_angle=1.0, **common)
        bg = np.asarray(scene.background, np.float64)
        if not np.any(bg > 0):
            return None
        return cls("world", radiance=bg,
                   photon_flux=bg * math.pi * radius ** 2 * 4.0 * math.pi,
                   radius=0.0, cos_half_angle=1.0, **common)

    @property
    def needs_choice(self) -> bool:
        return self.environment is not None

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code.
        The environment's arrays travel beside the rows (pack_lights)."""
        row[pk.RGB:pk.RGB + 3] = self.radiance
        if self.environment is not None:
            row[pk.ENV_ON] = 1.0
            row[pk.ENV_INTERP] = self.environment.interp_code
            row[pk.ENV_FRAME:pk.ENV_FRAME + 9] = self.environment.rotation.ravel()
        return pk.CODE_WORLD

    def pdf(self, wi: np.ndarray, ns: np.ndarray) -> np.ndarray:
        """Solid-angle pdf (N,) (1/sr) with which this light's shadow-ray sampling
        (directlight.sample_lights) picks unit directions wi (N,3) towards the world at
        shading points with shading normals ns (N,3): cos(wi, ns)^+ / pi for a constant
        world; ENV_MAP_FRACTION x the environment's cosine-weighted pdf at ns + (1 -
        ENV_MAP_FRACTION) x cos^+ / pi with an environment map. Multiply by the light's selection probability
        (engine/lights/selection.py) for the full light-sampling pdf of a BSDF-sampled ray
        that escapes (power or balance heuristic, pbrt-v4's PathIntegrator)."""
        wi = np.asarray(wi, np.float64).reshape(-1, 3)
        cos_pdf = np.maximum(dot(wi, np.asarray(ns, np.float64).reshape(-1, 3)), 0.0) / math.pi
        if self.environment is None:
            return cos_pdf
        return (ENV_MAP_FRACTION * self.environment.cosine_pdf(wi, ns)
                + (1.0 - ENV_MAP_FRACTION) * cos_pdf)

    def seen_at_infinity(self, d):
        return None  # the background itself: background_radiance

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        env = self.environment
        if env is None:
            none = np.zeros((1, 1, 3), np.float32)
            arrays = (np.eye(3), none, none, np.ones(3), 0, np.array([0.0, 1.0]),
                      np.array([[0.0, 1.0]]), np.zeros((1, 1), np.float32))
        else:
            rows, cols, pdf_uv = env.distribution
            arrays = (env.rotation, env.pixels, env.stored, env.scale, int(env.interp_code),
                      rows, cols, pdf_uv)
        return emit_world(env is not None, *arrays, f64(self.photon_flux), f64(self.center),
                          float(self.scene_radius), *aim.arrays, aimed, key,
                          first, n, float(count), *out.arrays, start)


@kernel
def emit_world(env_on, rotation, pixels, stored, scale, interp, rows, cols, pdf_uv, flux,
               center, R, centers, radii, probs, cdf, aimed, key, first, n, count, o32, d32,
               d, power, slot, start):
    """Photons of the world. A constant background: directions uniform over the sphere,
    each flux / count (flux: the radiance through the natural disk of radius R from every
    direction). An environment map (env_on; its rotation, radiance texels, interpolation
    and distribution: environment.py): directions from the map's distribution, power
    L / pdf x pi R^2 / count (pixels: its linear texels, which the distribution samples;
    stored, scale: what its lookup reads, Environment.stored / scale). Photons travel
    against the sampled direction, from the natural disk (emission.disk_origin) or,
    aimed, a caster's shadow disk (emission.aim_origin). Dimensions: 0, 1 the direction,
    2, 3 the origin; aimed: 2 the target, 3, 4 the origin."""
    j = start
    f0, f1, f2 = flux[0] / count, flux[1] / count, flux[2] / count
    area = math.pi * R * R
    for i in range(n):
        s = first + i
        u1 = emit_uniform(key, s, 0)
        u2 = emit_uniform(key, s, 1)
        if env_on:
            w0, w1, w2, pdf = env_sample(rotation, pixels, interp, rows, cols, pdf_uv, u1, u2)
            L0, L1, L2 = env_radiance(rotation, stored, interp, scale, w0, w1, w2)
            inv = 1.0 / max(pdf, 1e-300) if pdf > 0 else 0.0
            g = inv * area / count
            p0, p1, p2 = L0 * g, L1 * g, L2 * g
            d0, d1, d2 = -w0, -w1, -w2
        else:
            d0, d1, d2 = uniform_sphere(u1, u2)
            p0, p1, p2 = f0, f1, f2
        if not aimed:
            o0, o1, o2 = disk_origin(center, R, d0, d1, d2, emit_uniform(key, s, 2),
                                     emit_uniform(key, s, 3))
        else:
            o0, o1, o2, w = aim_origin(center, R, centers, radii, probs, cdf, d0, d1, d2,
                                       emit_uniform(key, s, 2), emit_uniform(key, s, 3),
                                       emit_uniform(key, s, 4))
            p0, p1, p2 = p0 * w, p1 * w, p2 * w
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, p0, p1, p2, s)
    return j
