"""Interactive render session: progressive passes on a background thread, restarted by
edits (Blender's rendered viewport, addon/viewport.py; never imports bpy).

A session owns a Scene and a view (camera, size, optional pixel region). Its thread
renders

    pass 1's photons -> preview at 1/4 size -> preview at 1/2 size -> full-size pass 1,
    then full-size passes 2, 3, ... until the pass budget,

publishing the newest image as a Frame after each step, so a first picture appears after
one photon pass and one small camera pass. The full-size passes are exactly the passes of
engine.progressive.render_progressive (same pass_settings, same PassMerger), so after k
passes the image equals a plain progressive render of the same view with the same seed
(tests/test_session.py).

Edits restart the passes without blocking the caller: update_view() / update_scene()
only record the request and raise the cancel flag, which the running stage polls (Embree
chunks, photon chunks, camera chunks: engine/parallel.py); the thread then rebuilds what
the request needs:

- view change (camera, size, region): nothing of the scene is rebuilt; the effect plan is
  re-analysed (which mirrors the camera sees) and every pass's photon maps are reused, as
  photons do not depend on the view (Photons kept per pass, up to a memory budget);
- light / world / material change with the same triangles: geometry and BVH kept, the
  material table, lights and plan rebuilt, photons re-shot;
- geometry change: triangles merged again (engine.geometry.prepare); the BVH is rebuilt
  only when the triangle set or its ray visibility changed (a material re-assignment
  keeps it); photons re-shot.

What was rebuilt is counted in Session.counters and logged in Session.events, for tests.

The newest Frame is swapped in as one attribute assignment (atomic in CPython): a reader
(the viewport's draw callback) never waits for the renderer. stop() raises the cancel
flag and joins the thread and the worker chunks of this session's cancelled stages; it
returns when no thread of the session is left (measured in bench/bench_viewport.py).
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field, fields, replace

import numpy as np

from . import shadowcatcher
from .effects import analyse
from .ambientocclusion import attach_tracer
from .geometry import MaterialTable, prepare, set_camera_view
from .jit import ensure_compiled
from .lights import prepare_lights
from .lightlinking import links_for
from .displacement import moves_vertices
from .shadowtransmittance import ShadowTransmittance
from .parallel import Cancelled, StopFlag, drain, polled_by
from .progressive import PassMerger, pass_settings
from .mallocheap import render_heap
from .render import (Context, _check_region, packed_lights_for, prepare_context, render_pass,
                     shoot_photons)
from .resources import check_resources
from .scene import Camera, Scene
from .settings import RenderSettings
from .visibility import VisibilityAccel
from .raymaterials import expanded_names
from .worldmedium import table_materials

PREVIEW_SCALES = (4, 2)        # reduced resolutions before the first full-size pass
PHOTON_CACHE_BYTES = 256 << 20  # photon maps kept for view changes (per session)
# Photon-map fields of a Context that one pass's photon stage fills (render.shoot_photons),
# the samples a pixel its maps' estimates take among them: a pass whose maps are reused
# reads its own (the glow map's stride from its shot's glow share, render.smooth_counts),
# not the last shot pass's.
_MAP_FIELDS = ("global_map", "caustic_map", "glow_map", "gather_map", "secondary_map",
               "regather_maps", "regather_secondary", "gather_counts",
               "global_radius", "secondary_radius", "caustic_radius", "glow_radius",
               "gather_short", "gather_rays", "glow_per_pixel", "secondary_per_pixel")
# (photons_emitted_all: every shot's, the glow shot's included, as PassMerger counts a
# pass's photons; glow_photons / radius_glow: the glow map's, GLOW_MAP_APART)
_PHOTON_STATS = ("photons_emitted", "caustic_photons_emitted", "photons_emitted_all",
                 "global_photons", "caustic_photons", "glow_photons", "radius_global",
                 "radius_caustic", "radius_glow", "radius_spacing", "photon_bytes")


@dataclass(frozen=True)
class Frame:
    """One published image of a session.

    rgba: (h, w, 4) float32 linear radiance and alpha, rows top to bottom.
    region: (x0, y0, x1, y1) the pixels of the full-size view it covers (top-left origin,
    exclusive max); a preview covers them with fewer pixels (scale > 1).
    passes: full-size passes averaged in it (0 for a preview); photons: photons emitted
    for them; elapsed: seconds since the restart that produced it; generation: the
    number of the update it belongs to; done: the pass budget is spent."""

    rgba: np.ndarray
    region: tuple
    full_size: tuple
    scale: int
    passes: int
    photons: int
    elapsed: float
    generation: int
    done: bool = False


@dataclass
class _Request:
    scene: Scene | None = None      # new scene content
    geometry: bool = False          # its triangles (or their visibility) may have changed
    view: tuple | None = None       # (camera, width, height, region)


@dataclass
class _PhotonEntry:
    maps: dict
    stats: dict
    nbytes: int


@dataclass
class SessionCounters:
    """What the session rebuilt since it started (tests read these)."""

    restarts: int = 0
    geometry_builds: int = 0    # engine.geometry.prepare (triangles merged)
    bvh_builds: int = 0         # Embree BVHs built
    light_builds: int = 0       # prepare_lights
    catcher_builds: int = 0     # shadow catchers' catchers-alone contexts
    photon_shots: int = 0       # photon passes traced
    photon_reuses: int = 0      # photon passes taken from the cache
    previews: int = 0           # reduced-resolution camera passes
    passes: int = 0             # full-size camera passes
    cancels: int = 0            # stages stopped by an update or stop()
    events: list = field(default_factory=list)


class Session:
    """Progressive rendering of one scene on a background thread, restarted by edits.

    scene: engine Scene (its camera, width and height are the initial view unless
    update_view() gives another); settings: RenderSettings of every pass (pass i uses
    progressive.pass_settings(settings, i)); passes: the pass budget (0 = refine until
    stopped); preview_scales: reduced resolutions shown before the first full pass.
    Raises ValueError for a bad budget or scale. Errors of the render itself (SceneError,
    ResourceError, ...) do not raise: they stop the passes and are kept in self.error
    (a message) until the next update."""

    def __init__(self, scene: Scene, settings: RenderSettings | None = None, passes: int = 16,
                 preview_scales=PREVIEW_SCALES, region=None,
                 photon_cache_bytes: int = PHOTON_CACHE_BYTES):
        if int(passes) < 0:
            raise ValueError(f"session 'passes' must be >= 0 (0 = no limit), got {passes}")
        scales = tuple(int(s) for s in preview_scales)
        if any(s < 2 for s in scales):
            raise ValueError(f"preview_scales must be integers >= 2, got {preview_scales!r}")
        self.settings = replace(settings or RenderSettings(), show_photons=False)
        self.passes = int(passes)
        self.preview_scales = tuple(sorted(set(scales), reverse=True))
        self.photon_cache_bytes = int(photon_cache_bytes)
        self.counters = SessionCounters()
        self.frame: Frame | None = None
        self.error: str | None = None
        self.generation = 0
        self._scene = _copy_scene(scene)
        self._view = (scene.camera, int(scene.width), int(scene.height), region)
        self._cond = threading.Condition()
        # Compiled steps poll its array (parallel.StopFlag): stop() reaches the middle of
        # a photon-map estimate or a kd-tree build at once, not at its end (issue 19).
        self._cancel = StopFlag()
        self._pending: _Request | None = _Request(scene=self._scene, geometry=True)
        self._stopping = False
        self._busy = False
        self._ctx: Context | None = None
        self._plan_key = None
        self._photons: dict[int, _PhotonEntry] = {}
        self._scene_dirty = True
        self._geometry_dirty = True
        self._thread: threading.Thread | None = None

    # --- control (any thread) ----------------------------------------------------------
    def start(self) -> "Session":
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="photonmap-session",
                                            daemon=True)
            self._thread.start()
        return self

    def update_view(self, camera: Camera, width: int, height: int, region=None) -> None:
        """A new view (camera, image size, optional region): restarts the passes and
        keeps the photon maps. Returns at once. Raises ValueError (size < 1) and
        RuntimeError (the session was stopped)."""
        if int(width) < 1 or int(height) < 1:
            raise ValueError(f"view size must be at least 1x1, got {width}x{height}")
        self._request(view=(camera, int(width), int(height), region))

    def update_scene(self, scene: Scene, geometry: bool = True) -> None:
        """New scene content (the view stays): re-shoots photons. geometry=False promises
        the same meshes (triangles, visibility and material names) as before, so only
        materials, lights and the world are rebuilt. Returns at once. Raises RuntimeError
        (the session was stopped)."""
        # A material with true displacement moves vertices: a new one (or one gone) is
        # a geometry change whatever the caller knows (engine/displacement.py).
        old = self._scene.materials if self._scene is not None else {}
        moved = {n for n, m in scene.materials.items() if moves_vertices(m)}
        moved |= {n for n, m in old.items() if moves_vertices(m)}
        if any(scene.materials.get(n) is not old.get(n) for n in moved):
            geometry = True
        self._request(scene=_copy_scene(scene), geometry=bool(geometry))

    def stop(self) -> float:
        """Cancel the running stage and join the thread; returns the seconds it took.
        The session cannot be restarted."""
        t0 = time.perf_counter()
        with self._cond:
            self._stopping = True
            self._cancel.set()
            self._cond.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()
            # The chunks this session's cancels left running stop at their next check:
            # wait for those only (pools of other sessions and renders drain on their
            # own; joining them made one stop take seconds).
            drain(self._cancel)
        return time.perf_counter() - t0

    @property
    def running(self) -> bool:
        """The thread exists and is alive."""
        return self._thread is not None and self._thread.is_alive()

    @property
    def busy(self) -> bool:
        """Work is pending or running (the image will still change)."""
        return self._busy or self._pending is not None

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until the passes of the latest update are done (or failed); for scripts
        and tests, never for a UI. Returns False on timeout."""
        end = None if timeout is None else time.perf_counter() + timeout
        with self._cond:
            while self.busy and not self._stopping:
                left = None if end is None else end - time.perf_counter()
                if left is not None and left <= 0:
                    return False
                self._cond.wait(left if left is not None else 0.5)
        return True

    def _request(self, scene=None, geometry=False, view=None):
        with self._cond:
            if self._stopping:
                raise RuntimeError("the render session is stopped: start a new Session")
            req = self._pending or _Request()
            if scene is not None:
                req.scene = scene
                req.geometry = req.geometry or geometry
            if view is not None:
                req.view = view
            self._pending = req
            self.generation += 1
            self._cancel.set()
            self._cond.notify_all()

    # --- the thread ----------------------------------------------------------------------
    def _run(self):
        # The kernels load (or compile) first, outside the session's flag: an update that
        # arrives meanwhile cancels the running stage, and a warm-up that polled the flag
        # (the kd-tree's build) raised Cancelled out of the thread, leaving the session
        # busy for ever (an edit in the first seconds of a viewport; tests/test_session.py).
        try:
            ensure_compiled()
        except Exception as exc:  # noqa: BLE001 - kept for the caller to show
            self.error = f"{type(exc).__name__}: {exc}"
            self._event("error", self.error)
            with self._cond:
                self._stopping = True  # nothing will render: waiters return
                self._cond.notify_all()
            return
        # Every pool started on this thread belongs to the session's flag (stop() joins
        # them), also where a stage polls it through a plain callable.
        with polled_by(self._cancel):
            self._loop()

    def _loop(self):
        try:
            while True:
                with self._cond:
                    while self._pending is None and not self._stopping:
                        self._busy = False
                        self._cond.notify_all()
                        self._cond.wait()
                    if self._stopping:
                        break
                    req, self._pending = self._pending, None
                    generation = self.generation
                    self._cancel.clear()
                    self._busy = True
                try:
                    self.counters.restarts += 1
                    self.error = None
                    self._apply(req)
                    self._render(generation)
                except Cancelled:
                    self.counters.cancels += 1
                except Exception as exc:  # noqa: BLE001 - kept for the caller to show
                    self.error = f"{type(exc).__name__}: {exc}"
                    self._event("error", self.error)
        finally:
            if self._ctx is not None:
                self._ctx.accel.close(wait=True)  # no query thread outlives stop()
                if self._ctx.links is not None:
                    self._ctx.links.close(wait=True)
                if self._ctx.catcher_alone is not None:
                    self._ctx.catcher_alone.accel.close(wait=True)
                self._ctx = None
            self._photons.clear()
            with self._cond:
                self._busy = False
                self._cond.notify_all()

    def _event(self, *what):
        self.counters.events.append((self.generation,) + what)

    def view_scene(self) -> Scene:
        """The scene as the current view sees it (its camera and image size)."""
        camera, width, height, _ = self._view
        return _scene_with(self._scene, camera=camera, width=width, height=height)

    def _apply(self, req: _Request):
        """Rebuild what the request needs (see the module docstring)."""
        if req.view is not None:
            self._view = req.view
        if req.scene is not None:
            # Kept until a rebuild succeeds: a scene that failed is rebuilt next time.
            self._scene = req.scene
            self._scene_dirty = True
            self._geometry_dirty = self._geometry_dirty or req.geometry
        scene = self.view_scene()
        scene.validate()
        ctx = self._ctx
        s = self.settings
        old_geo = None if ctx is None else ctx.geo
        # An empty scene is centred on the camera (engine.geometry.prepare): it follows
        # the view.
        empty = ctx is not None and ctx.geo.count == 0
        if self._scene_dirty or ctx is None or empty:
            self._photons.clear()
            same_names = (ctx is not None
                          and expanded_names(table_materials(scene)) == ctx.table.names)
            if self._geometry_dirty or not same_names or ctx is None or empty:
                geo, table = prepare(scene, self._cancel.is_set)
                self.counters.geometry_builds += 1
                self._event("geometry", geo.count)
                accel = ctx.accel if ctx is not None else None
                if accel is None or not _same_triangles(old_geo, geo):
                    if accel is not None:
                        accel.close(wait=True)
                    accel = VisibilityAccel(geo.vertices32, geo.faces32, geo.visibility,
                                            _accel_class(), threads=s.threads,
                                            should_cancel=self._cancel.is_set,
                                            instances=geo.instances)
                    self.counters.bvh_builds += 1
                    self._event("bvh", geo.count)
            else:
                geo, accel = ctx.geo, ctx.accel
                table = MaterialTable.build(table_materials(scene))
            attach_tracer(geo, accel)  # (Ambient Occlusion nodes trace from their hits)
            lights = prepare_lights(scene, geo, table)
            self.counters.light_builds += 1
            self._event("lights", len(lights))
            # The catchers-alone context of the last build, kept if its scene is the same.
            alone, alone_key = None, None
            if ctx is not None:
                alone, alone_key = ctx.catcher_alone, ctx.catcher_key
                ctx.catcher_alone = None
            if ctx is not None and ctx.links is not None:
                ctx.links.close(wait=True)
            self._ctx = ctx = Context(
                scene, s, geo, table, accel, lights, packed_lights=packed_lights_for(lights, s),
                shadow=ShadowTransmittance.for_scene(geo, table, s.transparent_max_bounces))
            # Light and Shadow Linking (engine/lightlinking.py), rebuilt with the lights.
            ctx.links = links_for(scene, lights, geo, accel, _accel_class(), s.threads,
                                  self._cancel.is_set)
            # Shadow catchers: the catchers-alone scene the camera pass compares with
            # (engine/shadowcatcher.py), rebuilt when the catchers, their materials, the
            # lights, the world or the settings changed (its digest: alone_key), kept
            # through edits of the other objects; it follows the view
            # (render._render_alone).
            ctx.catcher_objects = shadowcatcher.catcher_objects(scene)
            key = (shadowcatcher.alone_key(scene, s) if ctx.catcher_objects is not None
                   else None)
            if alone is not None and (key is None or key != alone_key):
                alone.accel.close(wait=True)
                alone = None
            if ctx.catcher_objects is not None:
                if alone is None:
                    alone = prepare_context(
                        shadowcatcher.alone_scene(scene), shadowcatcher.alone_settings(s),
                        _accel_class(), self._cancel.is_set)
                    self.counters.catcher_builds += 1
                    self._event("catchers alone", int(ctx.catcher_objects.sum()))
                ctx.catcher_alone, ctx.catcher_key = alone, key
            self._scene_dirty = self._geometry_dirty = False
        else:
            ctx.scene = scene
        # The view may have moved without a rebuild: Camera / Window coordinates follow it.
        set_camera_view(ctx.geo, scene)
        ctx.settings = s
        # (no clamp probe: the viewport shows no effect report)
        ctx.plan = analyse(scene, ctx.geo, ctx.table, ctx.lights, ctx.accel, s,
                           probe_clamp=False)
        key = _photon_plan_key(ctx.plan)
        if key != self._plan_key:
            self._photons.clear()
        self._plan_key = key

    def _check(self):
        if self._cancel.is_set():
            raise Cancelled()

    def _maps(self, i: int) -> dict:
        """Fill the context's photon maps for pass i (from the cache or shot now)."""
        ctx = self._ctx
        entry = self._photons.get(i)
        if entry is not None:
            for name, value in entry.maps.items():
                setattr(ctx, name, value)
            self.counters.photon_reuses += 1
            self._event("photons reused", i)
            return entry.stats
        stats = {}
        shoot_photons(ctx, stats, None, self._cancel.is_set)
        maps = {name: getattr(ctx, name) for name in _MAP_FIELDS}
        kept = {k: stats[k] for k in _PHOTON_STATS if k in stats}
        nbytes = int(stats.get("photon_bytes", 0))
        used = sum(e.nbytes for e in self._photons.values())
        if used + nbytes <= self.photon_cache_bytes:
            self._photons[i] = _PhotonEntry(maps, kept, nbytes)
        self.counters.photon_shots += 1
        self._event("photons shot", i)
        return kept

    def _render(self, generation: int):
        ctx = self._ctx
        s = self.settings
        scene = ctx.scene
        camera, W, H, region = self._view
        region = _check_region(region, W, H)
        check_resources(scene, s, region, progressive=True)
        x0, y0, x1, y1 = region
        merger = PassMerger(x1 - x0, y1 - y0)
        t0 = time.perf_counter()
        i = 0
        # One malloc setting over this view's passes and maps (engine/mallocheap.py):
        # the heaps a pass grew serve the next; trimmed once when they end or an edit
        # cancels them, not after every pass.
        with render_heap():
            while self.passes == 0 or i < self.passes:
                i += 1
                self._check()
                ctx.settings = pass_settings(s, i)
                photon_stats = self._maps(i)
                if i == 1:
                    for scale in self.preview_scales:
                        self._preview(scale, scene, region, photon_stats, t0, generation)
                film = render_pass(ctx, region, None, self._cancel.is_set, shoot=False)
                if film.stats.get("cancelled"):
                    raise Cancelled()
                film.stats.update(photon_stats)
                merger.add(film)
                self.counters.passes += 1
                done = self.passes > 0 and i >= self.passes
                self._publish(merger.film, region, (W, H), 1, i, merger.photons, t0, generation,
                              done)

    def _preview(self, scale, scene, region, photon_stats, t0, generation):
        W, H = scene.width, scene.height
        ws, hs = max(1, round(W / scale)), max(1, round(H / scale))
        if ws >= W and hs >= H:
            return
        x0, y0, x1, y1 = region
        sub = (int(x0 * ws / W), int(y0 * hs / H),
               max(int(x0 * ws / W) + 1, math.ceil(x1 * ws / W)),
               max(int(y0 * hs / H) + 1, math.ceil(y1 * hs / H)))
        sub = _check_region(sub, ws, hs)
        small = replace(self._ctx, scene=_scene_with(scene, width=ws, height=hs))
        self._check()
        film = render_pass(small, sub, None, self._cancel.is_set, shoot=False)
        if film.stats.get("cancelled"):
            raise Cancelled()
        self.counters.previews += 1
        self._event("preview", scale)
        covered = (sub[0] * W / ws, sub[1] * H / hs, sub[2] * W / ws, sub[3] * H / hs)
        photons = photon_stats.get("photons_emitted", 0) + photon_stats.get("caustic_photons_emitted", 0)
        self._publish(film, covered, (W, H), scale, 0, photons, t0, generation, False)

    def _publish(self, film, region, full_size, scale, passes, photons, t0, generation, done):
        rgb = film.combined
        alpha = film.alpha if self.settings.film_transparent else 1.0 - film.holdout
        rgba = np.concatenate([rgb, alpha[:, :, None].astype(np.float32)], axis=2)
        # Shadow catchers: Combined as Cycles' approximate shadow catcher (None: none).
        caught = shadowcatcher.combined_rgba(film, self.settings.film_transparent)
        rgba = rgba if caught is None else caught
        self.frame = Frame(rgba=rgba, region=tuple(region), full_size=tuple(full_size),
                           scale=scale, passes=passes, photons=int(photons),
                           elapsed=time.perf_counter() - t0, generation=generation,
                           done=done)


def _copy_scene(scene: Scene) -> Scene:
    """The scene with its own lists (the caller may go on editing its copy: meshes,
    materials and lights are replaced by the exporter, never changed in place)."""
    return _scene_with(scene, meshes=list(scene.meshes), materials=dict(scene.materials),
                       lights=list(scene.lights), warnings=list(scene.warnings))


def _scene_with(scene: Scene, **changes) -> Scene:
    """A plain Scene with the fields of `scene` (of any Scene subclass, whose own
    __init__ may add content) and the given changes."""
    kw = {f.name: getattr(scene, f.name) for f in fields(Scene)}
    kw.update(changes)
    return Scene(**kw)


def _same_triangles(a, b) -> bool:
    """The same triangles with the same ray visibility (the BVHs can be kept)."""
    return (a is not None and a.count == b.count
            and all(np.array_equal(getattr(a, n), getattr(b, n)) for n in ("v0", "e1", "e2"))
            and np.array_equal(a.visibility, b.visibility))


def _photon_plan_key(plan):
    """The parts of the effect plan the photon pass reads (none depends on the camera;
    compared anyway, so a plan that changed never reuses stale photons)."""
    return (plan.indirect, plan.caustics, plan.caustics_from_global,
            tuple(np.asarray(plan.caster_ids).tolist()), tuple(plan.rough_specular),
            tuple(np.asarray(plan.caster_spheres[1]).tolist()))


def _accel_class():
    from .accel import Accel
    return Accel
