"""Teaching operators: Compare Methods, Parameter Sweep and Effects Strip.

Each renders the scene at a preview size with the engine's teaching module
(engine/teaching.py: the same series as `photonmap compare / sweep / render --strip`),
burns the labels in with Blender's own font (BLF drawing into an image buffer) and opens
the result as an Image (bpy.data.images) in an Image Editor. The Render menu and the
Teaching panel (addon/ui.py) call them; addon/batch.py calls teaching_image() for
--compare / --sweep / --strip.

In Blender's window the renders run on a thread of their own (TeachingJob) while a modal
operator keeps the UI live, moves the progress bar and cancels on Esc: a sweep takes
minutes, and it froze Blender with no way out when it ran inside execute() (newuser42).
The export before and the labels after (Blender's data and font) stay on the main
thread. That is how the menus and buttons start them (invoke); one runs at a time.
Scripts (`bpy.ops.photonmap.compare_methods()`: execute) and background mode (`blender
-b`, the batch command) render inside execute() and have the image when it returns.
"""
from __future__ import annotations

import os
import tempfile
import threading
import time

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty

from . import export
from .core import load_engine

IMAGE_NAMES = {"compare": "Photon Mapping: Compare Methods",
               "sweep": "Photon Mapping: Parameter Sweep",
               "strip": "Photon Mapping: Effects Strip"}
QUALITY_ITEMS = (
    ("preview", "Preview", "The Preview quality preset's photons, samples and neighbours "
                           "(quick); other settings from the scene"),
    ("scene", "Scene Settings", "The scene's own render settings"),
)
SWEEP_ITEMS = (
    ("photons", "Photons", "Global photons (caustic photons scale with them)"),
    ("radius", "Search Radius", "Maximum photon search radius in metres"),
    ("k", "Nearest Photons", "Photons per k-nearest estimate"),
    ("spp", "Samples", "Camera samples per pixel"),
    ("ray_depth", "Max Ray Depth", "Specular bounces along a camera path"),
    ("photon_depth", "Max Photon Depth", "Bounces a photon may take"),
)
PRESET_ITEMS = (
    ("none", "None", "Sweep the parameter and values above"),
    ("paper-ladder", "Paper's Figure 6 Ladder",
     "1k photons / r 4.0 ... 200k / r 0.4 (paper units, x0.2 m), classic estimator, no "
     "final gathering"),
)


# --- labels with Blender's font ------------------------------------------------------------

def blf_label_mask(lines, width: int, size: int) -> np.ndarray:
    """Text coverage (h, w >= width) float32 in [0, 1] of `lines` in Blender's default
    font at `size` pixels, fitted by engine.teaching.fit_label (engine.teaching.compose's
    label_mask). BLF draws into an ImBuf,
    which is read back through a temporary PNG (ImBuf has no pixel access in Python)."""
    import blf
    import imbuf
    font = 0  # Blender's default font
    teaching = load_engine().teaching

    def measure(text, sz):
        blf.size(font, sz)
        return blf.dimensions(font, text)[0]

    # Smaller, then wrapped, then wider than the tile: never clipped (teaching.fit_label).
    lines, size, width = teaching.fit_label(lines, width, size, measure)
    step = size + max(2, size // 4)
    height = step * len(lines) + 4
    buf = imbuf.new((int(width), int(height)))
    with blf.bind_imbuf(font, buf, display_name="sRGB"):
        blf.size(font, size)
        blf.color(font, 1.0, 1.0, 1.0, 1.0)
        for i, line in enumerate(lines):
            # BLF's y runs upwards from the bottom row to the text's baseline.
            blf.position(font, teaching.LABEL_PAD, height - 2 - i * step - round(0.8 * size),
                         0)
            blf.draw_buffer(font, str(line))
    fd, path = tempfile.mkstemp(suffix=".png", prefix="photonmap_label_")
    os.close(fd)
    image = None
    try:
        imbuf.write(buf, filepath=path)
        image = bpy.data.images.load(path, check_existing=False)
        px = np.empty(int(width) * int(height) * 4, np.float32)
        image.pixels.foreach_get(px)
    finally:
        buf.free()
        if image is not None:
            bpy.data.images.remove(image)
        os.unlink(path)
    return px.reshape(int(height), int(width), 4)[::-1, :, 0].copy()  # rows top-down


# --- series --------------------------------------------------------------------------

def _preview_size(render, long_side: int):
    w, h = export.render_size(render)
    scale = min(1.0, long_side / max(w, h))
    return max(1, round(w * scale)), max(1, round(h * scale))


def teaching_image(kind: str, scene, depsgraph, preview_size: int = 160,
                   quality: str = "preview", params: dict | None = None,
                   sweep_preset: str = "none", progress=None, label_mask=None,
                   reference: str = "", should_cancel=None):
    """Render the teaching series `kind` ("compare", "sweep", "strip") of the Blender
    scene at a preview size and compose it. params: {name: [values]} for a sweep
    (engine.teaching.SWEEP_PARAMS names); sweep_preset: "paper-ladder" or "none";
    reference: an image file the sweep's errors are measured against (else the last
    tile); should_cancel() polled by the renders.
    Returns (tiles, rgb8 (H, W, 3) uint8). Raises ValueError (bad parameters, named),
    SceneError, ResourceError, engine.parallel.Cancelled (should_cancel() turned true)."""
    work = prepare_teaching(kind, scene, depsgraph, preview_size, quality, params,
                            sweep_preset, reference)
    tiles, columns = work(progress, should_cancel)
    return tiles, compose_teaching(tiles, columns, label_mask)


def compose_teaching(tiles, columns: int, label_mask=None) -> np.ndarray:
    """The tiles side by side, labelled with Blender's font (main thread: BLF), as
    (H, W, 3) uint8."""
    return load_engine().teaching.compose(tiles, columns,
                                          label_mask=label_mask or blf_label_mask)


def prepare_teaching(kind: str, scene, depsgraph, preview_size: int = 160,
                     quality: str = "preview", params: dict | None = None,
                     sweep_preset: str = "none", reference: str = ""):
    """What teaching_image does on Blender's main thread before rendering: check the
    arguments, export the scene, read the reference image. Returns work(progress,
    should_cancel) -> (tiles, columns), which renders without touching Blender's data
    (safe on another thread). Raises as teaching_image."""
    pm = load_engine()
    teaching = pm.teaching
    if kind not in IMAGE_NAMES:
        raise ValueError(f"unknown teaching image '{kind}' (one of {', '.join(IMAGE_NAMES)})")
    if preview_size < 1:
        raise ValueError(f"preview size must be >= 1 pixel, got {preview_size}")
    width, height = _preview_size(scene.render, preview_size)
    # The images stand for F12 renders: what is disabled in renders stays out.
    pm_scene, _ = export.export_scene(pm, depsgraph, camera=scene.camera, width=width,
                                      height=height, render_visibility=True)
    props = scene.photonmap
    kwargs = props.to_settings_kwargs(scene.render.film_transparent)
    if quality == "preview":
        kwargs.update(pm.presets.PRESETS["preview"])
    params = dict(params or {})
    if kind == "sweep" and sweep_preset not in (None, "", "none"):
        preset = teaching.SWEEP_PRESETS.get(sweep_preset)
        if preset is None:
            raise ValueError(f"unknown sweep preset '{sweep_preset}' (one of "
                             f"{', '.join(teaching.SWEEP_PRESETS)})")
        kwargs.update(preset["settings"])
        params = {**preset["params"], **params}
    settings = pm.RenderSettings(**kwargs)
    pm_scene.validate()
    pm.resources.check_resources(pm_scene, settings, in_blender=True)
    if kind == "sweep" and not params:
        raise ValueError("Parameter Sweep: give values (e.g. 1000,10000,100000) or "
                         "choose a preset")
    ref = load_reference(reference) if kind == "sweep" and reference else None

    def work(progress=None, should_cancel=None):
        if kind == "compare":
            return teaching.compare_methods(pm_scene, settings, progress, should_cancel), 4
        if kind == "sweep":
            tiles = teaching.sweep(pm_scene, settings, params, ref, progress=progress,
                                   should_cancel=should_cancel)
            return tiles, min(len(tiles), 4)
        t0 = time.perf_counter()
        film = pm.render(pm_scene, settings, progress=progress, should_cancel=should_cancel)
        if film.stats.get("cancelled"):
            raise pm.parallel.Cancelled()
        film.stats.setdefault("time_total", time.perf_counter() - t0)
        tiles = teaching.effects_strip(film)
        return tiles, len(tiles)
    return work


def load_reference(path: str) -> np.ndarray:
    """A reference image for a sweep as linear (H, W, 3) float32, read by Blender (EXR,
    HDR as stored; 8-bit formats decoded from sRGB). Raises ValueError naming the file."""
    if not path or not os.path.isfile(bpy.path.abspath(path)):
        raise ValueError(f"reference image '{path}' not found")
    try:
        image = bpy.data.images.load(bpy.path.abspath(path), check_existing=False)
    except RuntimeError as exc:
        raise ValueError(f"reference image '{path}' cannot be read: {exc}") from None
    try:
        w, h = image.size
        px = np.empty(w * h * image.channels, np.float32)
        image.pixels.foreach_get(px)
        rgb = px.reshape(h, w, image.channels)[::-1, :, :3]
        if not image.is_float:  # byte images hold their sRGB-encoded values
            rgb = load_engine().imageio.srgb_decode(rgb)
    finally:
        bpy.data.images.remove(image)
    return np.ascontiguousarray(rgb, np.float32)


def store_image(name: str, rgb8: np.ndarray):
    """bpy.data.images[name] holding the sRGB uint8 image (created or resized)."""
    h, w = rgb8.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and (tuple(image.size) != (w, h) or image.is_float):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, w, h, alpha=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb8[::-1].astype(np.float32) / 255.0  # Blender's rows bottom-up
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    return image


def save_image(image, path: str):
    """Write a stored image to `path` (PNG, or JPEG for .jpg) atomically."""
    replacing = load_engine().imageio.replacing
    ext = os.path.splitext(path)[1].lower()
    with replacing(path) as tmp:
        image.filepath_raw = tmp
        image.file_format = "JPEG" if ext in (".jpg", ".jpeg") else "PNG"
        image.save()


def show_in_image_editor(context, image) -> bool:
    """Show `image` in an Image Editor: an open one, else a new window (as F11 opens the
    render view). False when there is no window (background mode)."""
    wm = context.window_manager
    if bpy.app.background or context.window is None or not wm.windows:
        return False

    def editors():
        return [a for win in wm.windows for a in win.screen.areas if a.type == "IMAGE_EDITOR"]

    areas = editors()
    if not areas:
        try:
            bpy.ops.render.view_show("INVOKE_DEFAULT")  # a window with an Image Editor
        except RuntimeError:
            return False
        areas = editors()
    for area in areas[:1]:
        area.spaces.active.image = image
        area.tag_redraw()
    return bool(areas)


# --- a teaching render on its own thread -----------------------------------------------

class TeachingJob:
    """work(progress, should_cancel) on a daemon thread (prepare_teaching's, which touches
    no Blender data), polled from Blender's main thread by the modal operator: fraction
    and text of its progress, done, then result (its return value) or error (what it
    raised; engine.parallel.Cancelled after cancel())."""

    def __init__(self, work):
        self._work = work
        self._cancel = threading.Event()
        self.fraction, self.text = 0.0, ""
        self.result = self.error = None
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name="Photon Mapping teaching render")

    def start(self) -> "TeachingJob":
        self._thread.start()
        return self

    def _run(self):
        try:
            self.result = self._work(self._progress, self._cancel.is_set)
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread
            self.error = exc

    def _progress(self, stage, fraction, text):
        self.fraction, self.text = min(max(float(fraction), 0.0), 1.0), text

    def cancel(self):
        """Ask the renders to stop at their next poll (engine should_cancel)."""
        self._cancel.set()

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def wait(self, timeout=None) -> bool:
        self._thread.join(timeout)
        return self.done


def runs_modal(context) -> bool:
    """Whether an operator started from the UI in `context` can run modal: a window to
    live in (not background mode: `blender -b`, the batch command)."""
    return not bpy.app.background and getattr(context, "window", None) is not None


# The teaching render running on its thread (one at a time: a second would share the
# cores and the progress bar, and Esc reaches only the newest modal handler).
_running: TeachingJob | None = None


def running_job() -> TeachingJob | None:
    """The teaching job still rendering, if any."""
    return _running if _running is not None and not _running.done else None


# --- operators -----------------------------------------------------------------------

class _TeachingOperator:
    bl_options = {"REGISTER"}
    kind = ""

    preview_size: IntProperty(
        name="Preview Size", default=160, min=16, soft_max=640, max=4096,
        description="Longer image side of each tile in pixels")
    quality: EnumProperty(name="Quality", items=QUALITY_ITEMS, default="preview",
                          description="Settings of the renders")

    # Set by invoke (the menus and buttons): execute then renders on a thread while the
    # UI stays live. Hidden and not saved: scripts calling the operator get it False.
    from_ui: BoolProperty(default=False, options={"HIDDEN", "SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        if running_job() is not None:
            cls.poll_message_set("A teaching render is running (Esc cancels it)")
            return False
        return context.scene is not None and context.scene.camera is not None

    def invoke(self, context, event):
        self.from_ui = True
        return self.execute(context)

    def _params(self):
        return {}, "none"

    def _reference(self):
        return ""

    def execute(self, context):
        try:
            params, preset = self._params()
            work = prepare_teaching(self.kind, context.scene,
                                    context.evaluated_depsgraph_get(), self.preview_size,
                                    self.quality, params, preset, self._reference())
        except Exception as exc:  # noqa: BLE001 - a report, never a traceback dialog
            self.report({"ERROR"}, f"Photon Mapping: {exc}")
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        if self.from_ui and runs_modal(context):
            global _running
            self._job = _running = TeachingJob(work).start()
            self._timer = wm.event_timer_add(0.2, window=context.window)
            wm.modal_handler_add(self)
            context.workspace.status_text_set(f"{self.bl_label}: rendering (Esc cancels)")
            return {"RUNNING_MODAL"}

        def progress(stage, fraction, text):
            wm.progress_update(int(1000 * min(max(fraction, 0.0), 1.0)))

        try:
            result = work(progress, None)
        except Exception as exc:  # noqa: BLE001
            self.report({"ERROR"}, f"Photon Mapping: {exc}")
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        return self._finish(context, *result)

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC" and event.value == "PRESS":
            job.cancel()  # the renders stop at their next poll; the timer sees it end
            context.workspace.status_text_set(f"{self.bl_label}: cancelling")
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}  # the UI stays live while the renders run
        if not job.done:
            context.window_manager.progress_update(int(1000 * job.fraction))
            if job.text:
                context.workspace.status_text_set(
                    f"{self.bl_label}: {job.text} (Esc cancels)")
            return {"RUNNING_MODAL"}
        self._end_modal(context)
        if isinstance(job.error, load_engine().parallel.Cancelled):
            self.report({"WARNING"}, f"Photon Mapping: {self.bl_label} cancelled")
            return {"CANCELLED"}
        if job.error is not None:
            self.report({"ERROR"}, f"Photon Mapping: {job.error}")
            return {"CANCELLED"}
        return self._finish(context, *job.result)

    def cancel(self, context):
        """Blender ends the modal operator (a new or opened file, the window closed,
        quitting): stop the renders too, and the bars."""
        self._job.cancel()
        self._end_modal(context)

    def _end_modal(self, context):
        global _running
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        if _running is self._job:
            _running = None

    def _finish(self, context, tiles, columns):
        rgb8 = compose_teaching(tiles, columns)
        image = store_image(IMAGE_NAMES[self.kind], rgb8)
        show_in_image_editor(context, image)
        summary = "; ".join(", ".join(line for line in t.lines if line) for t in tiles)
        self.report({"INFO"}, f"{image.name}: {summary}")
        return {"FINISHED"}


class PHOTONMAP_OT_compare_methods(_TeachingOperator, bpy.types.Operator):
    """Render the scene with local illumination, ray tracing and photon mapping, plus the
    photon hits, into one labelled image"""
    bl_idname = "photonmap.compare_methods"
    bl_label = "Compare Methods"
    kind = "compare"


class PHOTONMAP_OT_effects_strip(_TeachingOperator, bpy.types.Operator):
    """Render the scene and show its direct, indirect, caustic, specular and emission
    passes side by side with their sum, labelled"""
    bl_idname = "photonmap.effects_strip"
    bl_label = "Effects Strip"
    kind = "strip"


class PHOTONMAP_OT_parameter_sweep(_TeachingOperator, bpy.types.Operator):
    """Render the scene for each value of one parameter into a labelled ladder with each
    render's time and error against the last (finest) one"""
    bl_idname = "photonmap.parameter_sweep"
    bl_label = "Parameter Sweep"
    kind = "sweep"

    parameter: EnumProperty(name="Parameter", items=SWEEP_ITEMS, default="photons",
                            description="The setting to vary")
    values: StringProperty(
        name="Values", default="1000,10000,100000",
        description="Comma-separated values, coarse to fine (the last is the reference)")
    preset: EnumProperty(name="Preset", items=PRESET_ITEMS, default="none",
                         description="A predefined sweep instead of the parameter above")
    reference: StringProperty(
        name="Reference", default="", subtype="FILE_PATH",
        description="Image to measure each tile's error against (EXR for linear values; "
                    "the same size as the tiles). Empty: against the last tile")

    def _params(self):
        if self.preset != "none":
            return {}, self.preset
        teaching = load_engine().teaching
        name, values = teaching.parse_param(f"{self.parameter}={self.values}")
        return {name: values}, "none"

    def _reference(self):
        return self.reference

    def invoke(self, context, event):
        self.from_ui = True  # (kept through the dialog: execute renders on a thread)
        return context.window_manager.invoke_props_dialog(self)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "preset")
        col = layout.column()
        col.active = self.preset == "none"
        col.prop(self, "parameter")
        col.prop(self, "values")
        layout.prop(self, "reference")
        layout.prop(self, "preview_size")
        layout.prop(self, "quality")


classes = (PHOTONMAP_OT_compare_methods, PHOTONMAP_OT_parameter_sweep,
           PHOTONMAP_OT_effects_strip)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
