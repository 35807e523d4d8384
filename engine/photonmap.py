"""Photon maps: stored photons in a compiled search structure (engine/kdtree.py, or
engine/hashgrid.py) and the irradiance estimators, run as numba kernels (engine/jit.py).

Estimators (irradiance E in W/m^2; the caller multiplies by the diffuse albedo / pi):
  classic      the paper's: all photons within a fixed radius r, each weighted by
               max(-d.N, 0), divided by pi r^2; ignored when fewer than the minimum.
               (The cosine weight is the paper's; it darkens light arriving at grazing
               angles, so it is not the default.)
  radius       all photons within a fixed radius r, Simpson kernel (no cosine weight):
               the estimator of progressive passes, whose radius shrinks pass by pass
  knn_simpson  k nearest photons within the max radius, Simpson kernel 3/(pi r^2)(1-d^2/r^2)^2
  knn_cone     k nearest, Jensen's cone filter (k=1), normalised by (1 - 2/3) pi r^2
Photons that arrive from behind the query's surface (d.N >= 0) or lie on a surface facing
another way (photon normal . N < 0.5, e.g. round a corner or the other side of a thin
wall) are ignored: that is what keeps light from leaking.
"""
from __future__ import annotations

import copy
import math

import numpy as np

from . import hashgrid, kdtree, mortontree, photonlayout
from . import photonkernels as pk
from .jit import kernel, register_warm_up
from .mortontree import morton_order  # noqa: F401 (query order; tests, benches)
from .parallel import Cancelled, StopFlag, ordered_map, run_tasks, stop_array
from .photonlayout import cos_at_most, cos_below, read_axis, read_power, read_vector
from .photons import Photons
from .rayoffset import G32_PLANE, ulp32_scalar
from .samesurface import (COPLANAR_COS, NO_SURFACE, off_plane, query_surfaces, same_surface,
                          surface_ids)

NORMAL_AGREEMENT = 0.5
BOUNDARY_OFFSET = 0.25  # centroid offset / r that marks an estimate's disc as cut off
# ... or, with few photons, the offset a whole disc's n photons exceed with this
# probability: |centroid| / r of n points uniform in a disc is about Rayleigh with
# per-axis variance 1 / (4 n), so P(offset > t) = exp(-2 n t^2), and the limit is
# sqrt(ln(1 / BOUNDARY_FALSE_ALARM) / (2 n)) where that exceeds BOUNDARY_OFFSET (n < 24).
# A fixed 0.25 flagged a whole disc of 8 photons 37 % of the time, of 16 14 %, of 32 2 %:
# the points kept (not gathered again) were those with more photons than their disc's
# mean, and their lookups read bright: +3 % at 16 photons a disc, +11 % at 8, +32 % at 4
# (a plane's sparse discs, capped at the search radius; tests/test_two_sided.py,
# docs/performance.md "backside"). At a fixed false-alarm rate the flag no longer
# depends on the count, so it selects no estimate.
BOUNDARY_FALSE_ALARM = 0.05
BOUNDARY_LOG = math.log(1.0 / BOUNDARY_FALSE_ALARM)
MAX_CLASSIC_K = 4096
# A k-NN row with fewer than k accepted photons in its search sphere takes its radius from
# its last accepted photon when it has at least this many (_irradiance_rows). Then the
# estimate is unbiased wherever those photons lie uniformly around the query, whatever the
# area of their surface: N uniform in a disc of radius R put the last at d^2 = R^2 max(U),
# E[1 / max(U)] = N / (N - 1), and Simpson's kernel gives the last weight 0, so E[estimate]
# = (N - 1) / (pi R^2) x N / (N - 1) = N / (pi R^2); on a sphere the surface within chord
# distance d is exactly pi d^2 (Archimedes), so the same holds on a ball. Its variance is
# finite from N = 3 (E[1 / max(U)^2] = N / (N - 2)): with 2 the rare close pair makes
# fireflies (a plane with 2 photons a disc: max 84 x its mean, 30 x at 3, 6.7 x with the
# max radius). docs/accuracy.md "caustic31".
SPARSE_MIN_ACCEPTED = 3
MAX_WIDEN_K = 4096  # k-NN queries widen up to this many photons to find k accepted ones
# The k-NN radius never shrinks below this share of the search radius. A lens focusing a
# point light piles k photons onto a point; a smaller disc makes the estimate there huge,
# and the few camera samples that land on it become fireflies (the Figure 8 focus, seen
# magnified through the ball: one pixel at 939 x the image mean). The photons inside the
# floor disc are all counted (_irradiance_rows), so light is spread over it, never lost.
MIN_RADIUS_FRACTION = 0.01
# A row about to widen first scans its search sphere for accepted photons, up to this many
# photons (measured: a scan of this many costs less than the MAX_WIDEN_K heap query it
# saves; bench/bench_lookup.py). 512 KB of scratch per kernel call.
SCAN_BUDGET = 16 * MAX_WIDEN_K
# A widening row over a listed sphere orders its photons only as far as its estimate
# reads them: the kq nearest of each width, and where the estimate reads the whole sphere,
# its accepted photons alone (the same bits: docs/performance.md "secondary"). False: the
# whole sphere ordered and summed, as before (tests compare the two).
WIDEN_ORDER_AS_READ = True
# A k-NN estimate lists its whole search sphere (then orders its k nearest: no heap) when
# the sphere holds at most this many times k photons (kdtree.ball_d2, nearest_first).
LIST_FACTOR = 8
# A k-NN row first lists a sphere of this many times the previous row's kq-th squared
# distance (1.2x the distance; measured on Figure 6's gather map: 1.2x lists 92 photons
# a row and is taken by 96 % of rows, 1.41x 128 and 91 %, the whole sphere ~243).
SEED_GROWTH = 1.44
# Rows in Morton order lie close together: a block of up to CAND_ROWS consecutive k-NN
# rows within CAND_SPAN x the search radius of their box's centre lists the photons of
# the sphere that holds all their search spheres once (one kd-tree search), and each row
# lists its own sphere from those candidates (a scan of at most CAND_CAP photons, float64
# distances as the tree computes them) instead of a tree search of its own. A block with
# more candidates, or a row whose answer could depend on the listing's order (equal
# distances), takes the tree as before (docs/performance.md "causticknn").
CAND_ROWS = 32
CAND_SPAN = 0.25
CAND_CAP = 512
CAND_MIN_ROWS = 4
CAND_BACKOFF = 16
# Where a block's candidates overflow (a dense caustic: Figure 8's focus), its rows' seeded
# spheres (SEED_GROWTH x the previous row's kq-th squared distance) are far smaller than
# the search sphere: a block of rows within SEED_SPAN x a seed radius of their box's centre,
# that radius SEED_REACH x the previous row's seeded one, lists the photons of the sphere
# holding every such seeded sphere once, and each row whose own seeded sphere is no wider
# lists it from those (docs/performance.md "caustickernel"). Rows whose seeded sphere is
# wider, or that need their whole sphere, take the tree.
SEED_REACH = 1.25
SEED_SPAN = 0.5
BLOCK_ROWS = 8192  # rows per kernel call when the rows are shared among worker threads
# Estimates between two looks at the stop flag: 64 x ~15 us (a widening row: ~1.5 ms) is
# far below the 0.2 s a viewport stop may take (issue 19).
STOP_ROWS = 64

ESTIMATOR_CODES = {"classic": 0, "radius": 1, "knn_simpson": 2, "knn_cone": 3}
CLASSIC, RADIUS, KNN_SIMPSON, KNN_CONE = 0, 1, 2, 3
STRUCTURES = ("kdtree", "hashgrid")
KDTREE, HASHGRID = 0, 1


class PhotonMap:
    """Stored photons and their search structure (engine/kdtree.py by default, or
    engine/hashgrid.py), with the irradiance estimators compiled into one kernel.

    The photons are kept in the structure's order (self.photons is that permutation of
    the input), so a search result indexes the photon arrays directly: the map adds under
    2 bytes (kd-tree nodes) or 4-8 bytes (hash grid) per photon to the photons' 25 (29
    with their surfaces, Photons.surface: 4 B) in the compact layout (photonlayout.COMPACT,
    the default: power, direction and normal in 12 B; 49 / 53 B with it off).
    structure: "kdtree" or "hashgrid"; cell: the hash grid's cell size (the search radius
    it serves best), required for "hashgrid". Raises ValueError for anything else.
    rows: (K,) int, the map holds only those photons (photons.take(rows), gathered once
    straight into the tree's order instead of twice); power_scale: (K,) float32 factors
    multiplying those photons' power (the same float32 products as scaling first);
    keep_source: keep self.source, (K,) int64, each map photon's row in `photons`."""

    def __init__(self, photons: Photons, workers: int = 1, structure: str = "kdtree",
                 cell: float | None = None, rows: np.ndarray | None = None,
                 power_scale: np.ndarray | None = None, keep_source: bool = False):
        if structure not in STRUCTURES:
            raise ValueError(f"PhotonMap: structure must be one of {', '.join(STRUCTURES)}, "
                             f"got {structure!r}")
        if structure == "hashgrid" and cell is None:
            raise ValueError("PhotonMap: the hash grid needs a cell size (cell=radius)")
        self.workers = workers
        self.structure = structure
        self.tree = None
        # "precomputed": k-NN estimates through engine/causticcache.py (the caustic map,
        # settings.caustic_lookup); its per-parameter estimates live in `precomputed`,
        # shared with serial() views.
        self.lookup = "knn"
        self.precomputed = {}
        position = photons.position if rows is None else np.take(photons.position, rows,
                                                                   axis=0)
        if not len(position):
            self.photons = photons if rows is None else photons.take(rows)
            return
        if structure == "kdtree":
            self.tree = kdtree.KdTree(position, workers=workers)
        else:
            self.tree = hashgrid.HashGrid(position, cell)
        order = self.tree.order
        self.tree.order = None  # the photons are permuted below; the map needs no order
        source = order if rows is None else np.take(rows, order)
        if keep_source:
            self.source = source
        power = np.take(photons.power, source, axis=0)
        if power_scale is not None:
            if power.dtype == np.uint8:  # a compact map's photons: scaled as float32
                power = photonlayout.decode_power(power, np.float32)
            power *= np.take(np.asarray(power_scale, np.float32), order)[:, None]
        self.photons = Photons(self.tree.position, power, *(
            np.take(a, source, axis=0) for a in (photons.direction, photons.normal,
                                                 photons.kind)), photons.emitted,
            surface=None if photons.surface is None else np.take(photons.surface, source),
            blur_pdf=None if photons.blur_pdf is None else np.take(photons.blur_pdf, source),
            # (|L|_1 is the path's, not the flux's: power_scale leaves it; photonclamp)
            radiance=None if photons.radiance is None else np.take(photons.radiance, source))
        if photonlayout.COMPACT:
            # Direction, normal and power in 12 B instead of 36 (engine/photonlayout.py:
            # the kernels decode each photon they read).
            photonlayout.compact(self.photons)

    def __len__(self):
        return len(self.photons)

    @property
    def nbytes(self) -> int:
        """Bytes held by the map: the photons plus the structure's index arrays."""
        pre = sum(e.nbytes for e in getattr(self, "precomputed", {}).values())
        if self.tree is None:
            return self.photons.nbytes + pre
        return self.photons.nbytes + self.tree.nbytes - self.tree.position.nbytes + pre

    def surface_ids(self) -> np.ndarray:
        """(N,) int32 the photons' surfaces for the estimate kernels: Photons.surface, or
        all -1 (unknown: kept on the map) where the photons have none."""
        return surface_ids(self.photons)

    def serial(self) -> "PhotonMap":
        """The same map, queried on the calling thread only (the caller runs chunks on
        threads already, engine/parallel.py)."""
        view = copy.copy(self)
        view.workers = 1
        return view

    def _arrays(self):
        """(kind, position, nodes, start, grid) for the kernels; unused ones are empty.
        nodes: the kd-tree's (axis, split, leaf) arrays (KdTree.nodes).
        grid is the hash grid's (origin, cell size), or the kd-tree's bounds."""
        t = self.tree
        if self.structure == "kdtree":
            return KDTREE, t.position, t.nodes, _NO_START, t.bounds
        return HASHGRID, t.position, _NO_NODES, t.start, t.grid

    def irradiance(self, p: np.ndarray, n: np.ndarray, radius: float, k: int,
                   min_photons: int, estimator: str, return_boundary: bool = False,
                   r_floor: np.ndarray | None = None, should_cancel=None,
                   masks: np.ndarray | None = None, hidden=None, read=None, surface=None):
        """knn_irradiance's answer; with self.lookup == "precomputed" (a kd-tree map, k-NN
        estimators, no masks, no read lists) through engine/causticcache.py's estimates
        at the photons (the k-NN rows where those cannot answer)."""
        if (getattr(self, "lookup", "knn") == "precomputed" and masks is None
                and read is None
                and self.tree is not None and self.structure == "kdtree"
                and estimator in ("knn_simpson", "knn_cone")
                and len(p) and radius > 0 and len(self.photons) >= min_photons):
            from . import causticcache
            return causticcache.lookup(self, p, n, radius, k, min_photons, estimator,
                                       return_boundary, r_floor, should_cancel, surface)
        return self.knn_irradiance(p, n, radius, k, min_photons, estimator, return_boundary,
                                   r_floor, should_cancel, masks, hidden, read, surface)

    def knn_irradiance(self, p: np.ndarray, n: np.ndarray, radius: float, k: int,
                       min_photons: int, estimator: str, return_boundary: bool = False,
                       r_floor: np.ndarray | None = None, should_cancel=None,
                       masks: np.ndarray | None = None, hidden=None, read=None,
                       surface=None):
        """Irradiance estimate E (W/m^2, (M,3) float64) at points p (M,3) with unit normals
        n (M,3) facing the viewer.
        surface: (M,) int, the object id of each point's surface (Geometry.object_id of
        the hit triangle; < 0: unknown), or None: a photon counts only where it lies on the
        query's own surface or on another continuing its plane (engine/samesurface.py),
        where the map's photons know theirs (Photons.surface); else the normal test
        alone decides.
        return_boundary: also return, per point, whether the estimate's disc is not whole:
        photons of another surface lay inside it (a corner or contact) or its photons lie
        off to one side (an open edge), or it had too few photons for an estimate (0).
        There the estimate is biased dark.
        r_floor: per point, the smallest k-NN radius (a camera sample's pixel footprint):
        a focus is spread over at least that disc instead of a point.
        masks: (S, N) bool over self.photons, or the same as bits ((S, ceil(N / 8)) uint8,
        pack_masks): also return, last, (S, M, 3) float64 the
        irradiance of each mask's photons alone from the same search (the others' power
        counted as 0): the bits of S more calls on maps whose power arrays zero the
        other photons, for about the cost of one (GatherMap's subsets).
        hidden: with masks, (starts (M+1,) int64, photons (H,) int64): row i's photons
        photons[starts[i]:starts[i+1]] (ascending) are left out of every mask for row i
        alone (engine/photonvisibility.py: the photons a row cannot see), the bits of
        one call a row with those photons cleared in its masks, in one call.
        read: (count (M,) int64, photons (M, W) int64), filled with each row's read
        photons: the accepted photons inside its estimate's disc (distance <= rk, the
        k-NN radius or the search radius), in the order the sum reads them, which are
        all the photons whose power the estimate can weigh (the others' weight is 0):
        count[i] of them, the first min(count[i], W) into photons[i] (count[i] > W: the
        list is cut; ask again with a wider W); count[i] = 0 for a row without an
        estimate (fewer than min_photons). engine/photonvisibility.py traces these.
        read may also hold (weight (M, W) float64, factor (M,) float64): each read
        photon's kernel weight (1/m^2; 1.0 for a floored focus, whose estimate is its
        photons' plain sum) and each row's factor, so that the masked estimate of a row
        with an estimate (count[i] >= 1) whose list is whole is exactly
        (sum over its read photons kept, in order, of weight x float64(power)) x factor,
        the bits of masks / hidden without a second search (photonvisibility).

        Memory is the output plus a fixed scratch per kernel call (MAX_WIDEN_K and
        SCAN_BUDGET entries; a widening row whose sphere holds more than MAX_WIDEN_K
        photons up to 2 MB more while it runs), however far a query widens.
        Raises ValueError for an unknown estimator; should_cancel() is asked between
        blocks of rows, and the kernel polls its stop flag (parallel.stop_flag_of:
        should_cancel's StopFlag, or that of the chunk running on this thread) every
        STOP_ROWS rows; raises parallel.Cancelled."""
        code = ESTIMATOR_CODES.get(estimator)
        if code is None:
            raise ValueError(f"estimator must be one of {', '.join(ESTIMATOR_CODES)}, "
                             f"got {estimator!r}")
        m = len(p)
        out = np.zeros((m, 3))
        boundary = np.ones(m, bool)  # rows with no estimate keep True
        result = (out, boundary) if return_boundary else out
        if masks is None:
            masks, masked = _NO_MASKS, _NO_MASKED
        else:
            masks = np.asarray(masks)
            bits = (len(self.photons) + 7) // 8
            if masks.dtype != np.uint8:
                if masks.ndim != 2 or masks.shape[1] != len(self.photons):
                    raise ValueError(f"irradiance: masks must have shape "
                                     f"(S, {len(self.photons)}), got {masks.shape}")
                masks = pack_masks(masks)
            elif masks.ndim != 2 or masks.shape[1] != bits:
                raise ValueError(f"irradiance: packed masks (uint8, pack_masks) must have "
                                 f"shape (S, {bits}), got {masks.shape}")
            masks = np.ascontiguousarray(masks)
            masked = np.zeros((len(masks), m, 3))
            result = (*result, masked) if return_boundary else (out, masked)
        if hidden is None or not len(masks):
            hid_start, hid_photon = _NO_HIDDEN
        else:
            hid_start = np.ascontiguousarray(hidden[0], dtype=np.int64)
            hid_photon = np.ascontiguousarray(hidden[1], dtype=np.int64)
            if hid_start.shape != (m + 1,):
                raise ValueError(f"irradiance: hidden starts must have shape ({m + 1},), "
                                 f"got {hid_start.shape}")
        if read is None:
            read_count, read_photon = _NO_READ
            read_weight, read_factor = _NO_WEIGHT
        else:
            read_count, read_photon = read[:2]
            read_weight, read_factor = read[2:] if len(read) > 2 else _NO_WEIGHT
            if len(read) > 2 and (read_weight.shape != read_photon.shape
                                  or read_factor.shape != (m,)
                                  or read_weight.dtype != np.float64
                                  or read_factor.dtype != np.float64
                                  or not read_weight.flags.c_contiguous):
                raise ValueError(f"irradiance: read's weight and factor must be float64 "
                                 f"arrays of shapes {read_photon.shape} and ({m},), "
                                 f"C-contiguous")
            if (read_count.shape != (m,) or read_photon.ndim != 2
                    or read_photon.shape[0] != m or read_count.dtype != np.int64
                    or read_photon.dtype != np.int64 or not read_photon.flags.c_contiguous):
                raise ValueError(f"irradiance: read must be int64 arrays of shapes ({m},) "
                                 f"and ({m}, W), C-contiguous")
            read_count[:] = 0
        if self.tree is None or m == 0 or radius <= 0 or len(self.photons) < min_photons:
            return result
        surf = self.surface_ids()
        if surface is None or self.photons.surface is None:
            qsurf = NO_SURFACE
        else:
            qsurf = query_surfaces(surface, m)
        p = np.ascontiguousarray(p, dtype=np.float64)
        n = np.ascontiguousarray(n, dtype=np.float64)
        floor = (np.zeros(0) if r_floor is None
                 else np.ascontiguousarray(np.broadcast_to(r_floor, (m,)), dtype=np.float64))
        # Rows taken in Morton order (morton_order: the tree stays in cache); each row
        # writes its own answer, so the result does not depend on the order.
        order = morton_order(p)
        kind, pos, nodes, start, grid = self._arrays()
        ph = self.photons
        threads = self.workers if m > BLOCK_ROWS else 1
        rows = BLOCK_ROWS if threads > 1 else m

        def job(a, stop):
            # The kernel polls the stop flag every STOP_ROWS rows: a cancel ends a
            # block of thousands of estimates at once (issue 19).
            flag = stop.array if isinstance(stop, StopFlag) else stop_array(should_cancel)
            b = min(a + rows, m)
            _irradiance_rows(kind, pos, nodes, start, grid, ph.power, ph.direction, ph.normal,
                             surf, p, n, qsurf, floor, order[a:b], float(radius), int(k),
                             int(min_photons),
                             code, bool(return_boundary), out, boundary, flag, masks, masked,
                             hid_start, hid_photon, read_count, read_photon, read_weight,
                             read_factor)
            if flag[0]:
                raise Cancelled()
            return None

        for _ in ordered_map(job, range(0, m, rows), threads, should_cancel):
            pass
        return result


def pack_masks(masks: np.ndarray) -> np.ndarray:
    """(S, ceil(N / 8)) uint8: the masks (S, N) bool as bits, photon j of mask s bit j & 7
    of byte j >> 3 (np.packbits, bitorder "little"): the layout _irradiance_rows reads
    (1/8 B a photon and mask; a lazy GatherMap keeps its masks so, docs/performance.md
    "mem48"). unpack_masks(bits, N) gives the masks back."""
    masks = np.asarray(masks, dtype=np.bool_)
    if masks.ndim != 2:
        raise ValueError(f"pack_masks: masks must be (S, N), got shape {masks.shape}")
    return np.packbits(masks, axis=1, bitorder="little")


def unpack_masks(bits: np.ndarray, n: int) -> np.ndarray:
    """(S, n) bool: the masks pack_masks made bits (S, ceil(n / 8)) uint8 of."""
    return np.unpackbits(bits, axis=1, count=n, bitorder="little").view(np.bool_)


_NO_NODES = (np.zeros(0, np.uint8), np.zeros(0, np.float32), np.zeros(1, np.int64))
_NO_MASKS = np.zeros((0, 0), np.uint8)
_NO_MASKED = np.zeros((0, 0, 3))
_NO_HIDDEN = (np.zeros(0, np.int64), np.zeros(0, np.int64))
_NO_READ = (np.zeros(0, np.int64), np.zeros((0, 0), np.int64))
_NO_WEIGHT = (np.zeros((0, 0)), np.zeros(0))
_NO_START = np.zeros(1, np.int32)


@kernel
def _knn(kind, pos, nodes, start, grid, qx, qy, qz, kq, r2, d2, idx, buckets):
    if kind == KDTREE:
        return kdtree.knn(pos, nodes[0], nodes[1], nodes[2], qx, qy, qz, kq, r2, d2, idx)
    return hashgrid.knn(pos, start, grid, qx, qy, qz, kq, r2, d2, idx, buckets)


@kernel
def _ball(kind, pos, nodes, start, grid, qx, qy, qz, r2, out, cap, buckets):
    if kind == KDTREE:
        return kdtree.ball(pos, nodes[0], nodes[1], nodes[2], qx, qy, qz, r2, out, cap)
    return hashgrid.ball(pos, start, grid, qx, qy, qz, r2, out, cap, buckets)


@kernel
def _ball_count(kind, pos, nodes, start, grid, qx, qy, qz, r2, buckets):
    if kind == KDTREE:
        return kdtree.ball_count(pos, nodes[0], nodes[1], nodes[2], grid, qx, qy, qz, r2)
    return hashgrid.ball_count(pos, start, grid, qx, qy, qz, r2, buckets)


@kernel
def _accepted(direction, normal, surface, pos, j, nx, ny, nz, qs, qx, qy, qz):
    """(accepted, other_surface) for photon j at a query at (qx, qy, qz) with float32
    normal (nx, ny, nz) on surface qs (object id, < 0: unknown): it arrived from the front
    (d.N < 0) and lies on a surface facing the same way, the query's own or one
    continuing its plane (samesurface.same_surface's rule). surface: (P,) int32, -1 where
    unknown (PhotonMap.surface_ids: never empty). The photon's vectors are read along
    their axes (photonlayout.read_axis: a compact map's octahedral code unnormalised) and
    the cosines compared as such (cos_below, cos_at_most): a float32 map's tests are the
    same expressions as before (docs/performance.md "compact50")."""
    d0, d1, d2, _ = read_axis(direction, j)  # (photonlayout: float32 or octahedral)
    m0, m1, m2, mw = read_axis(normal, j)
    cos_in = -(d0 * nx + d1 * ny + d2 * nz)  # (its sign: any positive scale keeps it)
    agree = m0 * nx + m1 * ny + m2 * nz
    # samesurface.same_surface without branches: the loops over a row's photons stay
    # vectorised (a branch calling continues_plane cost the k-NN rows 1.6x, even where
    # it was never taken).
    off = off_plane(pos, j, qx, qy, qz, nx, ny, nz)
    sj = surface[j]
    foreign = (sj != qs) & (sj >= 0) & (qs >= 0) & (
        cos_below(normal, agree, mw, COPLANAR_COS) | off)
    other = cos_at_most(normal, agree, mw, NORMAL_AGREEMENT) | foreign
    return (cos_in > 0) & (not other), other


@kernel
def _cos_in(direction, j, nx, ny, nz):
    """The cosine of photon j's incoming direction with the query's float32 normal (nx,
    ny, nz): the classic estimator's weight (_accepted tests only its sign)."""
    d0, d1, d2 = read_vector(direction, j)  # (photonlayout: float32 or octahedral)
    return -(d0 * nx + d1 * ny + d2 * nz)


@kernel
def _fill_accepted(direction, normal, surface, pos, idx, lo, hi, nx, ny, nz, qs, qx, qy,
                   qz, row_ok, row_other):
    """_accepted of photons idx[lo:hi] into row_ok / row_other[lo:hi]; returns how many
    of idx[:hi] are accepted (row_ok[:lo] already filled). A k-NN row tests its photons
    once, for its widening test and its sums alike."""
    for j in range(lo, hi):
        row_ok[j], row_other[j] = _accepted(direction, normal, surface, pos, idx[j], nx, ny,
                                            nz, qs, qx, qy, qz)
    acc = 0
    for j in range(hi):
        acc += row_ok[j]
    return acc


@kernel
def _back_face(normal, pos, j, nx, ny, nz, qx, qy, qz):
    """Whether photon j is on the back face of a slab thinner than the disc: it faces the
    opposite way (normal . n < -COPLANAR_COS) and lies behind the query's plane, off it
    (samesurface.off_plane). Such photons are the other side of a wall or table top (a
    room's Solidify walls 0.1 m thick, lit by the sky outside, inside a 0.13 m disc on
    the dim wall within): they cut nothing off the disc's own side, so they do not mark
    its estimate as a corner or contact (a boundary). Flagged, 61 % of a window-lit
    room's final-gather lookups read such a point and gathered again (interior41,
    docs/performance.md). A photon on the back of a zero-thickness sheet lies on the
    plane, not behind it, and still counts; a ball smaller than the disc still has
    photons of other directions that flag it."""
    m0, m1, m2, mw = read_axis(normal, j)  # (photonlayout: _accepted's reading)
    agree = m0 * nx + m1 * ny + m2 * nz
    h = ((np.float64(pos[j, 0]) - qx) * nx + (np.float64(pos[j, 1]) - qy) * ny
         + (np.float64(pos[j, 2]) - qz) * nz)
    return cos_below(normal, agree, mw, -COPLANAR_COS) and h < 0.0 and \
        off_plane(pos, j, qx, qy, qz, nx, ny, nz)


@kernel
def _count_accepted(direction, normal, surface, pos, idx, cnt, nx, ny, nz, qs, qx, qy, qz):
    acc = 0
    for j in range(cnt):
        if _accepted(direction, normal, surface, pos, idx[j], nx, ny, nz, qs, qx, qy, qz)[0]:
            acc += 1
    return acc


@kernel
def _accepted_at_least(direction, normal, surface, pos, idx, cnt, nx, ny, nz, qs, qx, qy, qz,
                       need):
    """Whether at least `need` of photons idx[:cnt] are accepted (_accepted): stops
    counting once they are."""
    acc = 0
    for j in range(cnt):
        if acc >= need:
            return True
        if _accepted(direction, normal, surface, pos, idx[j], nx, ny, nz, qs, qx, qy, qz)[0]:
            acc += 1
    return acc >= need


@kernel
def _widen_listed(pos, scan, nb, qx, qy, qz, r2, widest, src_d2, hist, d2, idx):
    """A widening k-NN row's answer from the sphere a scan listed whole: scan[:nb], the
    photons with squared distance <= r2 (kdtree.ball / hashgrid.ball; nb <= SCAN_BUDGET).
    Into d2 / idx (increasing distance, float64 squared distances from the float32
    positions, as the searches compute them): the `widest` nearest of those strictly
    inside r2 (the k-NN bound), or all of them if fewer. Returns their count, or -1
    where the caller must take the heap search instead (kdtree.knn / hashgrid.knn).

    The answer is bitwise the heap's, without its ~log2(widest) sift steps a photon
    (docs/performance.md "knn"): the distances are listed, then ordered by
    kdtree.nearest_first (a histogram partial order). Where the distances are all
    distinct the heap's order is the only increasing one, so both agree. Equal distances
    (photons at one position: a focus) are ordered by the heap in a way that depends on
    its insertion order, which no sort reproduces, so such rows take the heap: nb <=
    widest the heap over scan's order (this kernel, as the estimator did before), nb >
    widest return -1 (the caller's kd-tree / grid heap search, whose order differs).
    scan[:found] is compacted in place to the photons strictly inside r2 (their order
    kept). Scratch: src_d2 (>= widest), hist (>= widest + 1); d2 / idx hold at least widest
    entries. A sphere of more than widest photons makes its own (4 x 8 B x nb, at most 2 MB
    while the row runs: the estimator's fixed scratch stays small, tests/
    test_photon_lookup.py test_widening_has_a_fixed_memory_budget)."""
    if nb > widest:
        src_d2 = np.empty(nb, np.float64)
        hist = np.empty(nb + 1, np.int64)
    found = 0
    for j in range(nb):
        ph = scan[j]
        dx = qx - np.float64(pos[ph, 0])
        dy = qy - np.float64(pos[ph, 1])
        dz = qz - np.float64(pos[ph, 2])
        dd = dx * dx + dy * dy + dz * dz
        if dd < r2:  # the k-NN query's bound is strict
            src_d2[found] = dd
            scan[found] = ph  # found <= j: an entry not yet read
            found += 1
    if found <= widest:
        kdtree.nearest_first(src_d2, scan, found, found, r2, d2, idx, hist)
        if kdtree.unique_nearest(d2, found, found) or found == 0:
            return found
        if nb > widest:
            return -1
        # Equal distances: the heap, fed in scan's order as it always was.
        count = 0
        for j in range(found):
            count = kdtree.heap_insert(d2, idx, count, widest, src_d2[j], scan[j])
        kdtree.heap_sort(d2, idx, count, widest)
        return count
    # More than widest inside: the widest nearest first, then a check that they are one
    # set in one order (strictly increasing, strictly nearer than the rest).
    out_d2 = np.empty(found, np.float64)
    out_idx = np.empty(found, np.int64)
    kdtree.nearest_first(src_d2, scan, found, widest, r2, out_d2, out_idx, hist)
    if not kdtree.unique_nearest(out_d2, found, widest):
        return -1
    for j in range(widest):
        d2[j] = out_d2[j]
        idx[j] = out_idx[j]
    return widest


@kernel
def _block_candidates(pos, nodes, p, rows, r, radius, span, cand, cx, cy, cz, search):
    """The candidates of the block of k-NN rows starting at rows[r] (engine/kdtree.py
    order): (end, count). end: the block's end in rows (up to CAND_ROWS rows whose
    points' box has a half diagonal of at most span x radius: CAND_SPAN for the rows'
    search spheres, SEED_SPAN for their seeded ones); count: the photons
    within radius of the box (a superset: the sphere about the box's centre of radius
    radius + the half diagonal, with a margin) into cand[:count] and their float64
    coordinates into cx, cy, cz, or -1 (fewer than CAND_MIN_ROWS rows, or search False:
    the rows search the tree) or -2 (more than CAND_CAP: the same)."""
    m = rows.shape[0]
    i = rows[r]
    lx, ly, lz = p[i, 0], p[i, 1], p[i, 2]
    hx, hy, hz = lx, ly, lz
    lim = (span * radius) ** 2
    e = r + 1
    while e < m and e - r < CAND_ROWS:
        j = rows[e]
        ax, ay, az = min(lx, p[j, 0]), min(ly, p[j, 1]), min(lz, p[j, 2])
        bx, by, bz = max(hx, p[j, 0]), max(hy, p[j, 1]), max(hz, p[j, 2])
        h2 = 0.25 * ((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2)
        if not h2 <= lim:
            break
        lx, ly, lz, hx, hy, hz = ax, ay, az, bx, by, bz
        e += 1
    if e - r < CAND_MIN_ROWS or not search:
        return e, -1
    ox, oy, oz = 0.5 * (lx + hx), 0.5 * (ly + hy), 0.5 * (lz + hz)
    h = 0.5 * math.sqrt((hx - lx) ** 2 + (hy - ly) ** 2 + (hz - lz) ** 2)
    # The margin covers the rounding of every row's float64 distances (relative 1e-7 of
    # the reach, and 1e-9 of the coordinates' size for rows far from the origin).
    reach = (radius + h) * (1.0 + 1e-7) + 1e-9 * max(abs(ox), abs(oy), abs(oz))
    nc = kdtree.ball(pos, nodes[0], nodes[1], nodes[2], ox, oy, oz, reach * reach, cand,
                     CAND_CAP)
    if nc > CAND_CAP:
        return e, -2
    for j in range(nc):
        ph = cand[j]
        cx[j] = np.float64(pos[ph, 0])
        cy[j] = np.float64(pos[ph, 1])
        cz[j] = np.float64(pos[ph, 2])
    return e, nc


@kernel
def _list_candidates(cand, cx, cy, cz, nc, qx, qy, qz, r2, d2, idx, cap, tmp):
    """kdtree.ball_d2's answer (the points with squared distance < r2, their distances;
    cap + 1 when more than cap) from a block's candidates cand[:nc] (_block_candidates),
    in the candidates' order: the same set and distances, not necessarily the same
    order. tmp: scratch of at least nc; d2 / idx beyond count (up to cap) may be
    overwritten."""
    if nc <= cap:
        # The distances in one loop (vectorised), then the inside ones kept without a
        # branch: about half the candidates lie inside a row's sphere, and a branch on
        # each mispredicts (1.9 against 0.45 us for 500 candidates; docs/performance.md
        # "caustickernel"). The same float64 operations: the same distances.
        for j in range(nc):
            dx = qx - cx[j]
            dy = qy - cy[j]
            dz = qz - cz[j]
            tmp[j] = dx * dx + dy * dy + dz * dz
        count = 0
        for j in range(nc):
            dist2 = tmp[j]
            d2[count] = dist2
            idx[count] = cand[j]
            count += dist2 < r2
        return count
    count = 0
    for j in range(nc):
        dx = qx - cx[j]
        dy = qy - cy[j]
        dz = qz - cz[j]
        dist2 = dx * dx + dy * dy + dz * dz
        if dist2 < r2:
            if count == cap:
                return cap + 1
            d2[count] = dist2
            idx[count] = cand[j]
            count += 1
    return count


@kernel
def _irradiance_rows(kind, pos, nodes, start, grid, power, direction, normal, surface, p, n,
                     qsurf, r_floor, rows, radius, k, min_photons, code, want_boundary, out,
                     boundary, stop,
                     masks, masked, hid_start, hid_photon, read_count, read_photon,
                     read_weight, read_factor):
    """The estimators of this module's docstring for the rows `rows` of p / n (and
    r_floor, if not empty) into the same rows of out (E) and boundary. Scratch:
    MAX_WIDEN_K (or k) neighbours, reused by every row. stop: (1,) uint8, polled every
    STOP_ROWS rows; once nonzero the kernel returns with rows left unwritten.
    masks: (S, ceil(P / 8)) uint8, S masks over the photons as bits (photon j of mask s:
    bit j & 7 of masks[s, j >> 3], np.packbits' bitorder="little": 1/8 B a photon and
    mask; pack_masks), masked: (S, M, 3) float64: row i's estimate
    from mask s's photons alone into masked[s, i] (the other photons' power counted as
    0; the same neighbours, disc and terms in the same order as an estimate whose power
    array zeroes them: the same bits). S = 0: none. hid_start (M+1,) / hid_photon (H,)
    int64, or hid_start empty: row i's masks also leave out the photons
    hid_photon[hid_start[i]:hid_start[i+1]] (ascending; found by bisection).
    read_count (M,) / read_photon (M, W) int64, or read_count empty: row i's read photons
    (the accepted ones inside rk, in the sum's order: PhotonMap.knn_irradiance's read)
    into read_photon[i, :W], their number into read_count[i] (0 without an estimate);
    read_weight (M, W) / read_factor (M,) float64, or read_weight empty: their weights
    and the row's factor (PhotonMap.knn_irradiance's read).
    surface (P,) int32 the photons' surfaces (-1: unknown) and qsurf (M,) int32 the
    queries' (empty: unknown): _accepted's surface test."""
    P = pos.shape[0]
    test_surface = qsurf.shape[0] > 0
    S = masks.shape[0]
    rec = read_count.shape[0] > 0
    rec_w = rec and read_weight.shape[0] > 0
    W = read_photon.shape[1]
    ms = np.zeros((S, 6))  # per mask: e0, e1, e2, a0, a1, a2 of the row
    cap = max(min(max(k, MAX_WIDEN_K, MAX_CLASSIC_K), P), 1)
    d2 = np.empty(cap, np.float64)
    idx = np.empty(cap, np.int64)
    scan = np.empty(SCAN_BUDGET + 1, np.int64)
    # The floored focus disc (below) may exceed radius where 1e-6 |p| does.
    big = 0.0
    for r in range(rows.shape[0]):
        i = rows[r]
        big = max(big, abs(p[i, 0]), abs(p[i, 1]), abs(p[i, 2]))
    buckets = np.empty(hashgrid.cells_spanned(grid, max(radius, 1e-6 * big))
                       if kind == HASHGRID else 0, np.int64)
    r2 = radius * radius
    knn = code >= KNN_SIMPSON
    list_cap = min(cap, LIST_FACTOR * max(k, 1))
    list_d2 = np.empty(list_cap, np.float64)  # a listed sphere, before nearest_first
    list_idx = np.empty(list_cap, np.int64)
    hist = np.empty(list_cap + 1, np.int64)
    prev_kth = -1.0  # the previous k-NN row's kq-th squared distance (a seed; -1: none)
    # _widen_listed's scratch for spheres of at most `widest` photons (made here, not at
    # a call's first widening: arrays rebound inside the row loop cost every row ~5-8 %,
    # docs/performance.md "knn").
    wide_d2 = np.empty(cap, np.float64)
    wide_hist = np.empty(cap + 1, np.int64)
    # A listed sphere's accepted photons, in the listing's order (a widening row's
    # estimate over its whole sphere sums only these: below).
    acc_d2 = np.empty(list_cap, np.float64)
    acc_idx = np.empty(list_cap, np.int64)
    # The row's photons' _accepted answers (accepted, other surface), computed once for
    # the widening test, the k-th accepted search and the sums (each read them: up to
    # three times the work); `known`: how many of idx's are in (_fill_accepted).
    row_ok = np.empty(cap, np.bool_)
    row_other = np.empty(cap, np.bool_)
    # The current block's candidates (_block_candidates): rows before blk_end use them
    # where nc >= 0.
    use_cand = knn and kind == KDTREE
    cand = np.empty(CAND_CAP + 1 if use_cand else 0, np.int64)
    cand_x = np.empty(cand.shape[0], np.float64)
    cand_y = np.empty(cand.shape[0], np.float64)
    cand_z = np.empty(cand.shape[0], np.float64)
    cand_d2 = np.empty(cand.shape[0], np.float64)  # _list_candidates' scratch
    blk_end = 0
    nc = -1
    # The widest row sphere (squared radius) the block's candidates hold whole: r2 for a
    # block of search spheres, a seeded sphere's for a block of those (SEED_REACH).
    cand_r2 = 0.0
    # After a block with too many candidates (a dense map) the next `skip` blocks search
    # the tree without trying (1, 2, 4 ... CAND_BACKOFF blocks while they keep
    # overflowing): a dense map pays few wasted searches.
    skip = 0
    backoff = 1
    for r in range(rows.shape[0]):
        if r % STOP_ROWS == 0 and stop[0]:
            return
        i = rows[r]
        qx, qy, qz = p[i, 0], p[i, 1], p[i, 2]
        nx, ny, nz = np.float32(n[i, 0]), np.float32(n[i, 1]), np.float32(n[i, 2])
        qs = np.int64(qsurf[i]) if test_surface else np.int64(-1)
        out[i, 0] = out[i, 1] = out[i, 2] = 0.0
        for s in range(S):
            masked[s, i, 0] = masked[s, i, 1] = masked[s, i, 2] = 0.0
            for c in range(6):
                ms[s, c] = 0.0
        boundary[i] = True
        if rec:
            read_count[i] = 0
        scale = 1.0
        r_simpson = radius  # the radius estimator's kernel support
        only_accepted = False  # d2 / idx hold the listed sphere's accepted photons alone
        known = 0  # row_ok / row_other hold idx[:known]'s answers
        if knn:
            if use_cand and r >= blk_end:
                blk_end, nc = _block_candidates(pos, nodes, p, rows, r, radius, CAND_SPAN,
                                                cand, cand_x, cand_y, cand_z, skip == 0)
                if skip > 0:
                    skip -= 1
                elif nc == -2:
                    skip = backoff
                    backoff = min(2 * backoff, CAND_BACKOFF)
                elif nc >= 0:
                    backoff = 1
                cand_r2 = r2
                if nc < 0 and prev_kth > 0.0 and prev_kth * SEED_GROWTH < r2:
                    # Too many candidates for the search spheres (or backed off): a block
                    # of seeded spheres instead, ending where its rows spread wider.
                    seed_r = SEED_REACH * math.sqrt(prev_kth * SEED_GROWTH)
                    end, got = _block_candidates(pos, nodes, p, rows, r, seed_r, SEED_SPAN,
                                                 cand, cand_x, cand_y, cand_z, True)
                    if got >= 0:
                        blk_end, nc, cand_r2 = end, got, seed_r * seed_r
            # Candidates that hold the rows' whole search spheres; (seed_cand) or at least
            # seeded spheres no wider than cand_r2.
            seed_cand = use_cand and nc >= 0
            from_cand = seed_cand and cand_r2 == r2
            kq = min(k, P)
            widest = min(P, MAX_WIDEN_K)
            # A sphere holding at most list_cap photons is listed whole (ball_d2) and its
            # kq nearest put first (nearest_first): the knn answer without a heap, which
            # costs a sparse map's estimate most (kdtree.knn's heap steps). A fuller
            # sphere takes the heap search, bounded by the kq-th distance among the
            # photons listed so far. Rows choose by their own sphere, never by another
            # row's, so the answer does not depend on the rows' order or blocks (the
            # seeded sphere below is taken only where it proves the same answer; a
            # block's candidates list the same photons as the tree, their order taken
            # only where it cannot matter: no equal distances).
            listed = -1
            seeded = False
            if kind == KDTREE and prev_kth > 0.0 and prev_kth * SEED_GROWTH < r2:
                # First a smaller sphere, sized by the previous row's kq-th distance (rows
                # come in Morton order: a neighbour of similar density). When it holds at
                # least kq photons whose kq nearest are strictly ordered and strictly
                # nearer than the rest (kdtree.unique_nearest), those are the kq nearest
                # of the whole sphere in the only order any path can give them (either
                # path below sorts by the same float64 distances): the same d2 / idx
                # prefix, from a sphere listing ~1/3 of the photons (the gather map's
                # estimates, docs/performance.md "Tenth slice: lookups"). Rows that would widen
                # take the path below (the widening reads the whole sphere).
                b2 = prev_kth * SEED_GROWTH
                if seed_cand and b2 <= cand_r2:  # (the kq nearest are checked free of ties)
                    got = _list_candidates(cand, cand_x, cand_y, cand_z, nc, qx, qy, qz, b2,
                                           list_d2, list_idx, list_cap, cand_d2)
                else:
                    got = kdtree.ball_d2(pos, nodes[0], nodes[1], nodes[2], qx, qy, qz, b2,
                                         list_d2, list_idx, list_cap)
                if kq <= got <= list_cap:
                    kdtree.nearest_first(list_d2, list_idx, got, kq, b2, d2, idx, hist)
                    if kdtree.unique_nearest(d2, got, kq):
                        if kq >= widest:
                            seeded = True
                        else:
                            seeded = _fill_accepted(direction, normal, surface, pos, idx, 0,
                                                    kq, nx, ny, nz, qs, qx, qy, qz, row_ok,
                                                    row_other) >= k // 2
                            known = kq if seeded else 0
            if seeded:
                cnt = kq
            else:
                if from_cand:
                    listed = _list_candidates(cand, cand_x, cand_y, cand_z, nc, qx, qy, qz,
                                              r2, list_d2, list_idx, list_cap, cand_d2)
                    if listed <= list_cap:
                        cnt = min(kq, listed)
                        kdtree.nearest_first(list_d2, list_idx, listed, cnt, r2, d2, idx,
                                             hist)
                        # Equal distances keep the listing's order: the tree's own
                        # listing decides them, as it always did.
                        from_cand = cnt == 0 or kdtree.unique_nearest(d2, listed, cnt)
                    else:
                        from_cand = False
                    if not from_cand:
                        listed = kdtree.ball_d2(pos, nodes[0], nodes[1], nodes[2], qx, qy,
                                                qz, r2, list_d2, list_idx, list_cap)
                elif kind == KDTREE:
                    listed = kdtree.ball_d2(pos, nodes[0], nodes[1], nodes[2], qx, qy, qz,
                                            r2, list_d2, list_idx, list_cap)
                if from_cand:
                    pass  # d2 / idx hold the kq nearest (or the whole sphere) in order
                elif 0 <= listed <= list_cap:
                    cnt = min(kq, listed)
                    kdtree.nearest_first(list_d2, list_idx, listed, cnt, r2, d2, idx, hist)
                else:
                    bound = r2
                    if listed > list_cap and list_cap >= kq:
                        # kq photons lie within the kq-th listed distance: a bound (with the
                        # margin of _seed_bound) that the kq nearest all pass.
                        kdtree.nearest_first(list_d2, list_idx, list_cap, kq, r2, d2, idx, hist)
                        bound = min(r2, d2[kq - 1] * (1.0 + 1e-9) + 1e-300)
                    listed = -1
                    cnt = _knn(kind, pos, nodes, start, grid, qx, qy, qz, kq, bound, d2, idx,
                               buckets)
            prev_kth = d2[kq - 1] if cnt == kq else -1.0
            widen = False
            if not seeded and cnt == kq and kq < widest:
                known = cnt
                widen = _fill_accepted(direction, normal, surface, pos, idx, 0, cnt, nx, ny,
                                       nz, qs, qx, qy, qz, row_ok, row_other) < k // 2
            if widen:
                known = 0  # (d2 / idx change below)
                # Widen (x4 up to MAX_WIDEN_K) while fewer than k / 2 of the nearest are
                # accepted (a crowded neighbour surface). First, a row whose sphere holds
                # fewer than min_photons accepted photons has no estimate at any width
                # (a caustic query beside a wall lit only on its far side): one scan of
                # the sphere (at most SCAN_BUDGET photons) settles it.
                # The next row lists its whole sphere at once: beside a crowded surface
                # its seeded sphere would mostly fail the same test (Figure 7's
                # regathered points: 2 of 3 tries).
                prev_kth = -1.0
                if listed >= 0 and from_cand:
                    # The widening reads the listing's order only where distances are
                    # equal: a sphere whose distances all differ widens the same from any
                    # listing; else the tree's listing (the same photons) decides.
                    kdtree.nearest_first(list_d2, list_idx, listed, listed, r2, d2, idx, hist)
                    if not kdtree.unique_nearest(d2, listed, listed):
                        listed = kdtree.ball_d2(pos, nodes[0], nodes[1], nodes[2], qx, qy,
                                                qz, r2, list_d2, list_idx, list_cap)
                if listed >= 0:
                    # The sphere is listed already (list_d2 / list_idx, tree order; a row
                    # widens only where k < widest, and then listed <= list_cap <= widest).
                    if not _accepted_at_least(direction, normal, surface, pos, list_idx,
                                              listed, nx, ny, nz, qs, qx, qy, qz,
                                              min_photons):
                        continue
                    # The widening below, ordering only as far as it reads: the kq
                    # nearest of a step (nearest_first's prefix, taken where it is one set
                    # in one order: kdtree.unique_nearest, so any sort gives those bits),
                    # else the whole sphere (nearest_first of all, as before).
                    found = min(listed, widest)
                    step = kq  # the last width tried
                    ordered = 0 if WIDEN_ORDER_AS_READ else -1  # d2 / idx's ordered prefix
                    while ordered >= 0:
                        kq = min(4 * step, widest)
                        cnt = min(found, kq)
                        if cnt < kq or kq >= widest:
                            break
                        kdtree.nearest_first(list_d2, list_idx, listed, kq, r2, d2, idx, hist)
                        if not kdtree.unique_nearest(d2, listed, kq):
                            ordered = -1  # ties at the prefix's end
                            break
                        ordered = kq
                        if _count_accepted(direction, normal, surface, pos, idx, cnt, nx, ny,
                                           nz, qs, qx, qy, qz) >= k // 2:
                            break
                        step = kq
                    if ordered < 0:
                        kdtree.nearest_first(list_d2, list_idx, listed, found, r2, d2, idx,
                                             hist)
                    elif cnt < kq and found == listed:
                        # The estimate reads the whole sphere (cnt = found: not `full`, so
                        # not floored): only its accepted photons add to it, in increasing
                        # distance. Their own order is that of the whole sphere's where
                        # their distances are distinct (checked; else the whole sphere is
                        # ordered as before): the same sums, from ~n_acc of ~listed photons.
                        n_acc = 0
                        for j in range(listed):  # the accepted ones, in the listing's order
                            if _accepted(direction, normal, surface, pos, list_idx[j], nx, ny,
                                         nz, qs, qx, qy, qz)[0]:
                                acc_d2[n_acc] = list_d2[j]
                                acc_idx[n_acc] = list_idx[j]
                                n_acc += 1
                        kdtree.nearest_first(acc_d2, acc_idx, n_acc, n_acc, r2, d2, idx, hist)
                        only_accepted = True
                        for j in range(n_acc - 1):
                            if not d2[j] < d2[j + 1]:
                                only_accepted = False
                                break
                        if only_accepted:
                            cnt = n_acc
                        else:
                            kdtree.nearest_first(list_d2, list_idx, listed, found, r2, d2,
                                                 idx, hist)
                    elif ordered < cnt:
                        # The whole sphere read (kq >= widest), all of it in order.
                        kdtree.nearest_first(list_d2, list_idx, listed, found, r2, d2, idx,
                                             hist)
                else:
                    nb = _ball(kind, pos, nodes, start, grid, qx, qy, qz, r2, scan,
                               SCAN_BUDGET, buckets)
                    if nb <= SCAN_BUDGET and _count_accepted(
                            direction, normal, surface, pos, scan, nb, nx, ny, nz, qs, qx, qy,
                            qz) < min_photons:
                        continue
                    # Each wider query's result is a prefix of the widest one (increasing
                    # distance): one query, then the prefixes are tried in turn. A sphere
                    # the scan listed whole is that query's answer, ordered without a heap
                    # (_widen_listed); a sphere fuller than the scan, or one whose widest
                    # nearest tie with the rest, takes the heap search.
                    found = -1
                    if nb <= SCAN_BUDGET:
                        found = _widen_listed(pos, scan, nb, qx, qy, qz, r2, widest, wide_d2,
                                              wide_hist, d2, idx)
                    if found < 0:
                        found = _knn(kind, pos, nodes, start, grid, qx, qy, qz, widest, r2,
                                     d2, idx, buckets)
                    step = kq
                    ordered = -1
                if ordered < 0:
                    # The whole sphere in order (d2 / idx): its prefixes tried in turn.
                    kq = step
                    while True:
                        kq = min(4 * kq, widest)
                        cnt = min(found, kq)
                        if cnt < kq or kq >= widest:
                            break
                        if _count_accepted(direction, normal, surface, pos, idx, cnt, nx, ny,
                                           nz, qs, qx, qy, qz) >= k // 2:
                            break
        else:
            c = _ball_count(kind, pos, nodes, start, grid, qx, qy, qz, r2, buckets)
            if c < min_photons:
                continue  # too few photons in range: no estimate
            kq = min(c, MAX_CLASSIC_K)
            cnt = _knn(kind, pos, nodes, start, grid, qx, qy, qz, kq, r2, d2, idx, buckets)
            # A dense caustic can hold more than MAX_CLASSIC_K photons in the radius; the
            # nearest kq stand in for all of them. The box kernel scales by all / gathered;
            # the Simpson kernel cannot (the nearest photons weigh most: 1.8x too bright),
            # so it narrows to the gathered photons' disc, a k-NN estimate with k = kq.
            if c > kq:
                if code == RADIUS:
                    r_simpson = max(math.sqrt(d2[cnt - 1]), MIN_RADIUS_FRACTION * radius)
                else:
                    scale = c / kq
        # The row's estimate from its cnt nearest photons (d2 / idx, increasing distance),
        # here in the loop: a kernel called per row with its ~18 arrays paid ~0.25 us of
        # reference counting (docs/performance.md, "Eighth slice"). k-NN estimators use
        # the k nearest *accepted* photons (facing the query's surface).
        full = cnt == kq and not only_accepted  # stopped at kq photons: more may lie beyond
        rk = radius
        floored = False
        _fill_accepted(direction, normal, surface, pos, idx, known, cnt, nx, ny, nz, qs, qx,
                       qy, qz, row_ok, row_other)
        if code >= KNN_SIMPSON:
            # rk: distance to the k-th accepted photon; with fewer accepted (acc of them, at
            # least SPARSE_MIN_ACCEPTED), to the last accepted one: the k-NN estimate with
            # k = acc. The disc the query has seen (the max radius) is the right area only
            # where the accepted photons' surface fills it; a small object's does not (a
            # 5 cm ball's accepted cap is 1/24 of a 0.24 m disc: it read 0.1 of its light,
            # issue 14). With fewer, the disc the query has seen completely (its last
            # photon, or the max radius), as before.
            acc = 0
            last = -1
            for j in range(cnt):
                if row_ok[j]:
                    acc += 1
                    last = j
                    if acc == k:
                        break
            if acc >= min(k, SPARSE_MIN_ACCEPTED):
                rk = math.sqrt(d2[last])
            elif full:
                rk = math.sqrt(d2[cnt - 1])
            # k photons on (nearly) the query point, as a focusing lens makes: the k-th
            # distance is 0 and 1/rk^2 would be inf. Floor rk (MIN_RADIUS_FRACTION), and at a
            # resolution the float32 photon positions can represent.
            bq = max(abs(qx), abs(qy), abs(qz))
            r_min = max(1e-6 * bq, max(MIN_RADIUS_FRACTION * radius, 1e-15))
            if r_floor.shape[0]:
                r_min = max(r_min, min(r_floor[i], radius))
            floored = full and rk < r_min  # the floor disc may hold more than the kq fetched
            rk = max(rk, r_min)
        area = math.pi * rk * rk
        e0 = e1 = e2 = 0.0
        a0 = a1 = a2 = 0.0  # accepted power inside rk (the floored focus)
        count = 0
        fetched = 0
        other_inside = False
        c0 = c1 = c2 = np.float32(0.0)  # float32 sums of the accepted photons' offsets
        h_lo = h_hi = 0
        if S and hid_start.shape[0]:
            h_lo, h_hi = hid_start[i], hid_start[i + 1]
        for j in range(cnt):
            pj = idx[j]
            d = math.sqrt(d2[j])
            ok, other = row_ok[j], row_other[j]
            inside = d <= rk
            if inside:
                fetched += 1
                if other and not _back_face(normal, pos, pj, nx, ny, nz, qx, qy, qz):
                    other_inside = True
            if not ok:
                continue
            seen = True  # pj is not among the row's hidden photons
            if h_hi > h_lo:
                lo, hi = h_lo, h_hi
                while lo < hi:
                    mid = (lo + hi) >> 1
                    if hid_photon[mid] < pj:
                        lo = mid + 1
                    else:
                        hi = mid
                seen = not (lo < h_hi and hid_photon[lo] == pj)
            if code == CLASSIC:
                w = _cos_in(direction, pj, nx, ny, nz) / (math.pi * radius * radius)
            elif code == RADIUS:
                x = min(max(1.0 - (d / r_simpson) ** 2, 0.0), 1.0)
                w = 3.0 / (math.pi * r_simpson * r_simpson) * x * x
            elif code == KNN_SIMPSON:
                x = min(max(1.0 - (d / rk) ** 2, 0.0), 1.0)
                w = 3.0 / area * x * x
            else:
                w = min(max(1.0 - d / rk, 0.0), 1.0) / ((1.0 - 2.0 / 3.0) * area)
            f0, f1, f2 = read_power(power, pj)  # (photonlayout: float32 or RGBE)
            e0 += w * f0
            e1 += w * f1
            e2 += w * f2
            byte, bit = pj >> 3, pj & 7
            for s in range(S):
                if (masks[s, byte] >> bit) & 1 and seen:
                    ms[s, 0] += w * f0
                    ms[s, 1] += w * f1
                    ms[s, 2] += w * f2
            if not inside:
                continue  # accepted photons beyond the k-th do not count towards the minimum
            if rec and count < W:
                read_photon[i, count] = pj
                if rec_w:
                    # (a floored focus sums its photons' plain power: below)
                    read_weight[i, count] = 1.0 if floored else w
            count += 1
            a0 += f0
            a1 += f1
            a2 += f2
            for s in range(S):
                if (masks[s, byte] >> bit) & 1 and seen:
                    ms[s, 3] += f0
                    ms[s, 4] += f1
                    ms[s, 5] += f2
            c0 += pos[pj, 0] - np.float32(qx)
            c1 += pos[pj, 1] - np.float32(qy)
            c2 += pos[pj, 2] - np.float32(qz)
        if floored:
            # A focus: more photons lie inside the floored disc than the query fetched. The
            # estimate is the disc's photon count times the fetched photons' mean accepted
            # power, over pi rk^2 (a box kernel): the focus's light is spread, never dropped.
            in_disc = _ball_count(kind, pos, nodes, start, grid, qx, qy, qz, rk * rk, buckets)
            f = in_disc / max(fetched, 1) / area
            if rec_w:
                # (masked = f x sum x scale; scale is 1 for the k-NN estimators, the only
                # ones floored)
                read_factor[i] = f
            e0, e1, e2 = f * a0, f * a1, f * a2
            for s in range(S):
                for c in range(3):
                    ms[s, c] = f * ms[s, 3 + c]
        elif rec_w:
            read_factor[i] = scale
        if rec:
            read_count[i] = count if count >= min_photons else 0
        if count >= min_photons:
            out[i, 0] = e0 * scale
            out[i, 1] = e1 * scale
            out[i, 2] = e2 * scale
            for s in range(S):
                for c in range(3):
                    masked[s, i, c] = ms[s, c] * scale
        if not want_boundary:
            continue
        if only_accepted:
            # The sum saw no other surface's photons: look for them in the listed sphere.
            for j in range(listed):
                if math.sqrt(list_d2[j]) <= rk and \
                        _accepted(direction, normal, surface, pos, list_idx[j], nx, ny, nz, qs,
                                  qx, qy, qz)[1] and \
                        not _back_face(normal, pos, list_idx[j], nx, ny, nz, qx, qy, qz):
                    other_inside = True
                    break
        # Too few photons for an estimate (E = 0) counts as boundary too: gather again.
        b = other_inside or count < min_photons
        # An open edge (a table's rim, the end of a floor) leaves no other surface's photons,
        # but the accepted ones lie off to one side: their centroid, in the tangent plane, is
        # more than BOUNDARY_OFFSET x rk from the point (a half disc gives 0.42 rk; 64 photons
        # of a whole disc scatter it by ~0.08 rk; a gradient needs a 100 % change across rk).
        # With fewer than ~24 photons the limit grows (BOUNDARY_FALSE_ALARM): a half disc
        # of n photons (0.42 rk) is still flagged from n ~ 9.
        mm = max(count, 1)
        cx, cy, cz = np.float64(c0) / mm, np.float64(c1) / mm, np.float64(c2) / mm
        fx, fy, fz = n[i, 0], n[i, 1], n[i, 2]
        dn = cx * fx + cy * fy + cz * fz
        cx, cy, cz = cx - dn * fx, cy - dn * fy, cz - dn * fz
        offset = math.sqrt(cx * cx + cy * cy + cz * cz) / rk
        limit = max(BOUNDARY_OFFSET, math.sqrt(BOUNDARY_LOG / (2.0 * mm)))
        boundary[i] = b or offset > limit


@register_warm_up
def _warm_up():
    """Compile every estimator / structure / boundary variant a render uses."""
    rng = np.random.default_rng(0)
    m = 64
    pos = rng.random((m, 3)).astype(np.float32)
    up = np.tile(np.float32([0.0, 0.0, 1.0]), (m, 1))
    ph = Photons(pos, np.ones((m, 3), np.float32), -up, up.copy(), np.zeros(m, np.uint8))
    q = rng.random((4, 3))
    nq = np.tile([0.0, 0.0, 1.0], (4, 1))
    for pm in (PhotonMap(ph), PhotonMap(ph, structure="hashgrid", cell=0.3)):
        for est in ESTIMATOR_CODES:
            pm.irradiance(q, nq, 0.3, 8, 2, est, return_boundary=True, r_floor=np.full(4, 0.01))
            pm.irradiance(q, nq, 0.3, 8, 2, est)


_NO_POINTS = np.zeros(0, np.int64)


class _LazyPoints:
    """A lazy GatherMap's estimates still to make (GatherMap._fill), shared by its views:
    the estimating PhotonMap, the masks over its photons (bits, (S, ceil(N / 8)) uint8:
    pack_masks; or None), the
    estimate's (k, min_photons, estimator), the points' surfaces (or None), the arrays to
    fill ((P,3) E of every photon, None where the map keeps a keep mask's instead, (P,)
    boundary, (S',P,3) the masks' but the drop bounds' or None), the drop
    bounds' (P,) bool arrays with their mask rows, and which points are known ((P,)
    bool)."""

    def __init__(self, estimating, chosen, args, surface, E, boundary, levels, hits):
        self.estimating, self.chosen, self.args, self.surface = estimating, chosen, args, surface
        self.E, self.boundary, self.levels, self.hits = E, boundary, levels, hits
        self.known = np.zeros(len(boundary), np.bool_)


# The gather points' levels (E, the subset maps' E, secondary_levels, counts_irradiance's
# answers): each point's float64 estimate rounded once to float32 (to nearest: within
# 2^-24 of it, relative), 12 B a point and level instead of 24. A lookup returns a
# point's value: a pixel's gathered light, a non-negative weighted sum of them, moves by
# at most 2^-24 of itself (docs/performance.md "hdri52").
LEVEL_DTYPE = np.float32


class GatherMap:
    """Precomputed irradiance at a subset of photon positions (Christensen 1999), so a
    final-gather ray needs only a nearest-neighbour lookup instead of a k-NN estimate.

    The gather points are every step-th photon and their irradiance is estimated from the
    *other* photons (power scaled up by all / others). Estimated from all photons, a
    lookup would be biased: a point in a locally sparse patch has both a large Voronoi
    cell (picked by more lookups) and a large k-NN radius (a low estimate), which darkened
    a furnace room's indirect light by 4 %; counting the point's own photon instead
    brightens every estimate by +3 photons of the Simpson kernel (+4.8 % at k = 64).
    The two thinned sets are independent, so neither bias appears (tests/test_furnace.py).

    A photon is a gather point with the probability _point_shares gives: 1 / step where
    photons are dense, more where they are sparse (counted from the every-step-th points),
    so that a lookup disc of the search radius holds a few gather points wherever photons
    are stored. Every step-th photon alone left surfaces lit 30x more thinly than the
    brightest ones (a room lit through a slot and a mirror) with a gather point in 1 of 3
    lookup discs; the others returned nothing and, after two regathers, no light (that half
    of the room 5 % dark against Cycles, docs/accuracy_time_figure7_mirror.md).
    min_photons: photons an estimate needs (fewer: no estimate, flagged);
    integrator.smooth_min_photons gives 1 outside paper mode.

    secondary_E: (P,3) float32 or None, per gather point (self.position's order) the
    irradiance of the secondary-caustic (CAUSTIC_DIFFUSE) photons alone from the point's
    own estimate: the share of E that a regathered end must add back
    (integrator._secondary_irradiance). Set by the caller from secondary_levels; None:
    the regathers estimate it from the secondary map.
    """

    secondary_E = None
    surface = NO_SURFACE  # the points' surfaces (set with the points)
    _lazy = None  # lazy: the estimates still to make (_LazyPoints), shared by the views

    def __init__(self, photons: Photons, radius: float, k: int, min_photons: int,
                 estimator: str, max_points: int = 60_000, accel=None,
                 workers: int = 1, should_cancel=None, rows: np.ndarray | None = None,
                 keep: np.ndarray | None = None, subsets=(), secondary=(),
                 bounces: np.ndarray | None = None, drop_bounds=None, lazy: bool = False):
        """rows: (K,) int, build from photons.take(rows) only (gathered once, straight into
        the trees' order). The independent steps run side by side on `workers` threads
        (parallel.run_tasks: the two kd-trees, then the points' irradiance and their
        neighbour lists): the same map for any thread count. should_cancel (a StopFlag or
        a callable) is asked between the steps; raises parallel.Cancelled.
        keep: (N,) bool over `photons`: the map's irradiance from those photons alone; the
        points, trees and estimate discs still come from all the rows' photons, the others'
        power counted as 0 (an unbiased estimate of the kept photons' irradiance). The
        bounce limits keep the photons valid for a lookup this way (engine/render.py):
        dropping them from the rows instead thinned the map, and its sparser points sent
        10 % more of Figure 7's gather rays to regather.
        subsets: (N,) bool masks over `photons` like keep, for the bounce limits' deeper
        levels; self.subset_maps then holds, per mask, this map with that mask's
        irradiance at the same points, for about the cost of the points' estimates
        instead of a whole map's.
        secondary: (N,) bool masks over `photons` like keep; self.secondary_levels then
        holds, per mask, the points' irradiance (P,3) from that mask's photons alone
        (the same searches: another mask of the estimate pass; [] without).
        bounces: (N,4) uint8 over `photons`, their counts (Photons.bounces): the map keeps
        its estimating photons and their counts for counts_irradiance (None: not kept).
        drop_bounds: {key: (N,) bool over `photons`} or None; self.drop_bounds then holds,
        per key, (P,) bool: whether some photon of that mask adds to the point's estimate
        (another mask of the same searches; a mask without a photon of nonzero power:
        all False, no mask). integrator._chain_lookups reads them as bounds on the
        photons a lookup's counts can drop (render._drop_bound_masks).
        lazy: each point's estimate (E, boundary, the masks' arrays, the drop bounds) is
        made by the first lookup that takes the point (_fill), not all at construction:
        the same bits (one point's estimate depends on nothing else), for the points a
        render's gather rays read (a third of a world-lit yard's at 16 spp,
        docs/performance.md "fast46"). Until then those arrays hold 0 (boundary True) at
        the points not yet read: whoever reads them whole calls complete() first."""
        self.workers = workers
        self.subset_maps = []
        self.secondary_levels = []
        self.estimating = None  # counts_irradiance's photons (bounces given), else None
        self.drop_bounds = {}
        # With an Accel, a lookup only takes a gather point it can see: a point on the
        # other side of a wall (e.g. the ground outside a room, coplanar with the floor
        # inside) would otherwise leak light under the wall (docs/stability.md).
        self.accel = accel
        self.tree = None
        if rows is None:
            rows = np.arange(len(photons))
        n = len(rows)
        if n < 2:
            return
        step = max(4, int(math.ceil(n / max_points)))
        position = np.take(photons.position, rows, axis=0)
        share = np.empty(n)
        is_point = np.empty(n, np.bool_)
        _point_shares(position, step, radius, share, is_point, workers, should_cancel)
        if is_point.all():  # too few photons to split
            return
        points = np.flatnonzero(is_point)
        others = np.flatnonzero(~is_point)
        # Each photon left for the estimates stands in for the ones taken as points where
        # it lies (Horvitz-Thompson: power / (1 - share)): no region loses light.
        scale = (1.0 / (1.0 - np.take(share, others))).astype(np.float32)

        # The two trees side by side; their inputs are bound to the tasks (and dropped
        # with them), as are the shares', before the estimates' memory.
        trees = [lambda stop, pts=np.take(position, points, axis=0):
                 kdtree.KdTree(pts, workers=workers),
                 lambda stop, rows_=np.take(rows, others), scale_=scale:
                 PhotonMap(photons, workers, rows=rows_, power_scale=scale_,
                           keep_source=(keep is not None or bool(len(subsets))
                                        or bool(len(secondary)) or bounces is not None))]
        del position, share, is_point, others, scale
        tree, estimating = run_tasks(trees, workers, should_cancel)
        del trees
        # Kept in the tree's order: a search result indexes these arrays directly. The
        # points' position is the tree's float32 array and their normal the photons'
        # (float32): the kernels and estimates read both as float64, the same values
        # their float64 copies held (36 B a point less, docs/performance.md "mem48").
        self.position = tree.position
        chosen_rows = np.take(rows, np.take(points, tree.order))
        self.normal = (np.take(photons.normal, chosen_rows, axis=0)
                       if photons.normal.dtype != np.int16 else
                       photonlayout.vectors(photons.normal, chosen_rows, np.float32))
        # Each point's surface (its photon's, Photons.surface): its own estimate reads its
        # surface's photons, and a lookup takes only a point on its own surface
        # (engine/samesurface.py). NO_SURFACE: unknown, the normal tests alone.
        self.surface = (NO_SURFACE if photons.surface is None else
                        np.ascontiguousarray(np.take(photons.surface, chosen_rows),
                                             dtype=np.int32))
        del chosen_rows
        tree.order = None

        # keep's and the subsets' irradiance from one search per point: the neighbours,
        # discs and boundary flags depend on the photons' places and directions only,
        # never on their power (PhotonMap.irradiance's masks: the same bits as an estimate
        # pass per mask, for about the cost of one).
        masks = ([] if keep is None else [keep]) + list(subsets) + list(secondary)
        # The drop bounds' masks, each once, and only those holding a photon with power.
        bound_keys = list((drop_bounds or {}).keys())
        bound_masks, bound_of = [], []
        if bound_keys:
            with_power = photonlayout.has_power(photons.power)  # (either layout)
        for key in bound_keys:
            mask = drop_bounds[key] & with_power
            same = [i for i, m in enumerate(bound_masks) if np.array_equal(m, mask)]
            if same or not mask.any():
                bound_of.append(same[0] if same else -1)
            else:
                bound_of.append(len(bound_masks))
                bound_masks.append(mask)
        masks += bound_masks

        P = len(self.position)
        kept = len(masks) - len(bound_masks)  # the masks whose (P,3) levels the map keeps
        # A kept mask with no estimating photon of nonzero power has a level of zeros
        # (every term it sums is 0): not searched, its level one shared zero array
        # (a read-only broadcast for the secondary shares, read by np.take alone; a
        # (P,3) array where the lookup kernels read it as E). live: the others.
        chosen, live = None, list(range(kept))
        if masks:
            est_power = photonlayout.has_power(estimating.photons.power)  # (a map: compact)
            rows_of = []
            live = []
            for i, mask in enumerate(masks):
                row = np.take(mask, estimating.source)
                if i < kept:
                    if not (row & est_power).any():
                        continue  # a level of zeros
                    live.append(i)
                # As bits (pack_masks), row by row: 1/8 B a photon and mask, which a lazy
                # map keeps (the (S, N) bool masks were made whole before: S B a photon
                # at the map build's peak).
                rows_of.append(pack_masks(row[None]))
            del est_power, row
            chosen = np.concatenate(rows_of) if rows_of else None
            del rows_of

        def estimate(stop):
            return estimating.irradiance(self.position, self.normal, radius, k, min_photons,
                                         estimator, return_boundary=True, should_cancel=stop,
                                         masks=chosen,
                                         surface=self.surface if len(self.surface) else None)

        def neighbours(stop):
            return tree.neighbour_lists(workers=workers, should_cancel=stop)

        n_live = len(live)
        if lazy:
            # The arrays the estimates fill (in place: the views below read them); the
            # drop bounds' masks fill their (P,) flags alone (_fill), and with keep no
            # view reads the estimate of every photon (E is keep's level): not kept.
            # Float32 levels (LEVEL_DTYPE): the float64 estimates rounded once.
            done = (np.zeros((P, 3), LEVEL_DTYPE) if keep is None else None,
                    np.ones(P, np.bool_)) + (
                () if chosen is None else (np.zeros((n_live, P, 3), LEVEL_DTYPE),))
            self.neighbours = run_tasks([neighbours], 1, should_cancel)[0]
            hit = [np.zeros(P, np.bool_) for _ in bound_masks]
        else:
            done, self.neighbours = run_tasks([estimate, neighbours], workers, should_cancel)
            if bound_masks:
                # (from the float64 estimates: a tiny nonzero term still counts)
                hit = [np.any(b != 0.0, axis=1) for b in done[2][n_live:]]
            # The levels as float32 (LEVEL_DTYPE), the kept ones alone: the drop bounds'
            # (P,3) estimates, views of one array with them, would keep it all alive.
            done = ((None if keep is not None else done[0].astype(LEVEL_DTYPE)), done[1]) + (
                () if len(done) < 3 else (done[2][:n_live].astype(LEVEL_DTYPE),))
        E, self.boundary = done[0], done[1]
        levels = []
        if kept:
            zero_E = zero_share = None
            first_secondary = kept - len(secondary)
            for i in range(kept):
                if i in live:
                    levels.append(done[2][live.index(i)])
                elif i < first_secondary:
                    if zero_E is None:
                        zero_E = np.zeros((P, 3), LEVEL_DTYPE)
                    levels.append(zero_E)
                else:
                    if zero_share is None:
                        zero_share = np.broadcast_to(np.zeros(3, LEVEL_DTYPE), (P, 3))
                    levels.append(zero_share)
        for key, j in zip(bound_keys, bound_of):
            self.drop_bounds[key] = hit[j] if j >= 0 else np.zeros(len(self.position), bool)
        if lazy:
            self._lazy = _LazyPoints(
                estimating, chosen, (k, min_photons, estimator),
                self.surface if len(self.surface) else None, done[0], done[1],
                done[2] if chosen is not None else None,
                [(h, n_live + j) for j, h in enumerate(hit)] if bound_masks else [])
        self.E = E if keep is None else levels.pop(0)
        if len(secondary):
            self.secondary_levels = levels[len(levels) - len(secondary):]
            levels = levels[:len(levels) - len(secondary)]
        self.radius = radius
        self.tree = tree
        if bounces is not None:
            # (shared with the views below: one cache of counts_irradiance's answers)
            self.estimating = estimating
            # Its photons' distinct count rows and each photon's (a mask per count is
            # then a take: bounce_usable over every photon cost ~20 ms a call on
            # Figure 6's 0.7 M, 40 % of its render at 80 x 60), in the smallest integer
            # type; the photons' rows in `photons` are not needed after that.
            from .chaincounts import unique_counts
            rows, which = unique_counts(np.take(bounces, estimating.source, axis=0))
            self.estimating_classes = (rows, which.astype(np.min_scalar_type(len(rows))))
            self.estimate_args = (k, min_photons, estimator)
            self.counts_cache = {}
        # The estimating photons' rows in `photons` served the masks and count classes
        # above; a lazy map keeps its estimating photons (8 B a photon less).
        if getattr(estimating, "source", None) is not None:
            estimating.source = None
        for E in levels:
            # The same points, trees, neighbour lists and boundary flags (shared).
            view = copy.copy(self)
            view.E, view.subset_maps, view.secondary_levels = E, [], []
            self.subset_maps.append(view)

    def _fill(self, point: np.ndarray):
        """A lazy map's estimates at gather points `point` (M,) int64 (indices into
        self.position; -1 ignored) not made yet, written into the shared arrays (the same
        bits as the whole pass). Two threads may make a point twice: the same values,
        written before the point is marked known."""
        lz = self._lazy
        if lz is None or not len(point):
            return
        point = point[point >= 0]
        new = np.unique(point[~np.take(lz.known, point)])
        if not len(new):
            return
        got = lz.estimating.irradiance(
            np.take(self.position, new, axis=0), np.take(self.normal, new, axis=0),
            self.radius, *lz.args, return_boundary=True, masks=lz.chosen,
            surface=None if lz.surface is None else np.take(lz.surface, new))
        if lz.E is not None:
            lz.E[new] = got[0]
        lz.boundary[new] = got[1]
        if lz.levels is not None:
            lz.levels[:, new] = got[2][:len(lz.levels)]
            for hit, row in lz.hits:
                hit[new] = np.any(got[2][row] != 0.0, axis=1)
        lz.known[new] = True

    def complete(self) -> "GatherMap":
        """Every point's estimates made (a lazy map's, for readers of whole arrays: E,
        boundary, secondary_levels, drop_bounds, the subset maps' E); returns self."""
        if self._lazy is not None:
            self._fill(np.arange(len(self.position), dtype=np.int64))
        return self

    def counts_irradiance(self, points, limits, camera) -> np.ndarray:
        """(M,3) float32: the irradiance at gather points `points` (M,) int64 (indices into
        self.position) from the photons usable at camera-side counts `camera` (4-tuple,
        B_TOTAL order) within `limits` (4,) alone: what a subset map of those photons
        (the constructor's subsets, the others' power counted as 0) holds there, the same
        bits (one point's estimate depends on nothing else). Computed on first use per
        (counts, point) and kept (counts_cache, shared by the views): two threads may
        compute a point twice, the same values. Needs the map built with bounces;
        raises ValueError otherwise."""
        if self.estimating is None:
            raise ValueError("GatherMap.counts_irradiance: the map was built without bounces")
        points = np.asarray(points, np.int64)
        key = tuple(int(x) for x in camera)
        got = self.counts_cache.get(key)
        if got is None:
            rows, which = self.estimating_classes
            # The count's mask once, kept as bits (1/8 B a photon, pack_masks: what the
            # estimate reads): the take over every estimating photon per call was 2/3 of
            # these calls' CPU on Figure 6.
            bits = pack_masks(np.take(pk.bounce_usable(rows, np.asarray(limits, np.int64),
                                                       key), which)[None])
            got = self.counts_cache.setdefault(key, (bits, _NO_POINTS,
                                                     np.zeros((0, 3), LEVEL_DTYPE)))
        # A sparse store per count: the points asked so far (ascending) and their E. A
        # dense (P,3) + (P,) per count held 52 MB on Figure 6 (34 counts, 60 k points)
        # for 11 k points asked (docs/performance.md, mem45).
        bits, known, known_E = got
        at = np.minimum(np.searchsorted(known, points), max(len(known) - 1, 0))
        found = (np.take(known, at) == points) if len(known) else np.zeros(len(points), bool)
        new = np.unique(points[~found])
        if len(new):
            k, min_photons, estimator = self.estimate_args
            surf = self.surface if len(self.surface) else None
            _, masked = self.estimating.irradiance(
                np.take(self.position, new, axis=0), np.take(self.normal, new, axis=0),
                self.radius, k, min_photons, estimator, masks=bits,
                surface=None if surf is None else np.take(surf, new))
            merged = np.concatenate([known, new])
            order = np.argsort(merged, kind="stable")
            known = merged[order]
            # (as a subset map's level holds them: float32)
            known_E = np.concatenate([known_E, masked[0].astype(LEVEL_DTYPE)])[order]
            # (two threads may both add points: the last store wins, the other's are
            # computed again when asked, the same bits)
            self.counts_cache[key] = (bits, known, known_E)
            at = np.searchsorted(known, points)
        return np.take(known_E, at, axis=0)

    def serial(self) -> "GatherMap":
        """The same map, queried on the calling thread only (see PhotonMap.serial)."""
        view = copy.copy(self)
        view.workers = 1
        if self.accel is not None:
            view.accel = self.accel.serial()
        return view

    def lookup(self, p: np.ndarray, n: np.ndarray, candidates: int = 8,
               offset: np.ndarray | None = None, scratch=None, points: bool = False,
               surface=None):
        """(irradiance, boundary) at the nearest visible gather point facing the same way
        (normal . n > GATHER_AGREEMENT), among the 8 x candidates nearest within the radius.
        boundary: that point's estimate met another surface (a corner or contact), where
        the estimate is biased dark, or no such point was found in range (a sparsely lit
        patch crowded by another surface's gather points, e.g. the underside of a ball
        resting on a lit floor); those rows get irradiance 0 and should gather again.
        p, n: (M,3) points and unit normals; offset: (M,) distance along n that takes a
        ray from p clear of p's surface (SurfaceHit.offset); default: the float32
        resolution at p. Returns ((M,3) float64, (M,) bool). scratch: an object whose
        scratch_arrays(M) hands out the arrays to write into (integrator.GatherBuffers:
        the calling thread's, reused between calls; the answers are then valid until its
        next use); default: fresh arrays. points: also return, third, each row's gather
        point ((M,) int64 index into the map's points, -1 where none was found: the
        point whose E and flag the row took; secondary_E reads by it). surface: (M,) int
        the rows' object ids (PhotonMap.knn_irradiance's): a row takes only a point on its
        own surface or on one continuing its plane (engine/samesurface.py); None: any.

        One kernel (_gather_candidates) finds the nearest point (a walk over the gather
        points' neighbour lists from the previous row's answer, else the kd-tree), tests
        the normals, writes
        the answers and the visibility rays in Embree's float32 layout; the rows whose
        candidate is hidden take their next visible one (_next_visible)."""
        m = len(p)
        if self.tree is None or m == 0:
            none = (np.zeros((m, 3)), np.ones(m, bool))
            return (*none, np.full(m, -1, np.int64)) if points else none
        if scratch is not None:
            out, boundary, o32, d32, t32, ray_row, blocked, point = scratch.scratch_arrays(m)
        else:
            out = np.empty((m, 3))  # every row is written by the kernel
            boundary = np.empty(m, bool)
            o32 = np.empty((m, 3), np.float32)
            d32 = np.empty((m, 3), np.float32)
            t32 = np.empty(m, np.float32)
            ray_row = np.empty(m, np.int64)
            blocked = np.empty(m, bool)
            point = np.empty(m, np.int64)
        lazy = self._lazy is not None
        if lazy and scratch is None and not points:
            point = np.empty(m, np.int64)
        point = point if points or lazy else _NO_POINT
        p = np.ascontiguousarray(p, dtype=np.float64)
        n = np.ascontiguousarray(n, dtype=np.float64)
        lift = (_NO_LIFT if offset is None
                else np.ascontiguousarray(offset, dtype=np.float64))
        kmax = min(8 * candidates, len(self.position))
        rows = morton_order(p)  # cache-friendly query order; same answers
        want_rays = self.accel is not None
        r2 = self.radius * self.radius
        surf, qsurf = self._surfaces(surface, m)
        nrays = _gather_candidates(self.tree.position, self.tree.nodes, *self.neighbours,
                                   self.position, self.normal, surf, self.E, self.boundary,
                                   p, n, qsurf, lift, rows, r2, kmax, want_rays, out, boundary,
                                   o32, d32, t32, ray_row, point)
        if nrays:
            self.accel.occluded_into(o32[:nrays], d32[:nrays], t32[:nrays], blocked[:nrays])
            hidden = rows[ray_row[:nrays][blocked[:nrays]]]
            if len(hidden):
                self._next_visible(p, n, lift, hidden, kmax, out, boundary, point, qsurf)
        if lazy:
            # The kernels copied E and boundary of points perhaps not estimated yet: the
            # rows that found a point read them again once they are (no point: 0, True).
            found = np.flatnonzero(point >= 0)
            at = np.take(point, found)
            self._fill(at)
            out[found] = np.take(self.E, at, axis=0)
            boundary[found] = np.take(self.boundary, at)
        return (out, boundary, point) if points else (out, boundary)

    def _surfaces(self, surface, m):
        """(points' surfaces, queries' (m,) int32) for the lookup kernels; both NO_SURFACE
        where either is unknown (the normal test alone)."""
        surf = getattr(self, "surface", NO_SURFACE)
        if surface is None or not len(surf):
            return NO_SURFACE, NO_SURFACE
        return surf, query_surfaces(surface, m)

    def _next_visible(self, p, n, lift, hidden, kmax, out, boundary, point=None,
                      qsurf=NO_SURFACE):
        """Rows `hidden` (indices into p) whose candidate is hidden take the next visible
        agreeing gather point, in increasing distance among the kmax nearest (the answer
        of asking again candidate by candidate): the agreeing candidates are listed once
        per row, then tested in batches of growing size (1, 4, 16, ... rays per row) by
        one Embree call per batch."""
        out[hidden] = 0.0
        boundary[hidden] = True
        if point is None:
            point = _NO_POINT
        elif len(point):
            point[hidden] = -1
        lists = np.empty((len(hidden), max(kmax, 1)), np.int64)
        counts = np.empty(len(hidden), np.int64)
        surf = self.surface if len(qsurf) else NO_SURFACE
        _agreeing_lists(self.tree.position, self.tree.nodes, self.normal, surf, p, n, qsurf,
                        hidden, self.radius * self.radius, kmax, lists, counts)
        pending = np.nonzero(counts > 1)[0]  # entry 0 is the hidden candidate
        nxt = np.ones(len(hidden), np.int64)
        batch = 1
        while len(pending):
            cap = len(pending) * batch
            o32 = np.empty((cap, 3), np.float32)
            d32 = np.empty((cap, 3), np.float32)
            t32 = np.empty(cap, np.float32)
            slot = np.empty(cap, np.int64)
            nrays = _list_rays(self.position, self.normal, p, n, lift, hidden, lists, counts,
                               pending, nxt, batch, o32, d32, t32, slot)
            blocked = np.zeros(nrays, bool)
            self.accel.occluded_into(o32[:nrays], d32[:nrays], t32[:nrays], blocked)
            pending = _pick_visible(self.E, self.boundary, hidden, lists, counts, pending, nxt,
                                    batch, blocked, slot[:nrays], out, boundary, point)
            batch *= 4


# The gather map's normal test: a gather point's surface faces the query's way.
GATHER_AGREEMENT = 0.7
# Neighbour lists a gather lookup walks before it searches the tree (kdtree.nearest_walk;
# 3 settles 3-5 % more rows than 2 on Figures 6 and 7).
WALK_STEPS = 3
_NO_LIFT = np.zeros(0)
_NO_POINT = np.zeros(0, np.int64)  # _gather_candidates / _pick_visible: no point indices

# Gather points a lookup disc of the search radius should hold where photons are sparse
# (below ~12 photons a disc the share stops at MAX_POINT_SHARE: 8 photons give 4 points,
# a disc with none e^-4 of the time).
GATHER_POINTS_PER_DISC = 6.0
# The largest share of a region's photons taken as gather points (the rest estimate).
MAX_POINT_SHARE = 0.5
# Sparseness is counted on a grid of cells this many search radii wide.
DENSITY_CELL = 2.0


def _point_shares(position, step, radius, share, is_point, workers=1, should_cancel=None):
    """The gather points of GatherMap, from the base points (every step-th photon, share
    s = 1 / step): share (N,) float64, the probability that each photon (position (N,3))
    is a gather point, and is_point (N,) bool, the choice made with it; both written in
    place.

    share is s where photons are dense, more where they are sparse so that a disc of the
    search radius holds about GATHER_POINTS_PER_DISC points, at most MAX_POINT_SHARE. The
    density is counted from the base points alone, on a grid of cells DENSITY_CELL radii
    wide (a surface crossing a cell holds about its face's area). A share counted from
    all photons would pick points where photons happen to be sparse, whose estimates are
    low (measured: 9 % dark); the base points are an independent thinning and estimate
    nothing, so the points and the estimating photons stay independent. Cells are hashed
    (the hash grid's primes); two cells that share a hash count together, which only
    lowers their share (the estimates stay unbiased for any share: GatherMap weights the
    photons left by 1 / (1 - share)).

    is_point: the base points, and the others with probability (share - s) / (1 - s), so
    that each photon is a point with probability share: photon i when frac((i + 1) x
    golden ratio) is below it (a fixed sequence: the same points for any thread count and
    run; photons come in emission order, unrelated to where they lie).

    Compiled (_cell_keys, _shares_rows), rows in blocks on `workers` threads."""
    n = len(position)
    step_share = (-(-n // step)) / max(n, 1)  # base points / photons
    size = DENSITY_CELL * radius if radius > 0 else 1.0
    base_keys = np.empty(-(-n // step), np.int64)
    _cell_keys(position, size, step, base_keys)
    base_keys, counts = np.unique(base_keys, return_counts=True)
    table_keys, table_counts = _count_table(base_keys, counts.astype(np.int64))
    dense = bool(radius > 0)

    def job(a, stop):
        if stop():
            raise Cancelled()
        _shares_rows(position, size, step, step_share, table_keys, table_counts, dense, a,
                     min(a + SHARE_ROWS, n), share, is_point)
    for _ in ordered_map(job, range(0, n, SHARE_ROWS), workers if n > SHARE_ROWS else 1,
                         should_cancel):
        pass


SHARE_ROWS = 1 << 17  # photons per job of _point_shares


@kernel
def _cell_key(position, i, size):
    """The hashed density cell of photon i: floor(p / size) per axis (NaN as 0, clamped
    to +-2^40), mixed with the hash grid's primes."""
    key = np.int64(0)
    for c in range(3):
        v = np.floor(np.float64(position[i, c]) / size)
        if v != v:
            v = 0.0
        v = min(max(v, -CELL_CLAMP), CELL_CLAMP)
        key ^= np.int64(v) * PRIMES[c]
    return key


@kernel
def _cell_keys(position, size, step, out):
    """_cell_key of the photons 0, step, 2 step, ... into out."""
    for j in range(out.shape[0]):
        out[j] = _cell_key(position, j * step, size)


# Multiplier of _count_table's hash (an odd 64-bit constant: 2^64 / golden ratio).
TABLE_MIX = -7046029254386353131


@kernel
def _table_slot(key, mask):
    """_count_table's first slot for key."""
    return ((key * np.int64(TABLE_MIX)) >> np.int64(29)) & mask


@kernel
def _count_table(keys, counts):
    """An open-addressing hash table of the distinct cell keys (keys (K,) int64, their
    base-point counts (K,) int64): (table_keys, table_counts), a power of two of at least
    4 K slots, empty slots with count -1, linear probing from _table_slot. Looked up per
    photon by _shares_rows: the same count as a binary search of the sorted keys (exact
    key equality) at ~1/3 of its cost (docs/performance.md, "Thirteenth slice")."""
    size = 16
    while size < 4 * keys.shape[0]:
        size *= 2
    table_keys = np.zeros(size, np.int64)
    table_counts = np.full(size, -1, np.int64)
    mask = size - 1
    for a in range(keys.shape[0]):
        s = _table_slot(keys[a], mask)
        while table_counts[s] >= 0:
            s = (s + 1) & mask
        table_keys[s] = keys[a]
        table_counts[s] = counts[a]
    return table_keys, table_counts


@kernel
def _shares_rows(position, size, step, step_share, table_keys, table_counts, dense, lo, hi,
                 share, is_point):
    """_point_shares for the photons [lo, hi): table_keys / table_counts (_count_table)
    hold the base points' cells and how many base points each holds."""
    top = max(MAX_POINT_SHARE, step_share)
    mask = table_keys.shape[0] - 1
    spare = max(1.0 - step_share, 1e-300)
    for i in range(lo, hi):
        sh = step_share
        if dense:
            key = _cell_key(position, i, size)
            s = _table_slot(key, mask)
            found = 0
            while table_counts[s] >= 0:
                if table_keys[s] == key:
                    found = table_counts[s]
                    break
                s = (s + 1) & mask
            # Photons in a search disc: the base points' count / their share, over the
            # cell face's area in discs.
            per_disc = found / step_share * math.pi / (DENSITY_CELL * DENSITY_CELL)
            want = np.inf if per_disc == 0.0 else GATHER_POINTS_PER_DISC / per_disc
            sh = min(max(want, step_share), top)
        share[i] = sh
        x = (i + 1.0) * 0.6180339887498949
        u = x - np.floor(x)  # exact for x > 0 (modf's fraction)
        is_point[i] = i % step == 0 or u < (sh - step_share) / spare


CELL_CLAMP = 2.0 ** 40
PRIMES = np.array([hashgrid.P1, hashgrid.P2, hashgrid.P3], np.int64)


@kernel
def _gather_candidates(tree_pos, nodes, nbr, reach, position, normal, surface, E, E_boundary,
                       p, n, qsurf, lift, rows, r2, kmax, want_rays, out, boundary, o32, d32,
                       t32, ray_row, point):
    """For each row i = rows[r]: the candidate c = the nearest gather point within
    sqrt(r2) whose normal agrees with n[i] and that lies on its surface (the points'
    surface (P,) int32 and the rows' qsurf (M,) int32, samesurface.same_surface; either
    empty: not tested), if it is among the kmax nearest; out[i] = E[c]
    and boundary[i] = E_boundary[c] (no candidate: 0 and True); and, if want_rays, the
    ray from p[i] to c into o32 / d32 / t32 (float32, compacted, _ray_ends; ray_row =
    r). nbr, reach: the tree's neighbour lists (kdtree.neighbour_lists). point (M,)
    int64, or empty: point[i] = c (-1: none). Returns the number of rays."""
    P = tree_pos.shape[0]
    R = rows.shape[0]
    nrays = 0
    # The rows' queries first copied into their Morton order (position, normal, own
    # offset: the same values), so the walk and the row loop below read them in sequence.
    # Read at random inside the walk, behind its dependent loads and branches, they cost
    # ~40 ns a row more (one read-ahead loop pays them far cheaper): the kernel 227 ->
    # 163 ns a row on Figure 6's lookups, 253 -> 187 on Figure 7's (docs/performance.md,
    # "gatherlookup").
    q = np.empty((R, 7))
    for r in range(R):
        i = rows[r]
        qx, qy, qz = p[i, 0], p[i, 1], p[i, 2]
        q[r, 0], q[r, 1], q[r, 2] = qx, qy, qz
        q[r, 3], q[r, 4], q[r, 5] = n[i, 0], n[i, 1], n[i, 2]
        q[r, 6] = _query_lift(lift, i, qx, qy, qz)
    # Each row's nearest gather point first, for all rows (kdtree.nearest_walk: from the
    # previous row's answer by its neighbour list, 85-90 % of rows, else the tree; rows
    # come in Morton order, so the previous answer is usually near). The answer is the
    # one an unbounded tree search gives.
    near = np.empty(R, np.int64)
    st_node, st_off = kdtree.traversal_stack()  # the facing searches' scratch
    if P > 0:
        kdtree.nearest_walk(tree_pos, nodes[0], nodes[1], nodes[2], nbr, reach, q,
                            np.arange(R), r2, WALK_STEPS, near, np.zeros(0, np.bool_))
    # The previous row's chosen gather point (a seed for the facing search).
    prev_cand = -1
    test_surface = surface.shape[0] > 0 and qsurf.shape[0] > 0
    for r in range(R):
        i = rows[r]
        qx, qy, qz = q[r, 0], q[r, 1], q[r, 2]
        nx, ny, nz = q[r, 3], q[r, 4], q[r, 5]
        qs = np.int64(qsurf[i]) if test_surface else np.int64(-1)
        c = -1
        if P > 0:
            j = near[r]
            if j >= 0:
                if normal[j, 0] * nx + normal[j, 1] * ny + normal[j, 2] * nz \
                        > GATHER_AGREEMENT and \
                        same_surface(surface, tree_pos, normal, j, qs, qx, qy, qz, nx, ny, nz):
                    c = j
                elif kmax > 1:
                    # The nearest faces another way (or lies on another surface): the
                    # nearest facing point on the row's surface, if it is among the kmax
                    # nearest (fewer than kmax points nearer).
                    bound = r2
                    if prev_cand >= 0 and normal[prev_cand, 0] * nx \
                            + normal[prev_cand, 1] * ny + normal[prev_cand, 2] * nz \
                            > GATHER_AGREEMENT and \
                            same_surface(surface, tree_pos, normal, prev_cand, qs, qx, qy,
                                         qz, nx, ny, nz):
                        bound = min(bound, _seed_bound(tree_pos, prev_cand, qx, qy, qz))
                    j, dd = kdtree.nearest_facing_on_in(tree_pos, nodes[0], nodes[1],
                                                        nodes[2], normal, surface, qs, qx, qy,
                                                        qz, nx, ny, nz, GATHER_AGREEMENT,
                                                        bound, st_node, st_off)
                    if j >= 0 and kdtree.count_closer_in(tree_pos, nodes[0], nodes[1],
                                                         nodes[2], qx, qy, qz, dd, kmax,
                                                         st_node, st_off) < kmax:
                        c = j
        if point.shape[0]:
            point[i] = c
        if c < 0:
            out[i, 0] = out[i, 1] = out[i, 2] = 0.0
            boundary[i] = True
            continue
        prev_cand = c
        out[i, 0], out[i, 1], out[i, 2] = E[c, 0], E[c, 1], E[c, 2]
        boundary[i] = E_boundary[c]
        if not want_rays:
            continue
        # The ray's ends from scalars (_ray_ends): a kernel called with arrays pays ~14 ns
        # per array (reference counts) when it is not inlined, ~0.1 us a ray here.
        # (the points' float32 position and normal, as float64: _ray_ends' arithmetic)
        ox, oy, oz, dx, dy, dz, t = _ray_ends(
            qx, qy, qz, nx, ny, nz, q[r, 6], np.float64(position[c, 0]),
            np.float64(position[c, 1]), np.float64(position[c, 2]),
            np.float64(normal[c, 0]), np.float64(normal[c, 1]), np.float64(normal[c, 2]))
        o32[nrays, 0], o32[nrays, 1], o32[nrays, 2] = ox, oy, oz
        d32[nrays, 0], d32[nrays, 1], d32[nrays, 2] = dx, dy, dz
        t32[nrays] = t
        ray_row[nrays] = r
        nrays += 1
    return nrays


@kernel
def _query_lift(lift, i, qx, qy, qz):
    """The query's own offset along its normal: lift[i], else (lift empty) 4 float32
    ulps of p[i] = (qx, qy, qz)."""
    if lift.shape[0]:
        return lift[i]
    return 4.0 * ulp32_scalar(max(abs(qx), abs(qy), abs(qz)))


@kernel
def _ray_ends(qx, qy, qz, nx, ny, nz, la, bx, by, bz, mx, my, mz):
    """The visibility ray from a query q = (qx, qy, qz) with unit normal (nx, ny, nz) and
    own offset la (_query_lift) to a gather point b = (bx, by, bz) with normal
    (mx, my, mz): (origin x, y, z, unit direction x, y, z, length), float64, which the
    callers store in Embree's float32 arrays. Both ends lifted off their surfaces along
    their normals (shared by agreement) by bounds on their rounding error
    (engine/rayoffset.py): the query's own offset, and for the gather point (a float32
    photon position, triangle unknown) its float32 resolution plus the float32 error of
    the ray's length. Full length: a gather point a hair outside a wall is still behind it.

    A curved surface: the chord between two of its points runs inside it (on issue 14's
    Principled spheres every candidate on a ball was hidden and each lookup tried all
    kmax, 200 us). Both ends are also lifted by chord x |n - n_c| / 4, above the chord's
    depth below a sphere through both points with these normals (chord x theta / 8 for
    normals theta apart; 0.11 vs 0.19 chords at the agreement limit). Flat surfaces
    (equal normals) get no extra lift: a wall still hides the floor behind it.
    Scalars only: it runs once per lookup (docs/performance.md, "Eighth slice")."""
    ex, ey, ez = bx - qx, by - qy, bz - qz
    chord = math.sqrt(ex * ex + ey * ey + ez * ez)
    gx, gy, gz = nx - mx, ny - my, nz - mz
    bend = 0.25 * chord * math.sqrt(gx * gx + gy * gy + gz * gz)
    la += bend
    ax, ay, az = qx + la * nx, qy + la * ny, qz + la * nz
    ex, ey, ez = bx - ax, by - ay, bz - az
    dist0 = math.sqrt(ex * ex + ey * ey + ez * ez)
    lb = (4.0 * ulp32_scalar(max(abs(bx), abs(by), abs(bz))) + 2.0 * G32_PLANE * dist0
          + bend)
    bx, by, bz = bx + lb * mx, by + lb * my, bz + lb * mz
    wx, wy, wz = bx - ax, by - ay, bz - az
    dist = math.sqrt(wx * wx + wy * wy + wz * wz)
    inv = max(dist, 1e-300)
    return ax, ay, az, wx / inv, wy / inv, wz / inv, dist


@kernel
def _agreeing_lists(tree_pos, nodes, normal, surface, p, n, qsurf, rows, r2, kmax, lists,
                    counts):
    """For each row i = rows[r]: the gather points among the kmax nearest within sqrt(r2)
    whose normal agrees with n[i] and that lie on its surface (_gather_candidates'
    surface test), in increasing distance, into lists[r, :counts[r]]."""
    test_surface = surface.shape[0] > 0 and qsurf.shape[0] > 0
    d2 = np.empty(max(kmax, 1), np.float64)
    idx = np.empty(max(kmax, 1), np.int64)
    for r in range(rows.shape[0]):
        i = rows[r]
        nx, ny, nz = n[i, 0], n[i, 1], n[i, 2]
        qs = np.int64(qsurf[i]) if test_surface else np.int64(-1)
        cnt = kdtree.knn(tree_pos, nodes[0], nodes[1], nodes[2], p[i, 0], p[i, 1], p[i, 2],
                         kmax, r2, d2, idx)
        m = 0
        for jj in range(cnt):
            j = idx[jj]
            if normal[j, 0] * nx + normal[j, 1] * ny + normal[j, 2] * nz > GATHER_AGREEMENT \
                    and same_surface(surface, tree_pos, normal, j, qs, p[i, 0], p[i, 1],
                                     p[i, 2], nx, ny, nz):
                lists[r, m] = j
                m += 1
        counts[r] = m


@kernel
def _list_rays(position, normal, p, n, lift, rows, lists, counts, pending, nxt, batch, o32,
               d32, t32, slot):
    """Visibility rays to the entries [nxt[r], nxt[r] + batch) of lists[r] (clipped to
    counts[r]) of each pending r, row after row, entries in order; slot[k] = r's list
    entry of ray k. Returns the number of rays."""
    k = 0
    for q in range(pending.shape[0]):
        r = pending[q]
        i = rows[r]
        qx, qy, qz = p[i, 0], p[i, 1], p[i, 2]
        la = _query_lift(lift, i, qx, qy, qz)
        for e in range(nxt[r], min(nxt[r] + batch, counts[r])):
            c = lists[r, e]
            ox, oy, oz, dx, dy, dz, t = _ray_ends(
                qx, qy, qz, n[i, 0], n[i, 1], n[i, 2], la, np.float64(position[c, 0]),
                np.float64(position[c, 1]), np.float64(position[c, 2]),
                np.float64(normal[c, 0]), np.float64(normal[c, 1]), np.float64(normal[c, 2]))
            o32[k, 0], o32[k, 1], o32[k, 2] = ox, oy, oz
            d32[k, 0], d32[k, 1], d32[k, 2] = dx, dy, dz
            t32[k] = t
            slot[k] = e
            k += 1
    return k


@kernel
def _pick_visible(E, E_boundary, rows, lists, counts, pending, nxt, batch, blocked, slot,
                  out, boundary, point):
    """After _list_rays: each pending row takes its first entry whose ray is clear
    (out = its E, boundary its flag, point (if not empty) its index); rows with none
    clear and entries left stay pending (nxt advanced by batch). Returns the rows still
    pending."""
    still = np.empty(pending.shape[0], np.int64)
    s = 0
    k = 0
    for q in range(pending.shape[0]):
        r = pending[q]
        end = min(nxt[r] + batch, counts[r])
        found = False
        for e in range(nxt[r], end):
            if not found and not blocked[k]:
                c = lists[r, slot[k]]
                i = rows[r]
                out[i, 0], out[i, 1], out[i, 2] = E[c, 0], E[c, 1], E[c, 2]
                boundary[i] = E_boundary[c]
                if point.shape[0]:
                    point[i] = c
                found = True
            k += 1
        if not found and end < counts[r]:
            nxt[r] = end
            still[s] = r
            s += 1
    return still[:s]


@kernel
def _seed_bound(tree_pos, j, qx, qy, qz):
    """A search bound that point j certainly passes: its squared distance plus a margin
    (1e-9 relative) far above the rounding error of the traversal's incremental
    distances to cells (a few ulps), so no cell holding a point as near as j is pruned."""
    dx = qx - np.float64(tree_pos[j, 0])
    dy = qy - np.float64(tree_pos[j, 1])
    dz = qz - np.float64(tree_pos[j, 2])
    return kdtree.seed_bound(dx * dx + dy * dy + dz * dz)


@register_warm_up
def _warm_up_gather():
    rng = np.random.default_rng(0)
    m = 64
    pos = rng.random((m, 3)).astype(np.float32)
    up = np.tile(np.float32([0.0, 0.0, 1.0]), (m, 1))
    g = GatherMap(Photons(pos, np.ones((m, 3), np.float32), -up, up.copy(),
                          np.zeros(m, np.uint8)), 0.5, 8, 2, "knn_simpson")
    q = rng.random((4, 3))
    nq = np.tile([0.0, 0.0, 1.0], (4, 1))
    nbr, reach = g.neighbours
    # The uint16 neighbour table, then the int32 one (above kdtree.NARROW_NEIGHBOURS points).
    for table in (nbr, nbr.astype(np.int32)):
        g.neighbours = (table, reach)
        g.lookup(q, nq)
        g.lookup(q, nq, offset=np.full(4, 1e-6))
        g.lookup(q, nq, offset=np.full(4, 1e-6), points=True)
    # The hidden-candidate steps (they run only with an Accel).
    rows = np.arange(4)
    lists = np.empty((4, 8), np.int64)
    counts = np.empty(4, np.int64)
    _agreeing_lists(g.tree.position, g.tree.nodes, g.normal, NO_SURFACE, q, nq, NO_SURFACE,
                    rows, 0.25, 8, lists, counts)
    pending = np.nonzero(counts > 1)[0]
    nxt = np.ones(4, np.int64)
    o32, d32, t32 = np.empty((32, 3), np.float32), np.empty((32, 3), np.float32), \
        np.empty(32, np.float32)
    slot = np.empty(32, np.int64)
    out, boundary = np.zeros((4, 3)), np.ones(4, bool)
    for lift in (_NO_LIFT, np.full(4, 1e-6)):
        k = _list_rays(g.position, g.normal, q, nq, lift, rows, lists, counts, pending, nxt,
                       4, o32, d32, t32, slot)
        for point in (_NO_POINT, np.empty(4, np.int64)):
            _pick_visible(g.E, g.boundary, rows, lists, counts, pending, nxt, 4,
                          np.zeros(k, bool), slot[:k], out, boundary, point)


# Photons whose k-NN distance sets the automatic radius (a strided sample: enough for a
# median, a few ms).
RADIUS_SAMPLE = 4096


def auto_radius(diffuse_area: float, stored: int, k: int, extent: float,
                positions: np.ndarray | None = None, tree=None, workers: int = 1) -> float:
    """Max search radius (m) from the photons' own density: twice the median distance from
    a stored photon to its k-th nearest neighbour (positions: (N,3) the stored photons).
    Where photons gather (the lit part of a huge ground plane) this is the local spacing,
    not the spacing they would have if spread over all diffuse area. Without positions,
    or where that median is 0 (photons piled on a point), twice the radius of a disc that
    would hold k photons if the stored photons covered the diffuse area evenly. Never
    more than 0.1 x the scene's diagonal `extent`; no floor tied to the scene's size.
    tree: a kdtree.KdTree over the same points (a map's), queried instead of building a
    mortontree.KthTree (same distances: the k-NN distances do not depend on the tree);
    workers: threads for the queries."""
    if stored <= 0 or diffuse_area <= 0:
        return 0.05 * extent
    r = 0.0
    if positions is not None and len(positions) > k:
        step = max(1, len(positions) // RADIUS_SAMPLE)
        sample = np.asarray(positions, np.float32)[::step].astype(np.float64)
        # The nearest is the photon itself; the queries in blocks on the workers (each
        # query's answer is the same in any block). Same distances with any tree.
        rows = -(-len(sample) // max(1, workers))
        if tree is not None and hasattr(tree, "kth") and len(tree) == len(positions):
            def kth(a, stop):
                return tree.kth(sample[a:a + rows], k + 1)
        else:
            # Nothing else searches these points: a Morton box tree, built in O(N)
            # (mortontree), answers the 4,096 queries for a fraction of a kd-tree's
            # build. Its build and queries poll the stop flag of the job running on
            # this thread (a map build under run_cancellable; issue 19).
            stop = stop_array()
            tree = mortontree.KthTree(positions, stop)
            if stop[0]:
                raise Cancelled()

            def kth(a, job_stop):
                flag = stop_array(job_stop)
                out = tree.kth(sample[a:a + rows], k + 1, flag)
                if flag[0]:
                    raise Cancelled()
                return out
        r = 2.0 * float(np.median(np.concatenate(list(ordered_map(
            kth, range(0, len(sample), rows), workers)))))
    if not r > 0:
        r = 2.0 * math.sqrt(k * diffuse_area / (math.pi * stored))
    return float(min(r, 0.1 * extent))


def caustic_radius(global_radius: float, global_stored: int, caustic_stored: int, k: int,
                   diffuse_area: float, extent: float) -> float:
    """Max search radius (m) of the caustic map's k-NN estimates: the cap on the radius of
    each lookup, which takes the k nearest caustic photons. The k-NN radius follows the
    caustic photons' own density where they land: a few mm in a ball lens's focus, where
    they pile up, and wider in its halo. The cap only acts where fewer than k caustic
    photons lie within it: sparse caustics and glow. It is the global photons' radius
    (global_radius, from their spacing: auto_radius), scaled by sqrt(global_stored /
    the larger count) when the caustic map holds more photons; without a global shot,
    auto_radius's even spread of caustic_stored photons over diffuse_area m^2.

    Measured against an analytic ray bundle through a ball lens (a 0.6 m glass ball on a
    floor under a sun; bench/bench_caustic_radius.py, docs/performance.md "Caustic search
    radius"): the spot's peak, width and power match the reference at this cap (1.06, 1.00,
    1.00 at 80k photons). A cap from the caustic photons' own spacing (auto_radius over
    them: 2 x their median k-NN distance, 2.5 cm there) leaves the spot as it is (its k-NN
    radius is smaller still) and only makes the halo noisier: profile error 0.129 -> 0.154
    (80k photons), 0.123 -> 0.164 (320k), for every k from 16 to 128. So the cap stays the
    global photons' spacing."""
    dense = max(global_stored, caustic_stored, 1)
    if global_stored > k:
        return global_radius * math.sqrt(global_stored / dense)
    return auto_radius(diffuse_area, dense, k, extent)
