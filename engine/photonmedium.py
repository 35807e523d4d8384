"""Photons that scatter in homogeneous media (multiple scattering onto surfaces; issue 14).

A photon travelling in a medium with a scattering coefficient sigma_s > 0 (the medium it
is in: media.PhotonMedia) samples a free-flight distance on its segment to the next
surface (engine/photons.py _bounces, after the Embree call that found that surface):
  - it scatters at distance s < S (S: the segment's length) with the Henyey-Greenstein
    direction of the medium's g (volumescatter.sample_hg: phase / pdf = 1), its power
    times sigma_s exp(-sigma_t s) / pdf(s), and goes on from there as a new ray;
  - or it reaches the surface, its power times exp(-sigma_t S) / P(pass) (the exp(-sigma_t
    S) is media.PhotonMedia.attenuate's, done as before; here only the 1 / P(pass)).
Chromatic media: the distance is drawn from one colour channel's exponential, channel c
picked with probability q_c proportional to the photon's power in c (Cycles'
volume_sample_channel picks by throughput x albedo; pbrt-v4 samples a hero wavelength):
pdf(s) = sum_c q_c sigma_t,c exp(-sigma_t,c s), P(pass) = sum_c q_c exp(-sigma_t,c S),
the one-sample MIS over the channels (balance heuristic), unbiased in every channel. For a
grey medium the weights are exactly the albedo (scatter) and 1 (pass). Russian roulette
by the scatter weight's largest channel keeps a scattered photon's power (survival
probability min(1, max_c w_c), power x w / p), so the stored photons keep equal powers in
an albedo-1 fog and end in an absorbing one.

After a scatter the photon's path is indirect light (the F_DIFFUSE flag, as a diffuse
bounce: photons.py's INDIRECT, or CAUSTIC_DIFFUSE after a specular path): it is stored at
the surface it reaches like any indirect photon, so the final-gather rays' lookups see the
light the fog scatters onto surfaces. (The camera's own first hit reads no INDIRECT
photon: the gather rays from it carry the fog's single scattering themselves,
volumescatter.CameraScattering.radiance, so no path is counted twice.) A scatter counts a
bounce in the photon's total (Cycles' path_state_next counts volume scatters in
max_bounce) and against Light Paths > Volume bounces: Cycles' kernel limit is
volume_bounces + 1 (Integrator::device_update), a path's scatter k going on when k <
that, so a path has at most volume_bounces + 1 volume scatters, its last lit by the lamps.
A photon's scatters are the path's last ones (the camera side's gather rays and lookups
have none), so a photon scatters at most volume_bounces + 1 times (none at the default
Volume bounces 0: max_scatters). Past its last allowed scatter a photon only loses the light scattered
out (exp(-sigma_t S), as before): Cycles' PATH_RAY_TERMINATE_AFTER_VOLUME.

Random numbers: the photon stream's own hash (photonkernels.uniform's SplitMix64, by
slot and bounce) under a key of its own (VOLUME_KEY_SALT), so a photon's distances and
directions depend on its slot, its bounce and the seed alone: the same photons for any
worker count or chunking.
"""
from __future__ import annotations

import numpy as np

from . import photonkernels as pk
from .volumescatter import sample_hg, scattering_tables

# Salt of the volume stream's key (any fixed odd 64-bit number; not the surface stream's).
VOLUME_KEY_SALT = np.uint64(0xD1B54A32D192ED03)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_N_DIMS = 5  # per photon and bounce: channel pick, distance, roulette, the direction (2)
_B_ONE = np.int64(1)  # B_TOTAL is the packed counts' lowest field (photonkernels)
_B_MASK = np.int64((1 << 16) - 1)


def uniforms(key, slot: np.ndarray, bounce: int, dim: int) -> np.ndarray:
    """(n,) float64 in [0, 1): SplitMix64's output number (slot x 2^16 + bounce) x 5 +
    dim of the stream seeded by key ^ VOLUME_KEY_SALT (photonkernels.uniform's hash in
    numpy, under the volume stream's key)."""
    k = np.uint64(key) ^ VOLUME_KEY_SALT
    counter = ((np.asarray(slot, np.uint64) * np.uint64(pk.MAX_BOUNCES) + np.uint64(bounce))
               * np.uint64(_N_DIMS) + np.uint64(dim))
    with np.errstate(over="ignore"):
        z = k + (counter + np.uint64(1)) * _GOLDEN
        z = (z ^ (z >> np.uint64(30))) * _M1
        z = (z ^ (z >> np.uint64(27))) * _M2
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def max_scatters(volume_bounces: int) -> int:
    """The scatters a photon may take in a medium at Light Paths > Volume bounces: 0 at
    0 (the light the fog scatters once onto a surface is the final-gather rays' own
    single scattering there; a photon scattered once and stored on another surface X is
    light a path camera -> surface -> X -> fog -> lamp brings, which Cycles' limit allows,
    but left out at the default as before this module: measured in docs/accuracy.md,
    volphotons38), else volume_bounces + 1 (Cycles' per-path limit, see above)."""
    b = int(volume_bounces or 0)
    return 0 if b <= 0 else b + 1


class PhotonScattering:
    """Free flights of one chunk's photons in scattering media (module docstring); None
    from for_chunk when no material scatters, Volume bounces is 0 or the shot stores
    caustics only."""

    def __init__(self, tables, scatters: int, rays: int, limits):
        self.sigma_t, self.sigma_s, self.g = tables
        self.scatters = scatters
        # Each ray's volume scatters so far (per ray, not per slot: a copy passing behind
        # a surface shares its photon's slot, not its path; photons.py takes the continued
        # rays' from their rows, photonkernels.scatter's nx_row).
        self.count = np.zeros(rays, np.int16)
        self.max_total = int(np.asarray(limits)[pk.B_TOTAL])
        self.scattering = np.any(self.sigma_s > 0.0, axis=1)  # (M,) a medium that scatters
        # Density textures (engine/heterogeneous.py; set by photons._bounces): the
        # scatters' weights take the ratio-tracked T(s) and the field at the point (the
        # passing photons take their correction with the attenuation, photons.py).
        self.hetero = None

    @classmethod
    def for_chunk(cls, table, settings, rays: int, caustic_only: bool):
        scatters = max_scatters(getattr(settings, "volume_bounces", 0))
        if scatters <= 0 or caustic_only:
            return None
        tables = scattering_tables(table)
        if tables is None:
            return None
        return cls(tables, scatters, rays, settings.bounce_limits)

    def flights(self, key, bounce: int, o32, d, tfar, geom, power, slot, bnc, medium,
                clamp=None):
        """Sample each photon's free flight on its segment (photons o32, d (m,3), d unit,
        segment lengths tfar (m,) float32, a miss's the unbounded tmax; geom (m,) int32
        Embree's, < 0 a miss; power (m,3) float64 W; slot (m,); bnc (m,) int64 packed
        bounce counts (photonkernels, B_TOTAL lowest); medium (m,) int64 each
        ray's medium, -1 none known; self.count (m,) each ray's scatters). In place: the passing photons' power x 1 /
        P(pass); the scattering ones' geom set to -1 (the surface scatter treats them as
        lost: no store, no continuation, no attenuation). clamp (m,) float64 or None: the
        photons' Clamp Indirect ratio c = |L|_1 / |power|_1 (photonkernels._scatter's),
        the scattered ones' rescaled as the surface scatter does: L takes the scatter's
        weight w and the power w / p_keep, so c x p_keep (a passing photon's power and L
        both take exp(-sigma_t S) / P(pass): c as it is). Returns (rows (K,), origins
        (K,3), directions (K,3), powers (K,3)) of the K photons that scattered and
        survived the roulette, or None."""
        if len(geom) == 0:
            return None
        med = medium
        rows = np.flatnonzero((med >= 0))
        if len(rows) == 0:
            return None
        rows = rows[self.scattering[med[rows]] & (self.count[rows] < self.scatters)]
        if len(rows) == 0:
            return None
        s_rows = slot[rows]
        m_rows = med[rows]
        sig_t = self.sigma_t[m_rows]
        sig_s = self.sigma_s[m_rows]
        S = np.asarray(tfar, np.float64)[rows]
        S = np.where(np.asarray(geom)[rows] < 0, np.inf, S)
        pw = np.maximum(power[rows], 0.0)
        tot = pw.sum(axis=1)
        q = np.where(tot[:, None] > 0.0, pw / np.where(tot > 0.0, tot, 1.0)[:, None], 1.0 / 3.0)
        u_c = uniforms(key, s_rows, bounce, 0)
        u_s = uniforms(key, s_rows, bounce, 1)
        cdf = np.cumsum(q, axis=1)
        c = np.minimum((u_c[:, None] >= cdf).sum(axis=1), 2)
        sc = sig_t[np.arange(len(rows)), c]
        # s = -ln(1 - u) / sigma_t,c (inf where that channel has no extinction: passes)
        with np.errstate(divide="ignore"):
            s = np.where(sc > 0.0, -np.log1p(-u_s) / np.where(sc > 0.0, sc, 1.0), np.inf)
        hit = s >= S
        # Passing: x 1 / P(pass) (exp(-sigma_t S) is attenuate's).
        p_rows = rows[hit]
        if len(p_rows):
            Sp = S[hit]
            with np.errstate(invalid="ignore", over="ignore"):
                P = np.sum(q[hit] * np.exp(-sig_t[hit] * Sp[:, None]), axis=1)
            power[p_rows] /= np.where(P > 0.0, P, 1.0)[:, None]
        scat = ~hit
        if not np.any(scat):
            return None
        r = rows[scat]
        s = s[scat]
        st, ss = sig_t[scat], sig_s[scat]
        Tr = np.exp(-st * s[:, None])
        pdf = np.sum(q[scat] * st * Tr, axis=1)
        w = ss * Tr / np.maximum(pdf, 1e-300)[:, None]
        if self.hetero is not None:
            o_r = np.asarray(o32, np.float64)[r]
            d_r = np.asarray(d, np.float64)[r]
            w = self.hetero.scatter_weights(o_r, d_r, o_r + s[:, None] * d_r, med[r], w)
        geom[r] = -1  # the surface scatter sees a miss
        slots_r = slot[r]
        # Russian roulette by the weight's largest channel.
        p_keep = np.minimum(1.0, np.max(w, axis=1))
        u_rr = uniforms(key, slots_r, bounce, 2)
        live = u_rr < p_keep
        # Past Max Bounces (the total) a photon's light is no path's: not continued.
        live &= ((np.asarray(bnc, np.int64)[r] & _B_MASK) + 1) <= self.max_total
        if not np.any(live):
            return None
        r, s, w, p_keep = r[live], s[live], w[live], p_keep[live]
        slots_r = slot[r]
        self.count[r] += 1
        dr = np.asarray(d, np.float64)[r]
        x = np.asarray(o32, np.float64)[r] + s[:, None] * dr
        u1 = uniforms(key, slots_r, bounce, 3)
        u2 = uniforms(key, slots_r, bounce, 4)
        m_live = medium[r]
        w_new = sample_hg(dr, self.g[m_live], u1, u2)
        p_new = power[r] * (w / p_keep[:, None])
        if clamp is not None and len(clamp):
            clamp[r] *= p_keep
        return r, x, w_new, p_new


def continue_scattered(nxt, n_nx: int, found, flags, kinds, bnc, slot, clamp=None,
                       nx_clamp=None, nx_row=None, nx_blur=None) -> int:
    """Write the scattered photons found = flights(...) (rows into the bounce's arrays
    flags, kinds, bnc, slot) after the n_nx continued photons of the next-ray buffers nxt
    (photonkernels.next_arrays' order: o32, d32, d, power, flags, kinds, slot, bnc, from,
    off): their path is indirect (F_DIFFUSE, as a diffuse bounce: CAUSTIC_DIFFUSE after a
    specular path, its light one scatter later), every non-camera ray kind, B_TOTAL one
    more; clamp (m,) / nx_clamp (rows of nxt) the Clamp Indirect ratios (flights'
    rescaled ones; None or empty: none kept); nx_row, nx_blur (rows of nxt) each
    continued ray's row of the bounce and Filter Glossy state (photonkernels._scatter's;
    a medium's scatter is a diffuse bounce: -1; None or empty: not kept). Returns the new
    count."""
    r, x, w_new, p_new = found
    k = len(r)
    end = n_nx + k
    o32, d32, dd, pw, fl_o, kin_o, sl_o, bn_o, frm, off = nxt
    o32[n_nx:end] = x
    d32[n_nx:end] = w_new
    dd[n_nx:end] = w_new
    pw[n_nx:end] = p_new
    fl = np.asarray(flags)[r] & ((np.int64(1) << 8) - 1)
    fl &= ~np.int64(pk.F_IN_GLASS | pk.F_PANE)
    was_diffuse = (fl & pk.F_DIFFUSE) != 0
    was_specular = (fl & pk.F_SPECULAR) != 0
    fl = np.where(was_diffuse, fl & ~np.int64(pk.F_CAUSTIC_DIFF),
                  np.where(was_specular, fl | pk.F_CAUSTIC_DIFF, fl))
    fl_o[n_nx:end] = fl | pk.F_DIFFUSE
    kin_o[n_nx:end] = pk.SEGMENT_KINDS
    sl_o[n_nx:end] = np.asarray(slot)[r]
    if clamp is not None and len(clamp):
        nx_clamp[n_nx:end] = np.asarray(clamp)[r]
    if nx_row is not None and len(nx_row):
        nx_row[n_nx:end] = r
    if nx_blur is not None and len(nx_blur):
        nx_blur[n_nx:end] = -1.0
    b = np.asarray(bnc, np.int64)[r]
    bn_o[n_nx:end] = np.where((b & _B_MASK) == _B_MASK, b, b + _B_ONE)
    if len(frm):
        frm[n_nx:end] = -1
        off[n_nx:end] = 0.0
    return end
