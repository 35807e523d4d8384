"""Photon-guided final-gather directions (Jensen 1995, "Importance Driven Path Tracing
using the Photon Map", Rendering Techniques '95; Jensen's book "Realistic Image Synthesis
Using Photon Mapping" §9.x, importance sampling with the photon map).

A final-gather ray's cosine direction comes from (u1, u2) in [0, 1)^2: sin^2(theta) = u1,
phi = 2 pi u2 (Malley: sampling.cosine_hemisphere). Cut that square into ROWS x COLS
cells (rows in u1, columns in u2): each cell is an equal share of the cosine lobe. At each
gather point (the gather map's points, photonmap.GatherMap) the INDIRECT photons around it
(light that left a diffuse surface: what a gather ray can find; DIRECT photons came from
the lights, which shadow rays take) add their power into the cell of their incoming
direction. Photon flux per cell is the integral of L cos over the cell's solid angle, so
over the square's uniform measure (cos dw / pi) the cells' flux shares are the density
proportional to L: the zero-variance density of a gather ray's cos-weighted radiance,
piecewise constant.

A gather ray draws its (u1, u2) from the mixture density over the square
    q(u) = (1 - share) + share * CELLS * f_c        (f_c: cell c's flux share, sum 1)
(piecewise constant; sampled row by inverting the rows' marginal, then column by the
row's conditional: monotone in u1 and in u2, so the sampler's strata stay strata) and is
weighted 1 / q(u): the cosine lobe's pdf cancels (cos / (pi pdf) = 1 / q). q >= 1 - share
> 0 everywhere, so the estimate is unbiased whatever the photons say; a gathering hit with
no gather point nearby facing its way takes q = 1 (the plain cosine rays).

The grid is that of the nearest of the hit's CANDIDATES nearest gather points whose
normal agrees with its own (one k-NN search per point at build time, one query per
gathering hit), read in the hit's own shading frame (sampling.orthonormal_basis of its
normal, the frame the gather_rays kernel uses).

source="flux" fills the grids from the stored photons taken as small emitters instead
(_flux_grids). Measured (docs/accuracy.md, "guide33"): both halve the gathered noise of a
closed room lit by a small patch, neither wins at equal time on the example blends or a
daylit room. So the default, "auto" (docs/accuracy.md "night42"), builds the grids (one
per 2-radius cube: thin_points; shrunk by their photons' noise: shrink) and keeps them
only where the indirect share^2 x their predicted gain reaches AUTO_GAIN: rooms lit by
lamps' bright patches (a night room: 1.5x less time for the same noise; the lamp room
of bench_lamp_room.py breaks even), not the example blends.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .parallel import ordered_map
from .photonkernels import CAUSTIC, INDIRECT
from .photonlayout import powers, vectors
from .sampling import orthonormal_basis

ROWS, COLS = 4, 8   # cells in u1 (sin^2 theta) and u2 (phi / 2 pi)
CELLS = ROWS * COLS
# A hit takes the nearest gather point's grid only if their normals agree this well (the
# same surface; a corner's other wall would point the rays wrongly: still unbiased).
AGREEMENT = 0.9
# A hit's candidates: its nearest gather points (the nearest facing its way among them).
# A thin wall's other side holds points as near as its own (a daylit room's outside, lit
# by the sky, held 95 % of the points; the nearest alone left most hits unguided).
CANDIDATES = 8
_ONE_BELOW = np.nextafter(1.0, 0.0)
# Setting gather_guiding "auto" guides where share^2 x GatherGuide.gain (share: the
# indirect light's share of the diffuse irradiance the camera sees,
# visualimportance.indirect_share) is at least this: the predicted fall of a pixel's
# relative variance per gather ray, against the guide's cost (its build, 0.05-0.8 CPU s,
# and the per-hit search and warp: +16 % CPU in the night room). The cell-scale
# prediction overstates the measured fall ~3x (docs/accuracy.md "night42": the example
# blends read 0.001-0.10 and stay cosine; the lamp-lit rooms 0.24 and 0.39).
AUTO_GAIN = 0.2
# GatherGuide.gain's bound: a point's cosine variance (its grid's concentration, CELLS x
# sum f^2 - 1 for cell shares f summing to 1) is at most CELLS - 1 (all flux in one cell),
# its guided one at least 0, so the mean over the points is at most this.
MAX_GAIN = CELLS - 1.0
# Grid points: at most one per cube of this many gather radii (thin_points).
SPACING = 2.0
# Grid points a block of the build at least, and blocks at most (GatherGuide: its blocks
# on the workers).
GRID_ROWS = 512
GRID_BLOCKS = 8
# A hit reads the grid of the nearest agreeing point within this many gather radii (the
# night room: 0.3 % of its hits found none at 2 with SPACING 2, none at 3.5).
SEARCH = 2.0


class GatherGuide:
    """Per gather point (P of them) the mixture density's tables for guided gather rays.

    position, normal: (P,3) the gather points (world space, unit normals); photons: a
    photons.Photons (the shot; read through photonlayout.vectors / powers, so a map's
    compact photons would do too); radius: the gather map's search radius (m): the grid of a
    point counts the k nearest INDIRECT photons within 2 x radius on its own side
    (photon normal . point normal > AGREEMENT); share: the mixture's guided share in
    [0, 1) (at 1 a cell without flux would have q = 0: infinite weights; ValueError).
    Deterministic (no random numbers; the same for any thread count)."""

    def __init__(self, position, normal, photons, radius: float, k: int = 64,
                 share: float = 0.5, source: str = "indirect", emitters: int = 512,
                 workers: int = 1):
        if not 0.0 <= float(share) < 1.0:
            raise ValueError(f"gather guide share {share!r}: expected 0 <= share < 1")
        self.share = float(share)
        self.radius = float(radius)
        # One grid per SPACING x radius voxel and normal class: a grid sums the photons
        # within 2 radii, so the gather map's denser points would repeat their
        # neighbours' grids at their cost (k-NN, per-point tables, the per-hit search).
        position, normal = thin_points(position, normal, SPACING * self.radius)
        self.normal = normal
        p = len(position)
        self.position = position
        self.tree = cKDTree(position) if p else None
        flux = np.zeros((p, CELLS))
        w_sq = np.zeros(p)  # per point the summed squared weights of its photons
        rows = np.flatnonzero(photons.kind == INDIRECT)
        if source == "flux":
            flux = _flux_grids(position, self.normal, photons, radius, emitters)
        elif p and len(rows):
            ppos = np.take(photons.position, rows, axis=0).astype(np.float64)
            k = min(k, len(rows))
            # (an unbalanced, uncompacted tree: half the build time, the same neighbours)
            near = cKDTree(ppos, balanced_tree=False, compact_nodes=False)
            del ppos
            # Each point's grid from its own photons alone: blocks of points on the
            # workers (scipy's query and numpy's array kernels release the GIL), the same
            # numbers for any block size or thread count.
            step = max(GRID_ROWS, -(-p // GRID_BLOCKS))
            blocks = [(i, min(i + step, p)) for i in range(0, p, step)]

            def job(block, stop):
                i, e = block
                flux[i:e], w_sq[i:e] = _indirect_grids(
                    near, rows, photons, position[i:e], self.normal[i:e], k, radius)
            for _ in ordered_map(job, blocks, workers):
                pass
        total = flux.sum(axis=1, keepdims=True)
        f = np.where(total > 0.0, flux / np.where(total > 0.0, total, 1.0), 1.0 / CELLS)
        if source == "indirect":
            # The grid of a few photons is mostly their own noise: shrunk towards the
            # cosine lobe by what the photon count leaves of its concentration.
            f, self.concentration = shrink(f, total[:, 0], w_sq)
        else:
            self.concentration = np.maximum(CELLS * (f * f).sum(axis=1) - 1.0, 0.0)
        # Cell probabilities of the mixture (sum 1); q = CELLS * prob.
        prob = ((1.0 - self.share) / CELLS + self.share * f).reshape(p, ROWS, COLS)
        self.row_prob = prob.sum(axis=2)                              # (P, ROWS)
        self.col_prob = prob / self.row_prob[:, :, None]              # (P, ROWS, COLS)
        self.guided_points = int(np.count_nonzero(total[:, 0] > 0.0))
        # The cell-scale relative second moments of a gather ray's radiance, cosine
        # (1 + C) and guided (sum_c CELLS f_c^2 / q_c, f the shrunk grid), summed over the
        # points: their excesses over 1 are the two gathers' relative variances.
        q = CELLS * prob.reshape(p, CELLS)
        self.variance_cosine = float(self.concentration.sum())
        self.points = p
        self.variance_guided = float(np.maximum(
            (CELLS * f * f / q).sum(axis=1) - 1.0, 0.0).sum())

    @property
    def gain(self) -> float:
        """Predicted fall of a level-0 gather ray's relative variance, guided against
        cosine, at cell scale (the light's spread within a cell is not seen), the mean
        over the grids."""
        return (self.variance_cosine - self.variance_guided) / max(self.points, 1)

    @property
    def nbytes(self) -> int:
        return self.row_prob.nbytes + self.col_prob.nbytes + self.normal.nbytes

    def points_for(self, p: np.ndarray, ns: np.ndarray) -> np.ndarray:
        """(N,) int64 each gathering hit's gather point (the nearest within 2 x radius
        whose normal agrees with ns (N,3)), -1 where none: those rows sample the cosine
        lobe."""
        n = len(p)
        if self.tree is None or n == 0:
            return np.full(n, -1, np.int64)
        p = np.asarray(p, np.float64)
        ns = np.asarray(ns, np.float64)
        bound = SEARCH * self.radius
        # The nearest point first; the CANDIDATES nearest only where it does not agree
        # (the same answer: the nearest agreeing point either way).
        _, j = self.tree.query(p, k=1, distance_upper_bound=bound)
        out = self._agreeing(np.asarray(j, np.int64).reshape(n, 1), ns)
        again = np.flatnonzero(out < 0)
        kq = min(CANDIDATES, len(self.normal))
        if len(again) and kq > 1:
            _, j = self.tree.query(p[again], k=kq, distance_upper_bound=bound)
            out[again] = self._agreeing(np.asarray(j, np.int64).reshape(len(again), kq),
                                        ns[again])
        return out

    def _agreeing(self, j, ns):
        """(N,) the first of each row's candidate points j (N,K) (ascending distance; K =
        len(normal): none) whose normal agrees with ns (N,3), -1 where none does."""
        n = len(j)
        found = j < len(self.normal)
        jj = np.where(found, j, 0)
        nj = np.take(self.normal, jj, axis=0)
        # The grid is read in the hit's tangent frame (sampling.orthonormal_basis, Duff
        # et al.), which turns by 180 degrees where n_z changes sign: a point on the other
        # side of that cut would guide the rays the wrong way (review33).
        same_frame = (nj[..., 2] >= 0.0) == (ns[:, None, 2] >= 0.0)
        agree = found & same_frame & (np.einsum("ikc,ic->ik", nj, ns) > AGREEMENT)
        first = np.argmax(agree, axis=1)
        return np.where(agree.any(axis=1), jj[np.arange(n), first], -1)

    def tables(self, point: np.ndarray):
        """(row_prob (N,ROWS), col_prob (N,ROWS,COLS)) for the rows' points (-1: the
        cosine lobe's, all cells equal)."""
        ok = point >= 0
        jj = np.where(ok, point, 0)
        rp = np.take(self.row_prob, jj, axis=0)
        cp = np.take(self.col_prob, jj, axis=0)
        rp[~ok] = 1.0 / ROWS
        cp[~ok] = 1.0 / COLS
        return rp, cp


def can_guide(share) -> bool:
    """Whether "auto" could guide at indirect share `share` (visualimportance.indirect_share;
    None or not finite: no evidence, never): share^2 x MAX_GAIN reaches AUTO_GAIN, i.e.
    share >= 0.080. Below it no grid can pay (share^2 x gain < AUTO_GAIN for any photons),
    so the grids are not built (their build was 0.07-0.3 CPU s of renders lit mostly
    directly: docs/performance.md "worldfast43")."""
    return (share is not None and bool(np.isfinite(share))
            and share * share * MAX_GAIN >= AUTO_GAIN)


def thin_points(position, normal, spacing):
    """(position (M,3), normal (M,3)) float64: of the points (P,3) and unit normals (P,3),
    the first (by index) in each cube of side `spacing` (m) per normal class (the
    dominant axis and its sign: a thin wall's two sides stay apart); all of them where
    spacing <= 0. Deterministic."""
    position = np.asarray(position, np.float64)
    normal = np.asarray(normal, np.float64)
    if spacing <= 0.0 or len(position) < 2:
        return position, normal
    cell = np.floor((position - position.min(axis=0)) / spacing).astype(np.int64)
    axis = np.argmax(np.abs(normal), axis=1)
    cls = 2 * axis + (np.take_along_axis(normal, axis[:, None], 1)[:, 0] < 0.0)
    dims = cell.max(axis=0) + 1
    key = ((cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]) * 6 + cls
    _, first = np.unique(key, return_index=True)
    keep = np.sort(first)
    return position[keep], normal[keep]


def shrink(f, total, w_sq):
    """(f', C): per point (P of them) the cell shares f (P,CELLS) (rows sum to 1) of
    photons of summed weight total (P,) and summed squared weight w_sq (P,), shrunk
    towards the uniform 1 / CELLS, and the concentration C (P,) >= 0 of the flux they
    were drawn from: CELLS sum_c pi_c^2 - 1, the cosine gather's relative variance at
    cell scale.
    k photons (effective count k = total^2 / w_sq for unequal weights) drawn from shares
    pi give E[sum f^2] = (1 - 1/k) sum pi^2 + 1/k: sum pi^2 is estimated as
    (sum f^2 - 1/k) / (1 - 1/k), and f' = 1/CELLS + lam (f - 1/CELLS) with lam^2 =
    C / (CELLS sum f^2 - 1) has that concentration (lam in [0, 1]; 0 where the
    photons' spread is within their noise: the point guides by the cosine lobe)."""
    total = np.asarray(total, np.float64)
    k = np.where(w_sq > 0.0, total * total / np.where(w_sq > 0.0, w_sq, 1.0), 0.0)
    s2 = (f * f).sum(axis=1)
    big = k > 1.0
    pi2 = np.where(big, (s2 - 1.0 / np.where(big, k, 1.0))
                   / np.where(big, 1.0 - 1.0 / np.where(big, k, 2.0), 1.0), 1.0 / CELLS)
    conc = np.maximum(CELLS * pi2 - 1.0, 0.0)
    raw = CELLS * s2 - 1.0
    lam = np.sqrt(np.clip(conc / np.where(raw > 0.0, raw, 1.0), 0.0, 1.0))
    lam = np.where(raw > 0.0, lam, 0.0)
    return 1.0 / CELLS + lam[:, None] * (f - 1.0 / CELLS), conc


def _indirect_grids(near, rows, photons, position, normal, k, radius):
    """(flux (P,CELLS), w_sq (P,)) of points position (P,3) with unit normals (P,3): the
    Rec.709 luminance of each one's k nearest INDIRECT photons within 2 x radius that
    agree with its normal and arrive from above it, per cell of its incoming direction,
    and their summed squared weights. near: a cKDTree over those photons' positions,
    rows: their rows in photons. Row by row (a point's values depend on its own row
    alone)."""
    p = len(position)
    dist, j = near.query(position, k=k, distance_upper_bound=2.0 * radius)
    dist, j = dist.reshape(p, k), j.reshape(p, k)
    found = np.isfinite(dist)
    jj = np.take(rows, np.where(found, j, 0))  # the neighbours' photon rows
    # Incoming direction (towards where the photon came from) in each point's frame.
    wi = -vectors(photons.direction, jj)
    pn = vectors(photons.normal, jj)
    n = normal[:, None, :]
    t, b = orthonormal_basis(normal)
    l0 = np.einsum("pkc,pc->pk", wi, t)
    l1 = np.einsum("pkc,pc->pk", wi, b)
    l2 = np.einsum("pkc,pkc->pk", wi, np.broadcast_to(n, wi.shape))
    ok = found & (np.einsum("pkc,pkc->pk", pn, np.broadcast_to(n, pn.shape))
                  > AGREEMENT) & (l2 > 0.0)
    cell = _cells(l0, l1)
    pw = powers(photons.power, jj)
    lum = pw @ np.array([0.2126, 0.7152, 0.0722])  # Rec.709 luminance
    w = np.where(ok, lum, 0.0)
    flat = (np.arange(p)[:, None] * CELLS + cell).ravel()
    flux = np.bincount(flat, weights=w.ravel(), minlength=p * CELLS).reshape(p, CELLS)
    w_sq = (w * w).sum(axis=1)
    return flux, w_sq


def _cells(l0, l1):
    """Cell index (ROWS x COLS, row-major) of local unit directions (l0, l1, l2 > 0) in the
    cosine-warped square: u1 = sin^2 theta = l0^2 + l1^2, u2 = phi / 2 pi."""
    u1 = np.clip(l0 * l0 + l1 * l1, 0.0, _ONE_BELOW)
    u2 = (np.arctan2(l1, l0) / (2.0 * np.pi)) % 1.0
    return (np.minimum((u1 * ROWS).astype(np.int64), ROWS - 1) * COLS
            + np.minimum((u2 * COLS).astype(np.int64), COLS - 1))


def _flux_grids(position, normal, photons, radius, emitters, chunk=256):
    """(P, CELLS) per gather point the irradiance its cells would receive from the stored
    non-caustic photons taken as small diffuse emitters (each reflects its power from
    where it lies: the light a gather ray's end reads, one bounce on): `emitters` of them
    drawn by power (systematic sampling over the cumulative luminance: deterministic),
    each carrying total / emitters; a pair adds P cos_x cos_y / (pi max(r^2, radius^2))
    (the point-to-point form factor, Cohen & Wallace, "Radiosity and Realistic Image
    Synthesis" 1993; the disc of one radius bounds it near), visibility ignored: a wall
    between them only wastes rays, the estimate stays unbiased (the cosine lobe's share)."""
    p = len(position)
    out = np.zeros((p, CELLS))
    rows = np.flatnonzero(photons.kind != CAUSTIC)
    if not p or not len(rows):
        return out
    lum = (powers(photons.power, rows) @ np.array([0.2126, 0.7152, 0.0722]))
    cum = np.cumsum(lum)
    if cum[-1] <= 0.0:
        return out
    pick = np.searchsorted(cum, (np.arange(emitters) + 0.5) / emitters * cum[-1], side="right")
    pick = np.take(rows, np.minimum(pick, len(rows) - 1))
    ey = np.take(photons.position, pick, axis=0).astype(np.float64)
    ny = vectors(photons.normal, pick)
    r2min = radius * radius
    t, b = orthonormal_basis(normal)
    for a in range(0, p, chunk):
        z = slice(a, min(a + chunk, p))
        v = ey[None, :, :] - position[z, None, :]                  # (c, M, 3)
        r2 = np.einsum("cmk,cmk->cm", v, v)
        inv = 1.0 / np.sqrt(np.maximum(r2, 1e-30))
        cx = np.einsum("cmk,ck->cm", v, normal[z]) * inv
        cy = -np.einsum("cmk,mk->cm", v, ny) * inv
        w = np.where((cx > 0.0) & (cy > 0.0), cx * cy / np.maximum(r2, r2min), 0.0)
        l0 = np.einsum("cmk,ck->cm", v, t[z]) * inv
        l1 = np.einsum("cmk,ck->cm", v, b[z]) * inv
        cell = _cells(l0, l1)
        flat = ((np.arange(z.stop - a)[:, None] * CELLS) + cell).ravel()
        out[z] = np.bincount(flat, weights=w.ravel(),
                             minlength=(z.stop - a) * CELLS).reshape(-1, CELLS)
    return out


def _invert(prob, u):
    """Inverse of a piecewise-constant distribution per row: prob (N,K) (rows sum to 1),
    u (N,) in [0, 1) -> (cell k (N,), its probability (N,), u's fraction within it)."""
    ar = np.arange(len(u))
    cdf = np.cumsum(prob, axis=1)
    cdf[:, -1] = 1.0
    k = np.minimum((cdf <= u[:, None]).sum(axis=1), prob.shape[1] - 1)
    p = prob[ar, k]
    frac = np.clip((u - (cdf[ar, k] - p)) / p, 0.0, _ONE_BELOW)
    return k, p, frac


def warp(u1: np.ndarray, u2: np.ndarray, row_prob: np.ndarray, col_prob: np.ndarray):
    """(u1', u2', weight): (u1, u2) (N,) uniform in [0, 1) mapped to the piecewise-constant
    density q over the ROWS x COLS cells (row by the marginal row_prob (N,ROWS), column by
    the conditional col_prob (N,ROWS,COLS)), weight = 1 / q(u') (N,): a cosine gather
    ray's weight for a ray from u' (the cosine lobe's pdf cancels)."""
    ar = np.arange(len(u1))
    i, pr, fr = _invert(row_prob, u1)
    jcol, pc, fc = _invert(col_prob[ar, i], u2)                       # (N, COLS) given i
    v1 = np.minimum((i + fr) / ROWS, _ONE_BELOW)
    v2 = np.minimum((jcol + fc) / COLS, _ONE_BELOW)
    weight = 1.0 / (CELLS * pr * pc)
    return v1, v2, weight
