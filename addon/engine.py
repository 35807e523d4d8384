"""The RenderEngine: depsgraph -> export -> engine.render -> Blender render result."""
from __future__ import annotations

import importlib
import re
import time
import traceback

import bpy
import numpy as np

from . import export, motionvectors, viewport
from .aovs import aov_passes, view_layer_aovs
from .core import load_engine

ENGINE_ID = "PHOTONMAP"

# (Blender pass name, Film attribute, channels, chan_id, type)
EFFECT_PASSES = (
    ("Direct", "direct"),
    ("Indirect", "indirect"),
    ("Caustic", "caustic"),
    ("Specular", "specular"),
    ("Emission", "emission"),
)
PHOTON_PASS = ("Photon Hits", "photon_hits")
# Cycles' Shadow Catcher pass (View Layer > Passes > Light > Shadow Catcher): the shadow
# catchers' light with the objects over without them (engine/shadowcatcher.py). Asked
# for, it also leaves the shadow out of Combined, as in Cycles.
SHADOW_CATCHER_PASS = "Shadow Catcher"


def _shadow_catcher_pass(view_layer) -> bool:
    """The view layer asks for Cycles' Shadow Catcher pass (False without Cycles)."""
    return bool(getattr(getattr(view_layer, "cycles", None), "use_pass_shadow_catcher",
                        False))
# Adaptive sampling's per-pixel sample count (engine Film.sample_count), under Cycles'
# name for its pass; written as the share of Samples (Max Samples) a pixel took, 0..1.
SAMPLE_COUNT_PASS = "Debug Sample Count"
# Cycles' data passes the engine makes (engine/datapasses.py), under Cycles' pass names:
# (Blender pass name, Film.data key, channels, chan_id, type). Denoising Data (Cycles'
# view_layer.cycles.denoising_store_passes) feeds the compositor's Denoise node.
DENOISING_PASSES = (("Denoising Normal", "denoising_normal", 3, "XYZ", "VECTOR"),
                    ("Denoising Albedo", "denoising_albedo", 3, "RGB", "COLOR"),
                    ("Denoising Depth", "denoising_depth", 1, "Z", "VALUE"))
# (view layer switch, Blender pass name, Film.data key): Diffuse / Glossy / Transmission
# Color under the names Cycles' add-on registers them (Blender 5's; Blender 4 named them
# DiffCol, GlossCol, TransCol: _color_passes).
COLOR_PASSES = (("use_pass_diffuse_color", "Diffuse Color", "diffuse_color"),
                ("use_pass_glossy_color", "Glossy Color", "glossy_color"),
                ("use_pass_transmission_color", "Transmission Color", "transmission_color"))
_OLD_COLOR_NAMES = {"Diffuse Color": "DiffCol", "Glossy Color": "GlossCol",
                    "Transmission Color": "TransCol"}


# Cycles' surface data passes (engine/datapasses.py SURFACE): (view layer switch, Blender
# pass name, Film.data key = RenderSettings.data_passes kind, channels, chan_id, type),
# as Cycles' add-on registers them (Blender 5's names; Blender 4's index passes are
# IndexOB / IndexMA: _surface_passes).
SURFACE_PASSES = (("use_pass_mist", "Mist", "mist", 1, "Z", "VALUE"),
                  ("use_pass_position", "Position", "position", 3, "XYZ", "VECTOR"),
                  ("use_pass_uv", "UV", "uv", 3, "UVA", "VECTOR"),
                  ("use_pass_object_index", "Object Index", "object_index", 1, "X", "VALUE"),
                  ("use_pass_material_index", "Material Index", "material_index", 1, "X",
                   "VALUE"))
_OLD_SURFACE_NAMES = {"Object Index": "IndexOB", "Material Index": "IndexMA"}
# Cycles' Ambient Occlusion pass (engine/aopass.py; Blender 4 names it AO) and Vector pass
# (engine/vectorpass.py, made with motion blur off as Cycles): (view layer switch,
# Blender 5's pass name, RenderSettings.data_passes kind, channels, chan_id, type).
AO_PASS = ("use_pass_ambient_occlusion", "Ambient Occlusion", "ao", 3, "RGB", "COLOR")
VECTOR_PASS = ("use_pass_vector", "Vector", "vector", 4, "XYZW", "VECTOR")
VECTOR_WITH_BLUR = "Vector (made with Motion Blur off, as Cycles)"


def light_group_passes(view_layer) -> list[tuple[str, str]]:
    """(group name, pass name) of the view layer's Light Groups: Cycles' pass
    "Combined_<group>" each (engine/lightgroups.py)."""
    return [(g.name, f"Combined_{g.name}") for g in getattr(view_layer, "lightgroups", ())
            if g.name]


def _ao_vector_passes(view_layer=None):
    """AO_PASS and VECTOR_PASS (those view_layer asks for: both when None) with this
    Blender's pass names."""
    out = []
    for p in (AO_PASS, VECTOR_PASS):
        if view_layer is None or getattr(view_layer, p[0], False):
            name = p[1] if bpy.app.version >= (5, 0, 0) or p is VECTOR_PASS else "AO"
            out.append((p[0], name, *p[2:]))
    return out


def _surface_passes():
    """SURFACE_PASSES with this Blender's pass names."""
    if bpy.app.version >= (5, 0, 0):
        return SURFACE_PASSES
    return tuple((sw, _OLD_SURFACE_NAMES.get(name, name), *rest)
                 for sw, name, *rest in SURFACE_PASSES)


# Cycles' light passes (engine/lightpasses.py): (view layer switch, Blender 5's pass name,
# Film.data key), in Cycles' add-on's order; Blender 4 named them DiffDir, ... Emit, Env.
# Blender shows Direct / Indirect divided by their Color pass (lightpasses.shown).
LIGHT_PASSES = (("use_pass_diffuse_direct", "Diffuse Direct", "diffuse_direct"),
                ("use_pass_diffuse_indirect", "Diffuse Indirect", "diffuse_indirect"),
                ("use_pass_glossy_direct", "Glossy Direct", "glossy_direct"),
                ("use_pass_glossy_indirect", "Glossy Indirect", "glossy_indirect"),
                ("use_pass_transmission_direct", "Transmission Direct", "transmission_direct"),
                ("use_pass_transmission_indirect", "Transmission Indirect",
                 "transmission_indirect"),
                ("use_pass_emit", "Emission", "emission"),
                ("use_pass_environment", "Environment", "environment"))
_OLD_LIGHT_NAMES = {"Diffuse Direct": "DiffDir", "Diffuse Indirect": "DiffInd",
                    "Glossy Direct": "GlossDir", "Glossy Indirect": "GlossInd",
                    "Transmission Direct": "TransDir", "Transmission Indirect": "TransInd",
                    "Emission": "Emit", "Environment": "Env"}


# Cycles' Volume Direct / Indirect (view_layer.cycles' switches): made at Volume bounces 0
# (Cycles' default), where the media's light is single scattering of the lights at the
# camera segments (lightpasses.shown's volume_bounces); warned above it.
VOLUME_PASSES = (("use_pass_volume_direct", "Volume Direct", "volume_direct"),
                 ("use_pass_volume_indirect", "Volume Indirect", "volume_indirect"))
_OLD_LIGHT_NAMES.update({"Volume Direct": "VolumeDir", "Volume Indirect": "VolumeInd"})


def _volume_bounces(scene) -> int:
    return int(getattr(getattr(scene, "cycles", None), "volume_bounces", 0) or 0)


def _light_passes(view_layer=None, scene=None):
    """LIGHT_PASSES with this Blender's pass names (those view_layer asks for: all when
    None), and VOLUME_PASSES asked for when scene renders at Volume bounces 0."""
    new = bpy.app.version >= (5, 0, 0)
    out = [(sw, name if new else _OLD_LIGHT_NAMES[name], key)
           for sw, name, key in LIGHT_PASSES
           if view_layer is None or getattr(view_layer, sw, False)]
    cyc = getattr(view_layer, "cycles", None)
    if scene is not None and cyc is not None and _volume_bounces(scene) == 0:
        out += [(sw, name if new else _OLD_LIGHT_NAMES[name], key)
                for sw, name, key in VOLUME_PASSES if getattr(cyc, sw, False)]
    return tuple(out)


def _effect_passes(view_layer):
    """EFFECT_PASSES the view layer gets: in Blender 5 Cycles' Emission pass (use_pass_emit)
    takes the name "Emission", so our Emission effect pass gives way to it."""
    if bpy.app.version >= (5, 0, 0) and getattr(view_layer, "use_pass_emit", False):
        return tuple(p for p in EFFECT_PASSES if p[0] != "Emission")
    return EFFECT_PASSES


def _color_passes():
    """COLOR_PASSES with this Blender's pass names."""
    if bpy.app.version >= (5, 0, 0):
        return COLOR_PASSES
    return tuple((sw, _OLD_COLOR_NAMES[name], key) for sw, name, key in COLOR_PASSES)
# Passes a view layer may ask for that the engine does not make: (owner, switch, the name
# Blender shows). One warning names those asked for (left empty in the render result).
UNMADE_PASSES = (
    ("", "use_pass_shadow", "Shadow"),
    ("", "use_pass_subsurface_direct", "Subsurface Direct"),
    ("", "use_pass_subsurface_indirect", "Subsurface Indirect"),
    ("", "use_pass_subsurface_color", "Subsurface Color"),
    ("", "use_pass_grease_pencil", "Grease Pencil"),
    ("cycles", "use_pass_volume_direct", "Volume Direct (made at Volume bounces 0)"),
    ("cycles", "use_pass_volume_indirect", "Volume Indirect (made at Volume bounces 0)"),
    ("cycles", "pass_render_time", "Render Time"),
)


def _denoising_data(view_layer) -> bool:
    """The view layer asks for Denoising Data (Cycles' switch; False without Cycles)."""
    return bool(getattr(getattr(view_layer, "cycles", None), "denoising_store_passes", False))


# Cryptomatte layers by the view layer's switch: (switch, engine kind, pass prefix).
CRYPTOMATTE_LAYERS = (("use_pass_cryptomatte_object", "object", "CryptoObject"),
                      ("use_pass_cryptomatte_material", "material", "CryptoMaterial"),
                      ("use_pass_cryptomatte_asset", "asset", "CryptoAsset"))


def cryptomatte_passes(view_layer) -> list[tuple[str, str]]:
    """(engine kind, pass name) of every Cryptomatte pass the view layer asks for:
    ceil(Levels / 2) RGBA passes a layer, "CryptoObject00", "CryptoObject01", ..."""
    count = _engine_module("cryptomatte").pass_count(cryptomatte_levels(view_layer))
    return [(kind, f"{prefix}{i:02d}") for switch, kind, prefix in CRYPTOMATTE_LAYERS
            if getattr(view_layer, switch, False) for i in range(count)]


def _engine_module(name):
    """The engine's module `name` (no bpy, loaded with the engine)."""
    import importlib
    return importlib.import_module(load_engine().__name__ + "." + name)


def cryptomatte_levels(view_layer) -> int:
    return int(getattr(view_layer, "pass_cryptomatte_depth", 6) or 6)


def data_passes(view_layer) -> tuple:
    """RenderSettings.data_passes for the passes view_layer asks for."""
    out = []
    if _denoising_data(view_layer):
        out.append("denoising")
    if any(getattr(view_layer, switch, False) for switch, _, _ in COLOR_PASSES):
        out.append("color")
    cyc = getattr(view_layer, "cycles", None)
    if (any(getattr(view_layer, switch, False) for switch, _, _ in LIGHT_PASSES)
            or any(getattr(cyc, switch, False) for switch, _, _ in VOLUME_PASSES)):
        out.append("light")  # (brings "color": Blender divides by it)
    out += [key for switch, _, key, *_ in SURFACE_PASSES if getattr(view_layer, switch, False)]
    if getattr(view_layer, AO_PASS[0], False):
        out.append("ao")
    render = getattr(getattr(view_layer, "id_data", None), "render", None)
    if getattr(view_layer, VECTOR_PASS[0], False) and not getattr(render, "use_motion_blur",
                                                                    False):
        out.append("vector")  # (Cycles makes it with motion blur off only)
    return tuple(out)


def ao_distance(scene) -> float:
    """The Ambient Occlusion pass' distance: World > Settings > Ambient Occlusion >
    Distance (world.light_settings.distance), Cycles' 10 m without a world."""
    world = getattr(scene, "world", None)
    ls = getattr(world, "light_settings", None)
    d = getattr(ls, "distance", None)
    return max(float(d), 0.0) if d is not None else 10.0


def unmade_passes_warning(view_layer, adaptive: bool = False, volume_bounces: int = 0,
                          motion_blur: bool = False):
    """One warning naming the passes view_layer asks for that the engine does not make
    (they stay empty), or None. volume_bounces: the scene's Light Paths > Volume bounces
    (the volume passes are made at 0); motion_blur: Render > Motion Blur is on (the
    Vector pass is made without it, as Cycles)."""
    names = []
    if motion_blur and getattr(view_layer, VECTOR_PASS[0], False):
        names.append(VECTOR_WITH_BLUR)
    for owner, switch, label in UNMADE_PASSES:
        if volume_bounces == 0 and switch in {sw for sw, _, _ in VOLUME_PASSES}:
            continue
        holder = getattr(view_layer, owner, None) if owner else view_layer
        if holder is not None and bool(getattr(holder, switch, False)):
            names.append(label)
    cyc = getattr(view_layer, "cycles", None)
    if not adaptive and bool(getattr(cyc, "pass_debug_sample_count", False)):
        names.append("Debug Sample Count (made with adaptive sampling only)")
    if not names:
        return None
    return (f"view layer '{view_layer.name}' asks for passes Photon Mapping does not make "
            f"(left empty): {', '.join(names)}")


def _aov_buffers(data, view_layer, h, w) -> dict:
    """{pass name: (h, w, channels)} of the view layer's Shader AOVs from the film's
    data (engine/datapasses.py keys): a colour AOV as RGBA (its alpha the writes' share,
    Cycles' float4), a value AOV as one channel; zeros where the film has none."""
    dp = _engine_module("datapasses")
    out = {}
    for name, kind in view_layer_aovs(view_layer):
        if kind == "color":
            rgb = data.get(dp.AOV_COLOR + name, np.zeros((h, w, 3), np.float32))
            alpha = data.get(dp.AOV_ALPHA + name, np.zeros((h, w), np.float32))
            out[name] = np.concatenate([rgb, alpha[:, :, None]], axis=2)
        else:
            out[name] = data.get(dp.AOV_VALUE + name, np.zeros((h, w), np.float32))[:, :, None]
    return out


def _adaptive(scene) -> bool:
    """The render will sample adaptively (Noise Threshold on, not progressive)."""
    pm = getattr(scene, "photonmap", None)
    return bool(pm is not None and getattr(pm, "use_adaptive_sampling", False)
                and not getattr(pm, "progressive", False))
MAX_REPORTED_WARNINGS = 20
BACKGROUND_DEPTH = 1e10  # what Cycles writes for "nothing hit"

# Test hook: a callable polled together with RenderEngine.test_break() (Esc). Headless
# Blender cannot press Esc, so tests set this to simulate it. None in normal use.
test_break_hook = None
# Summary of the most recent render in this process (size, region, stats, warnings, and
# 'error' when it failed): for tests and scripts; the image is in Blender's render result.
last_render: dict = {}
# Callables listener(event, value) told what Blender's stats line and progress bar show,
# for scripts that run through the bpy module, which prints neither (addon/batch.py draws
# its progress bar from them). Events: ("stats", text), ("progress", fraction 0..1 of the
# whole render), ("stage", the engine's stage name: "photons", "photon_map", "render",
# told before its first progress, not by progressive renders: a pass is every stage),
# ("effects", [lines]), ("warning", text), ("film", the engine's Film of
# a finished render), ("warnings_repeated", how many of the previous frame's warnings this
# frame had: not told again), ("finished", "done" | "cancelled" | "error: <message>"). Called
# on Blender's main thread; a listener that raises is dropped from this render with a
# printed traceback, never stops the render.
status_listeners: list = []
# A background render without a listener prints a progress line each time the bar
# passes another tenth (RenderEngine._progress).
PROGRESS_LINE_STEP = 0.1
# The effect report last printed to the console: an animation's frames (Ctrl+F12) simulate
# the same effects, printed once, not once a frame.
_printed_effects: list = []
# The warnings of the last render (scene name, frame, warning keys): the next frame of an
# animation (Ctrl+F12, the batch's --frames: the frame after the last one rendered, by the
# scene's Frame Step) reports only what is new, and the count of
# the rest in one line, not the same warnings once a frame. A render of the same frame
# again (a user fixing what was warned) reports them all.
_previous_frame_warnings: dict = {}
_NUMBER = re.compile(r"\d[\d,.]*")


def effect_lines_to_print(effects: list, previous: list) -> list:
    """The console lines for this render's effect report (each without the "Photon
    Mapping: " prefix), given the report printed before it. A line whose words are the
    previous report's is not printed again when only its numbers changed: an animation
    where anything moves stores a few more or fewer photons each frame ("358,719 global
    photons stored, search radius 0.1222 m"), which reprinted the whole report every
    frame (s26 new-user trial). Then "effects as the previous render" stands for the
    unchanged lines ("..., except:" and the lines whose words changed: an effect switched
    on or off, another caster); the whole report when there is no previous one, it had
    another number of lines, or every line changed. The Effects of Last Render panel and last_render keep every frame's numbers."""
    if not effects:
        return []
    def words(lines):
        return [_NUMBER.sub("#", x) for x in lines]
    now, before = words(effects), words(previous)
    if len(now) != len(before):
        return list(effects)
    changed = [line for line, w, b in zip(effects, now, before) if w != b]
    if len(changed) == len(effects):
        return list(effects)
    if not changed:
        return ["effects as the previous render"]
    return ["effects as the previous render, except:"] + changed


def kernel_words(compiled: bool) -> str:
    """What the kernels' seconds were: a first render compiles them (once per machine),
    later processes load them from the cache (the stats line, the batch's last line)."""
    return "compiling the kernels" if compiled else "loading the compiled kernels"


MOTION_BLUR_PROGRESSIVE = ("motion blur is not rendered with progressive or distributed "
                           "rendering (each pass is one moment); turn Progressive off to "
                           "render it")


def motion_blur_warnings(scene, depsgraph) -> list:
    """What of Blender's motion blur settings the time steps do not follow, named:
    Cycles' Rolling Shutter, a shaped Shutter Curve."""
    out = []
    cycles = getattr(scene, "cycles", None)
    if cycles is not None and getattr(cycles, "rolling_shutter_type", "NONE") != "NONE":
        out.append("motion blur: Rolling Shutter is not simulated (a global shutter)")
    curve = getattr(scene.render, "motion_blur_shutter_curve", None)
    try:
        points = [tuple(p.location) for p in curve.curves[0].points]
    except (AttributeError, IndexError, TypeError):
        points = []
    if any(abs(y - 1.0) > 1e-6 for _, y in points):
        out.append("motion blur: the Shutter Curve is not followed (the shutter is open "
                   "fully for its whole time)")
    return out


def motion_blur_off(scene) -> set:
    """Names of the objects whose Object > Motion Blur is off (Cycles' per-object
    use_motion_blur): rendered at the frame's time in every step."""
    return {o.name for o in scene.objects
            if not getattr(getattr(o, "cycles", None), "use_motion_blur", True)}


def hold_still(moved, still, names: set, camera_name: str | None):
    """moved (the scene exported at a step's time) with the meshes, lights and camera of
    the objects in `names` taken from still (the scene at the frame's time): Cycles
    renders an object whose motion blur is off at the frame. Meshes are matched by their
    object (Mesh.cryptomatte_object, else its name: instances of it included), lights by name."""
    if not names:
        return moved
    def held(m):
        return (m.cryptomatte_object or m.name) in names

    moved.meshes = [m for m in moved.meshes if not held(m)] + [m for m in still.meshes
                                                              if held(m)]
    moved.lights = ([li for li in moved.lights if li.name not in names]
                    + [li for li in still.lights if li.name in names])
    if camera_name in names:
        moved.camera = still.camera
    return moved


# The bar's share of the export (before the render's settings are known); the render's
# stages share the rest in proportion to their work (engine/stagespans.py).
EXPORT_SHARE = 0.02
# The first render on a machine compiles the kernels (minutes): the progress bar's first
# COMPILE_SHARE follows the compile (kernels done / all), the render's own work the rest;
# a render with the kernels cached uses the whole bar. (The bar stood at 0 % through the
# whole compile: newuser39.)
COMPILE_SHARE = 0.5


class PhotonMapRenderEngine(bpy.types.RenderEngine):
    bl_idname = ENGINE_ID
    bl_label = "Photon Mapping"
    bl_use_preview = False          # material previews would cost a full photon pass
    bl_use_postprocess = True
    bl_use_eevee_viewport = True    # Material Preview shading uses EEVEE
    bl_use_shading_nodes_custom = False  # standard shader nodes in the node editor

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._last_stats = 0.0
        self._last_stage = None  # a new stage's first text is always shown (not throttled)
        self._progress_stage = None  # the stage of the last progress told the listeners
        self._bar_start = 0.0  # where the render's own work starts on the bar (compile)
        self._listeners = []
        self._viewport = None  # rendered viewport (addon/viewport.py)
        self._text = ""  # the stats line's last text (the background progress lines)
        self._next_line = PROGRESS_LINE_STEP

    def __del__(self):
        # Blender frees the engine when the view leaves Rendered shading (and on quit):
        # stop the viewport session's thread. When Blender has already removed the
        # engine's data, its attributes raise ReferenceError: the session was stopped
        # by free() or is stopped by viewport.stop_all at unregister / exit.
        try:
            self.free()
        except ReferenceError:
            return
        parent = getattr(super(), "__del__", None)
        if parent is not None:
            parent()

    # --- rendered viewport: a thin layer over addon/viewport.py -------------------------
    def view_update(self, context, depsgraph):
        try:
            if self._viewport is None:
                self._viewport = viewport.ViewportRender()
            self._viewport.update(context, depsgraph)
        except Exception as exc:  # noqa: BLE001 - a message in the header, never a dialog
            if not _expected(exc):
                traceback.print_exc()
            self.update_stats("", _user_message(exc))

    def view_draw(self, context, depsgraph):
        if self._viewport is not None:
            self._viewport.draw(self, context, depsgraph)

    def free(self):
        """Stop the viewport session, if any (returns when its thread has ended)."""
        vp = getattr(self, "_viewport", None)
        if vp is not None:
            vp.stop()

    # --- status: Blender's stats line / progress bar, and the script listeners ---------
    def _emit(self, event, value):
        for listener in list(self._listeners):
            try:
                listener(event, value)
            except Exception:  # noqa: BLE001 - a broken listener must not stop the render
                traceback.print_exc()
                self._listeners.remove(listener)

    def _stats(self, text):
        self.update_stats("", text)
        self._text = text
        self._emit("stats", text)

    def _throttled_stats(self, stage, fraction, text):
        """The stats line at most every 0.1 s, except a stage's first text and its end: a
        stage that starts right after another finished ("Building photon map" after the
        last photons) would otherwise show the finished one's text while it runs."""
        now = time.perf_counter()
        if stage != self._last_stage or fraction >= 1.0 or now - self._last_stats > 0.1:
            self._last_stage = stage
            self._last_stats = now
            self._stats(text)

    def _progress(self, fraction, stage=None, raw=False):
        """The bar at the render's fraction of its own work (raw: at fraction of the whole
        bar, the compile's share); the listeners hear the bar's position."""
        if not raw:
            fraction = self._bar_start + (1.0 - self._bar_start) * fraction
        self.update_progress(fraction)
        if (not self._listeners and bpy.app.background and fraction >= self._next_line
                and fraction < 1.0):
            # A script's bpy.ops.render.render() in the background shows no bar, and
            # Blender 5 no longer prints the stats line: a line every tenth of the bar
            # (the batch command's listener draws its own bar instead).
            step = PROGRESS_LINE_STEP
            self._next_line = (int(fraction / step) + 1) * step
            print(f"Photon Mapping: {int(100 * fraction)}% {self._text}", flush=True)
        if stage is not None and stage != self._progress_stage:
            self._progress_stage = stage
            self._emit("stage", stage)  # before its first progress (the batch's Eta)
        self._emit("progress", fraction)

    # --- passes ---------------------------------------------------------------------
    def update_render_passes(self, scene=None, renderlayer=None):
        if scene is None or renderlayer is None:
            return
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        settings = getattr(renderlayer, "photonmap", None)
        effects = settings is None or settings.use_pass_effects
        hits = settings is None or settings.use_pass_photon_hits
        if effects:
            for name, _ in _effect_passes(renderlayer):
                self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")
        if hits:
            self.register_pass(scene, renderlayer, PHOTON_PASS[0], 3, "RGB", "COLOR")
        if renderlayer.use_pass_z:
            self.register_pass(scene, renderlayer, "Depth", 1, "Z", "VALUE")
        if renderlayer.use_pass_normal:
            self.register_pass(scene, renderlayer, "Normal", 3, "XYZ", "VECTOR")
        if _denoising_data(renderlayer):
            for name, _, channels, chan_id, kind in DENOISING_PASSES:
                self.register_pass(scene, renderlayer, name, channels, chan_id, kind)
        for switch, name, _ in _color_passes():
            if getattr(renderlayer, switch, False):
                self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")
        for _, name, _ in _light_passes(renderlayer, scene):
            self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")
        for switch, name, _, channels, chan_id, kind in _surface_passes():
            if getattr(renderlayer, switch, False):
                self.register_pass(scene, renderlayer, name, channels, chan_id, kind)
        for _, name, _, channels, chan_id, kind in _ao_vector_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)
        for _, name in light_group_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")
        if _shadow_catcher_pass(renderlayer):
            self.register_pass(scene, renderlayer, SHADOW_CATCHER_PASS, 3, "RGB", "COLOR")
        if _adaptive(scene):
            self.register_pass(scene, renderlayer, SAMPLE_COUNT_PASS, 1, "X", "VALUE")
        for _kind, name in cryptomatte_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, 4, "rgba", "COLOR")
        for name, channels, chan_id, kind in aov_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    # --- render ---------------------------------------------------------------------
    def render(self, depsgraph):
        self._listeners = list(status_listeners)
        self._next_line = PROGRESS_LINE_STEP
        last_render.clear()
        try:
            self._render(depsgraph)
        except KeyboardInterrupt:
            # Ctrl-C in a script or terminal: a cancel, not a crash; the caller decides
            # what to keep (addon/batch.py keeps the old file).
            msg = "Photon Mapping: render interrupted"
            last_render.update(cancelled=True, error="interrupted")
            self._fail(msg, "cancelled")
        except Exception as exc:  # noqa: BLE001 - never a traceback dialog
            if not _expected(exc):
                traceback.print_exc()
            msg = _user_message(exc)
            last_render.update(error=msg)
            self._fail(msg, f"error: {msg}")
        finally:
            self._listeners = []

    def _report_warnings(self, warnings, already=0):
        """Emit each warning to the listeners and report the first MAX_REPORTED_WARNINGS of
        a render in Blender's UI (already: how many this render reported before); the
        rest go to the system console."""
        for w in warnings:
            self._emit("warning", w)
        room = max(MAX_REPORTED_WARNINGS - already, 0)
        for w in warnings[:room]:
            self.report({"WARNING"}, f"Photon Mapping: {w}")
        if len(warnings) > room:
            self.report({"WARNING"}, f"Photon Mapping: {len(warnings) - room}"
                        " more warnings (see the system console)")
            for w in warnings[room:]:
                print(f"Photon Mapping warning: {w}")

    def _fail(self, msg, status):
        self.report({"ERROR"}, msg)
        try:
            self.error_set(msg)
        except Exception:  # noqa: BLE001 - older Blender
            pass
        self._emit("finished", status)

    def _should_cancel(self) -> bool:
        if self.test_break():
            return True
        hook = test_break_hook
        return bool(hook is not None and hook())

    def _render(self, depsgraph):
        scene = depsgraph.scene
        props = scene.photonmap
        render = scene.render
        view_layer = depsgraph.view_layer
        self._stats("Loading engine")
        pm = load_engine()
        compiling = pm.jit.needs_compile()
        if compiling:  # ~20 s, once per machine: say why the render waits
            self._stats(pm.jit.COMPILE_MESSAGE)  # stats line and the batch command's bar
            if not self._listeners:  # the batch's bar shows it; a print would split the bar
                print(f"Photon Mapping: {pm.jit.COMPILE_MESSAGE}", flush=True)
        self._bar_start = 0.0

        def compile_progress(stage, fraction, text):
            self._stats(text)
            self._progress(COMPILE_SHARE * fraction, stage, raw=True)
        compile_seconds = pm.jit.ensure_compiled(compile_progress)
        self._bar_start = COMPILE_SHARE if compiling else 0.0

        width, height = export.render_size(render)
        region = export.border_region(render, width, height)

        def export_progress(done, total):
            self._stats(f"Exporting {done}/{total} objects")
            self._progress(EXPORT_SHARE * done / max(total, 1))

        try:
            pm_scene, info = export.export_scene(
                pm, depsgraph, camera=self.camera_override, width=width, height=height,
                progress=export_progress, should_cancel=self._should_cancel)
        except export.ExportCancelled:
            last_render.clear()
            last_render.update(cancelled=True, stats={"cancelled": True}, warnings=[])
            self.report({"INFO"}, "Photon Mapping: render cancelled during export")
            self._emit("finished", "cancelled")
            return

        kwargs = props.to_settings_kwargs(render.film_transparent)
        if props.use_animated_seed:
            kwargs["seed"] = frame_seed(props.seed, scene.frame_current)
        kwargs["data_passes"] = data_passes(view_layer)
        kwargs["ao_distance"] = ao_distance(scene)
        kwargs["light_groups"] = tuple(g for g, _ in light_group_passes(view_layer))
        kwargs["shader_aovs"] = view_layer_aovs(view_layer)
        kwargs["cryptomatte"] = tuple(k for switch, k, _ in CRYPTOMATTE_LAYERS
                                      if getattr(view_layer, switch, False))
        kwargs["cryptomatte_levels"] = min(max(cryptomatte_levels(view_layer), 1), 16)
        kwargs["pass_alpha_threshold"] = float(getattr(view_layer, "pass_alpha_threshold",
                                                       0.5))
        settings = pm.RenderSettings(**kwargs)
        unmade = unmade_passes_warning(view_layer, _adaptive(scene), _volume_bounces(scene),
                                       bool(render.use_motion_blur))
        if unmade is not None:  # said with the export's warnings, kept in film.warnings
            pm_scene.warnings.append(unmade)
        if "vector" in settings.data_passes:  # the scene a frame before and after
            self._stats("Vector pass: exporting the frames before and after")
            pm_scene.vector_motion, moved = motionvectors.scene_motion(
                self, pm, depsgraph, pm_scene, width, height)
            pm_scene.warnings.extend(moved)
        # Refuse what cannot fit before anything big is allocated (Blender's render result
        # included); raises ResourceError with the setting and the estimate.
        pm.resources.check_resources(pm_scene, settings, region, progressive=props.progressive,
                                     in_blender=True)

        # Compared by the engine's warning_key: a cluster's passes may tell a search
        # radius' warning in other words (another pass' photon count) than film.warnings.
        import importlib
        warning_key = importlib.import_module(pm.__name__ + ".render").warning_key
        previous = _previous_frame_warnings
        next_frame = (previous.get("scene") == scene.name and previous.get("frame") is not None
                      and previous["frame"] + scene.frame_step == scene.frame_current)
        repeats = set(previous.get("keys", ())) if next_frame else set()
        repeated_keys = set()  # this render's warnings the previous frame reported

        def new(warnings):
            """warnings less those the previous frame reported (counted apart)."""
            out = []
            for w in warnings:
                k = warning_key(w)
                if k in repeats:
                    repeated_keys.add(k)
                else:
                    out.append(w)
            return out

        # What the export could not convert is known now: say it before the long render
        # rather than after it (the end reports only what the engine adds).
        early = list(pm_scene.all_warnings())
        self._report_warnings(new(early))
        reported = list(early)
        reported_keys = {warning_key(w) for w in early}

        def on_warning(text):
            # What the render finds before its long passes (the effect analysis': a Max
            # Ray Depth that cuts a mirror's chain; a hand-set search radius once the
            # photon maps are built, before the camera pass; on a Dask cluster each as a
            # worker finds it), said then, not at the end; past the
            # reports' room, at the end with the others (one "N more warnings" report).
            if warning_key(text) not in reported_keys and len(reported) < MAX_REPORTED_WARNINGS:
                if new([text]):
                    self._report_warnings([text], already=len(reported))
                reported.append(text)
                reported_keys.add(warning_key(text))

        rows = (region[3] - region[1]) if region is not None else height
        cols = (region[2] - region[0]) if region is not None else width
        # Sized from the settings' photon counts, re-sized by the render's plan (a glow
        # shot can be several times the global one) before any photon is traced.
        spans = pm.stagespans.StageSpans(settings.uses_photon_maps,
                                         settings.photons + settings.caustic_photons,
                                         max(rows, 1) * max(cols, 1) * settings.spp,
                                         start=EXPORT_SHARE)

        def progress(stage, fraction, text):
            whole = spans.whole(stage, fraction)
            if whole is not None:  # the kernel compile is outside the render's work
                self._progress(whole, stage)
            self._throttled_stats(stage, fraction, text)

        t0 = time.perf_counter()
        if props.progressive or props.dask_scheduler.strip():  # a cluster renders passes
            if render.use_motion_blur:
                on_warning(MOTION_BLUR_PROGRESSIVE)
                pm_scene.warnings.append(MOTION_BLUR_PROGRESSIVE)
            film = self._render_progressive(pm, pm_scene, settings, props, progress, region,
                                            view_layer, render.film_transparent, on_warning)
        elif render.use_motion_blur:
            film = self._render_motion_blur(pm, depsgraph, pm_scene, settings, props,
                                            region, width, height, on_warning)
        else:
            film = pm.render(pm_scene, settings, progress=progress,
                             should_cancel=self._should_cancel, region=region,
                             on_warning=on_warning, on_plan=spans.plan)
        elapsed = time.perf_counter() - t0
        self._write_result(film, view_layer, render.film_transparent)
        cancelled = bool(film.stats.get("cancelled"))
        # The kernels were loaded (or compiled) above, before the export: the engine's
        # own time_compile then reads ~0, so the stats carry the add-on's number (one
        # name, the real time; `time` is the render after it).
        stats = dict(film.stats)
        stats["time_compile"] = compile_seconds + float(stats.get("time_compile") or 0.0)
        # Loading cached kernels takes ~1 s too: "compiling" only when they were compiled.
        stats["kernels_compiled"] = bool(compiling)
        last_render.clear()
        last_render.update(width=film.width, height=film.height, full_size=(width, height),
                           region=region, stats=stats, warnings=list(film.warnings),
                           export=dict(info), cancelled=cancelled, time=elapsed)
        if not cancelled:  # a cancelled render's bar stays where it stopped
            self._progress(1.0)
        self._emit("film", film)  # the engine's Film, for scripts (batch --save-passes)
        effects = list(film.stats.get("effects", []) or [])
        self._emit("effects", effects)
        if not self._listeners:  # a listener prints them itself
            global _printed_effects
            # Why each effect is on or off; an animation's next frame: what changed.
            for line in effect_lines_to_print(effects, _printed_effects):
                print(f"Photon Mapping: {line}")
            _printed_effects = effects
        self._report_warnings(new([w for w in film.warnings
                                   if warning_key(w) not in reported_keys]),
                              already=len(reported))
        if repeated_keys:
            n = len(repeated_keys)
            self.report({"INFO"}, f"Photon Mapping: {n} warning{'s' if n != 1 else ''} as "
                        f"the previous frame (frame {previous['frame']}), not repeated")
            self._emit("warnings_repeated", n)
        _previous_frame_warnings.clear()
        _previous_frame_warnings.update(
            scene=scene.name, frame=scene.frame_current,
            keys={warning_key(w) for w in [*early, *film.warnings]})
        # What lights the scene as the render found it (engine.lights.light_census: the
        # lamps, the World, the emissive meshes' triangles); the export's count of lamps
        # where a render gives none (a cancel before the lights were prepared).
        n = info['lights']
        lit = (f"lights: {stats['light_census']}" if stats.get("light_census")
               else f"{n} light{'' if n == 1 else 's'}")
        compiled = stats["time_compile"]
        adaptive = (f"adaptive: {stats['adaptive_mean_spp']:.1f} of {stats['adaptive_spp']} "
                    "samples a pixel, " if "adaptive_mean_spp" in stats else "")
        summary = (f"{info['triangles']} triangles, {lit}, "
                   + adaptive +
                   f"{elapsed:.1f} s" + (f" (+ {compiled:.1f} s "
                                         f"{kernel_words(compiling)})"
                                         if compiled >= 0.5 else ""))
        if cancelled:
            self.report({"INFO"}, f"Photon Mapping: render cancelled ({summary})")
            self._stats("Cancelled")
        else:
            self._stats(f"Done: {summary}")
        self._emit("finished", "cancelled" if cancelled else "done")

    def _render_motion_blur(self, pm, depsgraph, pm_scene, settings, props, region, width,
                            height, on_warning):
        """Render > Motion Blur: the scene exported at the middle of each of Motion Blur >
        Steps slices of the shutter (RenderEngine.frame_set, as Cycles evaluates its
        motion steps), each rendered whole and averaged (engine/motionblur.py). pm_scene,
        exported at the frame, gives the objects whose own Motion Blur is off
        (hold_still). The frame is restored."""
        scene = depsgraph.scene
        render = scene.render
        mb = pm.motionblur
        frame, subframe = scene.frame_current, scene.frame_subframe
        shutter, position = float(render.motion_blur_shutter), str(render.motion_blur_position)
        extra = motion_blur_warnings(scene, depsgraph)
        for w in extra:
            on_warning(w)
        step = {"i": 0, "n": 1, "spans": None}
        still_names = motion_blur_off(scene)
        cam = self.camera_override or scene.camera
        camera_name = cam.name if cam is not None else None

        cancelled_error = importlib.import_module(pm.__name__ + ".parallel").Cancelled

        def scene_at(t):
            f, sub = mb.frame_and_subframe(t)
            self.frame_set(f, subframe=sub)
            try:
                out, _ = export.export_scene(pm, depsgraph, camera=self.camera_override,
                                             width=width, height=height,
                                             should_cancel=self._should_cancel)
            except export.ExportCancelled as exc:  # the engine keeps the steps done
                raise cancelled_error(str(exc)) from exc
            out.warnings.extend(extra)
            return hold_still(out, pm_scene, still_names, camera_name)

        def on_step(i, n):
            step.update(i=i, n=n, spans=pm.stagespans.StageSpans(
                settings.uses_photon_maps, settings.photons + settings.caustic_photons,
                max(width * height, 1) * mb.step_settings(settings, i, n).spp))

        def progress(stage, fraction, text):
            spans = step["spans"]
            whole = spans.whole(stage, fraction) if spans is not None else None
            if whole is not None:  # (one stage for the time-left estimate: every step
                # repeats the photon and camera stages, so the rate is the steps' own)
                self._progress(EXPORT_SHARE + (1.0 - EXPORT_SHARE)
                               * (step["i"] + whole) / step["n"], "render")
            self._throttled_stats(stage, fraction, text)

        def plan(work):
            if step["spans"] is not None:
                step["spans"].plan(work)

        try:
            steps, why = int(props.motion_blur_steps), ""
            if steps <= 0:  # Auto: from the vertices' motion in the image
                self._stats("Motion blur: measuring the motion")
                steps, path = mb.auto_steps(scene_at, *mb.shutter_span(
                    frame + subframe, shutter, position))
                why = (f"Steps Auto: the fastest vertex moves {path:.0f} pixels while the "
                       "shutter is open")
            times = mb.shutter_times(frame + subframe, shutter, position, steps)
            return mb.render_motion_blur(scene_at, times, settings, progress=progress,
                                         should_cancel=self._should_cancel, region=region,
                                         on_warning=on_warning, on_plan=plan,
                                         on_step=on_step, why=why)
        except cancelled_error:  # before the first step: an empty film, marked cancelled
            x0, y0, x1, y1 = region if region is not None else (0, 0, width, height)
            film = pm.Film(x1 - x0, y1 - y0)
            film.stats.update(cancelled=True, motion_blur_steps=0)
            film.warnings = list(pm_scene.all_warnings())
            return film
        finally:
            self.frame_set(frame, subframe=subframe)

    def _render_progressive(self, pm, pm_scene, settings, props, progress, region, view_layer,
                            transparent, on_warning=None):
        """Passes until the budget is spent; the image is updated after every pass and the
        stats line shows pass, photons so far, elapsed time and the error estimate."""
        budget = pm.Budget(passes=props.max_passes or None, seconds=props.time_limit or None,
                           target_error=props.target_error or None)

        def pass_progress(stage, fraction, text):
            self._throttled_stats(stage, fraction, text)

        def on_pass(film, info):
            self._write_result(film, view_layer, transparent)
            err = info["error_estimate"]
            # Short enough for the batch bar's 46 columns ("error: after pass 2" was cut).
            err_text = f"error ~{err:.4f}" if err == err else "error from pass 2"
            self._stats(f"Pass {info['passes']}: {info['photons'] / 1e6:.2f} M photons, "
                        f"{info['elapsed']:.0f} s, {err_text}")
            done = []
            if budget.passes:
                done.append(info["passes"] / budget.passes)
            if budget.seconds:
                done.append(info["elapsed"] / budget.seconds)
            if budget.target_error and err == err:
                done.append(min(1.0, budget.target_error / max(err, 1e-12)))
            if not done:
                done.append(info["passes"] / pm.progressive.DEFAULT_MAX_PASSES)
            self._progress(min(1.0, max(done)))

        address = props.dask_scheduler.strip()
        if address:  # same passes on a Dask cluster (engine/distributed.py, imported lazily)
            import importlib
            dist = importlib.import_module(pm.__name__ + ".distributed")
            return dist.render_distributed(pm_scene, settings, budget, address=address,
                                           progress=pass_progress,
                                           should_cancel=self._should_cancel,
                                           on_pass=on_pass, region=region,
                                           on_warning=on_warning)
        return pm.render_progressive(pm_scene, settings, budget, progress=pass_progress,
                                     should_cancel=self._should_cancel, on_pass=on_pass,
                                     region=region, on_warning=on_warning)

    def _add_passes(self, view_layer, sample_count=False):
        """Allocate our passes in the render result (update_render_passes only tells the
        compositor which sockets exist)."""
        layer = view_layer.name
        settings = getattr(view_layer, "photonmap", None)
        if settings is None or settings.use_pass_effects:
            for name, _ in _effect_passes(view_layer):
                self.add_pass(name, 3, "RGB", layer=layer)
        if settings is None or settings.use_pass_photon_hits:
            self.add_pass(PHOTON_PASS[0], 3, "RGB", layer=layer)
        if view_layer.use_pass_z:
            self.add_pass("Depth", 1, "Z", layer=layer)
        if view_layer.use_pass_normal:
            self.add_pass("Normal", 3, "XYZ", layer=layer)
        if _denoising_data(view_layer):
            for name, _, channels, chan_id, _ in DENOISING_PASSES:
                self.add_pass(name, channels, chan_id, layer=layer)
        for switch, name, _ in _color_passes():
            if getattr(view_layer, switch, False):
                self.add_pass(name, 3, "RGB", layer=layer)
        for _, name, _ in _light_passes(view_layer, view_layer.id_data):
            self.add_pass(name, 3, "RGB", layer=layer)
        for switch, name, _, channels, chan_id, _ in _surface_passes():
            if getattr(view_layer, switch, False):
                self.add_pass(name, channels, chan_id, layer=layer)
        for _, name, _, channels, chan_id, _ in _ao_vector_passes(view_layer):
            self.add_pass(name, channels, chan_id, layer=layer)
        for _, name in light_group_passes(view_layer):
            self.add_pass(name, 3, "RGB", layer=layer)
        if _shadow_catcher_pass(view_layer):
            self.add_pass(SHADOW_CATCHER_PASS, 3, "RGB", layer=layer)
        if sample_count:
            self.add_pass(SAMPLE_COUNT_PASS, 1, "X", layer=layer)
        for _kind, name in cryptomatte_passes(view_layer):
            self.add_pass(name, 4, "rgba", layer=layer)  # lowercase: the Cryptomatte spec
        for name, channels, chan_id, _ in aov_passes(view_layer):
            self.add_pass(name, channels, chan_id, layer=layer)

    def _write_result(self, film, view_layer, transparent: bool):
        h, w = film.height, film.width
        self._add_passes(view_layer, film.sample_count is not None)
        result = self.begin_result(0, 0, w, h, layer=view_layer.name)
        try:
            layer = result.layers[0]
            rgb = film.combined
            # Holdout surfaces make alpha 0 with or without a transparent film (Cycles).
            alpha = film.alpha if transparent else 1.0 - film.holdout
            rgba = np.concatenate([rgb, alpha[:, :, None]], axis=2)
            catcher = _engine_module("shadowcatcher")
            with_pass = _shadow_catcher_pass(view_layer)
            if not film.show_photons:
                # Shadow catchers: Combined as Cycles makes it (the shadow as alpha or over
                # the world; without it when the Shadow Catcher pass carries it); None
                # without catchers.
                caught = catcher.combined_rgba(film, transparent, approximate=not with_pass)
                rgba = rgba if caught is None else caught
            buffers = {"Combined": rgba}
            if with_pass:
                buffers[SHADOW_CATCHER_PASS] = catcher.shadow_catcher_pass(film, transparent)
            for name, attr in _effect_passes(view_layer) + (PHOTON_PASS,):
                buffers[name] = getattr(film, attr)
            depth = np.where(np.isfinite(film.depth), film.depth, BACKGROUND_DEPTH)
            buffers["Depth"] = depth[:, :, None]
            buffers["Normal"] = film.normal
            data = getattr(film, "data", None) or {}
            for name, key in ([(p[0], p[1]) for p in DENOISING_PASSES]
                              + [(p[1], p[2]) for p in _color_passes()]
                              + [(p[1], p[2]) for p in _surface_passes()]):
                if key in data:
                    buffers[name] = data[key] if data[key].ndim == 3 else data[key][:, :, None]
            for _, name, key, *_ in _ao_vector_passes(view_layer):
                made = (_engine_module("vectorpass").shown(data) if key == "vector"
                        else data.get(key))
                if made is not None:
                    buffers[name] = made
            groups = _engine_module("lightgroups")
            for group, name in light_group_passes(view_layer):
                if groups.key(group) in data:
                    buffers[name] = data[groups.key(group)]
            # The light passes as Blender shows them (Direct / Indirect / Color).
            scene = view_layer.id_data
            shown = _engine_module("lightpasses").shown(data, _volume_bounces(scene))
            for _, name, key in _light_passes(view_layer, scene):
                if key in shown:
                    buffers[name] = shown[key]
            if film.sample_count is not None:  # the share of Samples each pixel took
                spp = float(film.stats.get("adaptive_spp") or film.sample_count.max() or 1.0)
                buffers[SAMPLE_COUNT_PASS] = (film.sample_count / spp)[:, :, None]
            mattes = getattr(film, "cryptomatte", None) or {}
            for kind, prefix in ((k, p) for _, k, p in CRYPTOMATTE_LAYERS):
                for i, rgba in enumerate(mattes.get(kind, ())):
                    buffers[f"{prefix}{i:02d}"] = rgba
                if kind in mattes:
                    # The compositor's Cryptomatte node finds the layer and its names in
                    # the whole render's metadata (get_result: a begin_result tile's own
                    # stamp data is not kept, as Cycles' stamp_view_layer_metadata).
                    meta = _engine_module("cryptomatte").metadata(
                        view_layer.name, kind, film.cryptomatte_names.get(kind, ()))
                    whole = self.get_result()
                    for key, value in meta.items():
                        whole.stamp_data_add_field(key, value)
            buffers.update(_aov_buffers(data, view_layer, h, w))
            written = set()
            for p in layer.passes:
                data = buffers.get(p.name)
                if data is None or (p.name, p.fullname) in written:
                    continue
                written.add((p.name, p.fullname))
                data = np.asarray(data, dtype=np.float32)
                if data.shape[2] != p.channels:
                    continue
                # Film rows run top to bottom, Blender's bottom to top.
                flat = np.ascontiguousarray(data[::-1]).reshape(-1)
                if flat.size != len(p.rect) * p.channels:
                    raise RuntimeError(f"pass '{p.name}' has {len(p.rect)} pixels, the "
                                       f"engine produced {w}x{h}")
                p.rect.foreach_set(flat)
        finally:
            self.end_result(result)


def _expected(exc: Exception) -> bool:
    """Refusals with a complete message of their own: no traceback in the console."""
    return (isinstance(exc, export.ExportError)
            or type(exc).__name__ in ("SceneError", "ResourceError"))


def frame_seed(seed: int, frame: int) -> int:
    """The seed of `frame` with Animated Seed on: seed and frame mixed into [0, 2^31), the
    same on every machine, so a farm renders each frame as one machine would
    (docs/distributed.md)."""
    return (int(seed) * 1_000_003 + int(frame) * 7919) % (1 << 31)


def _user_message(exc: Exception) -> str:
    name = type(exc).__name__
    if isinstance(exc, ModuleNotFoundError):
        return (f"Photon Mapping could not load '{exc.name}'. The extension bundles it for "
                "each platform: reinstall the build of the extension for this system.")
    if isinstance(exc, export.ExportError):
        return f"Photon Mapping: {exc}"
    if name == "SceneError":
        return f"Photon Mapping: the scene cannot be rendered: {exc}"
    if name == "ResourceError":
        return f"Photon Mapping: not rendered: {exc}"
    if isinstance(exc, MemoryError):
        return ("Photon Mapping ran out of memory: lower the photon counts, samples or "
                "resolution")
    return f"Photon Mapping failed: {exc} ({name}; details in the system console)"


def register():
    bpy.utils.register_class(PhotonMapRenderEngine)


def unregister():
    viewport.stop_all()  # no viewport thread outlives the add-on
    bpy.utils.unregister_class(PhotonMapRenderEngine)
