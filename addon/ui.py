"""Panels: our settings in Render / View Layer Properties, and Blender's standard panels
(format, output, camera, light, material, world) enabled for our engine."""
import bpy

from .engine import ENGINE_ID

# Standard panels written for EEVEE that also describe what we render.
EXTRA_COMPAT_PANELS = (
    "DATA_PT_EEVEE_light",
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_WORLD_PT_surface",
    "EEVEE_WORLD_PT_mist",  # World > Mist Pass: the Mist data pass' start / depth / falloff
)
# BLENDER_RENDER panels that make no sense for us.
EXCLUDED_PANELS = {
    "DATA_PT_camera_dof", "DATA_PT_camera_dof_aperture", "DATA_PT_falloff_curve",
    "DATA_PT_light", "DATA_PT_preview", "DATA_PT_area",
    "DATA_PT_sunsky", "DATA_PT_shadow", "DATA_PT_lightprobe", "DATA_PT_lightprobe_display",
    "DATA_PT_lightprobe_parallax", "DATA_PT_lightprobe_visibility",
    "DATA_PT_context_lightprobe", "MATERIAL_PT_freestyle_line",
    "EEVEE_MATERIAL_PT_viewport_settings",
}


def get_panels():
    panels = []
    for panel in bpy.types.Panel.__subclasses__():
        compat = getattr(panel, "COMPAT_ENGINES", None)
        if compat is None:
            continue
        name = panel.__name__
        if name in EXCLUDED_PANELS:
            continue
        if "BLENDER_RENDER" in compat or name in EXTRA_COMPAT_PANELS:
            panels.append(panel)
    return panels


class PhotonMapButtonsPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE_ID}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class PHOTONMAP_PT_sampling(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        layout.prop(pm, "quality_preset")
        layout.prop(pm, "method")
        col = layout.column()
        # Noise Threshold as Cycles draws it (a checkbox heading the threshold), then
        # Max / Min Samples; adaptive sampling is the plain render's, not the passes'.
        adaptive = pm.use_adaptive_sampling and not pm.progressive
        if not pm.progressive:
            row = col.row(heading="Noise Threshold", align=True)
            row.prop(pm, "use_adaptive_sampling", text="")
            sub = row.row()
            sub.active = pm.use_adaptive_sampling
            sub.prop(pm, "adaptive_threshold", text="")
        col.prop(pm, "spp", text="Samples per Pass" if pm.progressive
                 else ("Max Samples" if adaptive else "Samples"))
        if adaptive:
            col.prop(pm, "adaptive_min_samples", text="Min Samples")
        col.prop(pm, "light_samples")
        col.prop(pm, "seed")
        col.prop(pm, "use_animated_seed")


class PHOTONMAP_PT_light_paths(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        pass


class PHOTONMAP_PT_light_paths_max_bounces(PhotonMapButtonsPanel, bpy.types.Panel):
    """Light Paths > Max Bounces: Cycles' own properties when the Cycles add-on is there
    (the render reads them: addon/export.light_path_settings; the same panel as Cycles',
    so a scene set up for Cycles renders with its limits), else ours with the same names
    and defaults; and our Max Ray Depth, an extra cap on camera paths (docs/design.md,
    Bounce limits)."""
    bl_label = "Max Bounces"
    bl_parent_id = "PHOTONMAP_PT_light_paths"

    def draw(self, context):
        from .export import light_path_source
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        src = light_path_source(context.scene, pm)
        col = layout.column(align=True)
        col.prop(src, "max_bounces", text="Total")
        col = layout.column(align=True)
        col.prop(src, "diffuse_bounces", text="Diffuse")
        col.prop(src, "glossy_bounces", text="Glossy")
        col.prop(src, "transmission_bounces", text="Transmission")
        col.prop(src, "transparent_max_bounces", text="Transparent")
        if src is not pm:
            layout.label(text="Shared with Cycles' Light Paths", icon="LINKED")
        col = layout.column()
        col.prop(pm, "max_depth")
        if pm.max_depth < src.max_bounces:
            # The cap cuts camera paths shorter than the limits (the effect report says so).
            col.label(text=f"Camera paths stop after {pm.max_depth} mirror / glass bounces",
                      icon="INFO")


class PHOTONMAP_PT_light_paths_clamping(PhotonMapButtonsPanel, bpy.types.Panel):
    """Light Paths > Clamping: Cycles' own Direct / Indirect Light when the Cycles add-on
    is there (the render reads them: addon/export.clamp_settings), else ours with the same
    names and defaults (engine/sampleclamp.py)."""
    bl_label = "Clamping"
    bl_parent_id = "PHOTONMAP_PT_light_paths"

    def draw(self, context):
        from .export import clamp_source
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        src = clamp_source(context.scene, pm)
        col = layout.column(align=True)
        col.prop(src, "sample_clamp_direct", text="Direct Light")
        col.prop(src, "sample_clamp_indirect", text="Indirect Light")
        if src is not pm:
            layout.label(text="Shared with Cycles' Light Paths", icon="LINKED")


class PHOTONMAP_PT_photons(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Photon Mapping"

    def draw_header(self, context):
        self.layout.prop(context.scene.photonmap, "photon_mapping", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        layout.active = pm.photon_mapping and pm.method == "photon"
        col = layout.column()
        col.prop(pm, "photons")
        sub = col.column()
        # visual importance serves final gathering only (engine/render.py)
        sub.active = pm.indirect != "off" and pm.final_gather and not pm.paper_mode
        sub.prop(pm, "photon_importance")
        col.prop(pm, "max_photon_depth")
        col.separator()
        col.prop(pm, "caustics")
        sub = col.column()
        sub.active = pm.caustics != "off"
        sub.prop(pm, "caustic_photons")
        sub.prop(pm, "aim_caustics")
        col.separator()
        col.prop(pm, "subsurface_walk")
        col.separator()
        col.prop(pm, "indirect")
        col.prop(pm, "specular")
        col.prop(pm, "soft_shadows")


class PHOTONMAP_PT_estimate(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Radiance Estimate"
    bl_parent_id = "PHOTONMAP_PT_photons"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        layout.active = pm.photon_mapping
        col = layout.column()
        col.prop(pm, "paper_mode")
        sub = col.column()
        sub.active = not pm.paper_mode
        sub.prop(pm, "estimator")
        col.prop(pm, "use_auto_radius")
        sub = col.column()
        sub.active = not pm.use_auto_radius
        sub.prop(pm, "radius")
        if not pm.use_auto_radius and pm.radius <= 1e-6:
            sub.label(text="Radius 0: the automatic radius is used", icon="INFO")
        col.prop(pm, "min_photons")
        sub = col.column()
        sub.active = pm.estimator not in ("classic", "radius") and not pm.paper_mode
        sub.prop(pm, "k_nearest")
        col.separator()
        sub = col.column()
        sub.active = not pm.paper_mode
        sub.prop(pm, "final_gather")
        sub = col.column()
        sub.active = pm.final_gather and not pm.paper_mode
        sub.prop(pm, "gather_rays")
        sub.prop(pm, "gather_by_share")


class PHOTONMAP_PT_display(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Film"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        col.prop(context.scene.render, "film_transparent", text="Transparent")
        col.prop(context.scene.photonmap, "show_photons")
        # The pixel filter is Cycles' own setting (shared, so both engines filter alike;
        # addon/export.pixel_filter_settings); without Cycles, Blender's filter size.
        cycles = getattr(context.scene, "cycles", None)
        if cycles is not None and hasattr(cycles, "pixel_filter_type"):
            col.prop(cycles, "pixel_filter_type", text="Pixel Filter")
            if cycles.pixel_filter_type != "BOX":
                col.prop(cycles, "filter_width", text="Width")
        else:
            col.prop(context.scene.render, "filter_size", text="Filter Size")


class PHOTONMAP_PT_motion_blur(PhotonMapButtonsPanel, bpy.types.Panel):
    """Blender's own motion blur settings (shared with Cycles and EEVEE) and our steps."""
    bl_label = "Motion Blur"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header(self, context):
        self.layout.prop(context.scene.render, "use_motion_blur", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        render = context.scene.render
        col = layout.column()
        col.active = render.use_motion_blur
        col.prop(render, "motion_blur_position", text="Position")
        col.prop(render, "motion_blur_shutter")
        col.prop(context.scene.photonmap, "motion_blur_steps")


class PHOTONMAP_PT_performance(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.photonmap, "threads")


class PHOTONMAP_PT_distributed(PhotonMapButtonsPanel, bpy.types.Panel):
    """Progressive passes on a Dask cluster (docs/distributed.md). dask is needed only
    when an address is set; the panel says what is missing and how to install it."""
    bl_label = "Distributed"
    bl_parent_id = "PHOTONMAP_PT_performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        import importlib.util
        import sys
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        layout.prop(pm, "dask_scheduler")
        if not pm.dask_scheduler.strip():
            layout.label(text="Off: empty address renders on this machine")
            return
        missing = [m for m in ("dask", "distributed") if importlib.util.find_spec(m) is None]
        col = layout.column(align=True)
        if missing:
            col.alert = True
            col.label(text=f"Missing Python packages: {', '.join(missing)}", icon="ERROR")
            col.label(text="Install them into Blender's Python:")
            col.label(text=f'"{sys.executable}" -m pip install "dask[distributed]"')
            return
        col.label(text="F12 and animations render progressive passes on the cluster", icon="INFO")
        col.label(text="(budget: Sampling > Progressive); workers need the engine installed")


class PHOTONMAP_PT_passes(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        vl = context.view_layer
        col = layout.column(heading="Include")
        col.prop(vl.photonmap, "use_pass_effects")
        col.prop(vl.photonmap, "use_pass_photon_hits")
        col.prop(vl, "use_pass_z")
        col.prop(vl, "use_pass_normal")
        # Cycles' data passes we make (engine/datapasses.py); Denoising Data is Cycles'
        # own switch (absent without Cycles).
        if getattr(vl, "cycles", None) is not None:
            col.prop(vl.cycles, "denoising_store_passes", text="Denoising Data")
        col = layout.column(heading="Data")
        # Vector: made with Motion Blur off, as Cycles (engine/vectorpass.py).
        col.prop(vl, "use_pass_vector")
        col.prop(vl, "use_pass_position")
        col.prop(vl, "use_pass_uv")
        col.prop(vl, "use_pass_mist")
        col = layout.column(heading="Indexes")
        col.prop(vl, "use_pass_object_index")
        col.prop(vl, "use_pass_material_index")
        col = layout.column()
        col.prop(vl, "pass_alpha_threshold")
        col = layout.column(heading="Color")
        col.prop(vl, "use_pass_diffuse_color", text="Diffuse")
        col.prop(vl, "use_pass_glossy_color", text="Glossy")
        col.prop(vl, "use_pass_transmission_color", text="Transmission")
        col = layout.column(heading="Light")
        col.prop(vl, "use_pass_ambient_occlusion", text="Ambient Occlusion")  # aopass.py
        if getattr(vl, "cycles", None) is not None:
            # Cycles' switch (engine/shadowcatcher.py): the pass, and Combined without
            # the shadow.
            col.prop(vl.cycles, "use_pass_shadow_catcher")


def _light_group_field(layout, owner, view_layer):
    """owner's Light Group (an object's, the world's) picked among the view layer's, with
    Cycles' button that adds a typed name as a group (its CYCLES_OBJECT_PT_lightgroup)."""
    row = layout.row(align=True)
    row.use_property_decorate = False
    sub = row.column(align=True)
    sub.prop_search(owner, "lightgroup", view_layer, "lightgroups", text="Light Group",
                    results_are_suggestions=True)
    sub = row.column(align=True)
    sub.enabled = bool(owner.lightgroup) and not any(
        lg.name == owner.lightgroup for lg in view_layer.lightgroups)
    sub.operator("scene.view_layer_add_lightgroup", icon="ADD", text="").name = \
        owner.lightgroup


try:  # Blender's View Layer > Light Groups list (its helper; Cycles' panel is its own)
    from bl_ui.properties_view_layer import ViewLayerLightgroupsPanelHelper
except ImportError:  # (older Blender: the list is drawn below)
    ViewLayerLightgroupsPanelHelper = None


class PHOTONMAP_PT_passes_lightgroups(PhotonMapButtonsPanel, bpy.types.Panel):
    """View Layer > Passes > Light Groups: one pass "Combined_<group>" each
    (engine/lightgroups.py)."""
    bl_label = "Light Groups"
    bl_context = "view_layer"
    bl_parent_id = "PHOTONMAP_PT_passes"

    def draw(self, context):
        if ViewLayerLightgroupsPanelHelper is not None:
            ViewLayerLightgroupsPanelHelper.draw(self, context)
            return
        vl = context.view_layer
        row = self.layout.row()
        row.template_list("UI_UL_list", "lightgroups", vl, "lightgroups", vl,
                          "active_lightgroup_index", rows=3)
        col = row.column(align=True)
        col.operator("scene.view_layer_add_lightgroup", icon="ADD", text="")
        col.operator("scene.view_layer_remove_lightgroup", icon="REMOVE", text="")


class PHOTONMAP_PT_object_lightgroup(PhotonMapButtonsPanel, bpy.types.Panel):
    """Object > Shading > Light Group: the pass its light goes to (lamps, emissive
    objects; engine/lightgroups.py)."""
    bl_label = "Light Group"
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_shading"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and context.object is not None

    def draw(self, context):
        self.layout.use_property_split = True
        _light_group_field(self.layout, context.object, context.view_layer)


class PHOTONMAP_PT_world_lightgroup(PhotonMapButtonsPanel, bpy.types.Panel):
    """World > Light Group: the pass the world's light goes to (engine/lightgroups.py)."""
    bl_label = "Light Group"
    bl_context = "world"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and context.world is not None

    def draw(self, context):
        self.layout.use_property_split = True
        _light_group_field(self.layout, context.world, context.view_layer)


# Object types with surfaces (Cycles' has_geometry_visibility, less its light case).
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META", "CURVES", "POINTCLOUD",
                  "VOLUME"}


class PHOTONMAP_PT_object_visibility(PhotonMapButtonsPanel, bpy.types.Panel):
    """Object > Visibility's ray visibility and masks as Cycles shows them (the add-on
    reads them: addon/export.py ray_visibility); Blender's own Visibility panel shows
    them for Cycles and EEVEE only."""
    bl_label = "Ray Visibility and Mask"
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_visibility"

    @classmethod
    def poll(cls, context):
        ob = context.object
        return (context.engine in cls.COMPAT_ENGINES and ob is not None
                and (ob.type in GEOMETRY_TYPES or ob.type == "LIGHT"))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        ob = context.object
        col = layout.column(heading="Ray Visibility")
        if ob.type != "LIGHT":
            col.prop(ob, "visible_camera", text="Camera")
        col.prop(ob, "visible_diffuse", text="Diffuse")
        col.prop(ob, "visible_glossy", text="Glossy")
        col.prop(ob, "visible_transmission", text="Transmission")
        if ob.type != "LIGHT":
            col.prop(ob, "visible_shadow", text="Shadow")
            col = layout.column(heading="Mask")
            col.prop(ob, "is_shadow_catcher")
            col.prop(ob, "is_holdout")


class PHOTONMAP_PT_progressive(PhotonMapButtonsPanel, bpy.types.Panel):
    bl_label = "Progressive"
    bl_parent_id = "PHOTONMAP_PT_sampling"

    def draw_header(self, context):
        self.layout.prop(context.scene.photonmap, "progressive", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        col = layout.column()
        col.active = pm.progressive
        col.prop(pm, "max_passes")
        col.prop(pm, "time_limit")
        col.prop(pm, "target_error")


class PHOTONMAP_PT_effects(PhotonMapButtonsPanel, bpy.types.Panel):
    """What the last render decided to simulate, and why (engine/effects.py)."""
    bl_label = "Effects of Last Render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        from .engine import last_render
        lines = (last_render.get("stats") or {}).get("effects") or []
        col = self.layout.column(align=True)
        if not lines:
            col.label(text="Render once to see which effects the scene needs")
        for line in lines:
            effect, _, why = line.partition(" - ")
            icon = ("INFO" if effect.startswith("method:")
                    else "CHECKMARK" if effect.endswith(": on") else "X")
            col.label(text=effect, icon=icon)
            if why:
                col.label(text="    " + why)


class PHOTONMAP_PT_teaching(PhotonMapButtonsPanel, bpy.types.Panel):
    """Rendering methods and the teaching images (addon/operators.py, docs/teaching.md)."""
    bl_label = "Teaching"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        _teaching_operators(layout.column(align=True))


def _teaching_operators(layout):
    """The teaching operators (addon/operators.py), in the panel and the Render menu."""
    layout.operator("photonmap.compare_methods", icon="IMAGE_DATA")
    layout.operator("photonmap.parameter_sweep", icon="SEQ_STRIP_DUPLICATE")
    layout.operator("photonmap.effects_strip", icon="RENDERLAYERS")


def draw_render_menu(self, context):
    """Render menu entries, shown while our engine is selected."""
    if context.engine != ENGINE_ID:
        return
    self.layout.separator()
    _teaching_operators(self.layout)


# --- Rendered viewport (addon/viewport.py, issue 19) -------------------------------------
class PHOTONMAP_PT_viewport(PhotonMapButtonsPanel, bpy.types.Panel):
    """Settings of the 3D view's Rendered shading (smaller than the render's)."""
    bl_label = "Viewport"
    bl_parent_id = "PHOTONMAP_PT_sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        pm = context.scene.photonmap
        col = layout.column()
        col.prop(pm, "viewport_passes", text="Passes")
        col.prop(pm, "viewport_resolution", text="Resolution")
        col.prop(pm, "viewport_samples", text="Samples per Pass")
        col.prop(pm, "viewport_photons", text="Photons per Pass")
        col.prop(pm, "viewport_caustic_photons", text="Caustic Photons")
# --- end of the viewport block ------------------------------------------------------------


class PHOTONMAP_PT_material_settings(PhotonMapButtonsPanel, bpy.types.Panel):
    """Material > Settings as Cycles shows them: Emission Sampling (which sides of the
    emission shadow rays sample, addon/materials.py) and the Material Index pass' Pass
    Index. Cycles' own panel is drawn for Cycles alone."""
    bl_label = "Settings"
    bl_context = "material"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and context.material is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        mat = context.material
        col = layout.column()
        settings = getattr(mat, "cycles", None)
        if settings is not None and hasattr(settings, "emission_sampling"):
            col.prop(settings, "emission_sampling")
        col.prop(mat, "pass_index")


classes = (PHOTONMAP_PT_sampling, PHOTONMAP_PT_progressive, PHOTONMAP_PT_viewport,
           PHOTONMAP_PT_light_paths, PHOTONMAP_PT_light_paths_max_bounces,
           PHOTONMAP_PT_light_paths_clamping,
           PHOTONMAP_PT_effects,
           PHOTONMAP_PT_photons, PHOTONMAP_PT_estimate,
           PHOTONMAP_PT_display, PHOTONMAP_PT_motion_blur, PHOTONMAP_PT_performance,
           PHOTONMAP_PT_distributed,
           PHOTONMAP_PT_passes, PHOTONMAP_PT_passes_lightgroups,
           PHOTONMAP_PT_object_lightgroup, PHOTONMAP_PT_world_lightgroup,
           PHOTONMAP_PT_teaching, PHOTONMAP_PT_material_settings,
           PHOTONMAP_PT_object_visibility)

_patched = []


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_render.append(draw_render_menu)
    for panel in get_panels():
        if ENGINE_ID not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE_ID)
            _patched.append(panel)


def unregister():
    for panel in _patched:
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    _patched.clear()
    bpy.types.TOPBAR_MT_render.remove(draw_render_menu)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
