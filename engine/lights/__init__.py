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
        # Cycles light portals: the world's shadow rays sample them (lights/world.py),
        # but not those a surface covers (a glass pane in the window: panelight's).
        world.set_portals([lp for lp in scene.portals if not portal_covered(geo, lp)],
                          geo.offset)
    return out


# A light portal is covered when a surface crosses the window's normal within this share
# of its shorter side from its plane at most of PORTAL_PROBES x PORTAL_PROBES points.
PORTAL_COVER_DEPTH = 0.25
PORTAL_PROBES = 3


def portal_covered(geo: Geometry, portal) -> bool:
    """Whether a surface covers light portal `portal` (engine.scene.LightPortal): the
    segments along its normal through most (> half) of a PORTAL_PROBES^2 grid of points
    on it, PORTAL_COVER_DEPTH x its shorter side to either side, meet a triangle of geo
    (Moller-Trumbore; the triangles near its plane only). The world's ordinary shadow
    rays stop at such a surface (a glass pane: engine/panelight.py brings the light
    through it), so the portal's shadow-ray samples would all be lost there, and the
    share they take from the others would make light by other ways in noisier (measured:
    a pane under the portal and a 4 x 1 m opening beside, the floor's per-sample
    std/mean 4.37 without the portal strategy, 14.5 with it). Instanced triangles
    (geo.instances) are not looked at."""
    c = np.asarray(portal.corners, np.float64) - np.asarray(geo.offset, np.float64)
    n = np.asarray(portal.normal, np.float64)
    ex, ey = c[1] - c[0], c[3] - c[0]
    depth = PORTAL_COVER_DEPTH * min(np.linalg.norm(ex), np.linalg.norm(ey))
    if not depth > 0.0 or geo.count == 0:
        return False
    v0 = np.asarray(geo.v0, np.float64)
    e1 = np.asarray(geo.e1, np.float64)
    e2 = np.asarray(geo.e2, np.float64)
    h0 = (v0 - c[0]) @ n
    h1, h2 = h0 + e1 @ n, h0 + e2 @ n
    near = np.nonzero((np.minimum(np.minimum(h0, h1), h2) <= depth)
                      & (np.maximum(np.maximum(h0, h1), h2) >= -depth))[0]
    if not len(near):
        return False
    v0, e1, e2 = v0[near], e1[near], e2[near]
    f = (np.arange(PORTAL_PROBES) + 0.5) / PORTAL_PROBES
    covered = 0
    for a in f:
        for b in f:
            o = c[0] + a * ex + b * ey - depth * n
            p = np.cross(n, e2)
            det = np.einsum("ij,ij->i", p, e1)
            ok = np.abs(det) > 1e-300
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
            s = o - v0
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            v = (q @ n) * inv
            t = np.einsum("ij,ij->i", q, e2) * inv
            if np.any(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 2 * depth)):
                covered += 1
    return covered * 2 > PORTAL_PROBES * PORTAL_PROBES


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
