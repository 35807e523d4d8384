"""Scene analysis: which effects this scene needs, and why.

Before any photon is shot, look at materials, lights, geometry and settings and decide
what work is worth doing; every decision carries a one-line reason that the CLI prints,
the add-on shows, and the Film's stats record. Each effect can be forced on or off
("on" / "off") instead of "auto".
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from .closures.ggx import ALPHA_MIN
from .closures.principled import M_ANISO
from .geometry import CAMERA, SHADOW, Geometry, MaterialTable
from .glossysplit import settings_filter_glossy, shots_unread
from .lights import MESH, WORLD, PreparedLight
from .lights.selection import selection_samples, tree_members
from .panelight import find_panes
from . import blurredpassage, photonclamp, raymaterials, shadelight, worldmedium
from .shadelight import find_shades
from .casterspheres import bounding_sphere, caster_spheres, per_caster
from .casterspheres import corner_pieces as _corner_pieces
from .casterspheres import triangle_pieces as _pieces
from .rayoffset import ulp32
from .sampling import luminance
from .scene import AREA, SUN
from .settings import CYCLES_DEFAULT_BOUNCES
from .worldgraph import WorldGraph

PROBE_RAYS = 512  # rays per (light, caster) pair when testing whether light can reach it
# A report line names at most this many objects, then says how many more (a scene of
# hundreds of instances read as a wall of names).
REPORT_NAMES_MAX = 8
# A specular lobe focuses light into a caustic only if it is sharp. Our microfacet lobes
# have alpha = roughness^2, about the lobe's angular half-width in radians: at roughness
# 0.3 that is ~5 degrees, at Principled's default 0.5 already ~14 degrees, which spreads
# a reflected light over a patch half as wide as its distance - a soft glow that the
# unaimed photons carry as well as aimed ones. A transparent pass (alpha < 1) casts no
# caustic: shadow rays cross it (engine/shadowtransmittance.py), so light through it is
# direct light.
# The bound is exclusive, and a roughness within SHARP_TOLERANCE of it counts as rough:
# Blender hands over float32 (0.3 arrives as 0.30000001), so a `<=` made a 0.3 floor rough
# when exported and a caster when built headless. Aimed at, a rough metal floor of 0.3
# turned light_area_spread_glossy's block error to 0.58 (docs/compatibility.md); as
# rough, its glow comes from unaimed photons (engine/render.py, GLOW_STREAM).
SHARP_ROUGHNESS = 0.3
SHARP_TOLERANCE = 1e-6


def object_materials(geo: Geometry, oid: int) -> np.ndarray:
    """(K,) int64 the distinct material indices of object oid's triangles, sorted: what
    object_materials(geo, oid) gives, from a table of every object's
    materials made once per geometry (one np.unique of object x material codes) and
    kept on it, so that asking for each of many objects costs no pass over every
    triangle (2,000 objects of 2M triangles took ~2 CPU s that way)."""
    mat = geo.material
    obj = geo.object_id
    key = (id(mat), id(obj), len(mat))
    entry = getattr(geo, "_object_materials", None)
    if entry is None or entry[0] != key:
        m = np.asarray(mat, np.int64)
        n_mat = int(m.max()) + 1 if len(m) else 1
        codes = np.unique(np.asarray(obj, np.int64) * n_mat + m)
        # (floor division and modulo keep the pairs of a negative object id too)
        entry = (key, codes // n_mat, codes % n_mat)
        geo._object_materials = entry
    _, objs, mats = entry
    a, b = np.searchsorted(objs, (oid, oid + 1))
    return mats[a:b]


def is_sharp(roughness) -> np.ndarray:
    """Roughness (any shape) sharp enough to focus light: below SHARP_ROUGHNESS by more
    than float32's rounding (SHARP_TOLERANCE), whatever precision the value came in."""
    return np.asarray(roughness, np.float64) < SHARP_ROUGHNESS - SHARP_TOLERANCE


def sharp_specular(table: MaterialTable) -> np.ndarray:
    """(M,) bool: materials with a lobe sharp enough to focus light (a caustic caster): a
    metal, glass or dielectric specular lobe of roughness below SHARP_ROUGHNESS
    (is_sharp), a Principled coat of coat roughness below it (a clear-coated rough
    base). A transparent
    pass is none (shadow rays cross it)."""
    from .closures import principled as pr
    dielectric = (1 - table.metallic) * (1 - table.transmission)
    main = ((table.metallic * table.base_color.max(axis=1) > 0) | (table.transmission > 0)
            | (dielectric * table.specular > 0))
    coat = np.zeros(len(table.alpha), bool)
    if table.closure_params is not None and table.coat_weight is not None:
        coat = ((table.coat_weight > 0)
                & is_sharp(table.closure_params[:, pr.M_COAT_ROUGH]))
    return table.has_specular & ((main & is_sharp(table.roughness)) | coat)


# Rough refractors (transmission too rough to focus light: not sharp_specular) are aimed
# at by the caustic shot where its photons are read (rough_refractors; roughcaustic48).
# Their light through them onto diffuse surfaces comes from the caustic map alone at Filter
# Glossy 0 (no shadow ray crosses rough glass; the final gather reads the maps past it),
# which unaimed, it read from the global shot's few caustic-kind photons: Caustic Photons
# did not reach it (docs/accuracy.md "roughphoton47", "roughcaustic48"). False: they are
# unaimed glow, as before (the benchmark's "before").
AIM_ROUGH_REFRACTORS = True


def rough_refractive(table: MaterialTable) -> np.ndarray:
    """(M,) bool: materials with a refraction lobe (Glass BSDF, Principled Transmission)
    too rough to focus light: has_specular, transmission > 0, not sharp_specular."""
    return (np.asarray(table.has_specular, bool) & (np.asarray(table.transmission) > 0)
            & ~sharp_specular(table))


def rough_refractors(geo: Geometry, table: MaterialTable, emitting: list, accel, settings,
                     indirect: bool, rough_tri: np.ndarray, diff_tri: np.ndarray,
                     shades=None, sharp_tri=None) -> np.ndarray:
    """(K,) int64: the object ids of rough refractors (rough_refractive triangles among
    rough_tri (T,) bool, the plan's rough specular triangles: window and single-plane
    glass are not among them) that the caustic shot aims at, as at sharp casters: where
    AIM_ROUGH_REFRACTORS, caustic photons are traced (settings.caustic_photons > 0), some
    is read (not glossysplit.shots_unread: at Filter Glossy above 1/pi on matte surfaces
    the final gather's blurred chains carry that light and no caustic shot is traced),
    some diffuse surface (diff_tri) can receive the light and a light in `emitting`
    reaches the object first (_light_reaches, PROBE_RAYS photons), and the caustic shot
    would send more photons at it than the global shot does: aiming replaces the global
    shot's caustic-kind photons of those paths (render.py's partition by first hit). The
    aimed: settings.caustic_photons x its share of the aimed shot beside the sharp
    casters (sharp_tri (T,) bool: their triangles; each light's Light.aim probability of
    its bounding sphere among theirs, the lights weighted by the power they send into
    all of them, as render._allocate_aimed); the global: settings.photons x the share of
    the lights' power their natural emission sends into its sphere (_natural_share; 0
    without indirect light: then no global shot). So a lamp inside a rough glass globe,
    whose every photon meets it, keeps the global shot's (400,000 at the defaults, not
    200,000) until Caustic Photons is the larger count, and a shower screen beside a
    room of glossy tiles, which take most of the aimed shot, keeps its glow shot. A rough glass lamp shade
    (shadelight.Shades.glass_names) counts only lights it does not serve: a served
    lamp's light through it is direct (its shadow rays), its photons there direct-kind,
    which the caustic shot does not keep."""
    none = np.zeros(0, np.int64)
    if (not AIM_ROUGH_REFRACTORS or not emitting or not np.any(rough_tri)
            or not diff_tri.any() or settings.caustic_photons <= 0
            or shots_unread(settings, geo, table, indirect)):
        return none
    tri = rough_tri & rough_refractive(table)[geo.material]
    if not tri.any():
        return none
    served = list(shades.lights) if shades is not None else []
    shade_names = set(shades.glass_names) if shades is not None else set()
    rng = np.random.default_rng([settings.seed, 99, 48])
    oids, centers, radii, names = _object_spheres(geo, tri)
    power = sum(float(luminance(np.asarray(li.photon_flux))) for li in emitting)
    sharp_c, sharp_r = np.zeros((0, 3)), np.zeros(0)
    if sharp_tri is not None and sharp_tri.any():
        _, sharp_c, sharp_r, _ = _object_spheres(geo, sharp_tri)
    out = []
    for oid, c, r, name in zip(oids, centers, radii, names):
        lights = [li for li in emitting
                  if name not in shade_names or not any(li is x for x in served)]
        if not any(_light_reaches(li, accel, geo, int(oid), c, r, rng) for li in lights):
            continue
        through = (settings.photons * sum(_natural_share(li, c, r, rng) for li in lights)
                   / max(power, 1e-300) if indirect else 0.0)
        # Its share of the aimed shot: each light's choice of its sphere among the sharp
        # casters' and its own, the lights by the power they send into all of them.
        cen, rad = np.vstack([sharp_c, c[None, :]]), np.append(sharp_r, r)
        share = weight = 0.0
        for li in emitting:
            w = _natural_share(li, cen, rad, rng)
            weight += w
            if w > 0.0 and any(li is x for x in lights):
                share += w * float(np.asarray(li.aim(cen, rad).probs)[-1])
        aimed = settings.caustic_photons * share / weight if weight > 0.0 else 0.0
        if aimed > through:
            out.append(int(oid))
    return np.array(out, np.int64)


def _natural_share(light: PreparedLight, center, radius, rng) -> float:
    """The luminance of the power (W) that light's natural emission sends into the cones
    of the spheres (center (3,) or (K,3), radius () or (K,)) (from infinity: across
    their shadow disks): the aimed photons' power weights (natural pdf / aimed pdf) over
    PROBE_RAYS of them."""
    _, _, power = light.emit_towards(PROBE_RAYS, rng, np.reshape(center, (-1, 3)),
                                     np.reshape(np.asarray(radius, np.float64), -1))
    return float(luminance(power.sum(axis=0))) if len(power) else 0.0


def _focusing(table: MaterialTable) -> np.ndarray:
    """(M,) bool: materials with a mirror, glass, coat or translucent lobe (has_specular
    without the transparent pass, which camera rays continue through but which focuses
    nothing). A translucent lobe focuses nothing either, but the light it lets through
    travels as caustic-kind photons (the camera side continues the lobe, as a rough
    glossy one), so it is planned as a rough lobe's glow: never aimed at (not sharp)."""
    dielectric = (1 - table.metallic) * (1 - table.transmission)
    coat = (table.coat_weight > 0) if table.coat_weight is not None else False
    tl = (table.translucent > 0) if table.translucent is not None else False
    return ((table.metallic * table.base_color.max(axis=1) > 0) | (table.transmission > 0)
            | (dielectric * table.specular > 0) | coat | tl)


# What each teaching method does: the effect report's first line (settings.METHODS).
METHOD_TEXT = {
    "local": "local illumination: each light's direct light without shadow rays; no "
             "shadows, reflections, refractions or photon maps (emission and background "
             "shown)",
    "raytrace": "ray tracing (paper Fig. 5b): shadows, mirror reflection and refraction; "
                "no indirect diffuse light, no caustics",
    "photon": "photon mapping: ray tracing plus indirect diffuse light and caustics from "
              "photon maps",
}


@dataclass
class Decision:
    effect: str
    enabled: bool
    reason: str

    def __str__(self):
        return f"{self.effect}: {'on' if self.enabled else 'off'} - {self.reason}"


@dataclass
class EffectPlan:
    method: str | None = "photon"  # settings.METHODS: its line opens the report (None: none)
    caustics: bool = False
    indirect: bool = False
    specular_depth: int = 0                          # camera-path specular bounces
    light_samples: dict = field(default_factory=dict)  # light name -> shadow rays / sample
    shadows: dict = field(default_factory=dict)        # light name -> trace shadow rays?
    casters: list = field(default_factory=list)        # names of caustic-casting objects
    caster_spheres: tuple = (np.zeros((0, 3)), np.zeros(0))
    caster_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # their object ids
    # the object id of each of caster_spheres (a caster may have several: casterspheres.py)
    caster_sphere_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    rough_specular: list = field(default_factory=list)  # specular objects too rough to focus
    window_glass: list = field(default_factory=list)    # thin flat glass: shadow rays pass it
    pane_glass: list = field(default_factory=list)      # single-plane glass only suns light
    caustics_from_global: bool = False  # caustic map from the global shot, no caustic shot
    caustics_glow_only: bool = False  # the caustic map holds only rough layers' / window glow
    glow_words: str = ""  # what that glow-only map holds, for the maps line (only what exists)
    # What the surfaces the soft glow comes off are, in Blender's words ("glossy",
    # "glass", "translucent", joined by "/"): the glow shot's progress line "Tracing
    # glossy photons" and the maps line that explains it (render.py GLOW_SHOT).
    glow_label: str = ""
    trapped: dict = field(default_factory=dict)  # light name -> closed mesh it is shut in
    # light name -> share of the probed bounce light Cycles' Indirect clamp cuts from it
    # (clamped_bounce_light; only where that clamp is on)
    clamped: dict = field(default_factory=dict)
    # light name -> share of the casters' caustic light / the light seen through glass
    # that clamp cuts from it (clamped_caustics, clamped_through_glass)
    clamped_caustics: dict = field(default_factory=dict)
    clamped_glass: dict = field(default_factory=dict)
    decisions: list = field(default_factory=list)
    warnings: list = field(default_factory=list)  # students' mistakes, explained

    def add(self, effect, enabled, reason):
        self.decisions.append(Decision(effect, bool(enabled), reason))

    def report(self) -> list[str]:
        lines = [str(d) for d in self.decisions]
        if self.method in METHOD_TEXT:
            lines.insert(0, f"method: {self.method} - {METHOD_TEXT[self.method]}")
        return lines


def _summarise_many_lights(plan: EffectPlan, lights, s) -> None:
    """Many lights (the light tree picks them, engine/lights/selection.py): the per-light
    soft-shadow and shadow-ray lines become a few summary lines."""
    per_light = [d for d in plan.decisions
                 if d.effect.startswith("soft shadows '") or d.effect.startswith("shadow rays '")]
    gone = {id(d) for d in per_light}
    plan.decisions = [d for d in plan.decisions if id(d) not in gone]
    sized = sum(1 for d in per_light if d.effect.startswith("soft shadows '") and d.enabled)
    dark = [d.effect[len("shadow rays '"):-1] for d in per_light
            if d.effect.startswith("shadow rays '")]
    plan.add("light tree", True,
             f"{len(lights)} lights: each shadow ray goes to one light chosen by power, "
             f"distance and orientation ({selection_samples(s)} per sample)")
    plan.add("soft shadows", sized > 0,
             f"{sized} of {len(lights)} lights have a size" if sized else "no light has a size")
    if dark:
        names = _quoted(dark, most=3)
        plan.add("shadow rays", True, f"{len(dark)} lights cast no shadow ('Cast Shadow' "
                 f"off: {names})")


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


def filter_glossy_alpha(filter_glossy, diffuse_pdf) -> np.ndarray:
    """The GGX alpha below which Cycles' Filter Glossy widens a glossy, mirror or glass
    lobe met after a diffuse bounce of direction pdf `diffuse_pdf` (1/sr; cos / pi for a
    Lambert bounce, so at most 1/pi): 0.5 sqrt(1 - pdf / filter_glossy) where
    pdf / filter_glossy < 1, else 0 (Cycles' surface_shader_prepare_closures: blur_pdf =
    min_ray_pdf / Filter Glossy, bsdf_blur raises alpha to max(alpha, blur_roughness)).
    At Filter Glossy 1, after a Lambert bounce: 0.41 (a normal bounce) to 0.5 (grazing).
    The camera paths' own formula (engine/filterglossy.py blur_alpha, over arrays)."""
    from .filterglossy import blur_alphas
    return blur_alphas(filter_glossy, diffuse_pdf)


def _strong_reflector(geo: Geometry, table: MaterialTable, oid: int) -> bool:
    """Whether object oid reflects or refracts much of the light it meets by a specular
    lobe: glass, a mirror, a metal (specular_kind), a Glossy BSDF, or a dielectric
    specular layer sharp enough to focus light ("glossy": at grazing angles it reflects
    most of what it meets; newuser41: a wet road of roughness 0.05 under a sky lit the
    wall beside it 1.07x Cycles at Filter Glossy 1, 1.003 at 0)."""
    if specular_kind(geo, table, oid) in ("glass", "mirror", "polished metal", "metal",
                                          "glossy"):
        return True
    return bool(np.any(_is_glossy_node(table, object_materials(geo, oid))))


def _filter_glossy_note(plan: EffectPlan, filter_glossy: float, names,
                        split: bool = False, clamped: bool = True) -> None:
    """The "glossy blur" line: Cycles' Filter Glossy (the scene's, read by the add-on) is
    on and light reaches diffuse surfaces off specular ones here (the caustic map's L S+ D
    paths), which Cycles renders through blurred lobes (glow36: a roughness 0.4 metal
    block on a diffuse floor, the floor beside it 1.19x Cycles at its default 1.0 without
    the blur, within 5 % of Cycles at 0). split: engine/glossysplit.py renders those
    paths blurred too (on: Filter Glossy above 0, final gathering); else ours does not
    blur. clamped: Clamp Indirect is on (the clamp's clause only then)."""
    if not names:
        return
    lo, hi = (float(a) for a in filter_glossy_alpha(filter_glossy, [1.0 / math.pi, 0.0]))
    said = (f"Cycles' Light Paths > Caustics > Filter Glossy is {filter_glossy:g}: Cycles "
            "widens the glossy, mirror and glass lobes its paths meet after a diffuse "
            f"bounce (to GGX alpha {lo:.2f}-{hi:.2f}, roughness {math.sqrt(lo):.2f}-"
            f"{math.sqrt(hi):.2f}), which spreads and dims the light "
            + _quoted(names, most=REPORT_NAMES_MAX) + " throw"
            + ("" if len(names) > 1 else "s") + " onto diffuse surfaces")
    if split:
        plan.add("glossy blur", True,
                 said + "; so does ours: that light comes through the final gather's "
                 "rays, their lobes blurred as Cycles', not from the caustic photons "
                 "(light off them after a further diffuse bounce stays unblurred); at "
                 "Filter Glossy 0 both render sharp caustics, ours from the caustic "
                 "photons" + ((", each clamped as the Cycles path it ends (see the "
                               "clamping line)" if photonclamp.PER_PHOTON else
                               ", whose smooth estimates Cycles' clamp does not cut as it "
                               "cuts its own rare bright samples (see the clamping line "
                               "then)") if clamped else ""))
        return
    # (fgroom46: the camera paths' own lobes blur at any Filter Glossy, filterglossy.py;
    # only the maps' light named here stays unblurred without the split.)
    from .filterglossy import BLUR_CAMERA_PATHS
    own = " (only its camera paths' own lobes, as Cycles)" if BLUR_CAMERA_PATHS else ""
    plan.add("glossy blur", False,
             said + f"; ours does not blur that light{own}, so that light matches Cycles "
             "with Filter Glossy 0 (sharp caustics in both): set that to compare")


def _cycles_caustics_note(plan: EffectPlan, s, geo: Geometry, table: MaterialTable,
                          names) -> None:
    """The "Cycles' caustics" line: Cycles' Light Paths > Caustics > Reflective or
    Refractive (the scene's, read by the add-on) is off and light reaches diffuse surfaces
    off specular ones here (names: the objects whose specular light does, besides the
    window and single-plane glass of the plan). With the switch off, Cycles drops the
    glossy-reflection / transmission closures its paths meet after a diffuse bounce
    (intern/cycles/kernel/integrator/surface_shader.h, surface_shader_prepare_closures
    under __CAUSTICS_TRICKS__) and its shadow rays stop at glass, so that light is
    missing from its image: a room lit through a window pane loses the sun patch and the
    sky's light (newuser40's room: no patch in Cycles, ours within 0.2 % of Cycles with
    the switches on and its clamp off). Only named, as Filter Glossy: the engine renders
    that light (Cycles with the switches on). Translucent surfaces are diffuse
    transmission, which the switch leaves alone."""
    ids_of = {n: i for i, n in enumerate(geo.object_names)}
    glass = ([n for n in names if specular_kind(geo, table, ids_of[n]) == "glass"]
             + list(plan.window_glass) + list(plan.pane_glass))
    mirrors = [n for n in names if n not in glass and _strong_reflector(geo, table, ids_of[n])]
    off = []  # in the order of Cycles' panel
    if not s.cycles_caustics_reflective and mirrors:
        off.append(("Reflective", "off", mirrors))
    if not s.cycles_caustics_refractive and glass:
        off.append(("Refractive", "through", glass))
    if not off:
        return
    switches = " and ".join(k for k, _, _ in off)
    sources = " and ".join(f"{w} {_quoted(n, most=REPORT_NAMES_MAX)}" for _, w, n in off)
    plan.add("Cycles' caustics", False,
             f"Cycles' Light Paths > Caustics > {switches} "
             + ("are" if len(off) > 1 else "is") + " off: Cycles leaves out the light "
             f"that reaches diffuse surfaces {sources} (a sun patch through a window, the "
             "caustic of a glass or a mirror)"
             + (", and its shadow rays stop at glass" if glass and off[-1][1] == "through"
                else "") + ", so its image is darker there; ours renders that light, as Cycles with "
             + ("them" if len(off) > 1 else "it") + " on: turn "
             + ("them" if len(off) > 1 else "it") + " on to compare (a sun seen through "
             "smooth glass then comes to Cycles' paths in rare bright samples: it needs "
             "many samples, and no clamp, to show the patch ours shows)")


def layer_reflectance(table: MaterialTable, mats) -> tuple:
    """(at normal incidence, averaged over a diffuse incidence) reflectance of the
    strongest dielectric specular layer (a Principled base's specular layer or its coat)
    among materials mats: F0 = ((n - 1) / (n + 1))^2 of the layer's IOR (the base's
    scaled by 2 x Specular IOR Level, as principled.setup) and Kulla and Conty's average
    Fresnel Fss = (eta - 1) / (4.08567 + 1.00071 eta) (fresnel.fresnel_dielectric_Fss),
    each times the coat's weight for a coat. (0, 0) without such a layer."""
    from .closures import fresnel, principled as pr
    q = np.asarray(table.closure_params, np.float64)[np.asarray(mats, np.int64)]
    f0s, fss = [0.0], [0.0]

    def add(ior, scale, weight):
        for n, k, w in zip(ior, scale, weight):
            if w > 0.0:  # (a few material rows: the scalar kernels called from Python)
                f0 = min(fresnel.F0_from_ior(max(float(n), 1e-5)) * float(k), 0.9999999)
                f0s.append(w * f0)
                fss.append(w * fresnel.fresnel_dielectric_Fss(fresnel.ior_from_F0(f0)))
    add(q[:, pr.M_IOR], 2.0 * np.maximum(q[:, pr.M_LEVEL], 0.0),
        np.where(q[:, pr.M_SPEC] > 0.0, 1.0, 0.0) * (1.0 - q[:, pr.M_METALLIC])
        * (1.0 - q[:, pr.M_TRANS]))
    add(np.maximum(q[:, pr.M_COAT_IOR], 1.0), np.ones(len(q)),
        np.maximum(q[:, pr.M_COAT_W], 0.0))
    return max(f0s), max(fss)


def _aimed_words(geo: Geometry, table: MaterialTable, names, refractors) -> str:
    """The caustics line's words after the aimed casters `names` where some are not plain
    mirrors, glass or metal (roughcaustic48): rough refractors (`refractors`, aimed at by
    rough_refractors) focus no light, but the caustic map alone carries the light through
    them, so they are aimed at for it; a dielectric specular layer alone (a Principled
    plastic or glazed tile, no metal, Glossy BSDF or transmission) reflects a few per
    cent (layer_reflectance), so most photons aimed at it end in its diffuse base and are
    not stored (newuser47's tiles, roughness 0.15: 3,059 of 200,000 stored). "" where
    every caster is plain."""
    out = ""
    if len(refractors):
        many = len(refractors) > 1
        out += ("; rough " + _labelled(geo, table, refractors, most=REPORT_NAMES_MAX)
                + (" focus" if many else " focuses") + " no light, but the light "
                + ("they let" if many else "it lets") + " through onto diffuse surfaces "
                "comes from these photons alone (the Caustic pass), so Caustic Photons "
                "sets how smooth it is")
    ids = {n: i for i, n in enumerate(geo.object_names)}
    weak, lo, hi = [], 1.0, 0.0
    for n in names:
        if n not in ids or n in refractors:
            continue
        mats = object_materials(geo, ids[n])
        if (specular_kind(geo, table, ids[n]) != "glossy" or np.any(_is_glossy_node(table, mats))
                or np.any(table.metallic[mats] > 0) or np.any(table.transmission[mats] > 0)):
            continue
        f0, fss = layer_reflectance(table, mats)
        if not fss > 0.0:
            continue
        weak.append(n)
        lo, hi = min(lo, f0), max(hi, fss)
    if weak:
        many = len(weak) > 1
        out += ("; " + _quoted(weak, most=4) + " reflect" + ("" if many else "s")
                + f" only about {100 * lo:.0f}-{100 * hi:.0f} % of the light by "
                + ("their" if many else "its") + " glossy specular layer (a dielectric's "
                "Fresnel reflection, at normal to diffuse incidence): only those photons "
                "can make a caustic; the rest end in " + ("their" if many else "its")
                + " diffuse base, not stored")
    return out


def shot_words(lines: list, stats: dict) -> list:
    """The report `lines` (EffectPlan.report) with the caustics line ("caustics: on - N
    photons aimed at ...") followed by how many of the caustic shot's photons were stored
    (stats caustic_shot_stored, caustic_photons_emitted: render._photon_pass, where the
    shot was traced): a new user read "200,000 photons aimed at" glossy tiles beside the
    maps line's 3,059 caustic photons (newuser47). A new list; the plan is not changed (a
    session reuses it)."""
    stored, emitted = stats.get("caustic_shot_stored"), stats.get("caustic_photons_emitted")
    if stored is None or not emitted:
        return list(lines)
    aimed = "aimed " if stats.get("caustic_shot_aimed") else ""
    words = (f"; {stored:,} of the {emitted:,} {aimed}photons stored "
             f"({100.0 * stored / emitted:.1f} %)")
    return [ln + words if ln.startswith("caustics: on - ") else ln for ln in lines]


def _volume_only(geo: Geometry, table: MaterialTable, name: str) -> bool:
    """Whether object `name`'s triangles are all of volume-only materials (Material.
    volume_only: a medium's invisible boundary)."""
    if table.volume_only is None or name not in geo.object_names:
        return False
    mats = object_materials(geo, geo.object_names.index(name))
    return bool(len(mats)) and bool(np.all(table.volume_only[mats]))


def _object_spheres(geo: Geometry, tri_mask: np.ndarray):
    """Bounding spheres (centre, radius) and names of objects owning the masked triangles."""
    ids = np.unique(geo.object_id[tri_mask])
    centers, radii, names = [], [], []
    for oid in ids:
        c, r = bounding_sphere(geo, np.nonzero(tri_mask & (geo.object_id == oid))[0])
        centers.append(c)
        radii.append(r)
        names.append(geo.object_names[oid])
    return ids, np.array(centers).reshape(-1, 3), np.array(radii), names


def _aim_spheres(geo: Geometry, tri_mask: np.ndarray, ids: np.ndarray, roots: dict) -> tuple:
    """The spheres caustic photons aim at: ((centers (K,3), radii (K,)), owner object id
    (K,)) for casters ids, each one or a few spheres around its masked triangles
    (casterspheres.caster_spheres, at most per_caster(len(ids)) each); roots: object id
    -> its bounding sphere (centre, radius) from _object_spheres."""
    most = per_caster(len(ids))
    centers, radii, owners = [], [], []
    for oid in ids:
        if most <= 1:  # (many casters: no pass over the triangles per caster)
            c, r = roots[int(oid)]
            c, r = np.asarray(c, np.float64)[None, :], np.array([r], np.float64)
        else:
            c, r = caster_spheres(geo, np.nonzero(tri_mask & (geo.object_id == oid))[0],
                                  most, roots[int(oid)])
        centers.append(c)
        radii.append(r)
        owners.append(np.full(len(r), oid, np.int64))
    return ((np.concatenate(centers).reshape(-1, 3), np.concatenate(radii)),
            np.concatenate(owners))


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


def _enclosing_object(accel, geo: Geometry, table: MaterialTable, o, d) -> int:
    """The object that rays (o, d) all hit first from its inside (the back of its
    triangles, by winding) when it is opaque (no transmission or translucency, alpha 1):
    the closed mesh the origins are shut in. -1 if any ray escapes or meets anything
    else. (A closed globe of Translucent BSDF around a lamp lets its light out: it read
    as a trap, which switched the indirect light off and left the room black.)"""
    _, prim, _, _ = accel.intersect(o, d)
    if len(prim) == 0 or np.any(prim < 0):
        return -1
    ids = geo.object_id[prim]
    if np.any(ids != ids[0]) or np.any(np.einsum("ij,ij->i", d, geo.ng[prim]) <= 0):
        return -1
    mat = geo.material[prim]
    if np.any(table.transmission[mat] > 0) or np.any(table.alpha[mat] < 1):
        return -1
    if table.translucent is not None and np.any(table.translucent[mat] > 0):
        return -1
    return int(ids[0])


def trapped_lights(scene, geo: Geometry, table: MaterialTable, lights: list, accel,
                   rng) -> dict:
    """{light name: mesh name} for declared lights shut inside a closed opaque mesh that
    the camera is outside of: every photon and shadow ray of such a light stays inside,
    so its light reaches nothing the camera sees. Found with PROBE_RAYS photons per
    light (all must hit the mesh from inside) and as many rays from the camera. The
    probes leave the light's emission points in every direction, not along its emission:
    a spot or an area light aimed at the back of an open sheet (a bounce card) sends
    every photon into the sheet's back, yet it is not shut in anything."""
    if geo.count == 0 or scene.camera is None:
        return {}
    out = {}
    cam = None
    for li in lights:
        if li.source is None or li.kind in (SUN, WORLD):
            continue
        o, _, _ = li.emit(PROBE_RAYS, rng)
        d = rng.normal(size=o.shape)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        oid = _enclosing_object(accel, geo, table, np.ascontiguousarray(o), d)
        if oid < 0:
            continue
        if cam is None:
            u = rng.normal(size=(PROBE_RAYS, 3))
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            p = np.broadcast_to(scene.camera.position - geo.offset, u.shape)
            cam = _enclosing_object(accel, geo, table, np.ascontiguousarray(p), u)
        if cam != oid:
            out[li.name] = geo.object_names[oid]
    return out


def shadow_passed(geo, table) -> np.ndarray:
    """(T,) bool: triangles whose material shadow rays see as another one that lets them
    through (a Light Path variant with alpha < 1: Mix Shader(Is Shadow Ray, Glass,
    Transparent); engine/raymaterials.py)."""
    other = raymaterials.differs(table, SHADOW)
    if not other.any() or getattr(geo, "shared", None) is not None:
        return np.zeros(geo.count, bool)
    seen = raymaterials.triangle_materials(geo, table, SHADOW)
    return other[geo.material] & (np.asarray(table.alpha)[seen] < 1.0)


def _light_path_line(plan, geo, table) -> None:
    """The report's line on materials that read Light Path (engine/raymaterials.py): which
    ray classes meet another surface on which objects."""
    parts = []
    for key, cls in raymaterials.VARIANT_CLASSES.items():
        other = raymaterials.differs(table, cls)
        if not other.any() or getattr(geo, "shared", None) is not None:
            continue
        tri = other[geo.material]
        if not tri.any():
            continue
        names = [geo.object_names[i] for i in np.unique(geo.object_id[tri])]
        what = f"{key} rays see another surface on {_quoted(names, most=4)}"
        if key == "shadow":
            passed = np.unique(geo.object_id[shadow_passed(geo, table)])
            if len(passed):
                what += (" (transparent to them: " + _quoted(
                    [geo.object_names[i] for i in passed], most=4)
                    + " passes direct light by shadow rays, no caustic photons aimed at it)")
        parts.append(what)
    if parts:
        plan.add("Light Path in materials", True,
                 "; ".join(parts) + "; photons and diffuse rays see the material itself")


def _subsurface_line(plan: EffectPlan, geo: Geometry, table: MaterialTable, s,
                     has_tris: bool) -> None:
    """Says which surfaces scatter beneath them (Principled Subsurface Weight > 0, the
    Subsurface Scattering node) and how: the random walk (engine/subsurfacewalk.py) for
    camera paths, the diffuse stand-in (engine/subsurface.py) for photons and gather rays,
    or the stand-in alone where the walk is off. A subsurface candle read as a plain
    diffuse one would otherwise look like a bug (studio48)."""
    params = getattr(table, "subsurface", None) or []
    if not has_tris or not any(p is not None for p in params):
        return
    used = [int(m) for m in np.asarray(geo.used_materials(), np.int64)
            if m < len(params) and params[m] is not None]
    if not used:
        return
    materials = _quoted(sorted({table.names[m] for m in used}), most=REPORT_NAMES_MAX)
    names = materials
    if getattr(geo, "shared", None) is None and getattr(geo, "object_names", None):
        # The objects, as the report's other lines name them (newuser53: 'Wax' alone
        # beside the caustics line's 'CandleTall'), with their material.
        ids = np.unique(geo.object_id[np.isin(geo.material, used)])
        objects = _quoted(sorted(geo.object_names[i] for i in ids), most=REPORT_NAMES_MAX)
        plural = "s" if len(used) > 1 else ""
        names = f"{objects} (material{plural} {materials})"
    stand_in = ("a diffuse surface of the albedo Cycles' random walk gives a thick object "
                "of its Base Color")
    if not getattr(s, "subsurface_walk", True):
        plan.add("subsurface", False, f"{names} shaded as {stand_in} (Subsurface Random "
                 "Walk is off)")
    elif getattr(geo, "shared", None) is not None:
        # (subsurfacewalk.SubsurfaceWalks.for_context: instanced rows have no per-object
        # BVH to walk in yet)
        plan.add("subsurface", False, f"{names} shaded as {stand_in}: the scene keeps its "
                 "instances as placements, in which no walk runs yet")
    else:
        later = ("photons and final-gather rays that reach them" if s.uses_photon_maps
                 else "rays that reach them after a bounce")
        plan.add("subsurface", True, f"camera paths walk beneath {names} as Cycles' Random "
                 f"Walk does (light enters and leaves at different points); {later} see "
                 f"{stand_in}")


def analyse(scene, geo: Geometry, table: MaterialTable, lights: list, accel, settings,
            probe_clamp: bool = True) -> EffectPlan:
    # probe_clamp: measure what Cycles' Indirect clamp cuts for the clamping line
    # (clamped_bounce_light, ~0.1-0.3 s); a viewport session, which shows no report,
    # leaves it out.
    plan = EffectPlan()
    s = settings
    rng = np.random.default_rng([s.seed, 99])
    reached = []  # (object id, centre, radius, name) of the casters a light reaches
    mat = geo.material
    has_tris = geo.count > 0
    emitting = [li for li in lights if float(luminance(np.asarray(li.photon_flux))) > 0]
    spec_tri = table.has_specular[mat] if has_tris else np.zeros(0, bool)
    # Light Path in a material: what the camera meets is its camera variant
    # (engine/raymaterials.py; the same array without one).
    cam_mat = raymaterials.triangle_materials(geo, table, CAMERA) if has_tris else mat
    if cam_mat is not mat:
        spec_tri = spec_tri | table.has_specular[cam_mat]
    _light_path_line(plan, geo, table)
    diff_tri = table.has_diffuse[mat] if has_tris else np.zeros(0, bool)
    # Single-plane glass panes whose suns' and world's shadow rays refract through them
    # (engine/panelight.py; none under method 'local'): the caustics, sun and world lines
    # read it.
    panes = find_panes(geo, table, lights, s) if has_tris else None
    # Lamps through Translucent BSDF shades by shadow rays (engine/shadelight.py).
    shades = find_shades(geo, table, lights, s) if has_tris else None

    # --- lights shut inside a closed mesh (a student's mistake, explained) -------------
    plan.trapped = trapped_lights(scene, geo, table, emitting, accel,
                                  np.random.default_rng([s.seed, 96]))
    for name, mesh in plan.trapped.items():
        plan.warnings.append(
            f"light '{name}' is inside the closed mesh '{mesh}' (the camera is outside it): "
            f"all its photons and shadow rays stay inside '{mesh}', so none of its light "
            "reaches what the camera sees; move the light out of the mesh or delete the "
            "mesh's faces that are in the way")
    shut_in = [li for li in emitting if li.name in plan.trapped]
    if shut_in and len(shut_in) == len(emitting):
        emitting = []  # nothing the camera sees can receive light

    # --- the method (settings.METHODS) and photon mapping at all (the paper's switch) ---
    # A method is a set of the switches below: local and raytrace turn photon mapping off,
    # local also the shadow rays and the specular chains.
    photon_mapping = s.uses_photon_maps
    # The report's first line names the method unless photon mapping is switched off
    # the paper's way (then its own line says so).
    plan.method = s.method if (s.method != "photon" or s.photon_mapping) else None
    if not photon_mapping:
        plan.add("photon mapping", False,
                 f"method '{s.method}' has no photon maps: no indirect diffuse light, no "
                 "caustics" if s.method != "photon"
                 else "switched off: plain ray tracing (paper Fig. 5b)")

    # --- indirect diffuse (global map) -------------------------------------------------
    if not photon_mapping:
        plan.indirect = False
    else:
        if not emitting and plan.trapped:
            auto, why = False, ("every light is shut inside a closed mesh: "
                                + _quoted(sorted(set(plan.trapped.values())), most=None))
        elif not emitting:
            auto, why = False, "no light emits power"
        elif not diff_tri.any():
            auto, why = False, "no diffuse surface with non-zero albedo"
        elif (_single_flat_surface(geo, diff_tri | spec_tri)
              and not (worldmedium.active(scene)
                       and np.any(scene.world_medium.scattering > 0))):
            # (in a scattering world volume its final-gather rays find the fog's glow)
            auto, why = False, "a single flat surface cannot light itself"
        elif s.photons <= 0:
            # (newuser42: "on - 0 photons" while the image missed its bounce light)
            auto, why = False, ("Photons is 0: the light that bounces off diffuse "
                                "surfaces is missing from the image; set Photons above 0")
        else:
            most = (" at most (fewer where the indirect light is a small share)"
                    if s.gather_by_share else "")
            # (render.global_photon_count: a pilot sizes the shot under a world or a sun)
            fewer = (" at most" if s.gather_by_share and s.final_gather and not s.paper_mode
                     and any(li.kind in (SUN, WORLD) for li in lights) else "")
            auto, why = True, (f"{s.photons:,} photons{fewer}; final gathering with "
                               f"{s.gather_rays} ray(s) per sample{most}" if s.final_gather else
                               f"{s.photons:,} photons, estimated directly from the global map")
        plan.indirect = _override(s.indirect, auto, "indirect light (global map)", why, plan)

    # --- caustics ------------------------------------------------------------------------
    # Caustic photons are aimed only at casters whose specular lobe is sharp enough to
    # focus light (sharp_specular); light that reaches a diffuse surface by way of rough
    # specular surfaces only first (a glossy floor's coat) is a soft glow: it comes from
    # unaimed photons (render.py partitions the caustic paths by the object hit first,
    # and traces them with lighter photons where visual importance aims the global shot:
    # GLOW_STREAM's comment). The camera side continues every glossy lobe, rough or not,
    # and reads no photon map there: the glow stays in the caustic map (L S+ D), which
    # is read at the diffuse surface it lands on (docs/design.md, Photon mapping model).
    if photon_mapping:
        focus_tri = _focusing(table)[mat] if has_tris else np.zeros(0, bool)
        # Window glass (thin slabs, window_glass): passed by shadow rays, so no caustic
        # caster; its reflections come from unaimed photons, as a rough lobe's glow.
        window_tri = window_glass(geo, table) if has_tris else np.zeros(0, bool)
        if has_tris:
            # Glass that shadow rays see as a Transparent BSDF (Light Path's Is Shadow Ray,
            # engine/raymaterials.py): its direct light comes by shadow rays, so it needs
            # no caustic photons either.
            window_tri = window_tri | shadow_passed(geo, table)
        plan.window_glass = ([geo.object_names[i] for i in np.unique(geo.object_id[window_tri])]
                             if window_tri.any() else [])
        # Single-plane glass panes (engine/panelight.py) when every emitting light that
        # reaches them is a sun or the world whose shadow rays refract through them: the
        # light through them is direct, so they are no caustic casters either (their
        # reflections: unaimed photons). A lamp that cannot reach a pane (inside its
        # shade, newuser32's evening room: 200,000 photons were aimed at the window for
        # 10,288 stored) does not make it one.
        if panes is not None and emitting:
            others = [li for li in emitting if not panes.serves(li)]
            if others:
                p_ids, p_c, p_r, _ = _object_spheres(geo, panes.pane_tri >= 0)
                others = [li for li in others
                          if any(_light_reaches(li, accel, geo, oid, c, r, rng)
                                 for oid, c, r in zip(p_ids, p_c, p_r))]
        if panes is not None and emitting and not others:
            pane_tri = panes.pane_tri >= 0
            plan.pane_glass = [p.name for p in panes.panes]
            pane_lights = ("the sun and the world reach" if panes.suns and panes.world
                           is not None else "the world reaches" if panes.world is not None
                           else "the sun reaches")
            window_tri = window_tri | pane_tri
        sharp_tri = ((sharp_specular(table)[mat] if has_tris else np.zeros(0, bool))
                     & focus_tri & ~window_tri)
        rough_tri = focus_tri & ~sharp_tri & ~window_tri
        ids = np.unique(geo.object_id[sharp_tri]) if sharp_tri.any() else []
        # Rough refractors whose light through them the caustic map carries are aimed at
        # as the sharp casters are (rough_refractors: only where a caustic photon is
        # read, roughcaustic48); the rest of the rough lobes stay unaimed glow.
        refractors = rough_refractors(geo, table, emitting, accel, s, plan.indirect,
                                      rough_tri, diff_tri, shades, sharp_tri)
        if len(refractors):
            ids = np.union1d(np.asarray(ids, np.int64), refractors)
        # The aimed shot must cover every specular triangle of a caster object, its
        # rough parts too: the other shots drop L S+ D paths whose first hit is on a
        # caster object, by object (render.py), so a rough plate inside a metal ring
        # outside the ring's spheres lost its glow (review43: -9 % of the caustic pass).
        cast_tri = (sharp_tri | rough_tri) & np.isin(geo.object_id, ids)
        ids, centers, radii, names = (_object_spheres(geo, cast_tri) if len(ids)
                                      else ([], np.zeros((0, 3)), np.zeros(0), []))
        rough_ids = np.setdiff1d(np.unique(geo.object_id[rough_tri]), ids) if rough_tri.any() else []
        plan.rough_specular = [geo.object_names[i] for i in rough_ids]
        # Translucent objects (a lamp shade of Translucent BSDF) are said apart: they
        # let light through, spread; "specular roughness" would name the wrong thing.
        ids_of = {n: i for i, n in enumerate(geo.object_names)}
        translucent = [n for n in plan.rough_specular
                       if specular_kind(geo, table, ids_of[n]) == "translucent"]
        glossy_rough = [n for n in plan.rough_specular if n not in translucent]
        # The glow's sources by kind, named as a Blender user knows the surfaces: "glow
        # photons" in the progress line said nothing (newuser37).
        glassy = [n for n in glossy_rough if specular_kind(geo, table, ids_of[n]) == "glass"]
        plan.glow_label = "/".join(
            (["glossy"] if len(glassy) < len(glossy_rough) else [])
            + (["glass"] if glassy or plan.window_glass or plan.pane_glass else [])
            + (["translucent"] if translucent else []))
        reached = []
        aimed_spheres = None  # (spheres, owner ids) of the reached casters: _aim_spheres
        roots = {int(oid): (c, r) for oid, c, r in zip(ids, centers, radii)}
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
        if plan.window_glass:
            rough_note += ("; window glass " + _quoted(plan.window_glass)
                           + ": passed by shadow rays (thin flat glass), not a caustic "
                           "caster; unaimed photons carry its reflections")
            fg_win = float(getattr(s, "cycles_filter_glossy", 0.0) or 0.0)
            if fg_win > 0.0 and blurredpassage.CYCLES_BLUR:
                # (docs/compatibility.md "fgslab49": the light through it is dimmed)
                rough_note += (f"; the light through it dimmed as Cycles' Filter Glossy "
                               f"{fg_win:g} dims it")
        if plan.pane_glass:
            rough_note += ("; single-plane glass " + _quoted(plan.pane_glass)
                           + f": {pane_lights} through it by shadow rays, not a "
                           "caustic caster; unaimed photons carry its reflections")
        if glossy_rough:
            rough_note += ("; not aimed at " + _quoted(glossy_rough)
                           + f" (specular roughness {SHARP_ROUGHNESS:g} or more: too rough to focus "
                          "light, so not " + ("caustic casters" if len(glossy_rough) > 1
                                              else "a caustic caster")
                          + "; unaimed photons carry the soft glow "
                          + ("they reflect)" if len(glossy_rough) > 1 else "it reflects)"))
        # Shades the lamps reach through by shadow rays (engine/shadelight.py): their
        # light is direct; photons carry only what crosses one twice or after a bounce.
        # (their own line: "lamp through shade", below)
        shaded = [n for n in translucent if shades is not None and n in shades.names]
        if translucent:
            rough_note += ("; not aimed at translucent " + _quoted(translucent)
                           + " (diffuse transmission spreads light, focuses none; unaimed "
                           "photons carry the light " + ("they let" if len(translucent) > 1
                                                         else "it lets") + " through"
                           + (" twice or after another bounce"
                              if shaded and len(shaded) == len(translucent) else "") + ")")
        if not focus_tri.any():
            auto, why = False, ("no specular or refractive materials" if not spec_tri.any()
                                else "no mirror, glass or coat: light through transparent "
                                "surfaces comes from shadow rays")
        elif not diff_tri.any():
            auto, why = False, "no diffuse surface to receive a caustic"
        elif reached:
            # A forest of 300 instanced glass leaves is named by its first few (the
            # line listed all 300 in a new user's outdoor scene).
            names_r = _quoted([n for _, _, _, n in reached], most=REPORT_NAMES_MAX)
            aimed_spheres = _aim_spheres(geo, cast_tri,
                                         np.array([oid for oid, _, _, _ in reached], np.int64),
                                         roots)
            if len(aimed_spheres[1]) > len(reached) and s.aim_caustics:
                # (newuser42's thin half ring: 3.5 % of its aimed photons were stored)
                names_r += (f" (at {len(aimed_spheres[1])} spheres round "
                            + ("the parts of those that fill" if len(reached) > 1
                               else "its parts: it fills") + " one bounding sphere poorly)")
            # Why each kind is aimed at where it is not plain: rough refractors, and
            # casters whose photons mostly end in a diffuse base (newuser47's tiles).
            aimed_note = _aimed_words(geo, table, [n for _, _, _, n in reached],
                                      [n for oid, _, _, n in reached if oid in refractors])
            auto, why = True, (f"{s.caustic_photons:,} photons aimed at {names_r}"
                               f"{aimed_note}{rough_note}"
                               if s.aim_caustics
                               else f"{s.caustic_photons:,} photons, from {names_r}"
                               f"{aimed_note}{rough_note}")
            from .render import SKIP_UNREAD_SHOTS
            if SKIP_UNREAD_SHOTS and shots_unread(s, geo, table, plan.indirect):
                # Filter Glossy's split reads no caustic photon on these matte surfaces
                # (render._photon_pass leaves the shot out): the line said "200,000
                # photons aimed at" beside the maps line's "no caustic photons traced"
                # (cleanuser47, make render's figure6_box).
                why = (f"from {names_r}, through the final gather's blurred lobes (no "
                       "caustic photons traced: see the glossy blur line)" + rough_note)
        elif rough_reached or ((plan.window_glass or plan.pane_glass) and emitting):
            # Nothing focuses light: no caustic in a student's sense (a plain room's rough
            # Principled walls read "caustics: on" to a new user). Their specular layers
            # still reflect a soft glow onto the other surfaces, and that light is
            # estimated as before: from the caustic-kind paths of the global photons (or
            # an unaimed shot), into the Caustic pass; the line says so.
            plan.caustics_from_global = plan.indirect
            plan.caustics_glow_only = True
            # The maps line names these photons by what this scene has (the line read
            # "light through window glass or off rough specular layers" in a room without
            # a window; the caustics line below says which objects, once).
            tl_reached = [n for n in rough_reached if n in translucent]
            gl_reached = [n for n in rough_reached if n not in translucent]
            plan.glow_words = " and ".join(
                (["soft glow off rough specular layers"] if gl_reached else [])
                + (["light through translucent surfaces"] if tl_reached else [])
                + (["reflections of window glass"]
                   if plan.window_glass or plan.pane_glass else []))
            # Unaimed: the global shot's caustic-kind photons, or, where visual importance
            # aims the global shot, a lighter glow shot of their own (render.py,
            # GLOW_STREAM's comment).
            source = ("unaimed photons" if plan.indirect
                      else f"{s.caustic_photons:,} unaimed photons")
            glow = []
            if gl_reached:
                glow.append("the soft glow that the rough specular layer"
                            + ("s" if len(gl_reached) > 1 else "") + " of "
                            + _quoted(gl_reached) + " reflect" + ("" if len(gl_reached) > 1 else "s")
                            + " onto other surfaces")
            if tl_reached:
                glow.append("the light that translucent " + _quoted(tl_reached)
                            + (" let" if len(tl_reached) > 1 else " lets") + " through"
                            + (" twice or after another bounce"
                               if shades is not None and all(n in shades.names
                                                             for n in tl_reached) else ""))
            if plan.window_glass:
                # (thin flat glass, or glass a Light Path makes transparent to shadow rays)
                why = ("thin flat glass" if not shadow_passed(geo, table).any()
                       else "thin flat glass, or transparent to them by Light Path")
                glow.append("the reflections of window glass "
                            + _quoted(plan.window_glass) + f" (passed by shadow rays: {why})")
            if plan.pane_glass:
                glow.append("the reflections of single-plane glass "
                            + _quoted(plan.pane_glass) + f" ({pane_lights} through it "
                            "by shadow rays)")
            # Rough glass (a frosted lamp shade) is glass too: "no glass" beside the
            # specular line's "through glass 'Shade' (roughness 0.5)" read as a
            # contradiction (new-user trial, newuser29).
            rough_glass = [n for n in plan.rough_specular
                           if specular_kind(geo, table, ids_of[n]) == "glass"]
            kinds = ((["window"] if plan.window_glass else [])
                     + (["single-plane"] if plan.pane_glass else [])
                     + (["rough"] if rough_glass else []))
            glass_words = f"only {' and '.join(kinds)} glass" if kinds else "no glass"
            if rough_glass:
                glass_words += " " + _quoted(rough_glass, most=REPORT_NAMES_MAX)
            sharp_none = (f"no mirror, {glass_words}, "
                          f"no surface smoother than roughness {SHARP_ROUGHNESS:g}")
            # Sharp casters that no light's photons reach first (a glass ball in a room
            # lit through a single-plane window: the pane is hit first) do focus light:
            # "nothing focuses light (... only single-plane glass ...)" beside the
            # specular line's "through glass 'GlassBall'" read as a contradiction
            # (new-user trial newuser32). Their caustic comes from unaimed photons.
            if len(names):
                via = (f"only through single-plane glass {_quoted(plan.pane_glass)} "
                       "(caustic photons are not aimed through it; unaimed ones carry "
                       "the caustic)" if plan.pane_glass else
                       "(no caustic photons aimed at "
                       + ("them" if len(names) > 1 else "it") + ")")
                head = (f"no light reaches "
                        f"{_labelled(geo, table, names, most=REPORT_NAMES_MAX)} directly"
                        + (", " if plan.pane_glass else " ") + via)
            else:
                head = f"nothing focuses light ({sharp_none})"
            carried = (f"{' and '.join(glow)} come"
                       + ("s" if len(glow) == 1 and (gl_reached or tl_reached) else "")
                       + f" from {source} (Caustic pass)")
            if s.caustics == "off":
                plan.caustics = _override(s.caustics, True, "caustics", "", plan)
            elif s.caustics == "on":
                plan.caustics = True
                plan.add("caustics", True, "forced on (" + (
                    head if len(names) else f"nothing focuses light: {sharp_none}")
                    + f"); {carried}")
            else:
                plan.caustics = True  # the glow's estimate (above), as before
                plan.add("caustics", False, f"{head}; {carried}")
            auto = None
        elif not emitting:
            # (newuser42: a scene without a lamp listed seven matte objects here)
            auto, why = False, "no light emits power"
        else:
            all_names = list(names) + plan.rough_specular
            auto, why = False, ("no light reaches the specular object(s) "
                                + _labelled(geo, table, all_names, most=REPORT_NAMES_MAX))
        if auto is not None:
            plan.caustics = _override(s.caustics, auto, "caustics", why, plan)
        if plan.caustics and reached:
            plan.casters = [n for _, _, _, n in reached]
            plan.caster_ids = np.array([oid for oid, _, _, _ in reached], np.int64)
        elif plan.caustics and len(ids):
            plan.caster_ids = np.asarray(ids, np.int64)
            plan.casters = names
        if plan.caustics and len(plan.caster_ids):
            # Several smaller spheres where a caster fills its own poorly (a thin ring:
            # engine/casterspheres.py); a ball keeps its one sphere.
            plan.caster_spheres, plan.caster_sphere_ids = (
                aimed_spheres if reached and aimed_spheres is not None
                else _aim_spheres(geo, cast_tri, plan.caster_ids, roots))
        if plan.caustics and s.cycles_filter_glossy > 0:
            # Only strong reflectors: a dielectric specular layer (a Principled wall's
            # ~4 %) throws too little light for the blur to show.
            _filter_glossy_note(plan, s.cycles_filter_glossy, [
                n for n in [n for _, _, _, n in reached] + rough_reached
                if _strong_reflector(geo, table, ids_of[n])],
                split=settings_filter_glossy(s) > 0.0, clamped=s.clamp_indirect > 0)
        if not (s.cycles_caustics_reflective and s.cycles_caustics_refractive):
            _cycles_caustics_note(plan, s, geo, table,
                                  [n for _, _, _, n in reached] + rough_reached)

    # --- specular chains -------------------------------------------------------------------
    visible = _visible_specular(scene, geo, table, accel) if spec_tri.any() else []
    sharp_seen, kinds = [], {}
    if not spec_tri.any():
        auto, why = False, "no mirror, glass or glossy coat in the scene"
    elif not visible:
        auto, why = False, "no mirror or glass is visible to the camera"
    else:
        # The chain stops at the Light Paths limits (as Cycles'), or at Max Ray Depth
        # where that is set lower (settings.max_depth).
        limit = (f"at most {s.glossy_bounces} glossy, {s.transmission_bounces} "
                 "transmission: Light Paths" if s.max_depth >= s.max_bounces else
                 f"Max Ray Depth {s.max_depth}, below Light Paths' Total {s.max_bounces}")
        # Mirrors, glass and metals first: a room's rough walls listed first hid them
        # behind the "..." (new-user trial). Only what is sharp is listed as specular: a
        # rough Principled floor's layer, listed there as "matte 'Floor' (its rough
        # specular layer)", casts no caustic and shows no mirror image (new-user trial,
        # s17); its highlights (light sampling) and blurred reflections (the same camera
        # paths) are named after.
        sharp_seen, rough_seen, kinds = _split_sharp(geo, table, visible)
        # A volume's invisible boundary is no "transparent" surface to a user (newuser41b's
        # smoke was listed as one); the chain still passes it.
        sharp_seen = [n for n in sharp_seen if not _volume_only(geo, table, n)]
        # (grouped before the first four are taken: four copies of one instanced object
        # hid the rest; counted against the scene's copies, as only those in view are)
        in_view = _instance_totals(geo)
        through = (" through " + _labelled(geo, table, sharp_seen, most=4, totals=in_view,
                                           group_materials=SAME_MATERIAL_GROUP)
                   if sharp_seen
                   else ": no mirror, glass or sharp glossy surface in view")
        # Translucent surfaces are said apart: what they show is light through them.
        tl_seen = [n for n in rough_seen if kinds.get(n) == "translucent"]
        rough_seen = [n for n in rough_seen if kinds.get(n) != "translucent"]
        rough_part = ("; glossy highlights (light sampling) and blurred reflections, no "
                      "mirror image, on " + _rough_words(geo, table, rough_seen, kinds,
                                                         in_view)
                      if rough_seen else "")
        if tl_seen:
            rough_part += ("; light through translucent " + _quoted(tl_seen, most=4)
                           + " (diffuse transmission: light sampling from its far side)")
        bounces = f"{s.camera_depth} bounce" + ("s" if s.camera_depth != 1 else "")
        auto, why = True, f"up to {bounces} ({limit}){through}{rough_part}"
    if s.method == "local":
        on = False
        plan.add("specular reflection / refraction", False,
                 "method 'local' traces no reflected or refracted rays")
    else:
        on = _override(s.specular, auto, "specular reflection / refraction", why, plan)
    plan.specular_depth = s.max_depth if on else 0
    if on:
        _warn_max_ray_depth(plan, s, {n: kinds[n] for n in sharp_seen})

    # --- lights: soft shadows, shadow rays ------------------------------------------------
    nothing_occludes = has_tris and _single_flat_surface(geo, np.ones(geo.count, bool))
    if nothing_occludes and worldmedium.active(scene):
        nothing_occludes = False  # the shadow rays' length in the world volume dims them
    if s.method == "local":
        nothing_occludes = False  # said once below instead
    for li in lights:
        if li.kind == WORLD:
            # A constant world: two cosine-weighted shadow rays per sample, the samples
            # Cycles spends on it (its light sample plus the BSDF sample it weights by
            # MIS); one left the diffuse lobe at ~1.4x Cycles' noise at equal samples
            # (tools/glossy_noise.py).
            plan.light_samples[li.name] = s.light_samples * (2 if li.environment is None else 1)
            plan.shadows[li.name] = has_tris and s.method != "local"
            env = li.environment
            portals = len(getattr(li, "portal_rects", ()))
            if portals:
                # Not "from the whole sky": the shadow rays are aimed through the
                # portals (newuser36's round window). One portal is "it" (newuser46).
                them, their, ps = (("them", "their", "s") if portals > 1 else
                                   ("it", "its", ""))
                how = (f"the World colour lights the scene through {portals} light "
                       f"portal{ps}: two shadow rays a sample, aimed through the "
                       f"portal{ps} where a surface sees the sky through {them}, straight "
                       "out from it elsewhere" if env is None else
                       f"environment map '{env.name}' ({env.width}x{env.height}) lights "
                       f"the scene through {portals} light portal{ps} (shadow rays aimed "
                       f"through {them}, "
                       + (f"by the map seen through {them})" if li.by_map else
                          f"uniformly over {their} solid angle, and by the map)"))
            else:
                how = ("the World colour lights the scene from the whole sky: two shadow "
                       "rays a sample, aimed more often straight out from each surface, "
                       "where the sky lights it most" if env is None else
                       f"environment map '{env.name}' ({env.width}x{env.height}) lights "
                       "the scene (shadow rays importance-sample the map)")
            if isinstance(getattr(scene, "camera_environment", None), WorldGraph):
                how += ("; the camera sees the world's nodes evaluated at each of its rays "
                        "(a backplate of the Texture Coordinate's Window or Camera "
                        "output lands on the pixels as sharp as its image; where such a "
                        "plate lights the scene too, its light is the image as Cycles "
                        "projects it through the camera, baked into the map)")
            elif worldmedium.has_camera_world(scene):
                how += ("; the camera sees a world of its own behind the scene (a Light "
                        "Path Is Camera Ray mix, or Ray Visibility > Camera off), which "
                        "lights nothing")
            plan.add("world light", True, how)
            leak = _portal_leak_note(li)
            if leak:
                plan.warnings.append(leak)
            continue
        sized = li.has_size
        if s.soft_shadows == "off":
            sized = False
        n_samples = s.light_samples if sized else 1
        plan.light_samples[li.name] = n_samples
        spp = s.spp
        if s.soft_shadows == "off" and li.has_size:
            why = ("switched off in the settings: hard shadows, one shadow ray per sample to "
                   + ("each emitting triangle's centre" if li.kind == MESH
                      else f"the centre of '{li.name}'"))
        elif li.kind == MESH:
            # Named by their objects: "emissive meshes" alone left a user guessing which
            # objects glow (newuser45's lamp shade of Emission).
            owners = [geo.object_names[i] for i in np.unique(geo.object_id[li.tri_index])]
            why = (f"{len(li.tri_index):,} emitting triangles of "
                   f"{_quoted(owners, most=REPORT_NAMES_MAX)}, picked by a light tree at "
                   "each point")
        elif sized:
            rays = n_samples * spp
            why = f"{rays} shadow ray{'s' if rays != 1 else ''} per pixel for '{li.name}'"
        else:
            what = {SUN: "sun of angle 0", AREA: "area light"}.get(li.kind, f"{li.kind.lower()} light of radius 0")
            why = f"'{li.name}' is a {what}: one shadow ray per sample"
        plan.add(f"soft shadows '{li.name}'", sized, why)
        casts = li.source is None or li.source.cast_shadow
        if not casts:
            plan.add(f"shadow rays '{li.name}'", False, "the light's 'Cast Shadow' is off")
        plan.shadows[li.name] = casts and not nothing_occludes and s.method != "local"
    # Suns through single-plane glass panes (engine/panelight.py): their shadow rays
    # refract through the pane instead of stopping at it.
    if panes is not None:
        for li in panes.suns:
            if not plan.shadows.get(li.name, True):
                continue
            reflected = panes.total_reflections(li)
            if len(reflected) == len(panes.panes):
                # Every pane faces away from this sun: physically right (Cycles agrees),
                # but a new user's window plane rotated the wrong way (pane31's bench).
                name, inc, crit, ior = reflected[0]
                plan.add(f"sun through glass '{li.name}'", False,
                         f"single-plane glass {_quoted([r[0] for r in reflected])} faces "
                         f"away from the sun: its light meets '{name}' from the glass "
                         f"side at {inc:.0f} degrees, beyond the critical angle "
                         f"{crit:.1f} degrees (IOR {ior:g}), and is totally reflected, as "
                         "in Cycles; flip the plane's normals (Edit Mode > Mesh > Normals "
                         "> Flip) to let the sun in")
                continue
            through = _quoted([p.name for p in panes.panes
                               if p.name not in {r[0] for r in reflected}],
                              most=REPORT_NAMES_MAX)
            # One plane is the surface of a block of glass, not a window: the room lies
            # inside the glass, the sun bent and dimmed by 1 / n^2 (newuser31's study:
            # ~0.3x a real window). Say by how much, and what makes a window.
            first = next(p for p in panes.panes
                         if p.name not in {r[0] for r in reflected})
            bent = panes.bend(li, first)
            how = ""
            if bent is not None:
                how = (f" ('{first.name}': from {bent[0]:.0f} to {bent[1]:.0f} degrees off "
                       f"its normal, {bent[2]:.2f} of the sun's radiance: one plane is the "
                       "surface of a block of glass, what lies behind it inside the glass; "
                       "a window pane has two faces, e.g. a Solidify modifier)")
            plan.add(f"sun through glass '{li.name}'", True,
                     f"reaches through single-plane glass {through} by shadow rays "
                     f"refracted through it{how}; its photons through the glass are "
                     "direct light, not caustics")
        world = panes.world
        if world is not None and plan.shadows.get(world.name, True):
            # The world's light through a pane (paneworld32): the whole sky outside the
            # plane bent into the critical cone, at eta2 <T> of its light (a white
            # world's irradiance under the pane over that without it).
            first = panes.panes[0]
            through = _quoted([p.name for p in panes.panes], most=REPORT_NAMES_MAX)
            how = ""
            if first.ior > 1.0:
                crit = math.degrees(math.asin(1.0 / first.ior))
                keep = panes.world_share(first)
                how = (f" ('{first.name}': the sky outside it bent into {crit:.0f} degrees "
                       f"of its normal, {keep:.2f} of its light: one plane is the surface "
                       "of a block of glass, what lies behind it inside the glass; a "
                       "window pane has two faces, e.g. a Solidify modifier)")
            plan.add("world through glass", True,
                     f"reaches through single-plane glass {through} by shadow rays "
                     f"refracted through it{how}; its photons through the glass are "
                     "direct light, not caustics")
    # Lamps through Translucent BSDF or rough glass shades (engine/shadelight.py): a line
    # of their own
    # (newuser32 found it inside the caustics line).
    if shades is not None:
        for li in shades.lights:
            if not any(li is e for e in emitting) or not plan.shadows.get(li.name, True):
                continue
            tl_names = [n for n in shades.names if n not in shades.glass_names]
            through = " and ".join(
                (["translucent " + _quoted(tl_names, most=REPORT_NAMES_MAX)]
                 if tl_names else [])
                + (["rough glass " + _quoted(shades.glass_names, most=REPORT_NAMES_MAX)]
                   if shades.glass_names else []))
            plan.add(f"lamp through shade '{li.name}'", True,
                     "reaches through " + through
                     + " by shadow rays, sampled where its light lands on the shade; its "
                     "photons through the shade are direct light, not caustics"
                     + ("; those the glass reflects stay caustics" if shades.glass_names
                        else "")
                     # The glossy lobes take the shade samples too, by MIS with their
                     # reflected rays (engine/shadelight.py, glossshade34); without it
                     # (SERVE_GLOSSY off) those rays meet a peaky lobe alone: newuser33's
                     # floor and walls sparkled at 128 and 512 spp with nothing saying why.
                     + (("; glossy reflections of the lamp through the shade (rough "
                         "specular layers, sheen) take these samples too, shared with "
                         "their reflected rays by multiple importance sampling")
                        if shadelight.SERVE_GLOSSY else
                        ("; glossy reflections of the lamp through the glass (rough "
                         "specular layers, sheen) come from reflected rays alone and may "
                         "sparkle (Light Paths > Clamping > Indirect trims them)"
                         if shades.glass_names else "")))
    if s.method == "local" and lights:
        # No shadow rays: a light's samples only integrate over its area.
        for i, d in enumerate(plan.decisions):
            if d.effect.startswith("soft shadows '") and d.enabled:
                plan.decisions[i] = Decision(d.effect, False, "method 'local' has no shadows")
        plan.add("shadow rays", False, "method 'local' lights every surface facing a light "
                 "(no shadow rays)")
    if tree_members(lights):
        _summarise_many_lights(plan, lights, s)
    if nothing_occludes and lights:
        # (each light's samples still integrate its area: no shadow, soft or hard, to make)
        for i, d in enumerate(plan.decisions):
            if d.effect.startswith("soft shadows '") and d.enabled:
                plan.decisions[i] = Decision(d.effect, False, "nothing can cast a shadow; "
                                             "its samples light the surface unshadowed")
        plan.add("shadow rays", False, "the scene is a single flat surface: nothing can cast a shadow")
    # Per material first: the (T,3) radiance of every triangle cost ~60 B a triangle.
    if has_tris and np.any((luminance(table.emission) > 0)[mat]):
        plan.add("emission", True, "emissive surfaces are drawn and sampled as lights")
    if s.method != "local":
        # Cycles' Light Paths limits (docs/design.md, Bounce limits): said once, so a
        # render darker than expected points at them.
        # Max Ray Depth (settings.max_depth) is named only where it cuts camera chains
        # shorter than the limits do: Cycles has no such cap.
        cap = (f"; Max Ray Depth {s.max_depth} stops camera paths sooner: at most "
               f"{s.max_depth} mirror / glass bounce{'s' if s.max_depth != 1 else ''} "
               f"(below Total {s.max_bounces})" if s.max_depth < s.max_bounces else
               "; camera paths stop at these too, as in Cycles")
        limits = (s.max_bounces, s.diffuse_bounces, s.glossy_bounces, s.transmission_bounces)
        origin = ("Cycles' defaults" if limits == CYCLES_DEFAULT_BOUNCES
                  else "as set there")
        plan.add("bounce limits", True,
                 f"light paths up to {s.max_bounces} bounces: {s.diffuse_bounces} diffuse, "
                 f"{s.glossy_bounces} glossy, {s.transmission_bounces} transmission "
                 f"(Light Paths > Max Bounces, {origin}){cap}")
    if (s.clamp_direct > 0 or s.clamp_indirect > 0) and emitting:
        # Clamping trades energy for calm fireflies: said, so a highlight or caustic
        # darker than the unclamped render points at it (Cycles' default Indirect is 10).
        # Not where no light emits (a black image: newuser42 read the paragraph there).
        def limit(v):
            return f"{v:g} (R + G + B at most {3 * v:g} per sample)" if v > 0 else "off"
        # Light through panes and shades is indirect to Cycles (it arrives after a
        # refraction, in rare bright path samples) and its clamp cuts much of it; ours
        # samples it smoothly by shadow rays (newuser34: a frosted lamp shade's room
        # 1.46x Cycles at Indirect 10, 0.99x with both clamps off).
        through = sorted({d.effect.split(" '")[0] for d in plan.decisions if d.enabled
                          and d.effect.startswith(("sun through glass", "world through glass",
                                                   "lamp through shade"))})
        glass_note = ""
        # Which lights' bounce light the clamp cuts, measured by a probe of Cycles'
        # samples (clamped_bounce_light): the note named the World for a kitchen whose
        # cut was its window Area light's (newuser46; docs/accuracy.md, report47).
        if s.clamp_indirect > 0 and has_tris and probe_clamp:
            plan.clamped = clamped_bounce_light(scene, geo, table, emitting, accel,
                                                3.0 * s.clamp_indirect,
                                                np.random.default_rng([s.seed, 95]))
        named = [(k, v) for k, v in plan.clamped.items() if v >= CLAMP_CUT_MIN]
        if s.clamp_indirect > 0 and through:
            glass_note = ("; light through window glass and lamp shades (" + ", ".join(through)
                          + ") is indirect light to Cycles, whose clamp cuts much of it "
                          "(it reaches Cycles' paths after a refraction, in rare bright "
                          "samples): ours takes it by shadow rays, smoothly, and keeps it, "
                          "so Cycles renders what it lights darker than ours; set Indirect to 0 "
                          "in both to compare them")
        elif named:
            kinds_of = {li.name: li.kind for li in emitting}
            which = ", ".join(_light_words(k, kinds_of.get(k), v)
                              for k, v in named[:REPORT_NAMES_MAX])
            lights_it = "it lights" if len(named) == 1 else "they light"
            glass_note = ("; Cycles clamps each path sample, and the bounce light of "
                          + which + " comes to its paths in samples brighter than the "
                          "clamp, which it cuts (that share of the first diffuse bounce's "
                          "light off the surfaces in view, by a probe of Cycles' samples "
                          "here), while photon estimates are smooth and "
                          f"seldom reach it: what {lights_it} "
                          "can read brighter here than in Cycles; set Indirect to 0 in both "
                          "to compare them")
        elif s.clamp_indirect > 0 and any(li.kind == SUN for li in emitting):
            # Cycles clamps each path sample; a sunlit room's bounce light reaches its
            # paths in rare bright samples, which the clamp cuts, while our photon
            # estimates are smooth and seldom reach it (newuser40: a room lit through an
            # open window 1.046x Cycles at Indirect 10, its ceiling 1.21x; 1.002x with
            # Cycles' clamp off). Said as a possibility: the probe sees no deeper bounce
            # and no glossy lobe, and newuser40's cut came from neither its first diffuse
            # bounce (its mechanism unknown here); where Cycles' paths find the bounce
            # light often enough the clamp cuts nothing (newuser44: a table by a window,
            # Cycles the same with the clamp at 10 and off).
            probed = (": a probe of its first diffuse bounces here finds none over it"
                      if probe_clamp and has_tris else "")
            glass_note = ("; Cycles clamps each path sample, and the bounce light of a "
                          "sunlit scene comes to its paths in rare bright samples that the "
                          "clamp cuts, while photon estimates are smooth and seldom reach "
                          "it: such scenes can read brighter here than in Cycles (where the "
                          f"clamp cuts anything{probed}); set Indirect to 0 in both to "
                          "compare them")
        elif (s.clamp_indirect > 0 and any(li.kind == WORLD for li in emitting)
              and probe_clamp and has_tris):
            # Lit by the World without a sun, its bounce light probed and none over the
            # clamp: said in one sentence, not as a possibility (newuser45's evening room,
            # newuser46's HDRI, studio48's still life and newuser51's donut: Cycles' clamp
            # changed nothing measurable there, or 0.3 %, and the note "can read
            # brighter" pointed the user at it).
            glass_note = ("; Cycles' clamp changes nothing measurable in the World's bounce "
                          "light here (a probe of Cycles' first diffuse bounces finds none "
                          "over it)")
        # The casters' caustics and the light seen through glass, probed as the bounce
        # light is (clamped_caustics, clamped_through_glass): the clauses fired wherever
        # a caster or glass was in a clamped scene, and were false on studio48's still
        # life and newuser51's donut (every object 0.95-1.003 of Cycles, Cycles' clamp
        # changing nothing) while right on newuser41's glass eyes (1.12x at Indirect 10,
        # 1.000 with Cycles' clamp off) and newuser46's bottle before a window (0.63 of
        # its unclamped self in Cycles, 0.74 in ours).
        # At Filter Glossy above 1/pi (the split on: engine/glossysplit.py; a matte hit
        # reads no caustic photon, Lambert's pdf being at most 1/pi) the casters' light
        # reaches the matte surfaces through the final gather's paths, clamped per camera
        # sample (the mean of its gather rays; each ray apart, as Cycles clamps each path,
        # with integrator.CLAMP_PER_GATHER_RAY) (newuser52: under
        # the pendant ours 1.000-1.004 of clamped Cycles at Filter Glossy 1), and the
        # probe, which follows sharp lobes, read 5.2 % or none by seed: said so, not
        # probed. At 0 (and partly up to 1/pi) ours takes it from the caustic photons:
        # probed.
        kinds_of = {li.name: li.kind for li in emitting}
        quiet = []  # what the probes found under the clamp
        gathered = settings_filter_glossy(s) > 1.0 / math.pi
        if (s.clamp_indirect > 0 and plan.caustics and plan.casters and gathered):
            from . import integrator  # (lazy: integrator's imports reach this module)
            blur_line = any(d.effect == "glossy blur" for d in plan.decisions)
            glass_note += ("; the caustics of " + _quoted(plan.casters, most=REPORT_NAMES_MAX)
                           + " reach the matte surfaces through the final gather's paths "
                           f"here (Filter Glossy {s.cycles_filter_glossy:g}"
                           + (": see the glossy blur line" if blur_line else "")
                           + ("), and ours clamps each of those paths' light as Cycles "
                              "clamps its own samples" if integrator.CLAMP_PER_GATHER_RAY
                              else "), and ours clamps those paths' light per camera sample "
                              "as Cycles clamps its own samples (ours the mean of a "
                              "sample's gather rays: one bright path is cut a little less)"))
        elif (s.clamp_indirect > 0 and plan.caustics and plan.casters and probe_clamp
                and has_tris):
            # Fixed streams: the answer is the scene's, not the seed's (clampblur52).
            reach_rng = np.random.default_rng([CLAMP_CAUSTIC_STREAM[0], 93])
            reaching = ({li.name for li in emitting
                         if any(_light_reaches(li, accel, geo, oid, c, r, reach_rng)
                                for oid, c, r, _ in reached)} if reached else None)
            plan.clamped_caustics = clamped_caustics(
                scene, geo, table, emitting, accel, plan.caster_ids,
                3.0 * s.clamp_indirect, np.random.default_rng(CLAMP_CAUSTIC_STREAM), reaching)
            cut = [(k, v) for k, v in plan.clamped_caustics.items() if v >= CLAMP_CUT_MIN]
            casters = _quoted(plan.casters, most=REPORT_NAMES_MAX)
            if cut:
                glass_note += ("; the caustics of " + casters + " likewise reach Cycles' "
                               "paths in rare bright samples that its clamp cuts ("
                               + ", ".join(_light_words(k, kinds_of.get(k), v)
                                           for k, v in cut[:REPORT_NAMES_MAX])
                               + ": that share of the first diffuse bounce's light off the "
                               "surfaces in view, cut from their caustics by a probe of "
                               "Cycles' samples here), "
                               + ("and ours clamps each caustic photon as the Cycles path "
                                  "it ends" if photonclamp.PER_PHOTON else
                                  "while ours takes them from the caustic photons' smooth "
                                  "estimates: they can read brighter here"))
            else:
                quiet.append("the caustics of " + casters)
        # A lamp (or the sky) seen through a closed glass object is indirect light to
        # Cycles (bounce 2 or more: sampleclamp.py), and its clamp cuts it where it is
        # bright. Single-plane panes refract once: direct to Cycles.
        panes = set(plan.window_glass) | set(plan.pane_glass)
        seen_glass = [n for n in sharp_seen if kinds.get(n) == "glass" and n not in panes]
        if s.clamp_indirect > 0 and seen_glass and emitting and probe_clamp and has_tris:
            wanted = set(seen_glass)
            glass_ids = [i for i, n in enumerate(geo.object_names) if n in wanted]
            plan.clamped_glass = clamped_through_glass(
                scene, geo, table, emitting, accel, glass_ids, 3.0 * s.clamp_indirect,
                np.random.default_rng([s.seed, 92]), depth=max(1, min(s.max_depth, 8)))
            cut = [(k, v) for k, v in plan.clamped_glass.items() if v >= CLAMP_CUT_MIN]
            glass = _quoted(seen_glass, most=REPORT_NAMES_MAX)
            if cut:
                glass_note += ("; the light seen through glass " + glass + " (a lamp or "
                               "the sky behind it or reflected in it) reaches Cycles' camera "
                               "paths after a refraction or reflection, as indirect light "
                               "its clamp cuts where it is bright ("
                               + ", ".join(_light_words(k, kinds_of.get(k), v)
                                           for k, v in cut[:REPORT_NAMES_MAX])
                               + ": that share of what is seen through the glass, by a "
                               "probe of Cycles' samples): such glass can read brighter here")
            else:
                quiet.append("the light seen through glass " + glass)
        if quiet:
            glass_note += ("; a probe of Cycles' samples of " + " and of ".join(quiet)
                           + " finds none over the clamp: it changes nothing measurable "
                           "there")
        plan.add("clamping", True,
                 f"Light Paths > Clamping: direct light {limit(s.clamp_direct)}, indirect "
                 f"light and photon estimates {limit(s.clamp_indirect)}; brighter samples "
                 "are scaled down (less energy, fewer fireflies); 0 turns a clamp off"
                 + glass_note)
    see_through = (table.alpha < 1) | table.has_alpha_texture
    if has_tris and np.any(see_through[mat]):
        seen = np.unique(mat[see_through[mat]])
        # A volume without a surface is a transparent pass too, but no user set an
        # alpha there (newuser36: "alpha below 1 in 'Fog'" read as a mistake).
        vol = (np.asarray(table.volume_only, bool) if table.volume_only is not None
               else np.zeros(len(table.names), bool))
        volumes = sorted({table.names[m] for m in seen if vol[m]})
        # A cut-out by an image's alpha says which image (newuser54's leaves read as
        # "a Transparent BSDF, Alpha below 1 or an alpha texture" in 'Leaf').
        cutouts: dict[tuple, set] = {}
        for m in seen:
            if not vol[m] and table.alpha_textures:
                images = _alpha_images(table.alpha_textures[m])
                if images:
                    cutouts.setdefault(tuple(images), set()).add(table.names[m])
        cut_names = set().union(*cutouts.values()) if cutouts else set()
        names = sorted({table.names[m] for m in seen if not vol[m]} - cut_names)
        what = "; ".join(x for x in (
            # A Transparent BSDF (in an Add or Mix Shader) is alpha below 1 to the
            # engine, but the user set no Alpha there (newuser44's curtain card).
            "see-through (a Transparent BSDF, Alpha below 1 or an alpha texture) in "
            + _quoted(names, most=REPORT_NAMES_MAX) if names else "",
            "; ".join("cut out by the alpha of image" + ("s " if len(images) > 1 else " ")
                      + _quoted(images, most=REPORT_NAMES_MAX)
                      + " (an Image Texture's Alpha output) in material"
                      + ("s " if len(mats) > 1 else " ")
                      + _quoted(sorted(mats), most=REPORT_NAMES_MAX)
                      for images, mats in sorted(cutouts.items())),
            "the surfaces of volume-only " + _quoted(volumes, most=REPORT_NAMES_MAX)
            + " (invisible, as in Cycles)" if volumes else "") if x)
        cap = s.transparent_max_bounces
        plan.add("transparency", True, what
                 + (f"; shadow rays cross up to {cap} transparent surfaces, less those "
                    f"their camera path crossed, and a camera path ends at the surface "
                    f"after its {_ordinal(cap)} (Light Paths > Max Bounces > Transparent, "
                    "counted along the whole path as in Cycles)" if cap
                    else "; transparent max bounces 0: they block shadow rays, and a "
                    "camera path ends at the surface after its first"))
    sigma = getattr(table, "absorption", None)
    scat = getattr(table, "scattering", None)
    if sigma is not None and scat is not None:
        sigma = np.asarray(sigma) + np.asarray(scat)  # the extinction (engine/media.py)
    used = (np.asarray(geo.used_materials(), np.int64) if has_tris and sigma is not None
            and np.any(sigma > 0) else np.zeros(0, np.int64))
    used = used[np.any(np.asarray(sigma)[used] > 0, axis=1)] if len(used) else used
    if len(used):
        # Media inside objects (engine/media.py): said, with the strongest extinction's
        # colour, so a user sees the Volume Absorption / Scatter was read.
        names = sorted({table.names[m] for m in used})
        top = np.max(sigma[used], axis=0)
        scattering = scat is not None and bool(np.any(np.asarray(scat)[used] > 0))
        bounces = int(getattr(s, "volume_bounces", 0) or 0)
        plan.add("volume scattering" if scattering else "volume absorption", True,
                 "Beer-Lambert inside " + _quoted(names, most=REPORT_NAMES_MAX)
                 + " (sigma_t up to " + ", ".join(f"{x:.3g}" for x in top) + " /m, RGB) "
                 "along camera paths, photons and shadow rays; "
                 + ("the lamps' light scattered once towards the camera and along "
                    "final-gather rays (engine/volumescatter.py)"
                    + (f", then up to {bounces} more times along camera paths (Light "
                       "Paths > Volume bounces) with the diffuse surfaces' light at "
                       "their segments' ends (engine/volumewalk.py), and photons scatter "
                       "in the medium onto the surfaces (engine/photonmedium.py)"
                       if bounces > 0
                       else "; photons do not scatter in the medium (Volume bounces 0)")
                    if scattering
                    else "volume scattering is not simulated"))
    _subsurface_line(plan, geo, table, s, has_tris)
    seated = getattr(geo, "seated_volumes", None) or []
    if seated:
        # Fog boxes standing on a floor (engine/volumecontact.py): said, because Cycles
        # renders that contact differently (a hole where the faces coincide).
        pairs = [f"'{v}' on " + _quoted(on, most=REPORT_NAMES_MAX) for v, on, _ in seated]
        most = max(d for _, _, d in seated)
        plan.add("volume contact", True,
                 "; ".join(pairs[:REPORT_NAMES_MAX])
                 + (f" and {len(pairs) - REPORT_NAMES_MAX} more" if len(pairs) >
                    REPORT_NAMES_MAX else "")
                 + f": the volume's faces lying there moved {most * 1000:.2g} mm outward, "
                 "so those surfaces lie inside it (as with the volume sunk into them); "
                 "Cycles renders such a contact with a hole (about 44 % of its samples "
                 "there miss the surface): sink the volume 1 mm to compare")
    if s.light_groups:
        from . import lightgroups
        lit = [g for g in s.light_groups if lightgroups.members(scene, g) > 0]
        empty = [g for g in s.light_groups if g not in lit]
        # (newuser41b: four groups made a render 5.5x longer, nothing said why)
        plan.add("light groups", bool(lit),
                 (f"{len(lit)} Light Group pass{'es' if len(lit) != 1 else ''} ("
                  + ", ".join(f"'{g}'" for g in lit) + "): each is a render of its own "
                  "emitters alone, a photon and a camera pass, so the render takes about "
                  f"{len(lit) + 1} times as long as without; the groups sum to Combined on "
                  "average, not pixel by pixel as Cycles' (its groups split one path's "
                  "light)" if lit else "no group has an emitter")
                 + (f"; {', '.join(repr(g) for g in empty)}: no lamp, emissive object or "
                    "world in "
                    + ("it" if len(empty) == 1 else "them") + ", black"
                    if empty and lit else ""))
    if worldmedium.active(scene):
        # The world volume (engine/worldmedium.py): what it switched off, and why.
        plan.add("world volume", True, worldmedium.effect_reason(scene))
    glowing = _glowing_media(scene, geo, table, has_tris)
    if glowing:
        # Emitting media (engine/volumeemission.py): where their light comes from.
        plan.add("volume emission", True,
                 "the glow of " + _quoted(glowing, most=REPORT_NAMES_MAX) + " added along "
                 "camera paths and final-gather rays (surfaces see it through the gather "
                 "alone, up to its second diffuse bounce: no light sampling, as Cycles "
                 "samples none, and no photons from it)"
                 + ("" if s.photon_mapping else "; photon mapping off: no gather, so it "
                    "lights no surface"))
    return plan


def _glowing_media(scene, geo, table, has_tris) -> list:
    """The names of the emitting media the scene uses (materials on its triangles, and
    'the world volume')."""
    emit = getattr(table, "volume_emission", None)
    out = []
    if emit is not None and has_tris and np.any(np.asarray(emit) > 0):
        used = np.asarray(geo.used_materials(), np.int64)
        out = sorted({table.names[m] for m in used if np.any(np.asarray(emit)[m] > 0)})
    wm = getattr(scene, "world_medium", None)
    if worldmedium.active(scene) and np.any(np.asarray(getattr(wm, "emission", 0.0)) > 0):
        out.append("the world volume")
    return out


def _portal_leak_note(world) -> str:
    """A warning naming the light portals whose opening reaches past them
    (lights.portal_leaks), or ''."""
    names = getattr(world, "portal_leaks", None)
    if not names:
        return ""
    many = len(names) > 1
    quoted = ", ".join(f"'{n}'" for n in names)
    return (f"light portal{'s' if many else ''} {quoted}: the opening reaches past "
            f"{'their' if many else 'its'} edges, so the sky seen there is found without "
            "the portal's help and fewer shadow rays are aimed through the portals (more "
            f"noise); make {'each' if many else 'the'} portal cover its whole window "
            "(Size X / Size Y along the opening's sides)")


def _warn_max_ray_depth(plan: EffectPlan, s, kinds: dict) -> None:
    """A warning where Max Ray Depth (settings.max_depth, an extra cap on camera chains)
    stops camera paths through the glass or mirrors in view before the Light Paths limit
    of their kind does: Transmission 12 was silently capped by Max Ray Depth 8 (new-user
    trial, s16; the limits line says it too, but a capped glass chain looks dark, so it
    is said where a mistake is said). kinds: {object in view: specular_kind}."""
    plural = "s" if s.max_depth != 1 else ""
    for setting, count, names in (
            ("Transmission", s.transmission_bounces,
             [n for n, k in kinds.items() if k == "glass"]),
            ("Glossy", s.glossy_bounces,
             [n for n, k in kinds.items() if k in ("mirror", "polished metal", "glossy")])):
        limit = min(count, s.max_bounces)
        if names and s.max_depth < limit:
            plan.warnings.append(
                f"Max Ray Depth {s.max_depth} stops camera paths after {s.max_depth} mirror "
                f"/ glass bounce{plural}, before Light Paths > Max Bounces > {setting} "
                f"{count} does: what is seen through or in {_quoted(names)} after "
                f"{s.max_depth} bounce{plural} stays dark; raise Max Ray Depth to {limit} or "
                "more (its default, 1024, caps nothing)")


# Words for a dielectric's specular layer (a Principled base's, a coat's), by its
# roughness: below SHARP_ROUGHNESS it focuses light and shows sharp highlights ("glossy":
# plastic, varnish); from MATTE_ROUGHNESS (GGX alpha = roughness^2 >= 0.49, a lobe ~30
# degrees and more wide) its highlight spreads over most of the view and the surface reads
# as matte (a Principled floor at roughness 1.0 is not what a student calls glossy); in
# between "rough glossy" (satin).
MATTE_ROUGHNESS = 0.7


def _layer_roughness(table: MaterialTable, mats) -> np.ndarray:
    """(len(mats),) the sharpest dielectric specular roughness of materials mats: the
    base's specular layer, or a coat's roughness where it has a coat."""
    rough = np.asarray(table.roughness[mats], np.float64)
    if table.coat_weight is not None and table.closure_params is not None:
        from .closures import principled as pr
        coat = np.asarray(table.closure_params[mats, pr.M_COAT_ROUGH], np.float64)
        rough = np.where(table.coat_weight[mats] > 0, np.minimum(rough, coat), rough)
    return rough


def _is_glossy_node(table: MaterialTable, mats) -> np.ndarray:
    """(len(mats),) bool: materials whose metal lobe is a Glossy (or Anisotropic) BSDF
    node's (closures/principled.py NODE_GLOSSY: the colour as a constant reflectance), not
    a Principled metal's: a Glossy BSDF is not necessarily metal."""
    if table.closure_params is None:
        return np.zeros(len(mats), bool)
    from .closures import principled as pr
    return ((table.closure_params[mats, pr.M_NODE] == pr.NODE_GLOSSY)
            & (table.metallic[mats] > 0))


# A Principled material is called metal only above this Metallic (half metal, half
# dielectric reads as neither: below it the dielectric layer names it).
METAL_WORDS = 0.5


def specular_kind(geo: Geometry, table: MaterialTable, oid: int) -> str:
    """What a specular object is, in a student's words, by its closure: 'glass'
    (transmission), 'transparent' (alpha below 1 or an alpha texture: a card, a cut-out),
    'translucent' (a Translucent BSDF share: diffuse transmission),
    'mirror' (a metal or Glossy BSDF lobe that is mirror-smooth: GGX alpha below
    ggx.ALPHA_MIN, the engine's delta lobe); a Glossy BSDF: 'glossy' (sharp enough to
    focus light: is_sharp) or 'rough glossy'; a Principled metal (Metallic above
    METAL_WORDS): 'polished metal' (sharp), 'glossy' (rough under a sharp coat) or
    'metal'; else a specular layer over a
    diffuse base (a dielectric Principled, a coat), by its roughness: 'glossy' (sharp:
    plastic, varnish), 'rough glossy' (up to MATTE_ROUGHNESS) or 'matte' (rougher: its
    highlight spreads over most of the view). A Glossy BSDF at roughness 0.2 was called
    "polished metal" (new-user trial, s17)."""
    mats = object_materials(geo, oid)
    if np.any(table.transmission[mats] > 0):
        return "glass"
    if np.any(table.alpha[mats] < 1) or np.any(table.has_alpha_texture[mats]):
        return "transparent"
    if table.translucent is not None and np.any(table.translucent[mats] > 0):
        return "translucent"
    glossy = _is_glossy_node(table, mats)
    metal = (table.metallic[mats] > METAL_WORDS) & ~glossy
    rough = np.asarray(table.roughness[mats], np.float64)
    if np.any((metal | glossy) & (rough * rough < ALPHA_MIN)):
        return "mirror"
    if np.any(glossy):
        return "glossy" if np.any(glossy & is_sharp(rough)) else "rough glossy"
    if np.any(metal & is_sharp(rough)):
        return "polished metal"
    # A rough metal under a sharp coat (car paint) shows a mirror image in its coat: it is
    # named by the coat, as a coated dielectric is (newuser55's Suzanne, metallic 1 at
    # roughness 0.35 under Coat Roughness 0.03, read "metal ... no mirror image").
    if np.any(metal & is_sharp(_layer_roughness(table, mats))):
        return "glossy"
    if np.any(metal):
        return "metal"
    layer = float(_layer_roughness(table, mats).min())
    if is_sharp(layer):
        return "glossy"
    return "rough glossy" if layer < MATTE_ROUGHNESS - SHARP_TOLERANCE else "matte"


# Kinds sharp enough to be handled as specular (a mirror image, a refraction, a caustic);
# the rough ones show glossy highlights and blurred reflections only.
SHARP_KINDS = ("mirror", "glass", "polished metal", "transparent", "glossy")


def _closure_words(geo: Geometry, table: MaterialTable, oid: int, kind: str) -> str:
    """" (Glossy BSDF, roughness 0.2)" or " (metallic 1, roughness 0.2)": the closure
    behind a glossy-node or metal kind, so a student finds the setting; " (roughness
    0.2)" for glass that is not smooth (a Principled Transmission 1 at roughness 0.2 read
    as plain "glass", as if its roughness were ignored: new-user trial, newuser28);
    " (coat, roughness 0.03)" for a dielectric layer sharper by its coat than by its own
    roughness (newuser46's bowl at roughness 0.5 with a coat read as plain "glossy", as
    the rough walls beside it are not), " (coat, roughness 0.03 over metallic 1, roughness
    0.35)" for a rough metal under a sharp coat (car paint); "" otherwise."""
    mats = object_materials(geo, oid)
    if kind == "glass":
        # The smoothest transmitting material names it; smooth (the delta lobe) says nothing.
        r = float(np.min(table.roughness[mats[table.transmission[mats] > 0]]))
        return f" (roughness {r:.2g})" if r * r >= ALPHA_MIN else ""
    glossy = _is_glossy_node(table, mats)
    if glossy.any():
        return f" (Glossy BSDF, roughness {float(np.min(table.roughness[mats[glossy]])):.2g})"
    if kind in ("polished metal", "metal"):
        metal = mats[table.metallic[mats] > METAL_WORDS]
        # Brushed metal says so (newuser45's vase at Anisotropic 0.6 read as plain metal).
        aniso = (0.0 if table.closure_params is None else
                 float(np.max(np.abs(table.closure_params[metal, M_ANISO]))))
        return (f" (metallic {float(np.max(table.metallic[metal])):.2g}, roughness "
                f"{float(np.min(table.roughness[metal])):.2g}"
                + (f", anisotropic {aniso:.2g}" if aniso > 0 else "") + ")")
    if kind in ("glossy", "rough glossy"):
        layer = _layer_roughness(table, mats)
        coated = layer < np.asarray(table.roughness[mats], np.float64)
        if coated.any() and float(layer[coated].min()) <= float(layer.min()):
            metal = mats[coated & (table.metallic[mats] > METAL_WORDS)]
            base = (f" over metallic {float(np.max(table.metallic[metal])):.2g}, roughness "
                    f"{float(np.min(table.roughness[metal])):.2g}" if len(metal) else "")
            return f" (coat, roughness {float(layer[coated].min()):.2g}{base})"
    return ""


# The order the report names specular objects in: what a student looks for first.
_KIND_ORDER = ("mirror", "glass", "polished metal", "metal", "transparent", "glossy",
               "rough glossy", "matte")


_INSTANCE_NAME = re.compile(r"^(.+)#(\d+)$")


def _instance_groups(names) -> list[tuple[str, int, str]]:
    """names as the report lists them: [(shown name, instance count, first member)]. The
    add-on names instanced copies 'Instancer/Object#k' (addon/export.py); two or more
    copies of one name are listed once as "'Scatter/Rock' (40 instances)" (a report
    listed 'Scatter/Rock#0', 'Scatter/Rock#1' ... : newuser41b). Order of first appearance."""
    groups: dict[tuple, list[str]] = {}
    for n in names:
        m = _INSTANCE_NAME.match(str(n))
        # (An object's own name apart from copies named after it.)
        groups.setdefault((m.group(1), True) if m else (str(n), False), []).append(n)
    out = []
    for (base, copies), members in groups.items():
        if copies and len(members) > 1:
            out.append((base, len(members), members[0]))
        else:
            out.extend((str(m), 1, m) for m in members)
    return out


def _shown(name: str, count: int, total: int = 0) -> str:
    """"'Scatter/Rock' (40 instances)"; with the scene's total copies where the line
    names only some (those in view): "(23 of 89 instances in view)" (newuser51: the
    specular line's 23 read as a contradiction of the caustics line's 89)."""
    if total > count:
        return f"'{name}' ({count:,} of {total:,} instance{'s' if total > 1 else ''} in view)"
    return f"'{name}'" + (f" ({count:,} instances)" if count > 1 else "")


def _instance_totals(geo: Geometry) -> dict:
    """{shown name: copies in the scene} of instanced objects ('Instancer/Object#k')."""
    return {base: count for base, count, _ in _instance_groups(geo.object_names)
            if count > 1}


def _alpha_images(node, depth: int = 0, seen=None) -> list[str]:
    """Names of the images whose Alpha output an alpha node reads (an Image Texture's
    Alpha, through whatever nodes are between: Math, Mix, a Principled's Alpha), sorted;
    [] when the alpha comes from no image (a procedural texture, a constant)."""
    from .shadernodes import BoxLookup, ImageLookup
    seen = set() if seen is None else seen
    if node is None or id(node) in seen or depth > 64:
        return []
    seen.add(id(node))
    if isinstance(node, (ImageLookup, BoxLookup)):
        return [node.texture.name] if node.output == "ALPHA" else []
    found: set = set()
    values = (vars(node).values() if hasattr(node, "__dict__") else
              node if isinstance(node, (list, tuple)) else ())
    for v in values:
        if hasattr(v, "evaluate") or isinstance(v, (list, tuple)):
            found.update(_alpha_images(v, depth + 1, seen))
    return sorted(found)


def _ordinal(n: int) -> str:
    """1 -> "1st", 2 -> "2nd", 8 -> "8th", 11 -> "11th", 22 -> "22nd"."""
    n = int(n)
    tail = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{tail}"


def _quoted(names, most: int | None = 4, totals: dict | None = None) -> str:
    """"'a', 'b', 'c', 'd' ... (3 more)" for a report line: the first `most` names (None:
    all) quoted, " ... (N more)" where N more were left off; instanced copies once with
    their count (_instance_groups). totals: _instance_totals where names are those in
    view, so a count below the scene's says "N of M instances in view"."""
    entries = _instance_groups(names)
    shown = entries if most is None else entries[:most]
    left = len(entries) - len(shown)
    totals = totals or {}
    return (", ".join(_shown(n, c, totals.get(n, 0)) for n, c, _ in shown)
            + (f" ... ({left:,} more)" if left else ""))


# Objects of one kind and one material the specular line counts instead of naming, from
# this many on: "36 transparent objects of material 'Leaf'" (newuser54 listed "transparent
# 'Leaf00', transparent 'Leaf01', ... (33 more)").
SAME_MATERIAL_GROUP = 3


def _material_groups(geo: Geometry, table: MaterialTable, entries, at_least: int) -> list:
    """entries (_instance_groups) with the single objects of one specular kind and one
    material, `at_least` or more of them, replaced by one entry (None, count, (kind,
    material name, first object)) where the first of them stood."""
    ids = {n: i for i, n in enumerate(geo.object_names)}
    key_of = {}
    for shown, count, n in entries:
        if count == 1 and n in ids:
            mats = object_materials(geo, ids[n])
            if len(mats) == 1:
                key_of[n] = (specular_kind(geo, table, ids[n]), table.names[int(mats[0])])
    sizes: dict = {}
    for k in key_of.values():
        sizes[k] = sizes.get(k, 0) + 1
    out, done = [], set()
    for e in entries:
        k = key_of.get(e[2])
        if k is None or sizes[k] < at_least:
            out.append(e)
        elif k not in done:
            done.add(k)
            out.append((None, sizes[k], (*k, e[2])))
    return out


def _labelled(geo: Geometry, table: MaterialTable, names, most: int | None = None,
              totals: dict | None = None, group_materials: int | None = None) -> str:
    """"glass 'ball', glossy 'vase'" for object names (a matte one with the specular
    layer that puts it in the list: "matte 'floor' (its rough specular layer)"); the
    first `most` (None: all), then " ... (N more)" as _quoted (totals as there).
    group_materials: count objects of one kind and one material from this many on
    ("36 transparent objects of material 'Leaf'": _material_groups) instead of naming
    each."""
    totals = totals or {}
    entries = _instance_groups(names)
    if group_materials:
        entries = _material_groups(geo, table, entries, group_materials)
    left = 0 if most is None else max(len(entries) - most, 0)
    entries = entries[:len(entries) - left]
    ids = {n: i for i, n in enumerate(geo.object_names)}
    out = []
    for shown, count, n in entries:
        if shown is None:  # a group of objects sharing a material
            kind, material, first = n
            out.append(f"{count:,} {kind} objects of material '{material}'"
                       + _closure_words(geo, table, ids[first], kind))
            continue
        if n not in ids:
            out.append(_shown(shown, count, totals.get(shown, 0)))
            continue
        kind = specular_kind(geo, table, ids[n])
        out.append(f"{kind} {_shown(shown, count, totals.get(shown, 0))}"
                   + (" (its rough specular layer)" if kind == "matte"
                      else _closure_words(geo, table, ids[n], kind)))
    return ", ".join(out) + (f" ... ({left:,} more)" if left else "")


def _split_sharp(geo: Geometry, table: MaterialTable, names) -> tuple[list, list, dict]:
    """names split into those sharp enough to be handled as specular (SHARP_KINDS: a
    mirror image, a refraction) and the rough ones (glossy highlights, blurred
    reflections), each in _KIND_ORDER (stable within a kind: a room's rough walls
    listed first hid the mirrors behind "..."); and {name: specular_kind}."""
    ids = {n: i for i, n in enumerate(geo.object_names)}
    # Each object's kind once: specular_kind reads all of the scene's triangles.
    kinds = {n: specular_kind(geo, table, ids[n]) if n in ids else "" for n in names}
    rank = {k: i for i, k in enumerate(_KIND_ORDER)}
    names = sorted(names, key=lambda n: rank.get(kinds[n], len(_KIND_ORDER)))
    sharp = [n for n in names if kinds[n] in SHARP_KINDS or not kinds[n]]
    return sharp, [n for n in names if kinds[n] and kinds[n] not in SHARP_KINDS], kinds


def _rough_words(geo: Geometry, table: MaterialTable, names, kinds: dict,
                 totals: dict | None = None) -> str:
    """"the rough specular layers of 'Floor', 'BackWall', rough glossy 'Ball' (Glossy
    BSDF, roughness 0.5)": rough objects for the specular line, a Principled base's or
    coat's layer by name only (its kind, "matte" or "rough glossy", did not read as
    specular: new-user trial), a rough Glossy BSDF or metal with its closure. kinds:
    {name: specular_kind}; totals: _instance_totals (names are those in view)."""
    ids = {n: i for i, n in enumerate(geo.object_names)}

    def glossy_node(n):
        mats = object_materials(geo, ids[n])
        return bool(_is_glossy_node(table, mats).any())

    layers = [n for n in names if kinds[n] == "matte"
              or (kinds[n] == "rough glossy" and not glossy_node(n))]
    others = [n for n in names if n not in layers]
    parts = []
    if layers:
        parts.append("the rough specular layer" + ("s" if len(layers) > 1 else "") + " of "
                     + _quoted(layers, totals=totals))
    if others:
        parts.append(_labelled(geo, table, others, most=4, totals=totals))
    return ", ".join(parts)


def _single_flat_surface(geo: Geometry, mask: np.ndarray) -> bool:
    """All masked triangles lie in one plane (so none can light or shadow another)."""
    if not mask.any():
        return True
    n0 = geo.ng[np.argmax(mask)]
    # A piece at a time (geometry.PIECE_TRIANGLES): the normals and corners of every
    # triangle at once would cost ~100 B a triangle at the peak of the preparation.
    for idx in _pieces(mask):
        if np.any(np.abs(geo.ng[idx] @ n0) < 1.0 - 1e-9):
            return False
    # Flat to within what float32 (Embree's precision) resolves at these coordinates.
    lo, hi, big = np.inf, -np.inf, 0.0
    for corners in _corner_pieces(geo, mask):
        h = corners @ n0
        lo, hi = min(lo, float(h.min())), max(hi, float(h.max()))
        big = max(big, float(np.abs(corners).max()))
    return bool(hi - lo <= 16.0 * float(ulp32(big)))


def window_glass(geo: Geometry, table: MaterialTable) -> np.ndarray:
    """(T,) bool: triangles of window glass (photonkernels.window_triangles: thin slabs
    of smooth glass). Shadow rays pass them (engine/shadowtransmittance.py) and photons
    through them keep their path's kind, so they cast no caustic to aim at: their
    reflections (and the few inner ones) are the unaimed photons'."""
    from . import photonkernels as pk
    flat, limit = pk.flat_tables(geo, table)
    if not len(flat):
        return np.zeros(geo.count, bool)
    return pk.window_triangles(geo, flat, limit)


def _visible_specular(scene, geo, table, accel, probe=96, through=3) -> list:
    """Names of objects with a specular lobe that camera rays see (a probe grid), also
    behind up to `through` glass or see-through surfaces in front of them: a probe ray
    that hits glass goes on straight to what lies behind it (refraction's bend ignored:
    this names what is there, it traces nothing). The liquid in a glass bottle (nested
    glass volumes) was left out of the report, as no camera ray hits it first (s26
    new-user trial)."""
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
    see_through = (table.transmission > 0) | (table.alpha < 1) | table.has_alpha_texture
    seen = []
    # (the camera's Light Path variants: engine/raymaterials.py)
    cam_mat = raymaterials.triangle_materials(geo, table, CAMERA)
    for _ in range(through + 1):
        t, prim, _, _ = accel.intersect(o, d, tmax)
        live = prim >= 0
        hit = prim[live]
        seen.append(hit[table.has_specular[cam_mat[hit]]])
        on = see_through[cam_mat[hit]]
        if not on.any():
            break
        o, d, t, tmax = o[live][on], d[live][on], t[live][on], np.broadcast_to(
            tmax, live.shape)[live][on]
        # Past the hit by a relative step (float64 origins): the far side of a 4 mm glass
        # wall is still found, the surface just hit is not found again.
        step = 1e-7 * (1.0 + np.abs(o).max(axis=1) + t)
        o = o + d * (t + step)[:, None]
        tmax = tmax - t - step
    ids = np.unique(geo.object_id[np.concatenate(seen)])
    return [geo.object_names[i] for i in ids]


def _light_words(name: str, kind, share: float) -> str:
    """A light and the share of the bounce light the clamp cuts from it, as the
    clamping line names them: "'Window' (area light, 0.7 %)", "the World (0.5 %)", "the
    emissive meshes (1.0 %)"."""
    pct = f"{100 * share:.1f} %"
    if kind == WORLD:
        return f"the World ({pct})"
    if kind == MESH:
        return f"the emissive meshes ({pct})"
    what = {"AREA": "area light", "POINT": "point light", "SPOT": "spot light",
            "SUN": "sun"}.get(str(kind), "light")
    return f"'{name}' ({what}, {pct})"

# The clamping line names the lights whose bounce light Cycles' Indirect clamp cuts, by a
# probe of the samples Cycles' paths would make here (clamped_bounce_light), not by a
# light's kind: the line credited the World for what the clamp cut off a window Area
# light's bounce light (newuser46's kitchen; docs/accuracy.md, report47).
CLAMP_PROBE = 64           # probe grid: camera rays along the image's longer side
CLAMP_PROBE_REPEATS = 8    # bounce samples per probe ray
CLAMP_CUT_MIN = 0.002      # named when the clamp cuts this share of the probed bounce light
CLAMP_PROBE_LIGHTS = 16    # the brightest lights probed (by photon flux; one kernel call each)
CLAMP_CAUSTIC_PATHS = 8192  # caustic paths (diffuse point, caster, on) the caustic probe follows
CLAMP_CAUSTIC_REPEATS = 16  # at most this many paths a (diffuse point, caster point) pair
CLAMP_BASE_ROWS = 2048    # bounce samples off other surfaces the caustic probe's share is of
# The caustic probe's own sizes and stream: a lamp of radius 10 mm behind a 7 mm crystal
# drop (newuser52's jewellery display) reaches a few of 8,192 paths at most, and the
# clause flipped with the render's seed (5.2 % cut at seed 0, none at 1; Cycles' clamp
# cuts 13 % of that pendant's shadow at Filter Glossy 0). At these sizes it found a cut
# on 8 of 8 streams (docs/accuracy.md, clampblur52), in ~0.5 s; the stream is fixed, so
# one scene gets one answer at any seed.
CLAMP_CAUSTIC_GRID = 128          # probe grid of the caustic probe (CLAMP_PROBE's role)
CLAMP_CAUSTIC_GRID_REPEATS = 16   # its bounce samples per probe ray
CLAMP_CAUSTIC_FOLLOWED = 65536    # caustic paths it follows (CLAMP_CAUSTIC_PATHS' role)
CLAMP_CAUSTIC_FOLLOW_REPEATS = 256  # at most this many paths a pair (CLAMP_CAUSTIC_REPEATS')
CLAMP_CAUSTIC_STREAM = (94,)      # its random stream, the render seed's left out
CLAMP_CHAIN_DEPTH = 8      # specular bounces the caustic probe follows from a caster
CLAMP_SUN_CONE = math.radians(10.0)  # the kernel estimate's cone round a sun's disc


def clamped_bounce_light(scene, geo: Geometry, table: MaterialTable, lights: list, accel,
                         limit: float, rng, probe: int = CLAMP_PROBE,
                         repeats: int = CLAMP_PROBE_REPEATS) -> dict:
    """{light name: the share of the probed bounce light that Cycles' clamp cuts from that
    light's samples}, for each emitting light with a cut above 0 (sorted by it, largest
    first).

    The samples are Cycles' at its first indirect bounce, diffuse to diffuse: a probe
    grid of camera rays (probe along the image's longer side, each `repeats` times)
    meets x; a cosine-sampled ray from x (the diffuse lobe's albedo a_x,
    datapasses.lobe_albedo) meets y; each light's one shadow-ray sample at y
    (integrator.light_shadow_rays: irradiance E as the kernels sample it, occluded rays
    0) gives the sample a_x a_y / pi E (W sr^-1 m^-2, RGB), which Cycles' film_clamp_light
    scales to |R| + |G| + |B| <= limit (engine/sampleclamp.py; limit = 3 x Indirect). The
    share is the cut summed over the samples over every light's samples summed. Left
    out: Cycles' light tree picks one light per sample (its sample is E / P_pick, so it
    cuts more where several lights share a point), glossy lobes at x or y (a glossy
    worktop's glints) and deeper bounces; surfaces past glass (the camera's first hit
    only). Measured against Cycles (docs/accuracy.md, report47): a floor under a 400 W
    1 m area light 1 m above it, 11 % here, Cycles' Diffuse Indirect 8.9 % lower at
    Indirect 10 than off; at 3 m none, Cycles 0.0 %; newuser46's kitchen 0.7 % of its
    window Area light, none of its HDRI and Point lamp (Cycles: the window light's
    bounce light 1 % lower on the walls, the HDRI's and the lamp's within 0.6 %)."""
    from types import SimpleNamespace
    from .bsdf import surface_hit
    from .datapasses import lobe_albedo
    from .integrator import light_shadow_rays
    emitting = _probe_lights(lights)
    if not emitting or geo.count == 0 or scene.camera is None or not np.isfinite(limit):
        return {}
    first = _probe_first_bounce(scene, geo, table, accel, rng, probe, repeats)
    if first is None:
        return {}
    hx, a_x, keep, wd, prim2, u2, v2 = first
    on = np.nonzero(prim2 >= 0)[0]
    if not len(on):
        return {}
    hy = surface_hit(geo, table, prim2[on], u2[on], v2[on], wd[on])
    weight = a_x[keep][on] * lobe_albedo(table, hy)[1][:, 0, :] / math.pi
    ctx = SimpleNamespace(lights=lights, geo=geo)
    cut, total = {}, 0.0
    for i in emitting:
        lit, irr, o32, d32, t32 = light_shadow_rays(ctx, hy, i, rng)
        if not len(lit) or len(o32) != len(lit):
            continue
        seen = ~np.asarray(accel.occluded(o32, d32, t32), bool)
        sample = weight[lit] * irr * seen[:, None]
        sums = np.abs(sample).sum(axis=1)
        over = sums > limit
        total += float(sample.sum())
        c = float((sample[over] * (1.0 - limit / sums[over])[:, None]).sum())
        if c > 0:
            cut[lights[i].name] = cut.get(lights[i].name, 0.0) + c
    if total <= 0:
        return {}
    return dict(sorted(((k, c / total) for k, c in cut.items()), key=lambda kv: -kv[1]))


def _probe_lights(lights: list) -> list:
    """Indices of the CLAMP_PROBE_LIGHTS brightest emitting lights (photon flux), brightest
    first: the lights the clamp probes sample."""
    flux = [float(luminance(np.asarray(li.photon_flux))) for li in lights]
    return sorted((i for i, f in enumerate(flux) if f > 0),
                  key=lambda i: -flux[i])[:CLAMP_PROBE_LIGHTS]


def _probe_first_bounce(scene, geo: Geometry, table: MaterialTable, accel, rng, probe: int,
                        repeats: int):
    """Cycles' first indirect bounce as the clamp probes sample it: the probe grid's camera
    hits x (SurfaceHit hx), their diffuse albedo a_x (M, 3), the rows `keep` with one, a
    cosine-weighted direction wd (K, 3) about each kept row's shading normal (pdf cos / pi:
    the sample's weight is a_x) and what it meets (prim2 (K,), -1 none; u2, v2). None
    where no camera ray meets a diffuse surface."""
    from .bsdf import surface_hit
    from .datapasses import lobe_albedo
    d, prim, u, v = _probe_camera_hits(scene, geo, accel, rng, probe, repeats)
    rows = np.nonzero(prim >= 0)[0]
    if not len(rows):
        return None
    hx = surface_hit(geo, table, prim[rows], u[rows], v[rows], d[rows])
    a_x = lobe_albedo(table, hx)[1][:, 0, :]
    keep = np.nonzero(a_x.sum(axis=1) > 0)[0]
    if not len(keep):
        return None
    wd = _cosine_directions(hx.ns[keep], rng)
    _, prim2, u2, v2 = accel.intersect(hx.clear(keep, wd), wd)
    return hx, a_x, keep, wd, prim2, u2, v2


def _probe_camera_hits(scene, geo: Geometry, accel, rng, probe: int, repeats: int):
    """The probes' camera rays: a grid of probe rays along the image's longer side, each
    `repeats` times, jittered in its pixel: (d (N,3), prim (N,), u, v) of their first hits
    (prim -1: none)."""
    from .integrator import camera_rays
    W, H = scene.width, scene.height
    nx = max(1, int(round(probe * W / max(W, H))))
    ny = max(1, int(round(probe * H / max(W, H))))
    px = np.tile(np.repeat((np.arange(nx) + 0.5) / nx * W, ny), repeats)
    py = np.tile(np.tile((np.arange(ny) + 0.5) / ny * H, nx), repeats)
    o, d, tmax = camera_rays(scene.camera, geo.offset, W, H, np.floor(px), np.floor(py),
                             rng.random(len(px)), rng.random(len(py)))
    _, prim, u, v = accel.intersect(o, d, tmax)
    return d, prim, u, v


def clamped_caustics(scene, geo: Geometry, table: MaterialTable, lights: list, accel,
                     caster_ids, limit: float, rng, reaching=None,
                     probe: int = CLAMP_CAUSTIC_GRID,
                     repeats: int = CLAMP_CAUSTIC_GRID_REPEATS,
                     paths: int = CLAMP_CAUSTIC_FOLLOWED,
                     again: int = CLAMP_CAUSTIC_FOLLOW_REPEATS) -> dict:
    """{light name: the share of the first diffuse bounce's light off the surfaces in view
    that Cycles' clamp cuts from that light's caustics}, for each light with a cut above 0
    (largest first); reaching: the names of the lights whose photons reach a caster (None:
    every light).

    Cycles' samples at its first indirect bounce, as clamped_bounce_light's (a probe grid
    of camera rays meets x, a cosine-sampled ray from x, weight x's diffuse albedo a_x,
    meets y): where y is on a caster (caster_ids: object ids) the path follows its sharp
    lobes to a light (_follow_chain: Cycles' closure pick, the samples T L where it meets
    a light; at most `paths` paths, each (x, y) pair's up to `again` times; probe,
    repeats: the grid's rays along the longer side and bounce samples a ray); elsewhere each
    light's one shadow-ray sample at y gives a_x a_y / pi E (a subset of at most
    CLAMP_BASE_ROWS rows, scaled). Every sample is clamped as Cycles' film_clamp_light
    does (|R| + |G| + |B| <= limit, 3 x Indirect); the share is a light's caustic cut
    over all samples' light, so it reads as the bounce clause's. Left out: Cycles' light
    tree, glossy lobes at x. Measured (docs/accuracy.md, clampnote51): newuser51's
    donut and studio48's still life none (Cycles' clamp: 1.0000 on studio48's backdrop);
    newuser46's kitchen 'WindowLight' 1.6-1.7 %; a glass ball under a 400 W 1 m area
    light 3 m up 0.5-3.4 %, under a 5 W/m^2 sun of 0.526 degrees 3.1-4.5 %; newuser52's
    jewellery display (a 10 mm spot behind crystal) 47-89 % over 8 streams (clampblur52).
    The sharp lobes only: at Filter Glossy above 1/pi Cycles blurs them, and ours takes
    that light through the final gather's clamped paths (the clause is not probed there)."""
    from .bsdf import surface_hit
    from .datapasses import lobe_albedo
    caster_ids = np.asarray(caster_ids, np.int64)
    lit = _probe_lights(lights)
    if (not lit or not len(caster_ids) or geo.count == 0 or scene.camera is None
            or not np.isfinite(limit)):
        return {}
    first = _probe_first_bounce(scene, geo, table, accel, rng, probe, repeats)
    if first is None:
        return {}
    hx, a_x, keep, wd, prim2, u2, v2 = first
    on = np.nonzero(prim2 >= 0)[0]
    at = np.isin(geo.object_id[prim2[on]], caster_ids)
    pairs, rest = on[at], on[~at]
    if not len(pairs):
        return {}
    probe_ = _Clamped(limit)
    # The bounce light off the other surfaces (the share's base), from a subset.
    if len(rest):
        part = (rest if len(rest) <= CLAMP_BASE_ROWS
                else rng.choice(rest, size=CLAMP_BASE_ROWS, replace=False))
        hy = surface_hit(geo, table, prim2[part], u2[part], v2[part], wd[part])
        weight = a_x[keep][part] * lobe_albedo(table, hy)[1][:, 0, :] / math.pi
        _light_samples(lights, lit, geo, accel, hy, weight, rng, probe_,
                       scale=len(rest) / len(part), counted=False)
    # The caustic samples: y's sharp lobes to the lights, each pair's path followed
    # several times (a lamp's caustic reaches the few paths that meet it).
    part = (pairs if len(pairs) <= paths
            else rng.choice(pairs, size=paths, replace=False))
    again = max(1, min(again, paths // len(part)))
    part = np.repeat(part, again)
    hy = surface_hit(geo, table, prim2[part], u2[part], v2[part], wd[part])
    to_casters = [i for i in lit if reaching is None or lights[i].name in reaching]
    _follow_chain(scene, geo, table, lights, to_casters, accel, hy, a_x[keep][part], rng, probe_,
                  depth=CLAMP_CHAIN_DEPTH, shade_ends=False,
                  scale=len(pairs) / len(part))
    return probe_.shares()


class _Clamped:
    """The clamp probes' sums: every sample's light (total) and, per light, what
    film_clamp_light cuts (|R| + |G| + |B| scaled down to limit: engine/sampleclamp.py)
    from the samples counted against it."""

    def __init__(self, limit: float):
        self.limit, self.total, self.cut = limit, 0.0, {}

    def add(self, name, sample, weight=1.0, counted=True):
        """RGB samples (N,3), each of weight `weight` (scalar or (N,)) in the sums; a
        weight does not change what the clamp sees (a kernel estimate's share of a
        sample, _follow_chain's sun)."""
        if not len(sample):
            return
        w = np.broadcast_to(np.asarray(weight, np.float64), (len(sample),))
        sums = np.abs(sample).sum(axis=1)
        self.total += float((w * sample.sum(axis=1)).sum())
        over = sums > self.limit
        if counted and over.any():
            c = float((w[over] * sample[over].sum(axis=1)
                       * (1.0 - self.limit / sums[over])).sum())
            if c > 0:
                self.cut[name] = self.cut.get(name, 0.0) + c

    def shares(self) -> dict:
        if self.total <= 0:
            return {}
        return dict(sorted(((k, c / self.total) for k, c in self.cut.items() if c > 0),
                           key=lambda kv: -kv[1]))


def _light_samples(lights, lit, geo, accel, hit, weight, rng, probe, scale=1.0,
                   counted=True):
    """Each light's (lit: indices) one shadow-ray sample at hits (integrator.
    light_shadow_rays, occluded rays 0) times weight (N,3), into probe (a _Clamped) at
    scale (a number, or (N,) per hit)."""
    from types import SimpleNamespace
    from .integrator import light_shadow_rays
    ctx = SimpleNamespace(lights=lights, geo=geo)
    for i in lit:
        got, irr, o32, d32, t32 = light_shadow_rays(ctx, hit, i, rng)
        if not len(got) or len(o32) != len(got):
            continue
        seen = ~np.asarray(accel.occluded(o32, d32, t32), bool)
        probe.add(lights[i].name, weight[got] * irr * seen[:, None],
                  scale[got] if np.ndim(scale) else scale, counted)


def _follow_chain(scene, geo, table, lights, lit, accel, hit, T, rng, probe, depth: int,
                  shade_ends: bool, scale: float = 1.0):
    """Cycles' paths from hits (on a specular object) through its sharp lobes, T (N,3)
    their throughput so far, into probe (a _Clamped): at each mostly sharp hit one
    closure picked by albedo (luminance), T times its weight (bsdf.sample_specular) over
    the pick's probability among all lobes (the sample Cycles' pick makes); a path takes
    only the sharp lobes, which Cycles picks with their share of the albedo, so each
    sample counts in the sums at that share (its weight in probe.add, the product over
    the path's vertices: before, each counted in full, a share reading up to 2x); where
    a path meets a light's surface (an area light, a point light's disk, an emissive
    triangle) or escapes (the World) the sample T L. A sun's disc, too small for the probe's paths to meet, by a kernel
    estimate: paths leaving within CLAMP_SUN_CONE of it count its radiance at the
    weight of the disc's solid angle over the cone's (the clamp sees the whole sample).
    shade_ends: at a hit that is not mostly sharp (after a bounce), each light's
    shadow-ray sample T a_y / pi E; else the path ends there."""
    from .bsdf import sample_specular, surface_hit
    from .datapasses import lobe_albedo, lobe_alpha
    from .lights.world import background_radiance
    from .closures import principled as pr
    surfaced = [i for i in lit if lights[i].has_surface and lights[i].kind != MESH]
    suns = [lights[i] for i in lit if lights[i].kind == SUN
            and getattr(lights[i], "cos_half_angle", 1.0) < 1.0]
    world = next((lights[i].name for i in lit if lights[i].kind == WORLD), None)
    mesh = next((lights[i].name for i in lit if lights[i].kind == MESH), None)
    cone = 1.0 - math.cos(CLAMP_SUN_CONE)
    picks = np.array([pr.L_METAL, pr.L_GLASS_R, pr.L_SPEC, pr.L_COAT])
    # (N,) each path's share of Cycles' paths: the probability its picks were sharp
    share = np.full(len(T), float(scale))
    for bounce in range(depth + 1):
        if not len(T):
            break
        prm, alb = lobe_albedo(table, hit)
        lobes = np.stack([alb[:, pr.L_METAL], alb[:, pr.L_GLASS_R] + alb[:, pr.L_GLASS_T],
                          alb[:, pr.L_SPEC], alb[:, pr.L_COAT]], axis=1)   # glass as one
        sharp = lobe_alpha(prm)[:, picks] < SHARP_ROUGHNESS ** 2
        lum = luminance(lobes.reshape(-1, 3)).reshape(len(T), 4) * sharp
        l_all = luminance(alb.sum(axis=1))
        chain = lum.sum(axis=1) > 0.5 * np.maximum(l_all, 1e-300)
        if bounce > 0 and shade_ends:
            ends = np.nonzero(~chain)[0]
            if len(ends):
                _light_samples(lights, lit, geo, accel, hit.take(ends),
                               T[ends] * alb[ends, pr.L_DIFFUSE] / math.pi, rng, probe,
                               share[ends])
        go = np.nonzero(chain)[0]
        if not len(go) or bounce == depth:
            break
        p = lum[go] / lum[go].sum(axis=1, keepdims=True)
        choice = np.minimum((rng.random(len(go))[:, None] > np.cumsum(p, axis=1)).sum(axis=1), 3)
        sub = hit.take(go)
        wd, valid, _, weight = sample_specular(table, sub, picks[choice] - 1, rng)
        p_pick = lum[go, choice] / np.maximum(l_all[go], 1e-300)
        T = T[go] * weight / np.maximum(p_pick, 1e-300)[:, None]
        share = share[go] * np.minimum(lum[go].sum(axis=1) / np.maximum(l_all[go], 1e-300),
                                       1.0)
        keep = np.nonzero(valid)[0]
        T, wd, share = T[keep], wd[keep], share[keep]
        o = sub.clear(keep, wd)
        t_hit, prim2, u2, v2 = accel.intersect(o, wd)
        t_hit = np.where(prim2 >= 0, t_hit, np.inf)
        for i in surfaced:
            m, _, L = lights[i].intersect(o, wd, t_hit)
            if L is not None and m.any():
                probe.add(lights[i].name, T[m] * np.asarray(L)[m], share[m])
        out = np.nonzero(prim2 < 0)[0]
        if len(out):
            if world is not None:
                probe.add(world, T[out] * background_radiance(scene, wd[out]), share[out])
            for li in suns:
                near = out[wd[out] @ -np.asarray(li.dir, np.float64) >= math.cos(CLAMP_SUN_CONE)]
                if len(near):
                    disc = 1.0 - li.cos_half_angle
                    probe.add(li.name, T[near] * np.asarray(li.sun_radiance)[None, :],
                              share[near] * (disc / cone))
        on = np.nonzero(prim2 >= 0)[0]
        if not len(on):
            break
        hit = surface_hit(geo, table, prim2[on], u2[on], v2[on], wd[on])
        T, share = T[on], share[on]
        if mesh is not None and hit.emission is not None:
            e = np.asarray(hit.emission)
            if e.any():
                probe.add(mesh, T * e, share)


def _cosine_directions(n, rng):
    """Cosine-weighted unit directions (N,3) about unit normals n (N,3) (pdf cos / pi)."""
    r1, r2 = rng.random(len(n)), rng.random(len(n))
    s, phi = np.sqrt(r1), 2.0 * math.pi * r2
    a = np.where(np.abs(n[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return (t1 * (s * np.cos(phi))[:, None] + t2 * (s * np.sin(phi))[:, None]
            + n * np.sqrt(np.maximum(1.0 - r1, 0.0))[:, None])


def clamped_through_glass(scene, geo: Geometry, table: MaterialTable, lights: list, accel,
                          glass_ids, limit: float, rng, depth: int = 8,
                          probe: int = CLAMP_PROBE, repeats: int = CLAMP_PROBE_REPEATS) -> dict:
    """{light name: the share of the light seen through or in the glass objects glass_ids
    (object ids) that Cycles' clamp cuts from that light's samples} (largest first).

    The probe's camera rays (clamped_bounce_light's grid) that meet the glass first follow
    its sharp lobes (_follow_chain, up to `depth` bounces, with each light's shadow-ray
    sample where a path meets a surface that is not mostly sharp): every such sample is
    indirect light to Cycles (bounce 1 or more), which film_clamp_light scales to
    |R| + |G| + |B| <= limit (3 x Indirect). The share is a light's cut over every
    sample's light. Left out: Cycles' light tree (one light per sample) and the glossy
    lobes past the glass. Measured (docs/accuracy.md, clampnote51): newuser46's bottle
    37-40 % of 'WindowLight''s (Cycles: the bottle 0.63 of its unclamped self);
    studio48's bottle none (Cycles 0.9989)."""
    from .bsdf import surface_hit
    glass_ids = np.asarray(glass_ids, np.int64)
    lit = _probe_lights(lights)
    if (not lit or not len(glass_ids) or geo.count == 0 or scene.camera is None
            or not np.isfinite(limit)):
        return {}
    d, prim, u, v = _probe_camera_hits(scene, geo, accel, rng, probe, repeats)
    rows = np.nonzero(prim >= 0)[0]
    rows = rows[np.isin(geo.object_id[prim[rows]], glass_ids)]
    if not len(rows):
        return {}
    # Each camera ray's path followed several times (a lamp reflected in the glass or
    # behind it meets few of them).
    rows = np.repeat(rows, max(1, min(CLAMP_CAUSTIC_REPEATS, CLAMP_CAUSTIC_PATHS // len(rows))))
    hit = surface_hit(geo, table, prim[rows], u[rows], v[rows], d[rows])
    probe_ = _Clamped(limit)
    _follow_chain(scene, geo, table, lights, lit, accel, hit, np.ones((len(rows), 3)), rng,
                  probe_, depth=depth, shade_ends=True)
    return probe_.shares()
