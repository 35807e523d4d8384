"""Precomputed irradiance at the stored photons (Christensen, "Faster photon map global
illumination", JGT 4(3) 1999; Jensen, "Realistic Image Synthesis Using Photon Mapping"
2001, sec. 7.?): the caustic map's k-NN estimate is taken once at each stored photon, and
a lookup reads the estimate of the nearest photon whose surface faces the query's way (one
nearest-point walk of the map's kd-tree) instead of listing and sorting its k nearest.

Caustic lookups at the camera hits (~1.3M on Figure 8) far outnumber caustic photons
(~175k), so the precompute pays for itself; a lookup costs a fraction of a k-NN row.

What the k-NN rows guarantee, kept:
- No bias on flat regions. An estimate taken *at* photon j holds j itself at d = 0 with
  the kernel's largest weight (3 / (pi rk^2), Simpson and cone alike): +3/(k - 2) on a
  uniform caustic. But a lookup reads the photon *nearest* its point x, and the disc
  B(x, d) around x, d = |x - x_j|, holds no photon: j's estimate misses B's share of its
  kernel (Voronoi selection: photons with large empty cells are read more often). For a
  Poisson (uniform) caustic both are exact (own_term_removed): with beta = d^2 / rk^2
  ~ Beta(1, k - 1) and T = lambda pi rk^2 ~ Gamma(k) independent (the empty disc and the
  (k - 1)-th other photon's ring are disjoint regions), j's other k - 2 photons inside rk
  are uniform on its disc minus B, so E[lookup] / lambda = (w + (k - 2) J) / (k - 1),
  J = E[(1 - I(beta)) / (1 - beta)], I = the kernel's mass inside B. To first order the
  own term and the empty disc cancel (+3/k, -3/k); the rest (+0.42 % at k = 64, +6 % at
  k = 16, the kernel's curvature across B) is removed by giving j the weight
  w = (k - 1) - (k - 2) J instead of 3 (k = 64: the model's mean against a direct
  Poisson simulation within 0.02 %, tests/test_causticcache.py). The ACCEPT cut below
  selects rows too (the rows it sends to the k-NN row sit in sparser spots than their
  photon's disc: -4 % at k = 16); it rejects (1 - ACCEPT^2)^(k - 1) of a uniform
  caustic's rows, so the lookup is used only where that is below 1 % (k >= MIN_K, 50 at
  ACCEPT = 0.3): k = 64 rejects 0.26 %.
- Sharp edges: the nearest photon is accepted only within ACCEPT x its own rk (the
  nearest-photon distance on a uniform disc of k = 64 exceeds 0.3 rk with probability
  exp(-64 x 0.09) = 0.3 %); farther queries (outside a caustic's rim, sparse regions) take
  the k-NN row itself.
- Boundary handling: photons whose own estimate is flagged as boundary (another surface
  inside the disc, an open edge, too few photons), whose k nearest are not all accepted,
  whose rk is floored (a focus) or capped (fewer than k in the radius) store no estimate;
  queries reaching them, queries whose pixel footprint (r_floor) exceeds the photon's rk
  (the focus floor), and masked calls (chaincounts' subsets) take the k-NN row. Those rows
  are the k-NN rows' own bits.
- Fixed memory: 16 bytes a photon (E as float32 (N,3), rk as float32 (N,); rk = 0 marks
  "no estimate"), on the map's own tree: no second structure.
"""
from __future__ import annotations

import math
import threading

import numpy as np

from . import kdtree
from .jit import kernel
from .parallel import ordered_map
from .photonlayout import powers, read_vector, vectors
from .photonmap import _accepted
from .samesurface import NO_SURFACE, query_surfaces, same_surface, surface_ids

ACCEPT = 0.3  # a lookup reads the nearest photon's estimate within ACCEPT x its rk
# The smallest k whose uniform-caustic rows the ACCEPT cut sends to the k-NN row less than
# 1 % of the time ((1 - ACCEPT^2)^(k - 1) < 0.01): below it the cut's own selection biases.
MIN_K = 1 + math.ceil(math.log(0.01) / math.log(1 - ACCEPT * ACCEPT))
NORMAL_AGREEMENT = 0.5  # photonmap.NORMAL_AGREEMENT: the same "same surface" test
MIN_RADIUS_FRACTION = 0.01  # photonmap.MIN_RADIUS_FRACTION: rk's floor (a focus)
PRE_ROWS = 1 << 15  # photons per precompute job
LIST_CAP = 512  # photons a precompute sphere lists (photonmap.CAND_CAP)
BYTES_PER_PHOTON = 16

_lock = threading.Lock()  # one precompute per map and parameters, whichever thread asks


def _kernel_mass_in_empty_disc(beta, estimator):
    """I(beta): the mass of the unit-radius estimate kernel (knn_simpson: 3/pi (1 - rho^2)^2,
    knn_cone: 3/pi (1 - rho)) inside the disc of radius s = sqrt(beta) centred at distance s
    from the kernel's centre (a lookup's empty disc B, its edge through the photon).
    beta: (M,) floats in [0, 1/4] (B inside the kernel's support). Simpson in closed form
    (the moments of a disc: (1 - beta)^3 - (1 - 2 beta)^3 + 3 beta^3); the cone by a
    Gauss-Legendre product rule over B in polar coordinates about its centre."""
    beta = np.asarray(beta, np.float64)
    if estimator == "knn_simpson":
        return (1 - beta) ** 3 - (1 - 2 * beta) ** 3 + 3 * beta ** 3
    s = np.sqrt(beta)[:, None, None]
    u, wu = np.polynomial.legendre.leggauss(24)
    t = 0.5 * (u + 1)  # radius fraction in B
    th = np.pi * (u + 1)  # angle about B's centre
    rho = np.sqrt((s + s * t[None, :, None] * np.cos(th)[None, None, :]) ** 2
                  + (s * t[None, :, None] * np.sin(th)[None, None, :]) ** 2)
    f = 3 / np.pi * np.clip(1 - rho, 0, None)
    # dA = (s t) (s dt) dtheta; dt = du / 2, dtheta = pi du
    return (f * (s * s * t[None, :, None]) * (0.5 * wu)[None, :, None]
            * (np.pi * wu)[None, None, :]).sum(axis=(1, 2))


def own_term_removed(k: int, estimator: str) -> float:
    """The fraction f of a photon's own kernel term (3 / (pi rk^2) x its power) removed
    from its stored estimate so that a lookup (the nearest photon's estimate) has the k-NN
    rows' mean on a uniform (Poisson) caustic: its own weight w = (k - 1) - (k - 2) J,
    f = (3 - w) / 3 (module docstring; J by quadrature over beta ~ Beta(1, k - 1) on
    [0, 1/4], where the empty disc lies inside the kernel: beyond it a mass of (3/4)^(k-1),
    1e-8 at k = 64). k >= 3; f -> 0 as k grows (knn_simpson: k = 64 0.089, 256 0.023;
    knn_cone: k = 64 0.19)."""
    if k < 3:
        return 0.0
    b_max = 0.25
    u, wu = np.polynomial.legendre.leggauss(64)
    beta = 0.5 * b_max * (u + 1)
    pdf = (k - 1) * (1 - beta) ** (k - 2) * 0.5 * b_max * wu
    j = (pdf * (1 - _kernel_mass_in_empty_disc(beta, estimator)) / (1 - beta)).sum() \
        / pdf.sum()
    w = (k - 1) - (k - 2) * j
    return float((3.0 - w) / 3.0)


@kernel
def _lookup_rows(pos, axis, split, leaf, normal, surface, E, rk, p, n, qsurf, r_floor, r2,
                 accept, out, boundary, miss):
    """Rows i of p / n (float64 (M,3)): the nearest photon j facing n[i] within sqrt(r2)
    with rk[j] > 0, |p - x_j| <= accept rk[j] and r_floor[i] <= rk[j] (r_floor empty:
    none), on the query's surface qsurf[i] (samesurface.same_surface; surface or qsurf
    empty: not tested), gives out[i] = E[j], boundary[i] = False; other rows set
    miss[i] = True (the caller takes their k-NN rows)."""
    st_node, st_off = kdtree.traversal_stack()
    use_floor = r_floor.shape[0] > 0
    test_surface = surface.shape[0] > 0 and qsurf.shape[0] > 0
    a2 = accept * accept
    for i in range(p.shape[0]):
        nx, ny, nz = np.float32(n[i, 0]), np.float32(n[i, 1]), np.float32(n[i, 2])
        j, dj = kdtree.nearest_facing_in(pos, axis, split, leaf, normal, p[i, 0], p[i, 1],
                                         p[i, 2], nx, ny, nz, NORMAL_AGREEMENT, r2,
                                         st_node, st_off)
        hit = j >= 0
        if hit:
            rj = np.float64(rk[j])
            hit = rj > 0.0 and dj <= a2 * rj * rj and not (use_floor and r_floor[i] > rj)
        if hit and test_surface:
            # The nearest facing photon lies on another surface (a floor photon under a
            # small ball's top): the k-NN row answers, as it would by its photons.
            hit = same_surface(surface, pos, normal, j, np.int64(qsurf[i]), p[i, 0], p[i, 1],
                               p[i, 2], nx, ny, nz)
        if hit:
            out[i, 0] = E[j, 0]
            out[i, 1] = E[j, 1]
            out[i, 2] = E[j, 2]
            boundary[i] = False
        else:
            miss[i] = True


class PrecomputedIrradiance:
    """The caustic estimate at each photon of `pmap` (a kd-tree PhotonMap) for one set of
    estimate parameters. E: (N,3) float32 W/m^2 (the photon's own term removed), rk: (N,)
    float32 m (0: no estimate here). estimate(p, n, ...) -> the PhotonMap.irradiance answer
    from them, its k-NN rows where they cannot answer (module docstring)."""

    def __init__(self, pmap, radius: float, k: int, min_photons: int, estimator: str,
                 should_cancel=None, surfaces: bool = True):
        """surfaces: the estimates test the photons' surfaces (Photons.surface, where
        known: each photon's estimate at its own surface); False: the normal test alone,
        for queries that give no surface."""
        ph = pmap.photons
        t = pmap.tree
        m = len(ph)
        self.radius = float(radius)
        pos64 = ph.position.astype(np.float64)
        n64 = vectors(ph.normal)  # (float64; decoded where the map is compact)
        rk = np.zeros(m, np.float32)
        axis, split, leaf = t.nodes
        big = np.abs(ph.position).max() if m else 0.0
        r_min = max(1e-6 * float(big), MIN_RADIUS_FRACTION * radius, 1e-15)
        surfaces = surfaces and ph.surface is not None
        # (-1: unknown; photonmap._accepted reads a photon's surface without a branch)
        surf = surface_ids(ph) if surfaces else np.full(m, -1, np.int32)

        def job(a, stop):
            b = min(a + PRE_ROWS, m)
            _photon_radii_from(t.position, axis, split, leaf, ph.direction, ph.normal, surf,
                               int(k), float(radius) ** 2, r_min * r_min, a, rk[a:b])
            return None

        for _ in ordered_map(job, range(0, m, PRE_ROWS), pmap.workers, should_cancel):
            pass
        # The estimates only where a lookup may read them (rk > 0).
        rows = np.flatnonzero(rk > 0)
        E, bnd = pmap.knn_irradiance(
            np.take(pos64, rows, axis=0), np.take(n64, rows, axis=0), radius, k,
            min_photons, estimator, return_boundary=True, should_cancel=should_cancel,
            surface=np.take(surf, rows) if surfaces else None)
        r = np.take(rk, rows).astype(np.float64)
        keep = ~bnd & (r >= r_min) & (E.sum(axis=1) > 0)
        r = np.where(keep, r, 1.0)
        own = 3.0 / (math.pi * r * r)[:, None] \
            * powers(ph.power, rows) \
            * own_term_removed(k, estimator)
        self.E = np.zeros((m, 3), np.float32)
        self.E[rows] = np.where(keep[:, None], E - own, 0.0)
        self.rk = np.zeros(m, np.float32)
        self.rk[rows] = np.where(keep, np.take(rk, rows), np.float32(0.0))
        keep = self.rk > 0
        self.stored = int(keep.sum())

    @property
    def nbytes(self) -> int:
        return self.E.nbytes + self.rk.nbytes

    def estimate(self, pmap, p, n, radius, k, min_photons, estimator, return_boundary,
                 r_floor, should_cancel, surface=None):
        """PhotonMap.irradiance(p, n, ...) without masks, through the precomputed
        estimates (rows they cannot answer: pmap.knn_irradiance). surface: the queries'
        (M,) object ids, as PhotonMap.knn_irradiance's."""
        m = len(p)
        out = np.zeros((m, 3))
        boundary = np.ones(m, bool)
        miss = np.zeros(m, bool)
        p = np.ascontiguousarray(p, dtype=np.float64)
        n = np.ascontiguousarray(n, dtype=np.float64)
        floor = (np.zeros(0) if r_floor is None
                 else np.ascontiguousarray(np.broadcast_to(r_floor, (m,)), dtype=np.float64))
        t = pmap.tree
        axis, split, leaf = t.nodes
        surf = pmap.photons.surface
        if surface is None or surf is None:
            surf = qsurf = NO_SURFACE
        else:
            surf = np.ascontiguousarray(surf, dtype=np.int32)
            qsurf = query_surfaces(surface, m)
        _lookup_rows(t.position, axis, split, leaf, pmap.photons.normal, surf, self.E,
                     self.rk, p, n, qsurf, floor, float(radius) ** 2, ACCEPT, out, boundary,
                     miss)
        rows = np.nonzero(miss)[0]
        if len(rows):
            e, b = pmap.knn_irradiance(
                np.take(p, rows, axis=0), np.take(n, rows, axis=0), radius, k, min_photons,
                estimator, return_boundary=True,
                r_floor=None if r_floor is None else np.take(floor, rows),
                should_cancel=should_cancel,
                surface=np.take(qsurf, rows) if len(qsurf) else None)
            out[rows] = e
            boundary[rows] = b
        return (out, boundary) if return_boundary else out


@kernel
def _photon_radii_from(pos, axis, split, leaf, direction, normal, surface, k, r2, r2_min, a,
                       rk):
    """rk[r] (float32) for photon i = a + r: the radius of the disc its k-NN estimate
    reads (photonmap._irradiance_rows' rk): the distance to its k-th nearest photon (itself
    included); 0 (no estimate stored) where fewer than k lie within sqrt(r2) (the cap),
    where any of those is not accepted at i's surface (photonmap._accepted, with the
    photons' surfaces (P,) int32, -1: unknown: the disc holds another surface's or
    back-facing photons) or where k photons lie within sqrt(r2_min) (a focus: the
    estimate's rk is floored)."""
    # kdtree.knn's heap costs ~14-19 us a photon at k = 64 on Figure 8's map; a sphere
    # listed by ball_d2 and ordered by nearest_first (the estimates' own way) costs a
    # fraction. The sphere's radius starts at the previous photon's rk (the photons are in
    # the tree's order: neighbours), doubles while it holds fewer than k and halves
    # while it overflows LIST_CAP; the k-th distance is the same value knn returns.
    src_d2 = np.empty(LIST_CAP + 1, np.float64)
    src_idx = np.empty(LIST_CAP + 1, np.int64)
    d2 = np.empty(LIST_CAP + 1, np.float64)
    idx = np.empty(LIST_CAP + 1, np.int64)
    hist = np.empty(LIST_CAP + 2, np.int64)
    r_cap = math.sqrt(r2)
    r_min = math.sqrt(r2_min)
    seed = r_cap
    for r in range(rk.shape[0]):
        i = a + r
        qx, qy, qz = np.float64(pos[i, 0]), np.float64(pos[i, 1]), np.float64(pos[i, 2])
        nx, ny, nz = read_vector(normal, i)  # (photonlayout: float32 or octahedral)
        qs = np.int64(surface[i])
        rk[r] = np.float32(0.0)
        rt = min(max(seed, r_min), r_cap)
        cnt = 0
        found = False
        for _ in range(64):
            rt2 = r2 if rt >= r_cap else rt * rt
            c = kdtree.ball_d2(pos, axis, split, leaf, qx, qy, qz, rt2, src_d2, src_idx,
                               LIST_CAP)
            if c > LIST_CAP:
                if rt <= r_min:
                    break  # k photons within r_min: a focus (its rk is floored)
                rt = max(0.5 * rt, r_min)
                continue
            if c >= k or rt >= r_cap:
                cnt = min(c, k)
                if cnt > 0:
                    kdtree.nearest_first(src_d2, src_idx, c, cnt, rt2, d2, idx, hist)
                    found = True
                break
            rt = min(2.0 * rt, r_cap)
        if not found:
            continue
        ok = True
        for j in range(cnt):
            if not _accepted(direction, normal, surface, pos, idx[j], nx, ny, nz, qs, qx, qy,
                             qz)[0]:
                ok = False
                break
        rkr = math.sqrt(d2[k - 1]) if cnt == k else r_cap
        seed = 1.2 * rkr
        # (Fewer than k in the cap: the row's rk is its last accepted photon's distance,
        # photonmap.SPARSE_MIN_ACCEPTED, which the own-term model does not describe: the
        # k-NN row answers there.)
        if ok and cnt == k:
            rk[r] = np.float32(rkr)


def lookup(pmap, p, n, radius, k, min_photons, estimator, return_boundary, r_floor,
           should_cancel, surface=None):
    """pmap.irradiance's answer through pmap's precomputed estimates for these parameters,
    made on first use (under a lock: render threads share the map). k < MIN_K: the k-NN
    rows (module docstring). surface: the queries' object ids (PhotonMap.knn_irradiance);
    None: estimates made without the surface test."""
    if k < MIN_K:
        return pmap.knn_irradiance(p, n, radius, k, min_photons, estimator, return_boundary,
                                   r_floor, should_cancel, surface=surface)
    surfaces = surface is not None and pmap.photons.surface is not None
    key = (float(radius), int(k), int(min_photons), estimator, surfaces)
    cache = pmap.precomputed
    pre = cache.get(key)
    if pre is None:
        with _lock:
            pre = cache.get(key)
            if pre is None:
                pre = PrecomputedIrradiance(pmap, radius, k, min_photons, estimator,
                                            should_cancel, surfaces)
                cache[key] = pre
    return pre.estimate(pmap, p, n, radius, k, min_photons, estimator, return_boundary,
                        r_floor, should_cancel, surface if surfaces else None)
