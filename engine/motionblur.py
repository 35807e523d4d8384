"""Motion blur by shutter time steps (Blender's Render > Motion Blur).

Cycles gives every camera ray its own time in the shutter and moves the geometry to it
(motion BVHs). A photon map is built for one arrangement of the scene, so here the
shutter is cut into `steps` equal slices and each slice is rendered as a whole render of
the scene at the slice's middle time: its own export, its own photons (the full count, so
each slice's estimates have the still's resolution), its own seed, and 1 / steps of the
camera samples. The slices' films are averaged (progressive.PassMerger), so the image is
the mean over the shutter of the scene's image, sampled at `steps` times: a box shutter,
as Cycles' default shutter curve. What moves further than a slice's share of its path
in a pixel shows the steps as ghosts (raise the steps). Each slice pays its own scene
export, acceleration structure and effect analysis. This is "time-sliced" photon
mapping; Cammarano & Jensen ("Time dependent photon mapping", EGWR 2002) estimate with a
kernel in time instead, which needs motion-aware ray tracing we do not have.

Scenes in which nothing moves over the shutter (every mesh, light and the camera the
same at its start and end) render once, as a still, and the effect report says so.
"""
from __future__ import annotations

import hashlib
import math
import time
from dataclasses import fields, is_dataclass, replace
from typing import Callable

import numpy as np

from .film import Film
from .parallel import Cancelled
from .progressive import K_MIN, PassMerger
from .render import render, warning_key, warning_teller
from .scene import Scene, place
from .settings import RenderSettings

# Blender's Render > Motion Blur > Position (Cycles' motion_blur_position): where the
# shutter opens, relative to the frame, in units of the shutter time.
POSITIONS = {"START": 0.0, "CENTER": -0.5, "END": -1.0}
DEFAULT_STEPS = 8
MAX_STEPS = 256


def shutter_times(frame: float, shutter: float, position: str = "CENTER",
                  steps: int = DEFAULT_STEPS) -> np.ndarray:
    """The middle times (in frames) of `steps` equal slices of the shutter: (steps,)
    float64. shutter: Render > Motion Blur > Shutter (frames, > 0, Blender's default
    0.5); position: START (the shutter opens at the frame), CENTER (Cycles' default: the
    frame is the shutter's middle) or END. Raises ValueError on a bad position, shutter
    or step count."""
    if not (isinstance(steps, (int, np.integer)) and 1 <= steps <= MAX_STEPS):
        raise ValueError(f"motion blur steps must be an integer 1..{MAX_STEPS}, got {steps!r}")
    opens, _ = shutter_span(frame, shutter, position)
    return opens + shutter * (np.arange(steps) + 0.5) / steps


# Motion Blur > Steps 0 (Auto): as many steps as keep the fastest vertex within this many
# pixels a step (its path through the shutter's start, middle and end), at most
# AUTO_MAX_STEPS (newuser38: 8 steps showed 8 copies of a spinner where Cycles gives a
# smooth disc; 32, ~2.5 pixels a step, were smooth; 2 pixels took that scene 40 steps and
# 3.2x the time of 8).
AUTO_PIXELS_PER_STEP = 3.0
AUTO_MAX_STEPS = 64
# Vertices per mesh looked at for its motion (a stride through larger meshes).
AUTO_MAX_VERTICES = 20_000


def _world_vertices(mesh):
    """(V,3) world-space vertices of an engine Mesh (a placement without a copy: its
    prototype's placed by its matrix, scene.place)."""
    if mesh.vertices is not None:
        return np.asarray(mesh.vertices, np.float64)
    if mesh.prototype is None or mesh.matrix is None:
        return np.zeros((0, 3))
    return place(mesh.prototype, mesh.matrix)[0]


def image_motion(a: Scene, b: Scene) -> float:
    """The largest distance in pixels a mesh vertex moves in the image between scene a and
    scene b (the same scene at two times: meshes matched by name and vertex count, each
    seen by its scene's camera, so a moving camera counts too). Perspective: the angle
    between the vertex's view directions over the pixel's angle (fov / the larger image
    side); orthographic: the image-plane displacement over ortho_scale / the larger side;
    panoramic: the angle over 2 pi / width. 0 without a camera."""
    if a.camera is None or b.camera is None:
        return 0.0
    side = max(a.width, a.height, 1)
    kind = a.camera.kind
    unit = (float(a.camera.fov) / side if kind == "PERSP" else
            float(a.camera.ortho_scale) / side if kind == "ORTHO" else 2.0 * math.pi / max(a.width, 1))
    if not unit > 0.0:
        return 0.0

    def view(cam, v):
        R = np.asarray(cam.rotation, np.float64)
        return (v - np.asarray(cam.position, np.float64)) @ R

    others = {m.name: m for m in b.meshes}
    worst = 0.0
    for m in a.meshes:
        other = others.get(m.name)
        if other is None:
            continue
        va, vb = _world_vertices(m), _world_vertices(other)
        if va.shape != vb.shape or not len(va):
            continue
        step = max(1, len(va) // AUTO_MAX_VERTICES)
        ca, cb = view(a.camera, va[::step]), view(b.camera, vb[::step])
        if kind == "ORTHO":
            moved = np.linalg.norm(ca[:, :2] - cb[:, :2], axis=1)
        else:  # the angle between the view directions (atan2: exact for small angles)
            moved = np.arctan2(np.linalg.norm(np.cross(ca, cb), axis=1),
                               np.einsum("ij,ij->i", ca, cb))
        moved = moved[np.isfinite(moved)]
        if len(moved):
            worst = max(worst, float(moved.max()) / unit)
    return worst


def auto_steps(scene_at: Callable[[float], Scene], opens: float, closes: float) -> tuple:
    """Motion Blur > Steps 0 (Auto): (steps, path): ceil(path / AUTO_PIXELS_PER_STEP)
    steps, 2 to AUTO_MAX_STEPS, path the largest image_motion
    (pixels) from the shutter's opening (time opens, frames) through its middle to its
    closing (three scene_at calls)."""
    mid = 0.5 * (opens + closes)
    a, m, b = scene_at(opens), scene_at(mid), scene_at(closes)
    path = image_motion(a, m) + image_motion(m, b)
    # (at least 2: render_motion_blur renders a still once if nothing moves at all, and
    # a lamp's motion, which no vertex shows, still blurs its light)
    steps = math.ceil(path / AUTO_PIXELS_PER_STEP - 1e-9) if path > 0.0 else 2
    return int(min(AUTO_MAX_STEPS, max(2, steps))), path


def shutter_span(frame: float, shutter: float, position: str = "CENTER") -> tuple:
    """(opens, closes): the shutter's times in frames (see shutter_times). Raises
    ValueError on a bad position or shutter."""
    if position not in POSITIONS:
        raise ValueError(f"motion blur position must be one of {', '.join(POSITIONS)}, "
                         f"got {position!r}")
    if not (math.isfinite(shutter) and shutter > 0.0):
        raise ValueError(f"motion blur shutter must be > 0 frames, got {shutter!r}")
    opens = frame + POSITIONS[position] * shutter
    return opens, opens + shutter


def frame_and_subframe(t: float) -> tuple[int, float]:
    """(frame, subframe) with subframe in [0, 1): Blender's frame_set(frame, subframe)
    arguments for time t (frames)."""
    f = math.floor(t)
    sub = t - f
    if sub >= 1.0:  # t just below an integer rounds up
        f, sub = f + 1, 0.0
    return int(f), float(sub)


def _digest(h, value) -> None:
    """Feed a scene value into the hash h: numbers, arrays, sequences, dicts and
    dataclasses by their fields (what moves: positions, rotations, matrices)."""
    if value is None or isinstance(value, (bool, int, float, str, np.number)):
        h.update(repr(value).encode())
    elif isinstance(value, np.ndarray):
        h.update(str(value.shape).encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, dict):
        for k in sorted(value, key=str):
            h.update(str(k).encode())
            _digest(h, value[k])
    elif isinstance(value, (list, tuple)):
        for v in value:
            _digest(h, v)
    elif is_dataclass(value):
        for f in fields(value):
            if f.name != "warnings":
                _digest(h, getattr(value, f.name))
    else:
        h.update(repr(type(value)).encode())


def pose_signature(scene: Scene) -> str:
    """A hash of what motion can change: every mesh's vertices and placement matrix,
    every light and the camera (all their fields). Two scenes with equal signatures look
    the same at any time."""
    h = hashlib.sha1()
    for mesh in scene.meshes:
        h.update(mesh.name.encode())
        _digest(h, mesh.vertices)
        _digest(h, mesh.matrix)
    for light in scene.lights:
        _digest(h, light)
    _digest(h, scene.camera)
    return h.hexdigest()


def step_settings(settings: RenderSettings, i: int, steps: int) -> RenderSettings:
    """The settings of slice i (0-based) of `steps`: its own seed (the slices' photons and
    camera samples are independent), ceil(spp / steps) camera samples, and photons and
    k-NN neighbours cut by one factor q = k_i / k with k_i = max(K_MIN, k / steps): a
    k-NN search then reaches as far as the still's (k_i photons of a map q times as
    dense), so each slice's estimates have the still's blur and q x its photon count,
    and the mean of the slices' estimates the still's noise where nothing moves (the
    progressive photon mapping argument: Knaus & Zwicker 2011). The photon passes of all
    slices together cost about one still's (more once k / steps < K_MIN). Adaptive
    sampling is the still's only (a slice's few samples are below its minimum)."""
    k_i = min(settings.k_nearest, max(K_MIN, int(round(settings.k_nearest / steps))))
    q = k_i / settings.k_nearest

    def cut(n):
        return max(1, int(round(n * q))) if n > 0 else n

    return replace(settings, spp=max(1, -(-settings.spp // steps)),
                   seed=settings.seed * 1_000_003 + 7919 * (i + 1),
                   k_nearest=k_i, photons=cut(settings.photons),
                   caustic_photons=cut(settings.caustic_photons),
                   min_photons=max(1, int(round(settings.min_photons * q))),
                   adaptive_threshold=0.0)


ADAPTIVE_WARNING = ("motion blur: Noise Threshold (adaptive sampling) is not used with "
                    "motion blur; every time step takes its share of the samples")


def render_motion_blur(scene_at: Callable[[float], Scene], times,
                       settings: RenderSettings | None = None, progress=None,
                       should_cancel=None, region=None, on_warning=None, on_plan=None,
                       on_step=None, why: str = "") -> Film:
    """Render the average over the shutter of the scene at `times` (frames; see
    shutter_times): scene_at(t) returns the Scene at time t (the add-on exports
    Blender's depsgraph there). Each time is a whole render (render.render) with
    step_settings; their films are averaged. If the scene at the first and the last
    time has the same pose_signature (nothing moves), the first scene is rendered once
    with the still's settings. progress(stage, fraction, text) as render's, the text
    prefixed with the step; should_cancel / region / on_warning / on_plan as render's
    (each warning told once over all steps); on_step(i, steps) before step i (0-based)
    renders, so a progress bar can place the steps' stages; why: words on how the steps
    were chosen, added to the effect report's line. film.stats: the first step's, with
    motion_blur_steps (1 when nothing moved), motion_blur_times, the times summed and
    the photons of every step; cancelling keeps the steps done (at least the first
    step's partial film). scene_at may raise parallel.Cancelled (a cancelled export):
    after the first step the steps done are kept; before, it propagates.
    Raises what render raises (SceneError, ResourceError) and ValueError for no times."""
    settings = settings or RenderSettings()
    times = [float(t) for t in np.atleast_1d(np.asarray(times, np.float64))]
    if not times:
        raise ValueError("motion blur needs at least one shutter time")
    t_start = time.perf_counter()
    tell = warning_teller(on_warning)

    def tell_once(text):
        tell([text])

    steps = len(times)
    first = scene_at(times[0])
    scenes = {0: first}
    still = False
    if steps > 1:
        last = scene_at(times[-1])
        if pose_signature(last) == pose_signature(first):
            steps, times, still = 1, times[:1], True
        else:
            scenes[steps - 1] = last
    if steps == 1:
        if on_step is not None:
            on_step(0, 1)
        film = render(first, settings, progress=progress, should_cancel=should_cancel,
                      region=region, on_warning=tell_once, on_plan=on_plan)
        film.stats.update(motion_blur_steps=1, motion_blur_times=times,
                          motion_blur_still=still)
        film.stats["effects"] = list(film.stats.get("effects", [])) + [
            "motion blur: off - nothing moves while the shutter is open (meshes, lights "
            "and camera the same at its start and end): rendered once" if still else
            f"motion blur: off - Motion Blur > Steps is 1: the scene at one time "
            f"({times[0]:g}, the shutter's middle), no blur; raise Steps to blur"]
        return film
    own = [ADAPTIVE_WARNING] if settings.adaptive_threshold > 0 else []
    for w in own:
        tell_once(w)
    merger = None
    stats0, warnings, keys = {}, [], set()
    sums = {}
    done = 0
    cancelled = False
    for i, t in enumerate(times):
        if should_cancel is not None and should_cancel() and merger is not None:
            cancelled = True
            break
        try:
            scene = scenes.pop(i) if i in scenes else scene_at(t)
        except Cancelled:  # cancelled while the front end exported this step's scene
            cancelled = True
            break

        def step_progress(stage, fraction, text, _i=i):
            if progress is not None:
                progress(stage, fraction, f"Time step {_i + 1}/{steps}: {text}")

        if on_step is not None:
            on_step(i, steps)
        one = render(scene, step_settings(settings, i, steps), progress=step_progress,
                     should_cancel=should_cancel, region=region, on_warning=tell_once,
                     on_plan=on_plan)
        if merger is None:
            merger = PassMerger(one.width, one.height, settings.show_photons)
            stats0 = dict(one.stats)
        if one.stats.get("cancelled") and done:
            cancelled = True
            break
        merger.add(one)
        done += 1
        for key, value in one.stats.items():
            if key.startswith("time_") or key.startswith("photons_"):
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    sums[key] = sums.get(key, 0) + value
        for w in one.warnings + own:
            if warning_key(w) not in keys:
                keys.add(warning_key(w))
                warnings.append(w)
        if one.stats.get("cancelled"):
            cancelled = True
            break
    film = merger.film
    slice_settings = step_settings(settings, 0, steps)  # (the slices differ by seed only)
    film.stats.update(stats0)
    film.stats.update(sums)
    film.stats.update(motion_blur_steps=done, motion_blur_times=times[:done],
                      motion_blur_still=False, cancelled=cancelled,
                      spp=slice_settings.spp * done,
                      time_total=time.perf_counter() - t_start)
    film.stats["effects"] = list(stats0.get("effects", [])) + [
        f"motion blur: on - {steps} time steps over the shutter "
        f"({times[0]:g} to {times[-1]:g}, slice middles), each a whole render with its own "
        f"{slice_settings.photons:,} photons (k-NN over {slice_settings.k_nearest}) and "
        f"{slice_settings.spp} samples a pixel: the "
        "image is their mean (what moves further than its width in one step shows the "
        "steps: raise Motion Blur > Steps)" + (f"; {why}" if why else "")]
    film.warnings = warnings
    return film
