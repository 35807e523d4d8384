"""Rendered viewport: view_update / view_draw of our RenderEngine, a thin layer over the
engine's interactive session (engine/session.py), after Blender's custom render engine
template (bpy.types.RenderEngine: a GPU texture drawn with the display-space shader).

view_update (Blender's main thread, on every depsgraph change) re-exports only what
changed (addon/export.py, export_viewport) and hands the new scene to the session, which
restarts its passes on its own thread; view_draw draws the newest finished image and
never waits. Moving the view only re-aims the camera: the session keeps its photons.
"""
from __future__ import annotations

import atexit
import dataclasses
import importlib
import math
import weakref

import numpy as np

from . import export
from .core import load_engine

REDRAW_SECONDS = 0.1  # how often a running session's new image is looked for


# --- the view's camera (pure numpy: tested without a window) ---------------------------

def view_camera(pm, view_matrix, window_matrix, perspective: bool):
    """Engine Camera that sees what a 3D view's projection shows.

    view_matrix: world -> view (4x4, RegionView3D.view_matrix); window_matrix: the
    OpenGL-style projection of the region (RegionView3D.window_matrix), which already
    holds the lens, zoom, ortho scale, camera shift and the camera-view offset of every
    view mode (perspective, orthographic, looking through the scene camera). At view
    distance 1 (perspective) the image plane spans x in [(-1 + P02) / P00, (1 + P02) /
    P00] (orthographic: [(-1 - P03) / P00, (1 - P03) / P00]), likewise y; the near and
    far planes come from P22, P23. Orthographic views clip from -far/2 (behind the view
    point): the engine camera is moved back to the near plane."""
    V = np.asarray(view_matrix, dtype=np.float64).reshape(4, 4)
    P = np.asarray(window_matrix, dtype=np.float64).reshape(4, 4)
    C = np.linalg.inv(V)
    R, pos = C[:3, :3], C[:3, 3].copy()
    hw, hh = 1.0 / P[0, 0], 1.0 / P[1, 1]
    if perspective:
        cx, cy = P[0, 2] / P[0, 0], P[1, 2] / P[1, 1]
        near, far = P[2, 3] / (P[2, 2] - 1.0), P[2, 3] / (P[2, 2] + 1.0)
    else:
        cx, cy = -P[0, 3] / P[0, 0], -P[1, 3] / P[1, 1]
        near, far = (P[2, 3] + 1.0) / P[2, 2], (P[2, 3] - 1.0) / P[2, 2]
        back = R[:, 2] / max(np.linalg.norm(R[:, 2]), 1e-300)
        pos = pos - back * near
        near, far = 0.0, far - near
    big = 2.0 * max(hw, hh)
    kw = dict(position=pos, rotation=R, sensor_fit="HORIZONTAL", shift_x=cx / big,
              shift_y=cy / big, clip_start=max(near, 0.0), clip_end=far)
    if perspective:
        return pm.Camera(kind="PERSP", fov=2.0 * math.atan(hw), **kw)
    return pm.Camera(kind="ORTHO", ortho_scale=2.0 * hw, **kw)


def render_size(width: int, height: int, percent: float) -> tuple[int, int]:
    """Pixels the session renders for a region of width x height at `percent` %."""
    f = max(float(percent), 1.0) / 100.0
    return max(1, round(width * f)), max(1, round(height * f))


def border_pixels(corners_ndc, border, width: int, height: int):
    """Region (x0, y0, x1, y1) in top-left pixel coordinates of a width x height image
    for a render border (min_x, min_y, max_x, max_y as fractions of the frame, origin at
    the bottom left) inside a frame whose corners project to corners_ndc ((N,2), -1..1,
    y up). None when the border covers the whole image or nothing."""
    c = np.asarray(corners_ndc, dtype=np.float64)
    fx0, fy0 = (c.min(axis=0) + 1.0) / 2.0
    fx1, fy1 = (c.max(axis=0) + 1.0) / 2.0
    bx0, by0, bx1, by1 = border
    x0 = (fx0 + bx0 * (fx1 - fx0)) * width
    x1 = (fx0 + bx1 * (fx1 - fx0)) * width
    y0 = (fy0 + by0 * (fy1 - fy0)) * height
    y1 = (fy0 + by1 * (fy1 - fy0)) * height
    px0, px1 = int(max(0, math.floor(x0))), int(min(width, math.ceil(x1)))
    py0, py1 = int(max(0, math.floor(height - y1))), int(min(height, math.ceil(height - y0)))
    if px1 <= px0 or py1 <= py0:
        return None
    if (px0, py0, px1, py1) == (0, 0, width, height):
        return None
    return (px0, py0, px1, py1)


def stats_text(frame, budget: int, error: str | None = None) -> str:
    """The viewport header's stats line for a session Frame."""
    if error:
        return f"Error: {error}"
    if frame is None:
        return "Preparing scene"
    if frame.passes == 0:
        what = f"Preview 1/{frame.scale}"
    else:
        what = f"Pass {frame.passes}" + (f"/{budget}" if budget else "")
    done = " | Done" if frame.done else ""
    return (f"{what} | {frame.photons / 1e6:.2f} M photons | {frame.elapsed:.1f} s{done}")


# --- the RenderEngine side ----------------------------------------------------------------

class ViewportRender:
    """One rendered viewport: the export cache, the session, the drawn texture."""

    def __init__(self):
        self.pm = None
        self.cache = None
        self.session = None
        self.settings_key = None
        self.view_key = None
        self.view = None
        self.scene = None
        self.texture = None
        self.texture_frame = None
        self.last_export: dict = {}
        self.budget = 0
        self.timer = None
        _live.add(self)

    # view_update
    def update(self, context, depsgraph):
        bpy_scene = depsgraph.scene
        props = bpy_scene.photonmap
        if self.pm is None:
            self.pm = load_engine()
        pm = self.pm
        kwargs = props.to_viewport_settings_kwargs(bpy_scene.render.film_transparent)
        key = (tuple(sorted(kwargs.items())), props.viewport_passes)
        restart = self.session is None or key != self.settings_key
        view = self.view or self._view_from_context(context, bpy_scene)
        camera, width, height, region = view
        updates = None if restart else export.ViewportUpdates.from_depsgraph(depsgraph)
        if restart:
            self.cache = export.ViewportExport(pm)
        scene, info = export.export_viewport(self.cache, depsgraph, camera, width, height,
                                             updates)
        self.last_export = info
        self.scene = scene
        if restart:
            self.stop()
            self.settings_key = key
            self.budget = props.viewport_passes
            session = importlib.import_module(pm.__name__ + ".session")
            self.session = session.Session(scene, pm.RenderSettings(**kwargs),
                                           passes=props.viewport_passes, region=region)
            self.session.start()
        elif info["geometry_changed"]:
            self.session.update_scene(scene, geometry=True)
        elif info["materials_changed"] or info["lights_changed"] or info["world_changed"]:
            self.session.update_scene(scene, geometry=False)
        self.view = view
        self.view_key = _view_key(view)
        _ensure_redraw_timer(self)

    # view_draw
    def draw(self, engine, context, depsgraph):
        if self.session is None:
            return
        view = self._view_from_context(context, depsgraph.scene)
        key = _view_key(view)
        if key != self.view_key:
            self.view, self.view_key = view, key
            camera, width, height, region = view
            self.session.update_view(camera, width, height, region)
        frame = self.session.frame
        engine.update_stats("", stats_text(frame, self.budget, self.session.error))
        if frame is None:
            return
        import gpu
        from gpu_extras.presets import draw_texture_2d
        if self.texture_frame is not frame:
            h, w = frame.rgba.shape[:2]
            pixels = np.ascontiguousarray(frame.rgba[::-1], dtype=np.float32).reshape(-1)
            try:
                buf = gpu.types.Buffer("FLOAT", pixels.size, pixels)
            except TypeError:  # a Blender without the buffer protocol here
                buf = gpu.types.Buffer("FLOAT", pixels.size, pixels.tolist())
            self.texture = gpu.types.GPUTexture((w, h), format="RGBA16F", data=buf)
            self.texture_frame = frame
        region = context.region
        W, H = frame.full_size
        sx, sy = region.width / W, region.height / H
        x0, y0, x1, y1 = frame.region
        gpu.state.blend_set("ALPHA_PREMULT")
        engine.bind_display_space_shader(depsgraph.scene)
        draw_texture_2d(self.texture, (x0 * sx, (H - y1) * sy), (x1 - x0) * sx, (y1 - y0) * sy)
        engine.unbind_display_space_shader()
        gpu.state.blend_set("NONE")

    def stop(self) -> float:
        """Stop the session (joins its thread); returns the seconds it took."""
        session, self.session = self.session, None
        return session.stop() if session is not None else 0.0

    def _view_from_context(self, context, bpy_scene):
        """(engine camera, render width, height, region or None) of the 3D view."""
        region, rv3d = context.region, context.region_data
        props = bpy_scene.photonmap
        width, height = render_size(region.width, region.height, props.viewport_resolution)
        camera = view_camera(self.pm, rv3d.view_matrix, rv3d.window_matrix,
                             rv3d.is_perspective)
        border = None
        space = context.space_data
        if rv3d.view_perspective == "CAMERA":
            cam = space.camera if getattr(space, "use_local_camera", False) else bpy_scene.camera
            if cam is not None and cam.type == "CAMERA":
                # Through the scene camera its depth of field applies, as in Cycles' viewport
                # (the view's own lens elsewhere has none); warnings are the render's.
                dof = export.camera_dof(cam, cam.data, cam.data.type, [], bpy_scene.objects)
                if dof:
                    camera = dataclasses.replace(camera, **dof)
        if rv3d.view_perspective == "CAMERA" and bpy_scene.render.use_border:
            cam = space.camera if getattr(space, "use_local_camera", False) else bpy_scene.camera
            if cam is not None:
                frame = [cam.matrix_world @ v for v in cam.data.view_frame(scene=bpy_scene)]
                border = border_pixels(_project(rv3d.perspective_matrix, frame),
                                       (bpy_scene.render.border_min_x,
                                        bpy_scene.render.border_min_y,
                                        bpy_scene.render.border_max_x,
                                        bpy_scene.render.border_max_y), width, height)
        elif rv3d.view_perspective != "CAMERA" and getattr(space, "use_render_border", False):
            border = border_pixels([(-1, -1), (1, 1)],
                                   (space.render_border_min_x, space.render_border_min_y,
                                    space.render_border_max_x, space.render_border_max_y),
                                   width, height)
        return camera, width, height, border


def _project(perspective_matrix, points):
    M = np.asarray(perspective_matrix, dtype=np.float64).reshape(4, 4)
    p = np.array([[v[0], v[1], v[2], 1.0] for v in points]) @ M.T
    return p[:, :2] / p[:, 3:4]


def _view_key(view):
    camera, width, height, region = view
    return (camera.position.tobytes(), camera.rotation.tobytes(), camera.kind, camera.fov,
            camera.ortho_scale, camera.shift_x, camera.shift_y, camera.clip_start,
            camera.clip_end, camera.aperture_radius, camera.focus_distance,
            camera.aperture_blades, camera.aperture_rotation, camera.aperture_ratio, width,
            height, region)


def _ensure_redraw_timer(viewport):
    """Redraw the 3D views while the session produces images: a timer on Blender's main
    thread (the render thread must not touch Blender). It holds no reference to the
    RenderEngine, so Blender can free the engine (and so stop the session) when the view
    leaves Rendered shading; the timer ends with the session."""
    if viewport.timer is not None:
        return
    import bpy

    state = {"frame": None}

    def poll():
        session = viewport.session
        if session is None:
            viewport.timer = None
            return None
        frame = session.frame
        if frame is not state["frame"] or session.error:
            state["frame"] = frame
            for window in bpy.context.window_manager.windows:
                for area in window.screen.areas:
                    if area.type == "VIEW_3D":
                        area.tag_redraw()
        return REDRAW_SECONDS

    viewport.timer = poll
    bpy.app.timers.register(poll, first_interval=REDRAW_SECONDS)


def stop_all() -> None:
    """Stop every viewport session of this process (add-on unregistered, Python exits)."""
    for viewport in list(_live):
        viewport.stop()


_live = weakref.WeakSet()
atexit.register(stop_all)
