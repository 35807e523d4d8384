"""Compiled kernels of the final gather's bookkeeping (integrator.gather_indirect; issue 13,
fifth slice): what ran as numpy indexing between two Embree calls of every gather step.

- `keep_hits`: the rays that met something, compacted in place (the path arrays of a
  gather step: origins, directions, throughput, row of the gathering hit, triangle,
  barycentrics, distance, and the per-ray class once a specular bounce set one).
- `diffuse_lookups`: the hits whose diffuse lobe has weight, with their gather-map lookup
  inputs (point, geometric normal, offset) and ray length written contiguously.
- `add_gathered`: the lookups' irradiance weighted by throughput and diffuse albedo into
  the gathering hits' sums; rows to gather again (a boundary lookup or a short ray) are
  listed instead when the recursion may go deeper.
- `lean_diffuse` (eighth slice): the diffuse albedo of the hits on plain diffuse
  materials (`lean_materials`: one Lambert lobe, nothing textured) without the closures'
  set-up, and the list of the other hits, which alone take bsdf.closures and the
  specular continuation.
- `rays_f32`, `keep_embree_hits` (twelfth slice): a gather step's rays in Embree's
  float32 layout for Accel.intersect_hits(out=) (Embree called from a kernel into the
  thread's buffers), and its answer compacted as `keep_hits` compacts Accel.intersect's:
  the same triangle rows, distances and barycentrics without intersect's conversions
  and fresh arrays (GIL-held numpy, page faults on two workers).
- `count_bounces` (s20 fig8speed as count_bent; glasswater51 by lobe): the gather rays'
  bounce counts after a continuation step (integrator._count_continuations), one pass
  instead of a row take, a compare and four fancy-indexed adds.
- `touch_near` (percost55): coincident.CoincidentSurfaces.near's test (a ray leaves one
  of a touching pair inside its partners' box) in one pass, no per-axis row lists.

Each kernel performs the numpy stage's floating-point operations in the same order, so
images are bitwise unchanged (tests/test_gather_kernels.py keeps the numpy gather as an
oracle; docs/performance.md, "Fifth slice"). All are nogil (engine/jit.py): a chunk on one
worker thread no longer holds the GIL for this glue.
"""
from __future__ import annotations

import numpy as np

from .closures import principled as pr
from .jit import kernel, register_warm_up


def lean_materials(table) -> np.ndarray | None:
    """(M,) bool: the materials whose closures are one Lambert lobe of albedo = the base
    colour, at every hit: opaque (alpha 1, no alpha texture), no metal, transmission,
    specular, coat or sheen layer, no texture of any kind (colour, normal map, scalar
    input, emission) and no emission. principled.setup then leaves every other lobe's
    weight zero (so no continuation: camerakernels.choose_lobes' psum is 0) and the
    diffuse weight is alpha x base = the hit's base colour, bit for bit; `lean_diffuse`
    writes that instead of the whole set-up. A NaN parameter is not lean. None when no
    material is (the caller keeps the general path). table: geometry.MaterialTable."""
    q = table.closure_params
    m = len(q)
    if m == 0:
        return None

    def untextured(nodes):
        return np.array([x is None for x in (nodes or [None] * m)], bool)

    lean = ((np.asarray(table.alpha, np.float64) == 1.0)
            & (q[:, pr.M_METALLIC] <= 0.0) & (q[:, pr.M_TRANS] <= 0.0)
            & (q[:, pr.M_SPEC] <= 0.0) & (q[:, pr.M_COAT_W] <= 0.0)
            & (q[:, pr.M_SHEEN_W] <= 0.0) & (q[:, pr.M_ADD] == 0.0) & (q[:, pr.M_TL] <= 0.0)
            & np.isfinite(q[:, pr.M_TTINT:pr.M_TTINT + 3]).all(axis=1)
            & (np.asarray(table.emission, np.float64) == 0.0).all(axis=1)
            & untextured(table.textures) & untextured(table.normal_maps)
            & untextured(table.alpha_textures) & untextured(table.scalar_textures)
            & untextured(getattr(table, "emission_textures", None)))
    return lean if lean.any() else None


@kernel
def keep_hits(prim, o, d, tp, idx, u, v, t, cls):
    """Compact the rays with prim >= 0 to the front of every array, in order, in place:
    prim, idx (N,) int64; o, d, tp (N,3); u, v, t (N,); cls (N,) int64 or empty (a
    scalar class for all rays). Returns K, the rays kept (arrays[:K] are the hits)."""
    k = 0
    per_ray = cls.shape[0] > 0
    for i in range(prim.shape[0]):
        if prim[i] < 0:
            continue
        if k != i:
            for c in range(3):
                o[k, c] = o[i, c]
                d[k, c] = d[i, c]
                tp[k, c] = tp[i, c]
            prim[k] = prim[i]
            idx[k] = idx[i]
            u[k] = u[i]
            v[k] = v[i]
            t[k] = t[i]
            if per_ray:
                cls[k] = cls[i]
        k += 1
    return k


F32_MAX = float(np.finfo(np.float32).max)  # an unbounded ray's tfar (Accel.intersect's)


@kernel
def rays_f32(o, d, o32, d32, tf32):
    """Rays o, d (N,3) float64 in Embree's layout: o32, d32 (N,3) float32 (rounded to
    nearest, as np.ascontiguousarray(o, np.float32) rounds) and tf32 (N,) = float32's
    largest value (unbounded, Accel.intersect's tmax=None)."""
    for i in range(o.shape[0]):
        for c in range(3):
            o32[i, c] = np.float32(o[i, c])
            d32[i, c] = np.float32(d[i, c])
        tf32[i] = np.float32(F32_MAX)


@kernel
def keep_embree_hits(geom, prim32, u32, v32, tf32, starts, o, d, tp, idx, cls, prim, u, v, t):
    """keep_hits on Embree's answer (Accel.intersect_hits: geom, prim32 (N,) int32, geom
    < 0 a miss; u32, v32 (N,) float32; tf32 (N,) float32 the hit distance; starts (G,)
    int64 the pieces' first triangles): the rays that met something compacted to the
    front of o, d, tp (N,3), idx (N,) int64 and cls ((N,) int64 or empty: one class for
    all), in place, and their triangle row prim = starts[geom] + prim32 (int64), u, v and
    distance t (float64 of the float32 values) into prim, u, v, t (N,) from the front:
    what Accel.intersect answers and keep_hits keeps, bit for bit. Returns K."""
    k = 0
    per_ray = cls.shape[0] > 0
    for i in range(geom.shape[0]):
        g = geom[i]
        if g < 0:
            continue
        prim[k] = starts[g] + np.int64(prim32[i])
        u[k] = np.float64(u32[i])
        v[k] = np.float64(v32[i])
        t[k] = np.float64(tf32[i])
        if k != i:
            for c in range(3):
                o[k, c] = o[i, c]
                d[k, c] = d[i, c]
                tp[k, c] = tp[i, c]
            idx[k] = idx[i]
            if per_ray:
                cls[k] = cls[i]
        k += 1
    return k


@kernel
def diffuse_lookups(wd, p, ng, offset, t, rows, lp, ln, loff, lt):
    """The hits whose diffuse weight wd (N,3) has a positive channel (max3(wd) > 0: a NaN
    channel excludes the row, as np.maximum propagates it): their rows (K,) and, written
    contiguously for GatherMap.lookup, point lp (K,3), geometric normal ln (K,3), offset
    loff (K,) and the gather ray's length lt (K,). Returns K."""
    k = 0
    for i in range(wd.shape[0]):
        a, b, c = wd[i, 0], wd[i, 1], wd[i, 2]
        if a != a or b != b or c != c:
            continue
        if not (a > 0.0 or b > 0.0 or c > 0.0):
            continue
        rows[k] = i
        for j in range(3):
            lp[k, j] = p[i, j]
            ln[k, j] = ng[i, j]
        loff[k] = offset[i]
        lt[k] = t[i]
        k += 1
    return k


@kernel
def add_gathered(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, regather, again):
    """E[idx[rows[r]]] += tp[rows[r]] * wd[rows[r]] * Ey[r] / G for the lookups r (the
    numpy stage's order of operations; rows adding to one row add in order of r: a gather
    step's idx holds each gathering hit once, the regather batch (integrator._regather)
    several times). With regather, the rows r whose lookup met a boundary or
    whose ray is shorter than `short` (lt[r] < short) are skipped and listed in again
    instead (ascending r). E (M,3); idx (N,); rows (K,); tp, wd (N,3); Ey (K,3);
    boundary (K,) bool; lt (K,); again (K,). Returns the number of rows listed."""
    n_again = 0
    g = float(G)
    for r in range(rows.shape[0]):
        if regather and (boundary[r] or lt[r] < short):
            again[n_again] = r
            n_again += 1
            continue
        j = rows[r]
        i = idx[j]
        for c in range(3):
            E[i, c] += tp[j, c] * wd[j, c] * Ey[r, c] / g
    return n_again


@kernel
def lean_diffuse(mat, base, lean, table_alpha, wd, full):
    """The diffuse weight wd (N,3) of the hits of lean materials (lean (M,) bool,
    `lean_materials`): table_alpha[mat] x base, principled.setup's arithmetic for a lone
    Lambert lobe (alpha is 1: the base colour); the other hits' rows are listed in full
    (ascending) and their wd left for bsdf.closures. mat (N,) material index; base (N,3)
    the hits' base colour. Returns the number of rows listed."""
    n_full = 0
    for i in range(mat.shape[0]):
        m = mat[i]
        if lean[m]:
            a = table_alpha[m]
            for c in range(3):
                wd[i, c] = a * base[i, c]
        else:
            full[n_full] = i
            n_full += 1
    return n_full


@kernel
def count_bounces(cnt, idx, passed, cls, diffuse, glossy, transmission):
    """The gather rays' bounce counts after a continuation step (integrator.
    _count_continuations), as Cycles' path_state_next counts them: ray k continued by a
    lobe other than the transparent pass (passed[k] False: a reflection or refraction,
    an IOR 1 or normal-incidence refraction that goes on unbent too) adds 1 to
    cnt[idx[k], 0] and to column 1 / 2 / 3 where its class cls[k] is diffuse / glossy /
    transmission (B_TOTAL order); a pass adds none. passed (K,) bool; cnt (n,4) int64,
    updated in place (each hit has one ray a step: idx (K,) holds no row twice), or
    (0,4): only tell whether some ray is a bounce (idx, cls not read). Returns the
    number of bounces counted (at most 1 without cnt). Integer counts."""
    counting = cnt.shape[0] > 0
    nb = 0
    for k in range(passed.shape[0]):
        if passed[k]:
            continue
        nb += 1
        if not counting:
            return nb
        h = idx[k]
        c = cls[k]
        cnt[h, 0] += 1
        if c == diffuse:
            cnt[h, 1] += 1
        if c == glossy:
            cnt[h, 2] += 1
        if c == transmission:
            cnt[h, 3] += 1
    return nb


@kernel
def touch_near(side, tri, p, boxes, glass, other, out):
    """coincident.CoincidentSurfaces.near's test in one pass: out[i] (N,) bool True where
    tri[i] >= 0 is one of a touching pair (side[tri[i]] glass or other, side (T,) int8)
    and the point p[i] (N,3) lies in its partners' padded box, boxes[0] (2,3) the
    others' (for a glass triangle), boxes[1] the glass's (for an other), lower then upper
    corner, in p's dtype: numpy compared a float32 p with the float64 box's scalars in
    float32 (value-based casting), so the caller converts the boxes to p's dtype."""
    for i in range(tri.shape[0]):
        t = tri[i]
        out[i] = False
        if t < 0:
            continue
        s = side[t]
        if s == glass:
            b = 0
        elif s == other:
            b = 1
        else:
            continue
        inside = True
        for c in range(3):
            x = p[i, c]
            if not (x >= boxes[b, 0, c] and x <= boxes[b, 1, c]):
                inside = False
                break
        out[i] = inside


@register_warm_up
def _warm_up():
    n = 2
    prim = np.array([0, -1], np.int64)
    o, d, tp = np.zeros((n, 3)), np.zeros((n, 3)), np.ones((n, 3))
    idx = np.arange(n, dtype=np.int64)
    u, v, t = np.zeros(n), np.zeros(n), np.ones(n)
    for cls in (np.zeros(0, np.int64), np.zeros(n, np.int64)):
        keep_hits(prim.copy(), o, d, tp, idx, u, v, t, cls)
    o32, d32, tf32 = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, np.float32)
    rays_f32(o, d, o32, d32, tf32)
    geom, prim32 = np.array([0, -1], np.int32), np.zeros(n, np.int32)
    u32 = np.zeros(n, np.float32)
    for cls in (np.zeros(0, np.int64), np.zeros(n, np.int64)):
        keep_embree_hits(geom, prim32, u32, u32, tf32, np.zeros(1, np.int64), o, d, tp, idx,
                         cls, np.empty(n, np.int64), np.empty(n), np.empty(n), np.empty(n))
    rows = np.empty(n, np.int64)
    lp, ln, loff, lt = np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n)
    k = diffuse_lookups(tp, o, d, u, t, rows, lp, ln, loff, lt)
    again = np.empty(n, np.int64)
    full = np.empty(n, np.int64)
    for mat in (np.zeros(n, np.int32), np.zeros(n, np.int64)):
        lean_diffuse(mat, tp, np.ones(1, np.bool_), np.ones(1), np.empty((n, 3)), full)
    passed = np.zeros(n, np.bool_)
    for counts in (np.zeros((0, 4), np.int64), np.zeros((n, 4), np.int64)):
        count_bounces(counts, idx, passed, idx, 2, 4, 8)
    # The classes read-only (integrator._count_continuations broadcasts one class: one
    # continued ray's view stays read-only through ascontiguousarray).
    frozen = np.zeros(n, np.int64)
    frozen.flags.writeable = False
    count_bounces(np.zeros((n, 4), np.int64), idx, passed, frozen, 2, 4, 8)
    for regather in (False, True):
        add_gathered(np.zeros((n, 3)), idx, rows[:k], tp, tp, np.ones((k, 3)), 2,
                     np.zeros(k, np.bool_), lt[:k], 0.5, regather, again)
    for dtype in (np.float32, np.float64):
        touch_near(np.array([0, 1], np.int8), idx, np.zeros((n, 3), dtype),
                   np.zeros((2, 2, 3), dtype), 1, 2, np.empty(n, np.bool_))
