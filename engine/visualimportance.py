"""Visual importance for the global photon shot: the global photons go where camera paths
use them (docs/design.md, Photon budget: visual importance).

Final gathering looks the global photons up where gather rays end; a large scene lit from
far (a 30 m ground plane under a dim world, issue 14) spreads them over surfaces no camera
path reaches, the photon density where the camera looks falls, and with it the automatic
search radius and the estimates' quality. Here:

1. A coarse camera pre-pass (region_of_interest): a jittered grid of camera rays, mirrored
   on at surfaces without a diffuse lobe, and ROI_GATHER cosine-distributed rays from each
   diffuse hit, as final gathering casts them. Where those rays end are the global map's
   lookups (final gathering only: engine/render.py global_emitters). The region of interest
   is the set of grid cells holding ROI_COVER of them (at most ROI_CELLS cells: the cell
   size doubles until they fit), each as its bounding sphere.
2. A pilot (plan_global_shot): ROI_PILOT photons of every light, emitted as it emits them,
   tell which share of its power leaves towards the region (rays that meet one of the
   spheres). With I_in, I_out the lookups' shares inside / outside the region and P_in,
   P_out the lights' power sent there, photon density n ~ sqrt(lookup density / power
   density) minimises the summed k-NN blur (the squared radius ~ 1 / photon density, per
   lookup): a photon inside carries 1 / B of what one outside carries, with
   B = sqrt((I_in / P_in) / (I_out / P_out)). The same rule sphere by sphere
   (ROI_CELL_WEIGHTS) shares the aimed photons among the spheres: photons ~
   sqrt(I_k P_k); at least ROI_MIN_OUTSIDE of them stay outside. Below ROI_MIN_BOOST (a closed room, where the region is most of the
   scene) the shot stays as it was: every light emits naturally, photons in proportion
   to its power.
3. Each light that can aim (a RegionEmitter) emits a share f of its photons aimed at the
   region's spheres (its emission kernel's aimed mode, the caustic aiming's: power x
   natural pdf / aimed pdf, the sphere picked by the probabilities of step 2) and the
   rest naturally, dropping the natural photons whose ray meets a sphere. The two parts
   split the light's emission space between them without overlap (what is dropped is
   exactly where the aimed pdf is positive), so the expected power arriving anywhere is
   the light's own: no bias, and light bouncing in from surfaces outside the region is
   still carried, by fewer, brighter photons. Photons per light follow the power each
   sends into each sphere and outside, at the densities of step 2. A finite light whose
   photons mostly start inside a sphere (a glowing ball over the floor it lights) emits
   naturally: from there the aimed photons are heavier than natural ones
   (origins_inside).

Everything is seeded by the settings' seed and independent of the worker count (the
pre-pass and the pilot run on the calling thread, the photons keep their per-slot random
numbers: engine/lights/emission.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .bsdf import surface_hit
from .geometry import CAMERA, DIFFUSE, GLOSSY
from .lights.area import AreaLight
from .lights.base import InfiniteLight, emit_arrays
from .lights.emission import Aim, drop_meeting, sphere_meets
from .lights.mesh import MeshLight
from .lights.point import PointLight
from .lights.spot import SpotLight
from .sampling import cosine_hemisphere, dot, luminance, offset_origin, reflect, to_world

ROI_RAYS = 4096        # camera rays of the pre-pass
ROI_GATHER = 4         # cosine rays per diffuse camera hit
ROI_MIRROR_DEPTH = 4   # mirror bounces of a pre-pass camera ray at non-diffuse surfaces
# Share of the lookups the region holds. The lookups left outside lie mostly at the
# region's edges (the near field of the camera's hits at the frame's border), where the
# outside's fewer, brighter photons made blotches: light_mesh_emission's block error
# 0.295 at 0.9 (0.089-0.103 at 0.97 over seeds 0-3; main 0.109-0.143).
ROI_COVER = 0.97
ROI_CELLS = 32         # at most this many cells (spheres) in the region
ROI_PILOT = 4096       # pilot photons per light (up to 8 lights; fewer each beyond)
ROI_MIN_BOOST = 2.0    # below this photon-density boost the shot is left natural
ROI_MIN_OUTSIDE = 0.1  # at least this share of the photons outside the region
ROI_CELL_WEIGHTS = True  # photons per sphere by its own lookups and power (else uniform)
ROI_MIN_CELL = 0.1     # each sphere's aim probability at least this share of the mean
# A finite light whose pilot photons start inside a region sphere with more than this
# share of its power emits naturally (origins_inside): closure_emission's glowing ball
# 0.56 and light_point_sphere's 0.66 do (block errors within their seed noise); the
# lights of the feature matrix's window rooms (0.006-0.018) and light_point_radius (0.12)
# keep aiming as before.
ROI_MAX_ORIGINS_INSIDE = 0.25


@dataclass
class Region:
    """The region of interest: spheres (centers (K,3), radii (K,), re-centred world
    space, m) holding `inside` of the pre-pass lookups (`lookups` of them)."""
    centers: np.ndarray
    radii: np.ndarray
    inside: float
    lookups: int
    shares: np.ndarray | None = None  # (K,) each sphere's share of the lookups
    # The lookups themselves: points (N,3) and unit geometric normals (N,3) facing the
    # gather ray that found them (the side of the surface they read); None: not known.
    points: np.ndarray | None = None
    normals: np.ndarray | None = None

    @property
    def targets(self):
        return self.centers, self.radii


def region_of_interest(ctx, rays: int = ROI_RAYS) -> Region | None:
    """The region of interest of ctx's camera (module docstring, step 1), or None when
    the pre-pass finds no lookup (nothing diffuse in view)."""
    points, normals = lookup_points(ctx, rays, normals=True)
    if len(points) == 0:
        return None
    region = cover_cells(points, ROI_COVER, ROI_CELLS)
    region.points, region.normals = points, normals
    return region


def lookup_points(ctx, rays: int = ROI_RAYS, normals: bool = False):
    """(N,3) points where the pre-pass' gather rays end on a surface: where final
    gathering looks the global map up. normals=True: (points, (N,3) unit geometric
    normals there facing the gather ray, the side of the surface the lookup reads)."""
    rng = np.random.default_rng([ctx.settings.seed, 95])
    p, ng, off = diffuse_camera_hits(ctx, rays, rng)
    if len(p) == 0:
        return (np.zeros((0, 3)), np.zeros((0, 3))) if normals else np.zeros((0, 3))
    p, ng, off = (np.repeat(a, ROI_GATHER, axis=0) for a in (p, ng, off))
    u = rng.random((2, len(p)))
    d = to_world(cosine_hemisphere(u[0], u[1]), ng)
    o = offset_origin(p, ng, d, off)
    o, t, prim, _, _ = _past_invisible(ctx, o, d, DIFFUSE)
    ok = prim >= 0
    ok[ok] = stores_photons(ctx, prim[ok])
    points = o[ok] + t[ok, None] * d[ok]
    if not normals:
        return points
    return points, _facing(ctx.geo.ng[prim[ok]], d[ok])


# How many invisible surfaces (a volume-only material's boundary: a fog box's walls) a
# pre-pass ray passes before the hit it uses.
INVISIBLE_DEPTH = 4


def invisible_materials(table) -> np.ndarray:
    """(M,) bool: materials whose surface every ray passes unbent (a volume without a
    surface: Material.volume_only). The pre-pass treated a fog box's walls as mirrors
    and its gather rays as ending there: a floor in the fog read as "no surface that
    stores photons" (newuser36)."""
    vol = table.volume_only
    return (np.zeros(len(table.names), bool) if vol is None else np.asarray(vol, bool))


def _past_invisible(ctx, o, d, cls, tmax=None):
    """Rays o, d (N,3) traced past up to INVISIBLE_DEPTH invisible surfaces
    (invisible_materials): (origins (N,3) of the last segment, its hit distances (N,),
    the primitives hit (N,), -1 for none, its barycentrics u, v (N,))."""
    o = np.array(o, np.float64)
    d = np.asarray(d, np.float64)
    tmax = np.full(len(o), np.inf) if tmax is None else np.array(tmax, np.float64)
    t, prim, u, v = (np.array(a) for a in ctx.accel.intersect(o, d, tmax, cls=cls))
    invisible = invisible_materials(ctx.table)
    if not invisible.any():
        return o, t, prim, u, v
    for _ in range(INVISIBLE_DEPTH):
        rows = np.flatnonzero(prim >= 0)
        rows = rows[invisible[np.asarray(ctx.geo.material)[prim[rows]]]]
        if len(rows) == 0:
            break
        hit = surface_hit(ctx.geo, ctx.table, prim[rows], u[rows], v[rows], d[rows])
        o[rows] = offset_origin(hit.p, hit.ng, d[rows], hit.offset)
        tmax[rows] = tmax[rows] - t[rows]
        t[rows], prim[rows], u[rows], v[rows] = ctx.accel.intersect(o[rows], d[rows],
                                                                    tmax[rows], cls=cls)
    return o, t, prim, u, v


def stores_photons(ctx, prim: np.ndarray) -> np.ndarray:
    """(N,) bool: triangles prim (N,) whose material has a diffuse lobe, the only
    surfaces the global map stores photons on (engine/photonkernels.py). A gather ray
    ending anywhere else (a rough metal floor, an emitting panel, glass) reads no photon:
    counted as a lookup, it put region spheres where the pilot can send no photon power
    (a rough metal floor: ~0 % of the light, a 126x boost, the feature case
    light_area_spread_glossy) or where every photon of a light starts (an emitting
    panel's sphere holds the light itself: "100 % of the light", light_mesh_emission)."""
    return np.asarray(ctx.table.has_diffuse)[np.asarray(ctx.geo.material)[prim]]


def _facing(ng, d):
    """Unit normals ng (N,3) turned to face rays of direction d (N,3) that met them."""
    return np.where((dot(ng, d) > 0)[:, None], -ng, ng)


# The pilot's photons pass on through at most this many surfaces without a diffuse lobe
# (window glass, mirrors) before their first diffuse hit counts.
PILOT_SPECULAR_DEPTH = 4
# A pilot photon's first diffuse hit serves the lookups when one of its PILOT_NEIGHBOURS
# nearest lookups reads the same side of a surface (normals agreeing by more than
# PILOT_AGREEMENT).
PILOT_NEIGHBOURS = 8
PILOT_AGREEMENT = 0.5
# plan_global_shot counts a pilot photon's power for the region only where
# seen_side_hits says it serves the lookups (False: wherever its line meets a sphere, as
# before; bench/bench_window_room.py's A/B). It once broke light_area_spread_glossy
# (lookups on a rough metal floor: ~0 % of the light, a 126x boost): lookups now count
# only on surfaces that store photons (stores_photons). A clamp on the boost instead (32x)
# made that case worse, block error 1.874 (unclamped 0.672): the fault was the lookups,
# not the boost (docs/performance.md, "seenside").
PILOT_SEEN_SIDE = True


def seen_side_hits(ctx, o, d, region: Region) -> np.ndarray:
    """(N,) bool: photons (origins o, unit directions d (N,3)) whose first diffuse hit
    lies on the side of a surface the region's lookups read: one of the hit's
    PILOT_NEIGHBOURS nearest lookups faces the way the hit's surface faces the photon.
    Surfaces without a diffuse lobe are passed straight through (transmissive: window
    glass, whose two faces restore the direction) or mirrored (the rest), as the
    pre-pass' camera paths are. A sunlit roof whose inside is a room's ceiling lies in
    the ceiling's sphere, but its photons light the other side: they do not count."""
    from scipy.spatial import cKDTree
    n = len(o)
    out = np.zeros(n, bool)
    if region.points is None or len(region.points) == 0 or n == 0:
        return out
    geo, table, accel = ctx.geo, ctx.table, ctx.accel
    diffuse = table.has_diffuse
    passes = np.asarray(table.transmission, np.float64) > 0
    rows = np.arange(n)
    o = np.asarray(o, np.float64)
    d = np.asarray(d, np.float64)
    hit_p, hit_n, found = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, bool)
    for _ in range(PILOT_SPECULAR_DEPTH + 1):
        if len(rows) == 0:
            break
        o, _, prim, u, v = _past_invisible(ctx, o, d, DIFFUSE)
        keep = prim >= 0
        rows, o, d, prim, u, v = rows[keep], o[keep], d[keep], prim[keep], u[keep], v[keep]
        if len(rows) == 0:
            break
        hit = surface_hit(geo, table, prim, u, v, d)
        dif = diffuse[hit.mat]
        hit_p[rows[dif]] = hit.p[dif]
        hit_n[rows[dif]] = _facing(np.asarray(geo.ng[prim[dif]]), d[dif])
        found[rows[dif]] = True
        spec = ~dif
        through = passes[hit.mat[spec]]
        d_next = np.where(through[:, None], d[spec], reflect(d[spec], hit.ns[spec]))
        o = offset_origin(hit.p[spec], hit.ng[spec], d_next, hit.offset[spec])
        rows, d = rows[spec], d_next
    idx = np.flatnonzero(found)
    if len(idx) == 0:
        return out
    k = min(PILOT_NEIGHBOURS, len(region.points))
    _, near = cKDTree(region.points).query(hit_p[idx], k=k)
    near = np.asarray(near).reshape(len(idx), k)
    agree = np.einsum("ikj,ij->ik", region.normals[near], hit_n[idx]) > PILOT_AGREEMENT
    out[idx] = agree.any(axis=1)
    return out


def diffuse_camera_hits(ctx, rays: int, rng) -> tuple:
    """The pre-pass' camera paths: a jittered grid of about `rays` camera rays (rng draws
    the jitter), mirrored on at surfaces without a diffuse lobe (ROI_MIRROR_DEPTH times),
    passing invisible ones (invisible_materials).
    Returns (p, ng, offset) of the hits on surfaces with a diffuse lobe: (N,3) re-centred
    positions (m), (N,3) unit geometric normals facing the ray, (N,) origin offsets (m)."""
    from .integrator import camera_rays
    scene, geo, table, accel = ctx.scene, ctx.geo, ctx.table, ctx.accel
    W, H = scene.width, scene.height
    nx = max(1, int(round(math.sqrt(rays * W / max(H, 1)))))
    ny = max(1, int(round(rays / nx)))
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny))
    fx = (gx.ravel() + rng.random(nx * ny)) / nx * W
    fy = (gy.ravel() + rng.random(nx * ny)) / ny * H
    px, py = np.minimum(np.floor(fx), W - 1), np.minimum(np.floor(fy), H - 1)
    # Depth of field: rays from the whole lens, which see round a defocused foreground
    # (drawn only then: a pinhole camera's stream is unchanged).
    lens = rng.random((2, len(px))) if scene.camera.has_dof else None
    o, d, tmax = camera_rays(scene.camera, geo.offset, W, H, px, py, fx - px, fy - py,
                             None, lens)
    diffuse = table.has_diffuse
    hits = []
    # Each ray sees what its kind sees (docs/scene_format.md, "Ray visibility"): camera
    # rays, then mirrored (glossy) rays.
    ray_cls = CAMERA
    for _ in range(ROI_MIRROR_DEPTH + 1):
        if len(o) == 0:
            break
        # Past invisible surfaces (a fog box's walls), as every ray passes them.
        o, _, prim, u, v = _past_invisible(ctx, o, d, ray_cls, tmax)
        ray_cls = GLOSSY
        keep = prim >= 0
        if not keep.any():
            break
        d = d[keep]
        hit = surface_hit(geo, table, prim[keep], u[keep], v[keep], d)
        dif = diffuse[hit.mat]
        hits.append((hit.p[dif], hit.ng[dif], hit.offset[dif]))
        # Surfaces without a diffuse lobe: the camera path goes on as a mirror would.
        spec = ~dif
        d = reflect(d[spec], hit.ns[spec])
        o = offset_origin(hit.p[spec], hit.ng[spec], d, hit.offset[spec])
        tmax = np.full(len(o), np.inf)
    if not hits:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    return tuple(np.concatenate([h[i] for h in hits]) for i in range(3))


def _cells_of(key: np.ndarray) -> tuple:
    """np.unique(key, axis=0, return_inverse=True, return_counts=True)'s (inverse (N,),
    counts (C,)) for integer cell keys (N,3) int64: the rows' lexicographic order is that
    of one mixed-radix int64 per row where the key's span allows (~10x faster than
    np.unique over rows: 37 ms on 12 k points, the whole cover_cells, on a Cornell box's
    pre-pass; fast46), else np.unique's own."""
    lo = key.min(axis=0)
    span = key.max(axis=0) - lo + 1
    if float(span[0]) * float(span[1]) * float(span[2]) < 2.0 ** 62:
        flat = ((key[:, 0] - lo[0]) * span[1] + (key[:, 1] - lo[1])) * span[2] \
            + (key[:, 2] - lo[2])
        _, member, count = np.unique(flat, return_inverse=True, return_counts=True)
        return member, count
    _, member, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return member.ravel(), count


def cover_cells(points: np.ndarray, cover: float = ROI_COVER,
                max_cells: int = ROI_CELLS) -> Region:
    """The fewest grid cells holding `cover` of points (N,3), as bounding spheres; the
    cell size starts at 1/16 of the diagonal of the box holding the central 90 % of the
    points on each axis and doubles until at most max_cells cells do."""
    lo = np.quantile(points, 0.05, axis=0)
    hi = np.quantile(points, 0.95, axis=0)
    diag = float(np.linalg.norm(hi - lo))
    full = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    h = max(diag / 16.0, 1e-6 * max(full, 1e-30), 1e-30)
    need = int(math.ceil(cover * len(points) - 1e-9))
    while True:
        # Cells start half a cell below the quantile: a plane holding many points (a
        # floor: often the quantile itself) lies mid-cell, not on a cell boundary, where
        # last-bit differences of its points (an instanced or inside-out copy of the same
        # scene) would split it between two cells and change the photons.
        key = np.floor((points - lo) / h + 0.5).astype(np.int64)
        member, count = _cells_of(key)
        order = np.argsort(-count, kind="stable")
        taken = np.cumsum(count[order])
        k = int(np.searchsorted(taken, need) + 1)
        if k <= max_cells or h > 2.0 * full:
            break
        h *= 2.0
    k = min(k, len(order))
    # Each chosen cell as the bounding sphere of its points round their mean: on a floor
    # a flat disc's sphere, not the cube's (which reaches below the floor, where the
    # world's photons from underneath would land on its unseen side).
    member = member.ravel()
    rank = np.empty(len(count), np.int64)
    rank[order] = np.arange(len(count))
    slot = rank[member]
    take = slot < k
    n = np.bincount(slot[take], minlength=k).astype(np.float64)
    centers = np.stack([np.bincount(slot[take], weights=points[take, a], minlength=k)
                        for a in range(3)], axis=1) / n[:, None]
    dist = np.linalg.norm(points[take] - centers[slot[take]], axis=1)
    radii = np.zeros(k)
    np.maximum.at(radii, slot[take], dist)
    radii = np.maximum(radii, 1e-3 * h)
    return Region(centers, radii, float(taken[k - 1]) / len(points), len(points),
                  n / len(points))


# ---------------------------------------------------------------------- emission
def can_aim(light) -> bool:
    """Lights whose aimed emission (Light.emit_towards_into) draws its direction from the
    photon's own origin (finite lights) or its origin across its direction (lights at
    infinity), so that meets_region tells exactly where the aimed pdf is positive. A spot
    light shifts its photons' origins after aiming (engine/lights/spot.py): natural."""
    if isinstance(light, SpotLight):
        return False
    return isinstance(light, (InfiniteLight, AreaLight, PointLight, MeshLight))


def no_gain_report(light_share: float, lookup_share: float, boost: float) -> str:
    """The effect report's words when aiming photons at what the camera sees does not pay:
    light_share, lookup_share (0..1) of the light and of the camera's photon lookups there,
    boost the density gain aiming would give (< ROI_MIN_BOOST). Below 1 it would thin them
    out there ("0.2x denser" read as a gain to the s29 new user)."""
    gain = (f"make them only {boost:.1f}x denser" if boost >= 1.0 else
            f"make them sparser there, not denser ({boost:.1f}x)")
    return (f"no visual importance: what the camera sees gets {light_share:.0%} of the "
            f"light for {lookup_share:.0%} of the photon lookups, so aiming photons there "
            f"would {gain} (it pays from {ROI_MIN_BOOST:g}x)")


def _why_natural(lights, p_in: float, p_out: float, cell_power: np.ndarray,
                 starts_inside: bool) -> str:
    """Why plan_global_shot emits naturally although it has a region: the report's words.
    cell_power (L,K): the power each light sends into each sphere of the region;
    starts_inside: a light that could aim starts inside the region (ROI_MAX_ORIGINS_INSIDE
    of its power)."""
    if not p_in > 0:
        return "the lights send none of their light to what the camera sees"
    if not p_out > 0:
        return "the lights send all of their light to what the camera sees"
    reaching = [light for light, power in zip(lights, cell_power.sum(axis=1)) if power > 0]
    if not any(can_aim(light) for light in reaching):
        kinds = sorted({type(light).__name__.removesuffix("Light").lower()
                        for light in reaching})
        return (f"the lights that reach what the camera sees ({', '.join(kinds)}) cannot aim "
                f"their photons (spot lights emit naturally)")
    if starts_inside:
        return ("the lights that reach what the camera sees start inside it (over "
                f"{ROI_MAX_ORIGINS_INSIDE:.0%} of their power), so their photons land there "
                "anyway")
    return "the lights that can aim send all of their light to what the camera sees"


def meets_region(o: np.ndarray, d: np.ndarray, centers: np.ndarray, radii: np.ndarray,
                 infinite: bool) -> np.ndarray:
    """(N,) bool: meets_spheres(...).any(axis=1), stopping at the first sphere met."""
    met = _sphere_test(o, d, centers, radii, infinite, any_sphere=True)
    return met[:, 0] if met.shape[1] else np.zeros(len(o), np.bool_)


def meets_spheres(o: np.ndarray, d: np.ndarray, centers: np.ndarray, radii: np.ndarray,
                  infinite: bool) -> np.ndarray:
    """(N, K) bool: photons (origins o, unit directions d (N,3)) that the aimed emission at
    spheres (centers (K,3), radii (K,)) could have drawn, sphere by sphere. Lights at infinity: the line
    passes within the radius of a centre (the sphere's shadow disk, emission.aim_origin);
    finite lights: the direction lies in the cone from the origin holding a sphere, every
    direction from inside one (emission.aim_direction)."""
    return _sphere_test(o, d, centers, radii, infinite, any_sphere=False)


def _sphere_test(o, d, centers, radii, infinite, any_sphere):
    """lights/emission.sphere_meets on float64 copies where needed: (N, K) bool, or (N, 1)
    whether any sphere is met when any_sphere (and K > 1)."""
    K = len(radii)
    out = np.empty((len(o), 1 if any_sphere and K > 1 else K), np.bool_)
    if out.size:
        c = np.ascontiguousarray
        sphere_meets(c(o, np.float64), c(d, np.float64), c(centers, np.float64),
                     c(radii, np.float64), bool(infinite), out)
    return out


def origins_inside(o: np.ndarray, region: Region) -> np.ndarray:
    """(N,) bool: photon origins o (N,3) inside one of the region's spheres. From there
    every direction counts as meeting the sphere (sphere_meets): the split emission drops
    all the natural photons and the aimed part spreads the sphere's share of its photons
    over 4 pi (emission.aim_direction), a weight natural pdf / aimed pdf of up to
    2 |cos| / prob for the emitting triangles (both sides; 4 cos / prob one-sided) where
    no other sphere's cone holds the direction: up to 2 / prob times a natural photon's. closure_emission (a glowing ball 0.3 m over the stage, its lower part in
    the floor's spheres, prob ~0.5-7 %): such photons up to 6.2x the natural photons' power
    and 85x the aimed area light's, the ball's edge noisier (block error seeds 0-11 median
    0.124, max 0.297; the ball natural: 0.096, 0.152; docs/performance.md, "emitaim")."""
    d = np.linalg.norm(np.asarray(o, np.float64)[:, None, :] - region.centers[None], axis=2)
    return (d <= region.radii[None]).any(axis=1)


class RegionEmitter:
    """A light that emits `share` of its photons aimed at the region and the rest
    naturally, minus the natural photons that meet the region (module docstring, step 3).
    Each chunk of n of the light's `count` photons carries n / count of its flux, so the
    split may round differently per chunk without bias."""

    def __init__(self, light, region: Region, share: float, probs=None):
        self.light = light
        self.region = region
        self.share = float(share)
        # How the aimed photons pick a sphere: the light's own rule (Light.aim: by solid
        # angle or shadow-disk area), or probs (K,) (each > 0, so the aimed pdf is
        # positive wherever a natural photon is dropped).
        self.aim = light.aim(region.centers, region.radii)
        if probs is not None:
            self.aim = Aim(self.aim.centers, self.aim.radii, np.asarray(probs, np.float64))
        self.name = light.name
        self.ray_kinds = light.ray_kinds
        self.source = light.source
        self.photon_flux = light.photon_flux
        self.infinite = isinstance(light, InfiniteLight)

    def split(self, n: int) -> int:
        """Aimed photons of a chunk of n: round(share x n), one of each kind when n >= 2
        and 0 < share < 1 (each part covers its own piece of the emission space)."""
        a = int(round(self.share * n))
        if n >= 2 and 0.0 < self.share < 1.0:
            a = min(max(a, 1), n - 1)
        return min(max(a, 0), n)

    def emit_into(self, key, first: int, n: int, count: int, out, start: int) -> int:
        """Light.emit_into's contract: slots first .. first + n - 1, compacted rows from
        start, the chunk's expected power n / count of the flux; returns the next row."""
        a = self.split(n)
        j = start
        if a > 0:
            j = self.light._emit(self.aim, True, key, first, a, a * count / n, out, j)
        if a < n:
            j0 = j
            j = self.light.emit_into(key, first + a, n - a, (n - a) * count / n, out, j0)
            # The natural photons meeting the region dropped in place (meets_region's
            # test on their float64 origins, one compiled pass).
            c = np.ascontiguousarray
            j = drop_meeting(*out.arrays, j0, j, c(self.region.centers, np.float64),
                             c(self.region.radii, np.float64), bool(self.infinite))
        return j

    def emit_towards_into(self, key, first, n, count, targets, out, start):
        return self.light.emit_towards_into(key, first, n, count, targets, out, start)


@dataclass
class ShotPlan:
    """The global shot: emitters (lights or RegionEmitters) and their photon counts, with
    what was decided (report: one line)."""
    emitters: list
    counts: list
    report: str
    region: Region | None = None
    boost: float = 1.0


def plan_global_shot(ctx, lights, total: int, natural_counts, region: Region | None
                     ) -> ShotPlan:
    """How the global shot's `total` photons are emitted (module docstring, step 2):
    natural_counts are the photons per light without visual importance (returned when
    it does not pay)."""
    natural = ShotPlan(list(lights), list(natural_counts), "")
    if total <= 0 or not lights:
        natural.report = "no visual importance: no photons to send"
        return natural
    if region is None:
        # region None: the camera's gather rays end on no surface that stores photons
        # (an open scene, or only metal and glass where they end).
        # (newuser42 read the old "reach no surface that stores photons" as wrong on a
        # table that stores photons: the gather rays leave from it, they do not reach it)
        natural.report = ("no visual importance: the final-gather rays from the surfaces "
                          "in view leave the scene or end on metal and glass, never on a "
                          "surface that stores photons, so there is no region to aim at")
        return natural
    rng = np.random.default_rng([ctx.settings.seed, 94])
    K = len(region.radii)
    cell_power = np.zeros((len(lights), K))  # natural power each light sends into each sphere
    power_out = np.zeros(len(lights))
    aims = np.zeros(len(lights), bool)
    starts_inside_any = False  # a light that could aim starts inside the region (report)
    # ROI_PILOT photons a light for a few lights; with many, fewer each (at least 64).
    pilot = max(64, ROI_PILOT * 8 // max(8, len(lights)))
    for i, light in enumerate(lights):
        flux = float(luminance(np.asarray(light.photon_flux, np.float64)))
        if not flux > 0:
            continue
        o, d, power = emit_arrays(light, pilot, rng)
        w = luminance(power)
        total_w = float(w.sum())
        if not total_w > 0:
            continue
        met = meets_spheres(o, d, region.centers, region.radii,
                            isinstance(light, InfiniteLight))
        # Power into the region counts only where it lights the side the lookups read
        # (seen_side_hits): an aimed photon landing on a room's sunlit roof serves none
        # of the room's lookups. (The split emission stays unbiased whatever the counts.)
        inside = met.any(axis=1)
        if PILOT_SEEN_SIDE and region.points is not None and inside.any():
            met &= seen_side_hits(ctx, o, d, region)[:, None]
        # A photon meeting several spheres counts a part in each.
        many = np.maximum(met.sum(axis=1), 1)
        cell_power[i] = (met * (w / many)[:, None]).sum(axis=0) / total_w * flux
        power_out[i] = float(w[~inside].sum()) / total_w * flux
        # A finite light much of whose power starts inside a sphere stays natural
        # (origins_inside, ROI_MAX_ORIGINS_INSIDE).
        starts_inside = (not isinstance(light, InfiniteLight)
                         and float(w[origins_inside(o, region)].sum()) / total_w
                         > ROI_MAX_ORIGINS_INSIDE)
        aims[i] = can_aim(light) and inside.any() and not inside.all() and not starts_inside
        starts_inside_any = starts_inside_any or (can_aim(light) and starts_inside)
    power_in = cell_power.sum(axis=1)
    p_in, p_out = power_in.sum(), power_out.sum()
    i_in = region.inside
    # A region holding every lookup still leaves the outside a finite weight (the photons
    # outside keep a finite power; ROI_MIN_OUTSIDE below then sets their share).
    i_out = max(1.0 - i_in, ROI_MIN_OUTSIDE * 0.5)
    if not (p_in > 0 and p_out > 0 and aims.any()):
        natural.report = ("no visual importance: "
                          + _why_natural(lights, p_in, p_out, cell_power, starts_inside_any)
                          + ", so photons go where the lights send them")
        return natural
    # Photons ~ sqrt(lookups x power) per piece (module docstring): per watt, a sphere's
    # weight sqrt(I_k / P_k), outside sqrt(I_out / P_out). Uniform over the spheres
    # (ROI_CELL_WEIGHTS off): sqrt(I_in / P_in) for all.
    p_cell = cell_power.sum(axis=0)
    w_out = math.sqrt(i_out / p_out)
    if ROI_CELL_WEIGHTS and region.shares is not None:
        weight = np.sqrt(region.shares / np.maximum(p_cell, 1e-300 * p_in))
        weight = np.where(p_cell > 0, weight, 0.0)
    else:
        weight = np.full(K, math.sqrt(i_in / p_in))
    boost = float((p_cell * weight).sum() / p_in) / w_out
    if boost < ROI_MIN_BOOST:
        natural.report = no_gain_report(p_in / (p_in + p_out), i_in, boost)
        return natural
    # Photons per light: inside sum_k P_ik w_k, outside P_out w_out. A light that cannot
    # aim emits naturally: its photons as bright as the others' outside if it sends
    # nothing inside, else all as bright as the others' inside on average.
    per_cell = cell_power * weight[None, :]
    n_in = per_cell.sum(axis=1)
    n_out = power_out * w_out
    far = ~aims & (power_in <= 0)
    natural_light = ~aims & ~far
    n_in = np.where(natural_light, (power_in + power_out) * boost * w_out, n_in)
    n_out = np.where(natural_light, 0.0, n_out)
    # At least ROI_MIN_OUTSIDE of all photons outside.
    out_share = n_out.sum() / (n_in.sum() + n_out.sum())
    if 0 < out_share < ROI_MIN_OUTSIDE:
        n_out *= ROI_MIN_OUTSIDE * n_in.sum() / ((1.0 - ROI_MIN_OUTSIDE) * n_out.sum())
    want = n_in + n_out
    share = want / want.sum() * total
    counts = np.floor(share).astype(int)
    counts[np.argsort(-(share - counts), kind="stable")[: total - counts.sum()]] += 1
    emitters = []
    for i, light in enumerate(lights):
        if aims[i]:
            probs = None
            if ROI_CELL_WEIGHTS:
                # Every sphere keeps a share (a natural photon meeting only it is dropped,
                # so it must be aimed at): at least ROI_MIN_CELL of the mean.
                probs = per_cell[i] / max(n_in[i], 1e-300)
                probs = np.maximum(probs, ROI_MIN_CELL / K)
                probs /= probs.sum()
            emitters.append(RegionEmitter(light, region, n_in[i] / want[i], probs))
        else:
            emitters.append(light)
    # One plain sentence for the effect report (a student's words; the numbers kept).
    report = (f"visual importance: {i_in:.0%} of the photon lookups the camera makes fall "
              f"in {K} small region{'s' if K != 1 else ''} that get "
              f"{p_in / (p_in + p_out):.0%} of the light, so {boost:.1f}x more photons "
              "per watt are sent there: less noise where you look, the same brightness "
              "(the regions come from a pre-pass of camera rays, so their number and "
              "shares vary with the seed)")
    # (That last clause: two seeds of one donut read "32 small regions ... 4 %" and "8
    # small regions ... 8 %", which a reader took for a property of the scene: newuser51.)
    return ShotPlan(emitters, counts.tolist(), report, region, boost)


# The indirect share's pre-pass (indirect_share): camera rays, and at most this many of the
# global photons (a stride of the shot; the ratio of two estimates from the same photons
# does not need them all).
SHARE_RAYS = 1024
SHARE_PHOTONS = 1 << 16


def _kind_estimates(ctx, shot, radius: float, rows: np.ndarray, groups: list,
                    rays: int, max_photons: int):
    """(E, [E_g, ...]): luminance (N,) of k-NN irradiance estimates at the pre-pass'
    diffuse camera hits (diffuse_camera_hits, ~`rays` camera rays, seeded by the
    settings' seed): from the shot's photons `rows` (a stride of at most max_photons of
    them; radius (m), the search cap, scaled up by the stride's square root), and, per
    group of kinds in `groups` (a list of tuples), from those of them whose kind is in
    the group. Same discs for all: their ratio keeps no blur of its own. One search
    (PhotonMap.irradiance's masks: the bits of an estimate over the group's photons with
    the others' power zeroed, fast46). None when the camera sees nothing diffuse or
    `rows` holds fewer than two photons."""
    from .photonmap import PhotonMap
    s = ctx.settings
    p, ng, _ = diffuse_camera_hits(ctx, rays, np.random.default_rng([s.seed, 96]))
    if len(p) == 0 or len(rows) < 2:
        return None
    step = max(1, -(-len(rows) // max_photons))
    rows = rows[::step]
    pm = PhotonMap(shot, 1, rows=rows)
    r = radius * math.sqrt(step)
    kind = pm.photons.kind
    masks = np.stack([np.isin(kind, kinds) for kinds in groups])
    E, masked = pm.irradiance(p, ng, r, s.k_nearest, 1, s.estimator, masks=masks)
    return luminance(E), [luminance(Ek) for Ek in masked]


def indirect_share(ctx, shot, radius: float, rays: int = SHARE_RAYS,
                   max_photons: int = SHARE_PHOTONS) -> float | None:
    """The share of the irradiance at the diffuse surfaces the camera sees that final
    gathering carries: the INDIRECT photons' estimate over that of every photon the
    gather map holds (direct, indirect, and caustic light one diffuse bounce back; the
    caustic photons are left out as the gather map leaves them out), summed as luminance
    over the pre-pass' diffuse camera hits (_kind_estimates). None when the camera sees
    nothing diffuse or the shot holds no photon there. On the calling thread: the same
    value for any worker count."""
    from .photonkernels import CAUSTIC, INDIRECT
    est = _kind_estimates(ctx, shot, radius, np.flatnonzero(shot.kind != CAUSTIC),
                          [(INDIRECT,)], rays, max_photons)
    if est is None:
        return None
    total = float(est[0].sum())
    if not total > 0:
        return None
    return float(est[1][0].sum()) / total


def glow_share(ctx, shot, radius: float, rays: int = SHARE_RAYS,
               max_photons: int = SHARE_PHOTONS) -> float | None:
    """How much of the light the camera sees the caustic-kind photons of a global shot
    carry (the glow off rough specular layers and window glass, render.glow_emitters):
    the root mean square over the pre-pass' diffuse camera hits of each hit's share
    E_caustic / E_all (_kind_estimates, every photon of the shot), unitless in [0, 1].
    A pixel's relative variance from the caustic map is about its share^2 x the
    estimate's relative variance, so this (not the share of the summed light) is what
    the glow adds to relMSE: a shaded wall lit by sunlit grass's specular layer (most
    of the wall's light) weighs in even where the grass holds most of the image's light
    (tests/blender/test_rough_glow_cycles.py: 0.11 rms, 0.008 of the summed light).
    None when the camera sees nothing diffuse or the shot holds no photon there."""
    from .photonkernels import CAUSTIC
    return _rms_shares(ctx, shot, radius, [(CAUSTIC,)], rays, max_photons)[0]


def secondary_share(ctx, shot, radius: float, rays: int = SHARE_RAYS,
                    max_photons: int = SHARE_PHOTONS) -> float | None:
    """How much of the light the camera sees the secondary caustic carries (caustic light
    one diffuse bounce back: the CAUSTIC_DIFFUSE photons of a global shot, the secondary
    map's): the rms over the pre-pass' diffuse camera hits of each hit's share
    E_secondary / E_all, as glow_share (every photon of the shot; radius (m) the k-NN
    cap), unitless in [0, 1]; None where glow_share's is."""
    from .photonkernels import CAUSTIC_DIFFUSE
    return _rms_shares(ctx, shot, radius, [(CAUSTIC_DIFFUSE,)], rays, max_photons)[0]


def glow_and_secondary_shares(ctx, shot, radius: float, rays: int = SHARE_RAYS,
                              max_photons: int = SHARE_PHOTONS) -> tuple:
    """(glow_share, secondary_share) of the same shot at the same radius from one search:
    the values of the two calls (render's photon pass measures both where the glow shot
    needs the first and the secondary map will read the second, fast46)."""
    from .photonkernels import CAUSTIC, CAUSTIC_DIFFUSE
    return tuple(_rms_shares(ctx, shot, radius, [(CAUSTIC,), (CAUSTIC_DIFFUSE,)], rays,
                             max_photons))


def _rms_shares(ctx, shot, radius, groups, rays, max_photons):
    """Per group of kinds, the rms over the lit diffuse camera hits of E_group / E_all
    (_kind_estimates over every photon of the shot), or None (a list)."""
    est = _kind_estimates(ctx, shot, radius, np.arange(len(shot)), groups, rays,
                          max_photons)
    if est is None:
        return [None] * len(groups)
    E, Eks = est
    lit = E > 0
    if not lit.any():
        return [None] * len(groups)
    return [float(np.sqrt(np.mean((Ek[lit] / E[lit]) ** 2))) for Ek in Eks]


# --- Window glass's rims (effects.window_glass) --------------------------------------------
# Light that enters a slab of window glass through one of its thin rim faces (the 2 cm
# edge of a pane) is piped along inside it by total internal reflection (it meets the big
# faces beyond the critical angle) and leaves through the rim faces across, onto the wall
# or frame there: a line of light about the slab's thickness wide along the pane's edges
# (Cycles shows it under a pane lit from above). The light entering a big face cannot be
# piped (refracted within the critical angle, it leaves through the other big face), so
# the line's photons are those that met a rim face: a share of the light of order
# thickness / pane size (0.11 % of the window room's area light enters its rims). They are caustic-kind
# global photons (the glow's, effects.py: window glass casts no aimed caustic), the line's
# k-NN discs held at the caustic cap (~15 cm) by fewer than k of them, and the disc blurs
# the ~1 cm line to 0.70 of Cycles' block (docs/performance.md, "secedges" / "paneedge").
# So a share of each light's global photons is aimed at spheres covering the rims
# (RegionEmitter: the split emission, unbiased), the rest emitted as before.
# Off: on the window room (feature matrix, seeds 0-7, share 0.2) the line's block reads
# 0.72 -> 0.87 of Cycles and the block error 0.186 -> 0.157 (mean of seeds), no other
# case moves, but there the photon pass takes ~1.8x as long and stores 74 % more photons
# (the rims' photons are extra, most land on the outer walls round the window, those
# entering pipe through up to 32 bounces), the brightness moves 0.996 -> 0.991, and the
# k-NN disc still spans ~9 cm of the ~1 cm line (docs/performance.md, "paneedge").
RIM_AIM = False
# Photons per watt entering the rims against the light's mean: share = RIM_BOOST x the
# light's power share entering a rim face / the share of aimed photons that enter one,
# at most RIM_MAX_SHARE (the window room: 0.11 % of the light enters, 9.8 % of the aimed
# photons: 0.37 -> 0.2; the share 0.1 / 0.2 / 0.3 gave the line's block 0.77 / 0.87 / 0.86).
RIM_BOOST = 32.0
RIM_MAX_SHARE = 0.2
# The rims' photons added to the light's count (True) or taken from it (False).
RIM_EXTRA = True
RIM_MAX_SPHERES = 64   # spheres over all panes' rims (their size doubles until they fit)
RIM_PILOT = 256        # aimed pilot photons a light for its power into the rims
RIM_COS = 0.5          # a window triangle is a rim face when |n . n_pane| is below this


def rim_spheres(geo, window_tri: np.ndarray, max_spheres: int = RIM_MAX_SPHERES):
    """Spheres covering the rim faces of window glass: (centers (K,3) re-centred world
    space m, radii (K,) m). window_tri (T,) bool: effects.window_glass. A pane's rim
    faces are its triangles whose unit normal is within RIM_COS of perpendicular to its
    largest triangle's; each rim strip is cut into cells about sqrt(3) x the slab's
    thickness long (a sphere of radius ~ the thickness holding its piece), the cells
    doubling until the rims of every pane fit in max_spheres. Empty arrays without rims."""
    empty = (np.zeros((0, 3)), np.zeros(0))
    if not np.any(window_tri):
        return empty
    pts, ids, cell = [], [], []
    rng = np.random.default_rng(97)  # fixed: the spheres are the geometry's, not a seed's
    for oid in np.unique(geo.object_id[window_tri]):
        tris = np.flatnonzero(window_tri & (geo.object_id == oid))
        e1, e2, v0 = geo.e1[tris], geo.e2[tris], geo.v0[tris]
        cross = np.cross(e1, e2)
        area2 = np.linalg.norm(cross, axis=1)
        big = int(np.argmax(area2))
        if not area2[big] > 0:
            continue
        n0 = cross[big] / area2[big]
        rim = np.abs(cross @ n0) < RIM_COS * np.maximum(area2, 1e-300)
        if not rim.any():
            continue
        h = np.concatenate([v0 @ n0, (v0 + e1) @ n0, (v0 + e2) @ n0])
        thick = float(h.max() - h.min())
        if not thick > 0:
            continue
        # Points on the rim faces: their corners and ~256 per cell of the strip's length
        # (a sphere holds its cell's points and a margin: where one misses a sliver of
        # a face, those photons stay natural, which costs no bias).
        a = 0.5 * area2[rim]
        m = np.clip(np.ceil(256.0 * a / (thick * thick * math.sqrt(3.0))), 8, 16384).astype(int)
        r = np.repeat(np.flatnonzero(rim), m)
        u = rng.random((2, len(r)))
        fold = u[0] + u[1] > 1.0
        u[:, fold] = 1.0 - u[:, fold]
        p = v0[r] + u[0, :, None] * e1[r] + u[1, :, None] * e2[r]
        corners = np.concatenate([v0[rim], v0[rim] + e1[rim], v0[rim] + e2[rim]])
        p = np.concatenate([p, corners])
        pts.append(p)
        ids.append(np.full(len(p), len(cell)))
        cell.append(math.sqrt(3.0) * thick)
    if not pts:
        return empty
    scale = 1.0
    while True:
        centers, radii = [], []
        for j, p in enumerate(pts):
            size = cell[j] * scale
            key = np.floor((p - p.min(axis=0)) / size).astype(np.int64)
            # One integer a cell (np.unique(axis=0) sorts rows: ~10x slower).
            dims = key.max(axis=0) + 1
            _, member = np.unique(np.ravel_multi_index(key.T, dims), return_inverse=True)
            member = member.ravel()
            k = int(member.max()) + 1
            c = np.zeros((k, 3))
            np.add.at(c, member, p)
            c /= np.bincount(member, minlength=k)[:, None]
            rad = np.zeros(k)
            np.maximum.at(rad, member, np.linalg.norm(p - c[member], axis=1))
            centers.append(c)
            radii.append(rad + 0.05 * size)
        if sum(len(r) for r in radii) <= max_spheres:
            return np.concatenate(centers), np.concatenate(radii)
        scale *= 2.0


def aim_at_rims(ctx, emitters: list, counts: list, window_tri: np.ndarray | None = None):
    """The global shot's emitters with a share of each light's photons aimed at the rims
    of window glass (RIM_AIM's comment): (emitters, counts, report: a sentence, or ""
    when nothing is aimed there). Each light that can aim and whose light enters a rim
    face emits share = min(RIM_MAX_SHARE, RIM_BOOST x p / eff) of its photons at them (p:
    its power share entering a rim face first, eff: the share of aimed photons doing so;
    _rim_entry's pilots), each sphere by the power entering there (at least ROI_MIN_CELL
    of the mean), the rest as before: a RegionEmitter keeps its aimed photons per region
    sphere and its natural photons in the ratio they had, its spheres joined by the
    rims'. With RIM_EXTRA the light's count grows by 1 / (1 - share), else it stays.
    window_tri: effects.window_glass (computed when None). Seeded by the settings' seed
    (the pilots), on the calling thread."""
    geo, table = ctx.geo, ctx.table
    if window_tri is None:
        from .effects import window_glass
        window_tri = window_glass(geo, table)
    centers, radii = rim_spheres(geo, window_tri)
    if not len(radii):
        return emitters, counts, ""
    rng = np.random.default_rng([ctx.settings.seed, 93])
    rim_tri = rim_faces(geo, window_tri)
    out, aimed, shares, counts_out = [], [], [], list(counts)
    K = len(radii)
    rim = Region(centers, radii, 0.0, 0)
    for i, (emitter, count) in enumerate(zip(emitters, counts)):
        light = emitter.light if isinstance(emitter, RegionEmitter) else emitter
        flux = float(luminance(np.asarray(light.photon_flux, np.float64)))
        if not (can_aim(light) and flux > 0 and count >= 2):
            out.append(emitter)
            continue
        # The pilot, aimed by the light's own rule: the power entering the rim faces
        # straight from the light (its first hit a rim face) per sphere, and its share
        # of the flux (the aimed photons' weights make the sum unbiased).
        own = light.aim(centers, radii).probs
        enter, o = _rim_entry(ctx, light, rim, rim_tri, own, rng)
        p_enter = float(enter.sum()) / flux
        # From inside a rim sphere every direction meets it (origins_inside): natural.
        if not p_enter > 0 or (not isinstance(light, InfiniteLight) and len(o)
                               and origins_inside(o, rim).mean() > ROI_MAX_ORIGINS_INSIDE):
            out.append(emitter)
            continue
        probs = np.maximum(enter / enter.sum(), ROI_MIN_CELL / K)
        probs = probs / probs.sum()
        # The share of the aimed photons that enter a rim face with these probabilities
        # (a second pilot): share x eff photons per p_enter of the flux.
        eff_power, _ = _rim_entry(ctx, light, rim, rim_tri, probs, rng, count_only=True)
        eff = float(eff_power.sum())
        if not eff > 0:
            out.append(emitter)
            continue
        share = min(RIM_MAX_SHARE, RIM_BOOST * p_enter / eff)
        if isinstance(emitter, RegionEmitter):
            f = emitter.share * (1.0 - share)
            both = Region(np.concatenate([emitter.region.centers, centers]),
                          np.concatenate([emitter.region.radii, radii]),
                          emitter.region.inside, emitter.region.lookups)
            total = f + share
            new = RegionEmitter(light, both, total,
                                np.concatenate([f * emitter.aim.probs, share * probs]) / total)
        else:
            new = RegionEmitter(light, rim, share, probs)
        out.append(new)
        aimed.append(light.name)
        shares.append(share)
        if RIM_EXTRA:
            # The rims' photons on top of the light's: the rest keep their count (and
            # the shot's spacing, the global radius, its own).
            counts_out[i] = int(round(count / (1.0 - share)))
    if not aimed:
        return emitters, counts, ""
    from .effects import _quoted
    names = [geo.object_names[i] for i in np.unique(geo.object_id[window_tri])]
    report = (f"{max(shares):.0%} of the photons of {_quoted(aimed)} aimed at the thin edges "
              f"of window glass {_quoted(names)} ({K} small regions, up to {RIM_BOOST:g}x "
              "more photons per watt): light entering a pane's edge is piped inside the "
              "glass to its other edges, a thin line of light where the pane meets the wall")
    return out, counts_out, report


def rim_faces(geo, window_tri: np.ndarray) -> np.ndarray:
    """(T,) bool: the rim faces of window glass (rim_spheres' rule)."""
    out = np.zeros(geo.count, bool)
    for oid in np.unique(geo.object_id[window_tri]):
        tris = np.flatnonzero(window_tri & (geo.object_id == oid))
        cross = np.cross(geo.e1[tris], geo.e2[tris])
        area2 = np.linalg.norm(cross, axis=1)
        big = int(np.argmax(area2))
        if area2[big] > 0:
            n0 = cross[big] / area2[big]
            out[tris] = np.abs(cross @ n0) < RIM_COS * np.maximum(area2, 1e-300)
    return out


def _rim_entry(ctx, light, rim: Region, rim_tri: np.ndarray, probs, rng,
               count_only: bool = False):
    """A pilot of RIM_PILOT photons of light aimed at the rim spheres with probabilities
    probs (K,): (per sphere (K,): the luminance power (W) of the photons whose first hit
    is a rim face, the sphere holding the hit; or with count_only the share of the
    pilot's photons doing so), and the photons' origins (N,3)."""
    K = len(rim.radii)
    aim = Aim(*light.aim(rim.centers, rim.radii).arrays[:2], np.asarray(probs, np.float64))
    from .lights.base import emission_key
    from .lights.emission import EmissionBuffers
    buf = EmissionBuffers(RIM_PILOT)
    m = light._emit(aim, True, emission_key(rng), 0, RIM_PILOT, RIM_PILOT, buf, 0)
    o32, _, d, power, _ = buf.head(m)
    o, d = o32.astype(np.float64), d.astype(np.float64)
    got = np.zeros(K)
    if m == 0:
        return got, o
    t, prim, _, _ = ctx.accel.intersect(o, d, np.full(m, np.inf))
    hit = prim >= 0
    hit[hit] = rim_tri[prim[hit]]
    if not hit.any():
        return got, o
    p = o[hit] + t[hit, None] * d[hit]
    dist = np.linalg.norm(p[:, None, :] - rim.centers[None], axis=2) - rim.radii[None]
    k = np.argmin(dist, axis=1)
    w = np.ones(int(hit.sum())) / RIM_PILOT if count_only else luminance(
        power[hit].astype(np.float64))
    np.add.at(got, k, w)
    return got, o
