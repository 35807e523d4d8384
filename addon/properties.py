"""Render settings stored on the scene (scene.photonmap) and on each view layer.

Defaults mirror engine.settings.RenderSettings so a .blend renders like the CLI.
"""
import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty,
                       PointerProperty, StringProperty)

ESTIMATOR_ITEMS = (
    ("knn_simpson", "k-NN (Simpson kernel)",
     "Gather the k nearest photons and weight them with a smooth Simpson kernel "
     "(least blotchy)"),
    ("knn_cone", "k-NN (cone filter)",
     "Gather the k nearest photons and weight them with Jensen's cone filter"),
    ("classic", "Classic (paper)",
     "The paper's estimate: all photons inside the search radius, divided by pi r^2"),
    ("radius", "Fixed Radius (Simpson)",
     "All photons inside the search radius, weighted with the Simpson kernel"),
)
METHOD_ITEMS = (
    ("photon", "Photon Mapping",
     "The full renderer: ray tracing plus indirect diffuse light and caustics from photon "
     "maps"),
    ("raytrace", "Ray Tracing",
     "The paper's Fig. 5b: shadows (soft from area lights), mirror reflection and refraction; "
     "no indirect diffuse light, no caustics"),
    ("local", "Local Illumination",
     "Each light's direct light without shadow rays, reflections or refractions (an "
     "OpenGL-style local model); emission and background still shown"),
)
EFFECT_ITEMS = (
    ("auto", "Auto", "Let the engine decide from the scene (the render log says why)"),
    ("on", "On", "Always compute this effect"),
    ("off", "Off", "Never compute this effect"),
)


def _resolution(context):
    """The file's output size in pixels (resolution x percentage), or None."""
    r = getattr(getattr(context, "scene", None), "render", None)
    if r is None:
        return None
    pct = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * pct)), max(1, int(r.resolution_y * pct))


def _preset_items(self, context):
    """Preset labels carry measured cost (scaled to this file's resolution) and error
    (engine/presets_measured.json)."""
    size = _resolution(context)
    try:
        from .core import load_engine
        presets = load_engine().presets
        items = [(n, presets.label(n, *(size or ())),
                  f"Apply the {n} preset (photons, samples, neighbours)")
                 for n in presets.PRESETS]
    except Exception:  # noqa: BLE001 - engine not loadable: still show the choices
        items = [(n, n.capitalize(), "") for n in ("preview", "medium", "high", "reference")]
    # Blender keeps only references to the strings: hold them for the enum's lifetime.
    _preset_items.cache = items + [("custom", "Custom", "Settings edited by hand")]
    return _preset_items.cache


def _apply_preset(self, context):
    if self.quality_preset == "custom":
        return
    from .core import load_engine
    for key, value in load_engine().presets.PRESETS[self.quality_preset].items():
        setattr(self, key, value)


def _preset_edited(key):
    """Update callback of a setting a preset sets: a value other than the preset's turns
    the preset into Custom (applying a preset sets its own values: no change)."""
    def update(self, context):
        if self.quality_preset == "custom":
            return
        from .core import load_engine
        preset = load_engine().presets.PRESETS.get(self.quality_preset, {})
        if key in preset and getattr(self, key) != preset[key]:
            self.quality_preset = "custom"
    return update


class PhotonMapRenderSettings(bpy.types.PropertyGroup):
    quality_preset: EnumProperty(
        name="Quality", items=_preset_items, update=_apply_preset, default=2,  # "high"
        description="Settings bundles; the label shows time and error measured on the "
                    "Figure 6 box (bench/bench_accuracy.py)")
    # Render > Motion Blur (Blender's switch, Shutter and Position; engine/motionblur.py)
    motion_blur_steps: IntProperty(
        name="Steps", default=0, min=0, max=256, soft_max=64,
        description="Motion blur: the shutter is cut into this many time slices, each "
                    "rendered whole at its middle time (its own photons, a share of the "
                    "samples) and averaged; more steps blur fast motion without ghost "
                    "copies and cost one photon pass each. 0 = Auto: as many as keep the "
                    "fastest vertex within 3 pixels a step (at most 64)")
    # Progressive rendering
    progressive: BoolProperty(
        name="Progressive", default=False,
        description="Render passes of fresh photons with a shrinking search area and show "
                    "the image after every pass; stop at the budget below")
    max_passes: IntProperty(
        name="Passes", default=16, min=0, soft_max=1000,
        description="Stop after this many passes (0 = no pass limit)")
    time_limit: FloatProperty(
        name="Time Limit", default=0.0, min=0.0, soft_max=3600.0, subtype="TIME_ABSOLUTE",
        unit="TIME_ABSOLUTE",
        description="Stop before a pass would end after this many seconds (0 = no limit)")
    target_error: FloatProperty(
        name="Target Error", default=0.0, min=0.0, soft_max=0.1, precision=4,
        description="Stop when the estimated relative MSE (from two independent "
                    "half-images) falls below this (0 = no target)")
    # Pass 1: photons
    photons: IntProperty(
        name="Photons", default=400_000, min=0, soft_max=5_000_000, max=2**31 - 1,
        update=_preset_edited("photons"),
        description="Photons emitted for the global photon map (shared by all lights in "
                    "proportion to their power)")
    caustic_photons: IntProperty(
        name="Caustic Photons", default=200_000, min=0, soft_max=5_000_000, max=2**31 - 1,
        update=_preset_edited("caustic_photons"),
        description="Photons emitted towards glass and mirrors for the caustic map")
    max_photon_depth: IntProperty(
        name="Max Photon Depth", default=32, min=1, max=1000,
        description="An extra cap on the bounces a photon may take before it is dropped. "
                    "Photons also stop at Light Paths > Max Bounces (and Russian roulette "
                    "ends most sooner), so the default 32 caps nothing at Cycles' defaults")
    # Radiance estimate
    estimator: EnumProperty(
        name="Estimator", items=ESTIMATOR_ITEMS, default="knn_simpson",
        description="How the photons near a point are turned into radiance: which "
                    "photons (the k nearest, or all in the search radius) and how they are "
                    "weighted by distance")
    use_auto_radius: BoolProperty(
        name="Auto Radius", default=True,
        description="Derive the maximum photon search radius from scene size and photon "
                    "density")
    radius: FloatProperty(
        name="Search Radius", default=0.1, min=0.0, soft_max=10.0, subtype="DISTANCE",
        unit="LENGTH", precision=4,
        description="Maximum photon search radius in scene units (used when Auto Radius is "
                    "off; the paper's MaxPhotonSearchRadius). 0 = automatic, as Auto Radius")
    paper_mode: BoolProperty(
        name="Paper Mode", default=False,
        description="The paper's own method: its classic estimator (photons in a sphere of "
                    "the search radius, cosine-weighted), no final gathering. Overrides "
                    "Estimator and Final Gather")
    min_photons: IntProperty(
        name="Min Photons", default=8, min=1, max=10_000,
        description="Fewer photons than this in range: no estimate (as in the paper)")
    k_nearest: IntProperty(
        name="Nearest Photons", default=64, min=1, max=10_000,
        update=_preset_edited("k_nearest"),
        description="Photons gathered per k-nearest estimate: more is smoother but "
                    "blurs shadows and caustics, fewer is sharper but blotchier")
    final_gather: BoolProperty(
        name="Final Gather", default=True,
        description="Estimate indirect light by gather rays into the global map "
                    "(smoother) instead of reading the map directly")
    gather_rays: IntProperty(
        name="Gather Rays", default=2, min=1, max=256, update=_preset_edited("gather_rays"),
        description="Final-gather rays per camera sample (the most, with Gather by "
                    "Indirect Share)")
    gather_by_share: BoolProperty(
        name="Gather by Indirect Share", default=True,
        description="Cast fewer gather rays where indirect light is a small share of the "
                    "diffuse light the camera sees (measured from the global photons): "
                    "one ray below 5 % with the default 2, in proportion above")
    # Pass 2: camera
    spp: IntProperty(
        name="Samples", default=128, min=1, soft_max=1024, max=65536,
        update=_preset_edited("spp"),
        description="Camera samples per pixel (jittered, anti-aliasing)")
    # Adaptive sampling, Cycles' Sampling > Noise Threshold / Min Samples (same names,
    # ranges and threshold default; engine/adaptive.py). Our own properties, not
    # scene.cycles': Cycles has adaptive sampling on by default, which would switch it on
    # for every scene while it is opt-in here (docs/performance.md "adaptive").
    use_adaptive_sampling: BoolProperty(
        name="Adaptive Sampling", default=False,
        description="Automatically reduce the number of samples per pixel based on "
                    "estimated noise level (as Cycles' Noise Threshold)")
    adaptive_threshold: FloatProperty(
        name="Noise Threshold", default=0.01, min=0.0, max=1.0, soft_min=0.001,
        precision=4, step=0.1,
        description="Noise level step to stop sampling at, lower values reduce noise at "
                    "the cost of render time. Zero for automatic setting based on number "
                    "of AA samples")
    adaptive_min_samples: IntProperty(
        name="Min Samples", default=0, min=0, max=65536, soft_max=4096,
        description="Minimum AA samples for adaptive sampling, to discover noisy features "
                    "before stopping sampling. Zero for automatic setting based on noise "
                    "threshold")
    max_depth: IntProperty(
        name="Max Ray Depth", default=1024, min=0, max=1024,
        description="An extra cap on the mirror and glass bounces along a camera path. The "
                    "default 1024 caps nothing: camera paths stop at the Max Bounces above, "
                    "as in Cycles. (Photon Mapping Made Easy calls this MaxRayTraceDepth)")
    light_samples: IntProperty(
        name="Light Samples", default=1, min=1, max=256,
        description="Shadow rays per light with a size, per camera sample (soft shadows)")
    transparent_max_bounces: IntProperty(
        name="Transparent Bounces", default=8, min=0, max=1024,
        description="Transparent surfaces (alpha below 1) a shadow ray may cross before the "
                    "next one blocks it, as Cycles' Max Bounces > Transparent; 0 = every "
                    "surface casts a full shadow")
    # Cycles' Light Paths > Max Bounces, same names, defaults and meaning: used only where
    # the Cycles add-on is missing; with it the render reads (and our panel shows) Cycles'
    # own properties, so the limits follow a scene set up for Cycles
    # (export.light_path_settings; engine/settings.py, docs/design.md, Bounce limits)
    max_bounces: IntProperty(
        name="Total", default=12, min=0, max=1024,
        description="Total maximum number of bounces of a light path (as Cycles' Max "
                    "Bounces > Total)")
    diffuse_bounces: IntProperty(
        name="Diffuse", default=4, min=0, max=1024,
        description="Maximum number of diffuse reflection bounces (0: direct light only)")
    glossy_bounces: IntProperty(
        name="Glossy", default=4, min=0, max=1024,
        description="Maximum number of glossy and mirror reflection bounces")
    transmission_bounces: IntProperty(
        name="Transmission", default=12, min=0, max=1024,
        description="Maximum number of refractions (glass, transmission)")
    # Cycles' Light Paths > Clamping, same names, defaults (Direct 0, Indirect 10) and
    # meaning: used only where the Cycles add-on is missing, as the bounce limits above
    # (export.clamp_settings; engine/sampleclamp.py). Indirect 10 as Cycles, so a scene
    # made without Cycles' settings renders as Cycles would render it.
    sample_clamp_direct: FloatProperty(
        name="Direct Light", default=0.0, min=0.0, max=1e8, soft_max=1000.0,
        description="As Cycles' Clamping > Direct Light: each camera sample's light reaching "
                    "the first surface it meets (and emitters or the world it sees) is "
                    "scaled down to at most this brightness per channel on average; "
                    "0 = off (fireflies kept, unbiased)")
    sample_clamp_indirect: FloatProperty(
        name="Indirect Light", default=10.0, min=0.0, max=1e8, soft_max=1000.0,
        description="As Cycles' Clamping > Indirect Light: each camera sample's light "
                    "arriving after a further bounce (glossy reflections of lights, photon "
                    "estimates) is scaled down to at most this brightness per channel on "
                    "average, which removes fireflies but darkens bright indirect light; "
                    "0 = off")
    # Modes
    method: EnumProperty(
        name="Method", items=METHOD_ITEMS, default="photon",
        description="Rendering method, to show what each adds (docs/teaching.md)")
    photon_mapping: BoolProperty(
        name="Photon Mapping", default=True,
        description="Off: plain ray tracing with direct light only (the paper's Fig. 5b)")
    caustics: EnumProperty(
        name="Caustics", items=EFFECT_ITEMS, default="auto",
        description="Light focused by glass and mirrors onto diffuse surfaces (caustic map)")
    indirect: EnumProperty(
        name="Indirect Light", items=EFFECT_ITEMS, default="auto",
        description="Diffuse interreflection from the global photon map / final gathering")
    specular: EnumProperty(
        name="Specular", items=EFFECT_ITEMS, default="auto",
        description="Camera rays continued through mirrors and glass")
    soft_shadows: EnumProperty(
        name="Soft Shadows", items=EFFECT_ITEMS, default="auto",
        description="Several shadow rays for lights with a size")
    subsurface_walk: BoolProperty(
        name="Subsurface Random Walk", default=True,
        description="Camera rays walk beneath subsurface surfaces as Cycles' Random Walk "
                    "(light through thin parts, soft terminators); off: a diffuse surface "
                    "of the albedo the walk gives a thick object")
    aim_caustics: BoolProperty(
        name="Aim Caustic Photons", default=True,
        description="Shoot caustic photons only towards mirrors and glass")
    photon_importance: BoolProperty(
        name="Photons Where Seen", default=True,
        description="Send more global photons where the camera's gather rays use them "
                    "(visual importance: a coarse camera pre-pass marks the region; photons "
                    "elsewhere carry more power each, so the image stays unbiased). "
                    "A closed room keeps the plain shot")
    show_photons: BoolProperty(
        name="Show Photon Hits", default=False,
        description="Show the photon-hit view (dots by photon kind on black, the paper's "
                    "Fig. 6, left) as the image; the Photon Hits pass always has it")
    seed: IntProperty(
        name="Seed", default=0, min=0,
        description="Random seed: the same seed and settings give the same image")
    use_animated_seed: BoolProperty(
        name="Animated Seed", default=False,
        description="Use a different seed on every frame (seed and frame number mixed), so "
                    "the noise of an animation changes from frame to frame; off = the same "
                    "noise pattern on every frame. Either way a frame renders the same on any "
                    "machine of a render farm")
    threads: IntProperty(
        name="Threads", default=0, min=0, max=1024,
        description="Threads for ray tracing and photon search; 0 = all cores")

    # Distributed rendering (engine/distributed.py, docs/distributed.md)
    dask_scheduler: StringProperty(
        name="Scheduler", default="",
        description="Dask scheduler that renders the progressive passes on its workers: "
                    "tcp://HOST:8786 (or local:W for W worker processes on this machine). "
                    "Empty = render on this machine. Same image either way")

    # --- Rendered viewport (addon/viewport.py, issue 19) ---------------------------------
    viewport_passes: IntProperty(
        name="Viewport Passes", default=32, min=0, soft_max=1000,
        description="Passes the rendered viewport refines to before it stops "
                    "(0 = until the view is left)")
    viewport_resolution: IntProperty(
        name="Viewport Resolution", default=50, min=1, max=100, subtype="PERCENTAGE",
        description="Rendered viewport pixels in percent of the view's own; the first "
                    "images come at a quarter and a half of this")
    viewport_photons: IntProperty(
        name="Viewport Photons", default=20_000, min=0, soft_max=1_000_000, max=2**31 - 1,
        description="Global photons emitted per viewport pass")
    viewport_caustic_photons: IntProperty(
        name="Viewport Caustic Photons", default=10_000, min=0, soft_max=1_000_000,
        max=2**31 - 1, description="Caustic photons emitted per viewport pass")
    viewport_samples: IntProperty(
        name="Viewport Samples", default=1, min=1, soft_max=64, max=65536,
        description="Camera samples per pixel in each viewport pass")

    def to_viewport_settings_kwargs(self, film_transparent=False):
        """RenderSettings keyword arguments of the rendered viewport: the render's
        settings with the viewport's photons and samples per pass."""
        kwargs = self.to_settings_kwargs(film_transparent)
        kwargs.update(photons=self.viewport_photons,
                      caustic_photons=self.viewport_caustic_photons,
                      spp=self.viewport_samples, show_photons=False,
                      adaptive_threshold=0.0)  # (a viewport pass takes few samples)
        return kwargs

    def noise_threshold(self) -> float:
        """RenderSettings.adaptive_threshold: 0 (off) unless Adaptive Sampling is on; a
        threshold of 0 is automatic as in Cycles, max(0.001, 1 / Samples)
        (Integrator::get_adaptive_sampling)."""
        if not self.use_adaptive_sampling:
            return 0.0
        t = float(self.adaptive_threshold)
        return t if t > 0.0 else max(0.001, 1.0 / max(1, self.spp))
    # --- end of the viewport block -------------------------------------------------------

    def to_settings_kwargs(self, film_transparent=False):
        """Keyword arguments for engine.settings.RenderSettings (the pixel filter from
        the scene's Film settings: export.pixel_filter_settings)."""
        from .export import (clamp_settings, filter_glossy_settings, light_path_settings,
                             pixel_filter_settings)
        kwargs = dict(
            photons=self.photons, caustic_photons=self.caustic_photons,
            max_photon_depth=self.max_photon_depth, estimator=self.estimator,
            # 0 (typed, or Blender's old minimum 1e-6) means automatic, never a radius
            # that finds no photon.
            radius=None if self.use_auto_radius or self.radius <= 1e-6 else float(self.radius),
            paper_mode=self.paper_mode,
            min_photons=self.min_photons, k_nearest=self.k_nearest,
            final_gather=self.final_gather, gather_rays=self.gather_rays,
            gather_by_share=self.gather_by_share,
            spp=self.spp, max_depth=self.max_depth, light_samples=self.light_samples,
            adaptive_threshold=self.noise_threshold(),
            adaptive_min_samples=self.adaptive_min_samples,
            transparent_max_bounces=self.transparent_max_bounces,
            max_bounces=self.max_bounces, diffuse_bounces=self.diffuse_bounces,
            glossy_bounces=self.glossy_bounces, transmission_bounces=self.transmission_bounces,
            photon_mapping=self.photon_mapping, method=self.method, caustics=self.caustics,
            indirect=self.indirect, specular=self.specular, soft_shadows=self.soft_shadows,
            aim_caustics=self.aim_caustics, photon_importance=self.photon_importance,
            subsurface_walk=self.subsurface_walk,
            show_photons=self.show_photons, seed=self.seed, workers=self.threads,
            film_transparent=bool(film_transparent))
        kwargs.update(pixel_filter_settings(self.id_data))
        kwargs.update(light_path_settings(self.id_data, self))
        kwargs.update(clamp_settings(self.id_data, self))
        kwargs.update(filter_glossy_settings(self.id_data))
        return kwargs


class PhotonMapViewLayerSettings(bpy.types.PropertyGroup):
    use_pass_effects: BoolProperty(
        name="Effect Passes", default=True,
        description="Write Direct, Indirect, Caustic, Specular and Emission passes "
                    "(they sum to Combined)")
    use_pass_photon_hits: BoolProperty(
        name="Photon Hits", default=True,
        description="Write a pass with the stored photon hits drawn as dots on black, "
                    "coloured by kind: yellow direct, blue indirect, magenta caustic")


classes = (PhotonMapRenderSettings, PhotonMapViewLayerSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.photonmap = PointerProperty(type=PhotonMapRenderSettings)
    bpy.types.ViewLayer.photonmap = PointerProperty(type=PhotonMapViewLayerSettings)


def unregister():
    del bpy.types.ViewLayer.photonmap
    del bpy.types.Scene.photonmap
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
