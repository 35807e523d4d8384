"""Render settings: the paper's parameters keep their names and meaning."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields

import numpy as np

from .pixelfilter import PIXEL_FILTERS

ESTIMATORS = ("knn_simpson", "knn_cone", "classic", "radius")
CAUSTIC_LOOKUPS = ("knn", "precomputed")
# Their names in the add-on's Estimator menu (addon/properties.py ESTIMATOR_ITEMS), which the
# effect report uses: a user reads there what the panel shows, not the setting's key.
ESTIMATOR_LABELS = {"knn_simpson": "k-NN (Simpson kernel)", "knn_cone": "k-NN (cone filter)",
                    "classic": "Classic (paper)", "radius": "Fixed Radius (Simpson)"}
EFFECT_SWITCHES = ("caustics", "indirect", "specular", "soft_shadows")
# Rendering methods for teaching (docs/teaching.md), each a set of the effect switches
# (engine/effects.py): local = direct light without shadow rays, mirrors or glass (an
# OpenGL-style local model); raytrace = the paper's Fig. 5b; photon = the full renderer.
METHODS = ("local", "raytrace", "photon")

# Hard upper limits, Blender's own where it has them: Cycles' samples <= 65536 and the
# add-on's light samples <= 256; photon counts fit Blender's 32-bit int properties (and
# no product of them overflows int64); bounces as Cycles' max_bounces (1024). Memory is
# checked separately, against the machine, before a render (engine/resources.py).
LIMITS = {
    "photons": 2**31 - 1, "caustic_photons": 2**31 - 1, "max_photon_depth": 1024,
    "min_photons": 10_000, "k_nearest": 10_000, "gather_rays": 256, "spp": 65536,
    "max_depth": 1024, "light_samples": 256, "seed": 2**63 - 1, "workers": 1024,
    "chunk_size": 1 << 24, "transparent_max_bounces": 1024, "max_bounces": 1024,
    "diffuse_bounces": 1024, "glossy_bounces": 1024, "transmission_bounces": 1024,
    "volume_bounces": 1024, "adaptive_min_samples": 65536,
}
# Cycles' Noise Threshold property: 0 .. 1 (engine/adaptive.py)
ADAPTIVE_THRESHOLD_MAX = 1.0
# Cycles' Light Paths > Max Bounces (its defaults): the setting names and their defaults.
BOUNCE_LIMITS = (("max_bounces", 12), ("diffuse_bounces", 4), ("glossy_bounces", 4),
                 ("transmission_bounces", 12))
FILTER_WIDTH_MAX = 500.0  # pixels: Blender's limit for the filter size
# Cycles' Light Paths > Clamping (sample_clamp_direct / _indirect) takes 0 .. 1e8 in its UI
# (RNA soft max 1e8; 0 = off): the same range here (engine/sampleclamp.py).
CLAMP_MAX = 1e8
# Cycles' Light Paths > Caustics > Filter Glossy takes 0 .. 10 (RNA hard max; 0 = off).
FILTER_GLOSSY_MAX = 10.0


# Cycles' Light Paths defaults (max, diffuse, glossy, transmission bounces): ours too, so
# the effect report can say whether a scene changed them.
CYCLES_DEFAULT_BOUNCES = (12, 4, 4, 12)


# RenderSettings.data_passes' values (engine/datapasses.py)
DATA_PASSES = ("ao", "color", "denoising", "light", "material_index", "mist", "object_index",
               "position", "uv", "vector")
# RenderSettings.cryptomatte's values (engine/cryptomatte.py KINDS)
CRYPTOMATTE_KINDS = ("asset", "material", "object")


def _word_set(name: str, value, valid) -> tuple:
    """A setting that names some of `valid` (a word, or several): the sorted tuple of
    them, lower case. Raises ValueError naming the setting and the valid words."""
    words = (value,) if isinstance(value, str) else value
    words = tuple(sorted(set(str(v).lower() for v in (words or ()))))
    if any(v not in valid for v in words):
        raise ValueError(f"setting '{name}' takes {', '.join(valid)}, got {value!r}")
    return words


def _shader_aovs(value) -> tuple:
    """RenderSettings.shader_aovs checked: a tuple of (name, "value" | "color"), names
    unique and non-empty. Raises ValueError naming the setting."""
    out, seen = [], set()
    for item in value or ():
        try:
            name, kind = item
        except (TypeError, ValueError):
            raise ValueError(f"setting 'shader_aovs' takes (name, 'value' | 'color') pairs, "
                             f"got {item!r}") from None
        if not isinstance(name, str) or not name or kind not in ("value", "color"):
            raise ValueError(f"setting 'shader_aovs': expected a name and 'value' or "
                             f"'color', got {item!r}")
        if name in seen:
            raise ValueError(f"setting 'shader_aovs': AOV '{name}' named twice")
        seen.add(name)
        out.append((name, kind))
    return tuple(out)


@dataclass
class RenderSettings:
    # Pass 1 (photons)
    photons: int = 400_000          # global photons emitted (paper: MaxRayPerLightSrc x lights)
    caustic_photons: int = 200_000  # photons emitted for the caustic map
    max_photon_depth: int = 32      # bounces a photon may take (Russian roulette ends most sooner)
    # Radiance estimate
    estimator: str = "knn_simpson"  # knn_simpson | knn_cone | classic (paper) | radius
    radius: float | None = None     # max search radius (m): a k-NN estimate's cap; None = auto
    # from the k-NN distance where the estimates are made (render.lookup_radius, camera_radius;
    # without lookups the global photons' spacing: photonmap.auto_radius; the caustic map's
    # cap: photonmap.caustic_radius of that spacing, its k-NN radius follows the caustic
    # photons' density)
    min_photons: int = 8            # fewer photons found -> no estimate (paper)
    k_nearest: int = 64             # photons per k-NN estimate
    # The caustic map's k-NN lookups: "knn" (each lookup its own k-NN estimate) or
    # "precomputed" (Christensen 1999: the estimate at each caustic photon once, a lookup
    # reads the nearest facing photon's; engine/causticcache.py)
    caustic_lookup: str = "knn"
    final_gather: bool = True       # indirect light by gather rays into the global map
    gather_rays: int = 2            # final-gather rays per camera sample (the most, with
    # gather_by_share: fewer where the indirect light is a small share of what the camera
    # sees, measured from the global photons after the photon pass; engine/render.py
    # gather_count)
    gather_by_share: bool = True
    # Photon-guided gather directions (Jensen 1995; engine/guiding.py): the level-0 gather
    # rays drawn from a mixture of the cosine lobe and the nearest gather point's grid of
    # its indirect photons' incoming flux (share: the grid's part), each weighted by
    # cos / (pi pdf): unbiased.
    # "auto": on where the grids predict a fall of the pixels' relative variance worth
    # their cost (guiding.AUTO_GAIN: a room lit by lamps' bright patches), else off;
    # True / "on": always; False / "off": never.
    gather_guiding: str = "auto"
    gather_guide_share: float = 0.5
    # The grids' source: "indirect" (Jensen: the INDIRECT photons' incoming directions at
    # the point) or "flux" (the stored photons as small diffuse emitters, their form
    # factors to the point)
    gather_guide_source: str = "indirect"
    # Pass 2 (camera)
    spp: int = 128                  # camera samples per pixel (jittered, stratified)
    # Adaptive sampling (engine/adaptive.py), Cycles' Sampling > Noise Threshold and Min
    # Samples: a pixel stops sampling once its noise estimate is below the threshold, after
    # at least adaptive_min_samples samples (0: auto as Cycles derives it) and at most spp.
    # 0 = off (the default here, unlike Cycles' 0.01: opt-in while it is measured).
    adaptive_threshold: float = 0.0
    # Cycles' Light Paths > Clamping > Direct / Indirect, in its UI units (0 = off): each
    # camera sample's contribution of light reaching the first hit (direct) or arriving
    # after a further bounce (indirect, the photon estimates included) is scaled down so its
    # R + G + B stays at most 3 x the value (engine/sampleclamp.py). Off here (0, 0) so an
    # engine render is unbiased; the add-on reads Cycles' own (its default Indirect 10).
    clamp_direct: float = 0.0
    clamp_indirect: float = 0.0
    # Cycles' Light Paths > Caustics > Filter Glossy of the scene (0 = off; Cycles' default
    # 1.0), read by the add-on: Cycles widens every glossy, mirror and glass lobe its paths
    # meet after a bounce of low pdf (to GGX alpha 0.41-0.5 after a diffuse bounce at 1.0:
    # surface_shader_prepare_closures). The camera paths do too (engine/filterglossy.py,
    # docs/compatibility.md "fgcamera46"); with final gathering the caustic / glow maps'
    # paths are rendered blurred as well, photon by photon (engine/glossysplit.py,
    # "fgsplit46", "fgphoton46"); the rest (the secondary map, regathers) is
    # rendered unblurred, as Cycles with 0, and the effect report says where that differs.
    cycles_filter_glossy: float = 0.0
    # Cycles' Light Paths > Caustics > Reflective / Refractive of the scene (Cycles'
    # default: both on), read by the add-on only so the effect report can say where
    # Cycles' image differs: off, Cycles drops the glossy-reflection / transmission
    # closures its paths meet after a diffuse bounce (surface_shader_prepare_closures,
    # __CAUSTICS_TRICKS__), and its shadow rays stop at glass, so a sun patch through a
    # window or a glass's caustic is missing from its image. Not simulated: the engine
    # renders that light, as Cycles with both on.
    cycles_caustics_reflective: bool = True
    cycles_caustics_refractive: bool = True
    adaptive_min_samples: int = 0
    # An extra cap on the specular bounces along a camera path (the paper's
    # MaxRayTraceDepth), transparent passes included. Off by default (1024, the most
    # Cycles' Total allows): like Cycles, the camera chain stops at the Light Paths limits
    # below. Was 8, which silently cut glass chains below Cycles' Transmission 12.
    max_depth: int = 1024
    light_samples: int = 1          # shadow rays per light with size, per camera sample
    # Pixel filter (engine/pixelfilter.py): box | gaussian | blackman_harris, width in
    # pixels. Camera rays are drawn from its distribution, as Cycles does; the add-on
    # exports Blender's (Cycles' Film > Pixel Filter, default Blackman-Harris 1.5 px).
    pixel_filter: str = "box"
    filter_width: float = 1.5
    # Transparent surfaces (alpha < 1) a shadow ray may cross before the next one blocks it
    # (Cycles' Light Paths > Max Bounces > Transparent, same default; 0: every surface blocks)
    transparent_max_bounces: int = 8
    # Cycles' Light Paths > Max Bounces, same meaning and defaults (docs/design.md, Bounce
    # limits): a light path (camera to light, the photon's part included) may scatter at
    # most max_bounces times in all, diffuse_bounces times off a diffuse reflection,
    # glossy_bounces off a glossy / mirror reflection and transmission_bounces through a
    # refraction (transparent passes count apart, above); the vertex that connects to the
    # light (a shadow ray, or the photon's first hit) is not a bounce. 0 diffuse = direct
    # light only. max_depth (above) is an optional extra cap on the camera chain.
    max_bounces: int = 12           # (these four: Cycles' defaults, CYCLES_DEFAULT_BOUNCES)
    diffuse_bounces: int = 4
    glossy_bounces: int = 4
    transmission_bounces: int = 12
    # Cycles' Light Paths > Volume bounces (default 0: single scattering): the scatters in
    # a medium a camera path takes after its first, each lit by the lamps
    # (engine/volumescatter.py); above 0 photons scatter in media up to that + 1 times
    # (engine/photonmedium.py).
    volume_bounces: int = 0
    # Modes
    photon_mapping: bool = True     # False = the paper's plain ray tracer (Fig. 5b)
    # Random-walk subsurface scattering on camera paths (engine/subsurfacewalk.py); False:
    # every subsurface closure renders as its diffuse stand-in (engine/subsurface.py).
    subsurface_walk: bool = True
    method: str = "photon"          # local | raytrace | photon (METHODS)
    # Effects: "auto" lets engine.effects decide from the scene (and say why); "on" / "off"
    # force them. True / False are accepted for "on" / "off".
    caustics: str = "auto"          # caustic map (L S+ D light)
    indirect: str = "auto"          # global map / final gathering (diffuse interreflection)
    specular: str = "auto"          # camera rays through mirrors and glass
    soft_shadows: str = "auto"      # several shadow rays for lights with a size
    aim_caustics: bool = True       # shoot caustic photons only towards mirrors and glass
    # Global photons towards where the camera's gather rays end (engine/visualimportance.py)
    photon_importance: bool = True
    show_photons: bool = False      # the image shows the photon-hit view (Fig. 6 left)
    film_transparent: bool = False  # background not drawn (alpha 0), as Blender's option
    # Cycles' data passes to make besides the image (engine/datapasses.py): "denoising"
    # (Denoising Normal / Albedo / Depth), "color" (Diffuse / Glossy / Transmission Color),
    # "object_index", "material_index", "position", "uv", "mist" (one pass each), "light"
    # (Cycles' light passes, engine/lightpasses.py; it brings "color"), "ao" (Ambient
    # Occlusion, engine/aopass.py), "vector" (motion vectors: Scene.vector_motion).
    # Extra outputs: the image's bits do not depend on them.
    data_passes: tuple = ()
    # The Ambient Occlusion pass' ray length, m (Blender's World > Settings > Ambient
    # Occlusion > Distance, world.light_settings.distance; Cycles takes 10 without a world).
    ao_distance: float = 10.0
    # Shader AOVs (Blender's View Layer > Shader AOV): ((name, "value" | "color"), ...),
    # written by the materials' AOV Output nodes (engine/datapasses.py, Material.aovs).
    shader_aovs: tuple = ()
    # Cryptomatte ID mattes to make (engine/cryptomatte.py): any of "object", "material",
    # "asset"; and their Levels (ranks a pixel, 1-16, Blender's default 6). Extra outputs
    # from primary rays of their own: the image's bits do not depend on them.
    cryptomatte: tuple = ()
    cryptomatte_levels: int = 6
    # Light Group passes to make (Blender's View Layer > Light Groups: their names;
    # engine/lightgroups.py): each a render of its own of the group's emitters, in
    # Film.data["lightgroup:" + name]. The image's bits do not depend on them.
    light_groups: tuple = ()
    # Blender's View Layer > Passes > Data > Alpha Threshold (pass_alpha_threshold):
    # the UV pass is written at the first camera-chain surface whose alpha reaches it
    # (Cycles' film_write_data_passes; 0: the first surface whatever its alpha).
    pass_alpha_threshold: float = 0.5
    # The paper's own method (docs/paper_mode.md): its classic estimator (cosine-weighted,
    # fixed radius: `radius` is the paper's MaxPhotonSearchRadius in scene units, metres)
    # and no final gathering; overrides `estimator` and `final_gather`.
    paper_mode: bool = False
    # Reproducibility and resources
    seed: int = 0
    workers: int = 0                # threads for Embree/kd-tree; 0 = all cores
    chunk_size: int = 1 << 17       # rays per wavefront chunk (bounds memory)

    def __post_init__(self):
        def positive_int(name, lo=0):
            v = getattr(self, name)
            try:
                whole = not isinstance(v, bool) and (isinstance(v, int) or float(v).is_integer())
            except (TypeError, ValueError, OverflowError):
                whole = False
            if not whole:
                raise ValueError(f"setting '{name}' must be a whole number, got {v!r}")
            v = int(v)
            if v < lo:
                raise ValueError(f"setting '{name}' must be >= {lo}, got {v}")
            if v > LIMITS[name]:
                raise ValueError(f"setting '{name}' must be <= {LIMITS[name]:,}, got {v:,}")
            setattr(self, name, v)

        for name, lo in (("photons", 0), ("caustic_photons", 0), ("max_photon_depth", 1),
                         ("min_photons", 1), ("k_nearest", 1), ("spp", 1), ("max_depth", 0),
                         ("light_samples", 1), ("seed", 0), ("workers", 0), ("chunk_size", 256),
                         ("gather_rays", 1), ("transparent_max_bounces", 0),
                         ("max_bounces", 0), ("diffuse_bounces", 0), ("glossy_bounces", 0),
                         ("transmission_bounces", 0), ("volume_bounces", 0),
                         ("adaptive_min_samples", 0)):
            positive_int(name, lo)
        for name in ("final_gather", "gather_by_share", "photon_mapping",
                     "aim_caustics", "subsurface_walk",
                     "photon_importance",
                     "show_photons", "film_transparent", "paper_mode"):
            v = getattr(self, name)
            if not isinstance(v, (bool, np.bool_)):  # "no" is a true string
                raise ValueError(f"setting '{name}' must be true or false, got {v!r}")
            setattr(self, name, bool(v))
        for name in EFFECT_SWITCHES + ("gather_guiding",):
            v = getattr(self, name)
            if isinstance(v, bool) or v is None:
                v = {True: "on", False: "off", None: "auto"}[v]
            v = str(v).lower()
            if v not in ("auto", "on", "off"):
                raise ValueError(f"setting '{name}' must be auto, on or off, got {v!r}")
            setattr(self, name, v)
        share = self.gather_guide_share
        if isinstance(share, bool) or not isinstance(share, (int, float, np.floating)) \
                or not 0.0 <= float(share) < 1.0:
            raise ValueError("setting 'gather_guide_share' must be a number in [0, 1), "
                             f"got {share!r}")
        self.gather_guide_share = float(share)
        if self.gather_guide_source not in ("indirect", "flux"):
            raise ValueError("setting 'gather_guide_source' must be indirect or flux, "
                             f"got {self.gather_guide_source!r}")
        if not isinstance(self.method, str) or self.method.lower() not in METHODS:
            raise ValueError(f"setting 'method' must be one of {', '.join(METHODS)}, "
                             f"got {self.method!r}")
        self.method = self.method.lower()
        if not isinstance(self.pixel_filter, str) or \
                self.pixel_filter.lower() not in PIXEL_FILTERS:
            raise ValueError(f"setting 'pixel_filter' must be one of {', '.join(PIXEL_FILTERS)}, "
                             f"got {self.pixel_filter!r}")
        self.pixel_filter = self.pixel_filter.lower()
        ok = isinstance(self.filter_width, (int, float, np.floating, np.integer)) \
            and not isinstance(self.filter_width, bool)
        fw = float(self.filter_width) if ok else float("nan")
        if not (0.0 <= fw <= FILTER_WIDTH_MAX):
            raise ValueError(f"setting 'filter_width' must be a number from 0 to "
                             f"{FILTER_WIDTH_MAX:g} (pixels), got {self.filter_width!r}")
        self.filter_width = fw
        if self.caustic_lookup not in CAUSTIC_LOOKUPS:
            raise ValueError(f"setting 'caustic_lookup' must be one of "
                             f"{', '.join(CAUSTIC_LOOKUPS)}, got {self.caustic_lookup!r}")
        if not isinstance(self.estimator, str) or self.estimator not in ESTIMATORS:
            raise ValueError(f"setting 'estimator' must be one of {', '.join(ESTIMATORS)}, "
                             f"got {self.estimator!r}")
        if self.radius is not None:
            ok = isinstance(self.radius, (int, float, np.floating, np.integer)) \
                and not isinstance(self.radius, bool)
            r = float(self.radius) if ok else float("nan")
            if not (r > 0 and math.isfinite(r)):
                raise ValueError(f"setting 'radius' must be a positive number or None (auto), "
                                 f"got {self.radius!r}")
            self.radius = r
        ok = isinstance(self.adaptive_threshold, (int, float, np.floating, np.integer)) \
            and not isinstance(self.adaptive_threshold, bool)
        t = float(self.adaptive_threshold) if ok else float("nan")
        if not (0.0 <= t <= ADAPTIVE_THRESHOLD_MAX):
            raise ValueError(f"setting 'adaptive_threshold' (Noise Threshold) must be a number "
                             f"from 0 (off) to {ADAPTIVE_THRESHOLD_MAX:g}, got "
                             f"{self.adaptive_threshold!r}")
        self.adaptive_threshold = t
        for name in ("clamp_direct", "clamp_indirect"):
            v = getattr(self, name)
            ok = isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool)
            c = float(v) if ok else float("nan")
            if not 0.0 <= c <= CLAMP_MAX:
                raise ValueError(f"setting '{name}' (Cycles' Clamp {name[6:].title()}) must be "
                                 f"a number from 0 (off) to {CLAMP_MAX:g}, got {v!r}")
            setattr(self, name, c)
        v = self.cycles_filter_glossy
        ok = isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool)
        fg = float(v) if ok else float("nan")
        if not 0.0 <= fg <= FILTER_GLOSSY_MAX:
            raise ValueError("setting 'cycles_filter_glossy' (Cycles' Filter Glossy) must be a "
                             f"number from 0 (off) to {FILTER_GLOSSY_MAX:g}, got {v!r}")
        self.cycles_filter_glossy = fg
        for name in ("cycles_caustics_reflective", "cycles_caustics_refractive"):
            v = getattr(self, name)
            if not isinstance(v, (bool, np.bool_)):
                raise ValueError(f"setting '{name}' (Cycles' Caustics > "
                                 f"{name[16:].title()}) must be True or False, got {v!r}")
            setattr(self, name, bool(v))
        self.data_passes = _word_set("data_passes", self.data_passes, DATA_PASSES)
        ad = self.ao_distance
        if isinstance(ad, bool) or not isinstance(ad, (int, float, np.floating, np.integer)) \
                or not math.isfinite(float(ad)) or float(ad) < 0.0:
            raise ValueError("setting 'ao_distance' (the Ambient Occlusion pass' distance, m) "
                             f"must be a number >= 0, got {ad!r}")
        self.ao_distance = float(ad)
        self.shader_aovs = _shader_aovs(self.shader_aovs)
        if "light" in self.data_passes and "color" not in self.data_passes:
            # Blender shows the light passes divided by the Color passes (Cycles adds
            # them to its buffer when a light pass is asked for): made with them.
            self.data_passes = tuple(sorted(self.data_passes + ("color",)))
        self.cryptomatte = _word_set("cryptomatte", self.cryptomatte, CRYPTOMATTE_KINDS)
        groups = (self.light_groups,) if isinstance(self.light_groups, str) else \
            tuple(self.light_groups or ())
        if not all(isinstance(g, str) and g for g in groups):
            raise ValueError("setting 'light_groups' takes light group names (non-empty "
                             f"strings), got {self.light_groups!r}")
        self.light_groups = tuple(dict.fromkeys(groups))  # (in order, once each)
        lv = self.cryptomatte_levels
        if isinstance(lv, bool) or not isinstance(lv, (int, np.integer)) or not 1 <= lv <= 16:
            raise ValueError("setting 'cryptomatte_levels' must be a whole number from 1 to "
                             f"16, got {lv!r}")
        self.cryptomatte_levels = int(lv)
        a = float(self.pass_alpha_threshold)
        if not 0.0 <= a <= 1.0:
            raise ValueError(f"setting 'pass_alpha_threshold' takes 0 to 1, got "
                             f"{self.pass_alpha_threshold!r}")
        self.pass_alpha_threshold = a
        self.min_photons = min(self.min_photons, self.k_nearest)
        if self.paper_mode:
            self.estimator, self.final_gather = "classic", False

    @property
    def uses_photon_maps(self) -> bool:
        """Photon mapping is on and the method is the full renderer."""
        return self.photon_mapping and self.method == "photon"

    @property
    def bounce_limits(self) -> np.ndarray:
        """(4,) int64: max_bounces, diffuse_bounces, glossy_bounces, transmission_bounces
        (the order of the photons' bounce counts, photonkernels.B_TOTAL ...)."""
        return np.array([self.max_bounces, self.diffuse_bounces, self.glossy_bounces,
                         self.transmission_bounces], np.int64)

    @property
    def camera_depth(self) -> int:
        """The most bounces (bent ones: reflections and refractions) a camera chain takes
        before the Light Paths stop it: max_bounces, or max_depth where the extra cap is
        lower (the effect report names which)."""
        return min(self.max_depth, self.max_bounces)

    @property
    def gather_depth(self) -> int:
        """The most mirror / glass continuations of a final-gather ray: as many as the
        Light Paths allow (max_bounces bounces and transparent_max_bounces transparent
        passes; integrator.gather_indirect ends each chain at its own limits), at most
        max_depth. (Was a fixed 8: the glass of water at Max Bounces 64 read 0.96 of
        Cycles; docs/accuracy.md "### glasswater51".)"""
        return min(self.max_depth, self.max_bounces + self.transparent_max_bounces)

    @property
    def threads(self) -> int:
        return self.workers if self.workers > 0 else max(1, os.cpu_count() or 1)

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in fields(cls)]
