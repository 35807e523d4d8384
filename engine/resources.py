"""Resources checked before they are committed: a render's peak memory is estimated from
its settings and scene size and compared with the memory the machine has available, so
a render that cannot fit is refused in one line instead of growing until the machine
dies (issue 16). The settings' hard limits live in engine/settings.py (LIMITS).

The per-item costs are measured peak resident memory (ru_maxrss) of renders that vary
one size at a time, rounded up; `bench/bench_memory.py` prints the estimate beside the
measured peak for a set of renders. What each part counts:

- photons: each stored photon (57 B of arrays: 4 of them its bounce counts, 4 its
  surface's object id) with its copies, the kd-trees over it and the gather map. A
  global shot stores a photon at every diffuse hit until Russian roulette (or a bounce
  limit) ends it: measured 2.1 stored per emitted photon in the closed Figure 6 box, 0.7
  in the open Figure 3 scene; the estimate takes STORES_PER_PHOTON. A caustic shot
  stores at most one per emitted photon.
- photon chunks / camera chunks: the arrays of the photons or camera samples that are
  being traced at the same time (one chunk per worker thread, engine/parallel.py).
- image: the per-pixel accumulators (float64), the Film (float32 per pass) and, for a
  progressive render, the running sums; Blender's render result when rendering there.
- triangles: the scene's arrays, the merged tables and Embree's BVH (instances traced
  two-level keep their prototypes' tables and BVH once: instance_choice).
- environment: the sampling tables an environment map's light builds at prepare
  (engine/lights/environment.py): the cosine-weighted distributions of the shadow rays
  (N_OCT^2 clusters of coarse cells, ~10.7 MB, plus float64 prefix sums of the map's
  size) and, when photons are shot, the map's own distribution (float64 column cdfs and
  a float32 pdf of the map's size): 8k x 4k texels keep 682 MB (environment_bytes: the
  exact array sizes), and building them takes ENV_BUILD_BYTES_PER_TEXEL more for a moment
  (tests/test_resources_measured.py checks both against the arrays).
- data passes: Cycles' data passes when asked for (engine/datapasses.py): per pixel and
  channel a float64 sum, the Film's float32 copy and, in Blender, the render result's
  float32 pass (BYTES_PER_DATA_CHANNEL...).
- cryptomatte: the ID mattes when asked for (engine/cryptomatte.py): per pixel, layer and
  rank the hash and coverage (uint32 + float32), the float ids and the Film's float32
  passes (BYTES_PER_CRYPTOMATTE_RANK; in Blender the render result's passes too), and
  one chunk of primary rays in flight.
- visibility pre-test: photon visibility's pre-test grids (engine/onesurface.py
  OneSurfaceCells), kept for the render, one set per radius the estimates use (the global,
  caustic and secondary maps': VISIBILITY_RADII), each at most onesurface.KEPT_BYTES_MAX
  (its cell caps); they do not grow with the image, the samples or the orientations asked.
  Before issues 13/14's fix they did: a 300-object outdoor scene (bench/
  bench_outdoor_scale.py, 103k triangle orientations) grew 2.7 GB in its 80x60 camera
  pass (10 KB per in-flight camera sample; tracemalloc: 2.1 GB of it the orientation
  lookup's pairwise arrays and the per-orientation grids), now 0.48 GB (1.8 KB; the
  estimate's 1900 B a sample holds), the grids 17 MB (docs/performance.md "scale").
- visibility read lists: each render thread's photon visibility read lists (photon ids
  and weights, photonvisibility._read_buffers), kept for the thread's life: 32 MB a thread
  at k = 64.
- regather maps: the bounce limits' deeper gather levels (photonmap.GatherMap subsets,
  engine/render.py _build_maps): per level the irradiance and boundary flag of every
  gather point, counted at the most levels (integrator.MAX_GATHER_LEVEL) whenever the
  limits can drop photons.
- gather lookups' photons: where the limits can drop photons (regather_levels), the
  gather map keeps the photons its points' estimates read (photonmap.GatherMap
  estimating: their kd-tree, power, directions, normals, kinds, surfaces and count
  classes), for the lookups after a chain whose counts drop some of them
  (chaincounts.subset_irradiance), and the irradiance of each point and count asked
  (32 B each, only those asked).
- regather secondary shares: per regathering level (integrator.MAX_GATHER_LEVEL) the
  secondary-caustic share of every gather point's irradiance (GatherMap.secondary_levels,
  read by the regathered ends: integrator.SECONDARY_FROM_GATHER_POINTS).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from .parallel import chunk_length
from .settings import RenderSettings

MAX_RESOLUTION = 65536  # pixels per side, as Blender's resolution_x / resolution_y

BYTES_PER_STORED_PHOTON = 320   # measured 278 (figure3.toml) and 285 (Figure 6 box)
STORES_PER_PHOTON = 2.5         # global-shot photons stored per emitted (see above)
BYTES_PER_TRACED_PHOTON = 400   # in flight in a chunk; measured 324
BYTES_PER_CAMERA_SAMPLE = 1900  # in flight in a chunk; measured 1.5-1.7 K (1-16 light
#                                 samples, 1-8 gather rays: they are traced in sub-batches)
BYTES_PER_PIXEL = 300           # accumulators 168 B + Film 92 B + write-out copies
BYTES_PER_PIXEL_PROGRESSIVE = 350  # running sums, halves, one pass's Film
BYTES_PER_PIXEL_BLENDER = 260   # render result passes (float32) and the copies written
# A data pass's channel (engine/datapasses.py): the float64 sum and the Film's float32
# copy; in Blender its render result pass (float32) too; progressive: one more float64 sum.
BYTES_PER_DATA_CHANNEL = 12
BYTES_PER_DATA_CHANNEL_BLENDER = 4
BYTES_PER_DATA_CHANNEL_PROGRESSIVE = 8
# A Cryptomatte rank (engine/cryptomatte.py): hash and coverage, the float ids, the
# Film's pass (id, coverage float32); in Blender the render result's pass too.
BYTES_PER_CRYPTOMATTE_RANK = 20
BYTES_PER_CRYPTOMATTE_RANK_BLENDER = 8
BYTES_PER_CRYPTOMATTE_RAY = 160  # a chunk's primary rays: jitter, rays, hits, ids
BYTES_PER_TRIANGLE = 320        # measured peak 240-290 (bench_memory.py --triangles); tables + BVH
# Embree's copy and BVH of a triangle (default BVH ~91 B, compact ~61 B; docs/performance.md
# "Memory per triangle").
BYTES_PER_BVH_TRIANGLE = 95
# Instanced geometry is expanded into world-space copies (tables and BVH: fastest to
# trace, 2-3x faster per ray) only while that is small; otherwise it is traced two-level
# with its tables shared (engine/instancing.py, engine/sharedrows.py; docs/performance.md,
# "Instancing"): when the copies' extra memory (BYTES_PER_TRIANGLE a triangle beyond the
# prototypes') exceeds INSTANCE_BUDGET_FRACTION of the available memory, or when the
# copies hold more than INSTANCE_RATIO times the prototypes' triangles and their extra
# memory exceeds INSTANCE_FLOOR bytes.
INSTANCE_BUDGET_FRACTION = 1 / 32
INSTANCE_RATIO = 4
INSTANCE_FLOOR = 64 << 20
INSTANCE_BUDGET_UNKNOWN = 256 << 20  # bytes, when the available memory is unknown
BYTES_PER_INSTANCE = 400  # a shared instance: record, matrices, top-level box and node
# The regathers' maps: GatherMap's gather points are every step-th photon (at most
# GATHER_MAX_POINTS of those: GatherMap's max_points), and more where photons are sparse
# (photonmap._point_shares): measured 1.08x the every-step-th points in the Figure 6 box
# at the defaults (60,739 points of 733,827 photons), 0.99x on an HDRI-lit ground;
# GATHER_POINT_SPREAD leaves room above that. Each deeper level holds a (P,3) float32
# irradiance per point (photonmap.LEVEL_DTYPE); the boundary flags are the level-0 map's
# (shared).
# The estimating photons a gather map keeps for its lookups' subsets (GatherMap
# estimating, counts_cache): float32 position, power, direction, normal (48 B), kind,
# surface (5 B), the kd-tree's share and a count class (1-2 B), and the sparse per-count
# answers (32 B an asked point and count): measured 53 B a photon of Figure 6's 658 k
# estimating photons plus 0.4 MB of answers (docs/performance.md, mem45).
BYTES_PER_KEPT_GATHER_PHOTON = 64
GATHER_MAX_POINTS = 60_000
GATHER_POINT_SPREAD = 1.25
BYTES_PER_GATHER_POINT_LEVEL = 12
# Building an environment map's tables (lights.environment.texel_function: the texels as
# float64, their luminance and its filtered copies) holds this much per texel beyond the
# tables for a moment (tracemalloc, 2k x 1k: peak 40.0 B/texel with the cosine tables'
# 13.1 kept, 53.2 with both distributions' 25.1).
ENV_BUILD_BYTES_PER_TEXEL = 30
# Photon visibility's pre-test keeps a grid set for each radius it is asked with: the
# global, caustic and secondary maps' (engine/integrator.py's visible_irradiance calls).
VISIBILITY_RADII = 3


class ResourceError(ValueError):
    """A render that would exceed a limit or the available memory (one-line message)."""


@dataclass
class MemoryEstimate:
    """Estimated peak bytes of a render, by part. `drivers` names, for each part, the
    setting that controls it (for the refusal message)."""

    parts: dict = field(default_factory=dict)
    drivers: dict = field(default_factory=dict)

    @property
    def total(self) -> int:
        return int(sum(self.parts.values()))

    def largest(self) -> str:
        return max(self.parts, key=self.parts.get)

    def summary(self) -> str:
        ordered = sorted(self.parts.items(), key=lambda kv: -kv[1])
        return ", ".join(f"{name} {format_bytes(b)}" for name, b in ordered if b > 0)


# The modules whose objects make up a render's photon maps (held_bytes walks into these
# alone: an Embree scene or the Geometry a map refers to is not the map's memory).
MAP_MODULES = ("engine.photonmap", "engine.photons", "engine.kdtree", "engine.hashgrid",
               "engine.mortontree", "engine.chaincounts", "engine.guiding")


def held_bytes(*roots) -> int:
    """Bytes of the numpy arrays reachable from `roots` (maps, tuples, dicts of them)
    through the attributes of objects of MAP_MODULES, each buffer once however many views,
    maps or subset maps share it (a view counts its whole base array: what it keeps
    alive). Attributes named "accel" (Embree's scene) are not followed. The photon pass'
    stats["photon_bytes"] (engine/render.py): what its maps hold through the camera
    pass, lazy gather maps' masks and arrays to fill included."""
    import numpy as np
    seen, total = set(), 0
    stack = list(roots)
    while stack:
        obj = stack.pop()
        if isinstance(obj, np.ndarray):
            base = obj
            while isinstance(base.base, np.ndarray):
                base = base.base
            key = ("a", base.__array_interface__["data"][0], base.nbytes)
            if key not in seen:
                seen.add(key)
                total += base.nbytes
            continue
        if obj is None or isinstance(obj, (int, float, str, bool)) or id(obj) in seen:
            continue
        if isinstance(obj, (list, tuple)):
            seen.add(id(obj))
            stack.extend(obj)
        elif isinstance(obj, dict):
            seen.add(id(obj))
            stack.extend(obj.values())
        elif type(obj).__module__ in MAP_MODULES and hasattr(obj, "__dict__"):
            seen.add(id(obj))
            stack.extend(v for k, v in vars(obj).items() if k != "accel")
    return total


def format_bytes(n: float) -> str:
    n = float(n)
    for unit in ("B", "KB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1024 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024.0
    return f"{n:.1f} PB"  # pragma: no cover


def available_memory() -> int | None:
    """Bytes of memory available to this process without swapping, or None if unknown.
    Linux: MemAvailable of /proc/meminfo, lowered to the cgroup (container) limit if
    one is set; else psutil if installed; else os.sysconf; Windows: GlobalMemoryStatusEx."""
    avail = None
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        avail = None
    if avail is not None:
        cg = _cgroup_room()
        return min(avail, cg) if cg is not None else avail
    try:
        import psutil  # optional: not a dependency
        return int(psutil.virtual_memory().available)
    except Exception:  # noqa: BLE001 - not installed or not supported here
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        pass
    if os.name == "nt":  # pragma: no cover - Windows only
        try:
            import ctypes

            class _Status(ctypes.Structure):
                _fields_ = [("dwLength", ctypes.c_ulong), ("dwMemoryLoad", ctypes.c_ulong),
                            ("ullTotalPhys", ctypes.c_ulonglong),
                            ("ullAvailPhys", ctypes.c_ulonglong),
                            ("ullTotalPageFile", ctypes.c_ulonglong),
                            ("ullAvailPageFile", ctypes.c_ulonglong),
                            ("ullTotalVirtual", ctypes.c_ulonglong),
                            ("ullAvailVirtual", ctypes.c_ulonglong),
                            ("ullAvailExtendedVirtual", ctypes.c_ulonglong)]
            st = _Status()
            st.dwLength = ctypes.sizeof(_Status)
            if ctypes.windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(st)):
                return int(st.ullAvailPhys)
        except Exception:  # noqa: BLE001
            pass
    return None


def _cgroup_room() -> int | None:
    """Bytes left under a cgroup v2 memory limit (containers), or None without a limit."""
    try:
        with open("/sys/fs/cgroup/memory.max", encoding="ascii") as f:
            limit = f.read().strip()
        if limit == "max":
            return None
        with open("/sys/fs/cgroup/memory.current", encoding="ascii") as f:
            current = int(f.read().strip())
        return max(0, int(limit) - current)
    except (OSError, ValueError):
        return None


def _triangles(scene) -> int:
    return int(sum(len(mesh.faces) for mesh in scene.meshes))


def instance_budget(available: int | None = None) -> int:
    """Bytes the expanded instance copies may take beyond their prototypes
    (INSTANCE_BUDGET_FRACTION of the available memory, INSTANCE_BUDGET_UNKNOWN when that
    is unknown)."""
    room = available_memory() if available is None else int(available)
    return INSTANCE_BUDGET_UNKNOWN if room is None else int(room * INSTANCE_BUDGET_FRACTION)


def instance_choice(copies: int, shared: int, available: int | None = None):
    """(two_level, reason): how to trace `copies` instanced triangles whose prototypes
    hold `shared` triangles (the rule above INSTANCE_BUDGET_FRACTION); reason is one line
    for the effect report."""
    extra = max(0, copies - shared) * BYTES_PER_TRIANGLE
    budget = instance_budget(available)
    if extra > budget:
        why = f"expanding would add {format_bytes(extra)}, over {format_bytes(budget)}"
    elif copies > INSTANCE_RATIO * shared and extra > INSTANCE_FLOOR:
        why = (f"{copies / max(shared, 1):.0f}x the prototypes' triangles; expanding would "
               f"add {format_bytes(extra)}")
    else:
        return False, (f"{copies:,} instanced triangles expanded (adds {format_bytes(extra)}; "
                       "fastest to trace)")
    return True, (f"{copies:,} instanced triangles traced two-level from {shared:,} shared "
                  f"({why})")


def two_level_instances(instances, available: int | None = None) -> bool:
    """True when instances (engine.instancing.Instances) should be traced two-level
    with shared tables (instance_choice)."""
    shared = sum(len(f) for _, f in instances.prototypes)
    return instance_choice(instances.instanced_triangles(), shared, available)[0]


def _instanced_triangles(scene) -> int:
    """(copies, shared, count): the triangles of meshes with an instance record
    (Mesh.prototype), their prototypes' triangles counted once, and the instances."""
    protos = {id(m.prototype): len(m.prototype.faces) for m in scene.meshes
              if getattr(m, "prototype", None) is not None}
    placed = [m for m in scene.meshes if getattr(m, "prototype", None) is not None]
    copies = sum(len(m.faces) for m in placed)
    return int(copies), int(sum(protos.values())), len(placed)


def environment_bytes(env, photons: bool = True) -> int:
    """Bytes of the sampling tables that an environment map (lights.environment.Environment,
    H x W texels) builds at prepare: its cosine_distributions (the shadow rays'; always)
    and, with photons, its distribution (the world's photons are emitted from it)."""
    from .lights import environment as em
    H, W = int(env.height), int(env.width)
    K = em.N_OCT * em.N_OCT
    Hc, Wc = min(H, em.COARSE_H), min(W, em.COARSE_W)
    # rows (K,Hc+1), cols (K,Hc,Wc+1), mass (K,Hc,Wc), prefix (H,W+1), cell (Hc,Wc): float64
    cosine = 8 * (K * (Hc + 1) + K * Hc * (Wc + 1) + K * Hc * Wc + H * (W + 1) + Hc * Wc)
    # rows (H+1,) and cols (H,W+1) float64, pdf_uv (H,W) float32
    own = 8 * ((H + 1) + H * (W + 1)) + 4 * H * W
    return cosine + (own if photons else 0)


def regather_levels(settings: RenderSettings) -> int:
    """The most regather levels with maps of their own (GatherMap subsets) that the
    bounce limits can make: integrator.MAX_GATHER_LEVEL when a photon's bounces
    (max_photon_depth) plus the camera side's at the deepest level can pass a limit,
    else 0 (e.g. every limit at 1024)."""
    from .integrator import MAX_GATHER_LEVEL
    s = settings
    if not (s.uses_photon_maps and s.final_gather and s.photons):
        return 0
    reach = int(s.max_photon_depth) + MAX_GATHER_LEVEL + 2  # + the lookup's diffuse bounce
    return MAX_GATHER_LEVEL if int(min(s.bounce_limits)) < reach else 0


def gather_points(stored: float) -> int:
    """The most gather points a GatherMap over `stored` photons takes (see
    GATHER_POINT_SPREAD)."""
    n = int(math.ceil(stored))
    if n < 2:
        return 0
    step = max(4, -(-n // GATHER_MAX_POINTS))
    return int(math.ceil(-(-n // step) * GATHER_POINT_SPREAD))


def data_pass_channels(settings: RenderSettings) -> int:
    """Channels per pixel of the data passes settings.data_passes asks for (Denoising
    Normal / Albedo / Depth: 3 + 3 + 1; the three Color passes: 9; Object / Material
    Index and Mist 1 each, Position and UV 3 each; a Shader AOV 1, a colour one 4)."""
    from .datapasses import keys, wanted
    return sum(channels for _name, _key, channels in keys(wanted(settings)))


def estimate_memory(scene, settings: RenderSettings, region=None, progressive=False,
                    in_blender=False) -> MemoryEstimate:
    """Peak memory of rendering `scene` with `settings` (bytes, by part). region =
    (x0, y0, x1, y1) pixels or None for the whole image."""
    s = settings
    if region is None:
        w, h = int(scene.width), int(scene.height)
    else:
        w, h = int(region[2]) - int(region[0]), int(region[3]) - int(region[1])
    pixels = max(0, w) * max(0, h)
    tris = _triangles(scene)
    threads = s.threads
    est = MemoryEstimate()

    if s.uses_photon_maps and (s.photons or s.caustic_photons):
        stores = min(float(s.max_photon_depth), STORES_PER_PHOTON)
        stored = s.photons * stores + s.caustic_photons
        est.parts["photon maps"] = int(stored * BYTES_PER_STORED_PHOTON)
        est.drivers["photon maps"] = ("photons" if s.photons * stores >= s.caustic_photons
                                      else "caustic_photons")
        if any(getattr(m, "shadow_catcher", False) for m in scene.meshes):
            # The catchers-alone pass' maps, held with the scene's (engine/shadowcatcher.py):
            # a ground plane stores each photon once (it cannot send one back to itself).
            est.parts["shadow catcher maps"] = int((s.photons + s.caustic_photons)
                                                   * BYTES_PER_STORED_PHOTON)
            est.drivers["shadow catcher maps"] = "photons"
        biggest = max(s.photons, s.caustic_photons)
        in_flight = min(threads, -(-biggest // chunk_length(biggest, s.chunk_size)))
        est.parts["photon chunks"] = int(in_flight * chunk_length(biggest, s.chunk_size)
                                         * BYTES_PER_TRACED_PHOTON)
        est.drivers["photon chunks"] = "chunk_size"
        from . import integrator, onesurface
        if integrator.PHOTON_VISIBILITY:
            est.parts["visibility pre-test"] = VISIBILITY_RADII * onesurface.KEPT_BYTES_MAX
            est.drivers["visibility pre-test"] = "photons"
            # Each thread keeps its read lists (photon ids and weights, READ_ROWS rows
            # READ_WIDTH x k wide) for its life: photonvisibility._read_buffers.
            from . import photonvisibility as pv
            est.parts["visibility read lists"] = (threads * pv.READ_ROWS * pv.READ_WIDTH
                                                  * max(1, int(s.k_nearest)) * 16)
            est.drivers["visibility read lists"] = "k_nearest"
        levels = regather_levels(s)
        if levels:
            est.parts["regather maps"] = (gather_points(s.photons * stores) * levels
                                          * BYTES_PER_GATHER_POINT_LEVEL)
            est.drivers["regather maps"] = "photons"
            est.parts["gather lookups' photons"] = int(s.photons * stores
                                                       * BYTES_PER_KEPT_GATHER_PHOTON)
            est.drivers["gather lookups' photons"] = "photons"
        if s.final_gather and s.photons and integrator.SECONDARY_FROM_GATHER_POINTS:
            # Each regathering level's secondary-caustic share of the gather points'
            # estimates ((P,3) float32 a level: GatherMap.secondary_levels).
            est.parts["regather secondary shares"] = (
                gather_points(s.photons * stores) * integrator.MAX_GATHER_LEVEL
                * BYTES_PER_GATHER_POINT_LEVEL)
            est.drivers["regather secondary shares"] = "photons"

    samples = pixels * s.spp
    if samples:
        chunk = chunk_length(samples, s.chunk_size)
        in_flight = min(threads, -(-samples // chunk))
        est.parts["camera chunks"] = int(in_flight * chunk * BYTES_PER_CAMERA_SAMPLE)
        est.drivers["camera chunks"] = "chunk_size"
        from . import integrator
        if (s.final_gather and s.photons and s.clamp_indirect > 0
                and integrator.CLAMP_PER_GATHER_RAY):
            # Clamp Indirect per final-gather ray (integrator.gather_indirect's E_rays,
            # and chain_rays with Filter Glossy's chains): (G, n, 3) float64 a chunk, G
            # the most gather rays a sample casts (review of clampray53: 0.8 GB an
            # array a thread at G = 256).
            arrays = 2 if s.cycles_filter_glossy > 0 else 1
            est.parts["clamped gather rays"] = int(in_flight * chunk * 24 * arrays
                                                   * max(1, int(s.gather_rays)))
            est.drivers["clamped gather rays"] = "gather_rays"
    per_pixel = BYTES_PER_PIXEL + (BYTES_PER_PIXEL_PROGRESSIVE if progressive else 0) \
        + (BYTES_PER_PIXEL_BLENDER if in_blender else 0)
    est.parts["image"] = pixels * per_pixel
    est.drivers["image"] = "resolution"
    channels = data_pass_channels(s) + 3 * len(getattr(s, "light_groups", ()))
    if channels and pixels:
        per_channel = BYTES_PER_DATA_CHANNEL \
            + (BYTES_PER_DATA_CHANNEL_PROGRESSIVE if progressive else 0) \
            + (BYTES_PER_DATA_CHANNEL_BLENDER if in_blender else 0)
        est.parts["data passes"] = pixels * channels * per_channel
        est.drivers["data passes"] = "data_passes"
    if s.cryptomatte and pixels:
        from .cryptomatte import CHUNK_RAYS, pass_count
        ranks = 2 * pass_count(s.cryptomatte_levels) * len(s.cryptomatte)
        per_rank = BYTES_PER_CRYPTOMATTE_RANK + (BYTES_PER_CRYPTOMATTE_RANK_BLENDER
                                                 if in_blender else 0)
        est.parts["cryptomatte"] = (pixels * ranks * per_rank
                                    + min(CHUNK_RAYS, samples) * BYTES_PER_CRYPTOMATTE_RAY)
        est.drivers["cryptomatte"] = "cryptomatte_levels"
    copies, shared, count = _instanced_triangles(scene)
    saved = 0
    if copies and instance_choice(copies, shared)[0]:
        # Two-level with shared tables: the prototypes once, a record per instance.
        saved = (copies - shared) * BYTES_PER_TRIANGLE - count * BYTES_PER_INSTANCE
    est.parts["triangles"] = tris * BYTES_PER_TRIANGLE - saved
    est.drivers["triangles"] = "the scene's triangle count"
    if getattr(s, "light_groups", ()):
        # A light group's render (engine/lightgroups.py) builds its own scene, one group
        # at a time, while the main render's is held: its triangles and photon maps;
        # progressive passes keep every group's scene.
        est.parts["light group render"] = (est.parts["triangles"] + est.parts.get(
            "photon maps", 0)) * (len(s.light_groups) if progressive else 1)
        est.drivers["light group render"] = "light_groups"
    env = getattr(scene, "environment", None)
    if env is not None and getattr(scene, "background_is_light", True):
        shoots = bool(s.uses_photon_maps and (s.photons or s.caustic_photons))
        est.parts["environment"] = (environment_bytes(env, photons=shoots)
                                    + ENV_BUILD_BYTES_PER_TEXEL * env.height * env.width)
        est.drivers["environment"] = "the environment map's size"
    return est


def _setting_text(name, scene, settings) -> str:
    if name == "resolution":
        return f"resolution {scene.width}x{scene.height}"
    if name in ("the scene's triangle count", "the environment map's size"):
        return name
    value = getattr(settings, name)
    # (data_passes is a tuple: ',' would raise where the message was to be made)
    return f"setting '{name}' = {value:,}" if isinstance(value, (int, float)) \
        else f"setting '{name}' = {value!r}"


def check_resources(scene, settings: RenderSettings, region=None, progressive=False,
                    in_blender=False, available: int | None = None) -> MemoryEstimate:
    """Refuse a render that cannot fit before anything is allocated. Raises ResourceError
    naming the resolution when a side exceeds MAX_RESOLUTION, or the setting behind the
    largest part of the estimate when the estimate exceeds the available memory
    (`available` bytes, default: available_memory(); no check when that is unknown).
    Returns the estimate."""
    w, h = int(scene.width), int(scene.height)
    if w > MAX_RESOLUTION or h > MAX_RESOLUTION:
        raise ResourceError(f"resolution {w}x{h}: at most {MAX_RESOLUTION} pixels per side "
                            "(Blender's limit)")
    est = estimate_memory(scene, settings, region, progressive, in_blender)
    room = available_memory() if available is None else int(available)
    if room is not None and est.total > room:
        part = est.largest()
        what = _setting_text(est.drivers[part], scene, settings)
        raise ResourceError(
            f"{what}: the render would need about {format_bytes(est.total)} of memory "
            f"({est.summary()}) but {format_bytes(room)} is available; lower it")
    return est
