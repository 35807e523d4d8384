"""The interface every light kind implements (pbrt-v4's lights.h as the model).

A light kind is one subclass of Light in its own module (point.py, spot.py, area.py,
sun.py, mesh.py, world.py), registered by kind name in engine/lights/__init__.py. Each
holds that kind's
    prepare         from_scene / from_geometry: re-centred, everything sampling needs
    pack            its parameters for the compiled direct-light kernels, which sample it
                    for shadow rays (engine/lights/packing.py, engine/directlight.py)
    emit            photons as the light emits them (sum of power = flux)
    emit_towards    photons aimed at caustic casters, reweighted (same expected power)
    intersect       rays meeting the emitting surface (the light seen in mirrors)
    photon_flux     RGB power (W) the photon pass distributes among lights
Units: docs/units.md; docs/design.md, Units (Cycles).
"""
from __future__ import annotations

import math
import numpy as np

from ..geometry import ALL_RAYS, CAMERA, DIFFUSE, GLOSSY, SHADOW, TRANSMISSION
from ..sampling import concentric_disk, dot, orthonormal_basis, to_world, uniform_cone


def ray_kinds_of(light) -> int:
    """Bits of the ray kinds a scene light (engine/scene.py Light) is visible to. Shadow
    rays serve diffuse surfaces here (direct light is the diffuse lobe's), so they follow
    the light's diffuse visibility, as Cycles' next-event estimation from a diffuse
    closure does."""
    bits = CAMERA if light.visible_camera else 0
    if light.visible_diffuse:
        bits |= DIFFUSE | SHADOW
    if light.visible_glossy:
        bits |= GLOSSY
    if light.visible_transmission:
        bits |= TRANSMISSION
    return bits


class Light:
    """One light, re-centred, with everything sampling needs precomputed.

    Subclasses set `kind` (the registry key) and `declared` (True: a scene declares it as
    a light object; False: the engine makes it from emissive meshes / the background)."""

    kind: str = ""
    declared: bool = True
    # The ray kinds (engine/geometry.py bits) that see this light; emissive meshes and the
    # world keep all (a mesh's own visibility lives on its triangles).
    ray_kinds: int = ALL_RAYS
    source = None  # the scene's Light (engine/scene.py) a declared light was made from

    def __init__(self, name, **kw):
        self.name = name
        self.__dict__.update(kw)

    # ------------------------------------------------------------------ prepare
    @staticmethod
    def scene_params(light, geo, common) -> dict:
        """The parameters every declared light keeps (re-centred position, frame, ...)."""
        u, v = light.axis_u, light.axis_v  # computed properties: read once
        c = float(np.dot(u, v))
        du = (u - c * v) / (1.0 - c * c)
        dv = (v - c * u) / (1.0 - c * c)
        return dict(common, pos=light.position - geo.offset, dir=light.direction, u=u,
                    v=v, du=du, dv=dv, radius=light.radius, spot_size=light.spot_size,
                    spot_blend=light.spot_blend, shape=light.shape, size_x=light.size_x,
                    size_y=light.size_y, spread=light.spread,
                    ray_kinds=ray_kinds_of(light),
                    cos_half_angle=1.0, source=light)

    @classmethod
    def from_scene(cls, light, geo, common) -> "Light | None":
        """The prepared light for a scene's Light (engine/scene.py), or None when it
        emits nothing (e.g. an area light of zero area). common: center, scene_radius."""
        raise NotImplementedError(f"{cls.__name__} is not declared by scenes")

    # ------------------------------------------------------------------ properties
    @property
    def has_size(self) -> bool:
        """Needs several shadow samples (soft shadows)."""
        return True

    @property
    def has_surface(self) -> bool:
        """Rays can meet its emitting surface (intersect finds hits): the camera pass asks
        only these lights, so point lights of radius 0 cost nothing per ray."""
        return False

    @property
    def needs_choice(self) -> bool:
        """Takes a third random number per shadow sample (the SEL stream of
        directlight.sample_lights): a mesh light's triangle, an environment-mapped world's
        sampling strategy."""
        return False

    # ------------------------------------------------------------------ shadow rays
    def pack(self, row) -> int:
        """Write this light's parameters into row (P,) float64 (slots in
        engine/lights/packing.py) for the direct-light kernels; returns its kind code."""
        raise NotImplementedError

    # ------------------------------------------------------------------ photons
    def emit(self, n: int, rng):
        """n photons: origins (n,3), unit directions (n,3), RGB power (n,3) in W each;
        sum of power = photon_flux."""
        u1, u2, u3, u4 = (rng.random(n) for _ in range(4))
        return self._emit(n, rng, u1, u2, u3, u4)

    def _emit(self, n, rng, u1, u2, u3, u4):
        raise NotImplementedError

    # ------------------------------------------------------------------ aimed photons
    def emit_towards(self, n: int, rng, centers: np.ndarray, radii: np.ndarray):
        """n photons aimed at bounding spheres (centers (K,3), radii (K,): caustic casters),
        weighted so the expected power arriving anywhere inside the spheres equals that of
        emit(): power = natural power x natural pdf / aimed pdf (POV-Ray-style photon
        targets). Finite lights: each photon picks a sphere by its solid angle seen from
        the light, then a direction uniformly in its cone."""
        K = len(centers)
        if K == 0 or n == 0:
            z = np.zeros((0, 3))
            return z, z.copy(), z.copy()
        radii = self._aim_radii(radii)
        u1, u2, u3, u4 = (rng.random(n) for _ in range(4))
        o, normal, anchor, state = self._aim_origins(n, rng, u1, u2)
        # Choose a target per photon in proportion to its solid angle seen from the light.
        dist_a = np.linalg.norm(centers - anchor, axis=1)
        sin_a = np.clip(radii / np.maximum(dist_a, 1e-300), 0.0, 1.0)
        omega_a = 2.0 * math.pi * (1.0 - np.sqrt(1.0 - sin_a ** 2))
        probs = np.maximum(omega_a, 1e-12) / np.maximum(omega_a, 1e-12).sum()
        j = rng.choice(K, size=n, p=probs)
        to_c = centers[j] - o
        dist = np.linalg.norm(to_c, axis=1)
        axis = to_c / np.maximum(dist, 1e-300)[:, None]
        cos_max = np.sqrt(np.maximum(0.0, 1.0 - (radii[j] / np.maximum(dist, 1e-300)) ** 2))
        cos_max = np.where(dist <= radii[j], -1.0, cos_max)  # inside: whole sphere
        d = to_world(uniform_cone(u3, u4, cos_max), axis)
        aimed = np.zeros(n)
        for k in range(K):
            to_k = centers[k] - o
            dk = np.linalg.norm(to_k, axis=1)
            cos_k = np.sqrt(np.maximum(0.0, 1.0 - (radii[k] / np.maximum(dk, 1e-300)) ** 2))
            cos_k = np.where(dk <= radii[k], -1.0, cos_k)
            inside = dot(d, to_k) >= cos_k * dk
            aimed += probs[k] * inside / (2.0 * math.pi * (1.0 - cos_k))
        aimed = np.maximum(aimed, 1e-300)
        return self._aimed_photons(n, rng, o, d, normal, state, aimed)

    def _aim_radii(self, radii):
        return radii

    def _aim_origins(self, n, rng, u1, u2):
        """(origins (n,3), their surface normals or None, the point solid angles are seen
        from, kind-specific state for _aimed_photons)."""
        return np.broadcast_to(self.pos, (n, 3)).copy(), None, self.pos, None

    def _aimed_photons(self, n, rng, o, d, normal, state, aimed):
        """(origins, directions, power) of aimed photons; aimed = the aiming pdf of d."""
        raise NotImplementedError

    # ------------------------------------------------------------------ seen in mirrors
    def intersect(self, o, d, tmax):
        """Rays (o, d (N,3), tmax (N,)) that hit this light's emitting surface before tmax:
        (mask (N,), t (N,), radiance (N,3) or None). Lights without a surface: no hits."""
        n = len(o)
        return np.zeros(n, bool), np.full(n, np.inf), None

    def seen_at_infinity(self, d):
        """Radiance (N,3) of the light seen along escaping directions d, or None."""
        return None


class InfiniteLight(Light):
    """A light at infinity (sun, world): photons leave a disk of the scene's bounding
    radius, 2 radii before the scene's centre, across their direction."""

    def _directions(self, n, u1, u2):
        raise NotImplementedError

    def _photons_along(self, n, u1, u2):
        """(directions of travel (n,3), power (n,3) of n photons): by default directions
        of equal power (_directions); a light whose radiance varies with direction (an
        environment map) weights them by radiance / pdf."""
        d = self._directions(n, u1, u2)
        return d, np.broadcast_to(self.photon_flux / n, (n, 3)).copy()

    def _emit(self, n, rng, u1, u2, u3, u4):
        d, power = self._photons_along(n, u1, u2)
        x, yy = concentric_disk(u3, u4)
        t, b = orthonormal_basis(d)
        o = (self.center - 2.0 * self.scene_radius * d
             + self.scene_radius * (x[:, None] * t + yy[:, None] * b))
        return o, d, power

    def emit_towards(self, n: int, rng, centers: np.ndarray, radii: np.ndarray):
        """As Light.emit_towards; photons start on the casters' shadow disks in the plane
        of the natural emission disk."""
        K = len(centers)
        if K == 0 or n == 0:
            z = np.zeros((0, 3))
            return z, z.copy(), z.copy()
        u1, u2, u3, u4 = (rng.random(n) for _ in range(4))
        d, power = self._photons_along(n, u1, u2)
        probs = radii ** 2 / np.sum(radii ** 2)
        j = rng.choice(K, size=n, p=probs)
        x, yy = concentric_disk(u3, u4)
        t, b = orthonormal_basis(d)
        R = self.scene_radius
        start = self.center - 2.0 * R * d  # the natural disk's centre for direction d
        c = centers[j]
        # Centre of caster j's shadow disk in the plane through `start` normal to d.
        c_proj = c - dot(c - start, d)[:, None] * d
        o = c_proj + radii[j][:, None] * (x[:, None] * t + yy[:, None] * b)
        aimed = np.zeros(n)
        for k in range(K):
            ck = centers[k] - dot(centers[k] - start, d)[:, None] * d
            inside = np.linalg.norm(o - ck, axis=1) <= radii[k]
            aimed += probs[k] * inside / (math.pi * radii[k] ** 2)
        natural = (np.linalg.norm(o - start, axis=1) <= R) / (math.pi * R * R)
        ratio = natural / np.maximum(aimed, 1e-300)
        return o, d, power * ratio[:, None]
