"""Homogeneous media inside objects: coloured glass, liquids, fog (Beer-Lambert extinction).

A material's `absorption` (Material.absorption, sigma_a (3,) in 1/m, per channel) is the
medium filling the object it is on. Light that travels a distance s inside that medium
keeps T = exp(-sigma_t s) of its power, sigma_t = sigma_a + sigma_s the extinction of
an absorbing and scattering medium (absorption_table; the light scattered into the ray is
engine/volumescatter.py's) (Cycles' homogeneous volumes: the extinction
closure volume_extinction_setup, integrated analytically along the segment; for a Volume
Absorption node sigma_a = density x (1 - colour), svm_node_closure_volume in
intern/cycles/kernel/svm/closure.h; Principled Volume: svm_node_principled_volume,
docs/compatibility.md, Volume absorption). Distances are world distances: the object's
scale is in its triangles.

Which segments are inside a medium (a one-level medium stack): each camera path and
photon carries the medium it is in (`medium`, a material row, -1: none known). A ray
that crosses a surface of an absorbing material (a refraction, a transparent pass: the
continued direction is on the far side) enters that medium through a front face (the
winding's outside, d . (e1 x e2) < 0) and leaves it through a back face (media_after);
a reflection keeps the medium. Each segment is attenuated by its ray's medium where the
segment ends (the camera paths after each intersection, engine/integrator.py
_trace_paths, and the final-gather rays, gather_indirect; the photons before each
scatter, engine/photons.py _bounces), so a surface
inside the medium (a floor under a liquid, a straw in a drink, a box standing on the
floor) is seen and lit through it. A ray whose medium is not known (a camera inside a
liquid, a shadow ray from a point inside one) takes the local rule: its segment was
inside object O's medium when it ends on a back face of O. Shadow rays use that rule
alone (engine/shadowtransmittance.py shadow_step): they start on a surface and leave
every medium they are in through a back face, or are blocked. Limits of this first
slice: one level (a liquid inside coloured glass: inside the liquid the glass's medium is
forgotten, and leaving the liquid returns to none); meshes must be closed with outward
normals, as Cycles asks of volumes too.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up

NO_SIGMA = np.zeros((0, 3))  # no absorbing material: nothing to do
# The extinction of a medium that emits but neither absorbs nor scatters (absorption_table).
EMISSION_ONLY_SIGMA = 1e-300


def absorption_table(table) -> np.ndarray:
    """(M,3) float64 extinction sigma_t = sigma_a + sigma_s (1/m) of the material table's
    rows (MaterialTable.absorption plus MaterialTable.scattering, as Cycles' extinction
    closure sums both: svm_node_principled_volume; zeros where a material has no medium),
    or NO_SIGMA (0 rows) when no material has a medium, which the kernels read as "no
    media" (they then touch nothing). Every segment inside a medium keeps
    exp(-sigma_t s): the light a scattering medium scatters out of a ray is what
    engine/volumescatter.py adds back as in-scattering.

    A row with extinction in some channel is a medium: the one rule every kernel here
    (and shadowtransmittance, mediumstart) reads. A medium that only emits
    (MaterialTable.volume_emission, engine/volumeemission.py) gets EMISSION_ONLY_SIGMA in
    every channel so that the rule covers it: exp(-1e-300 s) is exactly 1 in float64 for
    every s below 1e280 m, so it dims nothing, and its emission integral takes the
    optical-depth expansion e s (volumeemission.emission_integral)."""
    sigma = getattr(table, "absorption", None)
    if sigma is None:
        return NO_SIGMA
    sigma = np.ascontiguousarray(sigma, np.float64).reshape(-1, 3)
    scat = getattr(table, "scattering", None)
    if scat is not None:
        sigma = sigma + np.asarray(scat, np.float64).reshape(-1, 3)
    emit = getattr(table, "volume_emission", None)
    if emit is not None:
        glow_only = (np.any(np.asarray(emit, np.float64).reshape(-1, 3) > 0, axis=1)
                     & ~np.any(sigma > 0, axis=1))
        if glow_only.any():
            sigma = np.array(sigma, copy=True)
            sigma[glow_only] = EMISSION_ONLY_SIGMA
    if not np.any(sigma > 0):
        return NO_SIGMA
    return np.ascontiguousarray(sigma)


@kernel
def segment_medium(e1, e2, row, m_hit, medium, sigma, dx, dy, dz):
    """The material row of the medium a segment along d (dx, dy, dz) that ends on
    triangle row `row` (material m_hit; row < 0: no surface, a lamp or the world) lay
    in, or -1: none. A ray whose medium is known (medium >= 0) was in it; else the local
    rule: inside m_hit's medium when the segment leaves through a back face of a medium
    material (d . (e1 x e2) > 0)."""
    if medium >= 0:
        return medium
    if row < 0:
        return -1
    if not (sigma[m_hit, 0] > 0.0 or sigma[m_hit, 1] > 0.0 or sigma[m_hit, 2] > 0.0):
        return -1
    nx = e1[row, 1] * e2[row, 2] - e1[row, 2] * e2[row, 1]
    ny = e1[row, 2] * e2[row, 0] - e1[row, 0] * e2[row, 2]
    nz = e1[row, 0] * e2[row, 1] - e1[row, 1] * e2[row, 0]
    if dx * nx + dy * ny + dz * nz <= 0.0:
        return -1  # entering (or grazing): the segment was outside
    return m_hit


@kernel
def leaving_transmittance(e1, e2, row, m, sigma, dx, dy, dz, t, out):
    """out (3,) = exp(-sigma[m] x distance) when the ray d (dx, dy, dz), which met
    triangle row `row` (edge tables e1, e2) of material m at t (units of |d|), leaves
    through the triangle's back face (d . (e1 x e2) > 0: the segment lay inside the
    object); else 1. Returns True when a channel is below 1."""
    out[0] = 1.0
    out[1] = 1.0
    out[2] = 1.0
    s0 = sigma[m, 0]
    s1 = sigma[m, 1]
    s2 = sigma[m, 2]
    if not (s0 > 0.0 or s1 > 0.0 or s2 > 0.0):
        return False
    nx = e1[row, 1] * e2[row, 2] - e1[row, 2] * e2[row, 1]
    ny = e1[row, 2] * e2[row, 0] - e1[row, 0] * e2[row, 2]
    nz = e1[row, 0] * e2[row, 1] - e1[row, 1] * e2[row, 0]
    if dx * nx + dy * ny + dz * nz <= 0.0:
        return False  # entering (or grazing): the segment was outside
    s = max(t, 0.0) * math.sqrt(dx * dx + dy * dy + dz * dz)
    out[0] = math.exp(-s0 * s)
    out[1] = math.exp(-s1 * s)
    out[2] = math.exp(-s2 * s)
    return True


@kernel
def _segment(e1, e2, row, m_hit, medium, sigma, dx, dy, dz, t, out):
    """out (3,) the transmittance of a segment along d (dx, dy, dz) of t (units of |d|)
    that ends on triangle row `row` (material m_hit) for a ray in `medium` (a material
    row; < 0: not known, then the local rule: segment_medium). Returns True when a
    channel is below 1."""
    m = segment_medium(e1, e2, row, m_hit, medium, sigma, dx, dy, dz)
    if m < 0:
        out[0] = 1.0
        out[1] = 1.0
        out[2] = 1.0
        return False
    s = max(t, 0.0) * math.sqrt(dx * dx + dy * dy + dz * dz)
    out[0] = math.exp(-sigma[m, 0] * s)
    out[1] = math.exp(-sigma[m, 1] * s)
    out[2] = math.exp(-sigma[m, 2] * s)
    return out[0] < 1.0 or out[1] < 1.0 or out[2] < 1.0


@kernel
def attenuate_rows(rows, material, e1, e2, sigma, d, t, tp, medium):
    """tp (n,3) *= the transmittance of each ray's last segment (_segment): rows (n,)
    int64 the triangle row each ray met (< 0: none, untouched), material (T,) its
    material, e1, e2 (T,3) its edges; d (n,3) the rays' directions, t (n,) their hit
    distances in units of |d|; medium (n,) int64 each ray's medium (-1: not known);
    sigma (M,3) absorption_table (0 rows: nothing done). Returns the count attenuated."""
    if sigma.shape[0] == 0:
        return 0
    out = np.empty(3)
    k = 0
    for i in range(rows.shape[0]):
        r = rows[i]
        if r < 0:
            continue
        if _segment(e1, e2, r, material[r], medium[i], sigma, d[i, 0], d[i, 1], d[i, 2],
                    t[i], out):
            tp[i, 0] *= out[0]
            tp[i, 1] *= out[1]
            tp[i, 2] *= out[2]
            k += 1
    return k


@kernel
def _crossed(e1, e2, row, m, sigma, ax, ay, az, bx, by, bz, medium):
    """The medium after a ray arriving along a (ax, ay, az) at triangle row (material m)
    went on along b: m when it crossed an absorbing material's front face, -1 when it
    crossed its back face, else `medium` (a reflection, or a surface without a medium)."""
    if not (sigma[m, 0] > 0.0 or sigma[m, 1] > 0.0 or sigma[m, 2] > 0.0):
        return medium
    nx = e1[row, 1] * e2[row, 2] - e1[row, 2] * e2[row, 1]
    ny = e1[row, 2] * e2[row, 0] - e1[row, 0] * e2[row, 2]
    nz = e1[row, 0] * e2[row, 1] - e1[row, 1] * e2[row, 0]
    a = ax * nx + ay * ny + az * nz
    b = bx * nx + by * ny + bz * nz
    if a < 0.0 and b < 0.0:
        return m
    if a > 0.0 and b > 0.0:
        return -1
    return medium


@kernel
def media_after(rows, material, e1, e2, sigma, d_in, keep, d_out, medium_in, medium_out):
    """The camera paths' media after a continuation: the rows keep (K,) of the n hits
    (triangle rows (n,), < 0 none; arriving directions d_in (n,3), media medium_in (n,))
    went on along d_out (K,3); medium_out (K,) written (_crossed)."""
    for k in range(keep.shape[0]):
        i = keep[k]
        r = rows[i]
        medium_out[k] = medium_in[i]
        if r < 0 or sigma.shape[0] == 0:
            continue
        medium_out[k] = _crossed(e1, e2, r, material[r], sigma, d_in[i, 0], d_in[i, 1],
                                 d_in[i, 2], d_out[k, 0], d_out[k, 1], d_out[k, 2],
                                 medium_in[i])


@kernel
def attenuate_hits(geom, prim, starts, material, e1, e2, sigma, d, t, power, medium,
                   hit_row):
    """The photons' side of attenuate_rows, for hits as Embree answers them (geom, prim
    (m,) int32, geom < 0 a miss, the triangle row starts[geom] + prim; t (m,) float32):
    power (m,3) *= its last segment's transmittance in the photon's medium (medium (m,)
    int64, each photon ray's own: a copy passing behind a surface shares its photon's
    slot, not its medium). Records each hit's triangle row (-1: a miss) in hit_row (m,)
    for photon_media_after. Returns the count attenuated."""
    out = np.empty(3)
    k = 0
    for i in range(geom.shape[0]):
        g = geom[i]
        if g < 0:
            hit_row[i] = -1
            continue
        r = starts[g] + prim[i]
        hit_row[i] = r
        if _segment(e1, e2, r, material[r], medium[i], sigma, d[i, 0], d[i, 1], d[i, 2],
                    float(t[i]), out):
            power[i, 0] *= out[0]
            power[i, 1] *= out[1]
            power[i, 2] *= out[2]
            k += 1
    return k


@kernel
def photon_media_after(parent, d_out, material, e1, e2, sigma, medium, hit_row, d_in,
                       medium_out):
    """The photons' media after the scatter: each continued photon k (K,), which came
    from row parent[k] of the bounce's rays (arriving along d_in (m,3) in medium (m,) at
    the hit attenuate_hits recorded in hit_row (m,)) and goes on along d_out[k], gets
    medium_out[k] (_crossed; its photon's medium where that row met no surface)."""
    for k in range(parent.shape[0]):
        i = parent[k]
        r = hit_row[i]
        if r < 0:
            medium_out[k] = medium[i]
            continue
        medium_out[k] = _crossed(e1, e2, r, material[r], sigma, d_in[i, 0], d_in[i, 1],
                                 d_in[i, 2], d_out[k, 0], d_out[k, 1], d_out[k, 2], medium[i])


def attenuated(geo, sigma, prim, d, t, tp, medium) -> np.ndarray:
    """The camera paths' throughput tp (n,3) after their last segment (a new array when
    any ray was attenuated, else tp itself): prim (n,) the triangles met (< 0: none), d
    (n,3), t (n,) in units of |d|, medium (n,) int64 each path's medium (-1: not known);
    sigma absorption_table's (NO_SIGMA: tp as it is). Shared instances read their hits'
    own rows (Geometry.hit_tables)."""
    if sigma.shape[0] == 0 or len(prim) == 0:
        return tp
    rows, (material, e1, e2) = geo.hit_tables(prim, "material", "e1", "e2")
    out = np.array(tp, np.float64, copy=True)
    n = attenuate_rows(rows, _int32(material), _f64(e1), _f64(e2), sigma, _f64(d), _f64(t),
                       out, np.ascontiguousarray(medium, np.int64))
    return out if n else tp


def after_continuation(geo, sigma, prim, d_in, keep, d_out, medium,
                       outside: int = -1) -> np.ndarray:
    """(K,) int64 the media of the continued camera paths (media_after): prim (n,) the
    hits' triangles, d_in (n,3) the arriving directions, medium (n,) their media, keep
    (K,) the continued rows, d_out (K,3) their new directions. outside: the medium of a
    path outside every object's medium (the world volume's row,
    engine/worldmedium.medium_row; -1: none), read for "none" (-1)."""
    out = np.empty(len(keep), np.int64)
    if sigma.shape[0] == 0:
        out[:] = -1
        return out
    rows, (material, e1, e2) = geo.hit_tables(prim, "material", "e1", "e2")
    media_after(rows, _int32(material), _f64(e1), _f64(e2), sigma, _f64(d_in),
                np.ascontiguousarray(keep, np.int64), _f64(d_out),
                np.ascontiguousarray(medium, np.int64), out)
    return _outside(out, outside)


def _outside(medium: np.ndarray, outside: int) -> np.ndarray:
    """medium (n,) int64 with "none" (-1) read as `outside` (in place; outside < 0:
    medium as it is): the one place that decides which medium lies outside every
    object's."""
    if outside >= 0:
        medium[medium < 0] = outside
    return medium


class PhotonMedia:
    """The media of one chunk's photon rays (engine/photons.py _bounces), per ray of the
    current bounce (not per slot: a copy passing behind a surface, photonkernels._scatter's
    split-off, shares its photon's slot but not its path): `medium` (m,) int64 the medium
    each ray is in (-1: none known), and the hits of the bounce (attenuate)."""

    def __init__(self, sigma, rays: int, start: int = -1):
        self.sigma = sigma
        self.medium = np.full(rays, start, np.int64)
        self.hit_row = np.full(rays, -1, np.int64)

    def attenuate(self, geom, prim, starts, material, e1, e2, d, t, power) -> int:
        """power (m,3) float64 x its last segment's transmittance in each ray's medium, in
        place (attenuate_hits); the hits recorded for after_scatter."""
        if len(geom) == 0:
            return 0
        self.tables = (_int32(material), _f64(e1), _f64(e2))
        if len(self.hit_row) < len(geom):
            self.hit_row = np.empty(len(geom), np.int64)
        self.d_in = _f64(d)
        return attenuate_hits(np.ascontiguousarray(geom, np.int32),
                              np.ascontiguousarray(prim, np.int32),
                              np.ascontiguousarray(starts, np.int64), *self.tables,
                              self.sigma, self.d_in, np.ascontiguousarray(t, np.float32),
                              power, self.medium, self.hit_row)

    def after_scatter(self, parent, d_out, outside: int = -1):
        """The continued rays' media (photon_media_after), which become `medium`: parent
        (K,) each one's row of the bounce's rays (photonkernels.scatter's nx_row), d_out
        (K,3) its direction; outside: after_continuation's."""
        out = np.empty(len(parent), np.int64)
        if len(parent):
            photon_media_after(np.ascontiguousarray(parent, np.int64), _f64(d_out),
                               *self.tables, self.sigma, self.medium, self.hit_row,
                               self.d_in, out)
        self.medium = _outside(out, outside)


def _int32(a):
    # (the geometry's own material table is int32: no copy of a large table)
    return np.ascontiguousarray(a, np.int32)


def _f64(a):
    return np.ascontiguousarray(a, np.float64)


@register_warm_up
def _warm_up():
    """Compile (or load) the kernels on one ray leaving a unit triangle."""
    e1 = np.array([[1.0, 0.0, 0.0]])
    e2 = np.array([[0.0, 1.0, 0.0]])
    sigma = np.ones((1, 3))
    d = np.array([[0.0, 0.0, 1.0]])
    tp = np.ones((1, 3))
    mat = np.zeros(1, np.int32)
    one = np.zeros(1, np.int64)
    attenuate_rows(one, mat, e1, e2, sigma, d, np.ones(1), tp, np.full(1, -1, np.int64))
    media_after(one, mat, e1, e2, sigma, d, one, d, np.full(1, -1, np.int64),
                np.empty(1, np.int64))
    pm = PhotonMedia(sigma, 1)
    pm.attenuate(np.zeros(1, np.int32), np.zeros(1, np.int32), one, mat, e1, e2, d,
                 np.ones(1, np.float32), tp)
    pm.after_scatter(one, d)
    leaving_transmittance(e1, e2, 0, 0, sigma, 0.0, 0.0, 1.0, 1.0, np.empty(3))
