"""Homogeneous absorbing media inside objects: coloured glass and liquids (Beer-Lambert).

A material's `absorption` (Material.absorption, sigma_a (3,) in 1/m, per channel) is the
medium filling the object it is on. Light that travels a distance s inside that medium
keeps T = exp(-sigma_a s) of its power (Cycles' homogeneous volumes: the extinction
closure volume_extinction_setup, integrated analytically along the segment; for a Volume
Absorption node sigma_a = density x (1 - colour), svm_node_closure_volume in
intern/cycles/kernel/svm/closure.h; Principled Volume: svm_node_principled_volume,
docs/compatibility.md, Volume absorption). Distances are world distances: the object's
scale is in its triangles.

Which segments are inside a medium, without a medium stack: a segment is inside object
O's medium when it ends on a hit of O's back face (the ray leaves O through a face whose
winding points along it: d . (e1 x e2) > 0). That rule is local to the hit that ends the
segment, so the three passes apply it where they already know the segment's length: the
camera paths after each intersection (engine/integrator.py _trace_paths), the photons
before each scatter (engine/photons.py _bounces), and the shadow rays at each surface
they cross (engine/shadowtransmittance.py shadow_step). It is right for a camera or a
light inside the liquid (its first segment leaves through a back face), for refraction
chains (each inner segment ends on the way out, an inner reflection's too), and for a
liquid in a clear glass (the liquid's segments end on its own back faces). It misses a
medium whose inner surface is another object's front face (a coloured glass holding a
liquid: the segment in the glass wall ends on the liquid's front face, and the wall's
own absorption is not applied there), and rays that miss every surface from inside an
open mesh; both are documented limits of this first slice. Meshes must be closed with
outward normals, as Cycles asks of volumes too.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up

NO_SIGMA = np.zeros((0, 3))  # no absorbing material: nothing to do


def absorption_table(table) -> np.ndarray:
    """(M,3) float64 sigma_a (1/m) of the material table's rows (MaterialTable.absorption;
    zeros where a material has no medium), or NO_SIGMA (0 rows) when no material absorbs,
    which the kernels read as "no media" (they then touch nothing)."""
    sigma = getattr(table, "absorption", None)
    if sigma is None:
        return NO_SIGMA
    sigma = np.ascontiguousarray(sigma, np.float64).reshape(-1, 3)
    if not np.any(sigma > 0):
        return NO_SIGMA
    return sigma


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
def attenuate_rows(rows, material, e1, e2, sigma, d, t, tp):
    """tp (n,3) *= the transmittance of each ray's last segment (leaving_transmittance):
    rows (n,) int64 the triangle row each ray met (< 0: none, untouched), material (T,)
    its material, e1, e2 (T,3) its edges; d (n,3) the rays' directions, t (n,) their hit
    distances in units of |d|; sigma (M,3) absorption_table (0 rows: nothing done).
    Returns the number of rays attenuated."""
    if sigma.shape[0] == 0:
        return 0
    out = np.empty(3)
    k = 0
    for i in range(rows.shape[0]):
        r = rows[i]
        if r < 0:
            continue
        if leaving_transmittance(e1, e2, r, material[r], sigma, d[i, 0], d[i, 1], d[i, 2],
                                 t[i], out):
            tp[i, 0] *= out[0]
            tp[i, 1] *= out[1]
            tp[i, 2] *= out[2]
            k += 1
    return k


@kernel
def attenuate_hits(geom, prim, starts, material, e1, e2, sigma, d, t, power):
    """attenuate_rows for hits as Embree answers them (photons: geom, prim (m,) int32,
    geom < 0 a miss, the triangle row starts[geom] + prim; t (m,) float32)."""
    if sigma.shape[0] == 0:
        return 0
    out = np.empty(3)
    k = 0
    for i in range(geom.shape[0]):
        g = geom[i]
        if g < 0:
            continue
        r = starts[g] + prim[i]
        if leaving_transmittance(e1, e2, r, material[r], sigma, d[i, 0], d[i, 1], d[i, 2],
                                 float(t[i]), out):
            power[i, 0] *= out[0]
            power[i, 1] *= out[1]
            power[i, 2] *= out[2]
            k += 1
    return k


def attenuated(geo, sigma, prim, d, t, tp) -> np.ndarray:
    """The camera paths' throughput tp (n,3) after their last segment (a new array when
    any ray left an absorbing medium, else tp itself): prim (n,) the triangles met
    (< 0: none), d (n,3), t (n,) in units of |d|; sigma absorption_table's (NO_SIGMA:
    tp as it is). Shared instances read their hits' own rows (Geometry.hit_tables)."""
    if sigma.shape[0] == 0 or len(prim) == 0:
        return tp
    rows, (material, e1, e2) = geo.hit_tables(prim, "material", "e1", "e2")
    out = np.array(tp, np.float64, copy=True)
    n = attenuate_rows(rows, _int32(material), _f64(e1), _f64(e2), sigma, _f64(d), _f64(t),
                       out)
    return out if n else tp


def attenuate_photons(geom, prim, starts, material, e1, e2, sigma, d, t, power) -> int:
    """The photons' power (m,3) float64 multiplied in place by their last segment's
    transmittance (attenuate_hits; Embree's hits geom, prim, starts as
    photonkernels.scatter reads them, t (m,) float32 in units of |d|). Returns the count
    attenuated (0 without media)."""
    if sigma.shape[0] == 0 or len(geom) == 0:
        return 0
    return attenuate_hits(np.ascontiguousarray(geom, np.int32),
                          np.ascontiguousarray(prim, np.int32),
                          np.ascontiguousarray(starts, np.int64), _int32(material), _f64(e1),
                          _f64(e2), sigma, _f64(d), np.ascontiguousarray(t, np.float32),
                          power)


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
    attenuate_rows(np.zeros(1, np.int64), np.zeros(1, np.int32), e1, e2, sigma, d,
                   np.ones(1), tp)
    attenuate_hits(np.zeros(1, np.int32), np.zeros(1, np.int32), np.zeros(1, np.int64),
                   np.zeros(1, np.int32), e1, e2, sigma, d, np.ones(1, np.float32), tp)
    leaving_transmittance(e1, e2, 0, 0, sigma, 0.0, 0.0, 1.0, 1.0, np.empty(3))
