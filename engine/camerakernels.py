"""Compiled kernels of the camera pass's shading (issue 13, third slice): what runs between
two Embree calls for every hit of a camera, gather or specular ray.

- `hit_geometry`: hit -> surface data in one pass over the hits (position, geometric and
  shading normals facing the ray, material, base colour, the ray-origin offset of
  engine/rayoffset.py), reading the triangle tables directly: no per-hit (N,3) copies of
  v0 / e1 / e2, and the per-triangle round32 / tilt32 bounds (Geometry.PerTriangle)
  computed in registers.
- `face_shading_normals`: the shading normal turned to the ray's side, and Veach's guard
  (a shading normal that puts the viewer below the surface falls back to ng).
- `gather_rays`: final-gather rays (cosine-distributed about the shading normal, kept
  above the geometric one), compacted with their offset origins.
- `choose_lobes`: the continuation's lobe choice (weights of the non-diffuse lobes,
  Russian roulette) from the closures' per-lobe albedo estimates.
- `pick_lobes` + `continue_lobes`: the specular continuation: the lobe each surviving
  path takes, its sampled direction and weight (principled.sample_lobe), the new
  throughput, ray class and MIS pdf, and the offset origins, compacted into the arrays
  handed to Embree. The uniform numbers are drawn in numpy between the two kernels, in
  the order the numpy stage drew them. On the hits the caller marks (a camera path's
  first glass hits, integrator._trace_paths) a picked glass lobe is split:
  `glass_both` continues its reflection and its refraction, each with its Fresnel weight.
  `mirror_survival`: no Russian roulette at the camera's first hits whose continuation
  is mirror-like only.
- `hit_closures` (sixth slice): bsdf.closures' set-up (view cosine, Cycles' glossy
  normal, glass rows, per-hit alpha and parameter rows, principled.setup) in one pass.
- `keep_path_hits` (sixth slice): the camera paths whose ray met a surface, compacted
  (integrator._trace_paths' state after each Embree call).
- `film_add` (sixth slice): the Accumulator's RGB scatter-add, throughput factor included.
- `shade_lobes` (eighth slice): one camera bounce's closures, lobe choice, glossy rows and
  the rows to shade in one call, writing only what the bounce reads (a diffuse-only
  material skips the closures' set-up and its packed row; no (N, N_LOBES, 3) albedos).
- `surface_lobes` (tenth slice): `hit_geometry`, `face_shading_normals` and `shade_lobes`
  in one call, block by block (a block's surface data is still in cache for its lobes),
  for scenes without per-hit material nodes.
- `glossy_unguarded_rows` (hotspots53): turnedglossy.camera_unguarded's test (the
  interpolated shading normal puts the viewer below it) in one pass, no (N,3) temporaries.
- `diffuse_pdf_weights` (hotspots53): glossysplit.DiffusePdf's lobe weights, their sum,
  the diffuse weight and the Lambert-only rows from the closures' albedos in one pass.
- `bsdf_pdf_rows` (hotspots53): principled.bsdf_pdf_many reading the hits' rows in place
  (glossysplit.DiffusePdf.pdf: no gathered copies of the packed lobes).
- `diffuse_reject_pairs` (percost54): glossysplit.DiffusePdf.reject_for's per-photon
  test (the photon's direction normalised, pdf_D, the camera's and the photon's min pdf
  against Filter Glossy) in one pass, no (K,3) temporaries; since percost55 it reads the
  query rows' hit rows and the photons' stored directions (float or octahedral codes) in
  place: one call for all of a block's pairs.

Every kernel computes the same floating-point operations in the same order as the numpy
stage it replaced, so images are bitwise unchanged (tests/test_camera_kernels.py and
tests/test_bounce_kernels.py keep the numpy stages as oracles). Formulas:
docs/performance.md, "Kernels, third slice: camera shading" and "Sixth slice"; the
offsets are engine/rayoffset.py's (pbrt-v4's error bounds).
"""
from __future__ import annotations

import math

import numpy as np

from .closures import ggx
from .closures import principled as pr
from .directlight import _npmax, _to_world
from .filterglossy import raise_alphas
from .jit import kernel, register_warm_up
from .photonlayout import oct_decode
from .rayoffset import G32_PLANE, G64, TINY32, U32, tilt32, winding_normal

# Indices into SPEC_LOBES (bsdf.py: LOBE_NAMES[1:], principled's L_* minus one).
_PASS, _GLASS_R, _GLASS_T = pr.L_PASS - 1, pr.L_GLASS_R - 1, pr.L_GLASS_T - 1
_TRANSL = pr.L_TRANSL - 1


@kernel
def _ulp32(x):
    # rayoffset.ulp32: 2^-23 |x|, at least float32's smallest normal.
    return max(2.0 * U32 * abs(x), TINY32)


@kernel
def hit_geometry(prim, u, v, d, v0, e1, e2, corner_normals, material, base_color,
                 p, ng, ns, front, mat, base, offset, bary):
    """Surface data of N hits, written into the caller's arrays.

    prim (N,) int64 triangle rows; u, v (N,) barycentrics of corners 1 and 2; d (N,3)
    ray directions; v0, e1, e2 (T,3) float64 triangle tables; corner_normals (T,3,3)
    float32 (or (0,3,3): every triangle flat); material (T,) int32; base_color (M,3).
    Out: p (N,3) = v0 + u e1 + v e2 (float64); ng (N,3) unit geometric normal facing the
    ray (against d); ns (N,3) unit shading normal on the winding side (not yet turned:
    normal maps perturb it there, then face_shading_normals turns it); front (N,) bool
    (the ray met the winding-order outside); mat (N,) material's dtype; base (N,3) the material's
    base colour; offset (N,) the ray-origin offset (rayoffset.surface_offset with the
    triangle's round32 / tilt32 bounds computed here, as geometry.PerTriangle does);
    bary (N,2) = (u, v)."""
    n = prim.shape[0]
    smooth_tables = corner_normals.shape[0] > 0
    # The unit normal, float32 tilt and corner terms of the offset of the last triangle: a
    # camera chunk's rays come pixel by pixel, so consecutive hits mostly share a triangle
    # (same values either way).
    last = -1
    gx = gy = gz = tilt = 0.0
    kx = ky = kz = hx = hy = hz = (0.0, 0.0, 0.0)
    for i in range(n):
        t = prim[i]
        b1, b2 = u[i], v[i]
        bary[i, 0], bary[i, 1] = b1, b2
        a0x, a0y, a0z = v0[t, 0], v0[t, 1], v0[t, 2]
        a1x, a1y, a1z = e1[t, 0], e1[t, 1], e1[t, 2]
        a2x, a2y, a2z = e2[t, 0], e2[t, 1], e2[t, 2]
        px = a0x + b1 * a1x + b2 * a2x
        py = a0y + b1 * a1y + b2 * a2y
        pz = a0z + b1 * a1z + b2 * a2z
        p[i, 0], p[i, 1], p[i, 2] = px, py, pz
        if t != last:
            last = t
            # Unit geometric normal (winding order): e1 x e2 / |e1 x e2| (np.cross, norm).
            cx, cy, cz = winding_normal(e1, e2, t)
            ln = max(math.sqrt(cx * cx + cy * cy + cz * cz), 1e-300)
            gx, gy, gz = cx / ln, cy / ln, cz / ln
            tilt = tilt32(a0x, a0y, a0z, a1x, a1y, a1z, a2x, a2y, a2z)
            kx, hx = _corner_terms(a0x, a1x, a2x)
            ky, hy = _corner_terms(a0y, a1y, a2y)
            kz, hz = _corner_terms(a0z, a1z, a2z)
        fr = d[i, 0] * gx + d[i, 1] * gy + d[i, 2] * gz < 0.0
        front[i] = fr
        sign = 1.0 if fr else -1.0
        ng[i, 0], ng[i, 1], ng[i, 2] = gx * sign, gy * sign, gz * sign
        # Interpolated corner normals, normalised; ng (winding side) where degenerate.
        if smooth_tables:
            w = 1.0 - b1 - b2
            sx = (w * np.float64(corner_normals[t, 0, 0]) + b1 * np.float64(corner_normals[t, 1, 0])
                  + b2 * np.float64(corner_normals[t, 2, 0]))
            sy = (w * np.float64(corner_normals[t, 0, 1]) + b1 * np.float64(corner_normals[t, 1, 1])
                  + b2 * np.float64(corner_normals[t, 2, 1]))
            sz = (w * np.float64(corner_normals[t, 0, 2]) + b1 * np.float64(corner_normals[t, 1, 2])
                  + b2 * np.float64(corner_normals[t, 2, 2]))
            sl = max(math.sqrt(sx * sx + sy * sy + sz * sz), 1e-300)
            sx, sy, sz = sx / sl, sy / sl, sz / sl
            s = abs(sx) + abs(sy) + abs(sz)
            if not math.isfinite(s) or s < 0.5:
                sx, sy, sz = gx, gy, gz
        else:
            sx, sy, sz = gx, gy, gz
        ns[i, 0], ns[i, 1], ns[i, 2] = sx, sy, sz
        m = material[t]
        mat[i] = m
        base[i, 0], base[i, 1], base[i, 2] = base_color[m, 0], base_color[m, 1], base_color[m, 2]
        # Ray-origin offset: the point's error (rayoffset._point_error) with the corners'
        # float32 rounding bound (geometry._round32_rows) and the plane's tilt
        # (rayoffset.triangle_tilt) computed from the corners here.
        b0 = 1.0 - b1 - b2
        w0, w1, w2 = abs(b0), abs(b1), abs(b2)
        offset[i] = _corner_offset(w0, w1, w2, kx, ky, kz, hx, hy, hz, ng[i, 0], ng[i, 1],
                                   ng[i, 2], px, py, pz, tilt)


@kernel
def _corner_terms(c0, c1, c2):
    """One component's per-triangle terms of the ray-origin offset: the corners k = (c0,
    c0 + c1, c0 + c2) (corner c0, edges c1, c2 = v1 - v0, v2 - v0) and their float32
    rounding bounds 0.5 ulp32(k) (geometry._round32_rows): computed once per triangle
    (hit_geometry's last triangle), read by _corner_offset at every hit on it."""
    k0, k1, k2 = c0, c0 + c1, c0 + c2
    return (k0, k1, k2), (0.5 * _ulp32(k0), 0.5 * _ulp32(k1), 0.5 * _ulp32(k2))


@kernel
def _corner_error(w0, w1, w2, k, h, pc):
    """One component of rayoffset._point_error: corners k and their rounding bounds h
    (_corner_terms), |barycentrics| w0..w2, point component pc."""
    interp = G64 * (w0 * abs(k[0]) + w1 * abs(k[1]) + w2 * abs(k[2]))
    tri32 = w0 * h[0] + w1 * h[1] + w2 * h[2]
    return interp + tri32 + max(2.0 * U32 * abs(pc), TINY32)


@kernel
def _corner_offset(w0, w1, w2, kx, ky, kz, hx, hy, hz, nx, ny, nz, px, py, pz, tilt):
    """rayoffset._offset_row of the point (px, py, pz) at |barycentrics| w0..w2 with unit
    normal n, from the triangle's corner terms (_corner_terms per component) instead of
    its table rows: the same operations in the same order, so the same bits. A triangle
    whose float32 plane cannot tilt (tilt 0: every axis-aligned one, the box's walls)
    skips the three corner distances: along + plane + 0 x far is along + plane (a sum of
    non-negative terms, never -0.0; far is finite for a finite point)."""
    ex = _corner_error(w0, w1, w2, kx, hx, px)
    ey = _corner_error(w0, w1, w2, ky, hy, py)
    ez = _corner_error(w0, w1, w2, kz, hz, pz)
    anx, any_, anz = abs(nx), abs(ny), abs(nz)
    along = anx * ex + any_ * ey + anz * ez
    r0 = max(max(abs(kx[0] - px), abs(kx[1] - px)), abs(kx[2] - px))
    r1 = max(max(abs(ky[0] - py), abs(ky[1] - py)), abs(ky[2] - py))
    r2 = max(max(abs(kz[0] - pz), abs(kz[1] - pz)), abs(kz[2] - pz))
    plane = G32_PLANE * (anx * r0 + any_ * r1 + anz * r2)
    if tilt == 0.0:
        return along + plane
    x, y, z = kx[0] - px, ky[0] - py, kz[0] - pz
    far = math.sqrt(x * x + y * y + z * z)
    x, y, z = kx[1] - px, ky[1] - py, kz[1] - pz
    far = max(far, math.sqrt(x * x + y * y + z * z))
    x, y, z = kx[2] - px, ky[2] - py, kz[2] - pz
    far = max(far, math.sqrt(x * x + y * y + z * z))
    return along + plane + tilt * far


@kernel
def face_shading_normals(ns, ng, front, d, exempt):
    """Turn the winding-side shading normals ns (N,3) to the ray's side (ng, front from
    hit_geometry) in place; where the result faces away from wo = -d (dot <= 1e-6), use
    ng instead (shading normals that put the viewer below the surface make black rings;
    Veach's guard, simplified), except on rows where exempt (N,) bool is set (the
    caller's choice, e.g. normals a Normal Map bent)."""
    for i in range(ns.shape[0]):
        sign = 1.0 if front[i] else -1.0
        sx, sy, sz = ns[i, 0] * sign, ns[i, 1] * sign, ns[i, 2] * sign
        if not exempt[i] and sx * -d[i, 0] + sy * -d[i, 1] + sz * -d[i, 2] <= 1e-6:
            sx, sy, sz = ng[i, 0], ng[i, 1], ng[i, 2]
        ns[i, 0], ns[i, 1], ns[i, 2] = sx, sy, sz


@kernel
def _view_cosine(ns, wo, i):
    # ns[i] . wo[i] summed as np.einsum("ij,ij->i") sums three terms (x + z) + y, which
    # the set-up this replaced used: the same bits.
    return (ns[i, 0] * wo[i, 0] + ns[i, 2] * wo[i, 2]) + ns[i, 1] * wo[i, 1]


@kernel
def hit_closures(ns, ng, wo, mat, params, per_hit, base, front, table_alpha, hit_alpha,
                 prm, albedo, blur):
    """The lobes of N hits (bsdf.closures), in one pass: the view cosine ns . wo, Cycles'
    glossy normal (principled.glossy_normals, for every glossy lobe, glass included:
    principled.raised_rough_glass), the closures' set-up (principled.setup) and the
    glossy normal packed into prm's P_GN columns.

    ns, ng, wo (N,3) float64; mat (N,) material index; params (M, N_MAT) the materials'
    closure rows, or (N, N_MAT) one row per hit when per_hit (texture-driven scalar
    inputs); base (N,3) base colour; front (N,) bool; table_alpha (M,) the materials'
    alpha; hit_alpha (N,) per-hit alpha (alpha textures) or (0,): the materials'.
    blur (N,) float64: Cycles' Filter Glossy alpha of each hit (engine/filterglossy.py:
    the microfacet alphas raised to it after the set-up, the albedos left), or (0,):
    none (0 also changes no bit).
    Out: prm (N, N_PACK), albedo (N, N_LOBES, 3). Same operations in the same order as
    the numpy set-up it replaced (tests/test_camera_kernels.py)."""
    n = ns.shape[0]
    cos_o = np.empty(n)
    for i in range(n):
        cos_o[i] = _view_cosine(ns, wo, i)
    cos_s = cos_o.copy()  # the sheen's: on ns, never raised (principled.setup_views)
    local = np.zeros((n, 3))
    pr.glossy_normals(ns, ng, wo, local, cos_o)
    rows = np.empty(n, np.int64)
    alpha = np.empty(n)
    per_hit_alpha = hit_alpha.shape[0] > 0
    for i in range(n):
        r = i if per_hit else mat[i]
        rows[i] = r
        alpha[i] = hit_alpha[i] if per_hit_alpha else table_alpha[mat[i]]
    pr.setup_views(rows, params, base, cos_o, cos_s, front, alpha, prm, albedo)
    if blur.shape[0] > 0:
        for i in range(n):
            raise_alphas(prm, i, blur[i])
    for i in range(n):
        for c in range(3):
            prm[i, pr.P_GN + c] = local[i, c]


@kernel
def _diffuse_only(params, r):
    """Material row r has the diffuse and pass lobes alone: principled.setup would
    skip its sheen, coat, metal, glass and specular layers (each needs a weight > 0) and
    leave every packed column 0 (photonkernels.plain_materials, per row)."""
    return not (params[r, pr.M_SHEEN_W] > 0.0 or params[r, pr.M_COAT_W] > 0.0
                or params[r, pr.M_METALLIC] > 0.0 or params[r, pr.M_TRANS] > 0.0
                or params[r, pr.M_SPEC] > 0.0 or params[r, pr.M_ADD] != 0.0
                or params[r, pr.M_TL] > 0.0)


@kernel
def _diffuse_only_rows(params):
    """(M,) bool: _diffuse_only of every material row (read once per call, not per hit)."""
    out = np.empty(params.shape[0], np.bool_)
    for r in range(params.shape[0]):
        out[r] = _diffuse_only(params, r)
    return out


@kernel
def _max3(a, b, c):
    """sampling.max3 of one row (np.maximum: NaN wins)."""
    return _npmax(_npmax(a, b), c)


@kernel
def shade_lobes(ns, ng, wo, mat, params, per_hit, base, front, table_alpha, hit_alpha, tp,
                want_glossy, prm, sel, q, p, psum, glossy, rows, wd, blur, mean_weights):
    """One camera bounce's lobes over N hits in one call (hit_closures, choose_lobes, the
    glossy rows of integrator.light_modes and the rows the diffuse stage shades), writing
    to memory only what the bounce reads.

    Inputs as hit_closures takes them (blur included: Filter Glossy's alphas, applied
    after the set-up, so the lobe choice keeps the unblurred albedos and a blurred mirror
    or smooth glass is a glossy row), plus tp (N,3) path throughputs and want_glossy
    (bool: some light takes glossy shadow rays; else no row is glossy).
    Hits whose material has the diffuse and pass lobes alone (_diffuse_only, read once a
    material) skip the closures' set-up: their lobe choice is computed from the two
    albedos principled.setup would give them, bit for bit; the others are set up
    together (principled.setup on a compacted batch).
    Out: prm (N, N_PACK) as hit_closures on the hits the set-up saw; q, psum (N,) as
    choose_lobes; p (N, N_LOBES - 1), sel (N, N_LOBES) as choose_lobes where psum > 0
    (the rows a continuation may pick); the diffuse-only rows' prm, the other rows' sel,
    and p where psum <= 0 are left unwritten (undefined: a continuation picks only rows
    with psum > 0, and through a diffuse-only material only its pass lobe, which reads
    no packed row);
    glossy (N,) bool (principled.has_rough_reflection); rows (K,) the hits with a diffuse
    albedo (max3 > 0) or a glossy lobe, in order, and wd (K,3) their diffuse albedo.
    When some row is glossy the direct stage reads every shaded row's prm and sel, so
    then every row is written: prm equals hit_closures' (zeros and the glossy normal on
    diffuse-only rows) and sel choose_lobes' everywhere. Returns K. Same floating-point operations as the
    kernels it fuses (tests/test_fused_camera.py).
    mean_weights (bool): the non-diffuse lobes' weights p are their albedos' mean channel,
    Cycles' closure sample weights (bsdf_alloc's average(weight) x average(the microfacet
    albedo estimate)), instead of choose_lobes' max channel; the camera's first hits take
    them (studio56: a red metal under a clear coat, the coat's white reflections most of
    the luminance, picked the coat 0.09 of the time by the max channel, ~0.2 by the mean,
    as Cycles). Diffuse-only rows keep the max channel (their pass lobe is their only
    choice)."""
    n = ns.shape[0]
    k_lobes = pr.N_LOBES - 1
    per_hit_alpha = hit_alpha.shape[0] > 0
    plain = np.empty(0, np.bool_) if per_hit else _diffuse_only_rows(params)
    # 1. The hits whose material has more than the diffuse and pass lobes, compacted,
    # with hit_closures' view cosine and glossy normal; principled.setup on them at once.
    nc = 0
    for i in range(n):
        if not (_diffuse_only(params, i) if per_hit else plain[mat[i]]):
            nc += 1
    at = np.empty(nc, np.int64)
    rows_c = np.empty(nc, np.int64)
    base_c, local_c = np.empty((nc, 3)), np.zeros((nc, 3))
    cos_c, cos_sc, alpha_c = np.empty(nc), np.empty(nc), np.empty(nc)
    front_c = np.empty(nc, np.bool_)
    j = 0
    for i in range(n if nc > 0 else 0):
        r = i if per_hit else mat[i]
        if _diffuse_only(params, i) if per_hit else plain[r]:
            continue
        at[j] = i
        rows_c[j] = r
        cos = _view_cosine(ns, wo, i)
        cos_sc[j] = cos  # the sheen's: on ns, never raised (principled.setup_views)
        raised, g0, g1, g2, c = pr.glossy_normal_row(ns, ng, wo, i)
        if raised:
            local_c[j, 0], local_c[j, 1], local_c[j, 2], cos = g0, g1, g2, c
        cos_c[j] = cos
        alpha_c[j] = hit_alpha[i] if per_hit_alpha else table_alpha[mat[i]]
        front_c[j] = front[i]
        base_c[j, 0], base_c[j, 1], base_c[j, 2] = base[i, 0], base[i, 1], base[i, 2]
        j += 1
    prm_c = np.empty((nc, pr.N_PACK))
    w_c = np.empty((nc, pr.N_LOBES, 3))
    pr.setup_views(rows_c, params, base_c, cos_c, cos_sc, front_c, alpha_c, prm_c, w_c)
    if blur.shape[0] > 0:
        for j in range(nc):
            raise_alphas(prm_c, j, blur[at[j]])
    # 2. Every hit in order: its packed row, lobe choice, glossy flag and diffuse row.
    m = np.empty(k_lobes)
    any_glossy = False
    j = 0
    k = 0
    for i in range(n):
        gl = False
        if j < nc and at[j] == i:
            for c in range(pr.P_GN):
                prm[i, c] = prm_c[j, c]
            for c in range(3):
                prm[i, pr.P_GN + c] = local_c[j, c]
            for c in range(pr.P_GN + 3, pr.N_PACK):  # (the anisotropic columns)
                prm[i, c] = prm_c[j, c]
            if want_glossy:
                gl = pr.has_rough_reflection(prm, i)
            wi = w_c[j]
            j += 1
            s, qi = _choose_row(wi, tp[i, 0], tp[i, 1], tp[i, 2], m, mean_weights)
            psum[i] = s
            q[i] = qi
            if s > 0:
                sel[i, 0] = 0.0
                for jj in range(k_lobes):
                    p[i, jj] = m[jj]
                    sel[i, jj + 1] = m[jj] / s * qi
            d0, d1, d2 = wi[0, 0], wi[0, 1], wi[0, 2]
        else:
            # A diffuse-only material: principled.setup's albedos are the pass lobe
            # (1 - a) x the transparent tint, the diffuse a x base and 0 for every other
            # lobe (W stays a). _choose_row on them, bit for bit, without the (N_LOBES, 3)
            # row: each zero lobe adds 0.0 to the sums (which turns -0.0 into 0.0 and
            # keeps every other value, NaN included) and weighs max3(0, 0, 0) = 0.
            r = i if per_hit else mat[i]
            a = hit_alpha[i] if per_hit_alpha else table_alpha[mat[i]]
            t0 = (1.0 - a) * params[r, pr.M_TTINT]
            t1 = (1.0 - a) * params[r, pr.M_TTINT + 1]
            t2 = (1.0 - a) * params[r, pr.M_TTINT + 2]
            m0 = max(max(t0, t1), t2)
            s = m0 + 0.0
            qi = 10.0 * max(max(tp[i, 0] * (t0 + 0.0), tp[i, 1] * (t1 + 0.0)),
                            tp[i, 2] * (t2 + 0.0))
            qi = min(max(qi, 0.0), 1.0)
            psum[i] = s
            q[i] = qi
            if s > 0:
                sel[i, 0] = 0.0
                p[i, 0] = m0
                sel[i, 1] = m0 / s * qi
                for jj in range(1, k_lobes):
                    p[i, jj] = 0.0
                    sel[i, jj + 1] = 0.0 / s * qi
            d0, d1, d2 = a * base[i, 0], a * base[i, 1], a * base[i, 2]
        glossy[i] = gl
        any_glossy = any_glossy or gl
        if _max3(d0, d1, d2) > 0 or gl:
            rows[k] = i
            wd[k, 0], wd[k, 1], wd[k, 2] = d0, d1, d2
            k += 1
    if any_glossy:
        _fill_unread_rows(ns, ng, wo, mat, params, per_hit, psum, sel, prm)
    return k


@kernel
def _fill_unread_rows(ns, ng, wo, mat, params, per_hit, psum, sel, prm):
    """shade_lobes' rows left unwritten, written as the direct stage reads them when some
    row of the batch is glossy (it then reads every shaded row's prm and sel): the
    diffuse-only rows' glossy normals (the rest of their packed row is 0) and the zero
    choice of rows with psum <= 0."""
    for i in range(ns.shape[0]):
        if not psum[i] > 0:
            for jj in range(pr.N_LOBES):
                sel[i, jj] = 0.0
        if not _diffuse_only(params, i if per_hit else mat[i]):
            continue  # (set up: its packed row is written)
        for c in range(pr.P_GN):
            prm[i, c] = 0.0
        for c in range(pr.P_GN + 3, pr.N_PACK):
            prm[i, c] = 0.0
        raised, g0, g1, g2, c = pr.glossy_normal_row(ns, ng, wo, i)
        prm[i, pr.P_GN] = g0
        prm[i, pr.P_GN + 1] = g1
        prm[i, pr.P_GN + 2] = g2


# Hits per block of surface_lobes: the block's surface data (~200 bytes a hit) stays in
# the core's cache between the stages it runs on it.
SURFACE_BLOCK = 512


@kernel
def surface_lobes(prim, u, v, d, v0, e1, e2, corner_normals, material, base_color, params,
                  table_alpha, tp, want_glossy, p, ng, ns, wo, front, mat, base, offset, bary,
                  prm, sel, q, pw, psum, glossy, rows, wd, blur, mean_weights):
    """hit_geometry, the shading normals turned to the ray's side (face_shading_normals,
    no row exempt), wo = -d and shade_lobes over N hits in one call, block by block
    (SURFACE_BLOCK hits: each block's surface data is still in cache when its lobes are
    set up), for a scene whose materials have no per-hit nodes (no normal map, texture,
    alpha texture or texture-driven scalar input: bsdf.plain_surfaces).

    Inputs as hit_geometry and shade_lobes take them (params (M, N_MAT) the materials'
    rows, table_alpha (M,)); out: hit_geometry's p, ng, ns, front, mat, base, offset, bary,
    wo (N,3), and shade_lobes' prm, sel, q, pw (its p), psum, glossy, rows, wd with the
    same rows written (when some row of the batch is glossy, every block's unread rows
    are filled in as shade_lobes fills them); blur (N,) or (0,) and mean_weights as
    shade_lobes'. Returns K, the number of shaded rows.
    The same kernels on slices: the same bits (tests/test_fused_camera.py)."""
    n = prim.shape[0]
    none_exempt = np.zeros(SURFACE_BLOCK, np.bool_)
    no_alpha = np.zeros(0)
    nb = (n + SURFACE_BLOCK - 1) // SURFACE_BLOCK
    block_glossy = np.zeros(nb, np.bool_)
    k = 0
    for bi in range(nb):
        a = bi * SURFACE_BLOCK
        b = min(a + SURFACE_BLOCK, n)
        hit_geometry(prim[a:b], u[a:b], v[a:b], d[a:b], v0, e1, e2, corner_normals, material,
                     base_color, p[a:b], ng[a:b], ns[a:b], front[a:b], mat[a:b], base[a:b],
                     offset[a:b], bary[a:b])
        for i in range(a, b):
            wo[i, 0], wo[i, 1], wo[i, 2] = -d[i, 0], -d[i, 1], -d[i, 2]
        face_shading_normals(ns[a:b], ng[a:b], front[a:b], d[a:b], none_exempt[:b - a])
        kb = shade_lobes(ns[a:b], ng[a:b], wo[a:b], mat[a:b], params, False, base[a:b],
                         front[a:b], table_alpha, no_alpha, tp[a:b], want_glossy, prm[a:b],
                         sel[a:b], q[a:b], pw[a:b], psum[a:b], glossy[a:b], rows[k:], wd[k:],
                         blur[a:b] if blur.shape[0] > 0 else blur, mean_weights)
        for j in range(k, k + kb):
            rows[j] += a
        k += kb
        for i in range(a, b):
            if glossy[i]:
                block_glossy[bi] = True
                break
    if block_glossy.any():
        # shade_lobes filled the glossy blocks' unread rows; the other blocks' too.
        for bi in range(nb):
            if not block_glossy[bi]:
                a = bi * SURFACE_BLOCK
                b = min(a + SURFACE_BLOCK, n)
                _fill_unread_rows(ns[a:b], ng[a:b], wo[a:b], mat[a:b], params, False,
                                  psum[a:b], sel[a:b], prm[a:b])
    return k


@kernel
def keep_path_hits(prim, o, d, tp, pix, u, v, t, sample_id, travelled, cls, pdf_b):
    """The camera paths whose ray met a surface (prim >= 0), compacted in order into new
    arrays (integrator._trace_paths' state after an Embree call): returns (rows (K,) the
    kept rows, o, d, tp (K,3), pix, prim (K,) int64, u, v, t (K,), sample_id (K,) int64,
    travelled (K,) = travelled + t, cls (K,) int64, pdf_b (K,)). Inputs: prim, pix,
    sample_id, cls (N,) int64; o, d, tp (N,3), u, v, t, travelled, pdf_b (N,) float64."""
    n = prim.shape[0]
    k = 0
    for i in range(n):
        if prim[i] >= 0:
            k += 1
    rows = np.empty(k, np.int64)
    o2, d2, tp2 = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    pix2, prim2 = np.empty(k, np.int64), np.empty(k, np.int64)
    u2, v2, t2 = np.empty(k), np.empty(k), np.empty(k)
    sid2, cls2 = np.empty(k, np.int64), np.empty(k, np.int64)
    trav2, pdf2 = np.empty(k), np.empty(k)
    j = 0
    for i in range(n):
        if prim[i] < 0:
            continue
        rows[j] = i
        for c in range(3):
            o2[j, c] = o[i, c]
            d2[j, c] = d[i, c]
            tp2[j, c] = tp[i, c]
        pix2[j] = pix[i]
        prim2[j] = prim[i]
        u2[j] = u[i]
        v2[j] = v[i]
        t2[j] = t[i]
        sid2[j] = sample_id[i]
        trav2[j] = travelled[i] + t[i]
        cls2[j] = cls[i]
        pdf2[j] = pdf_b[i]
        j += 1
    return rows, o2, d2, tp2, pix2, prim2, u2, v2, t2, sid2, trav2, cls2, pdf2


@kernel
def film_add(buf, lo, pix, rows, tp, rgb):
    """Add tp[rows[k]] * rgb[k] (RGB) into buf[pix[rows[k]] - lo]: buf (P,3) float64;
    pix (N,) int64 pixel of each row; rows (K,) int64, or (0,) for rows k = k; tp (N,3)
    float64 path throughput, or (0,3) for none; rgb (K,3) float64. As the Accumulator's
    np.bincount of tp[rows] * rgb did: each pixel's sum formed from zero in row order,
    then added to buf (the same floating-point operations, so the same bits)."""
    k_rows = rgb.shape[0]
    every = rows.shape[0] == 0
    weighted = tp.shape[0] > 0
    sums = np.zeros(buf.shape)
    for k in range(k_rows):
        i = k if every else rows[k]
        b = pix[i] - lo
        for c in range(3):
            sums[b, c] += tp[i, c] * rgb[k, c] if weighted else rgb[k, c]
    for b in range(buf.shape[0]):
        for c in range(3):
            buf[b, c] += sums[b, c]


@kernel
def film_add_scalar(buf, lo, pix, w):
    """Add w[i] into buf[pix[i] - lo]: buf (P,) float64, pix (N,) int64, w (N,) float64.
    As np.bincount(pix - lo, weights=w) added to buf: each pixel's sum formed from zero in
    row order, then added (the same bits), without holding the GIL."""
    sums = np.zeros(buf.shape[0])
    for i in range(pix.shape[0]):
        sums[pix[i] - lo] += w[i]
    for b in range(buf.shape[0]):
        buf[b] += sums[b]


@kernel
def film_first_normals(lo, pix, ns, front, normal):
    """The first hits' normal pass: ns[i] turned to the front side (times 1 or -1 as
    `front` says) into normal (P,3) at pixel pix[i] - lo; sums formed per pixel from zero
    in row order, then added, as the np.bincount calls they replace (same bits)."""
    n_pix = normal.shape[0]
    sums = np.zeros((n_pix, 3))
    for i in range(pix.shape[0]):
        b = pix[i] - lo
        f = 1.0 if front[i] else -1.0
        sums[b, 0] += ns[i, 0] * f
        sums[b, 1] += ns[i, 1] * f
        sums[b, 2] += ns[i, 2] * f
    for b in range(n_pix):
        normal[b, 0] += sums[b, 0]
        normal[b, 1] += sums[b, 1]
        normal[b, 2] += sums[b, 2]


@kernel
def view_depth(p, cam_pos, forward, depth):
    """depth (N,) = (p - cam_pos) . forward for hit points p (N,3), camera position and
    unit forward axis (3,): the depth pass, summed as sampling.dot's np.einsum sums three
    terms, (x + z) + y (the same bits), without the (N,3) difference array."""
    c0, c1, c2 = cam_pos[0], cam_pos[1], cam_pos[2]
    f0, f1, f2 = forward[0], forward[1], forward[2]
    for i in range(p.shape[0]):
        depth[i] = ((p[i, 0] - c0) * f0 + (p[i, 2] - c2) * f2) + (p[i, 1] - c1) * f1


@kernel
def mirror_survival(prm, p, psum, q, sel):
    """No Russian roulette on hits whose continuation is mirror-like only: rows (N,) with
    psum > 0 whose non-diffuse lobes of weight p > 0 are all mirror-like (no pass lobe, no
    lobe with a density: principled.is_rough) get q = 1 and sel (N, N_LOBES) = p / psum
    (choose_lobes' sel with q = 1). A smooth dielectric's mirror lobe (albedo ~4 %) took
    q = 0.4 and weight 2.5 on the ~40 % of samples that continued; light sampling cannot
    carry a mirror lobe, so its highlights were that much noisier. Returns the rows
    changed. Reads prm only on rows with such a lobe (shade_lobes leaves a diffuse-only
    row's prm unwritten; its only possible lobe is the pass lobe)."""
    k_lobes = p.shape[1]
    changed = 0
    for i in range(p.shape[0]):
        s = psum[i]
        if not s > 0.0 or q[i] >= 1.0:
            continue
        if p[i, _PASS] > 0.0:
            continue
        mirror = True
        for j in range(k_lobes):
            if p[i, j] > 0.0 and pr.is_rough(prm, i, j + 1):
                mirror = False
                break
        if not mirror:
            continue
        q[i] = 1.0
        sel[i, 0] = 0.0
        for j in range(k_lobes):
            sel[i, j + 1] = p[i, j] / s
        changed += 1
    return changed


@kernel
def choose_lobes(albedo, tp, sel, q, p, psum):
    """The continuation's lobe choice from the closures' lobe albedos albedo
    (N, N_LOBES, 3) (column 0 = diffuse, the rest SPEC_LOBES' order) and the path
    throughput tp (N,3). Out: p (N, N_LOBES - 1) each non-diffuse lobe's weight (its max
    channel), psum (N,), q (N,) the survival probability (Russian roulette only for paths
    that would contribute less than 10 %: q = clip(10 max3(tp sum_lobes w), 0, 1)), sel
    (N, N_LOBES) the probability of continuing through each lobe (diffuse: 0)."""
    k = albedo.shape[1] - 1
    m = np.empty(k)
    for i in range(albedo.shape[0]):
        s, qi = _choose_row(albedo[i], tp[i, 0], tp[i, 1], tp[i, 2], m, False)
        psum[i] = s
        q[i] = qi
        sel[i, 0] = 0.0
        for j in range(k):
            p[i, j] = m[j]
            sel[i, j + 1] = m[j] / s * qi if s > 0 else 0.0


@kernel
def _choose_row(w, t0, t1, t2, m, mean):
    """choose_lobes for one hit: w (N_LOBES, 3) its lobe albedos, (t0, t1, t2) its
    throughput. Writes m (N_LOBES - 1,) the non-diffuse lobes' weights (max channel, or
    with mean the mean channel: Cycles' sample weights, shade_lobes' mean_weights);
    returns (their sum psum, the survival probability q)."""
    k = w.shape[0] - 1
    s = 0.0
    wx = w[1, 0]
    wy = w[1, 1]
    wz = w[1, 2]
    for j in range(k):
        a0, a1, a2 = w[j + 1, 0], w[j + 1, 1], w[j + 1, 2]
        mj = (a0 + a1 + a2) / 3.0 if mean else max(max(a0, a1), a2)
        m[j] = mj
        s = s + mj if j > 0 else mj
        if j > 0:
            wx += a0
            wy += a1
            wz += a2
    qi = 10.0 * max(max(t0 * wx, t1 * wy), t2 * wz)
    qi = min(max(qi, 0.0), 1.0)
    return s, qi


@kernel
def pick_lobes(p, psum, q, idx, r, lobe, prob):
    """Lobe (index into SPEC_LOBES) of each surviving row idx[k], by inverting the
    cumulative distribution of p[row] / psum[row] with the uniform r[k] (glass_r and
    glass_t are one lobe here: sample_lobe decides between them), and its probability
    under the whole choice, q included. Returns how many picks are not the pass lobe
    (they take three uniform numbers each)."""
    k_lobes = p.shape[1]
    sampled = 0
    for k in range(idx.shape[0]):
        row = idx[k]
        c = 0.0
        count = 0
        for j in range(k_lobes):
            x = p[row, j] / psum[row]
            c = c + x if j > 0 else x
            if r[k] >= c:
                count += 1
        lb = min(count, k_lobes - 1)
        lobe[k] = lb
        if lb == _GLASS_R or lb == _GLASS_T:
            p_sel = p[row, _GLASS_R] + p[row, _GLASS_T]
        else:
            p_sel = p[row, lb]
        prob[k] = p_sel / psum[row] * q[row]
        if lb != _PASS:
            sampled += 1
    return sampled


@kernel
def glass_both(prm, i, ox, oy, oz, u1, u2):
    """Both halves of hit i's glass lobe for local wo, each weighted by its Fresnel term
    instead of chosen with it (a split; principled._glass_sample chooses one with the
    probability p_r of its reflectance share and divides by it): one microfacet normal
    (visible-normal sampled from u1, u2 on rough glass, about the raised normal where
    there is one (principled.raised_rough_glass); the raised or shading normal on smooth),
    then its mirror direction and its refraction. Returns (rx, ry, rz, reflection weight
    RGB, tx, ty, tz, transmission weight RGB) in the shading normal's frame; weights are
    f cos / pdf of the normal's sampling alone (r x G1 ratio, t x G1 ratio; smooth: the
    Fresnel-weighted colours), 0 where that half has no sample (below the lobe's normal,
    total internal reflection, a Refraction BSDF's reflection). Its expectation equals
    _glass_sample's, term by term."""
    (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2, p_r) = glass_both_share(
        prm, i, ox, oy, oz, u1, u2)
    return (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2)


@kernel
def glass_both_share(prm, i, ox, oy, oz, u1, u2):
    """glass_both and, last, p_r: the probability with which _glass_sample (Cycles'
    bsdf_microfacet_sample: average reflectance over average reflectance + transmittance
    at the microfacet normal, 0 transmittance under total internal reflection) would
    have chosen the reflection at that normal (1 - p_r: the refraction); 0 where wo sees
    the normal's back. A split branch's Cycles clamp is the limit x its p
    (engine/sampleclamp.py)."""
    if pr.raised_rough_glass(prm, i):
        qx, qy, qz = pr._to_glossy(prm, i, ox, oy, oz)
        (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2, p_r) = _glass_both_local_share(
            prm, i, qx, qy, qz, u1, u2)
        rx, ry, rz = pr._from_glossy(prm, i, rx, ry, rz)
        tx, ty, tz = pr._from_glossy(prm, i, tx, ty, tz)
        return (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2, p_r)
    return _glass_both_local_share(prm, i, ox, oy, oz, u1, u2)


@kernel
def _glass_both_local(prm, i, ox, oy, oz, u1, u2):
    """glass_both with wo in the lobe's frame (rough: z its normal)."""
    (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2, p_r) = _glass_both_local_share(
        prm, i, ox, oy, oz, u1, u2)
    return (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2)


@kernel
def _glass_both_local_share(prm, i, ox, oy, oz, u1, u2):
    """glass_both_share with wo in the lobe's frame (rough: z its normal)."""
    (rough, alpha, eta, hx, hy, hz, c, r0, r1, r2, t0, t1, t2) = pr.glass_microfacet(
        prm, i, ox, oy, oz, u1, u2)
    if c <= 0.0:
        return (0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0)
    # _glass_sample's choice probability, before the G1 ratios below (the same sums).
    sr = r0 + r1 + r2
    st = t0 + t1 + t2
    a2 = alpha * alpha
    lo = ggx.lambda_ggx(oz, a2) if rough else 0.0
    rx, ry, rz = 2.0 * c * hx - ox, 2.0 * c * hy - oy, 2.0 * c * hz - oz
    # The side checks against the lobe's normal: z on rough glass, the (raised)
    # normal h itself on smooth glass (Cycles' cos_NO; the geometric side: _ray_weight).
    if (rz if rough else rx * hx + ry * hy + rz * hz) <= 0.0:
        r0 = r1 = r2 = 0.0
    elif rough:
        g = (1.0 + lo) / (1.0 + lo + ggx.lambda_ggx(rz, a2))
        r0, r1, r2 = r0 * g, r1 * g, r2 * g
    inv_eta = 1.0 / eta
    s2 = inv_eta * inv_eta * (1.0 - c * c)
    if s2 >= 1.0:  # total internal reflection at this microfacet
        return (rx, ry, rz, r0, r1, r2, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0)
    p_r = sr / (sr + st) if sr + st > 0.0 else 0.0
    ct = math.sqrt(1.0 - s2)
    kk = inv_eta * c - ct
    tx, ty, tz = -inv_eta * ox + kk * hx, -inv_eta * oy + kk * hy, -inv_eta * oz + kk * hz
    if (tz if rough else tx * hx + ty * hy + tz * hz) >= 0.0:
        t0 = t1 = t2 = 0.0
    elif rough and abs(eta - 1.0) >= 1e-4:
        g = (1.0 + lo) / (1.0 + lo + ggx.lambda_ggx(-tz, a2))
        t0, t1, t2 = t0 * g, t1 * g, t2 * g
    return (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2, p_r)


@kernel
def _unit_world(n0, n1, n2, ix, iy, iz):
    # sample_lobe's local direction in world space, normalised.
    x, y, z = pr.frame_world(n0, n1, n2, ix, iy, iz)
    ln = math.sqrt(x * x + y * y + z * z)
    if ln > 0:
        x, y, z = x / ln, y / ln, z / ln
    return x, y, z


@kernel
def _ray_weight(x, y, z, w0, w1, w2, tr, prob, gx, gy, gz, tp0, tp1, tp2):
    """continue_lobes' checks of one sampled direction (x, y, z) (unit, world) with weight
    (w0, w1, w2) and choice probability prob at a hit with geometric normal (gx, gy, gz)
    and throughput (tp0, tp1, tp2): (kept, side = direction . ng, the continued
    throughput RGB). Not kept (absorbed): the wrong side of the surface, not finite, no
    weight. Scalars only: a kernel called per ray with arrays pays ~14 ns an array
    (reference counts) when numba does not inline it, which was most of continue_lobes'
    time (~20 arrays a ray)."""
    side = x * gx + y * gy + z * gz
    if not ((side < 0.0) if tr else (side > 0.0)):
        return False, side, 0.0, 0.0, 0.0
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return False, side, 0.0, 0.0, 0.0
    if math.isnan(w0) or math.isnan(w1) or math.isnan(w2) or not (
            w0 > 0.0 or w1 > 0.0 or w2 > 0.0):
        return False, side, 0.0, 0.0, 0.0
    s = max(prob, 1e-300)
    t0 = tp0 * w0 / s
    t1 = tp1 * w1 / s
    t2 = tp2 * w2 / s
    if not math.isfinite(t0 + t1 + t2) or not (t0 > 0.0 or t1 > 0.0 or t2 > 0.0):
        return False, side, 0.0, 0.0, 0.0
    return True, side, t0, t1, t2


@kernel
def continue_lobes(idx, lobe, prob, u1, u2, u3, prm, sel, mat, closure_params, table_alpha,
                   hit_alpha, p, ng, ns, wo, offset, tp, incoming, lobe_class, want_pdf,
                   split, split_rough, rows_out, o_out, d_out, tp_out, cls_out, pdf_out,
                   split_out, split_p_out):
    """Sample the picked lobes (pick_lobes) of rows idx (M,) of N hits and write the
    continued rays, compacted: returns K, and rows_out[:K] (the kept k into idx), o_out,
    d_out (K,3) float64 (origins off the surface by the hit's offset along ng, to the
    side the ray leaves: pbrt-v4's OffsetRayOrigin), tp_out (K,3) = tp weight / prob
    (weight = f cos / pdf of the lobe), cls_out (K,) the ray class (lobe_class[lobe],
    or the incoming class where that is 0, a pass), pdf_out (K,) the solid-angle pdf
    of the direction under the whole choice (inf: mirror-like, refracted or passed;
    only with want_pdf). u1, u2, u3: one number each per non-pass pick, in pick order.
    prm, sel (N, N_LOBES), p, ng, ns, wo (N,3), offset (N,), tp (N,3), incoming (N,)
    are the hits' (bsdf.SurfaceHit, lobe_choice); the pass lobe's weight is
    (1 - alpha) x the Transparent BSDF's colour, from mat (N,), closure_params
    (M, N_MAT) (its M_TTINT columns), and alpha: hit_alpha (N,) float64 per hit (alpha
    textures), or (0,): table_alpha (M,) of the material. A sample is dropped
    (absorbed) when it leaves through the wrong side of the surface, is not finite or
    has no weight (_ray_weight).
    split (N,) bool, or (0,) for none: on these hits a picked glass lobe is split
    (glass_both: its reflection and its refraction both continue, each with its Fresnel
    weight; smooth glass only unless split_rough), so one pick may write two rows (the
    output arrays then hold 2 M rows; the reflection first); split_out (K,) marks the
    rows a split wrote (u3 is drawn for them and not read), split_p_out (K,) float64 on
    those rows the probability with which Cycles would have chosen that half
    (glass_both_share's p_r or 1 - p_r; 1.0 on the other rows), for the clamp."""
    kept = 0
    j = 0
    any_split = split.shape[0] > 0
    for k in range(idx.shape[0]):
        row = idx[k]
        lb = lobe[k]
        # One or two directions (a split glass lobe: the reflection, then the refraction).
        halves = 1
        is_split = False
        rx = ry = rz = r0 = r1 = r2 = 0.0
        p_r = 1.0
        if lb == _PASS:
            x, y, z = -wo[row, 0], -wo[row, 1], -wo[row, 2]
            mt = mat[row]
            a = hit_alpha[row] if hit_alpha.shape[0] > 0 else table_alpha[mt]
            w0 = (1.0 - a) * closure_params[mt, pr.M_TTINT]
            w1 = (1.0 - a) * closure_params[mt, pr.M_TTINT + 1]
            w2 = (1.0 - a) * closure_params[mt, pr.M_TTINT + 2]
            tr = True
        else:
            n0, n1, n2 = ns[row, 0], ns[row, 1], ns[row, 2]
            ox, oy, oz = pr.frame_local(n0, n1, n2, wo[row, 0], wo[row, 1], wo[row, 2])
            if (any_split and split[row] and (lb == _GLASS_R or lb == _GLASS_T)
                    and (split_rough or not pr.is_rough(prm, row, lb + 1))):
                (rx, ry, rz, r0, r1, r2, tx, ty, tz, t0, t1, t2, p_r) = glass_both_share(
                    prm, row, ox, oy, oz, u1[j], u2[j])
                j += 1
                halves = 2
                is_split = True
                rx, ry, rz = _unit_world(n0, n1, n2, rx, ry, rz)
                x, y, z = _unit_world(n0, n1, n2, tx, ty, tz)
                w0, w1, w2, tr = t0, t1, t2, True
            else:
                ix, iy, iz, w0, w1, w2, tr = pr.sample_lobe(prm, row, lb + 1, ox, oy, oz,
                                                            u1[j], u2[j], u3[j])
                j += 1
                x, y, z = _unit_world(n0, n1, n2, ix, iy, iz)
        for half in range(halves):
            if halves == 2 and half == 0:  # the split's reflection first
                hx, hy, hz, h0, h1, h2, htr, lh = rx, ry, rz, r0, r1, r2, False, _GLASS_R
            else:
                hx, hy, hz, h0, h1, h2, htr, lh = x, y, z, w0, w1, w2, tr, lb
            gx, gy, gz = ng[row, 0], ng[row, 1], ng[row, 2]
            ok, side, c0, c1, c2 = _ray_weight(hx, hy, hz, h0, h1, h2, htr, prob[k], gx, gy,
                                               gz, tp[row, 0], tp[row, 1], tp[row, 2])
            if not ok:
                continue
            if lh == _GLASS_R or lh == _GLASS_T:
                lh = _GLASS_T if htr else _GLASS_R
            lift = (1.0 if side >= 0.0 else -1.0) * offset[row]
            o_out[kept, 0] = p[row, 0] + lift * gx
            o_out[kept, 1] = p[row, 1] + lift * gy
            o_out[kept, 2] = p[row, 2] + lift * gz
            d_out[kept, 0], d_out[kept, 1], d_out[kept, 2] = hx, hy, hz
            tp_out[kept, 0], tp_out[kept, 1], tp_out[kept, 2] = c0, c1, c2
            c = lobe_class[lh]
            cls_out[kept] = incoming[row] if c == 0 else c
            rows_out[kept] = k
            if want_pdf:
                pdf = np.inf
                if (not htr or lh == _GLASS_T or lh == _TRANSL) and pr.is_rough(prm, row,
                                                                                lh + 1):
                    n0, n1, n2 = ns[row, 0], ns[row, 1], ns[row, 2]
                    ox, oy, oz = pr.frame_local(n0, n1, n2, wo[row, 0], wo[row, 1],
                                                wo[row, 2])
                    ix, iy, iz = pr.frame_local(n0, n1, n2, hx, hy, hz)
                    if not htr:
                        pdf = pr.bsdf_pdf(prm, sel, row, ox, oy, oz, ix, iy, iz)
                    else:
                        # Rough glass's refraction and the translucent lobe: light
                        # sampling reaches them too (engine/glasslight.py), so the rays
                        # that meet a light take MIS weights.
                        pdf = pr.transmission_pdf(prm, sel, row, ox, oy, oz, ix, iy, iz)
                pdf_out[kept] = pdf
            if split_out.shape[0] > 0:
                split_out[kept] = is_split
                split_p_out[kept] = (1.0 if not is_split else
                                     p_r if half == 0 else 1.0 - p_r)
            kept += 1
    return kept


@kernel
def gather_rays(u1, u2, ns, ng, p, offset, rows, o, d):
    """Final-gather rays of N hits: a cosine-distributed direction about the shading
    normal ns from the uniform numbers u1, u2 (N,) (sampling.cosine_hemisphere in the
    frame of sampling.to_world); the rays that leave above the geometric normal ng are
    written compacted: rows (K,) the hit of each ray, o (K,3) origins lifted off the
    surface by offset along ng (pbrt-v4's OffsetRayOrigin), d (K,3). Returns K."""
    k = 0
    for i in range(u1.shape[0]):
        r = math.sqrt(u1[i])
        phi = 2.0 * np.pi * u2[i]
        l0 = r * math.cos(phi)
        l1 = r * math.sin(phi)
        l2 = math.sqrt(max(0.0, 1.0 - u1[i]))
        x, y, z = _to_world(l0, l1, l2, ns[i, 0], ns[i, 1], ns[i, 2])
        gx, gy, gz = ng[i, 0], ng[i, 1], ng[i, 2]
        if not x * gx + y * gy + z * gz > 0.0:
            continue
        # Above ng: the origin goes to that side (offset_along_normal's side is +1).
        lift = 1.0 * offset[i]
        o[k, 0] = p[i, 0] + lift * gx
        o[k, 1] = p[i, 1] + lift * gy
        o[k, 2] = p[i, 2] + lift * gz
        d[k, 0], d[k, 1], d[k, 2] = x, y, z
        rows[k] = i
        k += 1
    return k


@kernel
def glossy_unguarded_rows(rows, trow, u, v, d, e1, e2, corner_normals, eps, out):
    """turnedglossy.camera_unguarded's test on the hits rows (K,) int64 (those on its
    materials): out[i] = True (out (N,) bool, False on entry) where the interpolated shading
    normal puts the viewer wo = -d below it on the ray's side of the winding normal
    ((side x ns . wo) <= eps) and that normal does not point into the surface (ns . ng >
    0). trow (N,) the triangle table row of each hit (Geometry.hit_tables without shared
    instances: prim); u, v (N,) barycentrics; d (N,3) ray directions; e1, e2 (T,3)
    float64; corner_normals (T,3,3) float32, not empty. Returns the rows marked.

    The numpy stage's operations in its order (tests/test_hotspot_kernels.py): ng as
    geometry._ng_rows (np.cross, its norm), ns as Geometry.shading_normals (the corners'
    lerp, normalised; ng where not finite or degenerate, as hit_geometry), and each dot
    product as np.einsum("ij,ij->i") sums its three terms: (x + z) + y."""
    count = 0
    for j in range(rows.shape[0]):
        i = rows[j]
        t = trow[i]
        cx, cy, cz = winding_normal(e1, e2, t)
        ln = max(math.sqrt(cx * cx + cy * cy + cz * cz), 1e-300)
        gx, gy, gz = cx / ln, cy / ln, cz / ln
        b1, b2 = u[i], v[i]
        w = 1.0 - b1 - b2
        sx = (w * np.float64(corner_normals[t, 0, 0]) + b1 * np.float64(corner_normals[t, 1, 0])
              + b2 * np.float64(corner_normals[t, 2, 0]))
        sy = (w * np.float64(corner_normals[t, 0, 1]) + b1 * np.float64(corner_normals[t, 1, 1])
              + b2 * np.float64(corner_normals[t, 2, 1]))
        sz = (w * np.float64(corner_normals[t, 0, 2]) + b1 * np.float64(corner_normals[t, 1, 2])
              + b2 * np.float64(corner_normals[t, 2, 2]))
        sl = max(math.sqrt(sx * sx + sy * sy + sz * sz), 1e-300)
        sx, sy, sz = sx / sl, sy / sl, sz / sl
        s = abs(sx) + abs(sy) + abs(sz)
        if not math.isfinite(s) or s < 0.5:
            sx, sy, sz = gx, gy, gz
        d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
        side = 1.0 if (d0 * gx + d2 * gz) + d1 * gy < 0.0 else -1.0
        view = (sx * -d0 + sz * -d2) + sy * -d1
        if side * view <= eps and (sx * gx + sz * gz) + sy * gy > 0.0:
            out[i] = True
            count += 1
    return count


@kernel
def diffuse_pdf_weights(albedo, sel, psum, wd, lambert):
    """glossysplit.DiffusePdf's per-hit weights from the closures' albedos (N, N_LOBES, 3):
    sel (N, N_LOBES) 0 then each non-diffuse lobe's max channel (np.maximum, NaN wins);
    psum (N,) their sum as numpy's sum(axis=1) adds N_LOBES - 1 = 8 values (its pairwise
    form: ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7)), added to 0.0); wd (N,)
    np.maximum(the diffuse albedo's mean as numpy's mean(axis=1): 0.0 + ((0.0 + a0) + a1)
    + a2, / 3, 0.0); lambert (N,) bool: no lobe but the diffuse and pass ones weighs > 0.
    The numpy stage's bits (tests/test_hotspot_kernels.py; needs N_LOBES == 9), but for
    the sign of a zero weight in sel (numpy's maximum of 0.0 and -0.0 is -0.0, _npmax's
    0.0), which no reader sees: principled.bsdf_pdf weighs a lobe only where w > 0.0."""
    for i in range(albedo.shape[0]):
        sel[i, 0] = 0.0
        for j in range(1, pr.N_LOBES):
            sel[i, j] = _npmax(_npmax(albedo[i, j, 0], albedo[i, j, 1]), albedo[i, j, 2])
        pw = (((sel[i, 1] + sel[i, 2]) + (sel[i, 3] + sel[i, 4]))
              + ((sel[i, 5] + sel[i, 6]) + (sel[i, 7] + sel[i, 8])))
        psum[i] = 0.0 + pw
        m = 0.0 + ((0.0 + albedo[i, pr.L_DIFFUSE, 0]) + albedo[i, pr.L_DIFFUSE, 1]
                   + albedo[i, pr.L_DIFFUSE, 2])
        wd[i] = _npmax(m / 3.0, 0.0)
        lam = True
        for j in range(1, pr.N_LOBES):
            if j != pr.L_PASS and sel[i, j] > 0.0:
                lam = False
        lambert[i] = lam


@kernel
def bsdf_pdf_rows(prm, sel, rows, ns, wo, wi, out):
    """principled.bsdf_pdf_many on the hit rows rows (K,) int64 of prm (N, N_PACK), sel
    (N, N_LOBES) and wo (N,3), read in place (bsdf_pdf_many takes the K rows gathered:
    ~50 floats a pair copied, the larger part of glossysplit.DiffusePdf.pdf's CPU); ns,
    wi (K,3) by pair; out (K,). Each pair the same operations: the same bits."""
    for k in range(rows.shape[0]):
        r = rows[k]
        n0, n1, n2 = ns[k, 0], ns[k, 1], ns[k, 2]
        ox, oy, oz = pr.frame_local(n0, n1, n2, wo[r, 0], wo[r, 1], wo[r, 2])
        ix, iy, iz = pr.frame_local(n0, n1, n2, wi[k, 0], wi[k, 1], wi[k, 2])
        out[k] = pr.bsdf_pdf(prm, sel, r, ox, oy, oz, ix, iy, iz)


@kernel
def _npmin(a, b):
    """np.minimum: NaN wins."""
    if a != a or b != b:
        return a + b
    return a if a <= b else b


@kernel
def _npdiv(a, b):
    """a / b as numpy divides two float64s (a zero divisor gives inf or NaN where numba's
    default error model raises)."""
    if b == 0.0:
        if a == 0.0 or a != a:
            return math.nan
        return math.copysign(math.inf, a) * math.copysign(1.0, b)
    return a / b


@kernel
def diffuse_reject_pairs(prm, sel, plain, wd, psum, largest, camera, ns, wo, fg, at, rows,
                         pid, direction, code, stored, out):
    """glossysplit.DiffusePdf.reject_for's test of (query row, photon) pairs in one pass:
    out[k] (K,) bool True where Cycles blurs the photon's path at the hit row
    r = at[rows[k]] (at (Q,) int64 the query rows' hit rows, rows (K,) int64 into at):
    largest[r] < fg, else min(pdf_D(wi), stored[pid[k]]) < fg (not >=: NaN rejects),
    wi = -v / max(|v|, 1e-300), v photon pid[k]'s stored direction read in place from
    the map's array: direction (P,3) float (float32 in a shot) read as float64, or, when
    code (P,2) int16 is not empty (photonlayout's compact layout), photonlayout.oct_decode
    of its code (float32, photonlayout.decode_vectors' bits) read as float64.
    pdf_D is DiffusePdf.pdf's (cos / pi on its plain rows, else (bsdf_pdf + wd cos / pi)
    / (psum + wd); at most camera[r], camera (N,) or empty; NaN read as inf); stored
    (P,) float32 Photons.blur_pdf or empty. The numpy stage's operations in its order:
    |v| as np.linalg.norm(axis=1) sums (x^2 + y^2) + z^2, the cosine as
    np.einsum("ij,ij->i") (x + z) + y, np.maximum / np.minimum's NaN (the same bits:
    tests/test_hotspot_kernels.py). prm, sel, plain, wd, psum, ns, wo: DiffusePdf's (N
    rows); fg: Filter Glossy."""
    cam = camera.shape[0] > 0
    blur = stored.shape[0] > 0
    compact = code.shape[0] > 0
    for k in range(rows.shape[0]):
        r = at[rows[k]]
        if not largest[r] >= fg:
            out[k] = True
            continue
        j = pid[k]
        if compact:
            a, b, c = oct_decode(code[j, 0], code[j, 1])
            x, y, z = -np.float64(a), -np.float64(b), -np.float64(c)
        else:
            x = -np.float64(direction[j, 0])
            y = -np.float64(direction[j, 1])
            z = -np.float64(direction[j, 2])
        m = _npmax(math.sqrt((x * x + y * y) + z * z), 1e-300)
        x, y, z = x / m, y / m, z / m
        n0, n1, n2 = ns[r, 0], ns[r, 1], ns[r, 2]
        d = _npmax((x * n0 + z * n2) + y * n1, 0.0) / math.pi
        if not plain[r]:
            ox, oy, oz = pr.frame_local(n0, n1, n2, wo[r, 0], wo[r, 1], wo[r, 2])
            ix, iy, iz = pr.frame_local(n0, n1, n2, x, y, z)
            lobes = pr.bsdf_pdf(prm, sel, r, ox, oy, oz, ix, iy, iz)
            w = wd[r]
            d = _npdiv(lobes + w * d, psum[r] + w)
        if cam:
            d = _npmin(d, camera[r])
        if d != d:
            d = math.inf
        if blur:
            d = _npmin(d, np.float64(stored[j]))
        out[k] = not d >= fg


# (diffuse_reject_pairs' empty arrays: no float directions, no compact codes)
NO_DIRECTIONS = np.zeros((0, 3), np.float32)
NO_CODES = np.zeros((0, 2), np.int16)


@register_warm_up
def _warm_up():
    v0 = np.zeros((1, 3))
    e1 = np.array([[1.0, 0.0, 0.0]])
    e2 = np.array([[0.0, 1.0, 0.0]])
    one = np.full(1, 0.25)
    prim = np.zeros(1, np.int64)
    d = np.array([[0.0, 0.0, -1.0]])
    p, ng, ns, base = (np.empty((1, 3)) for _ in range(4))
    front = np.empty(1, np.bool_)
    mat = np.empty(1, np.int32)
    off = np.empty(1)
    for cn in (np.zeros((0, 3, 3), np.float32), np.ones((1, 3, 3), np.float32)):
        hit_geometry(prim, one, one, d, v0, e1, e2, cn, np.zeros(1, np.int32),
                     np.ones((1, 3)), p, ng, ns, front, mat, base, off, np.empty((1, 2)))
    face_shading_normals(ns, ng, front, d, np.zeros(1, np.bool_))
    view_depth(p, np.zeros(3), np.ones(3), np.empty(1))
    for cn in (np.zeros((0, 3, 3), np.float32), np.ones((1, 3, 3), np.float32)):
        surface_lobes(prim, one, one, d, v0, e1, e2, cn, np.zeros(1, np.int32),
                      np.ones((1, 3)), np.full((1, pr.N_MAT), 0.5), np.ones(1),
                      np.ones((1, 3)), True, p, ng, ns, np.empty((1, 3)), front, mat, base,
                      off, np.empty((1, 2)), np.empty((1, pr.N_PACK)),
                      np.empty((1, pr.N_LOBES)), np.empty(1), np.empty((1, pr.N_LOBES - 1)),
                      np.empty(1), np.empty(1, np.bool_), np.empty(1, np.int64),
                      np.empty((1, 3)), np.zeros(0), False)
    for per_hit, hit_alpha in ((False, np.zeros(0)), (True, np.ones(1))):
        hit_closures(ns, ng, -d, mat, np.zeros((1, pr.N_MAT)), per_hit, base, front,
                     np.ones(1), hit_alpha, np.empty((1, pr.N_PACK)),
                     np.empty((1, pr.N_LOBES, 3)), np.zeros(0))
    for per_hit, hit_alpha in ((False, np.zeros(0)), (True, np.ones(1))):
        for params in (np.zeros((1, pr.N_MAT)), np.full((1, pr.N_MAT), 0.5)):
            shade_lobes(ns, ng, -d, mat, params, per_hit, base, front, np.ones(1), hit_alpha,
                        np.ones((1, 3)), True, np.empty((1, pr.N_PACK)),
                        np.empty((1, pr.N_LOBES)), np.empty(1), np.empty((1, pr.N_LOBES - 1)),
                        np.empty(1), np.empty(1, np.bool_), np.empty(1, np.int64),
                        np.empty((1, 3)), np.zeros(0), False)
    gather_rays(one, one, ns, ng, p, off, np.empty(1, np.int64), np.empty((1, 3)),
                np.empty((1, 3)))
    glossy_unguarded_rows(np.zeros(1, np.int64), np.zeros(1, np.int64), one, one, d, e1, e2,
                          np.ones((1, 3, 3), np.float32), 1e-6, np.zeros(1, np.bool_))
    diffuse_pdf_weights(np.full((1, pr.N_LOBES, 3), 0.1), np.empty((1, pr.N_LOBES)),
                        np.empty(1), np.empty(1), np.empty(1, np.bool_))
    bsdf_pdf_rows(np.zeros((1, pr.N_PACK)), np.zeros((1, pr.N_LOBES)), np.zeros(1, np.int64),
                  ns, -d, d, np.empty(1))
    for camera, stored in ((np.zeros(0), np.zeros(0, np.float32)),
                           (np.ones(1), np.ones(1, np.float32))):
        for direction, code in ((d.astype(np.float32), NO_CODES),
                                (NO_DIRECTIONS, np.zeros((1, 2), np.int16))):
            diffuse_reject_pairs(np.zeros((1, pr.N_PACK)), np.zeros((1, pr.N_LOBES)),
                                 np.zeros(1, np.bool_), one, one, np.full(1, np.inf),
                                 camera, ns, -d, 1.0, np.zeros(1, np.int64),
                                 np.zeros(1, np.int64), np.zeros(1, np.int64), direction,
                                 code, stored, np.empty(1, np.bool_))
    i64 = np.zeros(1, np.int64)
    keep_path_hits(i64, p, d, base, i64, one, one, one, i64, one, i64, one)
    film_add(np.zeros((1, 3)), 0, i64, i64, base, base)
    film_add(np.zeros((1, 3)), 0, i64, np.zeros(0, np.int64), base, base)
    film_add(np.zeros((1, 3)), 0, i64, np.zeros(0, np.int64), np.zeros((0, 3)), base)
    film_add_scalar(np.zeros(1), 0, i64, np.ones(len(i64)))
    film_first_normals(0, i64, base, np.ones(len(i64), np.bool_), np.zeros((1, 3)))
    alb = np.full((1, pr.N_LOBES, 3), 0.1)
    sel, q, psum = np.empty((1, pr.N_LOBES)), np.empty(1), np.empty(1)
    pl = np.empty((1, pr.N_LOBES - 1))
    choose_lobes(alb, np.ones((1, 3)), sel, q, pl, psum)
    idx = np.zeros(1, np.int64)
    lobe = np.empty(1, np.int64)
    prob = np.empty(1)
    pick_lobes(pl, psum, q, idx, one, lobe, prob)
    mirror_survival(np.zeros((1, pr.N_PACK)), pl, psum, q, sel)
    prm, _ = pr.setup_np(np.zeros((1, pr.N_MAT)), np.zeros(1, np.int64), base, np.full(1, 0.8),
                         front)
    lobe[0] = pr.L_METAL - 1
    continue_lobes(idx, lobe, prob, one, one, one, prm, sel, mat, np.zeros((1, pr.N_MAT)),
                   np.ones(1), np.zeros(0), p, ng, ns, -d, off,
                   np.ones((1, 3)), np.zeros(1, np.int64), np.zeros(7, np.int64), True,
                   np.ones(1, np.bool_), False, np.empty(2, np.int64), np.empty((2, 3)),
                   np.empty((2, 3)), np.empty((2, 3)), np.empty(2, np.int64), np.empty(2),
                   np.empty(2, np.bool_), np.empty(2))
