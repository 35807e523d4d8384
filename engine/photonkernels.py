"""Compiled kernels of the photon pass: everything between two Embree calls.

One bounce of a chunk of photons is one kernel call, `scatter` (engine/photons.py drives
the bounces). Per block of hits (_BLOCK of them, whose data stays in cache):

  surfaces         hit -> surface data (point, geometric and shading normal facing the
                   photon, side, material, base colour, alpha, ray-origin offset),
                   computed in the kernel (`_surfaces`, also behind `photon_surfaces`) for
                   materials without textures or normal maps; scenes with them, and shared
                   instances (whose offsets take a floor from engine/geometry.py), hand in
                   the same arrays from bsdf.surface_hit / photon_surfaces instead.
  closures         engine/closures/principled.py setup (skipped for materials with only
                   the diffuse and pass lobes)
  scattering       stored photon record (kind of path, visibility rules) -> Russian
                   roulette over the lobes -> sampled continuation (cosine-weighted
                   diffuse, or the chosen lobe's own sampler) -> compacted float32 rays for
                   the next Embree call, plus the split-off copies that pass surfaces
                   invisible to some ray kinds (docs/scene_format.md, "Ray visibility").

Random numbers: each photon keeps its slot in the chunk, and every number it uses is
SplitMix64 (Steele et al. 2014) at counter (slot, bounce, dimension) of a stream keyed by
the chunk's seed, computed where it is needed. A photon whose path changes therefore never
shifts the numbers of any other photon, and no per-bounce array of numbers is drawn for
every slot. Same seed = same photons for any thread count (chunks are fixed).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .closures import principled as pr
from .closures import ggx, tables
from . import glassadjoint as ga
from .closures.fresnel import F0_from_ior, fresnel_dielectric
from .geometry import CAMERA, DIFFUSE, GLOSSY, SHADOW, TRANSMISSION, ALL_RAYS
from .blurredpassage import passage_factor
from .filterglossy import blur_alpha, raise_alphas
from .jit import kernel, register_warm_up
from .rayoffset import G64, TINY32, U32, _offset_row, tilt32, winding_normal
from .trig import sincos_turn

# A kernel numba inlines into its callers (its IR, before LLVM: the same operations, so
# the same bits; jit.kernel otherwise). For the smooth glass set-up and sample, which
# _scatter calls once a glass hit: as calls (5 arrays passed) they took ~25 ns more a
# glass hit of Figure 8's replayed scatter calls (docs/performance.md, glass55).
_inline_kernel = numba.njit(nogil=True, cache=True, inline="always")

# Kinds of path recorded with a stored photon (engine/photons.py explains them).
DIRECT, CAUSTIC, INDIRECT, CAUSTIC_DIFFUSE = 0, 1, 2, 3
# Path flags per photon (bits of one int64).
F_DIFFUSE = 1      # the path has bounced diffusely
F_SPECULAR = 2     # ... off a glossy / mirror / glass lobe (not a transparent pass)
F_CAUSTIC_DIFF = 4  # path so far L S+ D S* (light from a caustic, one diffuse bounce later)
F_FIRST_CASTER = 8  # its first hit was on a caustic caster (trace_photons' first_hit)
F_PATH = 15        # the bits above: the path's own state
# A flat passage under way (docs/design.md, Transparent shadows): the photon refracted
# into smooth glass that may be a thin slab. Its flags then also hold the path's state
# from before the glass (bits 8-11) and the entry triangle's row (bits 32-62), so that
# the exit through the slab's parallel face restores the path as it was (no caustic).
F_IN_GLASS = 16
# A sun's or the world's photon that crossed a next-event pane (engine/panelight.py), or a
# lamp's that crossed its shade (engine/shadelight.py), as its first scatter and is still
# direct: a second crossing after it makes it caustic (its shadow rays cross none), and so
# does a transparent pass after a shade (the shade's shadow rays cross none before it).
F_PANE = 32
# ... with F_PANE, set where a pane (not a shade) was crossed: transparent passes after it
# keep the photon direct, as the pane's shadow rays cross them between the receiver and
# the pane (panelight._through; docs/accuracy.md "passages56"). Above the pre-glass bits
# (8-11), below the entry triangle's (32-62).
F_PANE_PLANE = 1 << 12
# The two copies of a photon split by Filter Glossy at its first non-diffuse scatter before
# any diffuse bounce (_scatter's split_slots; docs/accuracy.md "photonblur50"): the
# unblurred one keeps only its CAUSTIC stores (the caustic map's), the blurred one only
# its others (read past the camera's diffuse bounce).
F_UNBLURRED = 64
F_BLURRED = 128
F_SPLIT = F_UNBLURRED | F_BLURRED
# pane_tri's codes of a next-event lamp shade's triangles (engine/shadelight.py): a lamp's
# photon whose first scatter is the shade's translucent lobe (SHADE_TRANSLUCENT) or, on a
# single-surface rough glass shade, its glass refraction (SHADE_GLASS) stays direct as
# through a pane (F_PANE): the shade's shadow rays carry that light. (The glass shade's
# reflection stays caustic: no shadow ray carries it.)
SHADE_TRANSLUCENT = -2
SHADE_GLASS = -3
# The path's own kind bits (F_PATH without F_FIRST_CASTER).
_F_KIND = 7
_PRE_SHIFT = 8
_TRI_SHIFT = 32
# The flat-passage test (shared with engine/shadowtransmittance.py): the exit face's
# geometric normal within 1 degree of the entry face's (either orientation), and the slab
# no thicker than FLAT_OBJECT_SHARE of the glass object's bounding-box diagonal and
# FLAT_SCENE_SHARE of the scene's. The true refracted path is displaced sideways by
# t sin(theta - theta_t) / cos(theta_t), which grows with the angle to t at grazing
# incidence (eta >= 1): bounding the thickness bounds the displacement at every angle, so
# one slab is flat (or not) for all light, and a shadow ray's straight line misses the
# true path by at most 1 % of the scene and 2 % of the pane's size (a 2 cm pane of
# 1.2 x 1 m in a 4 m room: 1.3 % of its diagonal; window glass is 0.3-1 %). A 1 m glass
# cube, a ball or a 30 cm block on an 8 m slab (2.7 %) are not flat: they keep the
# caustic map.
FLAT_COS = math.cos(math.radians(1.0))
FLAT_OBJECT_SHARE = 0.02
FLAT_SCENE_SHARE = 0.01
# A photon's bounce counts (Cycles' Light Paths limits, docs/design.md, Bounce limits),
# packed in one int64 per photon in flight, 16 bits each: B_TOTAL every scatter but a
# transparent pass; B_DIFFUSE, B_GLOSSY, B_TRANSMISSION the scatters of each kind after
# the first. The first scatter's kind does not count: read from the camera the photon's
# first hit is the vertex that connects to the light (Cycles' light sample, no bounce),
# and the photon's last hit, the camera side's lookup vertex, counts as a diffuse bounce
# instead once the photon has scattered (a direct photon's hit is that light vertex).
# Stored photons keep the four counts as uint8, saturated at 255 (BOUNCE_SATURATED).
B_TOTAL, B_DIFFUSE, B_GLOSSY, B_TRANSMISSION = 0, 1, 2, 3
_B_BITS = 16
_B_MASK = (1 << _B_BITS) - 1
BOUNCE_SATURATED = 255
# The ray kinds a photon segment can stand for on the camera side (not camera rays).
SEGMENT_KINDS = ALL_RAYS & ~CAMERA
# Random dimensions per photon and bounce: roulette, diffuse direction (2), lobe sample (3).
N_DIMS = 6
MAX_BOUNCES = 1 << 16
_BLOCK = 256  # hits per closure set-up in scatter
# Slots of the per-call cache of triangle data (_surfaces): a direct-mapped table keyed by
# the triangle's row, so photons that hit the same triangles (a room's few walls) compute
# its float32 plane's tilt and its unit winding normal once per call instead of per hit;
# the same values either way.
_TILT_SLOTS = 1024

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0  # 2^-53


@kernel
def uniform(key, slot, bounce, dim):
    """A uniform number in [0, 1): SplitMix64's output number `counter` of the stream
    seeded by key (uint64), counter = (slot * MAX_BOUNCES + bounce) * N_DIMS + dim."""
    counter = np.uint64((slot * MAX_BOUNCES + bounce) * N_DIMS + dim)
    z = key + (counter + np.uint64(1)) * _GOLDEN
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    z = z ^ (z >> _S31)
    return float(z >> _S11) * _INV53


@kernel
def uniforms(key, slot, bounce, dim, out):
    """out[i] = uniform(key, slot[i], bounce, dim) (slot (n,) int64, out (n,) float64):
    the photon stream's numbers at (slot, bounce, dim) for numpy code, the same bits as
    the kernels' own: meshphotons.emitted_triangles re-derives from it the triangle each
    mesh light photon was emitted from (the emission key's number at EMIT_BOUNCE)."""
    for i in range(slot.shape[0]):
        out[i] = uniform(key, slot[i], bounce, dim)


@kernel
def _round32(x):
    # Half a float32 spacing of a corner coordinate (geometry._round32_rows).
    return 0.5 * max(2.0 * U32 * abs(x), TINY32)


@kernel
def _tilt(v0, e1, e2, t):
    """rayoffset.triangle_tilt of triangle row t, from its float32 corners."""
    return tilt32(v0[t, 0], v0[t, 1], v0[t, 2], e1[t, 0], e1[t, 1], e1[t, 2],
                  e2[t, 0], e2[t, 1], e2[t, 2])


@kernel
def photon_surfaces(prim, u, v, d, v0, e1, e2, corner_normals, material, base_color,
                    mat_alpha, p, ng, ns, front, mat, base, alpha, offset):
    """Surface data at the hits of rays d (N,3) (rows with prim < 0 are skipped): writes
    p, ng, ns (N,3) (normals facing the incoming ray; the shading normal falls back to ng
    where it would put the ray's origin below the surface), front (N,) (arrived on the
    winding's outside), mat (N,), base (N,3) (the material's base colour), alpha (N,),
    offset (N,) (rayoffset: the distance along ng that clears a ray origin of the
    triangle). The same values as bsdf.surface_hit for materials without textures,
    normal maps or alpha textures. corner_normals (T,3,3) float32, or (0,3,3) when every
    triangle is flat. (scatter computes the same inline, a block of hits at a time.)"""
    rows = np.empty(prim.shape[0], np.int64)
    tri = np.empty(prim.shape[0], np.int64)
    nh = 0
    for i in range(prim.shape[0]):
        if prim[i] >= 0:
            rows[nh] = i
            tri[nh] = prim[i]
            nh += 1
    tilt_row, tilt = _tilt_cache()
    _surfaces(rows, tri, 0, nh, False, u, v, d, v0, e1, e2, corner_normals, material,
              base_color, mat_alpha, p, ng, ns, front, mat, base, alpha, offset, tilt_row,
              tilt)


@kernel
def _tilt_cache():
    """An empty triangle cache for _surfaces: (triangle row of each slot, -1 = empty;
    (_TILT_SLOTS, 4): the triangle's tilt and unit winding normal)."""
    return np.full(_TILT_SLOTS, -1, np.int64), np.zeros((_TILT_SLOTS, 4))


@kernel
def _surfaces(rows, tri, lo, hi, compact, u, v, d, v0, e1, e2, corner_normals, material,
              base_color, mat_alpha, p, ng, ns, front, mat, base, alpha, offset, tilt_row,
              tilt):
    """photon_surfaces for the hits rows[lo:hi] on triangle rows tri[lo:hi], written at
    row i = rows[k] of the outputs, or at k - lo when compact (a block's own buffers).
    u, v: float64 or Embree's float32 (the same values either way). tilt_row, tilt: the
    call's triangle cache (_tilt_cache), read and filled here."""
    smooth = corner_normals.shape[0] > 0
    for k in range(lo, hi):
        i = rows[k]
        o = k - lo if compact else i
        t = tri[k]
        b1, b2 = np.float64(u[i]), np.float64(v[i])
        px = v0[t, 0] + b1 * e1[t, 0] + b2 * e2[t, 0]
        py = v0[t, 1] + b1 * e1[t, 1] + b2 * e2[t, 1]
        pz = v0[t, 2] + b1 * e1[t, 2] + b2 * e2[t, 2]
        slot = t & (_TILT_SLOTS - 1)
        if tilt_row[slot] != t:
            cx, cy, cz = winding_normal(e1, e2, t)
            ln = max(math.sqrt(cx * cx + cy * cy + cz * cz), 1e-300)
            tilt[slot, 0] = _tilt(v0, e1, e2, t)
            tilt[slot, 1], tilt[slot, 2], tilt[slot, 3] = cx / ln, cy / ln, cz / ln
            tilt_row[slot] = t
        tl = tilt[slot, 0]
        gx, gy, gz = tilt[slot, 1], tilt[slot, 2], tilt[slot, 3]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        fr = dx * gx + dy * gy + dz * gz < 0.0
        sign = 1.0 if fr else -1.0
        gx, gy, gz = gx * sign, gy * sign, gz * sign
        sx, sy, sz = gx, gy, gz
        if smooth:
            valid, nx, ny, nz = _interpolated_normal(corner_normals, t, b1, b2)
            if valid:
                sx, sy, sz = nx * sign, ny * sign, nz * sign
        # Veach's guard: a shading normal that puts the viewer below the surface.
        if -(dx * sx + dy * sy + dz * sz) <= 1e-6:
            sx, sy, sz = gx, gy, gz
        m = material[t]
        p[o, 0], p[o, 1], p[o, 2] = px, py, pz
        ng[o, 0], ng[o, 1], ng[o, 2] = gx, gy, gz
        ns[o, 0], ns[o, 1], ns[o, 2] = sx, sy, sz
        front[o] = fr
        mat[o] = m
        base[o, 0], base[o, 1], base[o, 2] = base_color[m, 0], base_color[m, 1], base_color[m, 2]
        alpha[o] = mat_alpha[m]
        ex = _point_error(v0, e1, e2, t, b1, b2, px, 0)
        ey = _point_error(v0, e1, e2, t, b1, b2, py, 1)
        ez = _point_error(v0, e1, e2, t, b1, b2, pz, 2)
        offset[o] = _offset_row(ex, ey, ez, v0, e1, e2, t, gx, gy, gz, px, py, pz, tl)


@kernel
def _interpolated_normal(corner_normals, t, b1, b2):
    """(valid, unit normal) of triangle row t's corner normals (T,3,3) interpolated at
    barycentrics b1, b2, on its winding's side; valid False for a degenerate or
    non-finite one (the geometric normal is used instead)."""
    b0 = 1.0 - b1 - b2
    nx = (b0 * corner_normals[t, 0, 0] + b1 * corner_normals[t, 1, 0]
          + b2 * corner_normals[t, 2, 0])
    ny = (b0 * corner_normals[t, 0, 1] + b1 * corner_normals[t, 1, 1]
          + b2 * corner_normals[t, 2, 1])
    nz = (b0 * corner_normals[t, 0, 2] + b1 * corner_normals[t, 1, 2]
          + b2 * corner_normals[t, 2, 2])
    nl = max(math.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
    nx, ny, nz = nx / nl, ny / nl, nz / nl
    s = abs(nx) + abs(ny) + abs(nz)
    return math.isfinite(s) and s >= 0.5, nx, ny, nz


@kernel
def _glass_normal(corner_normals, t, b1, b2, front, gx, gy, gz, nx, ny, nz):
    """The shading normal Cycles' glass closure starts from at a photon's hit (on the
    arrival side g): the hit's n, or, where photon_surfaces' guard replaced it by g (the
    photon arrives below it), the interpolated one again (Cycles has no such guard:
    glassadjoint takes those arrivals). Returns the unit normal (3 floats)."""
    if nx == gx and ny == gy and nz == gz and corner_normals.shape[0] > 0:
        valid, sx, sy, sz = _interpolated_normal(corner_normals, t, b1, b2)
        if valid:
            sign = 1.0 if front else -1.0
            return sx * sign, sy * sign, sz * sign
    return nx, ny, nz


@kernel
def _point_error(v0, e1, e2, t, b1, b2, pc, c):
    """rayoffset._point_error (component c) with the triangle's corner rounding
    (Geometry.round32) computed here rather than read from a table."""
    b0 = 1.0 - b1 - b2
    a0, a1, a2 = abs(b0), abs(b1), abs(b2)
    c0, c1, c2 = v0[t, c], v0[t, c] + e1[t, c], v0[t, c] + e2[t, c]
    interp = G64 * (a0 * abs(c0) + a1 * abs(c1) + a2 * abs(c2))
    tri32 = a0 * _round32(c0) + a1 * _round32(c1) + a2 * _round32(c2)
    return interp + tri32 + max(2.0 * U32 * abs(pc), TINY32)


# Ray class of the camera-side ray that a continued photon segment stands for, by lobe
# (principled.L_*; visibility.SPEC_LOBE_CLASS): the diffuse lobe's is set per photon
# (shadow rays for direct light, else diffuse rays); a transparent pass keeps the
# incoming kinds.
_LOBE_CLASS = np.array([0, 0, GLOSSY, GLOSSY, TRANSMISSION, GLOSSY, GLOSSY, DIFFUSE,
                        TRANSMISSION], np.int64)


@kernel
def _path_kind(flags):
    if flags & F_DIFFUSE:
        return CAUSTIC_DIFFUSE if flags & F_CAUSTIC_DIFF else INDIRECT
    return CAUSTIC if flags & F_SPECULAR else DIRECT


@kernel
def flat_exit(v0, e1, e2, material, object_id, flat_mat, flat_limit, entry, t, dx, dy, dz,
              px, py, pz):
    """True when a ray (direction d, any length) that entered glass through triangle row
    `entry` and meets triangle row t at point p leaves it through a flat passage: t is of
    the entry's material (flat_mat (M,) bool: smooth glass), leaves the glass (d along
    the face's winding normal) with its geometric normal within FLAT_COS of the entry's,
    and the slab's thickness (p's distance to the entry plane) is at most
    flat_limit[object_id[entry]] (m; flat_thickness_limits)."""
    if entry < 0 or t < 0 or material[t] != material[entry] or not flat_mat[material[t]]:
        return False
    ax, ay, az = winding_normal(e1, e2, entry)
    bx, by, bz = winding_normal(e1, e2, t)
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    if not (la > 0.0 and lb > 0.0):
        return False
    ax, ay, az = ax / la, ay / la, az / la
    if abs(ax * bx + ay * by + az * bz) < FLAT_COS * lb:
        return False
    if dx * bx + dy * by + dz * bz <= 0.0:
        return False  # arrives on the exit face's outside: not leaving the glass
    thick = abs((px - v0[entry, 0]) * ax + (py - v0[entry, 1]) * ay
                + (pz - v0[entry, 2]) * az)
    return thick <= flat_limit[object_id[entry]]


@kernel
def flat_entry(e1, e2, material, flat_mat, t, dx, dy, dz):
    """True when a ray along d meeting triangle row t enters smooth glass that may form a
    flat passage: t's material is in flat_mat and d arrives on its winding's outside."""
    if t < 0 or not flat_mat[material[t]]:
        return False
    bx, by, bz = winding_normal(e1, e2, t)
    return dx * bx + dy * by + dz * bz < 0.0


def flat_glass_materials(table) -> np.ndarray:
    """(M,) bool: materials whose every lobe is smooth glass (Glass, Refraction, or
    Principled with transmission 1, roughness below the delta threshold ggx.ALPHA_MIN,
    opaque alpha, no metal, coat, sheen or Add Shader, no per-hit texture or normal map):
    the only ones a flat passage can cross."""
    from .closures import ggx
    params = np.asarray(table.closure_params)
    M = len(params)
    if M == 0:
        return np.zeros(0, np.bool_)
    rough = params[:, pr.M_ROUGH]
    ok = ((params[:, pr.M_TRANS] >= 1.0) & (rough * rough < ggx.ALPHA_MIN)
          & (np.asarray(table.alpha) >= 1.0) & (params[:, pr.M_METALLIC] <= 0.0)
          & (params[:, pr.M_COAT_W] <= 0.0) & (params[:, pr.M_SHEEN_W] <= 0.0)
          & (params[:, pr.M_ADD] == 0.0) & (params[:, pr.M_TL] <= 0.0))
    for attr in ("textures", "normal_maps", "alpha_textures", "scalar_textures"):
        nodes = getattr(table, attr, None)
        if nodes is not None and len(nodes) == M:
            ok &= np.array([n is None or (isinstance(n, (list, tuple)) and not n)
                            for n in nodes], np.bool_)
    return np.ascontiguousarray(ok)


def flat_thickness_limits(geo) -> np.ndarray:
    """(objects,) float64: the thickest slab of each object that still counts as flat
    (m): FLAT_OBJECT_SHARE of the object's bounding-box diagonal, at most FLAT_SCENE_SHARE
    of the scene's (Geometry.extent)."""
    n = len(geo.object_names)
    out = np.zeros(n)
    if geo.count == 0 or n == 0:
        return out
    oid = np.asarray(geo.object_id, np.int64)
    corners = np.concatenate([geo.v0, geo.v0 + geo.e1, geo.v0 + geo.e2])
    ids = np.concatenate([oid, oid, oid])
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, ids, corners)
    np.maximum.at(hi, ids, corners)
    diag = np.sqrt(np.sum(np.where(np.isfinite(hi - lo), hi - lo, 0.0) ** 2, axis=1))
    return np.ascontiguousarray(np.minimum(FLAT_OBJECT_SHARE * diag,
                                           FLAT_SCENE_SHARE * float(geo.extent)))


_NO_FLAT_MAT = np.zeros(0, np.bool_)
_NO_PANE_TRI = np.zeros(0, np.int64)
_NO_FLAT_LIMIT = np.zeros(0)


def window_triangles(geo, flat, limit) -> np.ndarray:
    """(T,) bool: triangles of window glass, objects wholly of flat-glass materials (flat
    (M,) bool) with two opposite faces (geometric normals within FLAT_COS of the largest
    triangle's, both orientations present) no further apart than the object's flat limit
    (limit (objects,)). Only such objects can hold a flat passage; without any, a scene
    has none (a glass ball or cube costs nothing here). Single-plane glass is not window
    glass (one orientation only)."""
    out = np.zeros(geo.count, bool)
    on = flat[geo.material]
    if not on.any():
        return out
    for oid in np.unique(geo.object_id[on]):
        tris = np.nonzero(geo.object_id == oid)[0]
        if not np.all(on[tris]):
            continue
        e1, e2 = geo.e1[tris], geo.e2[tris]
        cross = np.cross(e1, e2)
        area = np.linalg.norm(cross, axis=1)
        big = int(np.argmax(area))
        if not area[big] > 0:
            continue
        n0 = cross[big] / area[big]
        c = (cross @ n0) / np.maximum(area, 1e-300)
        if not (np.any(c >= FLAT_COS) and np.any(c <= -FLAT_COS)):
            continue
        v0 = geo.v0[tris]
        h = np.concatenate([v0 @ n0, (v0 + e1) @ n0, (v0 + e2) @ n0])
        if h.max() - h.min() <= limit[oid]:
            out[tris] = True
    return out


def flat_tables(geo, table):
    """(flat_mat (M,) bool, flat_limit (objects,)) for a prepared scene, or two empty
    arrays when no triangle is of a flat-glass material, or the scene's instances share
    their tables (engine/sharedrows.py: no per-triangle rows to remember an entry by).
    Cached on geo for its table (both passes use the same tables)."""
    cached = getattr(geo, "_flat_tables", None)
    if cached is not None and cached[0] is table:
        return cached[1]
    out = (_NO_FLAT_MAT, _NO_FLAT_LIMIT)
    if geo.count > 0 and getattr(geo, "shared", None) is None:
        flat = flat_glass_materials(table)
        if len(flat) and flat[geo.used_materials()].any():
            limit = flat_thickness_limits(geo)
            if window_triangles(geo, flat, limit).any():
                out = (flat, limit)
    try:
        geo._flat_tables = (table, out)
    except AttributeError:
        pass
    return out


_NO_ANISO_TAN = np.zeros((0, 3, 3))
_NO_MAY_DIFFUSE = np.zeros(0, np.bool_)
NO_BLUR_STATE = np.zeros(0)  # scatter: no Filter Glossy state kept
NO_CLAMP = np.zeros(0)  # scatter: no Clamp Indirect radiance ratio kept
NO_ROWS = np.zeros(0, np.int64)  # scatter: the continued rays' rows not written

# _scatter's argument `plain`: its position in the argument list.
_PLAIN_ARG = 31


def scatter(*args, flat_mat=_NO_FLAT_MAT, flat_limit=_NO_FLAT_LIMIT, aniso_tan=_NO_ANISO_TAN,
            may_diffuse=_NO_MAY_DIFFUSE, pane_tri=_NO_PANE_TRI, blur=NO_BLUR_STATE,
            passage_blur=None, gather_blur=0.0, split_slots=0, clamp=NO_CLAMP,
            nx_clamp=NO_CLAMP, nx_blur=NO_BLUR_STATE, nx_row=NO_ROWS, light_pdf=NO_CLAMP,
            pane_passes=True):
    """_scatter (the kernel) with the flat-passage tables: flat_mat (M,) bool
    (flat_glass_materials) and flat_limit (objects,) (flat_thickness_limits), triangle
    rows being the scene's own (no shared instances); empty (the default): no flat
    passages. `plain` may be lobe_classes' int8 codes or plain_materials' booleans (True:
    PLAIN, False: FULL; one compiled kernel for both). aniso_tan (T,3,3): the
    anisotropic lobes' per-corner world tangents (anisotropy.triangle_tangents), empty:
    none (those lobes scatter isotropically). may_diffuse (rows of params,) bool: a
    photon is stored where its row's flag is set even if the hit's own diffuse weight is
    0 (a texture-driven metallic map, a Mix Shader's per-hit closure pick: the incident
    flux does not depend on which closure the hit took); empty (the default): stored
    where the hit's diffuse weight is > 0. pane_tri (T,) int64: the next-event pane
    (engine/panelight.py) of each triangle row, -1 for none, SHADE_TRANSLUCENT or
    SHADE_GLASS a next-event lamp shade's (engine/shadelight.py); empty (the default, and
    for photons of lights served by neither): none. blur (m,) float64: each photon's
    Filter Glossy state (_scatter; -1 at emission), with nx_blur (as many rows as nx_*)
    for the continued photons'; empty (the default): none kept, every stored photon's
    blur pdf inf. passage_blur: None, or (Filter Glossy,
    blurredpassage.table(), blurredpassage.IOR): a photon out of a flat passage keeps
    passage_factor of its power at the blur of cos / pi, cos its direction's to the
    glass's normal (Cycles blurs the slab after the diffuse bounce at the hit it lights;
    docs/compatibility.md "fgslab49"). gather_blur: Filter Glossy (0, the default: off)
    with which the FULL hits of photons past a diffuse bounce scatter off blurred lobes
    (_scatter's gather_fg; docs/accuracy.md "photonblur49"). split_slots: with gather_blur
    > 0, the slot offset of the blurred copies of photons split at their first
    non-diffuse scatter (the chunk's slot count; nx_* then need room for one more copy
    per hit); 0 (the default): no split (_scatter).
    clamp (m,) float64: each photon's |L|_1 / |power|_1 (_scatter; set at emission by
    engine/photonclamp.py), with the stored photons' radiance array (store_arrays(m,
    True)) and nx_clamp (as many rows as nx_*) for the continued photons'; empty (the
    default): none kept. nx_row (as many rows as nx_*) int64: the row of d each continued
    photon came from (its continuation's or its copy's), for the caller's own per-ray
    state (media, coincident faces); empty (the default): not written. light_pdf (m,)
    float64: with clamp, each photon's light's solid-angle pdf towards the light at its
    hit (photonclamp.light_pdfs; <= 0: none), which its first non-delta scatter's
    nx_clamp takes (_scatter); empty (the default): none. pane_passes: whether the
    panes' shadow rays cross transparent passes (ctx.shadow exists): only then does a
    pass after a pane keep its photon direct (F_PANE_PLANE), else it goes caustic."""
    plain = args[_PLAIN_ARG]
    if plain.dtype != np.int8:
        args = (args[:_PLAIN_ARG] + (np.ascontiguousarray(plain, np.int8),)
                + args[_PLAIN_ARG + 1:])
    if GLASS_ADJOINT_MODE == GLASS_ADJOINT_EVERY_BENT:
        bend_cos = _FLAT_NORMAL_COS
    else:
        bend_cos = math.cos(math.radians(GLASS_ADJOINT_MIN_BEND_DEG))
    fg, ptab, pior = (0.0, _NO_PASSAGE_TAB, _NO_PASSAGE_IOR) if passage_blur is None \
        else passage_blur
    return _scatter(*args, flat_mat, flat_limit, aniso_tan, may_diffuse, pane_tri,
                    GLASS_ADJOINT_MODE, bend_cos, blur, float(fg), ptab, pior,
                    float(gather_blur), int(split_slots), clamp, nx_clamp, nx_blur, nx_row,
                    light_pdf, bool(pane_passes))


_NO_PASSAGE_TAB, _NO_PASSAGE_IOR = np.ones((2, 2, 2)), np.array([1.0, 2.0])

# Cycles' min_ray_pdf stand-in for a photon's scatter read past the camera's diffuse
# bounce (_scatter's gather_fg): a cosine-sampled gather ray's mean pdf, E[cos] / pi =
# (2/3) / pi; Filter Glossy 1 blurs to alpha 0.444 (0.41 .. 0.5 over the ray's cosines).
GATHER_PDF = (2.0 / 3.0) / math.pi


# How scatter sends photons at smooth glass with a bent shading normal.
# GLASS_ADJOINT_WHERE_TURNED (the default): where the normal is bent more than
# GLASS_ADJOINT_MIN_BEND_DEG from the face, by engine/glassadjoint.py (the adjoint of
# Cycles' per-direction turned normal: its flux ratio |w.Ng| / |s.Ng|, and the root
# search for turned-normal refractions only where glassadjoint.turn_possible); at
# smaller bends by the glass lobe's own sample about the shading normal (main's bits:
# there Cycles turns the normal only for arrivals within ~3 bends of grazing or of the
# critical angle and the flux ratio is 1 + O(bend), no change an image shows:
# docs/accuracy.md, smoothglass44; a UV sphere of 32 segments bends its normals up to
# ~5.3 degrees). The other two are diagnostics for A/B runs in one process
# (bench/bench_accuracy_ab.py's @photonkernels.GLASS_ADJOINT_MODE=...; tests): never, or
# with the root search at every hit bent more than ~0.1 degree (smoothglass43's rule).
GLASS_ADJOINT_NEVER, GLASS_ADJOINT_EVERY_BENT, GLASS_ADJOINT_WHERE_TURNED = 0, 1, 2
GLASS_ADJOINT_MODE = GLASS_ADJOINT_WHERE_TURNED
GLASS_ADJOINT_MIN_BEND_DEG = 6.0


# smooth_glass's per-(material, side) constants (smooth_glass_consts), columns of a row:
_SG_SET = 0      # 1: the row is filled
_SG_ETA = 1      # eta = ior outside, 1 / ior inside
_SG_F0 = 2       # F0_from_ior(ior)
_SG_X0 = 3       # 1: rough <= 0, the glass tables read at x = 0 from the columns below
_SG_EAVG = 4     # GLASS_EAVG / GLASS_INV_EAVG at z (rough <= 0)
_SG_KE = 5       # the E table's z cell (tables._coord: index as a float, fraction)
_SG_FZE = 6
_SG_KS = 7       # SCHLICK_IOR_S's z cell
_SG_FZS = 8
_SG_F0E = 9      # F0_from_ior(eta): schlick_remap(., eta)'s f0 on this side
_SG_INV_ETA = 10  # 1 / eta
_SG_F0C = 11     # (3) the glass lobe's f0 per channel (P_GLASS_F0)
_SG_BASE = 14    # (3) the base colour the next columns were taken for (NaN: none yet)
_SG_RT = 17      # (3) reflection tint of that base (Glass BSDF: base, Principled: 1)
_SG_TT = 20      # (3) transmission tint (Glass BSDF: base, Principled: sqrt(base))
_SG_FMS = 23     # (3) ggx.energy_factor's Fms of that tint (Multiscatter GGX; E_avg is the side's)
SG_N = 26


@kernel
def _lookup2_x0(tab, y):
    """tables.lookup2(tab, 0, y), the same bits (a x 1 + b x 0 is a: lookup3_at at x's
    cell (0, 0))."""
    if tab.shape[0] == 1:
        return tab[0, 0]
    j, fy = tables._coord(y, tab.shape[1])
    return tab[0, j] * (1.0 - fy) + tab[0, j + 1] * fy


@kernel
def smooth_glass_consts(params, m, front, sg, r):
    """Fill row r of sg (R, SG_N) with smooth_glass's terms of material row m on one side
    (front: arrived outside) that no hit changes: eta, F0, and at roughness <= 0 the glass
    tables' z cells and their average albedo (tables.lookup3(tab, 0, y, z) =
    tables.lookup3_at(tab, 0, 0, y, k, fz) with (k, fz) = tables._coord(z): the same
    operations on the same values as per hit, so the same bits), schlick_remap's f0 and
    1 / eta on this side, and the glass lobe's f0 per channel. The base colour's tints
    (_SG_BASE ..) are filled by smooth_glass_at at the row's first hit."""
    rough = params[m, pr.M_ROUGH]
    ior = max(params[m, pr.M_IOR], 1e-5)
    eta = ior if front else 1.0 / ior
    sg[r, _SG_ETA] = eta
    sg[r, _SG_F0] = F0_from_ior(ior)
    sg[r, _SG_X0] = 0.0 if rough > 0.0 else 1.0  # as setup's `rough > 0` test
    if sg[r, _SG_X0] != 0.0:
        if eta < 1.0:
            z = tables.z_from_ior(1.0 / eta)
            k, fz = tables._coord(z, tables.GLASS_INV_E.shape[2])
            sg[r, _SG_EAVG] = _lookup2_x0(tables.GLASS_INV_EAVG, z)
        else:
            z = tables.z_from_ior(eta)
            k, fz = tables._coord(z, tables.GLASS_E.shape[2])
            sg[r, _SG_EAVG] = _lookup2_x0(tables.GLASS_EAVG, z)
        sg[r, _SG_KE], sg[r, _SG_FZE] = float(k), fz
        k, fz = tables._coord(tables.z_from_ior(max(ior, 1.0)), tables.SCHLICK_IOR_S.shape[2])
        sg[r, _SG_KS], sg[r, _SG_FZS] = float(k), fz
    sg[r, _SG_F0E] = F0_from_ior(eta)
    sg[r, _SG_INV_ETA] = 1.0 / eta
    glass_node = params[m, pr.M_NODE] == pr.NODE_GLASS
    for c in range(3):
        sg[r, _SG_F0C + c] = (sg[r, _SG_F0] if glass_node else
                              min(sg[r, _SG_F0] * max(params[m, pr.M_STINT + c], 0.0), 1.0))
        sg[r, _SG_BASE + c] = np.nan  # (never equal: the first hit fills the tints)
    sg[r, _SG_SET] = 1.0


@kernel
def _glass_tables(rough, mu, eta, ior, sg, r):
    """(tables.glass_E(rough, mu, eta), tables.schlick_ior_s(rough, mu, ior)) as
    principled.setup reads them, the same bits; at rough <= 0 (a coordinate clamped to
    the tables' first plane) through x = 0 lookups at the z cells of sg[r]
    (smooth_glass_consts)."""
    if sg[r, _SG_X0] == 0.0:
        Eg, Eg_avg = tables.glass_E(rough, mu, eta)
        return Eg, Eg_avg, tables.schlick_ior_s(rough, mu, ior)
    tab = tables.GLASS_INV_E if eta < 1.0 else tables.GLASS_E
    Eg = tables.lookup3_at(tab, 0.0, 0.0, mu, sg[r, _SG_KE], sg[r, _SG_FZE])
    s_out = tables.lookup3_at(tables.SCHLICK_IOR_S, 0.0, 0.0, mu, sg[r, _SG_KS], sg[r, _SG_FZS])
    return Eg, sg[r, _SG_EAVG], s_out


@kernel
def smooth_glass(params, m, a, base, j, cos_o, front, gprm, wj):
    """principled.setup for one hit on a SMOOTH_GLASS material (lobe_classes), the same
    bits, without its 66 zeroed slots and the layers it would skip: material row m,
    hit alpha a, base colour base[j] (3,), cos_o = ns . wo, front (arrived outside).
    Writes the pass, glass (reflection, transmission) and diffuse (0: transmission 1
    leaves the base nothing) weights to wj[L_*] (N_LOBES, 3), and the glass lobe's
    packed columns (P_GLASS_*, all _glass_sample reads) to gprm[0]. Glass tables are
    read only where the energy compensation uses them (Multiscatter GGX). Returns the
    real-Fresnel remap schlick_remap(mu, eta) where computed (eta < 1), else -1."""
    sg = np.empty((1, SG_N))
    smooth_glass_consts(params, m, front, sg, 0)
    return smooth_glass_at(params, m, a, base, j, cos_o, gprm, wj, sg, 0)


@kernel
def glass_adjoint(params, m, base, j, eta_in, mu_in, mu_out, transmitted):
    """(3,) per-channel factors that make a photon's rough glass scattering the adjoint of
    Cycles' glass closure in its energy compensation: principled.setup scales the lobe by
    Cycles' multiple-scattering factor (ggx.energy_factor of tables.glass_E) at the view
    cosine on the view side, which for a photon is where it arrived from (mu_in, eta_in =
    n(far side) / n(arrival side)); Cycles' camera path reaches the same surface from the
    side the photon leaves to, and takes the factor there (microfacet_ggx_preserve_energy
    at its own wo): the factor of the photon's outgoing direction (mu_out = |cos|, on the
    far side for a refraction: eta 1 / eta_in). The compensation is not reciprocal, so the
    photon takes factor(out) / factor(in): 1 for plain GGX, a smooth lobe or a Refraction
    BSDF (no compensation). Thin glass lit from inside (a lamp shade of rough glass around
    its lamp) read +6 % (roughness 0.5) to +59 % (roughness 1) on the walls without it
    (docs/accuracy.md, lamp30). m: material row of params; base (N,3), j: the hit's base
    colour row (Principled's transmission tint is sqrt(base), Glass BSDF's base)."""
    node = params[m, pr.M_NODE]
    rough = params[m, pr.M_ROUGH]
    if (params[m, pr.M_MULTI] == 0.0 or node == pr.NODE_REFRACTION
            or rough * rough < ggx.ALPHA_MIN):
        return 1.0, 1.0, 1.0
    eta_out = 1.0 / eta_in if transmitted else eta_in
    e_in, ea_in = tables.glass_E(rough, min(max(mu_in, 0.0), 1.0), eta_in)
    e_out, ea_out = tables.glass_E(rough, min(max(mu_out, 0.0), 1.0), eta_out)
    # (Per channel as scalars: no array allocated per scattered photon.)
    glass_node = node == pr.NODE_GLASS
    return (_adjoint_channel(e_in, ea_in, e_out, ea_out, base[j, 0], glass_node),
            _adjoint_channel(e_in, ea_in, e_out, ea_out, base[j, 1], glass_node),
            _adjoint_channel(e_in, ea_in, e_out, ea_out, base[j, 2], glass_node))


@kernel
def lobe_adjoint(params, m, base, j, front, a, prm, w, jc, lobe, mu_out, scr):
    """Per-channel factors (3 floats) that make a photon's scattering off a FULL
    Principled hit's diffuse base, metal, dielectric specular or coat lobe the adjoint of
    Cycles' closure. Cycles weighs each of them by terms read at the view direction alone:
    Multiscatter GGX's energy compensation (microfacet_ggx_preserve_energy), the albedos
    of the layers above that darken what lies below (coat, specular layer, sheen:
    bsdf_albedo in svm_closure.h / bsdf_principled.h) and the coat tint's optical depth.
    A camera path meets this surface from the side the photon leaves to, so the photon
    takes those terms at its outgoing cosine mu_out (ns . wo), not at its arrival cosine
    where principled.setup read them (prm, w row jc): factor = coefficient(mu_out) /
    coefficient(mu_in), the coefficient being the lobe's weight (L_DIFFUSE) or its packed
    weight (P_METAL_W, P_SPEC_W, P_COAT_W), each a constant factor on the lobe's
    single-scattering BSDF. A channel whose coefficient was 0 at the arrival keeps 0.
    Without it a panel lit by a rough metal floor's reflection read +2.5 % of Cycles at
    roughness 1, +2.4 % under a rough coat (docs/accuracy.md, roughlobes31). m: material row; base (N,3), row j; front,
    a: the hit's side and alpha; scr: make_adjoint_scratch(). Not handled (factor 1):
    the sheen lobe (its LTC's shape, not only its weight, follows the view), the
    translucent lobe (no view-dependent term) and the glass lobe (glass_adjoint)."""
    if lobe == pr.L_DIFFUSE:
        col = -1
    elif lobe == pr.L_METAL:
        col = pr.P_METAL_W
    elif lobe == pr.L_SPEC:
        col = pr.P_SPEC_W
    elif lobe == pr.L_COAT:
        col = pr.P_COAT_W
    else:
        return 1.0, 1.0, 1.0
    mat1, base1, cos1, front1, a1, prm1, w1 = scr
    mat1[0] = m
    base1[0, 0], base1[0, 1], base1[0, 2] = base[j, 0], base[j, 1], base[j, 2]
    cos1[0] = mu_out
    front1[0] = front
    a1[0] = a
    pr.setup(mat1, params, base1, cos1, front1, a1, prm1, w1)
    if col < 0:
        return (_ratio(w1[0, pr.L_DIFFUSE, 0], w[jc, pr.L_DIFFUSE, 0]),
                _ratio(w1[0, pr.L_DIFFUSE, 1], w[jc, pr.L_DIFFUSE, 1]),
                _ratio(w1[0, pr.L_DIFFUSE, 2], w[jc, pr.L_DIFFUSE, 2]))
    return (_ratio(prm1[0, col], prm[jc, col]), _ratio(prm1[0, col + 1], prm[jc, col + 1]),
            _ratio(prm1[0, col + 2], prm[jc, col + 2]))


@kernel
def _ratio(out, inn):
    return out / inn if inn > 0.0 else 0.0


@kernel
def make_adjoint_scratch():
    """lobe_adjoint's one-hit set-up buffers: (mat, base, cos_o, front, alpha, prm,
    weights) as principled.setup takes them, one row each."""
    return (np.empty(1, np.int64), np.empty((1, 3)), np.empty(1), np.empty(1, np.bool_),
            np.empty(1), np.empty((1, pr.N_PACK)), np.empty((1, pr.N_LOBES, 3)))


@kernel
def _adjoint_channel(e_in, ea_in, e_out, ea_out, colour, glass_node):
    """glass_adjoint's factor for one channel of base colour `colour`: the transmission
    tint is the colour (Glass BSDF) or sqrt(colour) (Principled)."""
    tt = max(colour, 0.0) if glass_node else math.sqrt(min(max(colour, 0.0), 1.0))
    return ggx.energy_factor(e_out, ea_out, tt) / ggx.energy_factor(e_in, ea_in, tt)


@kernel
def _glass_s(rough, mu, ior, sg, r):
    """_glass_tables' third value alone (tables.schlick_ior_s, the same bits), for a
    material without Multiscatter GGX: its E and E_avg are not used (_compensation is
    (1, 1) there)."""
    if sg[r, _SG_X0] == 0.0:
        return tables.schlick_ior_s(rough, mu, ior)
    return tables.lookup3_at(tables.SCHLICK_IOR_S, 0.0, 0.0, mu, sg[r, _SG_KS], sg[r, _SG_FZS])


@kernel
def _schlick_remap_f0(cos_i, eta, f0):
    """fresnel.schlick_remap(cos_i, eta) with its f0 = F0_from_ior(eta) given (a
    constant of the material's side, sg[r, _SG_F0E]): the same operations on the same
    values, so the same bits."""
    f = fresnel_dielectric(cos_i, eta)
    if f0 >= 1.0:
        return 1.0
    return min(max((f - f0) / (1.0 - f0), 0.0), 1.0)


@kernel
def _same(x, y):
    """x and y are the same float for the tints' clamps and square root: equal, and of
    the same sign where 0 (-0.0 == 0.0, but max(-0.0, 0.0) and sqrt keep a sign)."""
    return x == y and (x != 0.0 or math.copysign(1.0, x) == math.copysign(1.0, y))


@_inline_kernel
def smooth_glass_at(params, m, a, base, j, cos_o, gprm, wj, sg, r):
    """smooth_glass with the material side's constants sg[r] (smooth_glass_consts) given:
    scatter fills them once per (material, side) a call. The same bits as smooth_glass
    before the constants: the glass tables are read only where their values are used
    (E and E_avg with Multiscatter GGX; s for a photon arriving from outside), the
    transmission tint sqrt(base) of a Principled glass, the f0 per channel and the energy
    compensation's Fms per channel are taken again only when the hit's base colour
    differs from the row's last one (an untextured base: once a call), the compensation's
    (1 - E) / E once for the three channels, and without Multiscatter GGX the weights
    skip their factors of exactly 1 (x * 1.0 is x)."""
    mu = min(max(cos_o, 0.0), 1.0)
    W = a * (1.0 + params[m, pr.M_ADD])
    for c in range(3):
        wj[pr.L_PASS, c] = (1.0 - a) * params[m, pr.M_TTINT + c]
    rough = params[m, pr.M_ROUGH]
    multi = params[m, pr.M_MULTI]
    tr = params[m, pr.M_TRANS]
    eta = sg[r, _SG_ETA]
    Eg = Eg_avg = s_out = 0.0
    if multi != 0.0:
        Eg, Eg_avg, s_out = _glass_tables(rough, mu, eta, max(params[m, pr.M_IOR], 1e-5),
                                          sg, r)
    elif eta >= 1.0:
        s_out = _glass_s(rough, mu, max(params[m, pr.M_IOR], 1e-5), sg, r)
    remap = -1.0
    if eta >= 1.0:
        s_n = s_out
    else:
        s_n = remap = _schlick_remap_f0(mu, eta, sg[r, _SG_F0E])
    if not (_same(base[j, 0], sg[r, _SG_BASE]) and _same(base[j, 1], sg[r, _SG_BASE + 1])
            and _same(base[j, 2], sg[r, _SG_BASE + 2])):
        glass_node = params[m, pr.M_NODE] == pr.NODE_GLASS
        for c in range(3):
            sg[r, _SG_BASE + c] = base[j, c]
            if glass_node:
                tt = max(base[j, c], 0.0)
                sg[r, _SG_RT + c] = tt
            else:
                tt = math.sqrt(min(max(base[j, c], 0.0), 1.0))
                sg[r, _SG_RT + c] = 1.0
            sg[r, _SG_TT + c] = tt
            if multi != 0.0:
                # ggx.energy_factor's Fms for Fss = tt: E_avg depends on the roughness
                # and eta alone (the row's), so it is the row's per tint.
                sg[r, _SG_FMS + c] = tt * Eg_avg / max(1.0 - tt * (1.0 - Eg_avg), 1e-9)
    tW = tr * W
    if multi != 0.0:
        # principled._compensation's (f, f x E) with f = ggx.energy_factor(E, E_avg, tt)
        # = 1 + Fms (1 - E') / E' (E' = max(E, 1e-4)): its per-hit term, once for the
        # three channels.
        Ec = max(Eg, 1e-4)
        missing = (1.0 - Ec) / Ec
    else:
        missing = 0.0
    for c in range(3):
        rt = sg[r, _SG_RT + c]
        tt = sg[r, _SG_TT + c]
        f0 = sg[r, _SG_F0C + c]
        F = f0 + (1.0 - f0) * s_n
        gprm[0, pr.P_GLASS_F0 + c] = f0
        if multi == 0.0:
            # _compensation's (1, 1): fac and dark are exact factors of 1.
            gprm[0, pr.P_GLASS_RW + c] = tW * rt
            gprm[0, pr.P_GLASS_TW + c] = tW * tt
            wj[pr.L_GLASS_R, c] = tW * rt * F
            wj[pr.L_GLASS_T, c] = tW * tt * (1.0 - F)
        else:
            fac = 1.0 + sg[r, _SG_FMS + c] * missing
            dark = fac * Eg
            gprm[0, pr.P_GLASS_RW + c] = tW * rt * fac
            gprm[0, pr.P_GLASS_TW + c] = tW * tt * fac
            wj[pr.L_GLASS_R, c] = tW * rt * dark * F
            wj[pr.L_GLASS_T, c] = tW * tt * dark * (1.0 - F)
    gprm[0, pr.P_GLASS_ALPHA] = rough * rough
    gprm[0, pr.P_GLASS_ETA] = eta
    Wd = W * (1.0 - tr)
    for c in range(3):
        wj[pr.L_DIFFUSE, c] = Wd * base[j, c]
    return remap


@kernel
def _smooth_glass_sample(gprm, ox, oy, oz, u3, mu, remap):
    """principled._glass_sample(gprm, 0, ox, oy, oz, 0, 0, u3) of a smooth glass hit (its
    microfacet normal is the shading normal, c = wo . n), the same operations on the same
    values, so the same bits; except that the real-Fresnel remap schlick_remap(c, eta) is
    remap where smooth_glass computed it for the same cosine (c == mu, remap >= 0)."""
    eta = gprm[0, pr.P_GLASS_ETA]
    return _smooth_glass_sample_at(gprm, ox, oy, oz, u3, mu, remap, F0_from_ior(eta),
                                   1.0 / eta)


@_inline_kernel
def _smooth_glass_sample_at(gprm, ox, oy, oz, u3, mu, remap, f0e, inv_eta):
    """_smooth_glass_sample with its side's constants given: f0e = F0_from_ior(eta)
    and inv_eta = 1 / eta (smooth_glass_consts' _SG_F0E, _SG_INV_ETA; eta =
    gprm[0, P_GLASS_ETA]), the same bits."""
    if gprm[0, pr.P_GLASS_ALPHA] >= ggx.ALPHA_MIN:  # not smooth after all
        return pr._glass_sample(gprm, 0, ox, oy, oz, 0.0, 0.0, u3)
    eta = gprm[0, pr.P_GLASS_ETA]
    hx, hy, hz = 0.0, 0.0, 1.0
    c = ox * hx + oy * hy + oz * hz
    if c <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, False
    s = remap if (remap >= 0.0 and c == mu) else _schlick_remap_f0(c, eta, f0e)
    F0 = pr._glass_F_s(gprm[0, pr.P_GLASS_F0], s)
    F1 = pr._glass_F_s(gprm[0, pr.P_GLASS_F0 + 1], s)
    F2 = pr._glass_F_s(gprm[0, pr.P_GLASS_F0 + 2], s)
    r0 = gprm[0, pr.P_GLASS_RW] * F0
    r1 = gprm[0, pr.P_GLASS_RW + 1] * F1
    r2 = gprm[0, pr.P_GLASS_RW + 2] * F2
    t0 = gprm[0, pr.P_GLASS_TW] * (1.0 - F0)
    t1 = gprm[0, pr.P_GLASS_TW + 1] * (1.0 - F1)
    t2 = gprm[0, pr.P_GLASS_TW + 2] * (1.0 - F2)
    s2 = inv_eta * inv_eta * (1.0 - c * c)
    if s2 >= 1.0:  # total internal reflection
        t0 = t1 = t2 = 0.0
    sr = r0 + r1 + r2
    st = t0 + t1 + t2
    if sr + st <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, False
    p_r = sr / (sr + st)
    if u3 < p_r:
        ix, iy, iz = 2.0 * c * hx - ox, 2.0 * c * hy - oy, 2.0 * c * hz - oz
        if iz <= 0.0:
            return ix, iy, iz, 0.0, 0.0, 0.0, False
        k = 1.0 / p_r
        return ix, iy, iz, r0 * k, r1 * k, r2 * k, False
    ct = math.sqrt(1.0 - s2)
    kk = inv_eta * c - ct
    ix, iy, iz = -inv_eta * ox + kk * hx, -inv_eta * oy + kk * hy, -inv_eta * oz + kk * hz
    if iz >= 0.0:
        return ix, iy, iz, 0.0, 0.0, 0.0, True
    k = 1.0 / (1.0 - p_r)
    return ix, iy, iz, t0 * k, t1 * k, t2 * k, True


@kernel
def _scatter(key, bounce, d, power, flags, kinds, slot, bnc, geom, prim, starts, u, v, v0,
             e1, e2, corner_normals, material, base_color, mat_alpha, given, p, ng, ns, front,
             mat, base, alpha, offset, bump, params, plain, mat_ior, visibility, object_id,
             caster, first_hit_mode, caustic_only, vis_on, limits,
             st_pos, st_power, st_dir, st_normal, st_kind, st_bnc, st_surface, st_blur,
             st_rad, nx_o, nx_d32, nx_d, nx_power, nx_flags, nx_kinds, nx_slot, nx_bnc, nx_from,
             nx_off, hit_rows, flat_mat, flat_limit, aniso_tan, may_diffuse, pane_tri,
             adjoint_mode, bend_cos, blur, passage_fg, passage_tab, passage_ior,
             gather_fg, split_slots, clamp, nx_clamp, nx_blur, nx_row, light_pdf,
             pane_passes):
    """One bounce of m photons that arrived along d (m,3) with power (m,3) W, path flags,
    ray kinds, slots and packed bounce counts bnc (m,) int64 (B_TOTAL ...), at the hits
    as Embree answers them (Accel.intersect_hits):
    geom, prim (m,) int32 (geom < 0: missed; lost; else the triangle's row is
    starts[geom] + prim, starts (G,) int64). Surface data: with
    given False computed here from the hits' float32 barycentrics u, v (m,) and the triangle
    tables v0, e1, e2 (T,3), corner_normals (T,3,3) float32 or (0,3,3), material (T,),
    base_color (M,3) and mat_alpha (M,) (photon_surfaces' inputs; p .. offset unused,
    may be empty); with given True read from p, ng, ns, front, mat, base, alpha, offset
    (photon_surfaces' outputs, or bsdf.surface_hit's). bump (m,) the diffuse lobe's bump shadowing
    factor (normalmap.bump_shadowing; 1 without a bent normal), or (0,): 1 for every
    photon (x * 1.0 is x: the same bits without reading it). params, mat_ior: the
    material table's closure parameters and IOR; plain (M,) int8 lobe_classes: PLAIN
    materials have only the diffuse and pass lobes, whose weights need no closure set-up;
    SMOOTH_GLASS ones are set up per hit by smooth_glass (both the same bits as
    principled.setup); FULL ones through principled.setup.
    visibility (T,) ray
    kinds per triangle, used with vis_on. caster (objects,) bool and first_hit_mode (0:
    off, 1: store caustic photons whose first hit is not on a caster, 2: only those whose
    first hit is) split the caustic paths between an aimed and an unaimed shot.
    limits (4,) int64: the bounce limits (settings.bounce_limits, B_TOTAL order); a
    photon whose counts after this scatter no photon lookup could use (bounce_usable with
    no camera-side bounce) is not continued.

    Writes the stored photons (float32 position, power, direction of travel, normal on
    the arriving side; uint8 kind; (4,) uint8 bounce counts; int32 surface: the hit's
    object_id, Photons.surface) to st_* (m rows at most) and
    the continued photons (float32 origins and directions for Embree, float64 directions,
    power, flags, kinds, slots, packed bounce counts; the triangle row each left, -1 for
    the copies below, and its origin's offset off the hit point (3,) float64, o = p + off,
    0 for the copies: engine/coincident.py's probe, written only where nx_from has rows,
    next_arrays(m, True)) to nx_* (2m rows at most: the continuations, then the
    copies that pass
    surfaces some of their ray kinds do not see). Returns (stored, continued) counts.
    hit_rows (2, >= m) int64: scratch for the hits' rows and triangle rows (lent by the
    trace's buffer pool: fresh arrays per call cost page faults; contents ignored).
    adjoint_mode: GLASS_ADJOINT_MODE's codes, bend_cos: the cosine between shading and
    geometric normal below which a smooth glass hit takes glassadjoint (the wrapper
    scatter passes the module's settings).

    Filter Glossy's reverse pdfs (engine/glossysplit.py, docs/compatibility.md
    "fgphoton46"): blur (m,) float64 per photon ray, the path's state: -1 (no
    non-diffuse scatter since the light or the last diffuse bounce), else the minimum of
    reverse_pdf over its non-diffuse scatters S_2 .. S_k since then (inf after S_1 alone).
    Each stored photon writes that minimum to st_blur (float32; inf for -1), each
    continued one the state after its scatter to nx_blur (a diffuse bounce: -1; a pass:
    unchanged), a copy passing behind the surface its own (per ray, not per slot, as
    clamp). Empty blur: no state, st_blur inf, nx_blur not written.
    nx_row (empty: not written): each continued photon's row i of the input.
    Cycles' Clamp Indirect on photon estimates (engine/photonclamp.py): clamp (m,)
    float64, each photon's c = |L|_1 / |power|_1 (L the radiance a Cycles path reversed
    along the photon carries, Le x the chain's throughput, of power's colour), set at
    emission; a continuation's power takes f cos / pdf x scale (scale: 1 / the
    roulette's pick probability, x eta^2 refracted) and L the f cos / pdf alone, so its
    nx_clamp is c / scale; a copy passing behind the surface keeps c (a ray's own, not
    its slot's: the copy and the continuation share a slot). A stored photon writes c x
    |power|_1 (its |L|_1) to st_rad (float32). Empty clamp: none kept, st_rad and
    nx_clamp not written (may be empty). At a photon's first scatter (no bounce counted
    yet) off a lobe with a density, light_pdf[i] > 0 (the light's pdf p_l towards -d,
    photonclamp.light_pdfs) multiplies its nx_clamp by p_b / (p_l + p_b), p_b the pdf
    with which Cycles' path arriving from the photon's next vertex samples -d
    (reverse_pdf; a PLAIN hit's diffuse share of it): Cycles reaches the light there by
    next-event estimation too (photonclamp.nee_share). Empty light_pdf: not applied.

    Filter Glossy on the gather map's light (gather_fg > 0: the render's Filter Glossy;
    0: off, the same bits): a photon that has made a diffuse bounce (F_DIFFUSE) can only
    be stored as INDIRECT or CAUSTIC_DIFFUSE, light the camera side reads past its own
    first diffuse bounce (a final gather ray's end, or the secondary caustic read at a
    camera hit D). Cycles' path meets this hit after that bounce, with min_ray_pdf at most
    the gather ray's pdf, so it blurs the hit's lobes: at FULL hits of such photons the
    microfacet alphas are raised (filterglossy.raise_alphas, after the set-up: weights,
    layer albedos and energy compensation stay those of the material's roughness) to
    blur_alpha(gather_fg, GATHER_PDF), GATHER_PDF the gather ray's pdf stand-in (2/3)/pi
    (the mean of a cosine-sampled direction's cos / pi). Photons without a diffuse bounce
    (L S+: their stores are the caustic map's, which the Filter Glossy split blurs from
    the camera side) and PLAIN / SMOOTH_GLASS hits scatter as set up.

    The split (split_slots > 0 with gather_fg > 0, not caustic_only): a photon without a
    diffuse bounce that takes a non-diffuse, non-pass lobe at a FULL hit (not a next-event
    pane's or shade's triangle, not a flat-passage glass) goes on as two copies of the
    same lobe choice, each with the whole weight of its own sample: the unblurred one
    (slot, its numbers as without the split; flag F_UNBLURRED) stores only CAUSTIC
    photons and ends at a diffuse choice, the blurred one (slot + split_slots, its own
    numbers; flag F_BLURRED, blurred at every later FULL hit too) stores only the others.
    Each map then holds an unbiased estimate of its own light: the caustic map's as
    without the split, bit for bit, the gather map's with every scatter of its paths
    blurred, as Cycles' paths past the camera's diffuse bounce are. Per-slot state of a
    blurred copy (blur, clamp) starts from its photon's, and nx_row gives the caller its
    photon's row for its own (media, coincident faces).

    Russian roulette picks one lobe with probability = its largest RGB albedo (absorbs with
    what is left); the power is divided by that probability and multiplied by the sampled
    direction's f cos / pdf (Jensen's scheme with pbrt's max rule). A refracted photon
    takes (eta_i / eta_t)^2: radiance is carried as invariant across the interface, as by
    the camera side and Cycles (docs/units.md, "Refraction").

    Flat passages (flat_mat non-empty; docs/design.md, Transparent shadows): a photon
    refracted into smooth glass from outside carries F_IN_GLASS, its path state and the
    entry triangle in its flags; refracted out at the next hit through a flat passage
    (flat_exit) it takes its path state back, as if the glass had not been there: shadow
    rays carry that light (engine/shadowtransmittance.py). Any other next event (an inner
    reflection, another surface) leaves the path specular."""
    m = geom.shape[0]
    keep_from = nx_from.shape[0] > 0
    flat_on = flat_mat.shape[0] > 0
    pane_on = pane_tri.shape[0] > 0
    may_diffuse_on = may_diffuse.shape[0] > 0
    bumped = bump.shape[0] > 0
    if hit_rows.shape[1] < m:
        raise ValueError("scatter: hit_rows has fewer than m columns")
    # The hits' rows and triangle rows, in order.
    rows = hit_rows[0]
    tri = hit_rows[1]
    nh = 0
    for i in range(m):
        g = geom[i]
        if g >= 0:
            rows[nh] = i
            tri[nh] = starts[g] + prim[i]
            nh += 1
    # The closures are set up a block of hits at a time: their rows stay in cache and the
    # buffers are allocated once per call.
    # Surface data of a block (photon_surfaces' values, computed here or copied from the
    # given arrays).
    p_b = np.empty((_BLOCK, 3))
    tilt_row, tilt = _tilt_cache()
    ng_b = np.empty((_BLOCK, 3))
    ns_b = np.empty((_BLOCK, 3))
    front_b = np.empty(_BLOCK, np.bool_)
    mat_b = np.empty(_BLOCK, np.int64)
    base_b = np.empty((_BLOCK, 3))
    alpha_b = np.empty(_BLOCK)
    off_b = np.empty(_BLOCK)
    # The split-off copies (vis_on) go after every continuation: their origins are kept.
    n_beh = 0
    beh_row = np.empty(nh if vis_on else 0, np.int64)
    beh_tri = np.empty(nh if vis_on else 0, np.int64)
    beh_o = np.empty((nh if vis_on else 0, 3), np.float32)
    mat_h = np.empty(_BLOCK, np.int64)
    base_h = np.empty((_BLOCK, 3))
    cos_h = np.empty(_BLOCK)
    front_h = np.empty(_BLOCK, np.bool_)
    alpha_h = np.empty(_BLOCK)
    prm = np.empty((_BLOCK, pr.N_PACK))
    w = np.empty((_BLOCK, pr.N_LOBES, 3))
    at = np.empty(_BLOCK, np.int64)
    # The hit's lobe weights, copied into one buffer (a view w[jc] per hit costs a
    # reference count; plain materials write only their two lobes, the only ones read).
    wj = np.zeros((pr.N_LOBES, 3))
    probs = np.empty(pr.N_LOBES)
    blur_on = blur.shape[0] > 0
    row_on = nx_row.shape[0] > 0
    clamp_on = clamp.shape[0] > 0
    nee_on = clamp_on and light_pdf.shape[0] > 0
    # The alpha to which a gather-bound photon's lobes are raised (0: none).
    gather_alpha = blur_alpha(gather_fg, GATHER_PDF) if gather_fg > 0.0 else 0.0
    split_on = split_slots > 0 and gather_alpha > 0.0 and not caustic_only
    # reverse_pdf's lobe weights, one row per FULL hit of a block (bsdf_pdf reads row jc).
    rsel = np.zeros((_BLOCK, pr.N_LOBES))
    # A SMOOTH_GLASS hit's packed glass columns (smooth_glass; the others are not read).
    gprm = np.zeros((1, pr.N_PACK))
    # lobe_adjoint's set-up of a FULL hit at the photon's outgoing cosine.
    adj = make_adjoint_scratch()
    # smooth_glass's constants per (material, side), filled at a material side's first
    # hit (most hits of a call share a few glass materials).
    sg = np.zeros((2 * params.shape[0], SG_N))  # row 2 x material + arrived outside
    sg_mu = 0.0
    sg_remap = -1.0
    sg_f0e = 0.0
    sg_inv_eta = 1.0
    # glassadjoint's arguments and candidate rows at a bent smooth glass hit.
    gd = np.empty(3)
    gnn = np.empty(3)
    gng = np.empty(3)
    gcand = np.empty((ga.MAX_W, 7))
    ns_ = 0
    nn = 0
    for b0 in range(0, nh, _BLOCK):
        nb = min(_BLOCK, nh - b0)
        if given:
            for j in range(nb):
                i = rows[b0 + j]
                for c in range(3):
                    p_b[j, c] = p[i, c]
                    ng_b[j, c] = ng[i, c]
                    ns_b[j, c] = ns[i, c]
                    base_b[j, c] = base[i, c]
                front_b[j] = front[i]
                mat_b[j] = mat[i]
                alpha_b[j] = alpha[i]
                off_b[j] = offset[i]
        else:
            _surfaces(rows, tri, b0, b0 + nb, True, u, v, d, v0, e1, e2, corner_normals,
                      material, base_color, mat_alpha, p_b, ng_b, ns_b, front_b, mat_b,
                      base_b, alpha_b, off_b, tilt_row, tilt)
        if vis_on:
            for j in range(nb):
                i = rows[b0 + j]
                if kinds[i] & ~np.int64(visibility[tri[b0 + j]]) != 0:
                    beh_row[n_beh] = i
                    beh_tri[n_beh] = tri[b0 + j]
                    for c in range(3):  # d leaves through the back of the surface
                        beh_o[n_beh, c] = p_b[j, c] - off_b[j] * ng_b[j, c]
                    n_beh += 1
        nc = 0
        for j in range(nb):
            i = rows[b0 + j]
            cls = plain[mat_b[j]]
            if cls != FULL:
                at[j] = -cls  # -1: PLAIN, -2: SMOOTH_GLASS, set up per hit below
                continue
            at[j] = nc
            mat_h[nc] = mat_b[j]
            base_h[nc, 0], base_h[nc, 1], base_h[nc, 2] = base_b[j, 0], base_b[j, 1], base_b[j, 2]
            cos_h[nc] = -(ns_b[j, 0] * d[i, 0] + ns_b[j, 1] * d[i, 1] + ns_b[j, 2] * d[i, 2])
            front_h[nc] = front_b[j]
            alpha_h[nc] = alpha_b[j]
            nc += 1
        if nc > 0:
            pr.setup(mat_h[:nc], params, base_h[:nc], cos_h[:nc], front_h[:nc],
                     alpha_h[:nc], prm[:nc], w[:nc])
            if aniso_tan.shape[0] > 0:
                # Anisotropic lobes: their tangent, interpolated over the triangle (the
                # camera side's engine/anisotropy.py, the same vector).
                for j in range(nb):
                    jc = at[j]
                    if jc < 0 or not prm[jc, pr.P_AX] > 0.0:
                        continue
                    t = tri[b0 + j]
                    i = rows[b0 + j]
                    b1, b2 = np.float64(u[i]), np.float64(v[i])
                    b0w = 1.0 - b1 - b2
                    pr.set_tangent_row(
                        prm, jc, ns_b[j, 0], ns_b[j, 1], ns_b[j, 2],
                        b0w * aniso_tan[t, 0, 0] + b1 * aniso_tan[t, 1, 0] + b2 * aniso_tan[t, 2, 0],
                        b0w * aniso_tan[t, 0, 1] + b1 * aniso_tan[t, 1, 1] + b2 * aniso_tan[t, 2, 1],
                        b0w * aniso_tan[t, 0, 2] + b1 * aniso_tan[t, 1, 2] + b2 * aniso_tan[t, 2, 2],
                        params[mat_h[jc], pr.M_AROT])
            if gather_alpha > 0.0:
                # Filter Glossy past the camera's diffuse bounce (see the docstring):
                # after the tangents, which set the anisotropic alphas.
                for j in range(nb):
                    jc = at[j]
                    if jc >= 0 and flags[rows[b0 + j]] & (F_DIFFUSE | F_BLURRED):
                        raise_alphas(prm, jc, gather_alpha)
        for j in range(nb):
            i = rows[b0 + j]
            jc = at[j]
            if jc == -PLAIN:
                # The diffuse and pass weights principled.setup gives a material without
                # other lobes, bit for bit (its other lobes' weights are 0 and not read).
                a = alpha_b[j]
                for c in range(3):
                    wj[pr.L_PASS, c] = (1.0 - a) * params[mat_b[j], pr.M_TTINT + c]
                    wj[pr.L_DIFFUSE, c] = a * base_b[j, c]
            elif jc == -SMOOTH_GLASS:
                # Its four lobes' weights (the others are 0 and not read), bit for bit.
                sgr = 2 * mat_b[j] + (1 if front_b[j] else 0)
                if sg[sgr, _SG_SET] == 0.0:
                    smooth_glass_consts(params, mat_b[j], front_b[j], sg, sgr)
                cos_o = -(ns_b[j, 0] * d[i, 0] + ns_b[j, 1] * d[i, 1] + ns_b[j, 2] * d[i, 2])
                sg_mu = min(max(cos_o, 0.0), 1.0)
                sg_remap = smooth_glass_at(params, mat_b[j], alpha_b[j], base_b, j, cos_o,
                                           gprm, wj, sg, sgr)
                sg_f0e = sg[sgr, _SG_F0E]
                sg_inv_eta = sg[sgr, _SG_INV_ETA]
            else:
                for l in range(pr.N_LOBES):
                    for c in range(3):
                        wj[l, c] = w[jc, l, c]
            t = tri[b0 + j]
            fl = flags[i]
            if bounce == 0 and first_hit_mode != 0 and caster[object_id[t]]:
                fl |= F_FIRST_CASTER
            kind = _path_kind(fl)
            kin = kinds[i]
            hit_vis = np.int64(visibility[t]) if vis_on else np.int64(ALL_RAYS)
            # --- store ---
            wd = max(wj[0, 0], max(wj[0, 1], wj[0, 2]))
            store = wd > 0.0
            if may_diffuse_on and may_diffuse[mat_b[j]]:
                # The photon's flux arrives whatever lobes this hit's closure has: a
                # surface whose diffuse lobe varies per hit (a closure pick, a metallic
                # map) stores it, or a camera hit reading the density through its own
                # pick would see the stored share of it twice ((1 - f)^2, not 1 - f).
                store = True
            if caustic_only and kind != CAUSTIC:
                store = False
            if fl & F_SPLIT:
                # A split photon's copy stores only its own map's photons (see above).
                if (kind == CAUSTIC) != ((fl & F_UNBLURRED) != 0):
                    store = False
            if first_hit_mode != 0 and kind == CAUSTIC:
                if ((fl & F_FIRST_CASTER) != 0) != (first_hit_mode == 2):
                    store = False
            if vis_on:
                # Stored for lookups here: the camera side reaches the photon's source with a
                # shadow ray (direct light) or a diffuse ray.
                if kin & (SHADOW if kind == DIRECT else DIFFUSE) == 0:
                    store = False
            if store:
                for c in range(3):
                    st_pos[ns_, c] = p_b[j, c]
                    st_power[ns_, c] = power[i, c] * bump[i] if bumped else power[i, c]
                    st_dir[ns_, c] = d[i, c]
                    st_normal[ns_, c] = ng_b[j, c]
                st_kind[ns_] = kind
                bi = bnc[i]
                for c in range(4):
                    st_bnc[ns_, c] = min((bi >> (_B_BITS * c)) & _B_MASK, BOUNCE_SATURATED)
                st_surface[ns_] = object_id[t]
                bs = blur[i] if blur_on else -1.0
                st_blur[ns_] = np.inf if bs < 0.0 else bs
                if clamp_on:
                    st_rad[ns_] = clamp[i] * (abs(st_power[ns_, 0]) + abs(st_power[ns_, 1])
                                              + abs(st_power[ns_, 2]))
                ns_ += 1
            # --- Russian roulette over the lobes ---
            xi = uniform(key, slot[i], bounce, 0)
            lobe = pr.N_LOBES  # absorbed
            s = 0.0
            cdf = 0.0
            if jc == -PLAIN:
                # Plain: only the diffuse and pass lobes (0 and 1) can weigh anything; the
                # others would add exact zeros to s and cdf and never be chosen, so the
                # sums and the choice are the full loop's, bit for bit.
                for l in (pr.L_DIFFUSE, pr.L_PASS):
                    probs[l] = max(wj[l, 0], max(wj[l, 1], wj[l, 2]))
                s += probs[pr.L_DIFFUSE]
                s += probs[pr.L_PASS]
                norm = max(s, 1.0)
                # x / 1.0 is x: the divisions are skipped where norm is 1 (the usual
                # case: weights summing to at most 1), the same bits.
                cdf += probs[pr.L_DIFFUSE] if norm == 1.0 else probs[pr.L_DIFFUSE] / norm
                if xi < cdf:
                    lobe = pr.L_DIFFUSE
                else:
                    cdf += probs[pr.L_PASS] if norm == 1.0 else probs[pr.L_PASS] / norm
                    if xi < cdf:
                        lobe = pr.L_PASS
            elif jc == -SMOOTH_GLASS:
                # Smooth glass: the diffuse (0 here), pass and glass lobes; the others'
                # exact zeros would leave s and cdf as they are (a lobe whose cdf does
                # not grow is never chosen): the full loop's sums and choice, bit for bit.
                for l in (pr.L_DIFFUSE, pr.L_PASS, pr.L_GLASS_R, pr.L_GLASS_T):
                    probs[l] = max(wj[l, 0], max(wj[l, 1], wj[l, 2]))
                    s += probs[l]
                norm = max(s, 1.0)
                for l in (pr.L_DIFFUSE, pr.L_PASS, pr.L_GLASS_R, pr.L_GLASS_T):
                    cdf += probs[l] if norm == 1.0 else probs[l] / norm  # (as PLAIN's)
                    if xi < cdf:
                        lobe = l
                        break
            else:
                for l in range(pr.N_LOBES):
                    probs[l] = max(wj[l, 0], max(wj[l, 1], wj[l, 2]))
                    s += probs[l]
                norm = max(s, 1.0)
                for l in range(pr.N_LOBES):
                    cdf += probs[l] if norm == 1.0 else probs[l] / norm  # (as PLAIN's)
                    if xi < cdf:
                        lobe = l
                        break
            if lobe == pr.N_LOBES or ((caustic_only or fl & F_UNBLURRED)
                                      and lobe == pr.L_DIFFUSE):
                continue
            # --- Filter Glossy's split of a pre-diffuse photon (photonblur50) ---
            # At its first non-diffuse scatter before any diffuse bounce, a photon whose
            # stores serve both maps goes on as two copies of its full power: copy 0
            # unblurred (F_UNBLURRED: only its CAUSTIC stores, the caustic map's, which
            # the Filter Glossy split blurs from the camera side), copy 1 off the lobes
            # raised to gather_alpha (F_BLURRED: only its other stores, read past the
            # camera's diffuse bounce, where Cycles blurs this hit) in slot
            # slot + split_slots (its own random numbers; its path state per ray, from
            # its photon's row).
            n_cp = 1
            if (split_on and jc >= 0 and lobe != pr.L_DIFFUSE and lobe != pr.L_PASS
                    and (fl & (F_DIFFUSE | F_SPLIT)) == 0
                    and not (pane_on and pane_tri[t] != -1)
                    and not (flat_on and flat_mat[material[t]])):
                n_cp = 2
            lobe0 = lobe
            old_blur = blur[i] if blur_on else -1.0
            old_clamp = clamp[i] if clamp_on else 0.0
            for copy in range(n_cp):
                lobe = lobe0
                sl = slot[i]
                if copy == 1:
                    sl = slot[i] + split_slots
                    raise_alphas(prm, jc, gather_alpha)
                glass = lobe == pr.L_GLASS_R or lobe == pr.L_GLASS_T
                p_sel = probs[pr.L_GLASS_R] + probs[pr.L_GLASS_T] if glass else probs[lobe]
                p_sel = max(p_sel if norm == 1.0 else p_sel / norm, 1e-300)
                dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
                gx, gy, gz = ng_b[j, 0], ng_b[j, 1], ng_b[j, 2]
                n0, n1, n2 = ns_b[j, 0], ns_b[j, 1], ns_b[j, 2]
                transmitted = False
                ix = iy = iz = lx = ly = lz = 0.0  # (set by the non-diffuse lobes' samples)
                if lobe == pr.L_DIFFUSE:
                    u1 = uniform(key, sl, bounce, 1)
                    u2 = uniform(key, sl, bounce, 2)
                    r = math.sqrt(u1)
                    cp, sp = sincos_turn(u2)  # cos, sin of phi = 2 pi u2 (engine/trig.py)
                    ox, oy, oz = pr.frame_world(n0, n1, n2, r * cp, r * sp,
                                                math.sqrt(max(0.0, 1.0 - u1)))
                    ok = ox * gx + oy * gy + oz * gz > 0.0
                    k0, k1, k2 = wj[0, 0], wj[0, 1], wj[0, 2]
                    if jc >= 0:
                        # The layers' albedos above the base at the side the photon leaves
                        # to (lobe_adjoint: the camera's view there), not where it arrived.
                        a0, a1, a2 = lobe_adjoint(params, mat_b[j], base_b, j, front_b[j],
                                                  alpha_b[j], prm, w, jc, lobe,
                                                  math.sqrt(max(0.0, 1.0 - u1)), adj)
                        k0, k1, k2 = k0 * a0, k1 * a1, k2 * a2
                    if bumped:
                        k0, k1, k2 = k0 * bump[i], k1 * bump[i], k2 * bump[i]
                elif lobe == pr.L_PASS:
                    ox, oy, oz = dx, dy, dz
                    transmitted = True
                    # (1 - alpha) x the Transparent BSDF's colour (principled.M_TTINT).
                    k0 = (1.0 - alpha_b[j]) * params[mat_b[j], pr.M_TTINT]
                    k1 = (1.0 - alpha_b[j]) * params[mat_b[j], pr.M_TTINT + 1]
                    k2 = (1.0 - alpha_b[j]) * params[mat_b[j], pr.M_TTINT + 2]
                    ok = max(k0, max(k1, k2)) > 0.0
                else:
                    lx, ly, lz = pr.frame_local(n0, n1, n2, -dx, -dy, -dz)
                    bent = turned = False
                    un0 = un1 = un2 = 0.0
                    if (jc == -SMOOTH_GLASS and corner_normals.shape[0] > 0
                            and adjoint_mode != GLASS_ADJOINT_NEVER):
                        t = tri[b0 + j]
                        un0, un1, un2 = _glass_normal(corner_normals, t, np.float64(u[i]),
                                                      np.float64(v[i]), front_b[j], gx, gy, gz,
                                                      n0, n1, n2)
                        # A bent shading normal: the adjoint of Cycles' glass there
                        # (engine/glassadjoint.py), not a sample about n; its root search
                        # only where Cycles could turn n for a direction sent to this arrival.
                        bent = abs(un0 * gx + un1 * gy + un2 * gz) < bend_cos
                        turned = bent and (adjoint_mode == GLASS_ADJOINT_EVERY_BENT
                                           or ga.turn_possible(dx, dy, dz, un0, un1, un2, gx,
                                                               gy, gz, gprm[0, pr.P_GLASS_ETA]))
                    if bent:
                        gd[0], gd[1], gd[2] = dx, dy, dz
                        gnn[0], gnn[1], gnn[2] = un0, un1, un2
                        gng[0], gng[1], gng[2] = gx, gy, gz
                        nw = ga.candidates(gprm, gd, gnn, gng, gcand, turned)
                        okp, ox, oy, oz, k0, k1, k2, transmitted = ga.pick(
                            gcand, nw, uniform(key, sl, bounce, 5))
                        ix, iy, iz = pr.frame_local(n0, n1, n2, ox, oy, oz)
                        if not okp:
                            k0 = k1 = k2 = 0.0
                    elif jc == -SMOOTH_GLASS:
                        # The glass lobe's own sampler; smooth, it reads only its third number
                        # (reflect or refract): the first two are not drawn.
                        ix, iy, iz, k0, k1, k2, transmitted = _smooth_glass_sample_at(
                            gprm, lx, ly, lz, uniform(key, sl, bounce, 5), sg_mu, sg_remap,
                            sg_f0e, sg_inv_eta)
                    else:
                        ix, iy, iz, k0, k1, k2, transmitted = pr.sample_lobe(
                            prm, jc, lobe, lx, ly, lz, uniform(key, sl, bounce, 3),
                            uniform(key, sl, bounce, 4), uniform(key, sl, bounce, 5))
                        if glass:
                            # Cycles' energy compensation at the side the photon leaves to
                            # (glass_adjoint: the camera's view there), not where it arrived.
                            g0, g1, g2 = glass_adjoint(params, mat_b[j], base_b, j,
                                                       prm[jc, pr.P_GLASS_ETA], lz, abs(iz),
                                                       transmitted)
                            k0, k1, k2 = k0 * g0, k1 * g1, k2 * g2
                        elif lobe != pr.L_SHEEN and lobe != pr.L_TRANSL:
                            # The same for the metal, specular and coat lobes (lobe_adjoint).
                            a0, a1, a2 = lobe_adjoint(params, mat_b[j], base_b, j, front_b[j],
                                                      alpha_b[j], prm, w, jc, lobe, abs(iz), adj)
                            k0, k1, k2 = k0 * a0, k1 * a1, k2 * a2
                    ox, oy, oz = pr.frame_world(n0, n1, n2, ix, iy, iz)
                    ln = math.sqrt(ox * ox + oy * oy + oz * oz)
                    if ln > 0.0:
                        ox, oy, oz = ox / ln, oy / ln, oz / ln
                    side = ox * gx + oy * gy + oz * gz
                    ok = ((side < 0.0) if transmitted else (side > 0.0)) and math.isfinite(ln)
                    if ok and not transmitted and not glass and lobe != pr.L_TRANSL:
                        # Shading normals are not symmetric: the camera side weighs light by
                        # its cosine to the shading normal, while photons arrive and leave a
                        # surface by its true (geometric) area, so a photon's reflection
                        # takes f |wi.Ns| |wo.Ng| / (|wi.Ng| pdf) (Veach 1997, sec. 5.3, the
                        # adjoint BSDF), not f |wo.Ns| / pdf. Without it the light off a
                        # normal-mapped metal onto the floor beside it read 1.14x Cycles,
                        # whose paths meet the metal from the floor (docs/accuracy.md, glow36).
                        cs_in = -(dx * n0 + dy * n1 + dz * n2)
                        cg_in = -(dx * gx + dy * gy + dz * gz)
                        cs_out = ox * n0 + oy * n1 + oz * n2
                        if cg_in > 0.0 and cs_out > 0.0:
                            sh = (cs_in * side) / (cg_in * cs_out)
                            k0, k1, k2 = k0 * sh, k1 * sh, k2 * sh
                        else:
                            ok = False
                    ok = ok and max(k0, max(k1, k2)) > 0.0
                    if glass:
                        lobe = pr.L_GLASS_T if transmitted else pr.L_GLASS_R
                if not ok:
                    continue
                scale = 1.0 / p_sel
                if glass and transmitted:
                    eta = 1.0 / mat_ior[mat_b[j]] if front_b[j] else mat_ior[mat_b[j]]
                    scale *= eta * eta
                q0 = power[i, 0] * k0 * scale
                q1 = power[i, 1] * k1 * scale
                q2 = power[i, 2] * k2 * scale
                if not (math.isfinite(q0 + q1 + q2) and max(q0, max(q1, q2)) > 0.0):
                    continue
                # --- bounce counts (Cycles' path_state_next; a transparent pass is none) ---
                bn = bnc[i]
                if lobe != pr.L_PASS:
                    first_scatter = (bn & _B_MASK) == 0
                    bn = _count_bounce(bn, B_TOTAL)
                    if not first_scatter:
                        # Cycles' path_state_next by the sampled label: any transmission (a
                        # Translucent BSDF's too, LABEL_TRANSMIT | LABEL_DIFFUSE) is a
                        # transmission bounce; a diffuse reflection (Diffuse, Sheen) a
                        # diffuse one; the other reflections glossy.
                        if transmitted:
                            bn = _count_bounce(bn, B_TRANSMISSION)
                        elif lobe == pr.L_DIFFUSE or lobe == pr.L_SHEEN:
                            bn = _count_bounce(bn, B_DIFFUSE)
                        else:
                            bn = _count_bounce(bn, B_GLOSSY)
                    if not _counts_usable(bn, limits):
                        continue
                # --- ray kinds (visibility) ---
                if vis_on:
                    if lobe == pr.L_DIFFUSE:
                        use = SHADOW if kind == DIRECT else DIFFUSE
                    elif lobe == pr.L_TRANSL and kind == DIRECT:
                        # The light's own segment is Cycles' light sample at the translucent
                        # surface, which a diffuse closure takes: the light's diffuse
                        # visibility (_surface_shader_exclude: CLOSURE_IS_BSDF_DIFFUSE spans
                        # DIFFUSE..TRANSLUCENT); later segments are transmission rays.
                        use = SHADOW
                    else:
                        use = _LOBE_CLASS[lobe]
                    if lobe != pr.L_PASS and kin & use == 0:
                        continue
                    new_kinds = (kin & hit_vis) if lobe == pr.L_PASS else (hit_vis & SEGMENT_KINDS)
                    if new_kinds == 0:
                        continue
                else:
                    new_kinds = kin
                # --- path flags ---
                nf = fl & ~np.int64(F_IN_GLASS) & ((np.int64(1) << _PRE_SHIFT) - 1)
                passage = fl & F_IN_GLASS
                pane = fl & F_PANE
                pane_plane = fl & F_PANE_PLANE
                nf &= ~np.int64(F_PANE)
                if lobe == pr.L_DIFFUSE:
                    # The first diffuse bounce after a caustic path starts L S+ D; any further
                    # diffuse bounce makes it ordinary indirect light.
                    if fl & F_DIFFUSE:
                        nf &= ~F_CAUSTIC_DIFF
                    elif fl & F_SPECULAR:
                        nf |= F_CAUSTIC_DIFF
                    nf |= F_DIFFUSE
                elif lobe == pr.L_PASS:
                    if pane and pane_plane:
                        # Past a pane, a transparent pass: the pane's shadow rays cross it
                        # (engine/panelight.py), so this light is still direct.
                        nf |= F_PANE | F_PANE_PLANE
                    elif pane:
                        # Past a shade, a transparent pass: the shade's shadow rays do not
                        # cross it (engine/shadelight.py), so this light is the caustic map's.
                        nf |= F_SPECULAR
                else:
                    # Every other lobe is continued by the camera side too (which reads no photon
                    # map at a glossy lobe), so light by way of it is caustic light however rough
                    # the lobe. A transparent pass leaves the kind as it was: shadow rays cross
                    # it, so light through it is direct light (docs/design.md, Transparent
                    # shadows).
                    if (flat_on and passage and glass and transmitted and flat_exit(
                            v0, e1, e2, material, object_id, flat_mat, flat_limit,
                            fl >> _TRI_SHIFT, t, dx, dy, dz, p_b[j, 0], p_b[j, 1], p_b[j, 2])):
                        # Out of a flat passage: the path as it was before the glass.
                        nf = ((fl >> _PRE_SHIFT) & F_PATH) | (fl & F_SPLIT)
                        if passage_fg > 0.0:
                            # Cycles' blurred slab (blurredpassage): the factor at the blur
                            # of the Lambert pdf along the photon's way.
                            en = fl >> _TRI_SHIFT
                            wx, wy, wz = winding_normal(e1, e2, en)
                            ln = math.sqrt(wx * wx + wy * wy + wz * wz)
                            lo = math.sqrt(ox * ox + oy * oy + oz * oz)
                            cg = min(abs(ox * wx + oy * wy + oz * wz) / max(ln * lo, 1e-300), 1.0)
                            fb = passage_factor(passage_tab, passage_ior, cg,
                                                blur_alpha(passage_fg, cg / math.pi),
                                                mat_ior[material[en]])
                            q0 *= fb
                            q1 *= fb
                            q2 *= fb
                    elif (pane_on and not passage and not pane and (fl & _F_KIND) == 0
                          and ((glass and transmitted
                                and (pane_tri[t] >= 0 or pane_tri[t] == SHADE_GLASS))
                               or (lobe == pr.L_TRANSL and pane_tri[t] == SHADE_TRANSLUCENT))):
                        # A sun's light refracted straight through a next-event pane, or a
                        # lamp's through its shade (translucent, or refracted by rough glass):
                        # still direct (the pane's / the shade's shadow rays carry it;
                        # engine/panelight.py, engine/shadelight.py).
                        nf |= F_PANE
                        if pane_tri[t] >= 0 and pane_passes:
                            nf |= F_PANE_PLANE
                    else:
                        pre = nf
                        nf |= F_SPECULAR
                        if (flat_on and glass and transmitted and not pane
                                and flat_entry(e1, e2, material, flat_mat, t, dx, dy, dz)):
                            nf |= F_IN_GLASS | (pre << _PRE_SHIFT) | (t << _TRI_SHIFT)
                if n_cp == 2:
                    nf |= F_UNBLURRED if copy == 0 else F_BLURRED
                # --- Filter Glossy's reverse pdf state (glossysplit, "fgphoton46") ---
                if blur_on:
                    nb_ = old_blur
                    if lobe == pr.L_DIFFUSE:
                        nb_ = -1.0
                    elif lobe != pr.L_PASS:
                        if old_blur < 0.0:
                            nb_ = np.inf  # S_1: its pdf blurs nothing after it
                        elif jc >= 0 and pr.is_rough(prm, jc, lobe):
                            rp = reverse_pdf(prm, rsel, jc, wj, probs, transmitted,
                                             ix, iy, iz, lx, ly, lz)
                            if rp < old_blur:
                                nb_ = rp
                    nx_blur[nn] = nb_
                if row_on:
                    nx_row[nn] = i
                if clamp_on:
                    nx_clamp[nn] = old_clamp / scale  # (L takes f cos / pdf alone)
                    if (nee_on and (bnc[i] & _B_MASK) == 0 and lobe != pr.L_PASS
                            and light_pdf[i] > 0.0):
                        # The light's first scatter: Cycles' MIS pair there
                        # (photonclamp.nee_share); a delta lobe (pb inf) keeps c, and
                        # so does pb 0 (a shading normal's asymmetry: not Cycles' pair).
                        pb = np.inf
                        if jc == -PLAIN:
                            w_dif = (wj[pr.L_DIFFUSE, 0] + wj[pr.L_DIFFUSE, 1]
                                     + wj[pr.L_DIFFUSE, 2]) / 3.0
                            cos_l = -(dx * n0 + dy * n1 + dz * n2)
                            if w_dif > 0.0 and cos_l > 0.0:
                                pb = w_dif / (w_dif + probs[pr.L_PASS]) * cos_l / math.pi
                        elif jc >= 0 and lobe == pr.L_DIFFUSE:
                            lx, ly, lz = pr.frame_local(n0, n1, n2, -dx, -dy, -dz)
                            ix, iy, iz = pr.frame_local(n0, n1, n2, ox, oy, oz)
                            pb = reverse_pdf(prm, rsel, jc, wj, probs, False,
                                             ix, iy, iz, lx, ly, lz)
                        elif jc >= 0 and pr.is_rough(prm, jc, lobe):
                            pb = reverse_pdf(prm, rsel, jc, wj, probs, transmitted,
                                             ix, iy, iz, lx, ly, lz)
                        if 0.0 < pb < np.inf:
                            nx_clamp[nn] *= pb / (light_pdf[i] + pb)
                # --- the continued ray, its origin cleared of this triangle (pbrt-v4) ---
                off = off_b[j] if ox * gx + oy * gy + oz * gz >= 0.0 else -off_b[j]
                nx_o[nn, 0] = p_b[j, 0] + off * gx
                nx_o[nn, 1] = p_b[j, 1] + off * gy
                nx_o[nn, 2] = p_b[j, 2] + off * gz
                if keep_from:
                    nx_from[nn] = t
                    nx_off[nn, 0], nx_off[nn, 1], nx_off[nn, 2] = off * gx, off * gy, off * gz
                nx_d32[nn, 0], nx_d32[nn, 1], nx_d32[nn, 2] = ox, oy, oz
                nx_d[nn, 0], nx_d[nn, 1], nx_d[nn, 2] = ox, oy, oz
                nx_power[nn, 0], nx_power[nn, 1], nx_power[nn, 2] = q0, q1, q2
                nx_flags[nn] = nf
                nx_kinds[nn] = new_kinds
                nx_slot[nn] = sl
                nx_bnc[nn] = bn
                nn += 1
    if vis_on:
        # The kinds that do not see this surface pass on behind it in a split-off copy
        # (same slot, so the same random numbers; its own clamp ratio and Filter Glossy
        # state: its path unscattered here); the photon stopped here for the others.
        for k in range(n_beh):
            i = beh_row[k]
            t = beh_tri[k]
            fl = flags[i]
            if bounce == 0 and first_hit_mode != 0 and caster[object_id[t]]:
                fl |= F_FIRST_CASTER
            for c in range(3):
                nx_o[nn, c] = beh_o[k, c]
                nx_d32[nn, c] = d[i, c]
                nx_d[nn, c] = d[i, c]
                nx_power[nn, c] = power[i, c]
            nx_flags[nn] = fl
            nx_kinds[nn] = kinds[i] & ~np.int64(visibility[t])
            nx_slot[nn] = slot[i]
            nx_bnc[nn] = bnc[i]
            if clamp_on:
                nx_clamp[nn] = clamp[i]  # (its path unscattered here)
            if blur_on:
                nx_blur[nn] = blur[i]
            if row_on:
                nx_row[nn] = i
            if keep_from:
                nx_from[nn] = -1
                nx_off[nn, 0], nx_off[nn, 1], nx_off[nn, 2] = 0.0, 0.0, 0.0
            nn += 1
    return ns_, nn


@kernel
def reverse_pdf(prm, rsel, jc, wj, probs, transmitted, ix, iy, iz, lx, ly, lz):
    """Cycles' one-sample MIS pdf (1/sr; filterglossy.mis_pdf's form) with which the
    camera side, arriving at FULL hit jc from the photon's next vertex (wo = the photon's
    outgoing direction, local (ix, iy, iz) in the shading frame), samples the direction
    back towards the photon's previous vertex (wi = -d, local (lx, ly, lz)):
    (sum_l p_l pdf_l(wo, wi) + w_d max(cos_i, 0) / pi) / (sum_l p_l + w_d), p_l the
    non-diffuse lobes' weights (probs: their albedo's max channel, as choose_lobes), w_d
    the diffuse weight's mean channel (wj[L_DIFFUSE]). Reflections: principled.bsdf_pdf;
    transmissions: principled.reverse_transmission_pdf (the lobes are set up at the
    photon's arriving side; the camera side samples from the far one, whose pdf differs by
    the rough glass's eta^2 and the two sides' cosines: Cycles' bsdf_microfacet.h). rsel
    (>= jc + 1, N_LOBES) scratch, row jc overwritten. NaN: inf (never a minimum)."""
    psum = 0.0
    rsel[jc, pr.L_DIFFUSE] = 0.0
    for l in range(1, pr.N_LOBES):
        rsel[jc, l] = probs[l]
        psum += probs[l]
    wd = (wj[pr.L_DIFFUSE, 0] + wj[pr.L_DIFFUSE, 1] + wj[pr.L_DIFFUSE, 2]) / 3.0
    den = psum + max(wd, 0.0)
    if not den > 0.0:
        return np.inf
    if transmitted:
        lp = pr.reverse_transmission_pdf(prm, rsel, jc, lx, ly, lz, ix, iy, iz)
    else:
        lp = (pr.bsdf_pdf(prm, rsel, jc, ix, iy, iz, lx, ly, lz)
              + max(wd, 0.0) * max(lz, 0.0) / math.pi)
    out = lp / den
    return out if out == out else np.inf


@kernel
def _count_bounce(packed, which):
    """packed bounce counts (int64, B_TOTAL ...) with count `which` one higher (held at
    the 16-bit field's top: never reached, photons stop far sooner)."""
    shift = _B_BITS * which
    c = (packed >> shift) & _B_MASK
    if c == _B_MASK:
        return packed
    return packed + (np.int64(1) << shift)


@kernel
def _counts_usable(packed, limits):
    """Whether a photon with these packed counts can still be stored and used: read at a
    camera hit with no camera-side bounce (the caustic map's case), its path scatters
    total times, and once it has scattered its last hit is a diffuse bounce more
    (bounce_usable)."""
    total = packed & _B_MASK
    diff = ((packed >> _B_BITS) & _B_MASK) + (1 if total > 0 else 0)
    glossy = (packed >> (2 * _B_BITS)) & _B_MASK
    trans = (packed >> (3 * _B_BITS)) & _B_MASK
    return (total <= limits[0] and diff <= limits[1] and glossy <= limits[2]
            and trans <= limits[3])


def bounce_usable(counts: np.ndarray, limits, camera=(0, 0, 0, 0)) -> np.ndarray:
    """(N,) bool: the stored photons whose light, read at a camera-side lookup vertex
    reached with `camera` bounces (total, diffuse, glossy, transmission; e.g. a final
    gather ray's end: (1, 1, 0, 0)), makes a path within the limits (4,) (max_bounces,
    diffuse, glossy, transmission). counts (N,4) uint8 (Photons.bounces). The path's
    bounces: the camera side's, the photon's total, and the lookup vertex's diffuse
    bounce once the photon has scattered (see B_TOTAL). A count at BOUNCE_SATURATED
    passes a limit at or above it (limits that high are no limit in practice)."""
    c = np.asarray(counts, np.int64)
    lim = np.asarray(limits, np.int64)
    cam = np.asarray(camera, np.int64)
    if len(c) == 0:
        return np.zeros(0, bool)
    total = c[:, 0] + cam[0]
    diff = c[:, 1] + (c[:, 0] > 0) + cam[1]
    ok = (total <= lim[0]) & (diff <= lim[1]) & (c[:, 2] + cam[2] <= lim[2]) \
        & (c[:, 3] + cam[3] <= lim[3])
    return ok


# |n.g| below this: a smooth glass hit's shading normal is bent (glassadjoint), ~0.1 deg.
_FLAT_NORMAL_COS = 1.0 - 1.5e-6

# lobe_classes' codes: how scatter sets up a material's lobes.
FULL, PLAIN, SMOOTH_GLASS = 0, 1, 2


def lobe_classes(params: np.ndarray) -> np.ndarray:
    """(M,) int8 per material row of params (MaterialTable.closure_params): PLAIN
    (plain_materials: diffuse and pass lobes only), SMOOTH_GLASS (transmission exactly 1,
    delta roughness (alpha = rough^2 below ggx.ALPHA_MIN, as glass_microfacet tests it),
    no metal, coat or sheen; Principled or Glass BSDF node: the pass and glass lobes
    alone, set up by smooth_glass and sampled with one number), else FULL
    (principled.setup). Photon pass only (scatter's `plain`)."""
    from .closures import ggx
    params = np.asarray(params)
    out = plain_materials(params).astype(np.int8)
    rough = params[:, pr.M_ROUGH]
    node = params[:, pr.M_NODE]
    glass = ((params[:, pr.M_TRANS] == 1.0) & (rough * rough < ggx.ALPHA_MIN)
             & (params[:, pr.M_METALLIC] <= 0.0) & (params[:, pr.M_COAT_W] <= 0.0)
             & (params[:, pr.M_SHEEN_W] <= 0.0) & (params[:, pr.M_TL] <= 0.0)
             & ((node == pr.NODE_GLASS) | (node == pr.NODE_PRINCIPLED)))
    out[glass] = SMOOTH_GLASS
    return np.ascontiguousarray(out)


def plain_materials(params: np.ndarray) -> np.ndarray:
    """(M,) bool: materials whose closures are the diffuse and pass lobes alone (no sheen,
    coat, metal, transmission or specular layer: principled.setup skips each of them
    unless its weight is > 0), for scatter's set-up-free path."""
    layers = (pr.M_SHEEN_W, pr.M_COAT_W, pr.M_METALLIC, pr.M_TRANS, pr.M_SPEC, pr.M_TL)
    return np.ascontiguousarray(~np.any(params[:, layers] > 0.0, axis=1)
                                & (params[:, pr.M_ADD] == 0.0))  # closure weight 1


def surface_arrays(m: int):
    """Empty per-hit arrays (p, ng, ns, front, mat, base, alpha, offset) for m rays."""
    return (np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3)), np.zeros(m, np.bool_),
            np.zeros(m, np.int64), np.zeros((m, 3)), np.ones(m), np.zeros(m))


def store_arrays(m: int, radiance: bool = False):
    """Buffers for up to m stored photons (position, power, direction, normal, kind,
    bounce counts (m,4) uint8, surface (m,) int32, blur pdf (m,) float32, radiance (m,)
    float32 with `radiance`, else (0,): Photons' fields in order)."""
    return (np.empty((m, 3), np.float32), np.empty((m, 3), np.float32),
            np.empty((m, 3), np.float32), np.empty((m, 3), np.float32), np.empty(m, np.uint8),
            np.empty((m, 4), np.uint8), np.empty(m, np.int32), np.empty(m, np.float32),
            np.empty(m if radiance else 0, np.float32))


def store_arrays_radiance(m: int):
    """store_arrays(m, True): with the stored photons' |L|_1 (Clamp Indirect)."""
    return store_arrays(m, True)


def next_arrays(m: int, origins: bool = False):
    """Buffers for up to m continued photons (origin32, direction32, direction, power,
    flags, kinds, slot, packed bounce counts, the triangle left, the origin's offset);
    the last two have 0 rows unless `origins` (a scene with glass touching something,
    engine/coincident.py: 32 B a row the others do not pay)."""
    k = m if origins else 0
    return (np.empty((m, 3), np.float32), np.empty((m, 3), np.float32), np.empty((m, 3)),
            np.empty((m, 3)), np.empty(m, np.int64), np.empty(m, np.int64),
            np.empty(m, np.int64), np.empty(m, np.int64), np.empty(k, np.int64),
            np.empty((k, 3)))


def next_arrays_from(m: int):
    """next_arrays(m, True): with the triangle each photon left and its offset."""
    return next_arrays(m, True)


_NO_LIMITS = np.full(4, 1 << 20, np.int64)  # limits no count reaches


@register_warm_up
def _warm_up():
    """Compile (or load) the kernels on one photon hitting one triangle."""
    v0 = np.zeros((1, 3))
    e1 = np.array([[1.0, 0.0, 0.0]])
    e2 = np.array([[0.0, 1.0, 0.0]])
    d = np.array([[0.0, 0.0, -1.0]])
    prim = np.zeros(1, np.int64)
    uv = np.full(1, 0.25)
    surf = surface_arrays(1)
    params = np.zeros((1, pr.N_MAT))
    params[0, pr.M_ALPHA] = 1.0
    for normals in (np.zeros((0, 3, 3), np.float32), np.zeros((1, 3, 3), np.float32)):
        photon_surfaces(prim, uv, uv, d, v0, e1, e2, normals, np.zeros(1, np.int32),
                        np.full((1, 3), 0.5), np.ones(1), *surf)
    # Embree's answer (Accel.intersect_hits): int32 ids, float32 barycentrics.
    geom32, prim32, uv32 = np.zeros(1, np.int32), np.zeros(1, np.int32), np.full(1, 0.25, np.float32)
    for given in (False, True):
        scatter(np.uint64(1), 0, d, np.ones((1, 3)), np.zeros(1, np.int64),
                np.full(1, SEGMENT_KINDS, np.int64), np.zeros(1, np.int64),
                np.zeros(1, np.int64), geom32, prim32,
                np.zeros(1, np.int64), uv32, uv32, v0,
                e1, e2, normals, np.zeros(1, np.int32), np.full((1, 3), 0.5), np.ones(1),
                given, *surf, np.ones(1), params, plain_materials(params), np.full(1, 1.5),
                np.full(1, ALL_RAYS, np.uint8), np.zeros(1, np.int32), np.zeros(1, np.bool_),
                0, False, False, _NO_LIMITS, *store_arrays(1), *next_arrays(2),
                np.empty((2, 1), np.int64))
        scatter(np.uint64(1), 0, d, np.ones((1, 3)), np.zeros(1, np.int64),
                np.full(1, SEGMENT_KINDS, np.int64), np.zeros(1, np.int64),
                np.zeros(1, np.int64), geom32, prim32,
                np.zeros(1, np.int64), uv32, uv32, v0,
                e1, e2, normals, np.zeros(1, np.int32), np.full((1, 3), 0.5), np.ones(1),
                given, *surf, np.ones(1), params, plain_materials(params), np.full(1, 1.5),
                np.full(1, ALL_RAYS, np.uint8), np.zeros(1, np.int32), np.zeros(1, np.bool_),
                0, False, False, _NO_LIMITS, *store_arrays(1), *next_arrays(2),
                np.empty((2, 1), np.int64), flat_mat=np.ones(1, np.bool_), flat_limit=np.full(1, 0.1))
    uniforms(np.uint64(1), np.zeros(1, np.int64), 0, 0, np.empty(1))
