"""The direct-light stage in compiled kernels: shadow rays to every light, then occlusion.

For a batch of diffuse hits, `sample_lights` draws every light sample (area rectangles and
ellipses with spread clamp and shear, point and spot lights with a radius and the scaled
spot frame, the sun's disk, emissive triangles by their light tree, the world), computes the
irradiance each would bring ignoring visibility (with Cycles' shading offset), and writes
the shadow rays of the lit samples, compacted, as float32 straight into the arrays handed
to Embree's OCCLUDED query (engine/accel.py, Accel.occluded_into). `accumulate` then adds
contribution x visible per hit, in sample order. Kernels are `@kernel` (engine/jit.py:
nogil, cached, no prange), so engine/parallel.py's threads run them side by side.

The arithmetic follows the light modules (engine/lights/) operation by operation, with the
same random numbers (drawn by the caller in numpy, in the order the lights draw them), so
images match the numpy implementation to rounding (docs/performance.md, "Direct light in
compiled kernels"). Ray ends follow engine/rayoffset.py (pbrt-v4's OffsetRayOrigin /
SpawnRayTo; Cycles' shadow terminator offset).
"""
from __future__ import annotations

import math

import numpy as np

from .closures import principled as pr
from .jit import kernel, register_warm_up
from .lights import packing as pk
from .ies import HEADER, ies_factor
from .lights.emission import concentric_disk as _concentric_disk, to_world as _to_world
from .lights.environment import N_OCT, env_cosine_pdf, env_cosine_sample, env_radiance
from .lights.area import MIN_SPHERICAL_SOLID_ANGLE, spherical_rectangle
from .lights.mesh import solid_angle_sampled, spherical_triangle_sample
from .lights.selection import NINF, empty_tree, select_light
from .lights.world import ENV_MAP_FRACTION, portal_choice, portal_density, portal_draw
from .normalmap import bump_shadowing_term, bump_shadowing_terms
from .rayoffset import G32_PLANE, G32_T, G64, TINY32, U32

F32_MAX = float(np.finfo(np.float32).max)
ONE_BELOW = 1.0 - 2.0 ** -53  # the largest float64 below 1
TWO_U32 = 2.0 * U32
TWO_PI = 2.0 * np.pi
PI = math.pi

# Slots (engine/lights/packing.py), as module constants the kernels freeze.
POS, DIR, U, V, DU, DV, RGB = pk.POS, pk.DIR, pk.U, pk.V, pk.DU, pk.DV, pk.RGB
RADIUS, SIZE_X, SIZE_Y, AREA_, COS_HALF = pk.RADIUS, pk.SIZE_X, pk.SIZE_Y, pk.AREA_, pk.COS_HALF
SPREAD_ON, TAN_H, SPREAD_NORM, IS_DISK, SPREAD_RECT = (pk.SPREAD_ON, pk.TAN_H, pk.SPREAD_NORM,
                                                       pk.IS_DISK, pk.SPREAD_RECT)
SPOT_COS_HALF, SPOT_WIDTH, SPOT_FRAME = pk.SPOT_COS_HALF, pk.SPOT_WIDTH, pk.SPOT_FRAME
ENV_ON, ENV_INTERP, ENV_FRAME = pk.ENV_ON, pk.ENV_INTERP, pk.ENV_FRAME
SPHERE = pk.SPHERE
C_POINT, C_SPOT, C_AREA, C_SUN, C_MESH, C_WORLD = (pk.CODE_POINT, pk.CODE_SPOT, pk.CODE_AREA,
                                                   pk.CODE_SUN, pk.CODE_MESH, pk.CODE_WORLD)


@kernel
def _ulp32(x):
    return max(TWO_U32 * abs(x), TINY32)


@kernel
def _npmax(a, b):
    """np.maximum: NaN wins."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@kernel
def _spread_attenuation(cos_a, q):
    if q[SPREAD_ON] == 0.0:
        return 1.0
    c = max(cos_a, 1e-12)
    tan_a = math.sqrt(max(1.0 - c * c, 0.0)) / c
    if cos_a > 0:
        return max((q[TAN_H] - tan_a) * q[SPREAD_NORM], 0.0)
    return 0.0


@kernel
def _spot_mask(w0, w1, w2, q):
    f = SPOT_FRAME
    l0 = w0 * q[f + 0] + w1 * q[f + 1] + w2 * q[f + 2]
    l1 = w0 * q[f + 3] + w1 * q[f + 4] + w2 * q[f + 5]
    l2 = w0 * q[f + 6] + w1 * q[f + 7] + w2 * q[f + 8]
    length = math.sqrt(l0 ** 2 + l1 ** 2 + l2 ** 2)
    x = l2 / max(length, 1e-300) - q[SPOT_COS_HALF]
    width = q[SPOT_WIDTH]
    if width <= 0:
        return 1.0 if x > 0 else 0.0
    t = min(max(x / width, 0.0), 1.0)
    return t * t * (3.0 - 2.0 * t)


@kernel
def _sphere_light_sample(p0, p1, p2, s0, s1, s2, g0, g1, g2, u1, u2, q, spot):
    """One shadow-ray sample of a point / spot light that is a sphere of radius q[RADIUS]
    (Soft Falloff off; Cycles' point_light_sample / spot_light_sample, is_sphere): from
    outside, a direction uniform in the cone the sphere subtends (pdf 1 / (2 pi (1 -
    cos a)), sin a = r / d); from inside, cosine-distributed round the shading normal s.
    The ray's end y is where the direction meets the sphere (law of cosines). Radiance
    I / (pi r^2) x a spot's mask along the ray (outside only). Returns (y (3), w (3), the
    irradiance L cos / pdf (3), the solid-angle pdf)."""
    rad = q[RADIUS]
    t0, t1, t2 = p0 - q[POS], p1 - q[POS + 1], p2 - q[POS + 2]
    d2c = t0 * t0 + t1 * t1 + t2 * t2
    dc = math.sqrt(d2c)
    dcs = max(dc, 1e-300)
    a0, a1, a2 = t0 / dcs, t1 / dcs, t2 / dcs
    r2 = rad * rad
    outside = d2c > r2
    if outside:
        x = r2 / d2c
        omc = x / (1.0 + math.sqrt(max(1.0 - x, 0.0)))  # 1 - cos a, stable for small x
        v = u1 * omc
        ct = 1.0 - v
        st = math.sqrt(max(v * (2.0 - v), 0.0))
        phi = TWO_PI * u2
        w0, w1, w2 = _to_world(st * math.cos(phi), st * math.sin(phi), ct, -a0, -a1, -a2)
        pdf = 1.0 / (TWO_PI * omc)
    else:
        r = math.sqrt(u1)
        phi = TWO_PI * u2
        z = math.sqrt(max(0.0, 1.0 - u1))
        w0, w1, w2 = _to_world(r * math.cos(phi), r * math.sin(phi), z, s0, s1, s2)
        ct = -(w0 * a0 + w1 * a1 + w2 * a2)
        pdf = z / PI
    root = math.sqrt(max(r2 - d2c + d2c * ct * ct, 0.0))
    t = dc * ct - (root if outside else -root)
    y0, y1, y2 = p0 + w0 * t, p1 + w1 * t, p2 + w2 * t
    cr = _npmax(w0 * s0 + w1 * s1 + w2 * s2, 0.0) * (
        1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0)
    f = cr / max(pdf, 1e-300) / (PI * r2) if pdf > 0 else 0.0
    if spot and outside:
        f = f * _spot_mask(-w0, -w1, -w2, q)
    if q.shape[0] > pk.IES and q[pk.IES + HEADER] > 0:
        # The IES profile along the ray, from the sampled point to the shaded point
        # (measured against Cycles 5.0: not along the sphere's normal there, which
        # read up to 56 % off; tests/blender/test_ies_cycles.py): engine/ies.py.
        f = f * ies_factor(q, pk.IES, -w0, -w1, -w2)
    return y0, y1, y2, w0, w1, w2, q[RGB] * f, q[RGB + 1] * f, q[RGB + 2] * f, pdf


@kernel
def _shift_cos_in(cos_in, offset):
    f = 1.0 / (1.0 - 0.5 * offset)
    if not f > 1.0:
        return 1.0
    c = min(max(cos_in, 0.0), 1.0)
    if not c > 0:
        return 0.0
    return max(math.cos(math.acos(c) * f), 0.0) / max(c, 1e-300)


@kernel
def _terminator_amount(cutoff, cos_ns, cos_ng):
    nl = abs(cos_ns)
    if nl < cutoff:
        return min(max(2.0 - (cos_ng + nl) / cutoff, 0.0), 1.0)
    return min(max(1.0 - cos_ng / cutoff, 0.0), 1.0)


@kernel
def _dot(a0, a1, a2, b0, b1, b2):
    return a0 * b0 + a1 * b1 + a2 * b2


@kernel
def terminator_lift(prim, bary, ng, smooth, object_id, terminator, v0, e1, e2,
                    corner_normals, cutoff, lift, only):
    """Per hit i (not per sample): cutoff[i] = the shadow-terminator geometry offset of its
    triangle's object (terminator[object_id[t]], per object: engine/geometry.py) if
    smooth-shaded (else 0) and lift[i] (3,) the lift of the hit from the flat
    facet to the smooth surface through the corners (a parabolic patch bounded by the
    corners' tangent planes): Blender's intern/cycles/kernel/light/sample.h,
    shadow_ray_smooth_surface_offset(), in world space.
    only (K,) int64: these hits alone (a camera bounce's shaded rows, sample_lights'
    hrow; the other rows of cutoff and lift stay unwritten); (0,): every hit."""
    some = only.shape[0] > 0
    for ii in range(only.shape[0] if some else prim.shape[0]):
        i = only[ii] if some else ii
        t = prim[i]
        cut = terminator[object_id[t]]  # per object (branch scale: 4 B a triangle less)
        if not (smooth[t] and cut > 0):
            cutoff[i] = 0.0
            lift[i, 0] = lift[i, 1] = lift[i, 2] = 0.0
            continue
        cutoff[i] = cut
        b1 = bary[i, 0]
        b2 = bary[i, 1]
        w = 1.0 - b1 - b2
        A0, A1, A2 = v0[t, 0], v0[t, 1], v0[t, 2]
        B0, B1, B2 = v0[t, 0] + e1[t, 0], v0[t, 1] + e1[t, 1], v0[t, 2] + e1[t, 2]
        C0, C1, C2 = v0[t, 0] + e2[t, 0], v0[t, 1] + e2[t, 1], v0[t, 2] + e2[t, 2]
        M = corner_normals[t]
        P0 = A0 * w + B0 * b1 + C0 * b2
        P1 = A1 * w + B1 * b1 + C1 * b2
        P2 = A2 * w + B2 * b1 + C2 * b2
        n0 = M[0, 0] * w + M[1, 0] * b1 + M[2, 0] * b2
        n1 = M[0, 1] * w + M[1, 1] * b1 + M[2, 1] * b2
        n2 = M[0, 2] * w + M[1, 2] * b1 + M[2, 2] * b2
        a = _dot(M[2, 0] - M[0, 0], M[2, 1] - M[0, 1], M[2, 2] - M[0, 2], A0 - C0, A1 - C1, A2 - C2)
        b = _dot(M[2, 0] - M[1, 0], M[2, 1] - M[1, 1], M[2, 2] - M[1, 2], B0 - C0, B1 - C1, B2 - C2)
        c = _dot(M[1, 0] - M[0, 0], M[1, 1] - M[0, 1], M[1, 2] - M[0, 2], B0 - A0, B1 - A1, B2 - A2)
        h = a * w * (w - 1) + (a + b + c) * w * b1 + b * b1 * (b1 - 1)
        N00, N01, N02 = M[0, 0], M[0, 1], M[0, 2]
        N10, N11, N12 = M[1, 0], M[1, 1], M[1, 2]
        N20, N21, N22 = M[2, 0], M[2, 1], M[2, 2]
        if _dot(n0, n1, n2, ng[i, 0], ng[i, 1], ng[i, 2]) > 0:
            h0 = _npmax(_npmax(_dot(B0 - A0, B1 - A1, B2 - A2, N00, N01, N02),
                               _dot(C0 - A0, C1 - A1, C2 - A2, N00, N01, N02)), 0.0)
            h1 = _npmax(_npmax(_dot(A0 - B0, A1 - B1, A2 - B2, N10, N11, N12),
                               _dot(C0 - B0, C1 - B1, C2 - B2, N10, N11, N12)), 0.0)
            h2 = _npmax(_npmax(_dot(A0 - C0, A1 - C1, A2 - C2, N20, N21, N22),
                               _dot(B0 - C0, B1 - C1, B2 - C2, N20, N21, N22)), 0.0)
            h0 = _npmax(_dot(A0 - P0, A1 - P1, A2 - P2, N00, N01, N02) + h0, 0.0)
            h1 = _npmax(_dot(B0 - P0, B1 - P1, B2 - P2, N10, N11, N12) + h1, 0.0)
            h2 = _npmax(_dot(C0 - P0, C1 - P1, C2 - P2, N20, N21, N22) + h2, 0.0)
            hh = _npmax(min(min(h0, h1), h2), h * 0.5)
        else:
            g0 = _npmax(_npmax(_dot(A0 - B0, A1 - B1, A2 - B2, N00, N01, N02),
                               _dot(A0 - C0, A1 - C1, A2 - C2, N00, N01, N02)), 0.0)
            g1 = _npmax(_npmax(_dot(B0 - A0, B1 - A1, B2 - A2, N10, N11, N12),
                               _dot(B0 - C0, B1 - C1, B2 - C2, N10, N11, N12)), 0.0)
            g2 = _npmax(_npmax(_dot(C0 - A0, C1 - A1, C2 - A2, N20, N21, N22),
                               _dot(C0 - B0, C1 - B1, C2 - B2, N20, N21, N22)), 0.0)
            g0 = _npmax(_dot(P0 - A0, P1 - A1, P2 - A2, N00, N01, N02) + g0, 0.0)
            g1 = _npmax(_dot(P0 - B0, P1 - B1, P2 - B2, N10, N11, N12) + g1, 0.0)
            g2 = _npmax(_dot(P0 - C0, P1 - C1, P2 - C2, N20, N21, N22) + g2, 0.0)
            hh = min(-min(min(g0, g1), g2), h * 0.5)
        lift[i, 0], lift[i, 1], lift[i, 2] = n0 * hh, n1 * hh, n2 * hh


@kernel
def sample_lights(p, ns, gate, ng, offset, shade_off, cutoff, lift, nsm,
                  codes, params, m_v0, m_e1, m_e2, m_ng, m_L, m_area, m_tf, m_ti, m_round32,
                  m_tilt32, m_side, env_px, env_stored, env_scale, env_rows, env_cols, env_mass,
                  env_prefix, env_cell, pt_f, pt_sat,
                  tree_f, tree_i, inf_idx, inf_f, l_trace, klight, ktrace, U1, U2, SEL,
                  contrib, row, kidx, ray, o32, d32, t32, wdir, lpdf, bump, hrow, gn):
    """Every light sample of a batch of hits, compacted to the lit ones.

    p, ns, gate, ng (N,3): hit points, shading normals, the normal whose hemisphere may
    receive light (gate (0,3): chosen here, ns where the hit has a terminator cut-off > 0,
    else ng: integrator._hit_arrays),
    geometric normals; offset (N,) the
    origin offset along ng (rayoffset.origin_offset); shade_off (N,) Cycles' shading
    offset (0: none); cutoff (N,) shadow-terminator geometry offset of smooth triangles (0:
    none) and lift (N,3) their smooth-surface lift (terminator_lift); shade_off (0,),
    cutoff (0,) and lift (0,3): no hit has one (nothing to read); nsm (N,3) the smooth
    normal before Normal Map / Bump nodes (equal to ns where no node bent it).
    codes (L,), params (L,P): packed lights; m_*: emissive triangles (m_side (T,) the
    sides sampled, scene.emission_sides: a one-sided triangle gives no sample from its
    other side), env_*: the world's environment map, pt_f, pt_sat: its light portals'
    tables (lights/portalmap.py; packing.pack_lights).
    tree_f, tree_i, inf_idx, inf_f: the light tree (lights/selection.py LightSelector;
    empty_tree() without one), l_trace (L,) whether each light's shadows are traced.
    klight (K,) light of sample k, or -1: a light chosen per hit by the tree, its
    contribution divided by the choice's probability; ktrace (K,) whether its shadows are
    traced (l_trace for chosen lights); U1, U2, SEL (K,N): its random numbers (SEL: the
    triangle choice of mesh lights, the strategy choice of an environment-mapped world
    (rescaled, its direction's first coordinate in place of U1),
    the tree's choice (remapped for those) when klight is -1). A mesh light reads SEL and
    U2 only: SEL walks the light's triangle tree (m_tf, m_ti: MeshLight.triangle_tree)
    at the hit's point and shading normal to a triangle and, remapped on the way
    (select_light), is the point's first coordinate, U2 its second
    (integrator.mesh_light_numbers).
    Writes entries j < m_all: contrib (j,3) irradiance without visibility, row (j,) hit,
    kidx (j,) sample k, ray (j,) its shadow ray's index or -1 (not traced), wdir (j,3) the
    unit direction towards the light sample and lpdf (j,) its solid-angle pdf (inf for a
    light without size) for BSDF evaluation and multiple importance sampling (the area
    lights' pdf is of the whole light, also with spread; for a light the tree picked, the
    light's pdf times the choice's probability, -1 for a constant-colour world, which the
    glossy lobes leave to their continuation), bump (j,) Cycles' bump shadowing of the
    diffuse lobe (normalmap.bump_shadowing_term; light from below the
    smooth surface, refused for every lobe, makes no entry); wdir (0,3) and lpdf (0,):
    not written (the diffuse lobe alone reads neither); bump (0,): not written (no hit's
    normal is bent, nsm is ns: every entry's term is 1, accumulate reads none); rays
    i < m_rays: o32, d32 (i,3), t32 (i,). Returns (m_all, m_rays).
    hrow (n,) int64: the hits are rows hrow of the per-hit arrays above (a camera
    bounce's shaded rows read in place, no compacted copies; row[j] and U1..SEL's
    columns count the n shaded hits); (0,): the per-hit arrays are the n hits.
    gn (N,3): the glossy lobes' raised normal in world space where the hit has one
    (principled.glossy_normals, Cycles' valid_reflection_N; a zero row: none), or (0,3):
    no hit has one. A raised hit's glossy lobes take light from the raised normal's side
    even where it lies below the shading normal ns, so its entries change meaning
    (accumulate_bsdf reads them so): contrib is the light's radiance / pdf without a
    cosine, and bump holds the diffuse lobe's cos(wi, ns) x bump shadowing term (0 where
    the diffuse lobe gets none of it), stored as -1 - that value where the glossy lobes
    get none of it (Cycles' bump_shadowing_term with the raised normal: light from below
    the smooth surface). Such an entry is made when either side receives the light."""
    indexed = hrow.shape[0] > 0
    has_gn = gn.shape[0] > 0
    n = hrow.shape[0] if indexed else p.shape[0]
    want_bump = bump.shape[0] > 0
    own_gate = gate.shape[0] == 0
    # Optional inputs and outputs, left empty when no hit has them or nothing reads them:
    # each is tens of bytes a hit of memory traffic, most of this kernel's time.
    has_shade = shade_off.shape[0] > 0
    has_terminator = cutoff.shape[0] > 0
    want_dir = wdir.shape[0] > 0
    K = klight.shape[0]
    m_all = 0
    m_rays = 0
    # The triangle tree has no lights at infinity.
    no_inf = np.zeros(0, np.int64)
    no_inf_f = np.zeros((0, NINF))
    env_frame = np.zeros((3, 3))
    pom = np.zeros(pk.MAX_PORTALS)  # the world's light portals' solid angles at a hit
    pmass = np.zeros(pk.MAX_PORTALS)  # ... and their map integrals (portalmap.py)
    last = -1
    code = codes[0] if codes.shape[0] > 0 else -1
    q = params[0] if params.shape[0] > 0 else np.zeros(pk.P)
    for k in range(K):
        for i in range(n):
            h = hrow[i] if indexed else i  # the hit's row in the per-hit arrays
            u1 = U1[k, i]
            u2 = U2[k, i]
            li = klight[k]
            pmf = 1.0
            chosen = li < 0
            # SEL is (K, 1) when no sample takes a third number: never index past it.
            selu = SEL[k, i] if SEL.shape[1] == n else 0.0
            trace = ktrace[k]
            if li < 0:
                # One light chosen for this hit by the light tree (lights/selection.py);
                # its remapped number serves the light's own third choice.
                li, pmf, selu = select_light(tree_f, tree_i, inf_idx, inf_f, p[h, 0],
                                             p[h, 1], p[h, 2], ns[h, 0], ns[h, 1], ns[h, 2],
                                             selu)
                if li < 0 or not pmf > 0:
                    continue
                trace = l_trace[li]
            if li != last:  # a light's row and frame, fetched when the light changes
                last = li
                code = codes[li]
                q = params[li]
                if code == C_WORLD and q[ENV_ON] != 0.0:
                    for a in range(3):
                        for b in range(3):
                            env_frame[a, b] = q[ENV_FRAME + 3 * a + b]
            p0, p1, p2 = p[h, 0], p[h, 1], p[h, 2]
            s0, s1, s2 = ns[h, 0], ns[h, 1], ns[h, 2]
            if not own_gate:
                g0, g1, g2 = gate[h, 0], gate[h, 1], gate[h, 2]
            elif has_terminator and cutoff[h] > 0:
                # Smooth with a terminator offset: light the shading normal faces is
                # traced (its ray leaves from the lifted point: integrator._hit_arrays).
                g0, g1, g2 = s0, s1, s2
            else:
                g0, g1, g2 = ng[h, 0], ng[h, 1], ng[h, 2]
            # The normal whose cosine the light's irradiance carries: the shading normal,
            # or for a hit with a raised glossy normal the gate's (every entry lies above
            # it, so its cosine divides out again, below: the lobes take their own).
            raised = has_gn and (gn[h, 0] != 0.0 or gn[h, 1] != 0.0 or gn[h, 2] != 0.0)
            if raised:
                cs0, cs1, cs2 = g0, g1, g2
            else:
                cs0, cs1, cs2 = s0, s1, s2
            finite = True      # the sample lies at a point y (not at infinity)
            surface = False    # ... on a surface with normal ny and end gap
            solid = False      # an emissive triangle sampled by solid angle omega
            omega = 0.0
            solid_rect = False  # a rectangle area light sampled by solid angle rect_omega
            rect_omega = 0.0
            tpmf = 1.0
            tri = 0
            y0 = y1 = y2 = 0.0
            ny0 = ny1 = ny2 = 0.0
            gap = 0.0
            e0 = e1 = e2 = 0.0
            w0 = w1 = w2 = 0.0
            lp = np.inf
            if code == C_SUN or code == C_WORLD:
                finite = False
                if code == C_SUN:
                    z = 1.0 - u1 * (1.0 - q[COS_HALF])
                    r = math.sqrt(max(0.0, 1.0 - z * z))
                    phi = TWO_PI * u2
                    w0, w1, w2 = _to_world(r * math.cos(phi), r * math.sin(phi), z,
                                           -q[DIR], -q[DIR + 1], -q[DIR + 2])
                    cr = _npmax(w0 * cs0 + w1 * cs1 + w2 * cs2, 0.0) * (
                        1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0)
                    e0, e1, e2 = q[RGB] * cr, q[RGB + 1] * cr, q[RGB + 2] * cr
                    if q[COS_HALF] < 1.0:
                        lp = 1.0 / (TWO_PI * (1.0 - q[COS_HALF]))
                elif q[pk.PORTAL_N] > 0.0:
                    # Light portals (lights/world.py, lightportal34): with probability
                    # s_p a direction through the portals seen (uniform in their solid
                    # angle; with a map, in proportion to the map seen through them:
                    # portalmap.py, portalenv35), else the strategies below; SEL picks
                    # and, rescaled, is the first coordinate. One-sample MIS (balance
                    # heuristic) over the mixture (1 - s_p) pdf_before + s_p pdf_portal.
                    ptot, sp = portal_choice(q, pt_sat, p0, p1, p2, s0, s1, s2, pom, pmass)
                    pp = 0.0
                    by_portal = selu < sp
                    rest = selu
                    if by_portal:
                        w0, w1, w2, pp = portal_draw(q, pt_f, pt_sat, p0, p1, p2,
                                                     min(selu / sp, ONE_BELOW), u2, pom,
                                                     pmass, ptot)
                    elif sp > 0.0:
                        rest = min((selu - sp) / (1.0 - sp), ONE_BELOW)
                    R = env_frame
                    env = q[ENV_ON] != 0.0
                    pe = 0.0
                    if not by_portal:
                        if env and rest < ENV_MAP_FRACTION:
                            w0, w1, w2, pe = env_cosine_sample(
                                R, env_px, int(q[ENV_INTERP]), env_rows, env_cols,
                                env_mass, env_prefix, env_cell, N_OCT, s0, s1, s2,
                                min(rest / ENV_MAP_FRACTION, ONE_BELOW), u2)
                        else:
                            x = (min((rest - ENV_MAP_FRACTION) / (1.0 - ENV_MAP_FRACTION),
                                     ONE_BELOW) if env else rest)
                            r = math.sqrt(x)
                            phi = TWO_PI * u2
                            z = math.sqrt(max(0.0, 1.0 - x))
                            w0, w1, w2 = _to_world(r * math.cos(phi), r * math.sin(phi), z,
                                                   s0, s1, s2)
                        if sp > 0.0:
                            pp = portal_density(q, pt_f, p0, p1, p2, w0, w1, w2, pom, pmass,
                                                ptot)
                    cs = w0 * s0 + w1 * s1 + w2 * s2
                    ok = 1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0
                    pdf = max(cs, 0.0) / PI
                    if env:
                        if by_portal or not rest < ENV_MAP_FRACTION:
                            pe = env_cosine_pdf(R, env_px, int(q[ENV_INTERP]), env_mass,
                                                env_prefix, env_cell, N_OCT,
                                                w0, w1, w2, s0, s1, s2)
                        pdf = ENV_MAP_FRACTION * pe + (1.0 - ENV_MAP_FRACTION) * pdf
                    pdf = (1.0 - sp) * pdf + sp * pp
                    # (a portal draw that found nothing, pdf 0, brings nothing)
                    if cs > 0 and pdf > 0 and ok > 0 and (pp > 0.0 or not by_portal):
                        if env:
                            L0, L1, L2 = env_radiance(R, env_stored, int(q[ENV_INTERP]),
                                                      env_scale, w0, w1, w2)
                        else:
                            L0, L1, L2 = q[RGB], q[RGB + 1], q[RGB + 2]
                        f = cs / pdf
                        e0, e1, e2 = L0 * f, L1 * f, L2 * f
                    lp = pdf
                elif q[ENV_ON] == 0.0:
                    r = math.sqrt(u1)
                    phi = TWO_PI * u2
                    z = math.sqrt(max(0.0, 1.0 - u1))
                    w0, w1, w2 = _to_world(r * math.cos(phi), r * math.sin(phi), z, s0, s1, s2)
                    ok = 1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0
                    e0, e1, e2 = (PI * q[RGB]) * ok, (PI * q[RGB + 1]) * ok, (PI * q[RGB + 2]) * ok
                    lp = z / PI
                else:
                    # Environment map: one-sample MIS (balance heuristic) of the map's
                    # cosine-weighted distribution for the shading normal's cluster and
                    # the cosine hemisphere. SEL picks the strategy and, rescaled within
                    # the strategy's share, is the sample's first coordinate (U2 its
                    # second; integrator.mesh_light_numbers stratifies the pair), as a
                    # mesh light's triangle choice.
                    R = env_frame
                    if selu < ENV_MAP_FRACTION:
                        x = min(selu / ENV_MAP_FRACTION, ONE_BELOW)
                        w0, w1, w2, pe = env_cosine_sample(R, env_px, int(q[ENV_INTERP]),
                                                           env_rows, env_cols, env_mass,
                                                           env_prefix, env_cell, N_OCT,
                                                           s0, s1, s2, x, u2)
                    else:
                        x = min((selu - ENV_MAP_FRACTION) / (1.0 - ENV_MAP_FRACTION),
                                ONE_BELOW)
                        r = math.sqrt(x)
                        phi = TWO_PI * u2
                        z = math.sqrt(max(0.0, 1.0 - x))
                        w0, w1, w2 = _to_world(r * math.cos(phi), r * math.sin(phi), z,
                                               s0, s1, s2)
                        pe = env_cosine_pdf(R, env_px, int(q[ENV_INTERP]), env_mass,
                                            env_prefix, env_cell, N_OCT,
                                            w0, w1, w2, s0, s1, s2)
                    cs = w0 * s0 + w1 * s1 + w2 * s2
                    ok = 1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0
                    pdf = ENV_MAP_FRACTION * pe + (1.0 - ENV_MAP_FRACTION) * max(cs, 0.0) / PI
                    if cs > 0 and pdf > 0 and ok > 0:
                        L0, L1, L2 = env_radiance(R, env_stored, int(q[ENV_INTERP]), env_scale,
                                                  w0, w1, w2)
                        f = cs / pdf
                        e0, e1, e2 = L0 * f, L1 * f, L2 * f
                    lp = pdf
            elif (code == C_POINT or code == C_SPOT) and q[SPHERE] != 0.0 and q[RADIUS] > 0:
                y0, y1, y2, w0, w1, w2, e0, e1, e2, lp = _sphere_light_sample(
                    p0, p1, p2, cs0, cs1, cs2, g0, g1, g2, u1, u2, q, code == C_SPOT)
            elif code == C_POINT or code == C_SPOT:
                t0, t1, t2 = p0 - q[POS], p1 - q[POS + 1], p2 - q[POS + 2]
                dc = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
                dcs = max(dc, 1e-300)
                a0, a1, a2 = t0 / dcs, t1 / dcs, t2 / dcs
                rad = q[RADIUS]
                if rad > 0:
                    x, yy = _concentric_disk(u1, u2)
                    sign = 1.0 if a2 >= 0.0 else -1.0
                    aa = -1.0 / (sign + a2)
                    bb = a0 * a1 * aa
                    y0 = q[POS] + rad * (x * (1.0 + sign * a0 ** 2 * aa) + yy * bb)
                    y1 = q[POS + 1] + rad * (x * (sign * bb) + yy * (sign + a1 ** 2 * aa))
                    y2 = q[POS + 2] + rad * (x * (-sign * a0) + yy * (-a1))
                else:
                    y0, y1, y2 = q[POS], q[POS + 1], q[POS + 2]
                v0_, v1_, v2_ = y0 - p0, y1 - p1, y2 - p2
                dist = math.sqrt(v0_ * v0_ + v1_ * v1_ + v2_ * v2_)
                ds = max(dist, 1e-300)
                w0, w1, w2 = v0_ / ds, v1_ / ds, v2_ / ds
                cr = _npmax(w0 * cs0 + w1 * cs1 + w2 * cs2, 0.0) * (
                    1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0)
                cl = _npmax((-w0) * a0 + (-w1) * a1 + (-w2) * a2, 0.0) if rad > 0 else 1.0
                md = 16.0 * (_ulp32(max(max(abs(p0), abs(p1)), abs(p2)))
                             + _ulp32(max(max(abs(y0), abs(y1)), abs(y2))))
                d2 = max(dist * dist, md * md)
                f = cr * cl / d2
                e0, e1, e2 = q[RGB] * f, q[RGB + 1] * f, q[RGB + 2] * f
                if rad > 0:
                    lp = d2 / max(PI * rad * rad * cl, 1e-300)
                if code == C_SPOT:
                    # Along the ray from the disk's sample to the shaded point (Cycles'
                    # spot_light_attenuation(-ls->D)), as rays that meet the disk read it
                    # (PointLight.intersect): the light's size softens the cone's edge.
                    m = _spot_mask(-w0, -w1, -w2, q) if rad > 0 else _spot_mask(a0, a1, a2, q)
                    e0, e1, e2 = e0 * m, e1 * m, e2 * m
                if q.shape[0] > pk.IES and q[pk.IES + HEADER] > 0:
                    # The IES profile along the direction from the light sample to the
                    # shaded point (Cycles' ls->Ng = -ls->D, the light shader's Normal;
                    # from the centre without a radius): engine/ies.py.
                    m = ies_factor(q, pk.IES, -w0, -w1, -w2)
                    e0, e1, e2 = e0 * m, e1 * m, e2 * m
            else:
                surface = True
                two_sided = code == C_MESH
                msides = 3  # the sides sampled (a mesh triangle's m_side)
                if code == C_MESH:
                    # The triangle by its importance at this point and shading normal
                    # (Cycles' light tree over emissive triangles, pbrt-v4's
                    # BVHLightSampler): near, facing triangles most often. The number,
                    # remapped at each node, stays uniform on [0, 1) and independent of
                    # the choice (pbrt-v4's SampleDiscrete, uRemapped): it places the
                    # point on the triangle, so a stratified choice spreads over the
                    # panel as a whole.
                    tri, tpmf, ur = select_light(m_tf, m_ti, no_inf, no_inf_f, p0, p1, p2,
                                                 s0, s1, s2, selu)
                    if tri < 0 or not tpmf > 0:
                        continue
                    ur = min(max(ur, 0.0), ONE_BELOW)
                    solid = solid_angle_sampled(p0, p1, p2, m_v0, m_e1, m_e2, m_ng, tri)
                    if solid:
                        # A direction uniform in the triangle's solid angle (lights/mesh.py)
                        # and where it meets the triangle (Moller-Trumbore barycentrics).
                        sw0, sw1, sw2, omega = spherical_triangle_sample(
                            p0, p1, p2, m_v0, m_e1, m_e2, tri, ur, u2)
                        if not omega > 0:
                            continue
                        f0, f1, f2 = m_e1[tri, 0], m_e1[tri, 1], m_e1[tri, 2]
                        k0, k1, k2 = m_e2[tri, 0], m_e2[tri, 1], m_e2[tri, 2]
                        pv0, pv1, pv2 = sw1 * k2 - sw2 * k1, sw2 * k0 - sw0 * k2, sw0 * k1 - sw1 * k0
                        det = f0 * pv0 + f1 * pv1 + f2 * pv2
                        if det == 0.0:
                            continue
                        tv0, tv1, tv2 = p0 - m_v0[tri, 0], p1 - m_v0[tri, 1], p2 - m_v0[tri, 2]
                        b1 = (tv0 * pv0 + tv1 * pv1 + tv2 * pv2) / det
                        qv0, qv1, qv2 = tv1 * f2 - tv2 * f1, tv2 * f0 - tv0 * f2, tv0 * f1 - tv1 * f0
                        b2 = (sw0 * qv0 + sw1 * qv1 + sw2 * qv2) / det
                        b1 = min(max(b1, 0.0), 1.0)
                        b2 = min(max(b2, 0.0), 1.0 - b1)
                    else:
                        sq = math.sqrt(ur)
                        b1 = 1.0 - sq
                        b2 = u2 * sq
                    y0 = m_v0[tri, 0] + b1 * m_e1[tri, 0] + b2 * m_e2[tri, 0]
                    y1 = m_v0[tri, 1] + b1 * m_e1[tri, 1] + b2 * m_e2[tri, 1]
                    y2 = m_v0[tri, 2] + b1 * m_e1[tri, 2] + b2 * m_e2[tri, 2]
                    ny0, ny1, ny2 = m_ng[tri, 0], m_ng[tri, 1], m_ng[tri, 2]
                    msides = m_side[tri]
                    bb0 = abs(1.0 - b1 - b2)
                    ab1, ab2 = abs(b1), abs(b2)
                    far = 0.0
                    gap_err = 0.0
                    plane = 0.0
                    yv = (y0, y1, y2)
                    nyv = (ny0, ny1, ny2)
                    pv = (p0, p1, p2)
                    for c in range(3):
                        c0 = m_v0[tri, c]
                        c1 = c0 + m_e1[tri, c]
                        c2 = c0 + m_e2[tri, c]
                        interp = G64 * (bb0 * abs(c0) + ab1 * abs(c1) + ab2 * abs(c2))
                        t32_ = (bb0 * m_round32[tri, 0, c] + ab1 * m_round32[tri, 1, c]
                                + ab2 * m_round32[tri, 2, c])
                        err = interp + t32_ + _ulp32(yv[c])
                        gap_err += abs(nyv[c]) * err
                        rmax = max(max(abs(c0 - pv[c]), abs(c1 - pv[c])), abs(c2 - pv[c]))
                        plane += abs(nyv[c]) * rmax
                    # norms of the corners seen from p (rayoffset.py, note 3)
                    d0 = math.sqrt((m_v0[tri, 0] - p0) ** 2 + (m_v0[tri, 1] - p1) ** 2
                                   + (m_v0[tri, 2] - p2) ** 2)
                    q0 = m_v0[tri, 0] + m_e1[tri, 0] - p0
                    q1 = m_v0[tri, 1] + m_e1[tri, 1] - p1
                    q2 = m_v0[tri, 2] + m_e1[tri, 2] - p2
                    d1 = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
                    q0 = m_v0[tri, 0] + m_e2[tri, 0] - p0
                    q1 = m_v0[tri, 1] + m_e2[tri, 1] - p1
                    q2 = m_v0[tri, 2] + m_e2[tri, 2] - p2
                    d2_ = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
                    far = max(max(d0, d1), d2_)
                    gap = gap_err + G32_PLANE * plane + m_tilt32[tri] * far
                    inv_pdf_a = m_area[tri] / tpmf
                    la0 = m_L[tri, 0] * inv_pdf_a
                    la1 = m_L[tri, 1] * inv_pdf_a
                    la2 = m_L[tri, 2] * inv_pdf_a
                else:  # area light
                    ny0, ny1, ny2 = q[DIR], q[DIR + 1], q[DIR + 2]
                    if q[SPREAD_RECT] != 0.0:
                        r0, r1, r2 = p0 - q[POS], p1 - q[POS + 1], p2 - q[POS + 2]
                        height = r0 * q[DIR] + r1 * q[DIR + 1] + r2 * q[DIR + 2]
                        reach = max(height, 0.0) * q[TAN_H]
                        pu = r0 * q[U] + r1 * q[U + 1] + r2 * q[U + 2]
                        pv_ = r0 * q[V] + r1 * q[V + 1] + r2 * q[V + 2]
                        hx, hy = q[SIZE_X] / 2, q[SIZE_Y] / 2
                        x0, x1 = max(pu - reach, -hx), min(pu + reach, hx)
                        yl0, yl1 = max(pv_ - reach, -hy), min(pv_ + reach, hy)
                        wx, wy = max(x1 - x0, 0.0), max(yl1 - yl0, 0.0)
                        x = x0 + u1 * wx
                        yy = yl0 + u2 * wy
                        y0 = q[POS] + x * q[U] + yy * q[V]
                        y1 = q[POS + 1] + x * q[U + 1] + yy * q[V + 1]
                        y2 = q[POS + 2] + x * q[U + 2] + yy * q[V + 2]
                        ar = wx * wy
                        la0, la1, la2 = q[RGB] * ar, q[RGB + 1] * ar, q[RGB + 2] * ar
                        inv_pdf_a = ar
                    else:
                        if q[IS_DISK] == 0.0:
                            # A rectangle: a direction uniform in its solid angle where
                            # that is large enough (lights/area.py).
                            ex0, ex1, ex2 = (q[DU] * q[SIZE_X], q[DU + 1] * q[SIZE_X],
                                             q[DU + 2] * q[SIZE_X])
                            ey0, ey1, ey2 = (q[DV] * q[SIZE_Y], q[DV + 1] * q[SIZE_Y],
                                             q[DV + 2] * q[SIZE_Y])
                            rect_omega, y0, y1, y2 = spherical_rectangle(
                                p0, p1, p2, q[POS] - 0.5 * (ex0 + ey0),
                                q[POS + 1] - 0.5 * (ex1 + ey1), q[POS + 2] - 0.5 * (ex2 + ey2),
                                ex0, ex1, ex2, ey0, ey1, ey2, u1, u2, True)
                            solid_rect = rect_omega >= MIN_SPHERICAL_SOLID_ANGLE
                        if not solid_rect:
                            if q[IS_DISK] != 0.0:
                                x, yy = _concentric_disk(u1, u2)
                                x, yy = x * q[SIZE_X] / 2, yy * q[SIZE_Y] / 2
                            else:
                                x, yy = (u1 - 0.5) * q[SIZE_X], (u2 - 0.5) * q[SIZE_Y]
                            y0 = q[POS] + x * q[DU] + yy * q[DV]
                            y1 = q[POS + 1] + x * q[DU + 1] + yy * q[DV + 1]
                            y2 = q[POS + 2] + x * q[DU + 2] + yy * q[DV + 2]
                        la0 = q[RGB] * q[AREA_]
                        la1 = q[RGB + 1] * q[AREA_]
                        la2 = q[RGB + 2] * q[AREA_]
                        inv_pdf_a = q[AREA_]
                    gap = (abs(q[DIR]) * (G64 * (abs(q[POS]) + abs(y0 - q[POS])) + _ulp32(y0))
                           + abs(q[DIR + 1]) * (G64 * (abs(q[POS + 1]) + abs(y1 - q[POS + 1]))
                                                + _ulp32(y1))
                           + abs(q[DIR + 2]) * (G64 * (abs(q[POS + 2]) + abs(y2 - q[POS + 2]))
                                                + _ulp32(y2)))
                v0_, v1_, v2_ = y0 - p0, y1 - p1, y2 - p2
                dist = math.sqrt(v0_ * v0_ + v1_ * v1_ + v2_ * v2_)
                ds = max(dist, 1e-300)
                w0, w1, w2 = v0_ / ds, v1_ / ds, v2_ / ds
                cr = _npmax(w0 * cs0 + w1 * cs1 + w2 * cs2, 0.0) * (
                    1.0 if w0 * g0 + w1 * g1 + w2 * g2 > 0 else 0.0)
                cl = (-w0) * ny0 + (-w1) * ny1 + (-w2) * ny2
                if two_sided and msides != 3:
                    # Emission Sampling Front / Back: the other side's light is left to
                    # the rays that meet it (MeshLight.unsampled_side).
                    if msides == 0 or (cl > 0.0) != (msides == 1):
                        continue
                cl = abs(cl) if two_sided else _npmax(cl, 0.0)
                md = 16.0 * (_ulp32(max(max(abs(p0), abs(p1)), abs(p2)))
                             + _ulp32(max(max(abs(y0), abs(y1)), abs(y2))))
                d2 = max(dist * dist, md * md)
                f = cr * cl / d2
                e0, e1, e2 = la0 * f, la1 * f, la2 * f
                lp = d2 / max(cl * inv_pdf_a, 1e-300)
                if solid_rect:
                    # By solid angle: L cos / (1 / omega) on the emitting side, pdf
                    # 1 / omega.
                    f = cr * rect_omega * (1.0 if cl > 0.0 else 0.0)
                    e0, e1, e2 = q[RGB] * f, q[RGB + 1] * f, q[RGB + 2] * f
                    lp = 1.0 / rect_omega
                if solid:
                    # By solid angle: L cos / (pmf / omega), pdf pmf / omega.
                    f = cr * omega / tpmf
                    e0, e1, e2 = m_L[tri, 0] * f, m_L[tri, 1] * f, m_L[tri, 2] * f
                    lp = tpmf / omega
                if code == C_AREA and q[SPREAD_ON] != 0.0:
                    at = _spread_attenuation((-w0) * q[DIR] + (-w1) * q[DIR + 1]
                                             + (-w2) * q[DIR + 2], q)
                    e0, e1, e2 = e0 * at, e1 * at, e2 * at
            if has_shade and shade_off[h] > 0 and not raised:
                sh = _shift_cos_in(w0 * s0 + w1 * s1 + w2 * s2, shade_off[h])
                e0, e1, e2 = e0 * sh, e1 * sh, e2 * sh
            if pmf != 1.0:
                e0, e1, e2 = e0 / pmf, e1 / pmf, e2 / pmf
            bd = 1.0
            m0, m1, m2 = nsm[h, 0], nsm[h, 1], nsm[h, 2]
            if raised:
                # The world's samples carry cos(wi, ns) (sampled round ns), the other
                # lights' the gate's: divided out, each lobe takes its own cosine.
                if code == C_WORLD:
                    cc = w0 * s0 + w1 * s1 + w2 * s2
                else:
                    cc = w0 * cs0 + w1 * cs1 + w2 * cs2
                if not cc > 0.0:
                    continue
                e0, e1, e2 = e0 / cc, e1 / cc, e2 / cc
                # Cycles' bsdf_eval per closure: the diffuse lobe on ns (light above ns,
                # bump shadowing against the smooth normal), the glossy lobes on the
                # raised normal (light above it; light from below the smooth surface
                # refused: bump_shadowing_term with sc->N the raised normal).
                cn = w0 * s0 + w1 * s1 + w2 * s2
                rn0, rn1, rn2 = gn[h, 0], gn[h, 1], gn[h, 2]
                dpass, dterm = False, 0.0
                if cn > 0.0:  # (the side test and the diffuse factor: one evaluation)
                    dside, dterm = bump_shadowing_terms(m0, m1, m2, s0, s1, s2, w0, w1, w2)
                    dpass = dside != 0.0
                gpass = (w0 * rn0 + w1 * rn1 + w2 * rn2 > 0.0
                         and bump_shadowing_term(m0, m1, m2, rn0, rn1, rn2, w0, w1, w2,
                                                 False) != 0.0)
                if not (dpass or gpass):
                    continue
                bd = 0.0
                if dpass:
                    bd = cn * dterm
                    if has_shade and shade_off[h] > 0:
                        bd = bd * _shift_cos_in(cn, shade_off[h])
                if not gpass:
                    bd = -1.0 - bd
            elif m0 != s0 or m1 != s1 or m2 != s2:
                # A bent normal: no light from below the smooth surface for any lobe,
                # the diffuse lobe dimmed towards grazing light (Cycles' bsdf_eval).
                side, bd = bump_shadowing_terms(m0, m1, m2, s0, s1, s2, w0, w1, w2)
                if side == 0.0:
                    continue
            if not ((e0 > 0 or e1 > 0 or e2 > 0) and e0 == e0 and e1 == e1 and e2 == e2):
                continue
            j = m_all
            m_all += 1
            contrib[j, 0], contrib[j, 1], contrib[j, 2] = e0, e1, e2
            if want_dir:
                wdir[j, 0], wdir[j, 1], wdir[j, 2] = w0, w1, w2
            if chosen and lp != np.inf:
                # Picked by the tree: a light with a size takes MIS with the lobes'
                # continuation, its pdf times the choice's probability at this point and
                # shading normal (as the continuation computes it: integrator._mis_weight,
                # _mesh_mis_weight; Cycles' light_tree_pdf, pbrt-v4's
                # BVHLightSampler::PMF); a constant-colour world is left to the
                # continuation (-1), as without the tree (integrator.light_modes).
                lp = -1.0 if (code == C_WORLD and q[ENV_ON] == 0.0) else lp * pmf
            if want_dir:
                lpdf[j] = lp
            if want_bump:
                bump[j] = bd
            row[j] = i
            kidx[j] = k
            if not trace:
                ray[j] = -1
                continue
            ray[j] = m_rays
            # Shadow-ray origin: lifted to the smooth surface at
            # the terminator, then off the facet along ng.
            h0, h1, h2 = ng[h, 0], ng[h, 1], ng[h, 2]
            o0, o1, o2 = p0, p1, p2
            if has_terminator and cutoff[h] > 0:
                amt = _terminator_amount(cutoff[h], s0 * w0 + s1 * w1 + s2 * w2,
                                         h0 * w0 + h1 * w1 + h2 * w2)
                if amt > 0:
                    o0 = o0 + lift[h, 0] * amt
                    o1 = o1 + lift[h, 1] * amt
                    o2 = o2 + lift[h, 2] * amt
            off = offset[h]
            o0, o1, o2 = o0 + off * h0, o1 + off * h1, o2 + off * h2
            if not finite:
                d0, d1, d2 = w0, w1, w2
                tmax = np.inf
            else:
                v0_, v1_, v2_ = y0 - o0, y1 - o1, y2 - o2
                dist = math.sqrt(v0_ * v0_ + v1_ * v1_ + v2_ * v2_)
                slack = G32_T * dist + _ulp32(dist)
                if surface:
                    gg = slack + gap
                    side = 1.0 if (o0 - y0) * ny0 + (o1 - y1) * ny1 + (o2 - y2) * ny2 >= 0.0 else -1.0
                    sg = side * gg
                    e_0, e_1, e_2 = y0 + sg * ny0, y1 + sg * ny1, y2 + sg * ny2
                    v0_, v1_, v2_ = e_0 - o0, e_1 - o1, e_2 - o2
                    dist = math.sqrt(v0_ * v0_ + v1_ * v1_ + v2_ * v2_)
                    tmax = dist
                else:
                    tmax = max(dist - slack, 0.0)
                ds = max(dist, 1e-300)
                d0, d1, d2 = v0_ / ds, v1_ / ds, v2_ / ds
            o32[m_rays, 0], o32[m_rays, 1], o32[m_rays, 2] = o0, o1, o2
            d32[m_rays, 0], d32[m_rays, 1], d32[m_rays, 2] = d0, d1, d2
            t = np.float32(tmax)
            if t != t:
                t = np.float32(0.0)
            elif t > F32_MAX:
                t = np.float32(F32_MAX)
            t32[m_rays] = t
            m_rays += 1
    return m_all, m_rays


# accumulate_bsdf's cut bits: a shadow ray's light is past the Light Paths limits for the
# diffuse f and sheen (CUT_DIFFUSE) or for the other rough reflective lobes (CUT_GLOSSY).
CUT_DIFFUSE, CUT_GLOSSY = 1, 2
NO_CUT = np.zeros(0, np.int64)


@kernel
def accumulate(E, contrib, row, kidx, ray, ksamples, blocked, m_all, bump):
    """E[row] += contrib * bump * visible / samples of its light, entry by entry (sample
    order): the irradiance the diffuse lobe receives. bump (0,): 1 for every entry."""
    has_bump = bump.shape[0] > 0
    for j in range(m_all):
        r = ray[j]
        # (x 1.0 where no bump term was written: the same bits as multiplying by a 1 row)
        vis = (1.0 if r < 0 or not blocked[r] else 0.0) * (bump[j] if has_bump else 1.0)
        s = ksamples[kidx[j]]
        i = row[j]
        E[i, 0] = E[i, 0] + contrib[j, 0] * vis / s
        E[i, 1] = E[i, 1] + contrib[j, 1] * vis / s
        E[i, 2] = E[i, 2] + contrib[j, 2] * vis / s


@kernel
def accumulate_bsdf(L, contrib, row, kidx, ray, ksamples, blocked, m_all, wdir, lpdf, kmode,
                    fd, prm, ns, wo, sel, bump, hrow, cut):
    """Radiance instead of irradiance: L[row] += contrib x f x visible / samples, entry by
    entry, where f = fd[row] (the diffuse lobe's f = albedo / pi) plus the rough reflective
    lobes' f(wo, wi) (engine/closures/principled.py, packed per hit in prm; ns, wo (N,3)),
    by the light's kmode[k]: 1 = a delta light (a point, spot or sun without size, which
    no sampled direction can hit): full weight; 2 = a light the lobes' sampled continuation
    also finds (engine/integrator.py): weighted by the power heuristic against the lobes'
    sampling pdf (principled.bsdf_pdf with the continuation's lobe-choice probabilities
    sel (N, N_LOBES)), lpdf the light sample's solid-angle pdf, ksamples its sample count;
    0 = the glossy part is left to the continuation; 3 = a light the light tree picked per
    hit: 1 for a light without size (lpdf inf), 2 for a light with a size (lpdf > 0, the
    choice's probability included), 0 for a constant-colour world (lpdf -1). contrib
    already holds cos(wi) (with the shading offset), so the glossy term is eval / cos(wi);
    bump (j,) dims the diffuse f alone (Cycles' bump shadowing term; (0,): 1 everywhere).
    hrow (n,) int64: entry row i's hit is row hrow[i] of prm, ns, wo and sel (fd and L
    are per shaded row i), as sample_lights' hrow; (0,): the same rows.
    cut (R,) int64 per traced ray: the lobes whose light it carries past the Light Paths
    limits (flat glass passages beyond their caps, direct_light): CUT_DIFFUSE the diffuse
    f and sheen (Cycles counts a sheen bounce as diffuse), CUT_GLOSSY the other rough
    reflective lobes; (0,): none.
    A hit with a raised glossy normal (prm's P_GN columns not zero) has entries as
    sample_lights writes them with its gn: contrib without a cosine, bump the diffuse
    lobe's cosine x bump term (-1 - it: the glossy lobes get none of the light), and its
    lobes are evaluated wherever wi lies above their own normal (eval_reflection's
    values carry their cosine)."""
    has_bump = bump.shape[0] > 0
    indexed = hrow.shape[0] > 0
    has_cut = cut.shape[0] > 0
    for j in range(m_all):
        r = ray[j]
        if r >= 0 and blocked[r]:
            continue
        k = kidx[j]
        s = ksamples[k]
        i = row[j]
        h = hrow[i] if indexed else i
        bd = bump[j] if has_bump else 1.0
        raised = (prm[h, pr.P_GN] != 0.0 or prm[h, pr.P_GN + 1] != 0.0
                  or prm[h, pr.P_GN + 2] != 0.0)
        glossy_lit = True
        if raised and bd < 0.0:
            bd = -1.0 - bd
            glossy_lit = False
        f0, f1, f2 = fd[i, 0] * bd, fd[i, 1] * bd, fd[i, 2] * bd
        kc = cut[r] if has_cut and r >= 0 else 0
        if kc & CUT_DIFFUSE:
            f0 = f1 = f2 = 0.0
        mode = kmode[k]
        if mode == 3:
            # A light the tree picked for this hit: a delta light (lpdf inf) in full, a
            # light with a size (lpdf > 0: its pdf x the tree's choice) by MIS, a
            # constant-colour world left to the continuation (integrator.light_modes).
            mode = 1 if lpdf[j] == np.inf else (2 if lpdf[j] > 0.0 else 0)
        if mode != 0 and glossy_lit:
            n0, n1, n2 = ns[h, 0], ns[h, 1], ns[h, 2]
            ix, iy, iz = pr.frame_local(n0, n1, n2, wdir[j, 0], wdir[j, 1], wdir[j, 2])
            if iz > 0.0 or raised:
                ox, oy, oz = pr.frame_local(n0, n1, n2, wo[h, 0], wo[h, 1], wo[h, 2])
                if kc == 0:
                    g0, g1, g2 = pr.eval_reflection(prm, h, ox, oy, oz, ix, iy, iz)
                else:
                    # Past a cap: only the lobes whose bounce kind is within it.
                    g0, g1, g2, s0, s1, s2 = pr.eval_reflection_parts(prm, h, ox, oy, oz, ix,
                                                                      iy, iz)
                    if kc & CUT_GLOSSY:
                        g0 = g1 = g2 = 0.0
                    if not kc & CUT_DIFFUSE:
                        g0, g1, g2 = g0 + s0, g1 + s1, g2 + s2
                mis = 1.0
                if mode == 2:
                    pb = pr.bsdf_pdf(prm, sel, h, ox, oy, oz, ix, iy, iz)
                    pl = s * lpdf[j]
                    mis = pl * pl / (pl * pl + pb * pb) if pl > 0.0 else 0.0
                # (contrib holds cos(wi, ns), or for a raised hit no cosine)
                cdiv = 1.0 if raised else iz
                f0 += g0 / cdiv * mis
                f1 += g1 / cdiv * mis
                f2 += g2 / cdiv * mis
        L[i, 0] = L[i, 0] + contrib[j, 0] * f0 / s
        L[i, 1] = L[i, 1] + contrib[j, 1] * f1 / s
        L[i, 2] = L[i, 2] + contrib[j, 2] * f2 / s


@kernel
def raised_glossy_normals(prm, ns, gn):
    """gn (N,3) <- the glossy lobes' raised normal in world space of each hit whose
    closure set-up raised it (prm's P_GN columns: principled.glossy_normals, in the
    frame of the shading normal ns (N,3)); a zero row where none is raised. Returns how
    many are raised."""
    m = 0
    for i in range(ns.shape[0]):
        if i >= prm.shape[0]:
            gn[i, 0] = gn[i, 1] = gn[i, 2] = 0.0
            continue
        l0, l1, l2 = prm[i, pr.P_GN], prm[i, pr.P_GN + 1], prm[i, pr.P_GN + 2]
        if l0 == 0.0 and l1 == 0.0 and l2 == 0.0:
            gn[i, 0] = gn[i, 1] = gn[i, 2] = 0.0
            continue
        gn[i, 0], gn[i, 1], gn[i, 2] = pr.frame_world(ns[i, 0], ns[i, 1], ns[i, 2], l0, l1, l2)
        m += 1
    return m


# sample_lights' optional arrays, empty: no per-hit row to read, no entry field to write.
NO_ROWS = np.zeros(0)
NO_ROWS3 = np.zeros((0, 3))
NO_HROWS = np.zeros(0, np.int64)  # hrow: the per-hit arrays are the hits themselves


# Entries (hits x light samples) per kernel call: bounds the compacted arrays' memory
# (about 70 bytes an entry) however many light samples a hit takes.
MAX_ENTRIES = 1 << 20


def _row_ready(u):
    """Whether a sample's numbers (N,) or None can be handed to sample_lights as a (1, N)
    view (C-contiguous, writable float64: the kernel's compiled signature)."""
    return u is None or (isinstance(u, np.ndarray) and u.dtype == np.float64 and u.ndim == 1
                         and u.flags.c_contiguous and u.flags.writeable)


class DirectLightBuffers:
    """The arrays one thread reuses between direct_light calls, grown as needed: the
    compacted entries (ensure), the per-hit sums (sums) and the samples' random numbers
    stacked (numbers). Fresh arrays of this size each call cost more in first-touch page faults
    than the kernels' own work (docs/performance.md, "Ninth slice"). The sums a call
    returns are valid until the next call with the same buffers."""

    def __init__(self):
        self.size = -1  # (-1: a first call for 0 rows still makes its empty arrays)
        self.n_hits = 0
        self.n_numbers = 0

    def ensure(self, m):
        if m > self.size:
            self.size = m
            self.contrib = np.empty((m, 3))
            self.row = np.empty(m, np.int64)
            self.kidx = np.empty(m, np.int64)
            self.ray = np.empty(m, np.int64)
            self.o32 = np.empty((m, 3), np.float32)
            self.d32 = np.empty((m, 3), np.float32)
            self.t32 = np.empty(m, np.float32)
            self.blocked = np.empty(m, np.bool_)
            self.wdir = np.empty((m, 3))
            self.lpdf = np.empty(m)
            self.bump = np.empty(m)
        return self

    def sums(self, n):
        """(n, 3) float64 zeros: a call's irradiance or radiance sums."""
        if n > self.n_hits:
            self.n_hits = n
            self.E = np.empty((n, 3))
        E = self.E[:n]
        E.fill(0.0)
        return E

    def numbers(self, K, n, third):
        """(U1, U2, SEL): unwritten (K, n) float64 arrays for K samples' random numbers
        (SEL (K, 1) when no sample takes a third number: sample_lights reads none)."""
        m = K * n
        if m > self.n_numbers:
            self.n_numbers = m
            self.u = np.empty((3, m))
        return (self.u[0, :m].reshape(K, n), self.u[1, :m].reshape(K, n),
                self.u[2, :m].reshape(K, n) if third else np.zeros((K, 1)))


def _passage_blur(buf, m_all, m_rays, ns, rows, fd, filter_glossy):
    """(m_rays,) the Filter Glossy alpha of each traced shadow ray's window glass
    (ShadowTransmittance's blur): filterglossy.blur_alpha(filter_glossy, cos / pi) with
    cos the ray's cosine to its hit's normal ns (rows: the hits' rows of ns; None: the
    hits themselves), Cycles' min_ray_pdf after a Lambert bounce towards the light; 0
    where the hit has no diffuse lobe (fd (n,3), per shaded hit, zero; None: every hit
    has one)."""
    from .filterglossy import blur_alphas
    r = buf.ray[:m_all]
    on = r >= 0
    shaded = buf.row[:m_all][on]
    hits = shaded if rows is None else np.asarray(rows, np.int64)[shaded]
    pdf = np.full(m_rays, np.inf)
    n = np.take(ns, hits, axis=0)
    d = np.asarray(buf.d32[:m_rays], np.float64)[r[on]]
    c = (n * d).sum(axis=1) / np.maximum(np.linalg.norm(d, axis=1), 1e-300)
    p = np.maximum(c, 0.0) / math.pi
    if fd is not None:
        p = np.where(np.take(fd, shaded, axis=0).max(axis=1) > 0.0, p, np.inf)
    pdf[r[on]] = p
    return blur_alphas(filter_glossy, pdf)


def direct_light(packed, hit_arrays, samples, accel, shadow_cls, n, shadow=None, tree=None,
                 bsdf=None, buffers=None, rows=None, transmission=None, passages=None,
                 light_cut=None, medium_sigma=None, world_sigma=None, link=None,
                 glossy=None, used=None, filter_glossy=0.0):
    """Irradiance (N,3) at N hits from the light samples `samples`: a list of (light
    index, traced?, light's sample count, u1 (N,), u2 (N,), third choice (N,) or None),
    in the order they must be summed; light index -1: the light tree `tree` (tree_f,
    tree_i, inf_idx, inf_f, l_trace: lights/selection.py) picks one light per hit with
    the third choice. packed = packing.pack_lights(lights); hit_arrays =
    (p, ns, gate, ng, offset, shade_off, cutoff, lift, nsm) as sample_lights takes them.
    shadow: an engine.shadowtransmittance.ShadowTransmittance (transparent shadows) or
    None (every surface blocks shadow rays).
    bsdf = (fd (N,3), prm (N,P), wo (N,3), mode (L,) int per light, sel (N, N_LOBES)):
    outgoing radiance instead, weighted by the BSDF (accumulate_bsdf; mode 3 with the tree).
    transmission = (prm (N,P), ns (N,3) the normals on wo's side, wo (N,3), mode (L,),
    sel (N, N_LOBES)): radiance through rough glass instead (principled
    .accumulate_transmission; hit_arrays then hold the flipped normals: the lights are
    sampled on the far side; engine/glasslight.py). At most one of bsdf, transmission.
    buffers: the calling thread's DirectLightBuffers (E is then its sums, valid until
    the next call with them; None: fresh arrays).
    rows (n,) int64: the n hits are these rows of hit_arrays and of bsdf's prm, wo and sel
    (a batch's shaded rows, read in place; the numbers, fd and E count the n hits);
    None: hit_arrays are the n hits.
    passages (n,) int64: the most flat glass passages a shadow ray from each hit may
    cross (the bounce limits, chaincounts.flat_passages; ShadowTransmittance); with bsdf
    also (n,2): the caps of the diffuse f and sheen (column 0) and of the other rough
    reflective lobes (column 1), which Cycles counts against different limits (a ray
    past one cap carries its light to the other lobe alone: accumulate_bsdf's cut);
    None: no cap.
    medium_sigma (n,3): the extinction (1/m) of the medium each hit is in (engine/media.py;
    0: none): a traced shadow ray that meets no surface on its way lies wholly in it and
    keeps exp(-sigma_t length) (a floor inside a fog cube lit by a lamp inside it; rays
    that cross surfaces take ShadowTransmittance's back-face rule); None: no medium.
    world_sigma (n,3): the world volume's extinction at the hits in it (engine/
    worldmedium.py; 0 elsewhere): a shadow ray that crossed transparent surfaces keeps
    exp(-sigma_t length) of it too (over its whole length: the part inside an object's
    medium on its way is counted twice, a thin world fog's small excess); None: none.
    light_cut (L,) int64, with bsdf: per light the lobes its samples may not light
    (CUT_DIFFUSE, CUT_GLOSSY as accumulate_bsdf's cut: Cycles' _shader_bsdf_exclude by
    the light's ray visibility); a light with a cut must be traced (its samples' traced
    flag True) and sampled by light index (not by the tree); None: every lobe.
    link = (links, recv): Light and Shadow Linking (engine/lightlinking.py LightLinks,
    recv (n,) int64 each hit's receiver set, -1: none): a hit takes no light from the
    lights its set is not linked to (their samples are zero, as Cycles' light_sample
    refuses them), and a light's shadow rays meet only its blockers (LightLinks.direct).
    None: every light lights every hit, every object blocks.
    glossy: None, or with bsdf (and no link) an (n,3) float64 array that receives the
    rough reflective lobes' part of the radiance, sheen aside (accumulate_bsdf again over
    the same entries with the diffuse f and the sheen's weight at 0: the light passes'
    Glossy Direct, engine/lightpasses.py).
    used (n,) int64: the transparent bounces each hit's camera path made before it
    (Cycles' transparent_bounce, which its shadow rays start from: they cross the
    shadow's max_hits minus that many; ShadowTransmittance's used); None: 0.
    filter_glossy: Cycles' Filter Glossy to emulate on window glass (0: none): a shadow
    ray from a hit with a diffuse lobe (every hit without bsdf; with bsdf where fd > 0;
    never with transmission) crossing a flat passage keeps blurredpassage.factor_lookup
    of it at the blur alpha of the Lambert pdf towards the light (ShadowTransmittance's
    blur; docs/compatibility.md "fgslab49").
    Returns (E or radiance, number of shadow rays traced)."""
    if link is not None and n and samples:
        links, recv = link
        return links.direct(direct_light, packed, hit_arrays, samples, accel, shadow_cls, n,
                            recv, shadow=shadow, tree=tree, bsdf=bsdf, buffers=buffers,
                            rows=rows, transmission=transmission, passages=passages,
                            light_cut=light_cut, medium_sigma=medium_sigma,
                            world_sigma=world_sigma, used=used, filter_glossy=filter_glossy)
    codes, params, mesh = packed
    hrow = NO_HROWS if rows is None else rows
    # No bent normal (nsm is ns): every bump term is 1, none is written or read.
    bent = hit_arrays[8] is not hit_arrays[1]
    if tree is None:
        tree = (*empty_tree(), np.ones(len(codes), np.bool_))
    if n == 0 or not samples:
        return np.zeros((n, 3)), 0
    buf = buffers or DirectLightBuffers()
    E = buf.sums(n)
    lobes = bsdf if transmission is None else transmission  # directions and pdfs wanted
    lobe_caps = passages is not None and np.ndim(passages) == 2
    if lobe_caps and bsdf is None:
        raise ValueError("direct_light: per-lobe passages (n,2) need bsdf")
    per_call = max(1, MAX_ENTRIES // n)
    # Hits whose glossy lobes work on a raised normal (Cycles' valid_reflection_N): their
    # light samples serve each lobe on its own side (sample_lights' gn).
    gn = NO_ROWS3
    if bsdf is not None:
        ns_all = hit_arrays[1]
        g = np.empty((len(ns_all), 3))
        if raised_glossy_normals(np.ascontiguousarray(bsdf[1], np.float64), ns_all, g) > 0:
            gn = g
            bent = True  # (the entries' bump column carries the lobes' split)
    rays = 0
    zeros = None
    glossy_bsdf = None  # (fd, prm) of the glossy part, made when first needed
    for a in range(0, len(samples), per_call):
        group = samples[a:a + per_call]
        K = len(group)
        klight = np.array([s[0] for s in group], np.int64)
        ktrace = np.array([s[1] for s in group], np.bool_)
        ksamples = np.array([float(s[2]) for s in group])
        third = any(s[5] is not None for s in group)
        if K == 1 and all(_row_ready(u) for u in group[0][3:6]):
            # One sample (one light, or the light tree's one pick): its numbers as they
            # are, no copy.
            U1, U2 = group[0][3][None], group[0][4][None]
            SEL = group[0][5][None] if third else np.zeros((1, 1))
        else:
            U1, U2, SEL = buf.numbers(K, n, third)
            np.stack([s[3] for s in group], out=U1)
            np.stack([s[4] for s in group], out=U2)
            if third:
                if zeros is None:
                    zeros = np.zeros(n)
                np.stack([zeros if s[5] is None else s[5] for s in group], out=SEL)
        buf.ensure(K * n)
        bump = buf.bump if bent else NO_ROWS
        m_all, m_rays = sample_lights(*hit_arrays, codes, params, *mesh, *tree, klight,
                                      ktrace, U1, U2, SEL, buf.contrib, buf.row, buf.kidx,
                                      buf.ray, buf.o32, buf.d32, buf.t32,
                                      NO_ROWS3 if lobes is None else buf.wdir,
                                      NO_ROWS if lobes is None else buf.lpdf, bump, hrow,
                                      gn)
        blocked = buf.blocked[:m_rays]
        cut = NO_CUT
        if m_rays:
            # Embree overwrites the distances: keep them for the transparent re-trace.
            t_keep = (buf.t32[:m_rays].copy() if shadow is not None or medium_sigma is not None
                      else None)
            accel.occluded_into(buf.o32[:m_rays], buf.d32[:m_rays], buf.t32[:m_rays], blocked,
                                cls=shadow_cls)
            if medium_sigma is not None:
                _dim_in_medium(buf, m_all, blocked, t_keep, medium_sigma)
                if getattr(shadow, "hetero", None) is not None:
                    # (a density texture's correction on those rays: heterogeneous.py)
                    _dim_in_medium(buf, m_all, blocked, t_keep, medium_sigma, shadow.hetero)
            if shadow is not None:
                # (the rays the first query found blocked: those crossing surfaces)
                was_blocked = blocked.copy() if world_sigma is not None else None
                ray_cap = crossed = None
                if passages is not None:
                    # Each traced ray's cap, from its hit (entries j < m_all).
                    r = buf.ray[:m_all]
                    on = r >= 0
                    hits = buf.row[:m_all][on]
                    if lobe_caps:
                        # The two lobes' caps: the ray crosses up to the larger, and the
                        # passages it crossed tell which lobes keep its light.
                        cap2 = np.zeros((m_rays, 2), np.int64)
                        cap2[r[on]] = np.take(passages, hits, axis=0)
                        ray_cap = cap2.max(axis=1)
                        crossed = np.zeros(m_rays, np.int64)
                    else:
                        ray_cap = np.zeros(m_rays, np.int64)
                        ray_cap[r[on]] = np.take(passages, hits)
                ray_used = None
                if used is not None:
                    # Each traced ray's path's transparent bounces, from its hit.
                    r = buf.ray[:m_all]
                    on = r >= 0
                    ray_used = np.zeros(m_rays, np.int64)
                    ray_used[r[on]] = np.take(used, buf.row[:m_all][on])
                ray_blur = None
                if (filter_glossy > 0.0 and transmission is None and shadow.flat_on
                        and not shadow.shared):
                    ray_blur = _passage_blur(buf, m_all, m_rays, hit_arrays[1], rows,
                                             None if bsdf is None else bsdf[0],
                                             filter_glossy)
                shadow.pass_blocked(buf.o32[:m_rays], buf.d32[:m_rays], t_keep, blocked,
                                    buf.contrib, buf.ray, m_all, shadow_cls, ray_cap, crossed,
                                    ray_used, ray_blur)
                if was_blocked is not None:
                    _dim_in_medium(buf, m_all, ~(was_blocked & ~blocked), t_keep,
                                   world_sigma)
                if crossed is not None:
                    over = crossed[:, None] > cap2
                    if over.any():
                        cut = (over[:, 0] * CUT_DIFFUSE + over[:, 1] * CUT_GLOSSY).astype(
                            np.int64)
        if light_cut is not None and m_rays:
            # Each traced ray's light's excluded lobes, beside the passages' cuts.
            r = buf.ray[:m_all]
            on = r >= 0
            own = np.zeros(m_rays, np.int64)
            kl = klight[buf.kidx[:m_all][on]]
            own[r[on]] = np.where(kl >= 0, light_cut[np.maximum(kl, 0)], 0)  # -1: the tree
            cut = own if len(cut) == 0 else cut | own
        if transmission is not None:
            prm, ns, wo, mode, sel = transmission
            pr.accumulate_transmission(E, buf.contrib, buf.row, buf.kidx, buf.ray, ksamples,
                                       blocked, m_all, buf.wdir, buf.lpdf, mode[klight], prm,
                                       ns, wo, sel)
        elif bsdf is None:
            # (sample_lights wrote no directions or pdfs: NO_ROWS3, NO_ROWS)
            accumulate(E, buf.contrib, buf.row, buf.kidx, buf.ray, ksamples, blocked, m_all,
                       bump)
        else:
            fd, prm, wo, mode, sel = bsdf
            accumulate_bsdf(E, buf.contrib, buf.row, buf.kidx, buf.ray, ksamples, blocked,
                            m_all, buf.wdir, buf.lpdf, mode[klight], fd, prm, hit_arrays[1], wo,
                            sel, bump, hrow, cut)
            if glossy is not None:
                if glossy_bsdf is None:
                    # The diffuse f at 0 and the sheen's weight at 0 (its pdf, which the
                    # MIS weight reads, kept): the glossy lobes alone, every entry
                    # (an untraced one carries no cut).
                    prm_g = prm
                    if prm[:, pr.P_SHEEN_W:pr.P_SHEEN_W + 3].any():
                        prm_g = prm.copy()
                        prm_g[:, pr.P_SHEEN_W:pr.P_SHEEN_W + 3] = 0.0
                    glossy_bsdf = (np.zeros_like(fd), prm_g)
                accumulate_bsdf(glossy, buf.contrib, buf.row, buf.kidx, buf.ray, ksamples,
                                blocked, m_all, buf.wdir, buf.lpdf, mode[klight],
                                glossy_bsdf[0], glossy_bsdf[1], hit_arrays[1], wo, sel, bump,
                                hrow, cut)
        rays += m_rays
    return E, rays


def _dim_in_medium(buf, m_all, blocked, t_keep, medium_sigma, hetero=None):
    """The entries (j < m_all) whose shadow ray the OCCLUDED query found clear: x
    exp(-sigma_t length), sigma_t their hit's medium_sigma row (direct_light); with
    hetero (engine/heterogeneous.py HeterogeneousMedia) x its ratio-tracked correction
    of that factor instead (for media with a density texture; 1 for the others)."""
    r = buf.ray[:m_all]
    j = np.flatnonzero(r >= 0)
    rr = r[j]
    clear = ~blocked[rr]
    j, rr = j[clear], rr[clear]
    if not len(j):
        return
    sig = np.take(medium_sigma, buf.row[j], axis=0)
    on = sig.max(axis=1) > 0.0
    if not on.any():
        return
    j, rr, sig = j[on], rr[on], sig[on]
    if hetero is not None:
        u, back = np.unique(rr, return_inverse=True)
        c = hetero.correction(buf.o32[u], buf.d32[u], t_keep[u], salt=6)
        buf.contrib[j] *= c[back]
        return
    length = t_keep[rr].astype(np.float64) * np.linalg.norm(
        buf.d32[rr].astype(np.float64), axis=1)
    buf.contrib[j] *= np.exp(-sig * length[:, None])


@register_warm_up
def _warm_up():
    """Compile (or load) the kernels on a tiny batch of every light kind."""
    from .lights import AreaLight, MeshLight, PointLight, SpotLight, SunLight, WorldLight
    from .lights.packing import pack_lights
    base = dict(pos=np.zeros(3), dir=np.array([0.0, 0.0, -1.0]), u=np.array([1.0, 0, 0]),
                v=np.array([0, 1.0, 0]), du=np.array([1.0, 0, 0]), dv=np.array([0, 1.0, 0]),
                radius=0.1, size_x=1.0, size_y=1.0, area=1.0, spread=1.0, shape="RECTANGLE",
                spot_size=1.0, spot_blend=0.1, spot_frame=np.eye(3), intensity=np.ones(3),
                radiance=np.ones(3), irradiance=np.ones(3), cos_half_angle=0.99)
    one = np.ones((1, 3))
    mesh = MeshLight("m", v0=np.zeros((1, 3)), e1=np.array([[1.0, 0, 0]]),
                     e2=np.array([[0, 1.0, 0]]), tri_ng=np.array([[0, 0, 1.0]]), tri_L=one,
                     tri_area=np.array([0.5]), prob=np.ones(1), cdf=np.ones(1),
                     round32=np.zeros((1, 3, 3)), tilt32=np.zeros(1))
    lights = [cls("w", **base) for cls in (PointLight, SpotLight, AreaLight, SunLight,
                                           WorldLight)] + [mesh]
    packed = pack_lights(lights)
    p = np.array([[0.2, 0.1, -1.0]])
    nrm = np.array([[0.0, 0.0, 1.0]])
    hit = (p, nrm, nrm, nrm, np.zeros(1), np.full(1, 0.1), np.full(1, 0.1), np.zeros((1, 3)),
           np.array([[0.0, 0.6, 0.8]]))  # a bent normal: the bump shadowing path too
    u = np.full(1, 0.5)
    samples = [(li, True, 1, u, u, u if li == 5 else None) for li in range(len(lights))]

    class _NoOcclusion:
        def occluded_into(self, o32, d32, t32, blocked, cls=None):
            blocked[:] = False
            return blocked

    direct_light(packed, hit, samples, _NoOcclusion(), None, 1)
    from .geometry import closure_params
    from .scene import Material
    prm, _ = pr.setup_np(closure_params([Material("w", specular=1.0, roughness=0.5)]),
                         np.zeros(1, np.int64), np.full((1, 3), 0.5), np.ones(1),
                         np.ones(1, np.bool_))
    direct_light(packed, hit, samples, _NoOcclusion(), None, 1,
                 bsdf=(np.ones((1, 3)), prm, nrm, np.full(len(lights), 2, np.int64),
                       np.full((1, pr.N_LOBES), 0.2)))
    # A raised glossy normal (raised_glossy_normals, sample_lights' gn rows).
    prm = prm.copy()
    prm[0, pr.P_GN:pr.P_GN + 3] = (0.6, 0.0, 0.8)
    direct_light(packed, hit, samples, _NoOcclusion(), None, 1,
                 bsdf=(np.ones((1, 3)), prm, nrm, np.full(len(lights), 2, np.int64),
                       np.full((1, pr.N_LOBES), 0.2)))
    terminator_lift(np.zeros(1, np.int64), np.full((1, 2), 0.25), nrm, np.ones(1, np.bool_),
                    np.zeros(1, np.int32), np.full(1, 0.1, np.float32), mesh.v0, mesh.e1, mesh.e2,
                    # float32 corner normals, as Geometry.corner_normals holds them (a float64
                    # copy compiled a variant no render uses; the render then compiled its own)
                    np.repeat(nrm[:, None, :], 3, axis=1).astype(np.float32), np.zeros(1),
                    np.zeros((1, 3)), NO_HROWS)
