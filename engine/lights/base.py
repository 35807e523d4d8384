"""The interface every light kind implements (pbrt-v4's lights.h as the model).

A light kind is one subclass of Light in its own module (point.py, spot.py, area.py,
sun.py, mesh.py, world.py), registered by kind name in engine/lights/__init__.py. Each
holds that kind's
    prepare         from_scene / from_geometry: re-centred, everything sampling needs
    pack            its parameters for the compiled direct-light kernels, which sample it
                    for shadow rays (engine/lights/packing.py, engine/directlight.py)
    emit_into       photons as the light emits them (sum of power = flux), written by a
                    compiled kernel of the kind's module (engine/lights/emission.py)
    emit_towards_into  photons aimed at caustic casters, reweighted (same expected power)
    intersect       rays meeting the emitting surface (the light seen in mirrors)
    photon_flux     RGB power (W) the photon pass distributes among lights
Units: docs/units.md; docs/design.md, Units (Cycles).
"""
from __future__ import annotations

import numpy as np

from ..geometry import ALL_RAYS, CAMERA, DIFFUSE, GLOSSY, SHADOW, TRANSMISSION
from .emission import NO_AIM, Aim, EmissionBuffers, aim_disks, aim_weights


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
    # Whether shadow rays sample this light (a mesh light's Emission Sampling can leave
    # every side to the rays that meet it: MeshLight.shadow_sampled).
    shadow_sampled: bool = True
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
    def emit_into(self, key, first: int, n: int, count: int, out, start: int) -> int:
        """Emit the photons in slots first .. first + n - 1 of a chunk keyed by key
        (uint64) into out (emission.EmissionBuffers) from row `start`, compacted (photons
        of no power take no row), each carrying photon_flux / count (count: this light's
        photons over all chunks); returns the next free row. A compiled kernel of the
        light's module (engine/lights/emission.py)."""
        return self._emit(NO_AIM, False, key, first, n, count, out, start)

    def aim(self, centers: np.ndarray, radii: np.ndarray) -> Aim:
        """How this light aims at bounding spheres (centers (K,3), radii (K,)): caustic
        casters (emission.aim_weights: by the solid angle each subtends)."""
        return aim_weights(centers, self._aim_radii(radii), self.pos)

    def emit_towards_into(self, key, first: int, n: int, count: int, targets, out,
                          start: int) -> int:
        """As emit_into, the photons aimed at bounding spheres targets = (centers (K,3),
        radii (K,)) (self.aim) and weighted so the expected power arriving anywhere inside
        them equals that of emit_into: power = natural power x natural pdf / aimed pdf."""
        return self._emit(self.aim(*targets), True, key, first, n, count, out, start)

    def _emit(self, aim: Aim, aimed: bool, key, first, n, count, out, start) -> int:
        """The kind's emission kernel: natural (aimed False) or aimed photons."""
        raise NotImplementedError

    def emit(self, n: int, rng):
        """n photons with a key drawn from rng (numpy.random.Generator): origins (m,3),
        unit directions (m,3), RGB power (m,3) in W each, for the m <= n that carry power;
        sum of power = photon_flux (in expectation for lights whose power varies per
        photon). The photon pass itself calls emit_into."""
        return emit_arrays(self, n, rng)

    # ------------------------------------------------------------------ aimed photons
    def emit_towards(self, n: int, rng, centers: np.ndarray, radii: np.ndarray):
        """As emit, n photons aimed at bounding spheres (centers (K,3), radii (K,)):
        emit_towards_into with a key drawn from rng."""
        return emit_arrays(self, n, rng, (centers, radii))

    def _aim_radii(self, radii):
        return radii

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

    def aim(self, centers: np.ndarray, radii: np.ndarray) -> Aim:
        """Photons from infinity aim at the casters' shadow disks (emission.aim_disks)."""
        return aim_disks(centers, radii)


def emission_key(rng) -> np.uint64:
    """The key of a chunk's random numbers (engine/photonkernels.uniform), from rng."""
    return np.uint64(rng.integers(1 << 63, dtype=np.uint64))


def emit_arrays(emitter, n: int, rng, targets=None):
    """(origins, directions, power) (m,3) float64 of n photons of a light or LightGroup
    (engine/lights/group.py), natural or aimed at targets = (centers, radii), with a key
    drawn from rng: Light.emit and emit_towards."""
    if n == 0 or (targets is not None and len(targets[0]) == 0):
        z = np.zeros((0, 3))
        return z, z.copy(), z.copy()
    out = EmissionBuffers(n)
    key = emission_key(rng)
    if targets is None:
        m = emitter.emit_into(key, 0, n, n, out, 0)
    else:
        m = emitter.emit_towards_into(key, 0, n, n, targets, out, 0)
    o32, _, d, power, _ = out.head(m)
    return o32.astype(np.float64), d.copy(), power.copy()
