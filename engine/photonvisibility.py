"""Photon visibility: a density estimate counts only the photons its point can see.

A photon map's estimate at a point x sums the photons within a disc around x on x's
surface. When another surface pierces x's surface (a lamp shade whose rim goes into the
wall, a partition standing on a floor, any intersecting geometry), the disc reaches across
it and takes photons from the far side: light that cannot reach x. Issue 14's lamp shade
(a Point light inside a closed metal cone whose rim pierces the back wall) lit a bright
blob on the wall outside the shade: caustic photons (light -> shade interior -> wall)
stored on the patch of wall *inside* the shade, 0.19 m (the caustic radius) away at most,
gathered by wall points just outside it (docs/performance.md, "leak").

The fix is the one the gather map already applies to its gather points
(photonmap.GatherMap.lookup): a visibility ray from x to each photon of its estimate, both
ends lifted off their surfaces by bounds on their rounding error (photonmap._ray_ends:
engine/rayoffset.py's bounds, plus the lift that keeps a chord of a tessellated curved
surface above it). A hidden photon's power counts as 0 (PhotonMap.irradiance's masks:
the same neighbours and disc), so a point whose whole disc lies behind an occluder reads
exactly 0 and a point next to one is biased dark exactly as at a corner, never bright.
Rows with no hidden photon keep the unmasked estimate bit for bit.

On a curved surface the ray is bent (_bent_path): two segments that meet above the
chord's midpoint, its ends lifted by rounding bounds only, so that neither end is lifted
across a nearby surface (a ball's underside above its floor) and the chord does not hide
the surface's own photons.

The photons traced are the ones the estimate read, handed back by its own search
(PhotonMap.knn_irradiance's read lists: the accepted photons inside its disc rk, the only
ones whose power its sum weighs, whatever the row's kind: k-NN, widened, floored by a
footprint or MIN_RADIUS_FRACTION, or a fixed-radius estimator), so no row is searched
twice (docs/performance.md "visreuse"; a second k-NN search a row was most of the cost).
"""
from __future__ import annotations

import math
import threading

import numpy as np

from . import chaincounts, photonclamp
from .jit import kernel, register_warm_up
# The pre-test (rows with no other surface near are not traced) lives in plain Python
# (engine/onesurface.py), so that editing it does not recompile these kernels.
from .onesurface import one_surface_cells
from .photonkernels import B_TOTAL
from .photonlayout import read_power, read_vector, snap_chord2
from .photonmap import _query_lift, _ray_ends
from .rayoffset import G32_PLANE, ulp32_scalar
from .samesurface import query_surfaces

# Rows per block of visibility rays (bounds the ray arrays: BLOCK_ROWS x cap rays).
BLOCK_ROWS = 1024


# Rows per estimate call of the visibility path: bounds the read lists (READ_ROWS x
# READ_WIDTH x k photon ids, 16 MB at k = 64; twice photonmap.BLOCK_ROWS, so that a map
# shared by worker threads still splits a call among them) and the rays of a block
# (BLOCK_ROWS rows).
READ_ROWS = 16384
# The same for a map no other thread shares (workers 1: a camera chunk's serial context,
# Context.serial): its search runs on the calling thread whatever the block, so the block
# only sets the read lists each worker keeps (4 MB at k = 64 instead of 16; slices52,
# docs/performance.md). Each row's estimate, search and visibility are its own: the same
# bits in any block (tests/test_photon_visibility_reuse.py).
SERIAL_READ_ROWS = 4096
# A row's read list holds up to this many times k photons; a row that reads more (a
# footprint floor or MIN_RADIUS_FRACTION wider than its k-th photon) is read again with
# a list as wide as it needs (a second search for those rows alone).
READ_WIDTH = 2
# _bent_path's margin beyond the lift a convex surface needs, in chord |n - m| / 4
# (photonmap._ray_ends' bend): room for rounding and for meshes only nearly convex.
BEND_MARGIN = 0.25


@kernel
def _read_rays(pos, normal, p, n, lift, rows, slots, count, photons, o32, d32, t32,
               ray_row, ray_photon):
    """Visibility rays from the rows `rows` of p (M,3) / n (M,3) (unit normals facing the
    viewer; lift (M,) or empty: their own offsets) to the photons their estimate read:
    row rows[r]'s are photons[slots[r], :count[slots[r]]] (PhotonMap.knn_irradiance's
    read lists), in Embree's float32 layout o32, d32 (R,3), t32 (R,); ray_row[j] the row,
    ray_photon[j] the photon (map order). A photon with the row's normal gets one ray
    (photonmap._ray_ends), one with another normal (a curved surface) the two segments
    of _bent_path, adjacent, both with its row and photon: it is hidden when either is
    blocked. R <= 2 x the rows' photons. Returns the number of rays."""
    m = 0
    snap = snap_chord2(normal)
    for r in range(rows.shape[0]):
        i = rows[r]
        s = slots[r]
        qx, qy, qz = p[i, 0], p[i, 1], p[i, 2]
        nx, ny, nz = n[i, 0], n[i, 1], n[i, 2]
        la = _query_lift(lift, i, qx, qy, qz)
        for jj in range(count[s]):
            j = photons[s, jj]
            bx, by, bz = np.float64(pos[j, 0]), np.float64(pos[j, 1]), np.float64(pos[j, 2])
            m0, m1, m2 = read_vector(normal, j)  # (photonlayout: float32 or octahedral)
            mx, my, mz = np.float64(m0), np.float64(m1), np.float64(m2)
            if (mx - nx) ** 2 + (my - ny) ** 2 + (mz - nz) ** 2 <= snap:
                # The query's own orientation within the layout's round trip (compact
                # photons: photonlayout.snap_chord2; float32 ones: exactly equal).
                mx, my, mz = nx, ny, nz
            if nx == mx and ny == my and nz == mz:
                # One orientation: photonmap._ray_ends' straight ray (no bend lift).
                ox, oy, oz, dx, dy, dz, t = _ray_ends(qx, qy, qz, nx, ny, nz, la, bx, by,
                                                      bz, mx, my, mz)
                o32[m, 0], o32[m, 1], o32[m, 2] = ox, oy, oz
                d32[m, 0], d32[m, 1], d32[m, 2] = dx, dy, dz
                t32[m] = t
                ray_row[m] = i
                ray_photon[m] = j
                m += 1
                continue
            ax, ay, az, cx, cy, cz, bx, by, bz = _bent_path(qx, qy, qz, nx, ny, nz, la,
                                                            bx, by, bz, mx, my, mz)
            m = _store_segment(ax, ay, az, cx, cy, cz, o32, d32, t32, m)
            ray_row[m - 1] = i
            ray_photon[m - 1] = j
            m = _store_segment(cx, cy, cz, bx, by, bz, o32, d32, t32, m)
            ray_row[m - 1] = i
            ray_photon[m - 1] = j
    return m


@kernel
def _store_segment(ax, ay, az, bx, by, bz, o32, d32, t32, m):
    """The ray from a to b into o32 / d32 / t32 at m (unit direction, length); m + 1."""
    wx, wy, wz = bx - ax, by - ay, bz - az
    dist = math.sqrt(wx * wx + wy * wy + wz * wz)
    inv = max(dist, 1e-300)
    o32[m, 0], o32[m, 1], o32[m, 2] = ax, ay, az
    d32[m, 0], d32[m, 1], d32[m, 2] = wx / inv, wy / inv, wz / inv
    t32[m] = dist
    return m + 1


@kernel
def _bent_path(qx, qy, qz, nx, ny, nz, la, bx, by, bz, mx, my, mz):
    """The visibility path from a query q (unit normal n, own offset la: _query_lift) to
    a photon b (unit normal m != n) on a curved surface: two segments a -> c -> b' that
    meet above the chord's midpoint, returned as (a, c, b') (9 floats).

    The ends are lifted only by their rounding-error bounds (a = q + la n, b' = b + lb m,
    lb as photonmap._ray_ends'). photonmap._ray_ends instead lifts both ends by the
    chord's bend, chord |n - m| / 4, which near another surface puts an end across it: a
    sphere's underside 3-9 cm above the floor it rests on, lifted 10-22 cm along its
    normal, started its rays below the floor, which hid 99.7 % of Figure 3's hidden
    (row, photon) pairs (docs/performance.md "e2e3x"). Here the lift goes to the
    chord's midpoint, away from both ends' surroundings: c = (q + b) / 2 + t w along the
    normals' bisector w = (n + m) / |n + m|. For a convex surface, which lies behind
    each of its tangent planes, a segment in front of q's plane (q, n) and a segment in
    front of b's plane (b, m) cannot meet it; a lies in front of q's plane and b' of
    b's, so c must be in front of both: t |n + m| / 2 >= -(b - q).n / 2 and
    >= (b - q).m / 2 (w.n = w.m = |n + m| / 2), t0 = max(-(b - q).n, (b - q).m, 0) /
    |n + m| (on a sphere chord tan(theta / 2) / 2, about _ray_ends' bend). With the
    geometric normals the estimates use (hit.ng, Photons.normal) the planes are the
    facets' own, so this holds for a tessellated convex mesh as it is. A concave surface
    needs none (t0 = 0: its chord runs in front of it). The margin beyond t0,
    BEND_MARGIN of the bend plus both ends' offsets, is room for rounding and meshes
    only nearly convex. What is left: where another surface comes closer to the chord's
    midpoint than t (a ball's contact with the floor it rests on, the last ~10 cm, where
    the gap under the ball is thinner than the path's lift) the photon is still hidden.
    Scalars only (a kernel called with arrays pays their reference counts)."""
    ex, ey, ez = bx - qx, by - qy, bz - qz
    chord = math.sqrt(ex * ex + ey * ey + ez * ez)
    gx, gy, gz = nx - mx, ny - my, nz - mz
    bend = 0.25 * chord * math.sqrt(gx * gx + gy * gy + gz * gz)
    sx, sy, sz = nx + mx, ny + my, nz + mz
    ls = max(math.sqrt(sx * sx + sy * sy + sz * sz), 1e-300)
    lb = 4.0 * ulp32_scalar(max(abs(bx), abs(by), abs(bz))) + 2.0 * G32_PLANE * chord
    t = (max(-(ex * nx + ey * ny + ez * nz), ex * mx + ey * my + ez * mz, 0.0) / ls
         + BEND_MARGIN * bend + la + lb)
    cx = 0.5 * (qx + bx) + t * sx / ls
    cy = 0.5 * (qy + by) + t * sy / ls
    cz = 0.5 * (qz + bz) + t * sz / ls
    return (qx + la * nx, qy + la * ny, qz + la * nz, cx, cy, cz, bx + lb * mx,
            by + lb * my, bz + lb * mz)




def _estimate_read(pmap, limits, counts, p, n, radius, k, min_photons, estimator, r_floor,
                   surface=None):
    """(E (M,3), count (M,) int64, photons (M, W) int64, weight (M, W) float64, factor
    (M,) float64): chaincounts.irradiance's estimate at p / n (counts (M,4) or None) and
    each row's read photons (PhotonMap.knn_irradiance's read: count[i] of them in
    photons[i, :count[i]], with their weights and the row's factor; photons and weight
    are this thread's _read_buffers, valid until its next call here). The
    list is READ_WIDTH x k wide; rows that read more are read again as wide as they need
    (the same search: the same photons). surface: the rows' (M,) object ids
    (PhotonMap.knn_irradiance) or None. A map with the precomputed caustic lookup
    (engine/causticcache.py, which has no search at the query) keeps its estimate, its
    read lists from the k-NN estimate the masked re-estimate takes.
    Also (wide (V,) int64, wide_count (V,), wide_photons (V, W'), wide_weight (V, W'),
    wide_factor (V,)): the rows whose lists were cut, read again whole (W' their longest
    list)."""
    m = len(p)
    width = max(1, READ_WIDTH * int(k))
    count = np.zeros(m, np.int64)
    photons, weight = _read_buffers(m, width)
    factor = np.empty(m)
    read = (count, photons, weight, factor)
    args = (radius, k, min_photons, estimator)
    if getattr(pmap, "lookup", "knn") == "precomputed":
        E = chaincounts.irradiance(pmap, limits, counts, p, n, *args, r_floor=r_floor,
                                   surface=surface)
        pmap.knn_irradiance(p, n, *args, r_floor=r_floor, read=read, surface=surface)
    else:
        E = chaincounts.irradiance(pmap, limits, counts, p, n, *args, r_floor=r_floor,
                                   read=read, surface=surface)
    wide = np.flatnonzero(count > width)
    v, w = len(wide), int(count[wide].max()) if len(wide) else 0
    more = (np.zeros(v, np.int64), np.empty((v, w), np.int64), np.empty((v, w)),
            np.empty(v))
    if len(wide):
        pmap.knn_irradiance(p[wide], n[wide], *args,
                            r_floor=None if r_floor is None else r_floor[wide], read=more,
                            surface=None if surface is None else surface[wide])
    return E, count, photons, weight, factor, (wide, *more)


_READ_BUFFERS = threading.local()


def _read_buffers(m, width):
    """This thread's (photons (m, width) int64, weight (m, width) float64) for
    _estimate_read's lists, valid until its next call on the thread (the callers consume
    a block's lists before the next). Fresh arrays each call faulted their pages in on
    every call: ~1 KB a row each (k = 64), 0.3 of Figure 3's 13 CPU s for the two lists.
    Kept for the thread's life at the largest size asked (at most READ_ROWS rows: 16 MB
    each at k = 64)."""
    got = getattr(_READ_BUFFERS, "arrays", None)
    if got is None or got[0].shape[0] < m or got[0].shape[1] != width:
        got = _READ_BUFFERS.arrays = (np.empty((m, width), np.int64), np.empty((m, width)))
    return got[0][:m], got[1][:m]


def _blocked_paths(accel, o32, d32, t32, ray_row, ray_photon, nr):
    """(nr,) bool: which of _read_rays' first nr rays are blocked, where a bent path's
    first segment is traced only when its second (the photon's end) is clear: a path is
    hidden when either is blocked, so the answer for each path is the same as tracing
    every segment, and a segment left untraced reads clear. (Hair: the photons of a
    strand's disc lie on other strands, so ~2/3 of its rays are bent pairs and ~30 % of
    the pairs' second segments are blocked: 14 % fewer visibility rays, docs/performance.md
    hair39.)"""
    blocked = np.zeros(nr, bool)
    # A pair's two segments are adjacent with one row and photon (a row reads a photon once).
    first = np.zeros(nr, bool)
    first[:-1] = (ray_row[1:nr] == ray_row[:nr - 1]) & (ray_photon[1:nr] == ray_photon[:nr - 1])
    if not first.any():
        accel.occluded_into(o32[:nr], d32[:nr], t32[:nr], blocked)
        return blocked
    now = np.flatnonzero(~first)  # single rays and second segments
    got = np.zeros(len(now), bool)
    accel.occluded_into(np.take(o32, now, axis=0), np.take(d32, now, axis=0),
                        np.take(t32, now), got)
    blocked[now] = got
    later = np.flatnonzero(first)
    later = later[~blocked[later + 1]]
    got = np.zeros(len(later), bool)
    accel.occluded_into(np.take(o32, later, axis=0), np.take(d32, later, axis=0),
                        np.take(t32, later), got)
    blocked[later] = got
    return blocked


def _hidden_pairs(pmap, accel, p, n, lift, rows, slots, count, photons):
    """(rows (H,) int64, photons (H,) int64): the pairs (row, map photon) among the rows
    `rows` of p / n (lift (M,) float64, empty: their own offsets) and their read photons
    (row rows[r]'s: photons[slots[r], :count[slots[r]]], _estimate_read's lists) whose
    visibility ray is blocked, in the rows' order."""
    ph = pmap.photons
    rows_out, photons_out = [], []
    for a in range(0, len(rows), BLOCK_ROWS):
        block = rows[a:a + BLOCK_ROWS]
        slot = slots[a:a + BLOCK_ROWS]
        size = 2 * int(count[slot].sum())  # a curved pair's path is two segments
        if not size:
            continue
        o32 = np.empty((size, 3), np.float32)
        d32 = np.empty((size, 3), np.float32)
        t32 = np.empty(size, np.float32)
        ray_row = np.empty(size, np.int64)
        ray_photon = np.empty(size, np.int64)
        nr = _read_rays(ph.position, ph.normal, p, n, lift, block, slot, count, photons,
                        o32, d32, t32, ray_row, ray_photon)
        if not nr:
            continue
        blocked = _blocked_paths(accel, o32, d32, t32, ray_row, ray_photon, nr)
        if blocked.any():
            # A pair once, though both its segments are blocked (they are adjacent).
            hit = np.flatnonzero(blocked)
            hit = hit[np.r_[True, (hit[1:] != hit[:-1] + 1)
                            | (ray_row[hit[1:]] != ray_row[hit[:-1]])
                            | (ray_photon[hit[1:]] != ray_photon[hit[:-1]])]]
            rows_out.append(ray_row[hit])
            photons_out.append(ray_photon[hit])
    if not rows_out:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(rows_out), np.concatenate(photons_out)


def _estimate_hidden(pmap, accel, p, n, lift, radius, k, min_photons, estimator, r_floor,
                     limits, counts, geo, visible=False, surface=None, reject=None,
                     clamp=None):
    """(E (M,3), rows (H,), photons (H,)): the estimate at p / n (chaincounts.irradiance,
    counts (M,4) or None) and its hidden (row, photon) pairs, by row: the photons each
    row's estimate read (_estimate_read) traced from the row (_hidden_pairs), in blocks
    of READ_ROWS rows (SERIAL_READ_ROWS where pmap is a one-thread view; one search a
    row for both). Rows the pre-test frees (geo:
    OneSurfaceCells; None: none) are not traced. visible: E's rows that hide a photon
    hold their estimate from their visible photons alone (_visible_sums: from the read
    lists, the bits of _reestimate's second search). surface: the rows' (M,) object ids
    (PhotonMap.knn_irradiance) or None. reject: a callable (rows (H,) of p, map photons
    (H,)) -> (H,) bool, the read pairs to leave out of E as well (counted as hidden ones
    are, the same search and disc; not in the returned pairs), or None. accel None: no
    pair is traced (reject's alone). clamp: (scale (M,3), limit) or (scale, limit,
    bounce (M,) int: the rows' camera path bounce, roulette_share's) or None: with visible,
    each photon of E weighed by Clamp Indirect's w_p (clamp_weights; scale the rows'
    clamp throughput x albedo), where the map keeps Photons.radiance: the rows
    where some photon is over the limit are summed again (_visible_sums, with their
    hidden photons left out), every other row keeps its bits."""
    m = len(p)
    if clamp is not None and (not visible or pmap.photons.radiance is None):
        clamp = None
    bounce = clamp[2] if clamp is not None and len(clamp) > 2 else None
    if surface is not None:
        surface = query_surfaces(surface, m)
    p = np.ascontiguousarray(p, dtype=np.float64)
    n = np.ascontiguousarray(n, dtype=np.float64)
    lift = (np.zeros(0) if lift is None else np.ascontiguousarray(lift, dtype=np.float64))
    floor = (None if r_floor is None
             else np.ascontiguousarray(np.broadcast_to(r_floor, (m,)), dtype=np.float64))
    traced = np.ones(m, bool)
    if geo is not None and radius > 0:
        reach = (np.maximum(radius, floor) if floor is not None
                 else np.full(m, float(radius)))
        traced = ~one_surface_cells(geo, radius).free(p, reach, n)
    E = np.empty((m, 3))
    rows_out, photons_out = [], []
    block = READ_ROWS if getattr(pmap, "workers", 1) > 1 else SERIAL_READ_ROWS
    for a in range(0, m, block):
        b = min(a + block, m)
        counts_here = None if counts is None else counts[a:b]
        E[a:b], count, photons, weight, factor, (wide, *wide_read) = _estimate_read(
            pmap, limits, counts_here, p[a:b], n[a:b], radius, k, min_photons, estimator,
            None if floor is None else floor[a:b],
            None if surface is None else surface[a:b])
        if accel is None and reject is None and clamp is None:
            continue
        here = (p[a:b], n[a:b], lift[a:b] if len(lift) else lift)
        listed = np.flatnonzero((count > 0) & (count <= photons.shape[1]))
        rows = hid = _NO_PAIRS
        if accel is not None:
            todo = listed[traced[a:b][listed]]
            rows, hid = _hidden_pairs(pmap, accel, *here, todo, todo, count, photons)
            rows_out.append(rows + a)
            photons_out.append(hid)
        dropped = over = None
        if reject is not None:
            dropped = _rejected_lists(listed, listed, count, photons, a, reject)
        if clamp is not None:
            # (Clamp Indirect per photon: each listed photon's weight, and the rows where
            # some photon is over the limit, summed again with the hidden ones)
            over = clamp_weights(pmap, (count, photons), listed, listed, clamp[0][a:b],
                                 clamp[1], None if bounce is None else bounce[a:b])
        if ((visible or reject is not None)
                and (len(rows) or over is not None or dropped is not None)):
            _visible_sums(pmap, limits, counts_here, E[a:b], rows, rows, hid,
                          (count, photons, weight, factor), over, dropped)
        if len(wide):
            rows = hid = _NO_PAIRS
            if accel is not None:
                slot = np.flatnonzero(traced[a:b][wide])
                rows, hid = _hidden_pairs(pmap, accel, *here, wide[slot], slot,
                                          *wide_read[:2])
                rows_out.append(rows + a)
                photons_out.append(hid)
            dropped = over = None
            if reject is not None:
                dropped = _rejected_lists(wide, np.arange(len(wide)), *wide_read[:2], a,
                                          reject)
            if clamp is not None:
                over = clamp_weights(pmap, wide_read[:2], wide, np.arange(len(wide)),
                                     clamp[0][a:b], clamp[1],
                                     None if bounce is None else bounce[a:b])
            if ((visible or reject is not None)
                    and (len(rows) or over is not None or dropped is not None)):
                # (each wide row's slot: its place in wide, which is ascending)
                _visible_sums(pmap, limits, counts_here, E[a:b], rows,
                              np.searchsorted(wide, rows), hid, wide_read, over, dropped)
    if not rows_out:
        return E, np.zeros(0, np.int64), np.zeros(0, np.int64)
    rows, photons = np.concatenate(rows_out), np.concatenate(photons_out)
    order = np.argsort(rows, kind="stable")  # (the cut rows' pairs came after their block)
    return E, rows[order], photons[order]


_NO_PAIRS = np.zeros(0, np.int64)


def _rejected_lists(qrows, slots, count, photons, a, reject):
    """The read pairs reject leaves out, as a mask over the read lists: qrows (Q,) the
    rows of the block whose lists photons[slots[r], :count[slots[r]]] are asked (a: the
    block's first row of p; reject's rows are p's, each pair answered alone). None where
    reject keeps every pair, else (rows (D,) int64, slots (D,) int64, dropped (L, W)
    bool): the rows that lose some photon, their lists, and the mask (photons' shape,
    False outside the asked lists) for _visible_rows. A mask in place of the pairs
    (row, photon) spares their keys' sort and _visible_rows' second, bisecting pass over
    pairs not in the lists' order (docs/performance.md "percost56")."""
    slots = np.asarray(slots, np.int64)
    c = np.take(count, slots)
    width = int(c.max()) if len(c) else 0
    if width == 0:
        return None
    lists = np.take(photons, slots, axis=0)[:, :width]
    inside = np.arange(width)[None, :] < c[:, None]
    pr = np.repeat(np.asarray(qrows, np.int64), c)
    drop = np.asarray(reject(pr + a, lists[inside]), bool)
    if not drop.any():
        return None
    sub = np.zeros(inside.shape, bool)
    sub[inside] = drop
    dropped = np.zeros(photons.shape, bool)
    dropped[slots, :width] = sub
    some = sub.any(axis=1)
    return np.asarray(qrows, np.int64)[some], slots[some], dropped


def clamp_weights(pmap, read, qrows, slots, scale, limit, bounce=None):
    """Clamp Indirect's photonclamp.photon_weights over an estimate's read lists, for
    _visible_sums: read = (count, photons) (_estimate_read's lists, (L,) and (L, W)),
    qrows (Q,) the rows of the block whose lists slots (Q,) are whole, scale (B,3) each
    row's clamp throughput x albedo, limit Clamp Indirect's, bounce (B,) int or None
    each row's camera path bounce (roulette_share's; None: 0, the camera's first hits).
    Returns None where no listed
    photon is over the limit (every weight 1: the estimates keep their bits), else (rows
    (V,), slots (V,), clamp_w (L, W) float64): the rows with some photon over the limit,
    their lists, and each listed photon's w_p (1 past a list's count and for lists not in
    slots). One compiled pass over the read lists (_clamp_list_weights) with no (rows,
    width, 3) temporaries: Cycles' Russian roulette share Q (photonclamp.roulette_share,
    numpy's pow) tabled per row and chain length, the rest of photonclamp.photon_weights
    per photon. The numpy stage it replaced took 4.7 of the candles' 31 profiled camera
    CPU s (docs/performance.md "percost56"); tests/test_hotspot_kernels.py keeps it as
    the reference, bit for bit."""
    ph = pmap.photons
    if ph.radiance is None or not len(qrows):
        return None
    count, photons = read
    qrows = np.ascontiguousarray(qrows, np.int64)
    slots = np.ascontiguousarray(slots, np.int64)
    bounces = getattr(ph, "bounces", None)
    if bounces is None or not photonclamp.ROULETTE:
        share, bounces = _NO_SHARE, _NO_BOUNCES
    else:
        chains = np.arange(_longest_chain(pmap) + 1, dtype=np.float64)
        share = np.ascontiguousarray(photonclamp.roulette_share(
            np.take(scale, qrows, axis=0)[:, None, :], chains[None, :],
            0 if bounce is None else np.take(bounce, qrows)[:, None]), dtype=np.float64)
    clamp_w = np.ones(photons.shape)
    over = np.zeros(len(qrows), bool)
    _clamp_list_weights(ph.power, ph.radiance, bounces, B_TOTAL, share,
                        np.ascontiguousarray(scale, dtype=np.float64), qrows, slots, count,
                        photons, float(limit), clamp_w, over)
    if not over.any():
        return None
    return qrows[over], slots[over], clamp_w


def _longest_chain(pmap) -> int:
    """The map's most scatters since the light (Photons.bounces[:, B_TOTAL].max()),
    found once per bounces array and kept on the map."""
    bounces = pmap.photons.bounces
    got = vars(pmap).get("longest_chain")
    if got is None or got[0] is not bounces:
        got = (bounces, int(bounces[:, B_TOTAL].max()) if len(bounces) else 0)
        vars(pmap)["longest_chain"] = got
    return got[1]


_NO_SHARE = np.zeros((0, 0))  # _clamp_list_weights: Q = 1 (no roulette share)
_NO_BOUNCES = np.zeros((0, 4), np.uint8)


@kernel
def _clamp_list_weights(power, radiance, bounces, b_total, share, scale, qrows, slots,
                        count, photons, limit, clamp_w, over):
    """clamp_weights' pass: for each r, the read list s = slots[r] (photons[s,
    :count[s]]) of row qrows[r] at its clamp throughput x albedo scale[qrows[r]] (3,):
    clamp_w[s, j] = photonclamp.photon_weights' w_p = min(1, Q x limit / contrib),
    contrib = radiance x |scale x flux|_1 / |flux|_1 (0 where no flux; a non-finite w
    is 1), Q = share[r, bounces[photon, b_total]] (share (Q, chains) or (0, 0): 1),
    its float64 operations in numpy's order; over[r] whether some w_p < 1."""
    use_share = share.shape[0] > 0
    for r in range(qrows.shape[0]):
        i = qrows[r]
        s = slots[r]
        s0, s1, s2 = scale[i, 0], scale[i, 1], scale[i, 2]
        clamped = False
        for jj in range(count[s]):
            pj = photons[s, jj]
            f0, f1, f2 = read_power(power, pj)  # (photonlayout: float32 or RGBE)
            flux = abs(f0) + abs(f1) + abs(f2)
            c = abs(s0 * f0) + abs(s1 * f1) + abs(s2 * f2)
            lim = limit
            if use_share:
                lim = limit * share[r, bounces[pj, b_total]]
            contrib = np.float64(radiance[pj]) * c / flux if flux > 0.0 else 0.0
            w = lim / contrib if contrib > lim else 1.0
            if not math.isfinite(w):
                w = 1.0
            clamp_w[s, jj] = w
            if w < 1.0:
                clamped = True
        over[r] = clamped


def hidden_photons(pmap, accel, p, n, lift, radius, k, r_floor=None, geo=None,
                   min_photons=1, estimator="knn_simpson", surface=None):
    """(rows (H,) int64, photons (H,) int64): the pairs (query row, map photon) whose
    visibility ray is blocked, over the photons the estimate at p (M,3) with unit
    normals n (M,3) facing the viewer reads (PhotonMap.knn_irradiance's read lists);
    lift (M,) their ray offsets (SurfaceHit.offset) or None; radius, k, min_photons,
    estimator, r_floor ((M,) or None, its footprint floor): the estimate's; geo: the
    scene's Geometry, for the pre-test (OneSurfaceCells: rows with no other surface near
    are not traced; None: every row is); surface: the rows' object ids or None
    (PhotonMap.knn_irradiance). Sorted by row."""
    none = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    if pmap is None or pmap.tree is None or len(p) == 0 or radius <= 0 or accel is None:
        return none
    _, rows, photons = _estimate_hidden(pmap, accel, p, n, lift, radius, k, min_photons,
                                        estimator, r_floor, None, None, geo,
                                        surface=surface)
    return rows, photons


def visible_irradiance(pmap, accel, p, n, lift, radius, k, min_photons, estimator,
                       r_floor=None, limits=None, counts=None, geo=None, surface=None,
                       reject=None, clamp=None):
    """E (M,3) (W/m^2): the estimate pmap.irradiance (or chaincounts.irradiance with
    limits and counts (M,4) or None) at p / n (unit normals (M,3) facing the viewer;
    lift (M,) their ray offsets or None), with the rows that have hidden photons
    (_estimate_hidden: the photons each row's estimate read, traced from it) estimated
    again from their visible photons alone (the hidden ones' power counted as 0, and the
    photons their camera-side counts cannot use, as chaincounts.irradiance does). Rows
    without a hidden photon keep the estimate's bits. accel None: the plain estimate.
    surface: the rows' (M,) object ids (PhotonMap.knn_irradiance) or None. reject:
    _estimate_hidden's (pairs left out as hidden ones are; accel None: those alone).
    clamp: (scale (M,3), limit[, bounce (M,)]) or None: _estimate_hidden's (Clamp Indirect
    per photon)."""
    if pmap is None or len(pmap) == 0 or pmap.tree is None or len(p) == 0 or radius <= 0:
        return chaincounts.irradiance(pmap, limits, counts, p, n, radius, k, min_photons,
                                      estimator, r_floor=r_floor, surface=surface)
    # The rows that hide a photon summed again over their read lists (_visible_sums):
    # the bits of a second, masked search (_reestimate) for a fraction of its cost
    # (Figure 7: 2.4 CPU s of 35 were those searches, docs/performance.md "gatherspeed").
    E, _, _ = _estimate_hidden(pmap, accel, p, n, lift, radius, k, min_photons, estimator,
                               r_floor, limits, counts, geo, visible=True, surface=surface,
                               reject=reject, clamp=clamp)
    return E


def _visible_sums(pmap, limits, counts, E, rows, slots, photons, read, over=None,
                  dropped=None):
    """E[rows] estimated again from each row's visible photons alone, from its read list:
    rows (H,) int64 the pairs' rows of E (M,3) (with repeats), photons (H,) the hidden
    map photons, slots (H,) each pair row's entry in read = (count, photons, weight,
    factor) (_estimate_read's lists, whole for these rows). The estimate is
    factor x the sum, in the list's order, of weight x power over the photons that are
    neither hidden from the row nor unusable at its counts (counts (M,4) or None, with
    limits: chaincounts' masks): PhotonMap.knn_irradiance's masked sum over the same
    search (its other photons weigh 0 or are masked), so the bits of _reestimate.
    over: None, or clamp_weights' (rows (V,), slots (V,), clamp_w (lists,
    width)): those rows of E summed again too (with or without hidden photons) and every
    photon's weight times its clamp_w (Clamp Indirect per photon). dropped: None, or
    _rejected_lists' (rows (D,), slots (D,), mask (lists, width) bool): those rows of E
    summed again too, the photons the mask marks left out as hidden ones are. Writes
    into E.

    _hidden_pairs lists each row's pairs together, in its read list's order: the sums
    walk both lists at once. Pairs in any other order are sorted (by row, then photon)
    and bisected instead: the same sums."""
    if len(rows) > 1 and (rows[1:] < rows[:-1]).any():
        order = np.argsort(rows, kind="stable")
        rows, photons, slots = rows[order], photons[order], slots[order]
    args = _visible_args(pmap, limits, counts, rows, photons, slots, read, E, over, dropped)
    if _visible_rows(*args, False):
        # (some row's hidden photons not in its list's order) each row's hidden photons
        # ascending, bisected
        order = np.lexsort((photons, rows))
        rows, photons, slots = rows[order], photons[order], slots[order]
        _visible_rows(*_visible_args(pmap, limits, counts, rows, photons, slots, read, E,
                                     over, dropped), True)


def _visible_args(pmap, limits, counts, rows, photons, slots, read, E, over=None,
                  dropped=None):
    """_visible_rows' arguments for _visible_sums' pairs (grouped by row; rows sorted)
    and over's and dropped's rows (each row once, its hidden photons the range bounds
    gives it, empty for a row without)."""
    rows = np.asarray(rows, np.int64)
    clamp_w = _NO_CLAMP_W if over is None else over[2]
    mask = _NO_DROPPED if dropped is None else dropped[2]
    more = [x for x in (over, dropped) if x is not None]
    if not more:
        starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
        hiding = rows[starts]
        slot_of = np.asarray(slots)[starts]
        bounds = np.r_[starts, len(rows)].astype(np.int64)
    else:
        # (the pairs' rows, over's and dropped's, each once, ascending; a row's pairs are
        # rows[bounds[r]:bounds[r + 1]], consecutive as the rows are sorted)
        hiding, first = np.unique(np.concatenate([rows] + [x[0] for x in more]),
                                  return_index=True)
        slot_of = np.concatenate([np.asarray(slots, np.int64)]
                                 + [np.asarray(x[1], np.int64) for x in more])[first]
        bounds = np.r_[np.searchsorted(rows, hiding), len(rows)].astype(np.int64)
    if (counts is not None and limits is not None
            and getattr(pmap.photons, "bounces", None) is not None):
        # (chaincounts.unique_counts: np.unique(axis=0)'s arrays without its slow sort)
        keys, cls = chaincounts.unique_counts(np.asarray(counts)[hiding])
        cache = chaincounts.map_cache(pmap)
        usable = np.stack([chaincounts._usable(pmap.photons, limits,
                                               tuple(int(x) for x in key), cache)
                           for key in keys])
        cls = np.ascontiguousarray(cls.reshape(-1), dtype=np.int64)
    else:
        usable = _ALL_USABLE
        cls = np.zeros(len(hiding), np.int64)
    count, listed, weight, factor = read
    return (pmap.photons.power, hiding, np.ascontiguousarray(slot_of, dtype=np.int64),
            bounds, np.ascontiguousarray(photons, dtype=np.int64), usable, cls, count,
            listed, weight, clamp_w, mask, factor, E)


_ALL_USABLE = np.zeros((0, 0), np.bool_)  # _visible_rows: every photon usable
_NO_CLAMP_W = np.zeros((0, 0))  # _visible_rows: no Clamp Indirect weights
_NO_DROPPED = np.zeros((0, 0), np.bool_)  # _visible_rows: no photon dropped by mask


@kernel
def _visible_rows(power, rows, slots, bounds, hidden, usable, cls, count, photons, weight,
                  clamp_w, dropped, factor, E, ascending):
    """_visible_sums' sums: for each r, E[rows[r]] = factor[s] x the sum over the read
    list s = slots[r] (photons[s, :count[s]], weights weight[s]) of weight x
    float64(power) for its photons not in hidden[bounds[r]:bounds[r + 1]] and usable
    (usable[cls[r]], or usable empty: all), in the list's order:
    photonmap._irradiance_rows' masked sum (its float64 operations in its order).
    clamp_w (lists, width) or (0, 0): each listed photon's Clamp Indirect weight
    (clamp_weights), one more factor of its weight (x 1.0: the same bits). dropped
    (lists, width) bool or (0, 0): listed photons left out as hidden ones are
    (_rejected_lists).
    ascending: each row's hidden photons are ascending (bisected); else in the list's
    order (walked along it). Returns the rows whose hidden photons were not all met
    in the list's order (not ascending only; their E is then wrong: sort and ask again)."""
    bad = 0
    clamped = clamp_w.shape[0] > 0
    masked = dropped.shape[0] > 0
    for r in range(rows.shape[0]):
        i = rows[r]
        s = slots[r]
        h_lo, h_hi = bounds[r], bounds[r + 1]
        h = h_lo  # the next hidden photon the walk expects
        c = cls[r]
        e0 = e1 = e2 = 0.0
        for jj in range(count[s]):
            pj = photons[s, jj]
            if not ascending:
                if h < h_hi and hidden[h] == pj:
                    h += 1
                    continue
            else:
                lo, hi = h_lo, h_hi
                while lo < hi:
                    mid = (lo + hi) >> 1
                    if hidden[mid] < pj:
                        lo = mid + 1
                    else:
                        hi = mid
                if lo < h_hi and hidden[lo] == pj:
                    continue
            if masked and dropped[s, jj]:
                continue
            if usable.shape[0] and not usable[c, pj]:
                continue
            w = weight[s, jj]
            if clamped:
                w = w * clamp_w[s, jj]
            f0, f1, f2 = read_power(power, pj)  # (photonlayout: float32 or RGBE)
            e0 += w * f0
            e1 += w * f1
            e2 += w * f2
        if not ascending and h != h_hi:
            bad += 1
        f = factor[s]
        E[i, 0] = e0 * f
        E[i, 1] = e1 * f
        E[i, 2] = e2 * f
    return bad


def _reestimate(E, pmap, p, n, radius, k, min_photons, estimator, r_floor, limits, counts,
                rows, photons, surface=None):
    """E with the rows `rows` estimated again without their hidden photons (rows (H,),
    photons (H,): the pairs), in one estimate call per count class (PhotonMap.irradiance's
    hidden: each row's hidden photons left out for that row alone). Writes into E.
    The reference _visible_sums reproduces bit for bit from the first search's read lists
    (tests/test_photon_visibility_reuse.py); visible_irradiance no longer calls it."""
    cache = chaincounts.map_cache(pmap) if counts is not None else None
    use_counts = (counts is not None and limits is not None
                  and getattr(pmap.photons, "bounces", None) is not None)
    # Each row's hidden photons ascending (the estimate kernel bisects them).
    order = np.lexsort((photons, rows))
    rows, photons = rows[order], photons[order]
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    hiding = rows[starts]
    # One estimate call per count class (all rows one class without counts): its mask of
    # usable photons, each row's hidden photons left out for that row alone (the bits of
    # one call a row with them cleared: PhotonMap.irradiance's hidden).
    if use_counts:
        _, cls = np.unique(np.asarray(counts)[hiding], axis=0, return_inverse=True)
        cls = cls.reshape(-1)
    else:
        cls = np.zeros(len(hiding), np.int64)
    count = np.diff(np.r_[starts, len(rows)])
    floor = None if r_floor is None else np.broadcast_to(r_floor, (len(p),))
    for c in np.unique(cls):
        pick = np.flatnonzero(cls == c)
        sel = hiding[pick]
        key = tuple(int(x) for x in counts[sel[0]]) if use_counts else None
        base = (chaincounts._usable(pmap.photons, limits, key, cache) if use_counts
                else np.ones(len(pmap.photons), np.bool_))
        # The picked rows' hidden photons, in their order (CSR by row).
        n_of = count[pick]
        sub_starts = np.r_[0, np.cumsum(n_of)].astype(np.int64)
        take = (np.repeat(starts[pick] - sub_starts[:-1], n_of)
                + np.arange(sub_starts[-1], dtype=np.int64))
        _, masked = pmap.irradiance(
            p[sel], n[sel], radius, k, min_photons, estimator,
            r_floor=None if floor is None else floor[sel], masks=base[None],
            hidden=(sub_starts, photons[take]),
            surface=None if surface is None else np.asarray(surface)[sel])
        E[sel] = masked[0]
    return E


@register_warm_up
def _warm_up():
    from .photonmap import PhotonMap
    from .photons import Photons
    rng = np.random.default_rng(0)
    ph = Photons(rng.random((8, 3)).astype(np.float32), np.ones((8, 3), np.float32),
                 np.tile(np.float32([0, 0, -1]), (8, 1)), np.tile(np.float32([0, 0, 1]), (8, 1)),
                 np.zeros(8, np.uint8), 8)
    pmap = PhotonMap(ph)
    o32, d32 = np.empty((8, 3), np.float32), np.empty((8, 3), np.float32)
    _read_rays(pmap.photons.position, pmap.photons.normal, np.zeros((1, 3)),
               np.float64([[0, 0, 1]]), np.zeros(0), np.zeros(1, np.int64),
               np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros((1, 8), np.int64),
               o32, d32, np.empty(8, np.float32), np.empty(8, np.int64),
               np.empty(8, np.int64))
    one = np.zeros(1, np.int64)
    _visible_rows(pmap.photons.power, one, one, np.int64([0, 1]), one, _ALL_USABLE, one,
                  np.ones(1, np.int64), np.zeros((1, 8), np.int64), np.ones((1, 8)),
                  _NO_CLAMP_W, _NO_DROPPED, np.ones(1), np.zeros((1, 3)), False)
    _clamp_list_weights(pmap.photons.power, np.ones(8, np.float32), _NO_BOUNCES, B_TOTAL,
                        _NO_SHARE, np.ones((1, 3)), one, one, np.ones(1, np.int64),
                        np.zeros((1, 8), np.int64), 1.0, np.ones((1, 8)),
                        np.zeros(1, bool))
