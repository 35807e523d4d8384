"""render(): scene -> photon pass -> photon maps -> camera pass -> Film."""
from __future__ import annotations

import copy
import importlib
import math
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from . import adaptive, cryptomatte, lightgroups, panorama, shadowcatcher
from .accel import Accel
from .ambientocclusion import attach_tracer
from .chaincounts import DROP_BOUND_EXTRA, DROP_BOUND_LEVELS, GatherCounts
from .film import Film
from .effects import EffectPlan, analyse
from .geometry import Geometry, MaterialTable, area_sum, prepare, set_camera_view
from . import integrator as _integrator
from .integrator import MAX_GATHER_LEVEL, render_camera, smooth_min_photons, smooth_per_pixel
from .jit import ensure_compiled
from .lightlinking import links_for
from .lights import allocate_photons, light_census, prepare_lights
from .lights.base import InfiniteLight
from .lights import packing as pk
from .lights.packing import pack_lights
from .mallocheap import render_heap
from .edgeimages import edge_images
from .glossysplit import settings_filter_glossy, shots_unread
from .guiding import AUTO_GAIN, GatherGuide, can_guide
from .photonmap import GatherMap, PhotonMap, auto_radius, caustic_radius
from .rayoffset import G32_T, ulp32
from .sampling import luminance, max3
from .panelight import panes_for
from .mortontree import KthTree
from .parallel import POLL_SECONDS, Cancelled, run_cancellable, run_tasks, stop_array
from .photons import (CAUSTIC, CAUSTIC_DIFFUSE, DIRECT, INDIRECT, Photons, concat_surfaces,
                      concat_blur_pdfs, concat_radiances,
                      trace_photons)
from .resources import check_resources, held_bytes, regather_levels
from .scene import Scene
from .settings import ESTIMATOR_LABELS, RenderSettings
from .stagespans import StageSpans
from .heterogeneous import HeterogeneousMedia
from .shadowtransmittance import ShadowTransmittance
from .visibility import VisibilityAccel
from .visualimportance import (glow_and_secondary_shares, glow_share, indirect_share,
                               secondary_share)
from .volumeemission import glows


@dataclass
class Context:
    scene: Scene
    settings: RenderSettings
    geo: Geometry
    table: MaterialTable
    accel: VisibilityAccel
    lights: list
    global_map: PhotonMap | None = None
    caustic_map: PhotonMap | None = None
    # The glow shot's photons beside an aimed caustic map (GLOW_MAP_APART): their own
    # estimate, cap glow_radius (None: none, or held in caustic_map).
    glow_map: PhotonMap | None = None
    gather_map: GatherMap | None = None
    secondary_map: PhotonMap | None = None  # caustic light after one diffuse bounce
    # The maps final gathering's regathers read at level 1, 2, ... (integrator._regather):
    # their points are that many diffuse bounces deeper, so under the bounce limits they
    # hold fewer photons (docs/design.md, Bounce limits); the same objects as gather_map
    # / secondary_map where the limits leave every photon; a regather map is gather_map's
    # subset map (GatherMap.subset_maps: the same points, that level's photons' irradiance).
    regather_maps: tuple = ()
    regather_secondary: tuple = ()
    # The gather map's photons' bounce counts and power: which lookups after a specular
    # chain its precomputed irradiance cannot serve (chaincounts.GatherCounts; None: no
    # final gathering).
    gather_counts: object = None
    gather_short: float = 0.0  # gather rays shorter than this gather again from their end
    plan: EffectPlan | None = None
    global_radius: float = 0.0
    secondary_radius: float = 0.0  # search radius of the secondary map (its own spacing)
    caustic_radius: float = 0.0
    glow_radius: float = 0.0  # glow_map's cap (glow_radius)
    # visualimportance.Region of an aimed global shot lit by a light at infinity (None:
    # the shot is natural, or no such light): the global radius is taken from the
    # photons inside it (_build_maps, global_emitters).
    importance_region: object = None
    # The pre-pass' lookups (visualimportance.lookup_points, (N,3)) where visual
    # importance traced them for this pass (global_emitters), else None: lookup_radius
    # reads them instead of tracing them again.
    lookups: np.ndarray | None = None
    # Final-gather rays per camera sample of the camera pass (0: settings.gather_rays),
    # chosen after the photon pass (gather_count)
    gather_rays: int = 0
    # Samples a pixel taking the glow-only caustic map's and the secondary map's estimates
    # (0: integrator's constants), chosen after the photon pass (smooth_counts)
    glow_per_pixel: int = 0
    secondary_per_pixel: int = 0
    packed_lights: tuple | None = None  # lights as the direct-light kernels read them
    shadow: ShadowTransmittance | None = None  # transparent shadows (None: none in the scene)
    # Light trees for many lights (engine/lights/selection.py selector_for), built on use.
    light_selectors: dict = field(default_factory=dict)
    # Adaptive sampling (engine/adaptive.py): the samples per pixel of the camera round
    # being rendered (0: the camera pass takes every pixel's spp at once). The smooth
    # estimates weigh their samples by it (integrator._smooth_estimate).
    camera_round: int = 0
    # The adaptive round being rendered (0: the first, or no rounds): the data passes
    # Cycles writes from a pixel's first sample are written in round 0 only.
    camera_round_index: int = 0
    # Shadow catchers (engine/shadowcatcher.py): (O,) bool over the objects (None: none),
    # and the context of the scene with only them, which the camera pass' catcher samples
    # are measured against (its settings set per pass by _render_pass).
    catcher_objects: np.ndarray | None = None
    catcher_alone: "Context | None" = None
    # What catcher_alone was built from (shadowcatcher.alone_key): a viewport session keeps
    # it through edits that leave it unchanged.
    catcher_key: str | None = None
    # Light Linking (engine/lightlinking.py): which light lights which object (None: every
    # light lights every object).
    links: object = None
    # Heterogeneous media (engine/heterogeneous.py: density textures; None: none).
    hetero: object = None
    # Light groups' contexts kept between passes (render_progressive: {name: Context});
    # None: each group's context is built and closed within its pass (_render_light_groups).
    light_group_contexts: dict | None = None


    def serial(self) -> "Context":
        """This context with every Embree and kd-tree query answered on the calling
        thread, for chunks that already run on worker threads (engine/parallel.py)."""
        def one(m):
            return None if m is None else m.serial()
        return replace(self, accel=self.accel.serial(), global_map=one(self.global_map),
                       caustic_map=one(self.caustic_map), glow_map=one(self.glow_map),
                       gather_map=one(self.gather_map),
                       secondary_map=one(self.secondary_map),
                       regather_maps=tuple(one(m) for m in self.regather_maps),
                       regather_secondary=tuple(one(m) for m in self.regather_secondary))


# The Context attributes that hold a photon pass' maps (held_bytes counts them).
MAP_FIELDS = ("global_map", "caustic_map", "glow_map", "gather_map", "secondary_map",
              "regather_maps", "regather_secondary", "gather_counts")


def _check_region(region, width, height):
    if region is None:
        return (0, 0, width, height)
    try:
        x0, y0, x1, y1 = (int(v) for v in region)
    except (TypeError, ValueError):
        raise ValueError(f"region must be (x0, y0, x1, y1) pixels, got {region!r}") from None
    x0, x1 = max(0, min(x0, width)), max(0, min(x1, width))
    y0, y1 = max(0, min(y0, height)), max(0, min(y1, height))
    if x1 <= x0 or y1 <= y0:
        raise ValueError(f"region {region!r} is empty inside the {width}x{height} image")
    return (x0, y0, x1, y1)


def prepare_context(scene: Scene, settings: RenderSettings, accel_class=Accel,
                    should_cancel=None) -> Context:
    """Validate the scene, merge and re-centre geometry, build the BVH, prepare lights and
    decide which effects to simulate. One Context serves several passes. accel_class lets
    the benchmarks record every ray query (bench/). should_cancel() is asked between the
    pieces of the geometry preparation and the BVH build: raises Cancelled."""
    scene.validate()
    geo, table = prepare(scene, should_cancel)
    # Density textures (engine/heterogeneous.py): the table's rows become the mean
    # density's stand-in before anything reads them.
    hetero = HeterogeneousMedia.for_scene(geo, table, settings.seed)
    # One BVH per distinct set of triangles a ray class sees (usually one in all).
    accel = VisibilityAccel(geo.vertices32, geo.faces32, geo.visibility, accel_class,
                            threads=settings.threads, should_cancel=should_cancel,
                            instances=geo.instances)
    attach_tracer(geo, accel)  # (Ambient Occlusion nodes trace from their hits)
    shadow = ShadowTransmittance.for_scene(geo, table, settings.transparent_max_bounces)
    lights = prepare_lights(scene, geo, table,
                            gathered=bool(settings.photon_mapping and settings.final_gather))
    # Light and Shadow Linking (engine/lightlinking.py): the shadow groups' BVHs are
    # built from the build arrays, before they go.
    links = links_for(scene, lights, geo, accel, accel_class, settings.threads, should_cancel)
    if shadow is None:
        # Embree holds its own copy; transparent shadows build their BVHs from them lazily.
        geo.release_build_arrays()
    ctx = Context(scene, settings, geo, table, accel, lights,
                  packed_lights=packed_lights_for(lights, settings), shadow=shadow)
    ctx.links = links
    ctx.hetero = hetero
    if shadow is not None and hetero is not None and hetero.fields:
        shadow.hetero = hetero  # (its shadow rays' transmittance: transmittance())
    ctx.plan = analyse(scene, geo, table, lights, accel, settings)
    if hetero is not None and hetero.fields:
        ctx.plan.add("heterogeneous media", True, hetero.describe())
    if geo.instances is not None:  # which way instancing went (engine/resources.py)
        from .resources import instance_choice
        ins = geo.instances
        two, why = instance_choice(ins.instanced_triangles(),
                                   sum(len(f) for _, f in ins.prototypes))
        ctx.plan.add("shared instances", bool(ins.two_level), why)
    ctx.catcher_objects = shadowcatcher.catcher_objects(scene)
    if ctx.catcher_objects is not None:
        try:
            ctx.catcher_alone = prepare_context(shadowcatcher.alone_scene(scene),
                                                shadowcatcher.alone_settings(settings),
                                                accel_class, should_cancel)
        except BaseException:
            ctx.accel.close()
            raise
        n = int(ctx.catcher_objects.sum())
        ctx.plan.add("shadow catcher", True,
                     f"{n} shadow catcher object{'s' if n > 1 else ''}: the camera sees "
                     "on them only the shadows the other objects cast (a second photon "
                     "and camera pass renders the catchers alone to compare)")
    return ctx


def close_context(ctx: Context) -> None:
    """Release ctx's Embree scenes (and its catcher-only context's)."""
    ctx.accel.close()
    if ctx.links is not None:
        ctx.links.close()
    if ctx.catcher_alone is not None:
        ctx.catcher_alone.accel.close()
    for group in (ctx.light_group_contexts or {}).values():
        close_context(group)
    if getattr(ctx.hetero, "accel", None) is not None:
        ctx.hetero.accel.close()  # (the textured media's boundaries: heterogeneous.py)


def _sample_every_side(lights) -> bool:
    """Shadow rays to every side of the emissive meshes, whatever their Emission Sampling
    (MeshLight.tri_sides), when nothing gathers the sides they leave out (no gather map:
    final gathering or indirect light off, or no photon to gather): True if a mesh
    light changed (its light tree is rebuilt). Emission Sampling changes only noise in
    Cycles; here it must not drop light either."""
    changed = False
    for light in lights:
        if light.kind == "MESH" and light.tri_sides is not None and (light.sides() != 3).any():
            light.tri_sides = None
            light.__dict__.pop("_triangle_tree", None)
            changed = True
    return changed


def packed_lights_for(lights, settings: RenderSettings):
    """The lights packed for the shadow-ray kernels (lights.packing.pack_lights), as
    points when soft shadows are off (hard_shadow_packing)."""
    packed = pack_lights(lights)
    return hard_shadow_packing(packed) if settings.soft_shadows == "off" else packed


def hard_shadow_packing(packed):
    """Soft shadows off: every light with a size packed as a point at its centre, so
    its one shadow ray per sample always aims there and shadows are hard (the paper's
    point-light shadows). Flux and emission profile are kept: an area light stays a
    one-sided cosine emitter of radiance x area (its kernel samples the centre of a
    0 x 0 rectangle), a point / spot light of radius r becomes radius 0, and each
    emitting triangle is sampled at its centroid. Photons still leave the whole light.
    packed: (codes, params, mesh arrays) of lights.packing.pack_lights; returns a copy."""
    codes, params, mesh = packed
    params = params.copy()
    area = codes == pk.CODE_AREA
    params[area, pk.SIZE_X] = params[area, pk.SIZE_Y] = 0.0
    params[area, pk.SPREAD_RECT] = 0.0  # the spread-cropped rectangle samples its window
    params[(codes == pk.CODE_POINT) | (codes == pk.CODE_SPOT), pk.RADIUS] = 0.0
    v0, e1, e2, *rest = mesh
    centroid = v0 + (e1 + e2) / 3.0
    return codes, params, (centroid, np.zeros_like(e1), np.zeros_like(e2), *rest)


def shoot_photons(ctx: Context, stats: dict, progress=None, should_cancel=None,
                  on_warning=None, on_plan=None) -> tuple:
    """The photon pass alone: (re)fills ctx's photon maps for ctx.settings and records
    its counts in stats. Returns the stored photons (for the photon-hit pass) as a tuple
    of Photons, one per shot (global, caustic; global, glow, caustic where the glow shot
    makes a map of its own, GLOW_MAP_APART; empty without photon mapping). Its
    warnings (a hand-set search radius that does wrong: radius_warnings) go into
    stats["warnings"] and, as soon as the maps are built, to on_warning(text) (None:
    nowhere), on the calling thread, before the camera pass. Raises
    Cancelled. A session may keep the maps of a pass and render other views from them
    (engine/session.py): with visual importance the global photons are denser where this
    camera looks (engine/visualimportance.py), but every view's estimates stay unbiased.
    on_plan({"photons": n}) is told, before the first photon is traced, how many photons
    the pass will emit over all its shots (global, glow, caustic: the effect analysis
    decides which; 0 when it leaves the photon pass out), so a progress bar can size
    the photon stage (None: nobody); told again after the global shot where it finds
    the caustic / glow shots read after all (_photon_pass, maps_unread)."""
    ctx.global_map = ctx.caustic_map = ctx.gather_map = ctx.secondary_map = None
    ctx.glow_map = None
    ctx.regather_maps = ctx.regather_secondary = ()
    ctx.gather_counts = None
    ctx.gather_rays = ctx.glow_per_pixel = ctx.secondary_per_pixel = 0
    s = ctx.settings
    shot = ()
    if s.photon_mapping and ctx.lights and (ctx.plan.indirect or ctx.plan.caustics):
        shot = _photon_pass(ctx, stats, progress, should_cancel, on_warning, on_plan)
    elif on_plan is not None:  # no photon pass after all: the bar's span goes to pixels
        on_plan({"photons": 0})
    if ctx.gather_map is None and _sample_every_side(ctx.lights):
        # No final gathering (off, indirect light off, or no photon to gather): no
        # gather ray brings the unsampled sides' direct light to a diffuse surface.
        ctx.packed_lights = packed_lights_for(ctx.lights, s)
        getattr(ctx, "light_selectors", {}).clear()
    return shot


def render_pass(ctx: Context, region, progress=None, should_cancel=None,
                shoot: bool = True, on_warning=None, on_plan=None) -> Film:
    """Photon pass + camera pass with ctx.settings into a new Film (raises Cancelled).
    shoot=False renders with the photon maps already in ctx (shoot_photons). The photon
    pass' warnings are in film.stats["warnings"] and told to on_warning(text) when known,
    before the camera pass (shoot_photons), as the photon count to on_plan. numpy's
    huge-page advice is off meanwhile (small_pages), and glibc's malloc keeps the worker
    threads' heaps (engine/mallocheap.py)."""
    with small_pages(), render_heap():
        return _render_pass(ctx, region, progress, should_cancel, shoot, on_warning, on_plan)


def _render_pass(ctx: Context, region, progress, should_cancel, shoot: bool,
                 on_warning, on_plan=None) -> Film:
    settings = ctx.settings
    x0, y0, x1, y1 = region
    film = Film(x1 - x0, y1 - y0, show_photons=settings.show_photons)
    stats = film.stats
    stats["cancelled"] = False
    # Compiled kernels: compiled on the first render on this machine (the progress text
    # says so), loaded from the on-disk cache by later processes, once per process.
    stats["time_compile"] = ensure_compiled(progress)
    if ctx.hetero is not None:
        stats.setdefault("warnings", []).extend(ctx.hetero.limits(settings))
    try:
        shots = ()
        if ctx.catcher_alone is not None and on_plan is not None:
            on_plan({"catcher_pass": True})  # (its span on the bar: stagespans)
        if settings.light_groups and on_plan is not None:
            on_plan({"light_groups": sum(lightgroups.members(ctx.scene, name) > 0
                                         for name in settings.light_groups)})
        if shoot:
            # The photon-hit view reads the photons' places and kinds alone: the shots'
            # other arrays (power, directions, normals, counts, surfaces: 44 B a photon,
            # 48 with Filter Glossy's reverse pdfs; the maps hold their own copies) are
            # let go before the camera pass (Figure 6: -33 MB of its peak,
            # docs/performance.md, mem45).
            shots = tuple((ph.position, ph.kind) for ph in
                          shoot_photons(ctx, stats, progress, should_cancel, on_warning,
                                        on_plan))
        # The photon-hit view's dots (at most photon_hit_budget of the image) picked as the
        # camera pass starts: with several workers on a thread of their own beside its
        # first chunks (0.05-0.15 CPU s on Figure 6's 0.9 M photons), else now. The
        # shots' positions and kinds (13 B a stored photon) go once they are picked, not
        # held through the camera pass, and the projection's float64 copy (24 B a photon)
        # is no longer made at its end, the render's peak (docs/performance.md "perf47").
        picked = _side_job(partial(_photon_hit_dots, ctx, shots, region),
                           settings.threads > 1)
        shots = None
        if settings.threads > 1:
            picked.start()
        else:
            picked()
        # The photon-hit pass, always: with several workers on its own thread, started
        # when the camera pass's last chunk is handed out (it fills a worker the tail
        # leaves idle, when fewer chunks hold memory), else after the camera pass; its
        # view is written to the film once the camera pass ends.
        hits = _side_job(lambda: _photon_hit_draw(ctx, *picked(), region, film.width,
                                                  film.height), settings.threads > 1)
        try:
            t0 = time.perf_counter()
            cam = ctx
            if ctx.gather_rays and ctx.gather_rays != settings.gather_rays:
                cam = replace(ctx, settings=replace(settings, gather_rays=ctx.gather_rays))
            counters = render_camera(cam, region, film, progress, should_cancel,
                                     on_tail=hits.start)
            stats["time_camera"] = time.perf_counter() - t0
            stats.update(camera_rays=counters.camera_rays, shadow_rays=counters.shadow_rays,
                         gather_rays=counters.gather_rays,
                         specular_rays=counters.specular_rays,
                         ray_stages=counters.stage_table())
            behind = sum(v for k, v in counters.stages.items()
                         if k[0] == "catcher behind transparent")
            if behind:
                stats.setdefault("warnings", []).append(
                    shadowcatcher.behind_transparent_warning(ctx, behind))
            view, shown, fraction = hits()
        finally:
            hits.join()
            picked.join()
        if view is not None:
            film.photon_hits[...] = view
        stats["photon_hits_shown"] = shown
        stats["photon_hits_fraction"] = fraction
        if ctx.catcher_alone is not None:
            _render_alone(ctx, region, film, progress, should_cancel)
        if settings.light_groups:
            _render_light_groups(ctx, region, film, progress, should_cancel)
    except Cancelled:
        stats["cancelled"] = True  # the film holds what was finished
    return film


def _render_alone(ctx: Context, region, film: Film, progress, should_cancel) -> None:
    """The catcher-only scene's photon and camera pass with this pass' settings (its
    seed, photon counts), recorded in film.catcher (engine/shadowcatcher.py); raises
    Cancelled."""
    t0 = time.perf_counter()
    alone = ctx.catcher_alone
    alone.settings = shadowcatcher.alone_settings(ctx.settings)
    scene = ctx.scene
    if (alone.scene.camera is not scene.camera or alone.scene.width != scene.width
            or alone.scene.height != scene.height):
        # The main scene's view (a viewport session's moved camera, its small previews).
        alone.scene = replace(alone.scene, camera=scene.camera, width=scene.width,
                              height=scene.height)
        set_camera_view(alone.geo, alone.scene)
        # (The effect analysis looks from the camera: where the photons are aimed.)
        alone.plan = analyse(alone.scene, alone.geo, alone.table, alone.lights, alone.accel,
                             alone.settings)

    # (A stage of its own: the progress bars' photon and render spans are the main
    # pass', which this one would run back over; its own stages placed within it.)
    x0, y0, x1, y1 = region
    inner = StageSpans(alone.settings.uses_photon_maps,
                       alone.settings.photons + alone.settings.caustic_photons,
                       max((x1 - x0) * (y1 - y0), 1) * alone.settings.spp)

    def told(stage, fraction, text):
        if progress is not None:
            whole = inner.whole(stage, fraction)
            progress("shadow catcher", fraction if whole is None else whole,
                     f"Shadow catcher: {text}")

    one = _render_pass(alone, region, told, should_cancel, True, None, inner.plan)
    if one.stats.get("cancelled"):
        raise Cancelled()
    shadowcatcher.add_alone(film, one)
    film.stats["time_shadow_catcher"] = time.perf_counter() - t0


def _render_light_groups(ctx: Context, region, film: Film, progress, should_cancel) -> None:
    """Each light group's render (engine/lightgroups.py): a photon and camera pass of the
    scene with only the group's emitters, its Combined into film.data; raises
    Cancelled. A group without emitters is black without a render. Its context is built
    for the pass and closed after it, or kept in ctx.light_group_contexts when that is a
    dict (progressive passes: built once)."""
    t0 = time.perf_counter()
    x0, y0, x1, y1 = region
    settings = lightgroups.group_settings(ctx.settings)
    names = ctx.settings.light_groups
    live = [name for name in names if lightgroups.members(ctx.scene, name) > 0]
    for name in names:
        if name not in live:
            film.data[lightgroups.key(name)] = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
    for i, name in enumerate(live):
        inner = StageSpans(settings.uses_photon_maps,
                           settings.photons + settings.caustic_photons,
                           max((x1 - x0) * (y1 - y0), 1) * settings.spp)

        def told(stage, fraction, text, _i=i, _name=name, _inner=inner):
            if progress is not None:
                whole = _inner.whole(stage, fraction)
                progress("light groups", (_i + (fraction if whole is None else whole))
                         / len(live), f"Light group '{_name}': {text}")

        kept = ctx.light_group_contexts
        group = None if kept is None else kept.get(name)
        if group is None:
            group = prepare_context(lightgroups.group_scene(ctx.scene, name), settings,
                                    should_cancel=should_cancel)
            if kept is not None:
                kept[name] = group
        group.settings = settings  # (this pass' seed and photon counts)
        try:
            one = _render_pass(group, region, told, should_cancel, True, None, inner.plan)
        finally:
            if kept is None:
                close_context(group)
        if one.stats.get("cancelled"):
            raise Cancelled()
        film.data[lightgroups.key(name)] = one.combined
    film.stats["time_light_groups"] = time.perf_counter() - t0


class _side_job:
    """fn() on a thread of its own (threaded=True) from start() on; calling the object
    returns its result (re-raising its error), starting it first if need be, after
    waiting for it; join() waits without raising (always call it). threaded=False: start()
    does nothing and fn runs on the first call, inline. fn runs once; it is let go after
    (with whatever its arguments hold), its result kept."""

    def __init__(self, fn, threaded: bool):
        self._fn, self._result, self._error, self._thread = fn, None, None, None
        self._threaded = threaded

    def start(self):
        if self._threaded and self._thread is None:
            self._thread = threading.Thread(target=self._run, daemon=True,
                                            name="photon-hit view")
            self._thread.start()

    def _run(self):
        try:
            self._result = self._fn()
        except BaseException as e:  # re-raised on the calling thread
            self._error = e
        finally:
            self._fn = None  # (what fn's arguments hold goes with it)

    def __call__(self):
        if not self._threaded:
            if self._fn is not None:  # (run once; its result kept)
                self._result, self._fn = self._fn(), None
            return self._result
        self.start()
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._result

    def join(self):
        if self._thread is not None:
            self._thread.join()


def _madvise_hugepage_setter():
    """numpy's switch for asking Linux for transparent huge pages on large arrays
    (_set_madvise_hugepage(on) -> the previous setting), or None."""
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            fn = getattr(importlib.import_module(name), "_set_madvise_hugepage", None)
        except ImportError:
            continue
        if fn is not None:
            return fn
    return None


_PAGES_LOCK = threading.Lock()
_PAGES = {"users": 0, "before": None}


@contextmanager
def small_pages():
    """numpy's huge-page advice off while a render runs (restored when the last
    overlapping render ends). numpy madvises every array of >= 4 MB for transparent huge
    pages; where Linux's THP defrag setting is "madvise" (a common default) each first
    touch of such an array may stall in direct memory compaction. The passes allocate
    arrays of tens of MB per chunk: measured on this 2-core machine under load, 0.7-1.4 of
    a Figure 7 render's ~10 CPU s went to the kernel that way (docs/performance.md,
    "Camera pass: reference counts, huge pages"). Only where memory comes from changes,
    never a value: images are bitwise the same. A no-op where numpy has no such switch."""
    setter = _madvise_hugepage_setter()
    if setter is None:
        yield
        return
    with _PAGES_LOCK:
        if _PAGES["users"] == 0:
            _PAGES["before"] = setter(False)
        _PAGES["users"] += 1
    try:
        yield
    finally:
        with _PAGES_LOCK:
            _PAGES["users"] -= 1
            if _PAGES["users"] == 0:
                setter(_PAGES["before"])


def warning_teller(on_warning):
    """tell(warnings): each warning not told before (by warning_key) to on_warning(text)
    (None: nothing), so a front end can print a render's warnings when they arise, once
    each (engine/cli.py, addon/engine.py) while film.warnings still lists them all at the
    end. tell(warnings) returns those of `warnings` it took as new, in order."""
    told = set()

    def tell(warnings):
        new = []
        for w in warnings:
            key = warning_key(w)
            if key not in told:
                told.add(key)
                new.append(w)
                if on_warning is not None:
                    on_warning(w)
        return new
    return tell


def warning_key(text: str) -> str:
    """What makes a warning the same as another for telling it once: its text; for a
    search-radius warning (radius_warnings) the words before its numbers in brackets.
    Each progressive pass (engine/progressive.py, engine/distributed.py) stores its own
    photons, so its 'below the photon spacing' warning gives another count and spacing:
    the same advice, said once (the first pass's words)."""
    if text.startswith(RADIUS_WARNING_START):
        return text.split(" (", 1)[0]
    return text


def render(scene: Scene, settings: RenderSettings | None = None, progress=None,
           should_cancel=None, region=None, on_warning=None, on_plan=None) -> Film:
    """Render `scene`. progress(stage, fraction, text) is called as work advances;
    should_cancel() is polled and, when it returns True, the partial Film is returned
    with film.stats['cancelled'] = True. region=(x0, y0, x1, y1) renders only that window
    (top-left origin, exclusive max) and the Film has its size. on_warning(text) is told
    each of film.warnings once, on the calling thread, as soon as the render knows it:
    the scene's at the start, the effect analysis' before the photons are shot, the
    photon pass' (a hand-set search radius) once its maps are built, before the camera
    pass. on_plan({"photons": n}) is told the photons the photon pass will emit, before
    it traces any (shoot_photons; not called without a photon pass), so a progress bar
    can size its photon stage (engine/stagespans.py). Raises SceneError for a scene that cannot render, ResourceError
    (engine/resources.py) for one that would not fit in the available memory - both
    before anything big is allocated."""
    settings = settings or RenderSettings()
    t_start = time.perf_counter()
    scene.validate()
    region = _check_region(region, scene.width, scene.height)
    check_resources(scene, settings, region)
    tell = warning_teller(on_warning)
    tell(scene.all_warnings())
    # The kernels load (or compile) before the preparation: their first use would
    # otherwise load them inside a step that polls should_cancel rarely (the effect
    # analysis' probe rays: 1.3 s).
    t_compile = ensure_compiled(progress)
    try:
        ctx = prepare_context(scene, settings, should_cancel=should_cancel)
    except Cancelled:
        # Cancelled before any pixel: an empty film, marked as cancelled.
        x0, y0, x1, y1 = region
        film = Film(x1 - x0, y1 - y0, show_photons=settings.show_photons)
        film.stats.update(cancelled=True, time_compile=t_compile,
                          time_prepare=time.perf_counter() - t_start,
                          time_total=time.perf_counter() - t_start)
        film.warnings = scene.all_warnings()
        tell(film.warnings)
        return film
    # Said before the long passes, with the scene's and the effect analysis'.
    early = adaptive.schedule_warnings(settings.adaptive_threshold,
                                       settings.adaptive_min_samples, settings.spp)
    tell(scene.all_warnings() + ctx.plan.warnings + early)
    t_prepare = time.perf_counter() - t_start - t_compile
    try:
        # One malloc setting over the pass and the mattes: trimmed once, at their end.
        with render_heap():
            film = render_pass(ctx, region, progress, should_cancel,
                               on_warning=lambda w: tell([w]),  # the photon pass' own
                               on_plan=on_plan)
            if settings.cryptomatte and not film.stats.get("cancelled"):
                render_cryptomatte(ctx, region, film, should_cancel)
    finally:
        close_context(ctx)
    film.stats["time_compile"] += t_compile
    from .effects import shot_words
    film.stats.update(effects=shot_words(ctx.plan.report(), film.stats) + photon_map_report(
        settings, film.stats, glow_only=ctx.plan.caustics_glow_only,
        glow_words=ctx.plan.glow_words),
                      triangles=ctx.geo.count, lights=len(ctx.lights),
                      light_census=light_census(ctx.lights, ctx.scene),
                      extent=ctx.geo.extent, time_prepare=t_prepare,
                      time_total=time.perf_counter() - t_start)
    film.warnings = (scene.all_warnings() + ctx.plan.warnings + early
                     + film.stats.get("warnings", []))
    tell(film.warnings)
    return film


def render_cryptomatte(ctx: Context, region, film: Film, should_cancel) -> None:
    """The Cryptomatte passes the settings ask for into film (engine/cryptomatte.py);
    a cancel leaves them out and marks the film cancelled."""
    s = ctx.settings
    t0 = time.perf_counter()
    try:
        film.cryptomatte = cryptomatte.render_mattes(ctx, region, s.cryptomatte,
                                                     s.cryptomatte_levels, s.spp, s.seed,
                                                     should_cancel)
    except Cancelled:
        film.stats["cancelled"] = True
        return
    film.cryptomatte_names = {k: cryptomatte.layer_names(ctx.scene, k) for k in film.cryptomatte}
    film.stats["time_cryptomatte"] = time.perf_counter() - t0


def _drop_bound_masks(shot, limits, gathered, masks, level_of) -> dict:
    """{(level, extra): (N,) bool} over the shot's photons, for the levels below
    chaincounts.DROP_BOUND_LEVELS and extra 1..chaincounts.DROP_BOUND_EXTRA: the photons of that level's map (gathered
    at level 0, else its subset mask masks[level_of[level - 1]], or gathered at -1: the
    map render.level_maps gives the level) that a lookup with camera counts (level + 1 +
    e_total, level + 1, e_glossy, e_transmission), each e at most extra, may drop: those
    not usable at (level + 1 + extra, level + 1, extra, extra). Usability only falls as
    counts grow, so that set holds every photon such a lookup drops
    (chaincounts.may_drop)."""
    out = {}
    for level in range(min(DROP_BOUND_LEVELS, MAX_GATHER_LEVEL + 1)):
        i = level_of[level - 1] if level else -1
        kept = gathered if i < 0 else masks[i]
        for extra in range(1, DROP_BOUND_EXTRA + 1):
            ok = shot.usable(limits, camera=(level + 1 + extra, level + 1, extra, extra))
            out[(level, extra)] = kept & ~ok
    return out


def _gather_masks(shot, limits, gathered, bounded: bool, stop=None) -> tuple:
    """The gather map's masks over the shot's photons (N,) bool, for _build_maps's gather
    chain: (subsets, level_of, secondary, secondary_of, drop_bounds).

    The regathers' maps, level by level: where the limits drop photons the level above
    keeps, the level-0 map's irradiance from those photons alone at the same gather
    points (GatherMap subsets: the points' estimates again, not a whole map; whole maps
    per level doubled Figure 6's map build). Every level whose limits drop any photon's
    light the level above keeps gets its subset, however small the dropped share of the
    whole shot's power: the deep photons gather where the light is trapped, not evenly.
    A house on a sunlit lawn (issue 14, bounces4) dropped 0.03 % of the shot's power at
    level 1, nearly all of it inside the house, whose back wall read 1.23-1.31x Cycles at
    Diffuse 4 while its regathers read the level-0 map (the share threshold this
    replaced, 0.5 %). A subset costs no search of its own (the masks of one pass,
    GatherMap): map build CPU the same within 3 % (docs/performance.md, bounces4).
    level_of[L - 1]: the subset index of level L (-1: the level-0 map's photons).

    The secondary-caustic (CAUSTIC_DIFFUSE) share of each regathering level's points,
    from the same searches: a regathered end adds it back from its lookup's point
    (integrator._secondary_irradiance) instead of a k-NN estimate of the secondary map
    (docs/performance.md, regather29). Level L's ends are L + 1 diffuse bounces from the
    camera's hit: the photons of regather_secondary[L] (other_maps). secondary: the
    distinct masks; secondary_of: each level's index into them.

    drop_bounds: _drop_bound_masks's where bounded (render.regather_levels), else None.
    stop: unused (a run_tasks step)."""
    subsets, level_of = [], []
    last = gathered
    power = shot.power.astype(np.float64).sum(axis=1) * (shot.kind != CAUSTIC)
    for level in range(1, MAX_GATHER_LEVEL + 1):
        ok = shot.usable(limits, camera=(level + 1, level + 1, 0, 0))
        if np.any(last & ~ok & (power != 0.0)):
            subsets.append(ok)
            last = ok
        level_of.append(len(subsets) - 1)
    del power
    secondary, secondary_of = [], []
    if _integrator.SECONDARY_FROM_GATHER_POINTS:
        for level in range(MAX_GATHER_LEVEL):
            mask = (shot.kind == CAUSTIC_DIFFUSE) & shot.usable(
                limits, camera=(level + 1, level + 1, 0, 0))
            same = [i for i, m in enumerate(secondary) if np.array_equal(m, mask)]
            secondary_of.append(same[0] if same else len(secondary))
            if not same:
                secondary.append(mask)
    drop_bounds = (_drop_bound_masks(shot, limits, gathered, subsets, level_of)
                   if bounded else None)
    return subsets, level_of, secondary, secondary_of, drop_bounds


def level_maps(gather_map: GatherMap, level_of: list, secondary_of: list) -> tuple:
    """The map each regathering level reads (render context's regather_maps), with each
    level's secondary-caustic share set (GatherMap.secondary_E).

    level_of: per level 1..MAX_GATHER_LEVEL the index of its subset map in
    gather_map.subset_maps, -1 for the level-0 map itself; secondary_of: per regathering
    level 0..MAX_GATHER_LEVEL - 1 the index of its share in gather_map.secondary_levels
    ([] without). Returns a tuple of len(level_of) maps (views where two levels share a
    map but not its share). A map without points (fewer than two non-caustic photons, or
    all of them points: GatherMap's early return) has no subset maps and no shares: it
    serves every level as it is and its lookups find nothing (indexing its empty lists
    raised IndexError on a shot whose only usable photons were caustic ones: feature
    case visibility_light_diffuse_off at seed 2, one caustic photon stored)."""
    empty = gather_map.tree is None
    deeper = [gather_map if i < 0 or empty else gather_map.subset_maps[i] for i in level_of]
    for level in range(0 if empty else len(secondary_of)):  # (the levels that regather)
        share = gather_map.secondary_levels[secondary_of[level]]
        view = gather_map if level == 0 else deeper[level - 1]
        if view.secondary_E is not None and view.secondary_E is not share:
            # (levels that share a map but not its secondary share: a view each)
            deeper[level - 1] = view = copy.copy(view)
        view.secondary_E = share
    return tuple(deeper)


def _shot_progress(progress, sizes, k):
    """The progress callback for shot k of a photon pass whose shots emit sizes (global,
    glow, caustic; 0: not traced) photons: the shot's own fraction placed after the shots
    before it, as a fraction of the whole pass (at most 1: a caustic shot's allocation may
    differ from its planned size by rounding). None without a progress callback."""
    if progress is None:
        return None
    total = max(sum(sizes), 1)
    before, size = sum(sizes[:k]), sizes[k]

    def report(stage, fraction, text):
        progress(stage, min((before + fraction * size) / total, 1.0), text)
    return report


def _photon_pass(ctx: Context, stats, progress, should_cancel, on_warning=None,
                 on_plan=None) -> tuple:
    s, geo, plan = ctx.settings, ctx.geo, ctx.plan
    t0 = time.perf_counter()
    shot = Photons.empty()
    use_caustic_shot = plan.caustics and s.caustic_photons > 0 and not plan.caustics_from_global
    targets = (plan.caster_spheres if (use_caustic_shot and s.aim_caustics
                                       and len(plan.caster_spheres[1])) else None)
    # Aimed caustic photons keep only the L S+ D paths whose first hit is a caster; the
    # global shot keeps the others (light by way of rough specular surfaces first, which
    # is not aimed at: engine/effects.py, sharp_specular), so together they hold each
    # path once (trace_photons, first_hit). Without rough specular surfaces there is no
    # such path worth the split (the photons are as before).
    split = None
    if targets is not None and plan.rough_specular:
        split = np.zeros(len(geo.object_names), bool)
        split[plan.caster_ids] = True
    # The global shot is needed for indirect light; without a separate caustic shot, or
    # for the caustic paths the aimed shot leaves out, it also carries caustic photons.
    glow = None
    # The shots' sizes first, so the progress moves through the whole pass once (the glow
    # shot, up to GLOW_SPLIT x the global one, parked the bar at the end of its photon
    # span with no estimate: newuser33).
    global_shot = plan.indirect or (plan.caustics and not use_caustic_shot) or split is not None
    # Filter Glossy's split (engine/glossysplit.py) above 1/pi with only matte diffuse
    # surfaces: no caustic or glow photon is read anywhere (every estimate left out
    # whole), so those shots are not traced where the gather map that carries their light
    # is built (its photons known after the global shot; docs/compatibility.md
    # "splitmaps47": 3.1 of 67 CPU s on newuser44's table).
    unread = SKIP_UNREAD_SHOTS and global_shot and shots_unread(s, geo, ctx.table,
                                                                plan.indirect)
    emitters = counts = g_emitters = g_counts = pre_radius = None
    camera_map_radius = [None]  # (without final gathering: _camera_map_radius's)
    known_secondary = None  # (radius, the secondary share there) measured with the glow's
    if global_shot:
        # (n: settings.photons, fewer where a pilot finds the indirect share small)
        memo = {}  # (the pilot's region of interest: the same camera pre-pass)
        n = global_photon_count(ctx, stats, should_cancel, memo)
        sctx = ctx if n == s.photons else replace(ctx, settings=replace(s, photons=n))
        emitters, counts = global_emitters(sctx, photon_counts(ctx, n), stats, memo)
        ctx.importance_region, ctx.lookups = sctx.importance_region, sctx.lookups
        glow_from_global = split is not None or (plan.caustics and not use_caustic_shot)
        if GLOW_SHOT and glow_from_global and _importance_aimed(emitters):
            g_emitters, g_counts = glow_emitters(emitters, counts, photon_counts(ctx, n))
    sizes = (int(sum(counts)) if global_shot else 0,
             int(sum(g_counts)) if g_emitters is not None and not unread else 0,
             int(s.caustic_photons) if use_caustic_shot and not unread else 0)
    if on_plan is not None:
        on_plan({"photons": int(sum(sizes))})
    if global_shot:
        shot = trace_photons(ctx, emitters, counts, caustic_only=False, stream=1,
                             progress=_shot_progress(progress, sizes, 0),
                             should_cancel=should_cancel,
                             first_hit=None if split is None else (split, False))
        # (without a gather map the split is off and the maps are read: the shots stay)
        planned = unread
        unread = unread and bool(shot.usable(s.bounce_limits, camera=(1, 1, 0, 0)).any())
        if unread != planned:
            # The plan follows: the glow / caustic shots are traced after all (planned
            # at 0, the caustic shot's bar sat at 100 % while it traced: splitfix47).
            sizes = (sizes[0], int(sum(g_counts)) if g_emitters is not None else 0,
                     int(s.caustic_photons) if use_caustic_shot else 0)
            if on_plan is not None:
                on_plan({"photons": int(sum(sizes))})
        if unread:
            stats["shots_unread"] = tuple(
                name for name, planned in (("caustic", use_caustic_shot),
                                           ("glow", g_emitters is not None)) if planned)
        if g_emitters is not None:
            # The glow shot's size from the glow's share of what the camera sees, now
            # that the global shot holds its caustic-kind photons (glow_split).
            # (The bar was planned with the largest shot: a smaller one only ends the
            # photon stage's span early.)
            # Capped by the global radius (computed once, here, for the maps too): with
            # 0.1 x the scene's extent (4 m in a 40 m yard) its two k-NN estimates searched
            # thousands of photons a hit, 0.5 CPU s (docs/performance.md "worldfast43").
            # Without final gathering the global map is read at the camera's diffuse hits:
            # its radius there (camera_radius, reused by the maps) is the cap; the
            # pre-pass' gather rays (lookup_points) would serve nothing (fast46).
            cap = None
            if s.radius is None and not GLOW_SHARE_EXTENT_CAP:
                if s.final_gather or not plan.indirect:
                    pre_radius = global_search_radius(ctx, shot, _diffuse_area(ctx))
                    cap = pre_radius[0]
                else:
                    cap, camera_map_radius[0] = _camera_map_radius(ctx, shot)
            cap = s.radius or (0.1 * geo.extent if GLOW_SHARE_EXTENT_CAP else cap)
            if s.final_gather and plan.indirect:
                # The secondary map's share (smooth_counts) from the same search: the
                # same shot and, where the maps keep this radius, the same value.
                g_share, sec = glow_and_secondary_shares(ctx, shot, cap)
                known_secondary = (cap, sec)
            else:
                g_share = glow_share(ctx, shot, cap)
            g_split = glow_split(g_share)
            stats["glow_share"], stats["glow_split"] = g_share, g_split
            g_emitters, g_counts = glow_emitters(emitters, counts, photon_counts(ctx, n),
                                                 g_split)
            sizes = (sizes[0], 0 if unread else int(sum(g_counts)), sizes[2])
            # The glow's caustic paths (light off rough specular layers first, or window
            # glass: L S+ D, the first S not a caster) from a shot of their own whose
            # photons are lighter (GLOW_STREAM's comment).
            # Named by the surfaces the light comes off ("Tracing glossy photons"), as the
            # maps line explains them (photon_map_report): "Tracing caustic photons 2156k"
            # beside "caustics: off - nothing focuses light" read as a contradiction
            # (newuser33), "Tracing glow photons" said nothing to a user (newuser37).
            label = f"{plan.glow_label or 'soft glow'} photons"
            if not unread:
                glow = trace_photons(ctx, g_emitters, g_counts, caustic_only=True,
                                     stream=GLOW_STREAM,
                                     progress=_shot_progress(progress, sizes, 1),
                                     should_cancel=should_cancel,
                                     first_hit=None if split is None else (split, False),
                                     label=label)
                stats["glow_photons_emitted"] = glow.emitted
                stats["glow_label"] = label
                stats["glow_words"] = plan.glow_words or " and ".join(
                    GLOW_KIND_WORDS[k] for k in plan.glow_label.split("/") if k) or "soft glow"
    caustic = Photons.empty()
    glow_apart = None  # the glow shot as a map of its own (GLOW_MAP_APART)
    if use_caustic_shot and unread:
        pass  # (not traced: an empty caustic map)
    elif use_caustic_shot:
        if targets is None:
            ccounts = allocate_photons(ctx.lights, s.caustic_photons)
        else:
            ccounts = _allocate_aimed(ctx, targets, s.caustic_photons)
        caustic = trace_photons(ctx, ctx.lights, ccounts, caustic_only=True, stream=2,
                                progress=_shot_progress(progress, sizes, 2),
                                should_cancel=should_cancel, targets=targets,
                                first_hit=None if split is None else (split, True))
        # (the caustics line says how many of them were stored: effects.shot_words)
        stats["caustic_shot_stored"] = len(caustic)
        stats["caustic_shot_aimed"] = targets is not None
        if split is not None and len(shot):
            # The caustic paths the aimed shot leaves out, from the global shot (or from
            # the glow shot where that one is aimed by visual importance).
            rest = glow if glow is not None else shot.select(shot.kind == CAUSTIC)
            if glow is not None and GLOW_MAP_APART:
                glow_apart, rest = glow, Photons.empty()
            emitted = caustic.emitted
            caustic = Photons(*(np.concatenate([getattr(caustic, f), getattr(rest, f)])
                                for f in ("position", "power", "direction", "normal", "kind")),
                              bounces=np.concatenate([caustic.bounces, rest.bounces]),
                              surface=concat_surfaces(caustic, rest),
                              blur_pdf=concat_blur_pdfs(caustic, rest),
                              radiance=concat_radiances(caustic, rest))
            caustic.emitted = emitted
    elif glow is not None:
        # Nothing focuses light (effects: glow only): the caustic map is the glow shot.
        caustic, use_caustic_shot = glow, True
    stats["time_photons"] = time.perf_counter() - t0
    stats["photons_emitted"] = shot.emitted
    stats["caustic_photons_emitted"] = caustic.emitted
    # Every shot's emitted photons, each once (the glow shot may be the caustic map):
    # what the pass traced, as on_plan announced it.
    stats["photons_emitted_all"] = int(shot.emitted) + int(caustic.emitted) + (
        int(glow.emitted) if glow is not None and caustic is not glow else 0)
    if progress is not None:
        progress("photon_map", 0.0, "Building photon map")
    t0 = time.perf_counter()
    # Built on a worker thread while this one polls should_cancel: the kd-tree builds are
    # single compiled calls of seconds at 10M photons (engine/parallel.run_cancellable).
    maps = run_cancellable(lambda stop: _build_maps(ctx, shot, caustic, use_caustic_shot,
                                                    stop, pre_radius, glow_apart,
                                                    camera_map_radius[0], known_secondary),
                           should_cancel)
    if "global_photons" in maps:
        stats["global_photons"] = maps.pop("global_photons")
    diffuse_area = maps.pop("diffuse_area")
    images = maps.pop("caustic_images", 0)
    glow_images = maps.pop("glow_images", 0)
    spacing = maps.pop("radius_spacing", 0.0)
    if spacing:
        stats["radius_spacing"] = spacing
    stats["secondary_images"] = maps.pop("secondary_images", 0)
    if "time_gather_guide" in maps:
        stats["time_gather_guide"] = maps.pop("time_gather_guide")
    pre_share = maps.pop("indirect_share", _NOT_MEASURED)
    maps_secondary = maps.pop("secondary_share", None)
    guide_skipped = maps.pop("guide_skipped", False)
    for name, value in maps.items():
        setattr(ctx, name, value)
    stats["caustic_photons"] = len(ctx.caustic_map) - images if ctx.caustic_map is not None \
        else 0
    stats["caustic_images"] = images
    if ctx.glow_map is not None:
        stats["glow_photons"] = len(ctx.glow_map) - glow_images
        stats["radius_glow"] = ctx.glow_radius
    stats["radius_global"] = ctx.global_radius
    stats["radius_caustic"] = ctx.caustic_radius
    if s.radius is not None and plan.indirect:
        warned = radius_warnings(s.radius, geo.extent, diffuse_area,
                                 stats.get("global_photons", 0), s.min_photons)
        stats.setdefault("warnings", []).extend(warned)
        # Said now, not after the camera pass: the user may stop a long render and fix
        # the radius (issue 14: the CLI printed them only after the camera pass's bar).
        for w in warned if on_warning is not None else ():
            on_warning(w)
    # (Where the share does not count all the gathered light: every ray, share_counts.)
    if pre_share is _NOT_MEASURED and ctx.gather_map is not None and (
            share_counts(ctx) or s.gather_guiding == "auto"):
        pre_share = indirect_share(ctx, shot, ctx.gather_short)
    if ctx.gather_map is not None and share_counts(ctx):
        share = pre_share
        ctx.gather_rays = gather_count(s.gather_rays, share)
        stats["indirect_share"] = share
        stats["gather_rays_used"] = ctx.gather_rays
    guide = getattr(ctx.gather_map, "guide", None)
    if guide is not None:
        # Guided gather directions where the grids predict a fall of the pixels' relative
        # variance worth their cost: share^2 x the gather ray's (guiding.AUTO_GAIN).
        share = pre_share
        # (None: the camera sees nothing diffuse, or no photon: no evidence, cosine)
        gain = (share * share * guide.gain if share is not None and math.isfinite(share)
                else None)
        stats["gather_guide_gain"] = gain
        stats["gather_guided"] = (s.gather_guiding == "on"
                                  or (gain is not None and gain >= AUTO_GAIN))
        stats["gather_guide_points"] = guide.points
        if not stats["gather_guided"]:
            ctx.gather_map.guide = None
    elif guide_skipped:
        # (auto at a share too small for any grid to pay: guiding.can_guide; not built)
        stats.update(gather_guide_gain=None, gather_guided=False, gather_guide_points=0)
    smooth_counts(ctx, shot, stats, maps_secondary or known_secondary)
    stats["time_photon_map"] = time.perf_counter() - t0
    # (The glow shot's photons beside an aimed map are the glow map's: counted, and
    # drawn in the photon-hit view, as when they were the caustic map's.)
    stats["shot_bytes"] = shot.nbytes + caustic.nbytes + (
        glow_apart.nbytes if glow_apart is not None else 0)
    # What the maps hold through the camera pass (their photons' copies, trees, gather
    # points, a lazy gather map's masks and arrays to fill, the counts' classes), each
    # buffer once: a session keeps these (engine/session.py's photon cache), and it is
    # the figure per stored photon issue 13 bounds (docs/performance.md "perf47").
    stats["photon_bytes"] = held_bytes(*(getattr(ctx, name) for name in MAP_FIELDS))
    # For the photon-hit pass (_photon_hit_view), always filled (the caustic shot last).
    return (shot, caustic) if glow_apart is None else (shot, glow_apart, caustic)


# The indirect light's share of the seen diffuse irradiance at and above which final
# gathering casts settings.gather_rays rays a sample; below it, fewer in proportion.
GATHER_SHARE_FULL = 0.1


def gather_count(most: int, share: float | None) -> int:
    """Final-gather rays per camera sample for a scene whose indirect light is `share` of
    the diffuse irradiance the camera sees (visualimportance.indirect_share; None: not
    known, `most`): most x share / GATHER_SHARE_FULL rounded up, from 1 to `most`.

    A pixel's variance from final gathering is about share^2 x V / G for G rays (V the
    gathered light's relative variance), its cost about C0 + G x Cg; minimising variance
    x cost puts G in proportion to the share (the sample allocation of pbrt's and
    Veach's splitting), so halving the share halves the rays. Where indirect light is a
    few per cent of the light (a lit floor under a dim world, issue 14's Principled
    spheres: 2 %), one ray costs no visible noise; rooms lit by their walls (18-43 %: the
    Figure 6 / 7 boxes, small diffuse rooms) keep every ray."""
    if share is None or not math.isfinite(share):
        return most
    return int(min(most, max(1, math.ceil(most * share / GATHER_SHARE_FULL))))


_NOT_MEASURED = object()  # (_photon_maps: the share not measured while the maps were built)


def smooth_counts(ctx, shot, stats, known_secondary=None) -> None:
    """Samples a pixel for the smooth estimates of a glow-only caustic map and of the
    secondary map, from their rms shares of the light the camera sees
    (integrator.smooth_per_pixel; visualimportance.glow_share, the glow shot's if it was
    measured, and secondary_share, ~0.02 s each, on this thread: the same for any
    worker count): ctx.glow_per_pixel, ctx.secondary_per_pixel and their stats.
    known_secondary: (radius, secondary_share there) measured beside the glow share
    (visualimportance.glow_and_secondary_shares), taken where the radius is this one."""
    from .integrator import (GLOW_LEAST_PER_PIXEL, GLOW_SAMPLES_PER_PIXEL,
                             SECONDARY_SAMPLES_PER_PIXEL)
    radius = ctx.settings.radius or ctx.global_radius
    if not (len(shot) and radius > 0):
        return
    if (ctx.plan.caustics_glow_only and ctx.caustic_map is not None
            and len(ctx.caustic_map)) or ctx.glow_map is not None:
        if "glow_share" not in stats:
            stats["glow_share"] = glow_share(ctx, shot, radius)
        ctx.glow_per_pixel = smooth_per_pixel(GLOW_SAMPLES_PER_PIXEL, stats["glow_share"],
                                              least=GLOW_LEAST_PER_PIXEL)
        stats["glow_per_pixel"] = ctx.glow_per_pixel
    if ctx.secondary_map is not None and len(ctx.secondary_map):
        share = (known_secondary[1] if known_secondary is not None
                 and known_secondary[0] == radius else secondary_share(ctx, shot, radius))
        stats["secondary_share"] = share
        ctx.secondary_per_pixel = smooth_per_pixel(SECONDARY_SAMPLES_PER_PIXEL, share)
        stats["secondary_per_pixel"] = ctx.secondary_per_pixel


def share_counts(ctx) -> bool:
    """Whether the indirect share (visualimportance.indirect_share) counts all the light
    the gather rays bring, so that their number and the gather map's points may follow it:
    settings.gather_by_share, and no emitter with unsampled sides (Emission Sampling: they
    send direct light through the gather rays too, which the photons' share does not
    count) nor emitting media (their glow comes through gather rays alone:
    engine/volumeemission.py)."""
    return bool(ctx.settings.gather_by_share) and not any(
        light.kind == "MESH" and light.tri_sides is not None
        and (light.sides() != 3).any() for light in ctx.lights) and not glows(ctx)


# The gather map's points (GatherMap's max_points) at an indirect share of
# POINTS_SHARE_FULL and above (gather_count's GATHER_SHARE_FULL); below it, fewer in
# proportion (gather_points; POINTS_SHARE_FULL 1e-9: always all, the A/B of worldfast43).
GATHER_POINTS = 60_000
POINTS_SHARE_FULL = GATHER_SHARE_FULL


def gather_points(photons: int, share: float | None, k: int) -> int:
    """GatherMap's max_points for a map of `photons` rows at indirect share `share`
    (None: not known or not counted, GATHER_POINTS): GATHER_POINTS x share /
    POINTS_SHARE_FULL, at least 4 x photons / k (a point per k / 4 photons at most: each
    point's Voronoi cell, holding about k / 4 photons (sqrt(k / 4) photon spacings
    across), stays inside its own estimate's disc of k photons, so a lookup's blur is
    still the estimate's) and at most GATHER_POINTS.

    The points' irradiance costs ~13 us each (a k-NN estimate with its boundary and
    surface tests): 0.73 CPU s for 57k points in a world-lit yard whose gather rays, one a
    sample at a 3 % share, add a 3 % share of the pixel's light; a lookup's error there is
    share x the map's. So the points follow the share as gather_count's rays do
    (docs/performance.md "worldfast43")."""
    if share is None or not math.isfinite(share) or share >= POINTS_SHARE_FULL:
        return GATHER_POINTS
    fewest = math.ceil(4 * photons / max(k, 1))
    return int(min(GATHER_POINTS, max(fewest, math.ceil(GATHER_POINTS * share
                                                        / POINTS_SHARE_FULL), 1)))


# Gather lookups after a camera chain whose counts drop more than this share of the power
# their level's map holds gather again (chaincounts.GatherCounts.reroute; docs/design.md,
# Bounce limits). The regathers' maps of the deeper levels no longer use it (_build_maps:
# a map wherever a level drops any photon's light).
SUBSET_POWER_SHARE = 0.005
# The caustic map's photons get images across the open edges of the surfaces they lie on
# (engine/edgeimages.py): the reflection method keeps a disc's light at an edge.
EDGE_IMAGES = True
# The secondary (CAUSTIC_DIFFUSE) map's photons with images too, within its own radius
# (the images lying in a gap narrower than 2 R dropped: SECONDARY_GAPS). A panel's
# secondary light then integrates to 1.01-1.03 of its photons' power (0.93-0.96 without),
# Figure 7 moves +0.2-1.6 % towards Cycles (docs/performance.md "secedges", "secgap").
# Kept off in s21 / s22 because the window room (feature case
# transparency_window_glass_plane) read worse with them, its far corners 1.39 -> 1.47 of
# Cycles; that was its 1024-spp reference, whose dim corners read 0.68-0.72 of a
# 16384-spp one (Cycles reaches them only through glass by BSDF sampling: spiky). Against
# 16384 spp, 12 seeds: corners 0.935-0.947 -> 1.003-1.004, brightness 0.9895 -> 0.9991,
# mean block deviation 0.0631 -> 0.0608 (-0.0023 +- 0.0010) (docs/performance.md
# "windowroom").
SECONDARY_EDGE_IMAGES = True
# With them: drop the images lying in a gap narrower than 2 radius (edgeimages gaps).
SECONDARY_GAPS = True
# With them: weight each image by the density's linear extrapolation across its edge
# where the light falls significantly towards the edge (edgeimages.flatness_weights).
SECONDARY_FLATNESS = False


def _with_images(photons: Photons, images: Photons) -> Photons:
    """photons with images (engine/edgeimages.py) appended after them, bounce counts too."""
    if not len(images):
        return photons
    return Photons(*(np.concatenate([getattr(photons, f), getattr(images, f)])
                     for f in ("position", "power", "direction", "normal", "kind")),
                   photons.emitted,
                   None if photons.bounces is None else
                   np.concatenate([photons.bounces, images.bounces]),
                   concat_surfaces(photons, images), concat_blur_pdfs(photons, images),
                   concat_radiances(photons, images))


def region_photons(positions: np.ndarray, region, k: int) -> np.ndarray:
    """The rows of positions (N,3) (stored photons, re-centred world space) inside the
    spheres of a visualimportance.Region; all of them without a region, or when at most
    k lie inside (too few for a spacing)."""
    if region is None or len(region.radii) == 0:
        return positions
    p = np.asarray(positions, np.float64)
    inside = np.zeros(len(p), bool)
    for c, r in zip(np.asarray(region.centers, np.float64), np.asarray(region.radii)):
        d = p - c
        inside |= np.einsum("ij,ij->i", d, d) <= r * r
    return positions[inside] if inside.sum() > k else positions

def _counted_map(photons: Photons, workers: int, rows: np.ndarray) -> PhotonMap:
    """PhotonMap(photons, workers, rows=rows) whose photons keep their bounce counts
    (Photons.bounces in the map's order), so a lookup after a specular chain counts only
    the photons usable for its counts (chaincounts.irradiance)."""
    counted = photons.bounces is not None
    pm = PhotonMap(photons, workers, rows=rows, keep_source=counted)
    if counted and pm.tree is not None:
        pm.photons.bounces = np.take(photons.bounces, pm.source, axis=0)
        del pm.source
    return pm


def _diffuse_tris(ctx) -> np.ndarray:
    """(T,) bool: the triangles whose material has a diffuse lobe."""
    geo = ctx.geo
    return ctx.table.has_diffuse[geo.material] if geo.count else np.zeros(0, bool)


def _diffuse_area(ctx) -> float:
    """The scene's diffuse surface area (m^2)."""
    return area_sum(ctx.geo, _diffuse_tris(ctx))


def global_search_radius(ctx, shot, diffuse_area: float, tree=None) -> tuple:
    """(radius (m), photons it was measured on; 0: measured at the lookups): the global
    search radius where the estimates are made (lookup_radius, docs/design.md, Photon
    mapping model); without lookups from the global photons' own spacing
    (photonmap.auto_radius; local: not the spacing they would
    have if spread over a huge ground plane they barely light). With an aimed shot (visual
    importance), from the photons inside its region of interest, which holds
    visualimportance.ROI_COVER of the camera's lookups: a sky lights a 40 m ground evenly,
    and the spacing of the 60 % of photons that land beyond the objects (1.2 m against
    0.21 m near them) made the gather map's discs 5x too wide (docs/performance.md,
    "skynoise"). tree: a mortontree.KthTree over shot.position, or None (built here)."""
    k = ctx.settings.k_nearest
    if RADIUS_FROM_LOOKUPS:
        r = lookup_radius(ctx, shot, k, tree)
        if r is not None:
            # measured 0: the caustic cap keeps the whole shot's spacing (_build_maps).
            return r, 0
    positions = region_photons(shot.position, ctx.importance_region, k)
    return (auto_radius(diffuse_area, len(positions), k, ctx.geo.extent, positions,
                        tree if tree is not None and len(tree) == len(positions) else None,
                        workers=ctx.settings.threads), len(positions))


# The global search radius from the k-NN distance where the estimates are made (the
# pre-pass' gather-ray ends; the camera's diffuse hits without final gathering) instead
# of at the stored photons (docs/accuracy.md "radius43", "radius44"). False: auto_radius
# over the photons (the rule before).
RADIUS_FROM_LOOKUPS = True
# The radius over the lookups' median k-NN distance (2: as auto_radius's over the photons').
LOOKUP_RADIUS_SCALE = 2.0


def lookup_radius(ctx, shot, k: int, tree=None) -> float | None:
    """Global search radius (m) at final gathering's lookups: kth_radius over the
    pre-pass' gather-ray ends (visualimportance.lookup_points: where final gathering's
    rays end on a surface that stores photons) and the photons of `shot` (any kind).
    The photons' own k-NN spacing (auto_radius) weighs each place by its photon count,
    so a lamp in a narrow gap, where most photons pile up, shrank the radius 5x for the
    whole room (docs/accuracy.md "night43"); the lookups weigh each place by how often an
    estimate is made there. The points are visual importance's (ctx.lookups, traced once
    by global_emitters) where it ran, else traced here (the same seeded stream: the same
    points). None: no lookup point, or the shot holds at most k photons (then
    auto_radius, as before). tree: kth_radius's."""
    from .visualimportance import lookup_points
    if len(shot) <= k:
        return None
    points = ctx.lookups if ctx.lookups is not None else lookup_points(ctx)
    return kth_radius(points, shot.position, k, ctx.geo.extent, tree)


def _global_map_rows(shot, at_hit: np.ndarray) -> np.ndarray:
    """(M,) int64: the rows of `shot` the global map holds without final gathering (its
    INDIRECT and CAUSTIC_DIFFUSE photons usable at the camera's hit, at_hit (N,) bool)."""
    return np.flatnonzero(np.isin(shot.kind, (INDIRECT, CAUSTIC_DIFFUSE)) & at_hit)


def _camera_map_radius(ctx, shot) -> tuple:
    """(the glow share's cap (m) without final gathering, camera_radius's answer or
    None): camera_radius over the photons the global map will hold (_global_map_rows; the
    k-NN distances do not depend on their order, so _build_maps reuses the answer), else
    those photons' own spacing (auto_radius) or, with at most k of them, the whole
    shot's."""
    k = ctx.settings.k_nearest
    positions = np.take(shot.position, _global_map_rows(
        shot, shot.usable(ctx.settings.bounce_limits)), axis=0)
    r = (RADIUS_FROM_LOOKUPS and camera_radius(ctx, positions, k)) or None
    if r is not None:
        return r, r
    if len(positions) <= k:
        positions = shot.position
    return auto_radius(_diffuse_area(ctx), len(positions), k, ctx.geo.extent, positions,
                       workers=ctx.settings.threads), None


def camera_radius(ctx, positions: np.ndarray, k: int) -> float | None:
    """Global search radius (m) without final gathering, where the global map is read at
    the camera's diffuse hits: kth_radius over the pre-pass' camera paths' diffuse hits
    (visualimportance.diffuse_camera_hits, ROI_RAYS rays, seeded as lookup_points) and the
    global map's photons `positions` (N,3). None as lookup_radius."""
    from .visualimportance import ROI_RAYS, diffuse_camera_hits
    if len(positions) <= k:
        return None
    rng = np.random.default_rng([ctx.settings.seed, 95])
    points = diffuse_camera_hits(ctx, ROI_RAYS, rng)[0]
    return kth_radius(points, positions, k, ctx.geo.extent)


def kth_radius(points: np.ndarray, positions: np.ndarray, k: int,
               extent: float, tree=None) -> float | None:
    """LOOKUP_RADIUS_SCALE (2) x the median, over `points` (M,3) (where the estimates are
    made; a strided sample of at most photonmap.RADIUS_SAMPLE of them), of the distance to
    the k-th nearest of `positions` (N,3, N > k), in m; at most 0.1 x the scene's
    `extent` (auto_radius's cap). A point far from every photon (a dark place) raises the
    median as any sparse one does. None without points or when the median is not a
    positive finite distance. tree: a mortontree.KthTree over `positions` (the same
    distances), or None: built here."""
    from .mortontree import KthTree
    from .photonmap import RADIUS_SAMPLE
    if points is None or len(points) == 0:
        return None
    points = points[::max(1, len(points) // RADIUS_SAMPLE)]
    d = (KthTree(positions) if tree is None else tree).kth(points, k)
    r = LOOKUP_RADIUS_SCALE * float(np.median(d))
    if not (r > 0 and math.isfinite(r)):
        return None
    return float(min(r, 0.1 * extent))


def _build_maps(ctx, shot, caustic, use_caustic_shot, stop, pre_radius=None,
                glow=None, camera_map_radius=None, known_secondary=None) -> dict:
    """The photon maps and radii of a pass, as Context attributes (name -> value) plus
    global_photons. stop() is asked between the steps (raises Cancelled).

    Two chains run side by side on the workers (parallel.run_tasks): the global radius and
    then the gather map, which needs it; beside them the secondary (or, without final
    gathering, the global) map, the gather counts' classes, and the caustic and glow maps
    once the first chain has the shot's spacing (their radii's cap, handed over: a
    _Handover), so no map waits for both chains. Each map is gathered from the shot once,
    straight into its tree's order (PhotonMap / GatherMap rows), and each step computes
    what it computes alone, so the maps are the same for any thread count. pre_radius:
    global_search_radius's answer for this shot where the photon pass has it, else None.
    glow: the glow shot's Photons for a map of their own (GLOW_MAP_APART), else None.
    camera_map_radius: without final gathering, camera_radius's answer for the global
    map's photons where the photon pass measured it (_camera_map_radius), else None.
    known_secondary: (radius, secondary share) the photon pass measured (smooth_counts),
    else None; where the maps keep another radius (or have none), the secondary map's
    share at theirs comes back as secondary_share: (radius, share)."""
    s, geo, plan = ctx.settings, ctx.geo, ctx.plan
    diffuse_tris = _diffuse_tris(ctx)
    diffuse_area = area_sum(geo, diffuse_tris)
    k = s.k_nearest
    workers = s.threads
    # Bounce limits (docs/design.md, Bounce limits): each map keeps the photons whose
    # paths stay within them as the camera side commonly reads that map: the gather map at
    # the end of a final-gather ray (one diffuse bounce on the camera side), the others at
    # the camera's hit (none). Paths with more camera-side bounces (after a mirror or glass
    # chain) read the same maps.
    limits = s.bounce_limits
    # (at_hit, gathered, final), made by whichever chain asks first, under a lock (the
    # other waits for it): the shot's count classes behind them (Photons.count_classes,
    # ~0.05 CPU s on Figure 6) were the build's serial prologue; other_maps asks at its
    # start, the gather chain after its Morton tree and radius (on one thread the gather
    # chain runs first and makes them: the same masks).
    usable = _Once(lambda: _usable_masks(shot, limits, plan.indirect and s.final_gather))

    def check(flag):
        if flag():
            raise Cancelled()

    shot_radius = _Handover()  # the whole shot's spacing (gather_chain -> other_maps)

    def gather_chain(flag):
        try:
            return _gather_chain(flag)
        finally:
            shot_radius.close()  # (after an error or a cancel: other_maps stops waiting)

    def _gather_chain(flag):
        # One Morton tree over the shot for the lookups' radius and the shot's own spacing
        # (the same distances as a tree each; a build was ~0.05 CPU s on Figure 6).
        # Built where a radius is measured over the shot here: not where the photon
        # pass' radius was measured over the whole shot (fast46).
        tree = None
        needs_tree = len(shot) > k and not (
            pre_radius is not None and pre_radius[1] == len(shot)
            and (s.final_gather or not plan.indirect))
        if needs_tree:
            stop = stop_array()
            tree = KthTree(shot.position, stop)
            if stop[0]:
                raise Cancelled()
        if s.final_gather or not plan.indirect:
            r_global, measured = pre_radius or global_search_radius(ctx, shot, diffuse_area,
                                                                    tree)
        else:
            # No gather ray reads a map: the global map's radius is measured at the
            # camera's diffuse hits (other_maps, camera_radius); visual importance's
            # gather-ray ends (lookup_points: 16 k rays more) would serve nothing.
            r_global, measured = None, -1
        # Three steps that need the radius at most, side by side on the workers (each
        # computes what it would alone, so the values are the same for any thread count;
        # on one thread in this order): the shot's spacing (handed over to other_maps
        # as soon as it is known), the indirect share, and the gather map's masks. One
        # after another they were a serial stretch of the longer chain, the build's
        # critical path (docs/performance.md "workers55").

        def spacing(job_stop):
            # The caustic map's cap stays the whole shot's spacing (caustic_radius): a
            # glow of light through a rough metal ball under a low Multiple Scattering
            # sun read 4x noisier with the region's (0.24 m against 0.46 m).
            shot_radius.set((r_global if measured == len(shot) else auto_radius(
                diffuse_area, len(shot), k, geo.extent, shot.position, tree,
                workers=workers), r_global))

        def share_step(job_stop):
            # The indirect share (visualimportance.indirect_share, ~0.05 s) before the
            # map: it sizes the map's points (gather_points) and tells whether the
            # guide's grids could pay (guiding.can_guide); _photon_maps reads the same
            # value.
            if share_counts(ctx) or s.gather_guiding == "auto":
                return indirect_share(ctx, shot, s.radius or r_global)
            return _NOT_MEASURED

        _, gathered, final = usable()
        steps = [spacing] + ([share_step, partial(_gather_masks, shot, limits, gathered,
                                                      regather_levels(s))]
                             if final else [])
        done = run_tasks(steps, workers, flag)
        del tree, steps
        gather_map = None
        if final:
            check(flag)
            share, (masks, level_of, secondary, secondary_of, drop_bounds) = done[1:]
            if share is _NOT_MEASURED:
                share = None
            else:
                out_deeper["indirect_share"] = share
            # Final gathering needs all light at the gathered point: every stored photon.
            # Photons that arrived straight from a caustic are left out: seen through a
            # few gather rays a bright caustic makes fireflies. Their light one bounce
            # later (CAUSTIC_DIFFUSE photons) is estimated directly at the camera hit.
            # Every photon of a disc counts outside paper mode (smooth_min_photons):
            # zeroing discs below min_photons darkened thinly lit surfaces.
            # Every non-caustic photon makes the map's points and discs; the irradiance
            # counts those valid one diffuse bounce after the camera's hit (keep).
            rows = np.flatnonzero(shot.kind != CAUSTIC)
            bounded = regather_levels(s)
            points = gather_points(len(rows), share if share_counts(ctx) else None, k)
            gather_map = GatherMap(shot, s.radius or r_global, k, smooth_min_photons(s),
                                   s.estimator, accel=ctx.accel, workers=workers,
                                   max_points=points,
                                   should_cancel=flag, rows=rows,
                                   keep=None if gathered[rows].all() else gathered,
                                   subsets=masks, secondary=secondary,
                                   # (its photons kept for the lookups that drop some:
                                   # chaincounts.subset_irradiance; none where no
                                   # limit can bind)
                                   bounces=shot.bounces if bounded else None,
                                   # (which points' estimates hold photons a lookup's
                                   # counts may drop: most hold none)
                                   drop_bounds=drop_bounds if bounded else None,
                                   # (each point's estimates when a lookup first takes
                                   # it, where few lookups a point are expected)
                                   lazy=gather_points_lazy(ctx, points, gather_count(
                                       s.gather_rays, share) if share_counts(ctx)
                                       else s.gather_rays))
            guide_pays = s.gather_guiding == "on" or can_guide(share)
            if s.gather_guiding != "off" and gather_map.tree is not None and not guide_pays:
                out_deeper["guide_skipped"] = True  # auto: no grid could reach AUTO_GAIN
            elif s.gather_guiding != "off" and gather_map.tree is not None:
                # Photon-guided gather directions (engine/guiding.py): each gather point's
                # grid of the flux coming in (its INDIRECT photons', or the photons' as
                # emitters); the level-0 gather rays read their nearest facing point's.
                # ("auto": kept or dropped once the indirect share is known, _photon_maps)
                t_guide = time.perf_counter()
                gather_map.guide = GatherGuide(gather_map.position, gather_map.normal, shot,
                                               gather_map.radius, k, s.gather_guide_share,
                                               s.gather_guide_source, workers=workers)
                out_deeper["time_gather_guide"] = time.perf_counter() - t_guide
            out_deeper["regather_maps"] = level_maps(gather_map, level_of, secondary_of)
        return r_global, gather_map

    def other_maps(flag):
        out = {}
        at_hit, _, final = usable()
        if plan.caustics:
            source = (caustic, np.flatnonzero(caustic.usable(limits))) if use_caustic_shot \
                else (shot, np.flatnonzero((shot.kind == CAUSTIC) & at_hit))
            if glow is not None:
                out["glow_source"] = (glow, np.flatnonzero(glow.usable(limits)))
            if EDGE_IMAGES:
                out["caustic_source"] = source  # built with its images below
            else:
                out["caustic_map"] = _counted_map(source[0], workers, source[1])
            check(flag)
        if final:
            rows = np.flatnonzero((shot.kind == CAUSTIC_DIFFUSE) & at_hit)
            # Its own photons' spacing: the global radius follows the dense photons of the
            # whole shot (a caustic's pile among them), which leaves the sparser secondary
            # photons below min_photons in much of the disc (zero estimate): walls lit
            # from a floor behind a window read 25 % dark against Cycles.
            source, images = shot, None
            if SECONDARY_EDGE_IMAGES and geo.count:
                # The radius first (from the photons alone: the images are estimator
                # support, not photons), then the images within it, then the maps of
                # photons and images (same k-NN distances from any tree: auto_radius).
                radius = s.radius or auto_radius(
                    diffuse_area, len(rows), k, geo.extent,
                    np.take(shot.position, rows, axis=0), workers=workers)
                check(flag)
                below = shot.take(np.flatnonzero(shot.kind == CAUSTIC_DIFFUSE))
                images = edge_images(below, geo, diffuse_tris, ctx.accel, radius,
                                     gaps=SECONDARY_GAPS, flatness=SECONDARY_FLATNESS)
                source = _with_images(below, images)
                rows = np.flatnonzero(source.usable(limits))
                out["secondary_map"] = secondary = _counted_map(source, workers, rows)
                out["secondary_radius"] = radius
                out["secondary_images"] = len(images)
            else:
                out["secondary_map"] = secondary = _counted_map(shot, workers, rows)
                out["secondary_radius"] = s.radius or auto_radius(
                    diffuse_area, len(rows), k, geo.extent,
                    np.take(shot.position, rows, axis=0), secondary.tree, workers=workers)
            # Read at regathered points, level + 1 diffuse bounces from the camera's hit.
            # A level whose limits keep the same secondary photons (they differ only in
            # others: Figure 6's levels 1 / 2) reads the map above (the same estimates).
            deeper, last = [], (secondary, rows)
            for level in range(1, MAX_GATHER_LEVEL + 1):
                ok = source.usable(limits, camera=(level, level, 0, 0))
                rows = np.flatnonzero(ok if images is not None else
                                      (shot.kind == CAUSTIC_DIFFUSE) & ok)
                if not np.array_equal(rows, last[1]):
                    last = (_counted_map(source, workers, rows), rows)
                deeper.append(last[0])
            out["regather_secondary"] = tuple(deeper)
            if shot.bounces is not None:
                # Lookups after a specular chain: which ones the gather map cannot serve
                # (decided on the float64 sums; it keeps its classes' sums alone). The
                # gather map's rows and powers, as gather_chain computes them.
                check(flag)
                rows = np.flatnonzero(shot.kind != CAUSTIC)
                power = shot.power.astype(np.float64).sum(axis=1) * (shot.kind != CAUSTIC)
                out["gather_counts"] = GatherCounts(
                    np.take(shot.bounces, rows, axis=0), np.take(power, rows), limits,
                    SUBSET_POWER_SHARE)
                del power
        elif plan.indirect and not s.final_gather:
            rows = _global_map_rows(shot, at_hit)
            out["global_map"] = pm = _counted_map(shot, workers, rows)
            # Read at the camera's diffuse hits: the k-NN distance there
            # (camera_radius, measured once: the photon pass' where it has it); the
            # photons' own spacing (auto_radius) without any.
            measured = camera_map_radius if camera_map_radius is not None else (
                RADIUS_FROM_LOOKUPS and camera_radius(ctx, pm.photons.position, k))
            out["global_radius"] = s.radius or measured or \
                auto_radius(diffuse_area, len(pm), k, geo.extent, pm.photons.position,
                            pm.tree, workers=workers)
        # The caustic and glow maps need the estimates' cap, from the whole shot's
        # spacing, which gather_chain measures first (waited for here; on one thread
        # gather_chain has run whole before this chain starts).
        spacing, r_lookups = shot_radius.wait(flag)
        # The caustic estimates' cap (photonmap.caustic_radius): each takes its k nearest
        # caustic photons, so a focus is as narrow as its photons; the cap acts where they
        # are sparse.
        out["caustic_radius"] = s.radius or caustic_radius(spacing, len(shot), len(caustic),
                                                           k, diffuse_area, geo.extent)
        # What that cap comes from, for the report (_caustic_radius_words): the global
        # radius is measured at the lookups, the cap from the shot's own spacing.
        out["radius_spacing"] = spacing
        if "caustic_source" in out:
            # Images across the open edges the caustic photons lie near
            # (engine/edgeimages.py): a disc hanging over a surface's edge keeps the light
            # its photons brought. They need the estimates' cap (above), so the map is
            # built here, once.
            check(flag)
            src, rows = out.pop("caustic_source")
            photons = src.take(rows)
            images = edge_images(photons, geo, diffuse_tris, ctx.accel, out["caustic_radius"])
            photons = _with_images(photons, images)
            out["caustic_map"] = _counted_map(photons, workers, None)
            out["caustic_images"] = len(images)
        if "glow_source" in out:
            check(flag)
            src, rows = out.pop("glow_source")
            photons = src.take(rows)
            out["glow_radius"] = s.radius or glow_radius(
                out["caustic_radius"], diffuse_area, photons.position, k, geo.extent, workers)
            images = (edge_images(photons, geo, diffuse_tris, ctx.accel, out["glow_radius"])
                      if EDGE_IMAGES else None)
            if images is not None:
                photons = _with_images(photons, images)
                out["glow_images"] = len(images)
            out["glow_map"] = _counted_map(photons, workers, None)
        secondary = out.get("secondary_map")
        radius = s.radius or r_lookups
        if secondary is not None and len(secondary) and len(shot) and radius and radius > 0 \
                and not (known_secondary is not None and known_secondary[0] == radius):
            # The secondary map's share for smooth_counts (its radius the one the maps
            # keep), here beside the gather chain rather than on the calling thread
            # after the build (~0.04 CPU s on Figure 6; the same value: one search).
            check(flag)
            out["secondary_share"] = (radius, secondary_share(ctx, shot, radius))
        return out

    out_deeper = {}
    # (gather_chain first: other_maps waits for its spacing)
    (r_global, gather_map), out = run_tasks([gather_chain, other_maps], workers, stop)
    out.update(out_deeper)
    check(stop)
    global_radius = out.pop("global_radius", s.radius or r_global)
    r_global = r_global or global_radius  # (without final gathering: the camera's)
    final = usable()[2]
    # The precomputed irradiance is blurred over about the k-NN radius: a gather ray that
    # ends closer than that gathers once more from its end (integrator.gather_indirect).
    out["gather_short"] = s.radius or r_global
    if final:
        out["gather_map"] = gather_map
        out["global_photons"] = len(shot)
    elif "global_map" in out:
        out["global_photons"] = len(out["global_map"])
    out["global_radius"] = global_radius
    for name in ("caustic_map", "glow_map"):
        if out.get(name) is not None:
            out[name].lookup = s.caustic_lookup  # engine/causticcache.py
    out["diffuse_area"] = diffuse_area
    return out


def _usable_masks(shot, limits, gathering: bool) -> tuple:
    """(at_hit, gathered, final) for _build_maps: the shot's photons (N,) bool usable at
    the camera's hit and one diffuse bounce after it (Photons.usable), and whether the
    gather map is built (gathering: indirect light by final gathering, and some photon
    is usable there)."""
    at_hit = shot.usable(limits)
    gathered = shot.usable(limits, camera=(1, 1, 0, 0))
    return at_hit, gathered, gathering and bool(gathered.any())


class _Once:
    """make()'s result, made by the first thread that calls this and kept; a thread that
    calls meanwhile waits for it (a lock held only while make runs, so a chain never
    waits on one that is not running). An error in make reaches every caller."""

    def __init__(self, make):
        self._make = make
        self._lock = threading.Lock()
        self._done = False
        self._value = self._error = None

    def __call__(self):
        with self._lock:
            if not self._done:
                try:
                    self._value = self._make()
                except BaseException as e:  # (each caller re-raises it)
                    self._error = e
                self._done = True
        if self._error is not None:
            raise self._error
        return self._value


class _Handover:
    """One value one map-build chain hands to another that runs beside it (_build_maps):
    set() once by the first chain, wait(flag) in the second, which returns the value, or
    raises parallel.Cancelled when flag() turns True or the first chain closed without
    setting it (its error or cancel reaches the caller through run_tasks)."""

    def __init__(self):
        self._event = threading.Event()
        self._value = None
        self._set = False

    def set(self, value):
        self._value, self._set = value, True
        self._event.set()

    def close(self):
        self._event.set()

    def wait(self, flag):
        # (polled: a cancel reaches the waiting chain within POLL_SECONDS)
        while not self._event.wait(POLL_SECONDS):
            if flag():
                raise Cancelled()
        if not self._set:
            raise Cancelled()
        return self._value


# The gather map's points estimated when a lookup first takes them (GatherMap lazy: the
# same bits; docs/performance.md "fast46") where the camera pass is expected to make
# fewer than LAZY_LOOKUPS_PER_POINT level-0 lookups a point. A lazy estimate costs ~1.6x
# the build's (its points come scattered, not in the tree's order), so it pays where a
# render reads under ~60 % of the points: a world-lit yard 1.0 lookups a point (31 % of
# its points read at 16 spp), hdri_sphere 1.6, product 1.5 gain 0.07-0.16 CPU s; Figure 3
# at 2.1 is even, Figure 8 at 3.8 and Figure 6 at 6.9 lose 0.16-0.5 s.
# False: every point at the map's build (A/B).
GATHER_POINTS_LAZY = True
LAZY_LOOKUPS_PER_POINT = 2.0


def gather_points_lazy(ctx, points: int, gather_rays: int) -> bool:
    """Whether the gather map of at most `points` points estimates them lazily: the
    level-0 lookups the camera pass is expected to make (pixels x spp x gather_rays x the
    share of the pre-pass' camera rays whose gather rays end on a surface that stores
    photons: len(ctx.lookups) / (ROI_RAYS x ROI_GATHER)) under LAZY_LOOKUPS_PER_POINT a
    point. False without the pre-pass' lookups (visual importance off) or points."""
    from .visualimportance import ROI_GATHER, ROI_RAYS
    if not GATHER_POINTS_LAZY or ctx.lookups is None or points <= 0:
        return False
    pixels = ctx.scene.width * ctx.scene.height
    expected = (pixels * ctx.settings.spp * gather_rays * len(ctx.lookups)
                / (ROI_RAYS * ROI_GATHER))
    return expected < LAZY_LOOKUPS_PER_POINT * points


# A search radius above this share of the scene's size blurs light across objects.
RADIUS_SCENE_FRACTION = 0.1
# How every radius_warnings text starts (warning_key).
RADIUS_WARNING_START = "search radius "


def radius_warnings(radius: float, extent: float, diffuse_area: float, stored: int,
                    min_photons: int) -> list[str]:
    """What a hand-set search radius (m) does wrong, in words: larger than
    RADIUS_SCENE_FRACTION of the scene's size (extent: its bounding-box diagonal, m), or
    smaller than the spacing of the `stored` global photons over `diffuse_area` m^2
    (sqrt(area / stored): the mean distance between neighbours of an even spread)."""
    out = []
    if radius > RADIUS_SCENE_FRACTION * extent:
        ratio = radius / extent
        # A percentage up to 6 digits; beyond, a factor (1e300 m printed 300 digits).
        share = f"{100 * ratio:.0f} % of" if ratio < 1e4 else f"{ratio:.3g} times"
        disc_area = math.pi * radius * radius  # inf beyond ~1e154 m
        disc = f"{disc_area:.3g} m^2" if math.isfinite(disc_area) else "beyond any number"
        out.append(
            f"{RADIUS_WARNING_START}{radius:.4g} m is {share} the scene's size "
            f"({extent:.3g} m across): each estimate spreads photons over a disc of "
            f"{disc}, so indirect light is blurred across corners "
            "and objects (and too dark where the disc is larger than the surface it lands on), "
            "and every lookup scans many photons (slow); use a few % of the scene or the "
            "automatic radius")
    if stored > 0 and diffuse_area > 0:
        spacing = math.sqrt(diffuse_area / stored)
        if radius < spacing:
            out.append(
                f"{RADIUS_WARNING_START}{radius:.4g} m is below the photon spacing "
                f"(~{spacing:.3g} m: {stored:,} photons stored on {diffuse_area:.3g} m^2 of "
                f"diffuse surface): most estimates find fewer than {min_photons} photons and "
                "give no light, so indirect light is dark and spotty; raise the radius above "
                "the spacing or shoot more photons")
    return out


def photon_map_report(settings: RenderSettings, stats: dict, glow_only: bool = False,
                      glow_words: str = "") -> list[str]:
    """One effect-report line with what the photon maps hold and the radius used.
    glow_only: the caustic map holds only the soft glow of rough specular layers and
    window glass (the report's "caustics: off - nothing focuses light"), named so, by
    glow_words (EffectPlan.glow_words: only what the scene has) where given."""
    if "radius_global" not in stats:
        return []
    parts = []
    # "caustic photons" beside "caustics: off" read as a contradiction (new-user trial).
    # "57 glow photons (Caustic pass)" did not say what glow (new-user trial s17); the
    # caustics line names the objects, this one what the photons carry, and only what the
    # scene has (it said "light through window glass" in a room without a window).
    held = (f"photons of {glow_words or 'soft glow'} (the Caustic pass)" if glow_only
            else "caustic photons")
    if stats.get("global_photons"):
        parts.append(f"{stats['global_photons']:,} global photons stored, search radius "
                     f"{stats['radius_global']:.4g} m")
    if stats.get("caustic_photons"):
        parts.append(_caustic_radius_words(settings, stats, held))
    if stats.get("glow_photons_emitted"):
        # What the progress line's "Tracing glossy photons" were (the glow shot).
        parts.append(f"{stats.get('glow_label', 'soft glow photons')}: "
                     f"{stats['glow_photons_emitted']:,} traced for the "
                     f"{stats.get('glow_words', 'soft glow')} (the light those surfaces, "
                     "which focus none, send onto diffuse ones; not aimed at), lighter "
                     "photons of their own, stored in the Caustic pass"
                     + _glow_apart_words(stats) + _glow_blur_words(settings, stats))
    if stats.get("caustic_photons") or stats.get("glow_photons_emitted"):
        unread = _maps_unread_words(settings)
        if unread:
            parts.append(unread)
    elif stats.get("shots_unread"):
        parts.append(_shots_unread_words(settings, stats["shots_unread"]))
    if stats.get("photon_importance"):
        parts.append(stats["photon_importance"])
    if stats.get("photon_portals"):
        parts.append(stats["photon_portals"])
    if stats.get("gather_rays_used"):
        share = stats.get("indirect_share")
        seen = ("share not measured" if share is None else
                f"indirect light {100 * share:.1f} % of the seen diffuse irradiance")
        parts.append(f"final gathering with {stats['gather_rays_used']} of "
                     f"{settings.gather_rays} ray(s) a sample ({seen})")
    how = "radius set" if settings.radius is not None else "automatic radius"
    est = (f"estimator {ESTIMATOR_LABELS.get(settings.estimator, settings.estimator)}"
           + (", paper mode" if settings.paper_mode else ""))
    return [f"photon maps: on - {'; '.join(parts) or 'no photons stored'} ({how}, {est})"]


def _glow_apart_words(stats: dict) -> str:
    """The maps line's words after the glow shot where its photons make a map of their
    own (GLOW_MAP_APART: stats glow_photons, radius_glow): how many, and their estimates'
    own cap, not the caustic photons' radius said before them. "" otherwise."""
    if "glow_photons" not in stats:
        return ""
    return (f" ({stats['glow_photons']:,} of them, in a map of their own: search radius "
            f"at most {stats.get('radius_glow', 0.0):.4g} m)")


# The glow's rms share of the seen diffuse light (visualimportance.glow_share) from which
# the maps line says that Cycles' Filter Glossy dims it. tableroom45 (docs/accuracy.md):
# a window-lit room whose Principled floor, table and mug (roughness 0.3-0.6) throw the
# sun's glow onto the walls, rms share 0.060: Cycles' walls at Filter Glossy 1 read
# 0.978-0.988 of its own at 0 (ours 0.997-1.003 of the latter), so the blur took about a
# fifth to a third of that glow. newuser46 (docs/accuracy.md): a kitchen whose white
# worktop (roughness 0.2) and walls reflect a window light and an HDRI sun, rms share
# 0.04: walls, cabinet and floor 0.958-0.977 of Cycles' own at 0, about all of the glow
# (the blur also widens the lobes light meets after a diffuse bounce, which the glow,
# light off a specular layer first, does not count). FILTER_GLOW_DIMS: that range.
FILTER_GLOSSY_GLOW_SHARE = 0.03
FILTER_GLOW_DIMS = (0.2, 1.0)


def _maps_unread_words(settings: RenderSettings) -> str:
    """The maps line's words where engine/glossysplit.py's split is on (Filter Glossy
    above 0 with final gathering): a caustic or glow photon is read at a camera path's
    diffuse hit only if Cycles leaves its path unblurred (on a matte surface above 1/pi:
    none), and the final gather's chains carry the rest, blurred. The line otherwise says
    the photons are "stored in the Caustic pass", which a user reads as their light being
    there (fgroom46, docs/accuracy.md). "" otherwise."""
    fg = settings_filter_glossy(settings)
    if not fg > 0.0:
        return ""
    matte = " (on a matte surface, none)" if fg > 1.0 / math.pi else ""
    return (f"at Filter Glossy {fg:g} (Light Paths > Caustics) the caustic and glow photons "
            f"are read only on paths Cycles leaves unblurred{matte}: the final gather's rays "
            "carry the rest of that light instead, through blurred lobes, into the Caustic "
            "pass")


def _shots_unread_words(settings: RenderSettings, shots) -> str:
    """The maps line's words where _photon_pass left the caustic / glow shots untraced
    (stats shots_unread: their names, "caustic", "glow"; glossysplit.maps_unread): the
    scene's Filter Glossy blurs every path of that light onto its matte surfaces, and
    the final gather's chains carry it. Without them the line said nothing of caustics."""
    what = " and ".join(shots)
    fg = settings_filter_glossy(settings)
    return (f"no {what} photons traced: at Filter Glossy {fg:g} (Light Paths > Caustics) "
            "Cycles blurs every path of that light onto this scene's matte surfaces, so the "
            "final gather's rays carry it instead, through blurred lobes, into the Caustic "
            "pass")


def _glow_blur_words(settings: RenderSettings, stats: dict) -> str:
    """The maps line's words after the glow shot where Cycles' Filter Glossy (the
    scene's, read by the add-on) is on and the glow carries at least
    FILTER_GLOSSY_GLOW_SHARE of the light the camera sees: Cycles widens those rough
    lobes after a diffuse bounce (effects.filter_glossy_alpha: GGX alpha 0.41-0.5, so
    roughness below ~0.7) and dims that light; ours does not blur. The effects' "glossy
    blur" line names only strong reflectors (a dielectric layer reflects ~4 %), which
    left a new user's walls 1-2 % brighter than Cycles' unexplained. "" otherwise, and
    where engine/glossysplit.py blurs that glow as Cycles does."""
    share = stats.get("glow_share")
    fg = getattr(settings, "cycles_filter_glossy", 0.0)
    if settings_filter_glossy(settings) > 0.0:
        return ""  # (blurred as Cycles': engine/glossysplit.py)
    if not fg or share is None or not math.isfinite(share) or share < FILTER_GLOSSY_GLOW_SHARE:
        return ""
    lo, hi = (100 * share * f for f in FILTER_GLOW_DIMS)
    return (f"; that glow is {100 * share:.0f} % (rms) of the diffuse light the camera "
            f"sees, and Cycles' Light Paths > Caustics > Filter Glossy ({fg:g}) widens those "
            "lobes after a diffuse bounce and dims it, so the surfaces it lights read "
            f"brighter here than in Cycles, by about {lo:.1f}-{hi:.0f} % (a fifth of that "
            "share to all of it in the rooms measured, more where the lamps' light meets a "
            "specular layer after a diffuse bounce): set Filter Glossy 0 in Cycles to compare")


def _caustic_radius_words(settings: RenderSettings, stats: dict, held: str) -> str:
    """The maps line's caustic part: what the caustic estimate's radius is, and why. A k-NN
    estimate takes the k nearest caustic photons, so its radius is as narrow as they lie
    (a ball lens's focus: mm) and the search radius only caps it where they are sparse;
    "the same search radius 0.52 m" read as a 0.52 m blur of the focus (new-user trial
    s16). The cap is the global one unless the caustic map holds more photons
    (photonmap.caustic_radius): then printed, else said once. Where the global radius
    was measured at the lookups (render.lookup_radius) the cap still comes from the
    global photons' spacing (stats["radius_spacing"]), and is printed as such."""
    rc, rg = stats["radius_caustic"], stats.get("radius_global")
    same = bool(stats.get("global_photons") and rg and abs(rc - rg) <= 1e-9 * rg)
    rs = stats.get("radius_spacing")
    # The cap's base is the photons' spacing, not the (lookup-measured) global radius.
    apart = bool(rs and rg and abs(rs - rg) > 1e-9 * rg)
    if settings.radius is not None:
        cap = ("the same search radius (set in the settings)" if same
               else f"search radius {rc:.4g} m (set in the settings)")
    elif apart and stats.get("global_photons") and abs(rc - rs) <= 1e-9 * rs:
        cap = f"{rc:.4g} m (the global photons' spacing)"
    elif apart and stats.get("global_photons") and rc < rs:
        cap = (f"{rc:.4g} m (the global photons' spacing, scaled down to their greater "
               "number)")
    elif same:
        cap = "the global search radius (from the global photons' spacing)"
    elif stats.get("global_photons") and rg and rc < rg:
        cap = f"{rc:.4g} m (the global radius, scaled down to their greater number)"
    else:
        cap = f"{rc:.4g} m (from their number over the diffuse area)"
    n = f"{stats['caustic_photons']:,} {held} stored"
    if settings.estimator.startswith("knn") and not settings.paper_mode:
        focus = " (a focus stays sharp)" if held == "caustic photons" else ""
        return (f"{n}, each estimate from its {settings.k_nearest} nearest: as narrow as "
                f"they lie{focus}, at most {cap} where they are sparse")
    return f"{n}, every photon within {cap}"


# The global shot's photons follow the indirect share (worldcolour44): a pilot shot of
# PILOT_FRACTION x settings.photons (its own random stream, PILOT_STREAM; thrown away)
# measures the share (visualimportance.indirect_share, as gather_count's), and below
# PHOTONS_SHARE_FULL the shot is settings.photons x share / PHOTONS_SHARE_FULL, never
# under PHOTONS_LEAST of it. The indirect pass's variance is the gather rays' (share^2 x
# their variance / G) plus the map's; where the share is small the gather ray's own
# noise is most of it: a world-lit yard at 2.9 % read relMSE 0.0019 with 400k and 200k
# photons (its indirect pass 8 -> 9 % of the seeds' variance) in 30 % less CPU. The
# floor bounds the estimates' blur (the radius grows as 1 / sqrt(photons): 1.41x at
# half); PHOTONS_SHARE_FULL 0: always settings.photons, no pilot (A/B benches). Only
# with a light at infinity (a world, a sun: open scenes, whose direct light is most of
# what the camera sees): the pilot costs 0.1-0.15 CPU s (its region of interest, radius
# and share), which rooms lit by lamps alone (the example boxes: shares 13-41 %) would
# pay for nothing.
PHOTONS_SHARE_FULL = GATHER_SHARE_FULL
PHOTONS_LEAST = 0.5
PILOT_FRACTION = 1.0 / 32.0
PILOT_STREAM = 4  # trace_photons' random stream of the pilot (global 1, caustic 2, glow 3)


def photons_for_share(most: int, share: float | None) -> int:
    """Global photons for an indirect share `share` (None or not finite: not known,
    `most`): most x share / PHOTONS_SHARE_FULL rounded up, from most x PHOTONS_LEAST
    (rounded up) to most."""
    if (share is None or not math.isfinite(share) or not PHOTONS_SHARE_FULL > 0
            or share >= PHOTONS_SHARE_FULL):
        return int(most)
    return int(min(most, max(math.ceil(most * PHOTONS_LEAST),
                             math.ceil(most * share / PHOTONS_SHARE_FULL))))


def global_photon_count(ctx: Context, stats: dict, should_cancel=None,
                        memo: dict | None = None) -> int:
    """The global shot's photon total: settings.photons, or photons_for_share of a pilot
    shot's indirect share where the share decides the gather rays (final gathering,
    share_counts) and the photons are the renderer's to size (not the paper's method,
    no photons per light), in a scene with a light at infinity (PHOTONS_SHARE_FULL's
    comment); stats get pilot_photons and pilot_share; memo: global_emitters' (the
    pilot's region of interest, for the shot's)."""
    s = ctx.settings
    if not (PHOTONS_SHARE_FULL > 0 and s.photons > 0 and ctx.plan.indirect
            and any(isinstance(light, InfiniteLight) for light in ctx.lights)
            and s.final_gather and not s.paper_mode
            and not getattr(ctx.scene, "photons_per_light", None) and share_counts(ctx)):
        return s.photons
    n = max(1, int(s.photons * PILOT_FRACTION))
    sub = replace(ctx, settings=replace(s, photons=n))
    emitters, counts = global_emitters(sub, photon_counts(sub, n), {}, memo)
    pilot = trace_photons(sub, emitters, counts, caustic_only=False, stream=PILOT_STREAM,
                          should_cancel=should_cancel)
    if not len(pilot):
        return s.photons
    radius = s.radius or global_search_radius(sub, pilot, _diffuse_area(ctx))[0]
    share = indirect_share(sub, pilot, radius)
    stats["pilot_photons"], stats["pilot_share"] = int(pilot.emitted), share
    return photons_for_share(s.photons, share)


def photon_counts(ctx: Context, total: int) -> list[int]:
    """Global photons per prepared light: a light named in scene.photons_per_light (the
    paper's MaxRayPerLightSrc, engine/api.py) emits exactly that many; the others share
    what is left of `total` in proportion to their power (lights.allocate_photons)."""
    fixed = getattr(ctx.scene, "photons_per_light", None) or {}
    own = [li.source is not None and li.name in fixed for li in ctx.lights]
    if not any(own):
        return allocate_photons(ctx.lights, total)
    rest = [li for li, o in zip(ctx.lights, own) if not o]
    spare = max(total - sum(fixed[li.name] for li, o in zip(ctx.lights, own) if o), 0)
    shared = iter(allocate_photons(rest, spare))
    return [fixed[li.name] if o else next(shared) for li, o in zip(ctx.lights, own)]


def global_emitters(ctx: Context, counts: list[int], stats: dict, memo: dict | None = None):
    """The global shot's emitters and photon counts: with visual importance
    (engine/visualimportance.py) the photons go where the camera's gather rays end; else
    ctx.lights with `counts`. Off for the paper's method (its photons are the paper's:
    power-proportional, docs/paper_mode.md), for a scene that fixes photons per light,
    where the global map serves no indirect light, and without final gathering (the map
    is then read at camera hits, where its light has mostly bounced in from elsewhere:
    aiming the photons' first hits there starves it). stats gets the decision
    (photon_importance: one line). memo: a dict that keeps the region of interest
    (visualimportance.region_of_interest: a camera pre-pass) for the next call of the
    same pass (global_photon_count's pilot, then the shot), or None."""
    s = ctx.settings
    ctx.lookups = None  # (this pass': set below where visual importance traces them)
    if not (s.photon_importance and ctx.plan.indirect and s.final_gather
            and not s.paper_mode and not getattr(ctx.scene, "photons_per_light", None)):
        if s.photon_importance and ctx.plan.indirect and not s.paper_mode:
            # Portals keep each light's count and where its photons land inside: they
            # only drop the photons that meet the room's outside (engine/portal.py).
            from .portal import portal_plan
            emitters, counts, said = portal_plan(ctx, list(ctx.lights), counts)
            if said:
                stats["photon_portals"] = said
            return emitters, counts
        return ctx.lights, counts
    from .visualimportance import plan_global_shot, region_of_interest
    memo = {} if memo is None else memo
    if "region" not in memo:  # (None is a kept answer: no region)
        memo["region"] = region_of_interest(ctx)
    region = memo["region"]
    ctx.lookups = np.zeros((0, 3)) if region is None else region.points
    shot = plan_global_shot(ctx, ctx.lights, s.photons, counts, region)
    stats["photon_importance"] = shot.report
    # Photons from infinity (a world, a sun) fall evenly on every open surface to its far
    # edge, so a large ground's far photons set the whole shot's spacing; a local light's
    # thin out with distance, their spacing is already that near the light (Figure 8's
    # spot: 0.149 m over the shot, 0.084 m in the region; not measured against Cycles:
    # left as it was). None: the shot stays natural, or no light is at infinity.
    if any(isinstance(light, InfiniteLight) for light in ctx.lights):
        ctx.importance_region = shot.region
    emitters, counts = shot.emitters, shot.counts
    # The world's and suns' photons from the window panes in a room lit through them
    # (engine/portal.py).
    from .portal import portal_plan
    from .visualimportance import RegionEmitter
    aimed = any(isinstance(e, RegionEmitter) for e in emitters)
    emitters, counts, said = portal_plan(ctx, emitters, counts, region)
    if said:
        stats["photon_portals"] = said
        if aimed and not any(isinstance(e, RegionEmitter) for e in emitters):
            stats.pop("photon_importance", None)  # (its aimed lights now start on portals)
    # Window glass's rims pipe a line of light to the pane's edges; its photons are the
    # global shot's where the caustic map is built from it (visualimportance.aim_at_rims).
    plan = ctx.plan
    from . import visualimportance
    if (visualimportance.RIM_AIM and plan.window_glass and plan.caustics
            and plan.caustics_from_global):
        emitters, counts, said = visualimportance.aim_at_rims(ctx, emitters, counts)
        if said:
            stats["photon_importance"] = "; ".join(x for x in (shot.report, said) if x)
    return emitters, counts


# The glow shot (issue 14, roughglint). Light that reaches a diffuse surface off a rough
# specular layer first (roughness >= 0.3: effects.is_sharp) or window glass is not aimed
# at; those L S+ D paths came from the global shot's caustic-kind photons. With visual
# importance (engine/visualimportance.py) that shot's photons starting outside its region
# carry count / outside-count of a natural photon's power (~10x at ROI_MIN_OUTSIDE), and
# few of them turn glossy: sunlit far grass put 222 glow photons into a trial's caustic
# map (5.5 W against the 2,562 aimed ones' 1.8 W), the heaviest 0.64 W; the caustic
# estimate takes the k nearest photons, so each made a 1.4 m disc: a sun-coloured blob of
# +57 % on one seed (docs/performance.md, "sunglint"). Where the global shot is aimed so,
# those paths (the same partition: trace_photons' first_hit) come from a caustic-only
# shot of their own, GLOW_SPLIT x the global shot's photons in the region and outside at
# least GLOW_SPLIT x the natural count (glow_emitters): the same expected light from
# lighter photons (Jensen's splitting by count), each traced only to its first diffuse
# hit. Where the global shot is natural, its caustic photons are used as before.
# The glow's sources (EffectPlan.glow_label's kinds) in the maps line's words.
GLOW_KIND_WORDS = {"glossy": "soft glow off rough specular layers",
                   "glass": "light off or through glass",
                   "translucent": "light through translucent surfaces"}
GLOW_SHOT = True  # False: the glow from the global shot's photons, as before (A/B benches)
# The caustic and glow shots left untraced where no photon of theirs can be read
# (glossysplit.maps_unread; _photon_pass). False: traced as before (A/B benches; the same
# image bits).
SKIP_UNREAD_SHOTS = True
GLOW_STREAM = 3  # trace_photons' random stream of the glow shot (global 1, caustic 2)
GLOW_SPLIT = 4.0  # glow photons per global photon, and outside per natural one (glow_emitters)
# The glow shot's split follows the glow's share of the light the camera sees
# (visualimportance.glow_share, an rms of per-hit shares): GLOW_SPLIT from this share up,
# in proportion below it, never under 1 (no glow photon heavier than a natural photon or
# than the global shot's aimed ones). Caustic-map noise in a pixel is about share^2 x V / N
# for N photons, their cost about N: variance x cost is least with N in proportion to
# the share, as gather_count's rays. The roughglint wall (the shot's reason: sunlit grass's
# specular layer most of a shaded wall's light) reads 0.11; small exteriors under a sun and
# sky, a world colour or an area light 0.02-0.03, where the 4x shot (2.0-2.4M photons to
# store 1.5-7k) was 40 % of a 16-spp render's CPU (docs/performance.md, "exterior42").
GLOW_SHARE_FULL = 0.08
# Beside an aimed caustic map, the glow shot's photons make a map of their own
# (Context.glow_map), estimated at the glow's samples a pixel (integrator.smooth_per_pixel)
# and capped at glow_radius; False: held in the caustic map with the aimed photons, under
# its cap, as before (A/B: bench/bench_accuracy_ab.py's @render.GLOW_MAP_APART=False).
GLOW_MAP_APART = True
GLOW_SHARE_EXTENT_CAP = False  # True: glow_share capped at 0.1 x the extent, as before (A/B)


def glow_radius(caustic_cap: float, diffuse_area: float, positions: np.ndarray, k: int,
                extent: float, workers: int = 1) -> float:
    """Max search radius (m) of the glow map's k-NN estimates (GLOW_MAP_APART): the glow
    photons' own spacing (photonmap.auto_radius over positions (N,3), twice their median
    k-NN distance, at most 0.1 x extent), as the secondary map's, never below the caustic
    map's cap caustic_cap (the global photons' spacing). Light off rough specular layers
    comes through lobes of GGX alpha 0.09 and more and spreads over much of a room; under
    the global spacing the few, unevenly heavy glow photons of a wall made blotches
    (tableroom45, docs/accuracy.md: 4 photons, 1.9 effective, a disc on the back wall;
    5 x 5-pixel means up to 1.10 of Cycles' where Cycles 256 spp reads 1.06)."""
    if len(positions) == 0:
        return caustic_cap
    return max(caustic_cap, auto_radius(diffuse_area, len(positions), k, extent, positions,
                                        workers=workers))


def glow_split(share: float | None) -> float:
    """Glow photons per global photon (and outside the region per natural one) for a
    glow of rms share `share` (visualimportance.glow_share; None: not known, GLOW_SPLIT):
    GLOW_SPLIT x share / GLOW_SHARE_FULL, from 1 to GLOW_SPLIT."""
    if share is None or not math.isfinite(share):
        return GLOW_SPLIT
    return float(min(GLOW_SPLIT, max(1.0, GLOW_SPLIT * share / GLOW_SHARE_FULL)))


def glow_emitters(emitters, counts, natural, split: float = GLOW_SPLIT) -> tuple:
    """The glow shot's (emitters, counts) from the global shot's (global_emitters: lights
    or visualimportance.RegionEmitters / portal.PortalEmitters, in ctx.lights' order) and the natural photon
    counts per light (photon_counts). A RegionEmitter emits `split` (glow_split) x its
    aimed photons (into the region: each 1 / split of the global shot's) and outside at
    least split x the light's natural count (each at most 1 / split of a natural
    photon's power); the split of the emission space is the RegionEmitter's, so the
    expected power anywhere is the light's own. Lights that do not aim keep split x
    their global counts."""
    out_e, out_c = [], []
    for e, c, nat in zip(emitters, counts, natural):
        if getattr(e, "share", None) is None or c <= 0:
            out_e.append(e)
            out_c.append(int(round(split * c)))
            continue
        aimed = split * e.share * c
        outside = split * max((1.0 - e.share) * c, nat)
        total = max(int(round(aimed + outside)), 1)
        g = copy.copy(e)  # the same light, region and sphere probabilities
        g.share = min(aimed / total, 1.0)
        out_e.append(g)
        out_c.append(total)
    return out_e, out_c


def _importance_aimed(emitters) -> bool:
    """Whether global_emitters' emitters aim by visual importance (a RegionEmitter among
    them): their photons' power then differs by where they start."""
    from .portal import PortalEmitter
    from .visualimportance import RegionEmitter
    return any(isinstance(e, (RegionEmitter, PortalEmitter)) for e in emitters)


def _allocate_aimed(ctx, targets, total):
    """Caustic photons per light in proportion to the power each sends at the casters
    (estimated with a small pilot batch of aimed photons). A sun's power at the
    single-plane panes its shadow rays refract through (engine/panelight.py) is left out:
    its photons through them are direct, which the caustic shot does not keep (a sun and a
    lamp over a pane: 68 of 100,000 caustic photons stored, the sun's share all lost); the
    world's likewise (paneworld32)."""
    rng = np.random.default_rng([ctx.settings.seed, 98])
    panes = panes_for(ctx)
    others = None  # the targets that are not panes, for the panes' suns and world
    if panes is not None:
        pane_ids = {int(ctx.geo.object_id[p.rows[0]]) for p in panes.panes}
        keep = np.array([int(i) not in pane_ids for i in ctx.plan.caster_sphere_ids],
                        bool)
        if len(keep) == len(targets[1]) and not keep.all():
            others = (targets[0][keep], targets[1][keep])
    weights = []
    for light in ctx.lights:
        aim = targets
        if others is not None and panes.serves(light):
            if not len(others[1]):
                weights.append(0.0)
                continue
            aim = others
        _, _, power = light.emit_towards(256, rng, *aim)
        weights.append(float(luminance(power.sum(axis=0))))
    w = np.array(weights)
    if w.sum() <= 0:
        return [0] * len(ctx.lights)
    share = w / w.sum() * total
    counts = np.floor(share).astype(int)
    counts[np.argsort(-(share - counts))[: total - counts.sum()]] += 1
    return counts.tolist()


# The photon-hit view (the paper's Fig. 6, left): one dot per drawn photon, coloured by
# the kind of path that brought it (engine/photons.py), on black.
PHOTON_KIND_COLORS = {
    DIRECT: (1.0, 0.85, 0.25),          # yellow: straight from a light
    INDIRECT: (0.25, 0.55, 1.0),        # blue: after a diffuse bounce (global map)
    CAUSTIC_DIFFUSE: (0.25, 0.55, 1.0),
    CAUSTIC: (1.0, 0.25, 0.85),         # magenta: through mirrors / glass (caustic map)
}


def photon_hit_budget(in_frame: int, width: int, height: int) -> int:
    """How many of `in_frame` photons (those projecting into the image) the photon-hit
    view draws. All of them up to one per 32 pixels; beyond that the count grows only
    logarithmically, so the view never saturates (400k photons in a 160x120 image would
    cover every pixel) yet still shows more photons as more are shot."""
    base = max(64, (width * height) // 32)
    if in_frame <= base:
        return int(in_frame)
    return int(round(base * (1.0 + math.log(in_frame / base))))


VIEW_ROWS = 1 << 16  # photons per block of the photon-hit view's projection


def _photon_hit_view(ctx: Context, shots, region, width: int, height: int):
    """The photon-hit view of the photons in shots (a sequence of (position (N,3) float32,
    kind (N,) uint8) pairs, a shot's Photons.position and kind each): the photons
    stored on surfaces the camera sees directly, thinned to photon_hit_budget and drawn
    as one-pixel dots coloured by kind (PHOTON_KIND_COLORS), on black. The thinning is a
    seeded choice per photon made on the whole image, so tiles (region) agree with a full
    render. Returns (view (height, width, 3) float32 or None when no dot is drawn, dots
    drawn, the share of the photons in the image that was drawn). Queries Embree on the
    calling thread only (Accel.serial), so it may run beside the camera pass.
    _photon_hit_dots then _photon_hit_draw: a render picks the dots before its camera
    pass and lets the shots go (13 B a stored photon, and the projection's 24 B a photon
    of float64, off the camera pass' peak: docs/performance.md "perf47")."""
    return _photon_hit_draw(ctx, *_photon_hit_dots(ctx, shots, region), region, width,
                            height)


def _photon_hit_dots(ctx: Context, shots, region) -> tuple:
    """_photon_hit_view's choice of dots: (share of the photons in the image drawn, dots
    or None where none is in the region), dots = (p (D,3) float64 positions, z (D,1) their
    camera-space depth, px, py (D,) int64 pixels, kinds (D,) uint8), the candidates before
    the visibility test: at most photon_hit_budget of the image, whatever the shots'
    size."""
    shots = [(p, kinds) for p, kinds in shots if len(p)]
    if not shots:
        return 1.0, None
    cam = ctx.scene.camera
    W, H = ctx.scene.width, ctx.scene.height
    x0, y0, x1, y1 = region
    position = np.concatenate([p for p, _ in shots])  # float32
    pos = cam.position - ctx.geo.offset
    R = cam.rotation
    local = (position.astype(np.float64) - pos) @ R  # camera coordinates
    hw, hh = cam.half_extents(W, H)
    big = 2.0 * max(hw, hh)
    # Which photons project into the frame, a block of rows at a time (element by element
    # the same numbers as whole arrays, with a fraction of their memory: this view may
    # run beside the camera pass's chunks).
    n = len(position)
    frame = np.zeros(n, bool)
    cols, rows_ = [], []
    pano = None if cam.panorama is None else cam.panorama.pack(W, H, cam.sensor_fit)
    for a in range(0, n, VIEW_ROWS):
        lb = local[a:a + VIEW_ROWS]
        z = -lb[:, 2]
        if pano is not None:
            # The panorama's image coordinates of the photon's direction (its frame:
            # object axes = frame @ d, so d = object axes @ frame as rows).
            uv = panorama.directions_to_uv(pano, lb @ panorama.frame(pano))
            with np.errstate(invalid="ignore"):
                px = np.floor((uv[:, 0] - cam.shift_x) * W)
                py = np.floor((1.0 - (uv[:, 1] - cam.shift_y)) * H)
            z = np.where(np.isfinite(px + py), 1.0, 0.0)
        else:
            if cam.kind == "ORTHO":
                x, y = lb[:, 0], lb[:, 1]
            else:
                x = lb[:, 0] / np.maximum(z, 1e-300)
                y = lb[:, 1] / np.maximum(z, 1e-300)
            sx = (x - cam.shift_x * big) / hw
            sy = (y - cam.shift_y * big) / hh
            with np.errstate(invalid="ignore"):
                px = np.floor((sx + 1.0) / 2.0 * W)
                py = np.floor((1.0 - sy) / 2.0 * H)
        with np.errstate(invalid="ignore"):
            fb = (z > 0) & (px >= 0) & (px < W) & (py >= 0) & (py < H)
        frame[a:a + VIEW_ROWS] = fb
        cols.append(px[fb].astype(np.int64))
        rows_.append(py[fb].astype(np.int64))
    n_frame = int(frame.sum())
    if n_frame == 0:
        return 1.0, None
    px, py = np.concatenate(cols), np.concatenate(rows_)  # of the frame's photons, in order
    keep = photon_hit_budget(n_frame, W, H) / n_frame
    chosen = np.ones(n_frame, bool)
    if keep < 1.0:
        u = np.random.default_rng([ctx.settings.seed, 97]).random(n)
        chosen = u[frame] < keep
    fraction = min(keep, 1.0)
    inside = chosen & (px >= x0) & (px < x1) & (py >= y0) & (py < y1)
    idx = np.flatnonzero(frame)[inside]
    px, py = px[inside], py[inside]
    if len(idx) == 0:
        return fraction, None
    p = np.take(position, idx, axis=0).astype(np.float64)
    kinds = np.concatenate([kinds for _, kinds in shots])[idx]
    return fraction, (p, local[idx, 2:3], px, py, kinds)


def _photon_hit_draw(ctx: Context, fraction: float, dots, region, width: int, height: int):
    """_photon_hit_view's answer from _photon_hit_dots' (fraction, dots): the dots nothing
    hides from the camera drawn into the region."""
    if dots is None:
        return None, 0, fraction
    p, z, px, py, kinds = dots
    cam = ctx.scene.camera
    x0, y0, x1, y1 = region
    pos = cam.position - ctx.geo.offset
    R = cam.rotation
    idx = np.arange(len(p))
    # Visible only if nothing lies between the camera and the photon.
    to = p - (pos if cam.kind != "ORTHO" else p + z * R[:, 2])
    dist = np.linalg.norm(to, axis=1)
    d = to / np.maximum(dist, 1e-300)[:, None]
    origin = p - to
    # Stop short of the photon's surface by the float32 resolution there (photon
    # positions are float32) plus the float32 error of the ray's length.
    gap = 4.0 * ulp32(max3(np.abs(p))) + G32_T * dist
    blocked = ctx.accel.serial().occluded(origin, d, np.maximum(dist - gap, 0.0))
    idx, px, py = idx[~blocked], px[~blocked], py[~blocked]
    if len(idx) == 0:
        return None, 0, fraction
    rw = x1 - x0
    flat = (py - y0) * rw + (px - x0)
    table = np.zeros((max(PHOTON_KIND_COLORS) + 1, 3))
    for kind, rgb in PHOTON_KIND_COLORS.items():
        table[kind] = rgb
    colour = table[kinds[idx]]
    size = height * width
    count = np.bincount(flat, minlength=size).astype(np.float64)
    buf = np.zeros((size, 3))
    for c in range(3):
        buf[:, c] = np.bincount(flat, weights=colour[:, c], minlength=size)
    buf /= np.maximum(count, 1.0)[:, None]  # a pixel with several dots shows their mix
    return buf.reshape(height, width, 3).astype(np.float32), int(len(idx)), fraction
