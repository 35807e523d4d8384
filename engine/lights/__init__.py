"""Lights in Cycles units: one module per kind, one interface (engine/lights/base.py),
one registry.

Conventions (docs/units.md; docs/design.md, Units (Cycles)): a point light of power P has
intensity P/(4*pi) W/sr; a spot is that point light masked by Cycles' smoothstep cone; an
area light emits one-sided uniform radiance P/(pi*A) along its -Z axis; a sun gives
irradiance `strength` W/m^2; emissive meshes emit their radiance from both sides; a
non-black background is a uniform environment, an environment map (environment.py) an
importance-sampled HDRI. Many lights: selection.py's light tree picks one per shadow ray.

To add a light kind: subclass Light in a new module, implement from_scene, pack (and its
sampling in engine/directlight.py), _emit (calling the module's emission kernel, natural
and aimed: engine/lights/emission.py) and, if it has a visible surface, intersect; then
add it to LIGHT_KINDS below and to emission._warm_up. engine/scene.py, engine/scenefile.py,
engine/api.py and addon/export.py take the declared kinds from here.
"""
from __future__ import annotations

import numpy as np

from ..geometry import Geometry, MaterialTable
from ..sampling import luminance
from ..scene import AREA, POINT, SPOT, SUN, Scene
from .area import AreaLight
from .base import InfiniteLight, Light
from .mesh import MESH, MeshLight
from .point import PointLight
from .spot import SpotLight
from .sun import SunLight
from .world import WORLD, WorldLight

# Kind name -> class. Declared kinds (a scene's light objects) first, in Blender's order.
LIGHT_KINDS: dict[str, type[Light]] = {
    cls.kind: cls for cls in (PointLight, SpotLight, AreaLight, SunLight, MeshLight, WorldLight)}
DECLARED_KINDS: tuple[str, ...] = tuple(k for k, c in LIGHT_KINDS.items() if c.declared)

# Off: the world's shadow rays ignore the scene's light portals, as before lightportal34
# (for A/B measurements: bench/bench_light_portal.py).
SHADOW_PORTALS = True

# The old single class, kept as the name of the interface.
PreparedLight = Light

__all__ = ["LIGHT_KINDS", "DECLARED_KINDS", "Light", "PreparedLight",
           "InfiniteLight", "PointLight", "SpotLight", "AreaLight", "SunLight", "MeshLight",
           "WorldLight", "POINT", "SPOT", "AREA", "SUN", "MESH", "WORLD", "prepare_lights",
           "allocate_photons"]


def prepare_lights(scene: Scene, geo: Geometry, table: MaterialTable,
                   gathered: bool = True) -> list[Light]:
    """Re-centre the scene's lights and add mesh and world lights: a list of Light, the
    declared lights in scene order, then the emissive meshes, then the world.
    gathered: final gathering runs (RenderSettings photon_mapping and final_gather), the
    only way the sides of an emissive mesh shadow rays do not sample (Emission
    Sampling) reach diffuse surfaces directly; without it shadow rays sample every side
    (MeshLight.from_geometry)."""
    center = (geo.bounds[0] + geo.bounds[1]) / 2.0
    radius = max(geo.extent / 2.0, 1e-6) * 1.01
    common = dict(center=center, scene_radius=radius)
    out = []
    for light in scene.lights:
        prepared = LIGHT_KINDS[light.kind].from_scene(light, geo, common)
        if prepared is not None:
            out.append(prepared)
    for extra in (MeshLight.from_geometry(geo, table, common, gathered),
                  WorldLight.from_background(scene, common)):
        if extra is not None:
            out.append(extra)
    world = out[-1] if out and out[-1].kind == WORLD else None
    if world is not None and SHADOW_PORTALS and getattr(scene, "portals", None):
        # Cycles light portals: the world's shadow rays sample them (lights/world.py)
        world.set_portals(scene.portals, geo.offset)
    return out


def allocate_photons(lights: list[Light], total: int) -> list[int]:
    """Photons per light, proportional to emitted power (the paper: power-proportional)."""
    w = np.array([float(luminance(np.asarray(li.photon_flux))) for li in lights])
    if total <= 0 or len(w) == 0 or w.sum() <= 0:
        return [0] * len(lights)
    share = w / w.sum() * total
    counts = np.floor(share).astype(int)
    rest = total - counts.sum()
    order = np.argsort(-(share - counts))
    counts[order[:rest]] += 1
    return counts.tolist()
