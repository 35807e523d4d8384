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

from .. import worldmedium
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
           "allocate_photons", "light_census"]


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
    # A world volume (engine/worldmedium.py): the world and suns, infinitely far beyond
    # it, light nothing.
    fog = worldmedium.active(scene)
    for light in scene.lights:
        if fog and light.kind == "SUN":
            continue
        prepared = LIGHT_KINDS[light.kind].from_scene(light, geo, common)
        if prepared is not None:
            out.append(prepared)
    for extra in (MeshLight.from_geometry(geo, table, common, gathered),
                  None if fog else WorldLight.from_background(scene, common)):
        if extra is not None:
            out.append(extra)
    world = out[-1] if out and out[-1].kind == WORLD else None
    if world is not None and SHADOW_PORTALS and getattr(scene, "portals", None):
        # Cycles light portals: the world's shadow rays sample them (lights/world.py),
        # but not those a surface covers (a glass pane in the window: panelight's).
        kept = [lp for lp in scene.portals if not portal_covered(geo, lp)]
        world.set_portals(kept, geo.offset)
        world.portal_leaks = [lp.name for lp in kept if portal_leaks(geo, lp)]
    return out


def light_census(lights: list[Light], scene: Scene | None = None) -> str:
    """What lights the scene, short enough for Blender's stats line ("lights: 2 lamps +
    world + 64 emitting triangles"): "2 lamps + world + 64 emitting triangles", "1 lamp",
    "world", "none".

    lights: prepare_lights' list (what the render samples and traces photons from); a
    Sky Texture's sun disc (a SUN light the export adds for the world, named as
    scene.environment.sun_light says) is the world's, not a lamp; the emissive meshes
    are counted by their triangles (MeshLight.tri_index), as the effect report says
    them. The stats line counted the lamps alone ("2 lights" under an HDRI and a glowing
    lamp shade, newuser45 / newuser46), which a user read as the World or the shade
    missing (docs/accuracy.md, report47)."""
    sky_sun = getattr(getattr(scene, "environment", None), "sun_light", None) or {}
    lamps = world = triangles = 0
    for li in lights:
        if li.kind == WORLD or (li.kind == SUN and li.name == sky_sun.get("name")):
            world = 1
        elif li.kind == MESH:
            triangles += len(li.tri_index)
        else:
            lamps += 1
    parts = ([f"{lamps} lamp{'' if lamps == 1 else 's'}"] if lamps else []) + (
        ["world"] if world else []) + (
        [f"{triangles} emitting triangle{'' if triangles == 1 else 's'}"] if triangles else [])
    return " + ".join(parts) or "none"


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


# Probes of an opening past a portal's outline: PORTAL_LEAK_PROBES a side (a round
# portal: 4 x that round its ellipse), PORTAL_LEAK_GAP x the side's length outside it;
# PORTAL_LEAK_MIN of them open (no surface within the cover depth along the normal) say
# the opening is larger than the portal.
PORTAL_LEAK_PROBES = 5
PORTAL_LEAK_GAP = 0.04
PORTAL_LEAK_MIN = 2


def _segments_meet(geo: Geometry, origins, n, length) -> np.ndarray:
    """(M,) whether the segments origins (M,3) + t n, t in [0, length], meet a triangle of
    geo (Moller-Trumbore over the triangles the segments' slab holds)."""
    v0 = np.asarray(geo.v0, np.float64)
    e1 = np.asarray(geo.e1, np.float64)
    e2 = np.asarray(geo.e2, np.float64)
    base = origins[0] @ n
    h0 = v0 @ n - base
    h1, h2 = h0 + e1 @ n, h0 + e2 @ n
    near = np.nonzero((np.maximum(np.maximum(h0, h1), h2) >= 0.0)
                      & (np.minimum(np.minimum(h0, h1), h2) <= length))[0]
    out = np.zeros(len(origins), bool)
    if not len(near):
        return out
    v0, e1, e2 = v0[near], e1[near], e2[near]
    p = np.cross(n, e2)
    det = np.einsum("ij,ij->i", p, e1)
    ok = np.abs(det) > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    for i, o in enumerate(origins):
        s = o - v0
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ n) * inv
        t = np.einsum("ij,ij->i", q, e2) * inv
        out[i] = np.any(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= length))
    return out


def portal_leaks(geo: Geometry, portal) -> bool:
    """Whether the opening under light portal `portal` (engine.scene.LightPortal) reaches
    past its outline: at PORTAL_LEAK_MIN or more points just outside it (module
    constants) no surface crosses the normal within PORTAL_COVER_DEPTH x the shorter side
    to either side. There the sky's light comes in by directions the portal strategy
    never draws, so only the others' share (1 - s_p) finds it (world.py
    PORTAL_SHARE_LEAK_*); measured on the new-user trial's daylit room, whose 1.2 x 1.0 m
    Portal was turned a quarter (1.0 wide in a 1.2 m wide window): the floor's per-sample
    std/mean in the dark corner 24.1 without portal sampling, 24.8 with shares up to
    0.9, 15.6 up to 0.5, its highest samples from the window's uncovered strips.
    Instanced triangles (geo.instances) are not looked at."""
    c = np.asarray(portal.corners, np.float64) - np.asarray(geo.offset, np.float64)
    n = np.asarray(portal.normal, np.float64)
    ex, ey = c[1] - c[0], c[3] - c[0]
    lx, ly = np.linalg.norm(ex), np.linalg.norm(ey)
    depth = PORTAL_COVER_DEPTH * min(lx, ly)
    if not depth > 0.0 or geo.count == 0:
        return False
    f = (np.arange(PORTAL_LEAK_PROBES) + 0.5) / PORTAL_LEAK_PROBES
    if getattr(portal, "round", False):
        a = 2.0 * np.pi * (np.arange(4 * PORTAL_LEAK_PROBES) + 0.5) / (4 * PORTAL_LEAK_PROBES)
        r = 0.5 * (1.0 + 2.0 * PORTAL_LEAK_GAP)
        fa, fb = 0.5 + r * np.cos(a), 0.5 + r * np.sin(a)
    else:
        g = PORTAL_LEAK_GAP
        fa = np.concatenate([f, f, np.full_like(f, -g), np.full_like(f, 1 + g)])
        fb = np.concatenate([np.full_like(f, -g), np.full_like(f, 1 + g), f, f])
    pts = c[0] + fa[:, None] * ex + fb[:, None] * ey - depth * n
    return int((~_segments_meet(geo, pts, n, 2.0 * depth)).sum()) >= PORTAL_LEAK_MIN


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
