"""Photon lookups after a camera chain: only the photons usable for the chain's real bounce
counts (Cycles' Light Paths limits, docs/design.md, Bounce limits).

The photon maps are filtered at build time for their common lookup (render._build_maps:
the caustic, secondary and global maps for the camera's first hit, camera-side counts
c = 0; the gather map for a final-gather ray's end, c = (1, 1, 0, 0); the regathers' maps
for their depth). A lookup reached after a chain of mirror / glass / glossy / sheen
bounces, or at the end of a gather ray that itself continued through such a surface, has
more bounces behind it: `extra`, (K,4) int64 per lookup row in B_TOTAL order (total,
diffuse, glossy, transmission) on top of the map's own camera counts.

- k-NN maps (caustic, secondary, global): `irradiance` counts only the photons usable
  for each row's counts (photonkernels.bounce_usable), their disc still found from all
  of the map's photons (PhotonMap.irradiance's masks: the others' power counted as 0; an
  unbiased estimate of the usable photons' irradiance, as GatherMap's keep).
- The gather map's irradiance is precomputed per gather point, so no per-lookup filter:
  `GatherCounts.reroute` tells the lookups whose counts drop more than
  render.SUBSET_POWER_SHARE of the power the map's own level keeps; final gathering
  gathers again from their ends (integrator.gather_indirect), where direct light,
  the next level's gather and the secondary caustic are all taken with the real counts.
  The other lookups whose counts drop some of the map's photons (below that share, or
  at the last level, which gathers no more) read the irradiance of their usable photons
  alone at their gather point (`subset_irradiance`: GatherMap.counts_irradiance, the
  point's estimate again with those photons' mask, made on first use).
- Shadow rays through flat glass passages (engine/shadowtransmittance.py) cross only as
  many as the hit's counts allow (`flat_passages`), per lobe kind: a hit's diffuse and
  glossy lobes may differ (directlight.accumulate_bsdf), rough glass counts its
  refraction (engine/glasslight.py).
"""
from __future__ import annotations

import math

import numpy as np

from . import photonkernels as pk
from .photonmap import pack_masks, unpack_masks


def camera_counts(extra, base=(0, 0, 0, 0)) -> np.ndarray:
    """(K,4) int64: the camera-side counts of lookups `base` (4,) + extra (K,4)."""
    return np.asarray(extra, np.int64) + np.asarray(base, np.int64)


# unique_counts packs a row's four counts into one int64 key, _KEY_BITS bits a count
# (counts are bounce counts: a photon's saturate at 255, Cycles' limits stop at 1024).
_KEY_BITS = 15
_KEY_SHIFTS = np.array([3 * _KEY_BITS, 2 * _KEY_BITS, _KEY_BITS, 0], np.int64)


# unique_counts of at least this many rows of uint8 / uint16 counts (photons' bounces)
# counts their mixed-radix keys in a table (np.bincount) when it holds at most
# _TABLE_KEYS entries, instead of sorting them (2x faster from 20 k rows; the camera
# side's int64 counts of a few thousand rows sort faster).
_TABLE_ROWS = 4096
_TABLE_KEYS = 1 << 22


def unique_counts(counts):
    """(keys (U,4) int64, which (K,) int64): the distinct rows of counts (K,4) in
    lexicographic order and each row's index into them, the same arrays as
    np.unique(counts, axis=0, return_inverse=True). That call sorts the rows as a
    structured dtype (numpy's generic field-by-field compare: ~0.7 ms a gather step's
    call, 10-18 % of a Figure 6 / 7 render, docs/performance.md camspeed2); rows that all
    equal the first (most calls) need no sort, and counts in [0, 2^15) sort as one int64
    key in the same order. A map's photons (hundreds of thousands of rows of small
    counts) are counted in a table of their keys instead (_table_unique: no sort; the
    sort was ~0.08 CPU s a call on Figure 6's 0.7 M photons, docs/performance.md mem45)."""
    raw = np.asarray(counts)
    if len(raw) >= _TABLE_ROWS and raw.ndim == 2 and raw.dtype.kind == "u" and raw.itemsize <= 2:
        got = _table_unique(raw)
        if got is not None:
            return got
    c = np.asarray(raw, np.int64)
    if len(c) and (c == c[0]).all():
        return c[:1].copy(), np.zeros(len(c), np.int64)
    if len(c) and c.min() >= 0 and c.max() < (1 << _KEY_BITS):
        # Disjoint bit fields: the sum is their OR (column by column, not numpy's slow
        # reduction over a short last axis; the same integers).
        key = c[:, 0] << _KEY_SHIFTS[0]
        for j in range(1, 4):
            key |= c[:, j] << _KEY_SHIFTS[j]
        u, which = np.unique(key, return_inverse=True)
        keys = (u[:, None] >> _KEY_SHIFTS) & ((1 << _KEY_BITS) - 1)
        return keys, which.reshape(-1).astype(np.int64, copy=False)
    keys, which = np.unique(c, axis=0, return_inverse=True)
    return keys, which.reshape(-1)


def _table_unique(raw):
    """unique_counts of integer counts (K,4) by a table: each count replaced by its rank
    among its column's distinct values, each row's mixed-radix key of those ranks (the
    first column most significant: lexicographic order), the keys present from
    np.bincount, each row's index from their running count. None where a count is
    negative or above _TABLE_KEYS, or the table would exceed _TABLE_KEYS."""
    cols, values = [], []
    for j in range(raw.shape[1]):
        col = raw[:, j]
        if int(col.min()) < 0 or int(col.max()) >= _TABLE_KEYS:
            return None
        present = np.bincount(col) > 0
        cols.append(np.take(np.cumsum(present) - 1, col))
        values.append(np.flatnonzero(present))
    span = [len(v) for v in values]
    if math.prod(span) > _TABLE_KEYS:
        return None
    key = cols[0]
    for col, radix in zip(cols[1:], span[1:]):
        key *= radix
        key += col
    present = np.bincount(key, minlength=math.prod(span)) > 0
    which = np.take(np.cumsum(present) - 1, key)
    u = np.flatnonzero(present)
    keys = np.empty((len(u), len(cols)), np.int64)
    for j in range(len(cols) - 1, -1, -1):
        keys[:, j] = np.take(values[j], u % span[j])
        u //= span[j]
    return keys, which


def within(counts, limits) -> np.ndarray:
    """(K,) bool: camera-side counts (K,4) whose bounces are all within the limits (4,):
    the lookup vertex is reached by a path Cycles would still shade."""
    c = np.asarray(counts, np.int64)
    lim = np.asarray(limits, np.int64)
    # Column by column: the same booleans as np.all(c <= lim, axis=1), whose reduction
    # over a short last axis is numpy's slow case (~5x the four compares).
    ok = c[:, 0] <= lim[0]
    for j in range(1, c.shape[1]):
        ok &= c[:, j] <= lim[j]
    return ok


# The kind of bounce a shaded hit's lobe makes (B_TOTAL columns, photonkernels): which of
# its counts the flat-passage cap adds the hit's own bounce to.
DIFFUSE, GLOSSY, TRANSMISSION = 1, 2, 3


def flat_passages(counts, limits, lobe=DIFFUSE) -> np.ndarray:
    """(K,) int64: the most flat glass passages a shadow ray from a hit reached with
    camera-side counts counts (K,4) may cross within the limits (4,) (B_TOTAL order),
    for the light a lobe of kind `lobe` (DIFFUSE, GLOSSY or TRANSMISSION) takes from it.
    A shadow ray through a flat passage (engine/shadowtransmittance.py) carries light
    that Cycles gathers by BSDF sampling: the hit's bounce (counted as the lobe's kind:
    diffuse and sheen DIFFUSE, the rough reflective lobes GLOSSY, rough glass's
    refraction TRANSMISSION: path_state_next's labels), then two refractions per
    passage, the last of which reaches the light (the light-sample vertex: no bounce of
    its kind, as a photon's first scatter, photonkernels.B_TOTAL). Every bounce before
    that last one must stay within its limit (path_state_next: a count at the setting + 1
    still collects the emission the next ray meets, but the ray goes no further). So k
    passages need lobe + 1 <= its limit, total + 2k <= Total and transmission + 2k - 1
    (+ 1 for a TRANSMISSION lobe) <= Transmission. A floor lit through a pane reads
    nothing at Transmission 0 in Cycles; it read the pane's full light before, and a
    glossy floor's glossy lobe kept it at Glossy 0 (tests/test_bounce_limits.py). No
    passage (k = 0) needs nothing: that light sample is Cycles' own, taken at every
    shaded hit whatever its lobes' counts."""
    c = np.asarray(counts, np.int64).reshape(-1, 4)
    lim = np.asarray(limits, np.int64)
    refraction = 1 if lobe == TRANSMISSION else 0
    k = np.minimum((lim[0] - c[:, 0]) // 2, (lim[3] - c[:, 3] - refraction + 1) // 2)
    k[c[:, lobe] + 1 > lim[lobe]] = 0
    return np.maximum(k, 0)


def _usable_bits(photons, limits, key, cache) -> tuple:
    """(bits (1, ceil(N / 8)) uint8, all, any): photons.usable(limits, key) as the bits
    PhotonMap.irradiance reads (photonmap.pack_masks) and whether it holds every photon /
    any, cached per key (a dict shared by the map's views; two threads may compute one
    mask twice, the same values). As bits: 1/8 B a photon and key where the (N,) bool
    masks held 1 (Figure 6's caustic map: 6 keys, 1.3 B a stored photon; docs/
    performance.md "mem48")."""
    got = cache.get(key)
    if got is None:
        mask = photons.usable(limits, key)
        got = cache[key] = (pack_masks(mask[None]), bool(mask.all()), bool(mask.any()))
    return got


def _usable(photons, limits, key, cache) -> np.ndarray:
    """(N,) bool photons.usable(limits, key), from the per-key cache (_usable_bits)."""
    return unpack_masks(_usable_bits(photons, limits, key, cache)[0], len(photons))[0]


def map_cache(pmap) -> dict:
    """The per-map dict of usable masks (keyed by camera counts), made on first use."""
    cache = vars(pmap).get("usable_masks")
    if cache is None:
        cache = vars(pmap).setdefault("usable_masks", {})
    return cache


def keeps_every_photon(pmap, limits, counts) -> np.ndarray:
    """(K,) bool: the rows whose camera-side counts (K,4) leave every photon of pmap usable,
    so that the map's own values (its estimate, a share of it) serve them as they are
    (without pmap.photons.bounces every photon counts: all True)."""
    if getattr(pmap.photons, "bounces", None) is None:
        return np.ones(len(counts), bool)
    keys, which = unique_counts(counts)
    cache = map_cache(pmap)
    whole = np.array([_usable_bits(pmap.photons, limits, tuple(int(x) for x in key),
                                   cache)[1] for key in keys], bool)
    return whole[which]


def irradiance(pmap, limits, counts, p, n, *args, **kwargs) -> np.ndarray:
    """pmap.irradiance(p, n, *args, **kwargs) (M,3) with each row's estimate from the
    photons usable at its camera-side counts counts (M,4) alone (None: every photon the
    map holds, the map's own call). Rows whose counts keep every photon take the plain
    estimate (the same bits), rows whose counts keep none 0; the rest the masked estimate
    of one call with a mask per distinct count (PhotonMap.irradiance's masks: the same
    search and disc). pmap.photons.bounces: the map photons' counts (render._build_maps);
    without them every photon counts."""
    if (counts is None or pmap is None or len(pmap) == 0
            or getattr(pmap.photons, "bounces", None) is None):
        return pmap.irradiance(p, n, *args, **kwargs)
    keys, which = unique_counts(counts)
    cache = map_cache(pmap)
    masks, slot = [], np.full(len(keys), -1, np.int64)  # -1: every photon; -2: none
    for j, key in enumerate(keys):
        bits, every, some = _usable_bits(pmap.photons, limits, tuple(int(x) for x in key),
                                         cache)
        if every:
            continue
        if not some:
            slot[j] = -2
            continue
        slot[j] = len(masks)
        masks.append(bits)
    if not masks:
        out = pmap.irradiance(p, n, *args, **kwargs)
        if (slot == -2).any():
            out = np.where((slot[which] == -2)[:, None], 0.0, out)
        return out
    out, masked = pmap.irradiance(p, n, *args, masks=np.concatenate(masks), **kwargs)
    s = slot[which]
    rows = np.nonzero(s >= 0)[0]
    out[rows] = masked[s[rows], rows]
    out[s == -2] = 0.0
    return out


# exact_class_sums' extraction levels: each takes ~31 more bits of every value (a
# million photons); three leave a residual below 2^-90 of the largest.
EXACT_LEVELS = 3


def exact_class_sums(which, values, n_classes: int) -> np.ndarray:
    """(n_classes, EXACT_LEVELS + 1) float64 partial sums per class of values (N,) float64
    (finite) by class which (N,) int: math.fsum of any set of classes' rows is the
    correctly rounded sum of their values (the last column's residual aside, below
    2^-90 of the largest value times N), in any order. Rump, Ogita and Oishi's
    error-free extraction ("Accurate floating-point summation", 2008, ExtractVector):
    with sigma a power of two at least 2 N max|r|, q = (sigma + r) - sigma is r's part
    on sigma's ulp grid, exact, and r - q the exact rest; sums of such q are exact in
    any order (multiples of one ulp, below 2^53 of them), so np.bincount adds them
    exactly. Non-finite values count as 0."""
    out = np.zeros((n_classes, EXACT_LEVELS + 1))
    r = np.array(values, np.float64)
    # (A non-finite value, which the photon pass does not store (its scatter drops
    # non-finite throughput), counts as 0: one inf would make sigma inf and every
    # class's sums NaN.)
    r[~np.isfinite(r)] = 0.0
    grow = math.ceil(math.log2(len(r) + 2)) + 1
    for j in range(EXACT_LEVELS):
        m = float(np.abs(r).max()) if len(r) else 0.0
        if m == 0.0:
            return out
        sigma = math.ldexp(1.0, math.frexp(m)[1] + grow)
        q = (sigma + r) - sigma
        r -= q
        out[:, j] = np.bincount(which, q, minlength=n_classes)
    out[:, EXACT_LEVELS] = np.bincount(which, r, minlength=n_classes)
    return out


class GatherCounts:
    """The gather map's photons' counts and power (the shot's non-caustic photons:
    bounces (N,4) uint8, power (N,) float64 summed over RGB), to decide which gather
    lookups the precomputed irradiance cannot serve (reroute). Shared by the render's
    threads; its cache is filled as lookups ask (the same answer from any thread).

    A decision reads the photons by their distinct count rows (a few hundred classes,
    bounce_usable row by row: the same mask), not photon by photon: Figure 6 asks ~45
    (level, counts) pairs a render over its 0.7 M photons (docs/performance.md
    camspeed2). Each class's power is held as exact partial sums (exact_class_sums,
    made from the float64 powers), so a decision compares the correctly rounded float64
    sums of the photons' powers, in any order: the photons themselves are not kept
    (review53: their powers were rounded to float32 first, which could flip a class
    within 2^-24 of the share)."""

    def __init__(self, bounces, power, limits, share):
        power = np.asarray(power, np.float64)
        self.limits = np.asarray(limits, np.int64)
        self.share = share
        self._cache = {}
        rows, which = unique_counts(bounces)
        self.rows = rows
        self.sums = exact_class_sums(which, power, len(rows))

    def _sum(self, classes) -> float:
        """The photons' summed power over classes ((U,) bool), correctly rounded."""
        return math.fsum(self.sums[classes].ravel().tolist())

    def drops(self, level, key) -> bool:
        """Whether lookups at gather level `level` (the map filtered for camera counts
        (level + 1, level + 1, 0, 0)) reached with camera counts key (4-tuple) would drop
        more than `share` of the power that level's photons carry."""
        got = self._cache.get((level,) + key)
        if got is None:
            nominal = pk.bounce_usable(self.rows, self.limits, (level + 1, level + 1, 0, 0))
            ok = pk.bounce_usable(self.rows, self.limits, key)
            got = self._sum(nominal & ~ok) > self.share * self._sum(nominal)
            self._cache[(level,) + key] = got
        return got

    def drops_any(self, level, key) -> bool:
        """Whether lookups at gather level `level` reached with camera counts key (4-tuple)
        drop any photon that level's map (counts (level + 1, level + 1, 0, 0)) keeps."""
        got = self._cache.get(("any", level) + key)
        if got is None:
            rows = self.rows
            nominal = pk.bounce_usable(rows, self.limits, (level + 1, level + 1, 0, 0))
            ok = pk.bounce_usable(rows, self.limits, key)
            got = self._cache[("any", level) + key] = bool((nominal & ~ok).any())
        return got

    def partial(self, level, counts) -> np.ndarray:
        """(K,) bool for lookups with camera counts (K,4) at gather level `level`: those
        whose counts drop some of the photons the level's map keeps (its precomputed
        irradiance holds their power too; subset_irradiance reads the rest alone)."""
        counts = np.asarray(counts, np.int64)
        if not len(counts):
            return np.zeros(0, bool)
        keys, which = unique_counts(counts)
        hit = np.array([self.drops_any(level, tuple(int(x) for x in k)) for k in keys])
        return hit[which]

    def kept_share(self, level, key) -> float:
        """The share of the power lookups at gather level `level` read from its map that
        photons usable for camera counts key (4-tuple) carry, over the whole map (s20's
        last-level scale; now only integrator.LOOKUP_SUBSETS = False reads it, an A/B
        diagnostic: a lookup's own share is where the dropped photons lie)."""
        got = self._cache.get(("share", level) + key)
        if got is None:
            nominal = pk.bounce_usable(self.rows, self.limits, (level + 1, level + 1, 0, 0))
            ok = pk.bounce_usable(self.rows, self.limits, key)
            kept = self._sum(nominal)
            got = self._sum(nominal & ok) / kept if kept > 0.0 else 1.0
            self._cache[("share", level) + key] = got
        return got

    def reroute(self, level, counts) -> np.ndarray:
        """(K,) bool for lookups with camera counts (K,4) at gather level `level`."""
        counts = np.asarray(counts, np.int64)
        out = np.zeros(len(counts), bool)
        if not len(counts):
            return out
        keys, which = unique_counts(counts)
        hit = np.array([self.drops(level, tuple(int(x) for x in k)) for k in keys])
        return hit[which]


# The gather map's per-point drop bounds (render._drop_bound_masks) cover lookups at the
# levels below DROP_BOUND_LEVELS whose counts exceed their level's by at most
# DROP_BOUND_EXTRA bounces of each kind but diffuse (others: the lookup's own estimate
# again, counts_irradiance). Each is a mask more in the map's one estimate pass (9
# masks: Figure 6's map build +0.5 CPU s); level 0 holds ~95 % of Figure 6's lookups
# that drop photons.
DROP_BOUND_EXTRA = 3
DROP_BOUND_LEVELS = 1


def may_drop(gmap, level, counts, point) -> np.ndarray:
    """(K,) bool for lookups at gather level `level` with camera counts (K,4) at gmap's
    gather points `point` (K,) int64: False where none of the photons their counts drop
    adds to the point's estimate, which then equals the point's irradiance E exactly
    (its photons' sums without terms that were 0; subset_irradiance need not run):
    counts beyond the level's (level + 1, level + 1, 0, 0) by no diffuse bounce and at
    most DROP_BOUND_EXTRA of each other kind, at a point whose bound
    (GatherMap.drop_bounds[(level, extra)]) holds no photon. True elsewhere (and for
    maps without bounds)."""
    counts = np.asarray(counts, np.int64)
    out = np.ones(len(counts), bool)
    bounds = getattr(gmap, "drop_bounds", None)
    if not bounds or not len(counts):
        return out
    extra = counts - np.array([level + 1, level + 1, 0, 0], np.int64)
    most = np.maximum(np.maximum(extra[:, 0], extra[:, 2]), extra[:, 3])
    most[extra[:, 1] != 0] = 0  # (a diffuse bounce more: no bound)
    for m in range(1, DROP_BOUND_EXTRA + 1):
        bound = bounds.get((level, m))
        rows = np.flatnonzero(most == m)
        if bound is not None and len(rows):
            out[rows] = np.take(bound, np.take(point, rows))
    return out


def subset_irradiance(gmap, limits, counts, point) -> np.ndarray:
    """(K,3) float64: the irradiance at gather points `point` (K,) int64 of gmap (a
    GatherMap built with the photons' bounces) from the photons usable at each row's
    camera counts counts (K,4) alone: what a subset map for those counts would hold at
    the point (GatherMap.counts_irradiance, computed per distinct count and point on
    first use). The lookups whose counts drop some of the level map's photons read it
    (integrator._chain_lookups): the dropped photons' share of a point's light is their
    share where they lie, not the whole map's (a closed sphere of glass and diffuse
    sides traps light bounce after bounce: its deep photons carry most of the power
    inside it and little of the map's)."""
    counts = np.asarray(counts, np.int64)
    out = np.empty((len(counts), 3))
    if not len(counts):
        return out
    keys, which = unique_counts(counts)
    if len(keys) > 1:
        _estimate_counts(gmap, limits, keys, which, np.asarray(point, np.int64))
    for j, key in enumerate(keys):
        rows = np.flatnonzero(which == j)
        out[rows] = gmap.counts_irradiance(np.take(point, rows), limits, key)
    return out


def _estimate_counts(gmap, limits, keys, which, point) -> None:
    """Into gmap.counts_cache (GatherMap.counts_irradiance's store): the irradiance of
    the points point[which == j] not yet known at counts keys[j], for every count at once
    in one search (knn_irradiance's masks, one a count: each mask's sum the bits of its
    own call), so that counts_irradiance then finds them all. A call a count cost ~0.5 ms
    of Python around its k-NN kernel (1,751 calls on Figure 6, 1,373 on the candles;
    docs/performance.md "percost54"). Fewer than two counts with new points: nothing
    done (counts_irradiance's own call is the one search)."""
    from .photonmap import LEVEL_DTYPE
    if getattr(gmap, "estimating", None) is None:
        return  # (counts_irradiance raises)
    need = []
    for j, key in enumerate(keys):
        key = tuple(int(x) for x in key)
        if key not in gmap.counts_cache:
            gmap.counts_irradiance(_NO_POINTS, limits, key)  # (the count's mask)
        _, known, _ = gmap.counts_cache[key]
        pts = np.unique(point[which == j])
        if len(known):
            at = np.minimum(np.searchsorted(known, pts), len(known) - 1)
            pts = pts[np.take(known, at) != pts]
        if len(pts):
            need.append((key, pts))
    if len(need) < 2:
        return
    every = np.unique(np.concatenate([pts for _, pts in need]))
    k, min_photons, estimator = gmap.estimate_args
    surf = gmap.surface if len(gmap.surface) else None
    _, masked = gmap.estimating.irradiance(
        np.take(gmap.position, every, axis=0), np.take(gmap.normal, every, axis=0),
        gmap.radius, k, min_photons, estimator,
        masks=np.concatenate([gmap.counts_cache[key][0] for key, _ in need]),
        surface=None if surf is None else np.take(surf, every))
    for s, (key, new) in enumerate(need):
        # (counts_irradiance's store: ascending points, their E as float32; another
        # thread's points stored meanwhile are kept, a point stored twice the same bits)
        bits, known, known_E = gmap.counts_cache[key]
        if len(known):
            at = np.minimum(np.searchsorted(known, new), len(known) - 1)
            new = new[np.take(known, at) != new]
        E = np.take(masked[s], np.searchsorted(every, new), axis=0).astype(LEVEL_DTYPE)
        merged = np.concatenate([known, new])
        order = np.argsort(merged, kind="stable")
        gmap.counts_cache[key] = (bits, merged[order],
                                  np.concatenate([known_E, E])[order])


_NO_POINTS = np.zeros(0, np.int64)
