"""render(): scene -> photon pass -> photon maps -> camera pass -> Film."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from .accel import Accel
from .film import Film
from .effects import EffectPlan, analyse
from .geometry import Geometry, MaterialTable, prepare
from .integrator import render_camera
from .jit import ensure_compiled
from .lights import allocate_photons, prepare_lights
from .lights.packing import pack_lights
from .photonmap import GatherMap, PhotonMap, auto_radius
from .rayoffset import G32_T, ulp32
from .sampling import luminance, max3
from .parallel import Cancelled
from .photons import CAUSTIC, CAUSTIC_DIFFUSE, INDIRECT, Photons, trace_photons
from .resources import check_resources
from .scene import Scene
from .settings import RenderSettings
from .visibility import VisibilityAccel


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
    gather_map: GatherMap | None = None
    secondary_map: PhotonMap | None = None  # caustic light after one diffuse bounce
    gather_short: float = 0.0  # gather rays shorter than this gather again from their end
    plan: EffectPlan | None = None
    global_radius: float = 0.0
    caustic_radius: float = 0.0
    packed_lights: tuple | None = None  # lights as the direct-light kernels read them
    # Light trees for many lights (engine/lights/selection.py selector_for), built on use.
    light_selectors: dict = field(default_factory=dict)


    def serial(self) -> "Context":
        """This context with every Embree and kd-tree query answered on the calling
        thread, for chunks that already run on worker threads (engine/parallel.py)."""
        def one(m):
            return None if m is None else m.serial()
        return replace(self, accel=self.accel.serial(), global_map=one(self.global_map),
                       caustic_map=one(self.caustic_map), gather_map=one(self.gather_map),
                       secondary_map=one(self.secondary_map))


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


def prepare_context(scene: Scene, settings: RenderSettings, accel_class=Accel) -> Context:
    """Validate the scene, merge and re-centre geometry, build the BVH, prepare lights and
    decide which effects to simulate. One Context serves several passes. accel_class lets
    the benchmarks record every ray query (bench/)."""
    scene.validate()
    geo, table = prepare(scene)
    # One BVH per distinct set of triangles a ray class sees (usually one in all).
    accel = VisibilityAccel(geo.vertices32, geo.faces32, geo.visibility, accel_class,
                            threads=settings.threads)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, settings, geo, table, accel, lights, packed_lights=pack_lights(lights))
    ctx.plan = analyse(scene, geo, table, lights, accel, settings)
    return ctx


def render_pass(ctx: Context, region, progress=None, should_cancel=None) -> Film:
    """Photon pass + camera pass with ctx.settings into a new Film (raises Cancelled)."""
    settings = ctx.settings
    x0, y0, x1, y1 = region
    film = Film(x1 - x0, y1 - y0, show_photons=settings.show_photons)
    stats = film.stats
    stats["cancelled"] = False
    ctx.global_map = ctx.caustic_map = ctx.gather_map = ctx.secondary_map = None
    # Compiled kernels: compiled on the first render on this machine (the progress text
    # says so), loaded from the on-disk cache by later processes, once per process.
    stats["time_compile"] = ensure_compiled(progress)
    try:
        all_photons = Photons.empty()
        if settings.photon_mapping and ctx.lights and (ctx.plan.indirect or ctx.plan.caustics):
            all_photons = _photon_pass(ctx, stats, progress, should_cancel)
        t0 = time.perf_counter()
        counters = render_camera(ctx, region, film, progress, should_cancel)
        stats["time_camera"] = time.perf_counter() - t0
        stats.update(camera_rays=counters.camera_rays, shadow_rays=counters.shadow_rays,
                     gather_rays=counters.gather_rays, specular_rays=counters.specular_rays)
        if settings.show_photons:
            _draw_photons(ctx, film, all_photons, region)
    except Cancelled:
        stats["cancelled"] = True  # the film holds what was finished
    return film


def render(scene: Scene, settings: RenderSettings | None = None, progress=None,
           should_cancel=None, region=None) -> Film:
    """Render `scene`. progress(stage, fraction, text) is called as work advances;
    should_cancel() is polled and, when it returns True, the partial Film is returned
    with film.stats['cancelled'] = True. region=(x0, y0, x1, y1) renders only that window
    (top-left origin, exclusive max) and the Film has its size. Raises SceneError for a
    scene that cannot render, ResourceError (engine/resources.py) for one that would not
    fit in the available memory - both before anything big is allocated."""
    settings = settings or RenderSettings()
    t_start = time.perf_counter()
    scene.validate()
    region = _check_region(region, scene.width, scene.height)
    check_resources(scene, settings, region)
    ctx = prepare_context(scene, settings)
    t_prepare = time.perf_counter() - t_start
    try:
        film = render_pass(ctx, region, progress, should_cancel)
    finally:
        ctx.accel.close()
    film.stats.update(effects=ctx.plan.report(), triangles=ctx.geo.count, lights=len(ctx.lights),
                      extent=ctx.geo.extent, time_prepare=t_prepare,
                      time_total=time.perf_counter() - t_start)
    film.warnings = scene.all_warnings()
    return film


def _photon_pass(ctx: Context, stats, progress, should_cancel) -> Photons:
    s, geo, table, plan = ctx.settings, ctx.geo, ctx.table, ctx.plan
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
    if plan.indirect or (plan.caustics and not use_caustic_shot) or split is not None:
        counts = allocate_photons(ctx.lights, s.photons)
        shot = trace_photons(ctx, ctx.lights, counts, caustic_only=False, stream=1,
                             progress=progress, should_cancel=should_cancel,
                             first_hit=None if split is None else (split, False))
    caustic = Photons.empty()
    if use_caustic_shot:
        if targets is None:
            ccounts = allocate_photons(ctx.lights, s.caustic_photons)
        else:
            ccounts = _allocate_aimed(ctx, targets, s.caustic_photons)
        caustic = trace_photons(ctx, ctx.lights, ccounts, caustic_only=True, stream=2,
                                progress=progress, should_cancel=should_cancel, targets=targets,
                                first_hit=None if split is None else (split, True))
        if split is not None and len(shot):
            # The caustic paths the aimed shot leaves out, from the global shot.
            rest = shot.select(shot.kind == CAUSTIC)
            emitted = caustic.emitted
            caustic = Photons(*(np.concatenate([getattr(caustic, f), getattr(rest, f)])
                                for f in ("position", "power", "direction", "normal", "kind")))
            caustic.emitted = emitted
    stats["time_photons"] = time.perf_counter() - t0
    stats["photons_emitted"] = shot.emitted
    stats["caustic_photons_emitted"] = caustic.emitted
    if progress is not None:
        progress("photon_map", 0.0, "Building photon map")
    t0 = time.perf_counter()
    diffuse_tris = table.has_diffuse[geo.material] if geo.count else np.zeros(0, bool)
    diffuse_area = float(geo.area[diffuse_tris].sum())
    k = s.k_nearest
    workers = s.threads
    # The global radius from the global photons' own spacing (local: not the spacing they
    # would have if spread over a huge ground plane they barely light). The caustic
    # radius from the same spacing, scaled to the larger shot's count (aimed caustic
    # photons pile up on a focus: their own spacing would make it tiny); without a
    # global shot, as if the caustic photons covered the diffuse area evenly.
    r_global = auto_radius(diffuse_area, len(shot), k, geo.extent, shot.position)
    dense = max(len(shot), len(caustic), 1)
    if len(shot) > k:
        r_auto = r_global * math.sqrt(len(shot) / dense)
    else:
        r_auto = auto_radius(diffuse_area, dense, k, geo.extent)
    ctx.global_radius = s.radius or r_global
    # The precomputed irradiance is blurred over about the k-NN radius: a gather ray that
    # ends closer than that gathers once more from its end (integrator.gather_indirect).
    ctx.gather_short = ctx.global_radius
    if plan.indirect:
        if s.final_gather:
            # Final gathering needs all light at the gathered point: every stored photon.
            # Photons that arrived straight from a caustic are left out: seen through a
            # few gather rays a bright caustic makes fireflies. Their light one bounce
            # later (CAUSTIC_DIFFUSE photons) is estimated directly at the camera hit.
            gathered = shot.select(shot.kind != CAUSTIC)
            ctx.gather_map = GatherMap(gathered, ctx.global_radius, k, s.min_photons,
                                       s.estimator, accel=ctx.accel,
                                       workers=workers)
            ctx.secondary_map = PhotonMap(shot.select(shot.kind == CAUSTIC_DIFFUSE), workers)
            stats["global_photons"] = len(shot)
        else:
            ctx.global_map = PhotonMap(shot.select(np.isin(shot.kind, (INDIRECT, CAUSTIC_DIFFUSE))),
                                       workers)
            ctx.global_radius = s.radius or auto_radius(diffuse_area, len(ctx.global_map), k,
                                                        geo.extent,
                                                        ctx.global_map.photons.position)
            stats["global_photons"] = len(ctx.global_map)
    if plan.caustics:
        ctx.caustic_map = PhotonMap(caustic if use_caustic_shot
                                    else shot.select(shot.kind == CAUSTIC), workers)
    ctx.caustic_radius = s.radius or r_auto
    stats["caustic_photons"] = len(ctx.caustic_map) if ctx.caustic_map is not None else 0
    stats["radius_global"] = ctx.global_radius
    stats["radius_caustic"] = ctx.caustic_radius
    stats["time_photon_map"] = time.perf_counter() - t0
    stats["photon_bytes"] = shot.nbytes + caustic.nbytes
    if not s.show_photons:
        return Photons.empty()  # only the photon-hit view needs them after this point
    return Photons(*(np.concatenate([getattr(shot, f), getattr(caustic, f)])
                     for f in ("position", "power", "direction", "normal", "kind")))


def _allocate_aimed(ctx, targets, total):
    """Caustic photons per light in proportion to the power each sends at the casters
    (estimated with a small pilot batch of aimed photons)."""
    rng = np.random.default_rng([ctx.settings.seed, 98])
    weights = []
    for light in ctx.lights:
        _, _, power = light.emit_towards(256, rng, *targets)
        weights.append(float(luminance(power.sum(axis=0))))
    w = np.array(weights)
    if w.sum() <= 0:
        return [0] * len(ctx.lights)
    share = w / w.sum() * total
    counts = np.floor(share).astype(int)
    counts[np.argsort(-(share - counts))[: total - counts.sum()]] += 1
    return counts.tolist()


def _draw_photons(ctx: Context, film: Film, photons: Photons, region):
    """Splat visible photon hits into film.photon_hits (the paper's Fig. 6, left)."""
    if len(photons) == 0:
        return
    cam = ctx.scene.camera
    W, H = ctx.scene.width, ctx.scene.height
    x0, y0, x1, y1 = region
    p = photons.position.astype(np.float64)
    pos = cam.position - ctx.geo.offset
    rel = p - pos
    R = cam.rotation
    local = rel @ R  # camera coordinates
    hw, hh = cam.half_extents(W, H)
    big = 2.0 * max(hw, hh)
    if cam.kind == "ORTHO":
        z = -local[:, 2]
        x, y = local[:, 0], local[:, 1]
    else:
        z = -local[:, 2]
        x = local[:, 0] / np.maximum(z, 1e-300)
        y = local[:, 1] / np.maximum(z, 1e-300)
    sx = (x - cam.shift_x * big) / hw
    sy = (y - cam.shift_y * big) / hh
    px = np.floor((sx + 1.0) / 2.0 * W).astype(np.int64)
    py = np.floor((1.0 - sy) / 2.0 * H).astype(np.int64)
    inside = (z > 0) & (px >= x0) & (px < x1) & (py >= y0) & (py < y1)
    idx = np.nonzero(inside)[0]
    if len(idx) == 0:
        return
    # Visible only if nothing lies between the camera and the photon.
    to = p[idx] - (pos if cam.kind != "ORTHO" else p[idx] + local[idx, 2:3] * R[:, 2])
    dist = np.linalg.norm(to, axis=1)
    d = to / np.maximum(dist, 1e-300)[:, None]
    origin = p[idx] - to
    # Stop short of the photon's surface by the float32 resolution there (photon
    # positions are float32) plus the float32 error of the ray's length.
    gap = 4.0 * ulp32(max3(np.abs(p[idx]))) + G32_T * dist
    blocked = ctx.accel.occluded(origin, d, np.maximum(dist - gap, 0.0))
    idx = idx[~blocked]
    if len(idx) == 0:
        return
    rw = x1 - x0
    flat = (py[idx] - y0) * rw + (px[idx] - x0)
    colour = photons.power[idx].astype(np.float64)
    colour = colour / np.maximum(colour.max(axis=1, keepdims=True), 1e-300)
    buf = np.zeros((film.height * film.width, 3))
    for c in range(3):
        buf[:, c] = np.bincount(flat, weights=colour[:, c], minlength=len(buf))
    peak = buf.max(axis=1, keepdims=True)
    buf = np.where(peak > 0, buf / np.maximum(peak, 1e-300), 0.0)
    film.photon_hits[...] = buf.reshape(film.height, film.width, 3).astype(np.float32)
