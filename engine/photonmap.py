"""Photon maps: a kd-tree over stored photons and the irradiance estimators.

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
from scipy.spatial import cKDTree

from .parallel import ordered_map
from .photons import Photons
from .rayoffset import G32_PLANE, ulp32
from .sampling import max3

NORMAL_AGREEMENT = 0.5
BOUNDARY_OFFSET = 0.25  # centroid offset / r that marks an estimate's disc as cut off
MAX_CLASSIC_K = 4096
MAX_WIDEN_K = 4096  # k-NN queries widen up to this many photons to find k accepted ones
# The k-NN radius never shrinks below this share of the search radius. A lens focusing a
# point light piles k photons onto a point; a smaller disc makes the estimate there huge,
# and the few camera samples that land on it become fireflies (the Figure 8 focus, seen
# magnified through the ball: one pixel at 939 x the image mean). The photons inside the
# floor disc are all counted (_estimate_rows), so light is spread over it, never lost.
MIN_RADIUS_FRACTION = 0.01
QUERY_BUDGET = 1 << 21  # rows * k per kd-tree query call: bounds memory
DENSE_FRACTION = 0.8   # skip the min-photons pre-query when this share of a sample is busy


class PhotonMap:
    def __init__(self, photons: Photons, workers: int = 1):
        self.photons = photons
        self.workers = workers
        self.tree = None
        if len(photons):
            # Unbalanced build: many identical points (a focused caustic) make the
            # balanced median build pathological (docs/design.md, kd-tree (scipy) facts).
            self.tree = cKDTree(photons.position.astype(np.float64), balanced_tree=False,
                                compact_nodes=False)

    def __len__(self):
        return len(self.photons)

    def serial(self) -> "PhotonMap":
        """The same map, queried on the calling thread only (the caller runs chunks on
        threads already, engine/parallel.py)."""
        view = copy.copy(self)
        view.workers = 1
        return view

    def irradiance(self, p: np.ndarray, n: np.ndarray, radius: float, k: int,
                   min_photons: int, estimator: str, return_boundary: bool = False,
                   r_floor: np.ndarray | None = None):
        """Irradiance estimate at points p with unit normals n (facing the viewer).
        return_boundary: also return, per point, whether the estimate's disc is not whole:
        photons of another surface lay inside it (a corner or contact) or its photons lie
        off to one side (an open edge), or it had too few photons for an estimate (0).
        There the estimate is biased dark.
        r_floor: per point, the smallest k-NN radius (a camera sample's pixel footprint):
        a focus is spread over at least that disc instead of a point."""
        out = np.zeros((len(p), 3))
        boundary = np.ones(len(p), bool)  # rows with no estimate keep True
        result = (out, boundary) if return_boundary else out
        if self.tree is None or len(p) == 0 or radius <= 0:
            return result
        # A cheap query for the min_photons nearest tells which points have enough photons
        # in range; only those pay for the k-NN query (most queries of a sparse caustic map).
        m = int(min(min_photons, len(self.photons)))
        if len(self.photons) < min_photons:
            return result
        # Where nearly every point is busy (a global map, the gather-map build) the cheap
        # query is pure overhead (~25 % of the k-NN query): a strided sample decides.
        # Skipping it changes nothing: a row with fewer than m photons in range gets
        # count < min_photons in _estimate and is zeroed there too.
        step = 32
        if len(p) >= 8 * step:
            ds, _ = self.tree.query(p[::step], k=m, distance_upper_bound=radius,
                                    workers=self.workers)
            dense = np.isfinite(ds.reshape(len(ds), -1)[:, -1]).mean() > DENSE_FRACTION
        else:
            dense = False
        if dense:
            busy = np.arange(len(p))
        else:
            dm, _ = self.tree.query(p, k=m, distance_upper_bound=radius, workers=self.workers)
            dm = dm.reshape(len(p), -1)
            busy = np.nonzero(np.isfinite(dm[:, -1]))[0]
        if len(busy) == 0:
            return result
        if estimator in ("classic", "radius"):
            counts = self.tree.query_ball_point(p[busy], radius, return_length=True,
                                                workers=self.workers)
            kq = int(min(max(int(counts.max()), 1), MAX_CLASSIC_K, len(self.photons)))
        else:
            kq = int(min(k, len(self.photons)))
        rows = max(1, QUERY_BUDGET // kq)
        if self.workers > 1:
            # Blocks on worker threads (the numpy part of the estimate too). Rows are
            # independent, so the block size does not change any result.
            rows = min(rows, max(4096, -(-len(busy) // (2 * self.workers))))
        blocks = range(0, len(busy), rows)
        threads = self.workers if len(blocks) > 1 else 1
        pm = self.serial() if threads > 1 else self

        def job(a, stop):
            sel = busy[a:a + rows]
            E, mix = pm._estimate(p[sel], n[sel], radius, kq, k, min_photons, estimator,
                                  return_boundary,
                                  None if r_floor is None else r_floor[sel])
            if estimator in ("classic", "radius"):
                # A dense caustic can hold more than MAX_CLASSIC_K photons in the radius;
                # the query returned the nearest kq of them. Scale by all / gathered so
                # the fixed-radius estimate is not capped (stand-in for the missing ones).
                c = counts[a:a + rows].astype(np.float64)
                E *= np.maximum(c / kq, 1.0)[:, None]
            return sel, E, mix

        for sel, E, mix in ordered_map(job, blocks, threads):
            out[sel] = E
            boundary[sel] = mix
        return result

    def _estimate(self, p, n, radius, kq, k, min_photons, estimator, want_boundary=False,
                  r_floor=None):
        """Estimate at rows p. k-NN estimators use the k nearest *accepted* photons (facing
        the query's surface): where photons of another surface crowd the k nearest (a
        corner, an object resting on the floor) the query widens, up to MAX_WIDEN_K,
        while fewer than k / 2 of them are left."""
        out = np.zeros((len(p), 3))
        boundary = np.zeros(len(p), bool)
        todo = np.arange(len(p))
        P = len(self.photons)
        knn = estimator not in ("classic", "radius")
        while len(todo):
            E, widen, mix = self._estimate_rows(p[todo], n[todo], radius, kq, k, min_photons,
                                                estimator, want_boundary,
                                                None if r_floor is None else r_floor[todo])
            last = not knn or not widen.any() or kq >= min(P, MAX_WIDEN_K)
            done = np.ones(len(todo), bool) if last else ~widen
            out[todo[done]] = E[done]
            if want_boundary:
                boundary[todo[done]] = mix[done]
            if last:
                break
            todo = todo[widen]
            kq = min(4 * kq, P, MAX_WIDEN_K)
        return out, boundary

    def _estimate_rows(self, p, n, radius, kq, k, min_photons, estimator, want_boundary,
                       r_floor=None):
        dist, idx = self.tree.query(p, k=kq, distance_upper_bound=radius, workers=self.workers)
        if kq == 1:
            dist, idx = dist[:, None], idx[:, None]
        P = len(self.photons)
        found = idx < P  # scipy returns idx = P where nothing was found
        # Any valid row stands in for 'not found' (masked below); np.take(axis=0) gathers
        # rows ~4x faster than fancy indexing.
        safe = np.minimum(idx, P - 1)
        ph = self.photons
        gd = np.take(ph.direction, safe, axis=0)
        gn = np.take(ph.normal, safe, axis=0)
        n32 = n.astype(np.float32)
        nx, ny, nz = n32[:, None, 0], n32[:, None, 1], n32[:, None, 2]
        # Dot products per component (same float32 products and left-to-right sums as an
        # einsum, no (N,k,3) temporaries).
        cos_in = -(gd[..., 0] * nx + gd[..., 1] * ny + gd[..., 2] * nz)
        other_surface = found & ((gn[..., 0] * nx + gn[..., 1] * ny + gn[..., 2] * nz)
                                 <= NORMAL_AGREEMENT)
        ok = found & (cos_in > 0) & ~other_surface
        del gd, gn
        widen = np.zeros(len(p), bool)
        knn = estimator not in ("classic", "radius")
        d_max = np.full((len(p), 1), radius)
        if estimator == "classic":
            weight = np.where(ok, cos_in, 0.0) / (math.pi * radius * radius)
        elif estimator == "radius":
            x = np.clip(1.0 - (np.where(found, dist, radius) / radius) ** 2, 0.0, 1.0)
            weight = np.where(ok, 3.0 / (math.pi * radius * radius) * x * x, 0.0)
        else:
            # r: distance to the k-th accepted photon; with fewer accepted, the radius of
            # the disc the query has seen completely (its last photon, or the max radius).
            accepted = np.cumsum(ok, axis=1)
            have_k = accepted[:, -1] >= k
            kth = np.argmax(accepted >= k, axis=1)
            full = found[:, -1]  # the query stopped at kq photons: more may lie beyond
            # Fewer than k accepted: the disc the query has seen (radius of its last
            # photon) still gives an unbiased estimate from the accepted photons in it,
            # only a noisier one. Widen only when fewer than half are left (a crowded
            # neighbour surface); a few photons arriving from behind are not worth a 4x
            # query.
            widen = (accepted[:, -1] < k // 2) & full
            rows = np.arange(len(p))
            r = np.where(have_k, dist[rows, kth], np.where(full, dist[:, -1], radius))
            # k photons on (nearly) the query point, as a focusing lens makes: the k-th
            # distance is 0 and 1/r^2 would be inf. Floor r (MIN_RADIUS_FRACTION), and at
            # a resolution the float32 photon positions can represent.
            r_min = np.maximum(1e-6 * max3(np.abs(p)), max(MIN_RADIUS_FRACTION * radius, 1e-15))
            if r_floor is not None:
                r_min = np.maximum(r_min, np.minimum(r_floor, radius))
            floored = full & (r < r_min)  # the floor disc may hold more than the kq fetched
            r = np.maximum(r, r_min)[:, None]
            d = np.where(found, dist, 0.0)
            if estimator == "knn_simpson":
                x = np.clip(1.0 - (d / r) ** 2, 0.0, 1.0)
                weight = np.where(ok, 3.0 / (math.pi * r * r) * x * x, 0.0)
            else:  # knn_cone
                weight = np.where(ok, np.clip(1.0 - d / r, 0.0, 1.0), 0.0)
                weight = weight / ((1.0 - 2.0 / 3.0) * math.pi * r * r)
            ok &= d <= r  # accepted photons beyond the k-th do not count towards the minimum
            d_max = r
        count = np.count_nonzero(ok, axis=1)
        # float64: weights near a focus exceed float32's range.
        E = np.einsum("nk,nkc->nc", weight, np.take(ph.power, safe, axis=0).astype(np.float64))
        if knn and floored.any():
            # A focus: more photons lie inside the floored disc than the query fetched.
            # There the estimate is the disc's photon count times the fetched photons'
            # mean accepted power, over pi r^2 (a box kernel): every photon spreads its
            # power over a disc of r, so the focus's light is spread, never dropped.
            f = np.nonzero(floored)[0]
            in_disc = self.tree.query_ball_point(p[f], r[f, 0], return_length=True,
                                                 workers=self.workers)
            fetched = np.count_nonzero(found[f] & (dist[f] <= r[f]), axis=1)
            accepted_power = np.einsum("nk,nkc->nc", ok[f].astype(np.float64),
                                       np.take(ph.power, safe[f], axis=0).astype(np.float64))
            E[f] = (in_disc / np.maximum(fetched, 1))[:, None] * accepted_power / (
                math.pi * r[f] * r[f])
        E[count < min_photons] = 0.0
        if not want_boundary:
            return E, widen, None
        inside = dist <= d_max
        # Too few photons for an estimate (E = 0) counts as boundary too: gather again.
        boundary = (other_surface & inside).any(axis=1) | (count < min_photons)
        # An open edge (a table's rim, the end of a floor) leaves no other surface's
        # photons, but the accepted ones lie off to one side: their centroid, in the
        # tangent plane, is more than BOUNDARY_OFFSET x r from the point (a half disc
        # gives 0.42 r; 64 photons of a whole disc scatter it by ~0.08 r; a gradient
        # needs a 100 % change across r to reach it).
        use = ok & inside
        m = np.maximum(np.count_nonzero(use, axis=1), 1)[:, None]
        rel = (np.take(ph.position, safe, axis=0) - p[:, None, :].astype(np.float32))
        c = np.einsum("nk,nkc->nc", use.astype(np.float32), rel) / m
        c -= np.einsum("nc,nc->n", c, n)[:, None] * n
        offset = np.sqrt(np.einsum("nc,nc->n", c, c)) / d_max[:, 0]
        boundary |= offset > BOUNDARY_OFFSET
        return E, widen, boundary


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
    """

    def __init__(self, photons: Photons, radius: float, k: int, min_photons: int,
                 estimator: str, max_points: int = 60_000, accel=None,
                 workers: int = 1):
        ph = photons
        self.workers = workers
        # With an Accel, a lookup only takes a gather point it can see: a point on the
        # other side of a wall (e.g. the ground outside a room, coplanar with the floor
        # inside) would otherwise leak light under the wall (docs/stability.md).
        self.accel = accel
        self.tree = None
        if len(ph) < 2:
            return
        step = max(4, int(math.ceil(len(ph) / max_points)))
        is_point = np.zeros(len(ph), bool)
        is_point[::step] = True
        others = ph.select(~is_point)
        others.power = others.power * np.float32(len(ph) / len(others))
        self.position = ph.position[is_point].astype(np.float64)
        self.normal = ph.normal[is_point].astype(np.float64)
        self.E, self.boundary = PhotonMap(others, workers).irradiance(
            self.position, self.normal, radius, k, min_photons, estimator, return_boundary=True)
        self.radius = radius
        self.tree = cKDTree(self.position, balanced_tree=False, compact_nodes=False)

    def serial(self) -> "GatherMap":
        """The same map, queried on the calling thread only (see PhotonMap.serial)."""
        view = copy.copy(self)
        view.workers = 1
        if self.accel is not None:
            view.accel = self.accel.serial()
        return view

    def lookup(self, p: np.ndarray, n: np.ndarray, candidates: int = 8,
               offset: np.ndarray | None = None):
        """(irradiance, boundary) at the nearest visible gather point facing the same way.
        boundary: that point's estimate met another surface (a corner or contact), where
        the estimate is biased dark, or no such point was found in range (a sparsely lit
        patch crowded by another surface's gather points, e.g. the underside of a ball
        resting on a lit floor); those rows get irradiance 0 and should gather again.
        offset: (N,) distance along n that takes a ray from p clear of p's surface
        (SurfaceHit.offset); default: the float32 resolution at p."""
        out = np.zeros((len(p), 3))
        boundary = np.ones(len(p), bool)
        if self.tree is None or len(p) == 0:
            return out, boundary
        todo = np.arange(len(p))
        # Most points' nearest gather point already faces their way: one neighbour first
        # (a k=8 kd-tree query costs 3x a k=1 query), more only for the rest. The first
        # agreeing, visible candidate in distance order is the same either way.
        for kq in (1, candidates, 8 * candidates):
            kq = min(kq, len(self.position))
            chosen, found = self._nearest_agreeing(p[todo], n[todo], kq,
                                                   None if offset is None else offset[todo])
            out[todo[found]] = self.E[chosen[found]]
            boundary[todo[found]] = self.boundary[chosen[found]]
            todo = todo[~found]
            if len(todo) == 0 or kq == len(self.position):
                break
        return out, boundary

    def _nearest_agreeing(self, p, n, kq, offset=None):
        dist, idx = self.tree.query(p, k=kq, distance_upper_bound=self.radius,
                                    workers=self.workers)
        if kq == 1:
            dist, idx = dist[:, None], idx[:, None]
        found = idx < len(self.position)
        safe = np.where(found, idx, 0)
        agree = found & (np.einsum("nkc,nc->nk", np.take(self.normal, safe, axis=0), n) > 0.7)
        if self.accel is not None:
            agree = self._visible_first(p, n, safe, agree, offset)
        first = np.argmax(agree, axis=1)
        anyok = agree.any(axis=1)
        return safe[np.arange(len(p)), first], anyok

    def _visible_first(self, p, n, safe, agree, offset=None):
        """Drop candidates hidden from p by geometry, nearest first, until each row's first
        remaining candidate is visible (usually one occlusion ray per lookup)."""
        agree = agree.copy()
        todo = np.nonzero(agree.any(axis=1))[0]
        for _ in range(agree.shape[1]):
            if len(todo) == 0:
                break
            first = np.argmax(agree[todo], axis=1)
            q = self.position[safe[todo, first]]
            # Both ends lifted off their surfaces along the normal (shared by agreement),
            # by bounds on their rounding error (engine/rayoffset.py): the query point's
            # own offset, and for the gather point (a float32 photon position, triangle
            # unknown) its float32 resolution plus the float32 error of the ray's length.
            lift_a = (4.0 * ulp32(max3(np.abs(p[todo]))) if offset is None
                      else offset[todo])
            a = p[todo] + lift_a[:, None] * n[todo]
            dist0 = np.linalg.norm(q - a, axis=1)
            lift_b = 4.0 * ulp32(max3(np.abs(q))) + 2.0 * G32_PLANE * dist0
            b = q + lift_b[:, None] * self.normal[safe[todo, first]]
            w = b - a
            dist = np.linalg.norm(w, axis=1)
            d = w / np.maximum(dist, 1e-300)[:, None]
            # Full length: a gather point a hair outside a wall is still behind it.
            blocked = self.accel.occluded(a, d, dist)
            agree[todo[blocked], first[blocked]] = False
            todo = todo[blocked & agree[todo].any(axis=1)]
        return agree


# Photons whose k-NN distance sets the automatic radius (a strided sample: enough for a
# median, a few ms).
RADIUS_SAMPLE = 4096


def auto_radius(diffuse_area: float, stored: int, k: int, extent: float,
                positions: np.ndarray | None = None) -> float:
    """Max search radius (m) from the photons' own density: twice the median distance from
    a stored photon to its k-th nearest neighbour (positions: (N,3) the stored photons).
    Where photons gather (the lit part of a huge ground plane) this is the local spacing,
    not the spacing they would have if spread over all diffuse area. Without positions,
    or where that median is 0 (photons piled on a point), twice the radius of a disc that
    would hold k photons if the stored photons covered the diffuse area evenly. Never
    more than 0.1 x the scene's diagonal `extent`; no floor tied to the scene's size."""
    if stored <= 0 or diffuse_area <= 0:
        return 0.05 * extent
    r = 0.0
    if positions is not None and len(positions) > k:
        pts = np.asarray(positions, np.float64)
        step = max(1, len(pts) // RADIUS_SAMPLE)
        tree = cKDTree(pts, balanced_tree=False, compact_nodes=False)
        d, _ = tree.query(pts[::step], k=k + 1)  # the nearest is the photon itself
        r = 2.0 * float(np.median(d[:, -1]))
    if not r > 0:
        r = 2.0 * math.sqrt(k * diffuse_area / (math.pi * stored))
    return float(min(r, 0.1 * extent))
