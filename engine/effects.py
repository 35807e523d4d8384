"""Scene analysis: which effects this scene needs, and why.

Before any photon is shot, look at materials, lights, geometry and settings and decide
what work is worth doing; every decision carries a one-line reason that the CLI prints,
the add-on shows, and the Film's stats record. Each effect can be forced on or off
("on" / "off") instead of "auto".
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import Geometry, MaterialTable
from .lights import MESH, WORLD, PreparedLight
from .rayoffset import ulp32
from .sampling import luminance
from .scene import AREA, SUN

PROBE_RAYS = 512  # rays per (light, caster) pair when testing whether light can reach it
# A specular lobe focuses light into a caustic only if it is sharp. Our microfacet lobes
# have alpha = roughness^2, about the lobe's angular half-width in radians: at roughness
# 0.3 that is ~5 degrees, at Principled's default 0.5 already ~14 degrees, which spreads
# a reflected light over a patch half as wide as its distance - a soft glow that the
# unaimed photons carry as well as aimed ones. Transparent (alpha < 1) passes are delta
# lobes: always sharp.
SHARP_ROUGHNESS = 0.3


def sharp_specular(table: MaterialTable) -> np.ndarray:
    """(M,) bool: materials with a lobe sharp enough to focus light (a caustic caster): a
    metal, glass or dielectric specular lobe of roughness <= SHARP_ROUGHNESS, a Principled
    coat of coat roughness <= SHARP_ROUGHNESS (a clear-coated rough base), or a
    transparent pass."""
    from .closures import principled as pr
    dielectric = (1 - table.metallic) * (1 - table.transmission)
    main = ((table.metallic * table.base_color.max(axis=1) > 0) | (table.transmission > 0)
            | (dielectric * table.specular > 0))
    coat = np.zeros(len(table.alpha), bool)
    if table.closure_params is not None and table.coat_weight is not None:
        coat = ((table.coat_weight > 0)
                & (table.closure_params[:, pr.M_COAT_ROUGH] <= SHARP_ROUGHNESS))
    return table.has_specular & ((main & (table.roughness <= SHARP_ROUGHNESS)) | coat
                                 | (table.alpha < 1))


@dataclass
class Decision:
    effect: str
    enabled: bool
    reason: str

    def __str__(self):
        return f"{self.effect}: {'on' if self.enabled else 'off'} - {self.reason}"


@dataclass
class EffectPlan:
    caustics: bool = False
    indirect: bool = False
    specular_depth: int = 0                          # camera-path specular bounces
    light_samples: dict = field(default_factory=dict)  # light name -> shadow rays / sample
    shadows: dict = field(default_factory=dict)        # light name -> trace shadow rays?
    casters: list = field(default_factory=list)        # names of caustic-casting objects
    caster_spheres: tuple = (np.zeros((0, 3)), np.zeros(0))
    caster_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # their object ids
    rough_specular: list = field(default_factory=list)  # specular objects too rough to focus
    caustics_from_global: bool = False  # caustic map from the global shot, no caustic shot
    decisions: list = field(default_factory=list)

    def add(self, effect, enabled, reason):
        self.decisions.append(Decision(effect, bool(enabled), reason))

    def report(self) -> list[str]:
        return [str(d) for d in self.decisions]


def _override(value: str, auto: bool, effect: str, auto_reason: str, plan: EffectPlan) -> bool:
    if value == "on":
        plan.add(effect, True, f"forced on ({auto_reason} when automatic)" if not auto
                 else "forced on")
        return True
    if value == "off":
        plan.add(effect, False, "switched off in the settings")
        return False
    plan.add(effect, auto, auto_reason)
    return auto


def _object_spheres(geo: Geometry, tri_mask: np.ndarray):
    """Bounding spheres (centre, radius) and names of objects owning the masked triangles."""
    ids = np.unique(geo.object_id[tri_mask])
    centers, radii, names = [], [], []
    for oid in ids:
        sel = np.nonzero(tri_mask & (geo.object_id == oid))[0]
        pts = np.concatenate([geo.v0[sel], geo.v0[sel] + geo.e1[sel], geo.v0[sel] + geo.e2[sel]])
        c = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
        # 0.1 % margin, and at least the float32 resolution at the sphere's coordinates.
        r = float(np.linalg.norm(pts - c, axis=1).max()) * 1.001 + 16.0 * float(
            ulp32(np.abs(pts).max()))
        centers.append(c)
        radii.append(r)
        names.append(geo.object_names[oid])
    return ids, np.array(centers).reshape(-1, 3), np.array(radii), names


def _light_reaches(light: PreparedLight, accel, geo: Geometry, oid: int, center, radius, rng) -> bool:
    """Does any photon from this light arrive at object `oid` without being blocked?
    Aimed photons towards the object's bounding sphere; the first surface they hit must
    belong to the object."""
    o, d, power = light.emit_towards(PROBE_RAYS, rng, center[None, :], np.array([radius]))
    live = power.max(axis=1) > 0
    if not live.any():
        return False
    _, prim, _, _ = accel.intersect(o[live], d[live])
    hit = prim >= 0
    return bool(np.any(geo.object_id[prim[hit]] == oid))


def analyse(scene, geo: Geometry, table: MaterialTable, lights: list, accel, settings) -> EffectPlan:
    plan = EffectPlan()
    s = settings
    rng = np.random.default_rng([s.seed, 99])
    mat = geo.material
    has_tris = geo.count > 0
    emitting = [li for li in lights if float(luminance(np.asarray(li.photon_flux))) > 0]
    spec_tri = table.has_specular[mat] if has_tris else np.zeros(0, bool)
    diff_tri = table.has_diffuse[mat] if has_tris else np.zeros(0, bool)

    # --- photon mapping at all (the paper's switch) ----------------------------------
    if not s.photon_mapping:
        plan.add("photon mapping", False, "switched off: plain ray tracing (paper Fig. 5b)")

    # --- indirect diffuse (global map) -------------------------------------------------
    if not s.photon_mapping:
        plan.indirect = False
    else:
        if not emitting:
            auto, why = False, "no light emits power"
        elif not diff_tri.any():
            auto, why = False, "no diffuse surface with non-zero albedo"
        elif _single_flat_surface(geo, diff_tri | spec_tri):
            auto, why = False, "a single flat surface cannot light itself"
        else:
            auto, why = True, (f"{s.photons:,} photons; final gathering with {s.gather_rays} ray(s) "
                               "per sample" if s.final_gather else f"{s.photons:,} photons, "
                               "estimated directly from the global map")
        plan.indirect = _override(s.indirect, auto, "indirect light (global map)", why, plan)

    # --- caustics ------------------------------------------------------------------------
    # Caustic photons are aimed only at casters whose specular lobe is sharp enough to
    # focus light (sharp_specular); light that reaches a diffuse surface by way of rough
    # specular surfaces only first (a glossy floor's coat) is a soft glow: it comes from
    # unaimed photons (render.py partitions the caustic paths by the object hit first).
    if s.photon_mapping:
        sharp_tri = (sharp_specular(table)[mat] if has_tris else np.zeros(0, bool)) & spec_tri
        rough_tri = spec_tri & ~sharp_tri
        ids, centers, radii, names = _object_spheres(geo, sharp_tri) if sharp_tri.any() else ([], np.zeros((0, 3)), np.zeros(0), [])
        rough_ids = np.setdiff1d(np.unique(geo.object_id[rough_tri]), ids) if rough_tri.any() else []
        plan.rough_specular = [geo.object_names[i] for i in rough_ids]
        reached = []
        if len(ids) and emitting and diff_tri.any():
            for oid, c, r, name in zip(ids, centers, radii, names):
                if any(_light_reaches(li, accel, geo, oid, c, r, rng) for li in emitting):
                    reached.append((oid, c, r, name))
        rough_reached = []
        if len(rough_ids) and emitting and diff_tri.any():
            _, rc, rr, rn = _object_spheres(geo, np.isin(geo.object_id, rough_ids) & rough_tri)
            for oid, c, r, name in zip(rough_ids, rc, rr, rn):
                if any(_light_reaches(li, accel, geo, oid, c, r, rng) for li in emitting):
                    rough_reached.append(name)
        rough_note = ""
        if plan.rough_specular:
            shown = plan.rough_specular[:4]
            rough_note = ("; not aimed at " + ", ".join(f"'{n}'" for n in shown)
                          + (" ..." if len(plan.rough_specular) > 4 else "")
                          + f" (specular roughness > {SHARP_ROUGHNESS:g}: too rough to focus "
                          "light; unaimed photons carry its glossy reflections)")
        if not spec_tri.any():
            auto, why = False, "no specular or refractive materials"
        elif not diff_tri.any():
            auto, why = False, "no diffuse surface to receive a caustic"
        elif reached:
            names_r = ", ".join(f"'{n}'" for _, _, _, n in reached)
            auto, why = True, (f"{s.caustic_photons:,} photons aimed at {names_r}{rough_note}"
                               if s.aim_caustics
                               else f"{s.caustic_photons:,} photons, from {names_r}{rough_note}")
        elif rough_reached:
            # Nothing to aim at: a soft glow is as dense in the global photons (a larger
            # shot) as in an unaimed caustic shot, so reuse them when there are any.
            plan.caustics_from_global = plan.indirect
            source = ("the global photons" if plan.indirect
                      else f"{s.caustic_photons:,} unaimed photons")
            auto, why = True, ("no sharp caustic caster; the glossy reflections of "
                               + ", ".join(f"'{n}'" for n in rough_reached[:4])
                               + (" ..." if len(rough_reached) > 4 else "")
                               + f" (specular roughness > {SHARP_ROUGHNESS:g}) come from {source}")
        else:
            all_names = list(names) + plan.rough_specular
            auto, why = False, ("no light reaches the mirror / glass object(s) "
                                + ", ".join(f"'{n}'" for n in all_names))
        plan.caustics = _override(s.caustics, auto, "caustics", why, plan)
        if plan.caustics and reached:
            plan.casters = [n for _, _, _, n in reached]
            plan.caster_ids = np.array([oid for oid, _, _, _ in reached], np.int64)
            plan.caster_spheres = (np.array([c for _, c, _, _ in reached]),
                                   np.array([r for _, _, r, _ in reached]))
        elif plan.caustics and len(ids):
            plan.caster_spheres = (centers, radii)
            plan.caster_ids = np.asarray(ids, np.int64)
            plan.casters = names

    # --- specular chains -------------------------------------------------------------------
    visible = _visible_specular(scene, geo, table, accel) if spec_tri.any() else []
    if not spec_tri.any():
        auto, why = False, "no mirror, glass or glossy coat in the scene"
    elif not visible:
        auto, why = False, "no mirror or glass is visible to the camera"
    else:
        auto, why = True, (f"up to {s.max_depth} bounces through "
                           + ", ".join(f"'{n}'" for n in visible[:4])
                           + (" ..." if len(visible) > 4 else ""))
    on = _override(s.specular, auto, "specular reflection / refraction", why, plan)
    plan.specular_depth = s.max_depth if on else 0

    # --- lights: soft shadows, shadow rays ------------------------------------------------
    nothing_occludes = has_tris and _single_flat_surface(geo, np.ones(geo.count, bool))
    for li in lights:
        if li.kind == WORLD:
            plan.light_samples[li.name] = s.light_samples
            plan.shadows[li.name] = has_tris
            plan.add("world light", True, "non-black background lights the scene "
                     "(cosine-weighted shadow rays)")
            continue
        sized = li.has_size
        if s.soft_shadows == "off":
            sized = False
        n_samples = s.light_samples if sized else 1
        plan.light_samples[li.name] = n_samples
        spp = s.spp
        if li.kind == MESH:
            why = f"{len(li.tri_index):,} emitting triangles sampled by area x brightness"
        elif sized:
            why = f"{n_samples * spp} shadow rays per pixel for '{li.name}'"
        else:
            what = {SUN: "sun of angle 0", AREA: "area light"}.get(li.kind, f"{li.kind.lower()} light of radius 0")
            why = f"'{li.name}' is a {what}: one shadow ray per sample"
        plan.add(f"soft shadows '{li.name}'", sized, why)
        casts = li.source is None or li.source.cast_shadow
        if not casts:
            plan.add(f"shadow rays '{li.name}'", False, "the light's 'Cast Shadow' is off")
        plan.shadows[li.name] = casts and not nothing_occludes
    if nothing_occludes and lights:
        plan.add("shadow rays", False, "the scene is a single flat surface: nothing can cast a shadow")
    if has_tris and np.any(luminance(table.emission[mat]) > 0):
        plan.add("emission", True, "emissive surfaces are drawn and sampled as lights")
    if has_tris and np.any(table.alpha[mat] < 1):
        names = sorted({table.names[m] for m in np.unique(mat[table.alpha[mat] < 1])})
        plan.add("transparency", True, "alpha below 1 in " + ", ".join(f"'{n}'" for n in names))
    return plan


def _single_flat_surface(geo: Geometry, mask: np.ndarray) -> bool:
    """All masked triangles lie in one plane (so none can light or shadow another)."""
    if not mask.any():
        return True
    n = geo.ng[mask]
    if np.any(np.abs(n @ n[0]) < 1.0 - 1e-9):
        return False
    # Flat to within what float32 (Embree's precision) resolves at these coordinates.
    corners = np.concatenate([geo.v0[mask], geo.v0[mask] + geo.e1[mask], geo.v0[mask] + geo.e2[mask]])
    h = corners @ n[0]
    return bool(np.ptp(h) <= 16.0 * float(ulp32(np.abs(corners).max())))


def _visible_specular(scene, geo, table, accel, probe=96) -> list:
    """Names of objects with a specular lobe that camera rays see (a probe grid)."""
    from .integrator import camera_rays
    W, H = scene.width, scene.height
    nx = min(W, probe)
    ny = min(H, max(1, int(round(probe * H / max(W, 1)))))
    xs = (np.arange(nx) + 0.5) / nx * W
    ys = (np.arange(ny) + 0.5) / ny * H
    px, py = np.meshgrid(xs, ys)
    px, py = px.ravel(), py.ravel()
    o, d, tmax = camera_rays(scene.camera, geo.offset, W, H, np.floor(px), np.floor(py),
                             px - np.floor(px), py - np.floor(py))
    _, prim, _, _ = accel.intersect(o, d, tmax)
    hit = prim[prim >= 0]
    spec = table.has_specular[geo.material[hit]]
    ids = np.unique(geo.object_id[hit[spec]])
    return [geo.object_names[i] for i in ids]
