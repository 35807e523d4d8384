"""The photon map's estimators as they were before the compiled kernels (numpy on scipy's
cKDTree, commit 21e8e1d): the oracle that tests/test_photon_lookup.py checks the compiled
estimators (engine/photonmap.py) against, estimate by estimate.

Kept verbatim apart from names, so any difference is the kernels' (a test-only copy: the
engine no longer uses cKDTree on a per-sample path)."""
from __future__ import annotations

import copy
import math

import numpy as np
from scipy.spatial import cKDTree

from engine.parallel import ordered_map
from engine.photonmap import (BOUNDARY_LOG, BOUNDARY_OFFSET, MAX_CLASSIC_K, MAX_WIDEN_K,
                              MIN_RADIUS_FRACTION, NORMAL_AGREEMENT,
                              SPARSE_MIN_ACCEPTED)
from engine.photons import Photons

QUERY_BUDGET = 1 << 21  # rows * k per kd-tree query call: bounds memory
DENSE_FRACTION = 0.8   # skip the min-photons pre-query when this share of a sample is busy


def max3(a):
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2])


class ReferencePhotonMap:
    def __init__(self, photons: Photons, workers: int = 1):
        self.photons = photons
        self.workers = workers
        self.tree = None
        if len(photons):
            # Unbalanced build: many identical points (a focused caustic) make the
            # balanced median build pathological.
            self.tree = cKDTree(photons.position.astype(np.float64), balanced_tree=False,
                                compact_nodes=False)

    def __len__(self):
        return len(self.photons)

    def serial(self) -> "ReferencePhotonMap":
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
            truncated = counts[a:a + rows] > kq if estimator in ("classic", "radius") else None
            E, mix = pm._estimate(p[sel], n[sel], radius, kq, k, min_photons, estimator,
                                  return_boundary,
                                  None if r_floor is None else r_floor[sel], truncated)
            if estimator == "classic":
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
                  r_floor=None, truncated=None):
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
                                                None if r_floor is None else r_floor[todo],
                                                None if truncated is None else truncated[todo])
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
                       r_floor=None, truncated=None):
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
            # More than kq photons in the radius (truncated): the Simpson kernel narrows to
            # the gathered photons' disc (scaling by all / gathered would weigh the nearest,
            # heaviest photons for the missing ones: 1.8x too bright).
            rs = np.full(len(p), radius)
            if truncated is not None and truncated.any():
                rs = np.where(truncated, np.maximum(np.where(found[:, -1], dist[:, -1], radius),
                                                    MIN_RADIUS_FRACTION * radius), radius)
            rs = rs[:, None]
            x = np.clip(1.0 - (np.where(found, dist, rs) / rs) ** 2, 0.0, 1.0)
            weight = np.where(ok, 3.0 / (math.pi * rs * rs) * x * x, 0.0)
        else:
            # r: distance to the k-th accepted photon; with fewer accepted (at least
            # SPARSE_MIN_ACCEPTED), to the last accepted one (the k-NN estimate with k =
            # their count: a small object's surface need not fill the max radius's disc);
            # with fewer still, the radius of the disc the query has seen completely (its
            # last photon, or the max radius).
            accepted = np.cumsum(ok, axis=1)
            m_acc = np.minimum(accepted[:, -1], k)
            have_k = m_acc >= min(k, SPARSE_MIN_ACCEPTED)
            kth = np.argmax(accepted >= np.maximum(m_acc, 1)[:, None], axis=1)
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
        # needs a 100 % change across r to reach it); with fewer than ~24 photons, more
        # than a whole disc's n photons exceed with probability BOUNDARY_FALSE_ALARM.
        use = ok & inside
        m = np.maximum(np.count_nonzero(use, axis=1), 1)[:, None]
        rel = (np.take(ph.position, safe, axis=0) - p[:, None, :].astype(np.float32))
        c = np.einsum("nk,nkc->nc", use.astype(np.float32), rel) / m
        c -= np.einsum("nc,nc->n", c, n)[:, None] * n
        offset = np.sqrt(np.einsum("nc,nc->n", c, c)) / d_max[:, 0]
        limit = np.maximum(BOUNDARY_OFFSET, np.sqrt(BOUNDARY_LOG / (2.0 * m[:, 0])))
        boundary |= offset > limit
        return E, widen, boundary
