"""Principled v2 layering as Cycles builds it (intern/cycles/kernel/svm/closure.h), and the
Glossy / Glass / Refraction BSDF nodes in the same terms, as compiled kernels.

Per hit, `setup` turns a material (a row of MaterialTable.closure_params) and the view
cosine into lobes, top layer first, each attenuating the ones below it by its estimated
albedo (Cycles' closure_layering_weight):
    pass      (1 - alpha) x transparent tint (Transparent BSDF share and colour)
    transl    Lambertian diffuse transmission (Cycles' Translucent BSDF, bsdf_translucent:
              f = colour / pi on the far side): translucency x the translucent colour (or
              the base colour); every layer below keeps 1 - translucency
    sheen     Cycles' microfiber sheen (engine/closures/sheen.py), weight x tint
    coat      GGX, real dielectric Fresnel (coat IOR), energy-compensated; then the coat
              tint tints the layers below along the refracted path (tint^(1/cos_t))
    metal     GGX with F82-tint Fresnel on the base colour (Principled), or the colour as a
              constant reflectance (Glossy BSDF); lower layers keep 1 - metallic
    glass     GGX glass: Principled's Fresnel remap (f0 = F0(ior) x specular tint),
              transmission tinted sqrt(base colour) (Principled) or the colour (Glass BSDF);
              lower layers keep 1 - transmission
    spec      GGX dielectric specular layer: f0 = F0(ior) x 2 x specular IOR level, tinted
    diffuse   Lambert, base colour x what the layers above leave
Each lobe's final multiplier is weight x energy factor (ggx.energy_factor: 1 for plain GGX,
Cycles' compensation for Multiscatter GGX, Principled's default). `weights` receives each
lobe's estimated albedo (RGB) for the view direction: the lobe-choice probabilities of
both passes and the diffuse weight the photon maps are scaled by.

The packed per-hit row (columns below) is what the sampling and evaluation kernels read;
all directions are in the frame of the shading normal (frame_local / frame_world).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from . import ggx, sheen, tables
from .fresnel import (F0_from_ior, f82_Fss, f82_tint_B, fresnel_dielectric,
                      fresnel_dielectric_Fss, fresnel_f82, ior_from_F0, schlick_remap)

# Lobes in the weights array (the order of bsdf.LOBE_NAMES).
L_DIFFUSE, L_PASS, L_METAL, L_GLASS_R, L_GLASS_T, L_SPEC, L_COAT, L_SHEEN, L_TRANSL = range(9)
N_LOBES = 9

# Material parameter columns (MaterialTable.closure_params).
M_ALPHA, M_METALLIC, M_ROUGH, M_TRANS, M_IOR, M_SPEC, M_LEVEL = range(7)
M_STINT = 7            # 3: specular tint
M_COAT_W, M_COAT_ROUGH, M_COAT_IOR = 10, 11, 12
M_CTINT = 13           # 3: coat tint
M_MULTI = 16           # 1: Multiscatter GGX (energy compensation), 0: plain GGX
M_NODE = 17            # NODE_* below
M_GCOL = 18            # 3: Glossy BSDF colour (metal lobe's constant reflectance) ...
M_HAS_GCOL = 21        # ... when 1 (else the base colour)
M_SHEEN_W, M_SHEEN_ROUGH = 22, 23
M_SHEEN_TINT = 24      # 3
M_TTINT = 27           # 3: Transparent BSDF colour (the pass lobe transmits (1 - alpha) x it)
M_ADD = 30             # 1: closure weight - 1 (Add Shader sums closures: every BSDF lobe x
                       # (1 + M_ADD); 0 = weight 1, the usual case)
M_ANISO = 31          # 1: anisotropy: Principled 'Anisotropic' (0..1) or Glossy BSDF
                      # 'Anisotropy' (-0.99..0.99), by M_NODE (aniso_alphas)
M_AROT = 32           # 1: its rotation of the tangent about the normal, in turns
M_TL = 33             # 1: translucency, the Translucent BSDF's share of the surface
M_TLCOL = 34          # 3: the translucent colour ...
M_HAS_TLCOL = 37      # ... when 1 (else the base colour, texture applied)
N_MAT = 38
# NODE_REFRACTION: the glass lobe transmits only, without Fresnel (Cycles' Refraction BSDF,
# MicrofacetFresnel::NONE: transmittance = colour) and without energy compensation.
NODE_PRINCIPLED, NODE_GLOSSY, NODE_GLASS, NODE_REFRACTION = 0, 1, 2, 3

# Packed per-hit row.
P_SPEC_W, P_SPEC_F0, P_SPEC_ALPHA, P_SPEC_ETA = 0, 3, 6, 7
P_METAL_W, P_METAL_F0, P_METAL_B, P_METAL_ALPHA = 8, 11, 14, 17
P_GLASS_RW, P_GLASS_TW, P_GLASS_F0, P_GLASS_ALPHA, P_GLASS_ETA = 18, 21, 24, 27, 28
P_COAT_W, P_COAT_ALPHA, P_COAT_ETA = 29, 32, 33
P_SHEEN_W, P_SHEEN_A, P_SHEEN_B = 34, 37, 38
P_GN = 39  # 3: the glossy lobes' normal in the shading normal's frame (Cycles'
           # ensure_valid_specular_reflection: glossy_normals); 0, 0, 0: the
           # shading normal itself (setup's default)
P_AX, P_AY = 42, 43  # the metal and specular lobes' alpha_x, alpha_y (Cycles' anisotropic
                     # GGX; 0, 0: isotropic, the lobes' own alpha)
P_TAN = 44  # 2: their tangent T (alpha_x's axis) in the glossy normal's frame, unit,
            # in its tangent plane (set_tangents); 0, 0: none yet (the lobes then stay
            # isotropic at their own alpha)
P_TL_W = 46  # 3: the translucent lobe's colour weight (f = P_TL_W / pi on the far side)
N_PACK = 49


@kernel
def frame_local(n0, n1, n2, v0, v1, v2):
    """v in the (t, b, n) frame of sampling.to_world's basis for unit n."""
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    t0, t1, t2 = 1.0 + sign * n0 * n0 * a, sign * b, -sign * n0
    b0, b1, b2 = b, sign + n1 * n1 * a, -n1
    return (v0 * t0 + v1 * t1 + v2 * t2, v0 * b0 + v1 * b1 + v2 * b2,
            v0 * n0 + v1 * n1 + v2 * n2)


@kernel
def frame_world(n0, n1, n2, l0, l1, l2):
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    x = l0 * (1.0 + sign * n0 * n0 * a) + l1 * b + l2 * n0
    y = l0 * (sign * b) + l1 * (sign + n1 * n1 * a) + l2 * n1
    z = l0 * (-sign * n0) + l1 * (-n1) + l2 * n2
    return x, y, z


@kernel
def _compensation(multi, E, E_avg, Fss):
    """(energy factor, albedo darkening = factor x E) of one channel (1, 1 without
    Multiscatter GGX, where Cycles' albedo estimate still assumes a lossless lobe)."""
    if multi == 0.0:
        return 1.0, 1.0
    f = ggx.energy_factor(E, E_avg, Fss)
    return f, f * E


@kernel
def setup(mat, params, base, cos_o, front, hit_alpha, prm, weights):
    """Lobes of N hits, every lobe set up at the view cosine cos_o (N,): setup_views
    with the sheen's cosine equal to it (no hit's glossy normal raised, or the sheen
    read where the glossy lobes are)."""
    setup_views(mat, params, base, cos_o, cos_o, front, hit_alpha, prm, weights)


@kernel
def setup_views(mat, params, base, cos_o, cos_s, front, hit_alpha, prm, weights):
    """Lobes of N hits. mat (N,) material index, params (M, N_MAT) material columns,
    base (N,3) base colour (texture applied), cos_o (N,) = ns . wo (wo . N' where the
    glossy lobes' normal is raised: glossy_normals), cos_s (N,) = ns . wo the sheen's
    view cosine (Cycles sets the sheen up on the unraised N: bsdf_sheen_setup reads its
    tables at dot(N, wi), clamped to [0, 1]; sheen55), front (N,) bool: the
    ray arrived on the outside, hit_alpha (N,) the hit's alpha (the material's, or its
    alpha texture's value there). Writes prm (N, N_PACK) and weights (N, N_LOBES, 3).
    The material's columns are read in place (params[r, col], no row view a hit), and the
    glass layer's terms that depend on the material and side alone (glass_terms) are
    computed once for a run of hits of one material on one side: the same operations on
    the same values as per hit, so the same bits (tests/test_closures_glass_terms.py)."""
    g = np.empty((2, G_N))
    g_mat = np.full(2, -1, np.int64)
    for i in range(mat.shape[0]):
        r = mat[i]
        mu = min(max(cos_o[i], 0.0), 1.0)
        for c in range(N_PACK):
            prm[i, c] = 0.0
        for l in range(N_LOBES):
            for c in range(3):
                weights[i, l, c] = 0.0
        a = hit_alpha[i]
        # The BSDF lobes' share: alpha x the closure weight (Add Shader); the pass lobe
        # keeps 1 - alpha. x (1.0 + 0.0) is exact: weight 1 changes no bit.
        W0 = W1 = W2 = a * (1.0 + params[r, M_ADD])
        for c in range(3):
            weights[i, L_PASS, c] = (1.0 - a) * params[r, M_TTINT + c]
        rough = params[r, M_ROUGH]
        alpha = rough * rough
        multi = params[r, M_MULTI]
        node = params[r, M_NODE]
        # Anisotropic metal and specular layers (Cycles: alpha_x, alpha_y and the
        # tangent): their tables read at sqrt(sqrt(alpha_x alpha_y)), as Cycles'
        # microfacet_ggx_preserve_energy and bsdf_microfacet_estimate_albedo do; that is
        # the roughness itself unless a clamp to 1 cut alpha_x.
        ax = ay = alpha
        rough_g = rough
        if params[r, M_ANISO] != 0.0:
            ax, ay = aniso_alphas(node, params[r, M_ANISO], alpha)
            if ax != ay:
                rough_g = math.sqrt(math.sqrt(ax * ay))
        # The GGX albedo tables only where a metal or specular layer reads them (a
        # diffuse-only material skips both lookups; nothing else changes).
        E = E_avg = 0.0
        if params[r, M_METALLIC] > 0.0 or params[r, M_SPEC] > 0.0:
            E = tables.ggx_E(rough_g, mu)
            E_avg = tables.ggx_Eavg(rough_g)
        # --- translucent: diffuse transmission, a share of the whole surface beside the
        # layers below (a Mix of any surface and a Translucent BSDF, exactly) ---
        tl = params[r, M_TL]
        if tl > 0.0:
            Wt = (W0, W1, W2)
            for c in range(3):
                col = (params[r, M_TLCOL + c] if params[r, M_HAS_TLCOL] != 0.0
                       else base[i, c])
                # Lambert transmits all it does not absorb: the albedo is exact.
                wc = tl * Wt[c] * max(col, 0.0)
                prm[i, P_TL_W + c] = wc
                weights[i, L_TRANSL, c] = wc
            W0, W1, W2 = W0 * (1.0 - tl), W1 * (1.0 - tl), W2 * (1.0 - tl)
        # --- sheen (the top layer) ---
        shw = params[r, M_SHEEN_W]
        if shw > 0.0 and a > 0.0:
            mu_s = min(max(cos_s[i], 0.0), 1.0)
            la, lb, alb = sheen.sheen_params(params[r, M_SHEEN_ROUGH], mu_s)
            if alb > 0.0:
                top = 0.0
                Wsh = (W0, W1, W2)
                for c in range(3):
                    wc = shw * max(params[r, M_SHEEN_TINT + c], 0.0) * Wsh[c] * alb
                    prm[i, P_SHEEN_W + c] = wc
                    weights[i, L_SHEEN, c] = wc
                    if Wsh[c] > 0.0:
                        top = max(top, wc / Wsh[c])
                prm[i, P_SHEEN_A] = la
                prm[i, P_SHEEN_B] = lb
                keep = min(max(1.0 - top, 0.0), 1.0)
                W0, W1, W2 = W0 * keep, W1 * keep, W2 * keep
        # --- coat ---
        cw = params[r, M_COAT_W]
        if cw > 0.0 and a > 0.0:
            cr = params[r, M_COAT_ROUGH]
            cior = max(params[r, M_COAT_IOR], 1.0)
            Ec = tables.ggx_E(cr, mu)
            fac, dark = _compensation(1.0, Ec, tables.ggx_Eavg(cr), fresnel_dielectric_Fss(cior))
            f0 = F0_from_ior(cior)
            est = dark * (f0 + (1.0 - f0) * tables.schlick_ior_s(cr, mu, cior))
            Wc = (W0, W1, W2)
            for c in range(3):
                prm[i, P_COAT_W + c] = cw * Wc[c] * fac
                weights[i, L_COAT, c] = cw * Wc[c] * est
            prm[i, P_COAT_ALPHA] = cr * cr
            prm[i, P_COAT_ETA] = cior
            keep = min(max(1.0 - cw * est, 0.0), 1.0)
            W0, W1, W2 = W0 * keep, W1 * keep, W2 * keep
            t0, t1, t2 = params[r, M_CTINT], params[r, M_CTINT + 1], params[r, M_CTINT + 2]
            if t0 != 1.0 or t1 != 1.0 or t2 != 1.0:
                cos_t = math.sqrt(max(1.0 - (1.0 - mu * mu) / (cior * cior), 1e-12))
                depth = 1.0 / cos_t
                W0 *= 1.0 - cw + cw * max(t0, 0.0) ** depth
                W1 *= 1.0 - cw + cw * max(t1, 0.0) ** depth
                W2 *= 1.0 - cw + cw * max(t2, 0.0) ** depth
        # --- metal ---
        m = params[r, M_METALLIC]
        if m > 0.0:
            s5 = tables.schlick5_s(rough_g, mu)
            Wm = (W0, W1, W2)
            for c in range(3):
                if node == NODE_GLOSSY:  # constant reflectance = the colour (in the weight)
                    f0 = 1.0
                    b = 0.0
                    col = params[r, M_GCOL + c] if params[r, M_HAS_GCOL] != 0.0 else base[i, c]
                else:
                    f0 = min(max(base[i, c], 0.0), 1.0)
                    tint = min(max(params[r, M_STINT + c], 0.0), 1.0)
                    b = f82_tint_B(f0, tint) if tint != 1.0 else 0.0
                    col = 1.0
                Fss = col * f82_Fss(f0, b)
                fac, dark = _compensation(multi, E, E_avg, Fss)
                prm[i, P_METAL_W + c] = m * Wm[c] * col * fac
                prm[i, P_METAL_F0 + c] = f0
                prm[i, P_METAL_B + c] = b
                weights[i, L_METAL, c] = m * Wm[c] * col * dark * (f0 + (1.0 - f0) * s5)
            prm[i, P_METAL_ALPHA] = alpha
            if ax != ay:
                prm[i, P_AX], prm[i, P_AY] = ax, ay
            W0, W1, W2 = W0 * (1.0 - m), W1 * (1.0 - m), W2 * (1.0 - m)
        # --- transmission (glass) ---
        tr = params[r, M_TRANS]
        if tr > 0.0:
            # The terms that depend on the material and side alone (glass_terms), once a
            # run of hits of one material on one side (g: the last ones of each side).
            sd = 0 if front[i] else 1
            if g_mat[sd] != r:
                glass_terms(params[r], front[i], g[sd])
                g_mat[sd] = r
            eta = g[sd, G_ETA]
            Eg = _glass_E_at(g, sd, mu)
            Eg_avg = g[sd, G_EAVG]
            F0g = g[sd, G_F0G]
            # Reflectance estimate: Cycles' table from outside; from inside the real
            # Fresnel at the view angle (total internal reflection included), so that the
            # two estimates add up to the lobe's albedo on both sides (they steer the lobe
            # choice and the photons' Russian roulette).
            if eta >= 1.0:
                s_n = tables.lookup3_at(tables.SCHLICK_IOR_S, g[sd, G_SI], g[sd, G_SFX], mu,
                                        g[sd, G_SK], g[sd, G_SFZ])
            else:  # schlick_remap(mu, eta), its F0_from_ior(eta) from glass_terms
                f0e = g[sd, G_F0E]
                s_n = 1.0
                if f0e < 1.0:
                    s_n = min(max((fresnel_dielectric(mu, eta) - f0e) / (1.0 - f0e), 0.0), 1.0)
            Wg = (W0, W1, W2)
            for c in range(3):
                if node == NODE_REFRACTION:
                    # Transmission alone, colour x refraction: no reflection, no Fresnel
                    # (f0 < 0 marks it for _glass_F), no energy compensation.
                    tt = max(base[i, c], 0.0)
                    prm[i, P_GLASS_RW + c] = 0.0
                    prm[i, P_GLASS_TW + c] = tr * Wg[c] * tt
                    prm[i, P_GLASS_F0 + c] = -1.0
                    weights[i, L_GLASS_R, c] = 0.0
                    weights[i, L_GLASS_T, c] = tr * Wg[c] * tt
                    continue
                if node == NODE_GLASS:
                    rt = tt = max(base[i, c], 0.0)
                    f0 = F0g
                else:
                    rt = 1.0
                    tt = math.sqrt(min(max(base[i, c], 0.0), 1.0))
                    f0 = g[sd, G_F0 + c]
                fac, dark = _compensation(multi, Eg, Eg_avg, tt)
                prm[i, P_GLASS_RW + c] = tr * Wg[c] * rt * fac
                prm[i, P_GLASS_TW + c] = tr * Wg[c] * tt * fac
                prm[i, P_GLASS_F0 + c] = f0
                weights[i, L_GLASS_R, c] = tr * Wg[c] * rt * dark * (f0 + (1.0 - f0) * s_n)
                weights[i, L_GLASS_T, c] = tr * Wg[c] * tt * dark * (1.0 - (f0 + (1.0 - f0)
                                                                            * s_n))
            prm[i, P_GLASS_ALPHA] = alpha
            prm[i, P_GLASS_ETA] = eta
            W0, W1, W2 = W0 * (1.0 - tr), W1 * (1.0 - tr), W2 * (1.0 - tr)
        # --- dielectric specular layer ---
        sp = params[r, M_SPEC]
        f0s = 0.0
        eta_s = 1.0
        if sp > 0.0:  # (its IOR terms only where the layer has a weight)
            ior = max(params[r, M_IOR], 1e-5)
            f0s = F0_from_ior(ior)
            eta_s = ior
            level = max(params[r, M_LEVEL], 0.0)
            if level != 0.5:
                f0s = f0s * 2.0 * level
                eta_s = ior_from_F0(f0s)
                if ior < 1.0:
                    eta_s = 1.0 / eta_s
        if sp > 0.0 and eta_s != 1.0 and (W0 > 0.0 or W1 > 0.0 or W2 > 0.0):
            F0r = F0_from_ior(eta_s)
            s_avg = 0.0
            if F0r < 1.0:
                s_avg = min(max((fresnel_dielectric_Fss(eta_s) - F0r) / (1.0 - F0r), 0.0), 1.0)
            s = tables.schlick_ior_s(rough_g, mu, max(eta_s, 1.0 / eta_s))
            Ws = (W0, W1, W2)
            top = 0.0
            for c in range(3):
                f0 = min(max(f0s * max(params[r, M_STINT + c], 0.0), 0.0), 1.0)
                Fss = f0 + (1.0 - f0) * s_avg
                fac, dark = _compensation(multi, E, E_avg, Fss)
                est = dark * (f0 + (1.0 - f0) * s)
                prm[i, P_SPEC_W + c] = sp * Ws[c] * fac
                prm[i, P_SPEC_F0 + c] = f0
                weights[i, L_SPEC, c] = sp * Ws[c] * est
                top = max(top, sp * est)
            prm[i, P_SPEC_ALPHA] = alpha
            prm[i, P_SPEC_ETA] = eta_s
            if ax != ay:
                prm[i, P_AX], prm[i, P_AY] = ax, ay
            keep = min(max(1.0 - top, 0.0), 1.0)
            W0, W1, W2 = W0 * keep, W1 * keep, W2 * keep
        # --- diffuse base ---
        weights[i, L_DIFFUSE, 0] = W0 * base[i, 0]
        weights[i, L_DIFFUSE, 1] = W1 * base[i, 1]
        weights[i, L_DIFFUSE, 2] = W2 * base[i, 2]


@kernel
def aniso_alphas(node, aniso, alpha):
    """(alpha_x, alpha_y) of the metal and specular lobes from the isotropic alpha =
    roughness^2 and the material's anisotropy (Cycles' svm/closure.h). Principled:
    anisotropic clamped to [0, 1], aspect = sqrt(1 - 0.9 anisotropic), alpha_x =
    alpha / aspect, alpha_y = alpha x aspect (the highlight stretched across T). Glossy
    BSDF: anisotropy clamped to [-0.99, 0.99], |a| <= 1e-4 isotropic; a > 0: alpha (1 - a),
    alpha / (1 - a); a < 0: alpha / (1 + a), alpha (1 + a). Both clamped to 1 as
    bsdf_microfacet_ggx_setup clamps them."""
    if node == NODE_GLOSSY:
        a = min(max(aniso, -0.99), 0.99)
        if abs(a) <= 1e-4:
            return alpha, alpha
        if a < 0.0:
            ax, ay = alpha / (1.0 + a), alpha * (1.0 + a)
        else:
            ax, ay = alpha * (1.0 - a), alpha / (1.0 - a)
    else:
        a = min(max(aniso, 0.0), 1.0)
        if a <= 0.0:
            return alpha, alpha
        aspect = math.sqrt(1.0 - a * 0.9)
        ax, ay = alpha / aspect, alpha * aspect
    return min(ax, 1.0), min(ay, 1.0)


@kernel
def set_tangents(prm, rows, ns, tangent, rot):
    """The anisotropic lobes' tangent of hits `rows` (int64; hits whose material is
    anisotropic, after setup and the glossy normal P_GN): tangent (N,3) world-space
    tangent per hit (not necessarily unit; Blender's Tangent node before its projection),
    ns (N,3) shading normals, rot (N,) the rotation in turns. As Cycles: the Tangent node
    projects T onto the shading normal's plane (cross(N, normalize(cross(T, N)))), the
    closure rotates it about N by 2 pi rot (rotate_around_axis, right-handed), and the
    microfacet frame (make_orthonormals_tangent) takes T's part in the plane of the
    glossy normal. Writes P_TAN (0, 0 where T is parallel to the normal: isotropic)."""
    for k in range(rows.shape[0]):
        i = rows[k]
        set_tangent_row(prm, i, ns[i, 0], ns[i, 1], ns[i, 2], tangent[i, 0], tangent[i, 1],
                        tangent[i, 2], rot[i])


@kernel
def set_tangent_row(prm, i, n0, n1, n2, t0, t1, t2, rot):
    """set_tangents for packed row i: shading normal n, world tangent t, rotation rot."""
    prm[i, P_TAN] = 0.0
    prm[i, P_TAN + 1] = 0.0
    if not prm[i, P_AX] > 0.0:
        return
    lx, ly, _ = frame_local(n0, n1, n2, t0, t1, t2)
    ln = math.sqrt(lx * lx + ly * ly)
    if not ln > 0.0:
        return
    lx, ly = lx / ln, ly / ln
    if rot != 0.0:
        ca, sa = math.cos(2.0 * math.pi * rot), math.sin(2.0 * math.pi * rot)
        lx, ly = ca * lx - sa * ly, sa * lx + ca * ly
    qx, qy, _ = _to_glossy(prm, i, lx, ly, 0.0)
    ln = math.sqrt(qx * qx + qy * qy)
    if ln > 0.0:
        prm[i, P_TAN] = qx / ln
        prm[i, P_TAN + 1] = qy / ln


@kernel
def _glossy_eval(prm, i, ox, oy, oz, ix, iy, iz, a):
    """ggx.reflect_eval of the metal or specular lobe (alpha a), in the glossy frame;
    anisotropic (ggx.reflect_eval_aniso in the tangent frame x = T, y = N x T) where
    the hit has alpha_x, alpha_y (P_AX > 0) and a tangent. (One column read on
    isotropic rows: the tangent only behind it.)"""
    if prm[i, P_AX] > 0.0:
        tx, ty = prm[i, P_TAN], prm[i, P_TAN + 1]
        if tx != 0.0 or ty != 0.0:
            return ggx.reflect_eval_aniso(ox * tx + oy * ty, oy * tx - ox * ty, oz,
                                          ix * tx + iy * ty, iy * tx - ix * ty, iz,
                                          prm[i, P_AX], prm[i, P_AY])
    return ggx.reflect_eval(ox, oy, oz, ix, iy, iz, a)


@kernel
def _glossy_sample(prm, i, ox, oy, oz, a, u1, u2):
    """ggx.reflect_sample of the metal or specular lobe, anisotropic as _glossy_eval."""
    if prm[i, P_AX] > 0.0:
        tx, ty = prm[i, P_TAN], prm[i, P_TAN + 1]
        if tx != 0.0 or ty != 0.0:
            x, y, z, w, pdf, c = ggx.reflect_sample_aniso(
                ox * tx + oy * ty, oy * tx - ox * ty, oz, prm[i, P_AX], prm[i, P_AY], u1, u2)
            return x * tx - y * ty, x * ty + y * tx, z, w, pdf, c
    return ggx.reflect_sample(ox, oy, oz, a, u1, u2)


# glass_terms' columns: the glass layer's terms of one material on one side.
G_ETA, G_INV, G_I, G_FX, G_K, G_FZ, G_EAVG, G_F0G = range(8)
G_SI, G_SFX, G_SK, G_SFZ, G_F0E = 8, 9, 10, 11, 12
G_F0 = 13  # 3: Principled's remapped f0 per channel (F0(ior) x specular tint, capped at 1)
G_N = 16


@kernel
def glass_terms(q, front, out):
    """The terms of setup's glass layer that depend on the material row q (N_MAT,) and
    the side (front: the ray arrived on the outside) alone, computed as setup computed
    them per hit, written to out (G_N,): eta; G_INV 1 where eta < 1 (tables.glass_E reads
    the inverse tables); the roughness's and z's cells in those tables (tables._coord: the
    lower index and the fraction, as floats); E_avg; F0(ior); the cells of
    tables.schlick_ior_s (its reflectance estimate where eta >= 1); F0(eta) (schlick_remap's,
    where eta < 1); Principled's per-channel f0. Per hit only the view cosine's cell and
    the table terms are left (_glass_E_at, tables.lookup3_at)."""
    rough = q[M_ROUGH]
    ior = max(q[M_IOR], 1e-5)
    eta = ior if front else 1.0 / ior
    out[G_ETA] = eta
    if eta < 1.0:
        z = tables.z_from_ior(1.0 / eta)
        out[G_INV] = 1.0
        out[G_EAVG] = tables.lookup2(tables.GLASS_INV_EAVG, rough, z)
        i, fx = tables._coord(rough, tables.GLASS_INV_E.shape[0])
        k, fz = tables._coord(z, tables.GLASS_INV_E.shape[2])
    else:
        z = tables.z_from_ior(eta)
        out[G_INV] = 0.0
        out[G_EAVG] = tables.lookup2(tables.GLASS_EAVG, rough, z)
        i, fx = tables._coord(rough, tables.GLASS_E.shape[0])
        k, fz = tables._coord(z, tables.GLASS_E.shape[2])
    out[G_I], out[G_FX], out[G_K], out[G_FZ] = i, fx, k, fz
    F0g = F0_from_ior(ior)
    out[G_F0G] = F0g
    zs = tables.z_from_ior(max(ior, 1.0))
    i, fx = tables._coord(rough, tables.SCHLICK_IOR_S.shape[0])
    k, fz = tables._coord(zs, tables.SCHLICK_IOR_S.shape[2])
    out[G_SI], out[G_SFX], out[G_SK], out[G_SFZ] = i, fx, k, fz
    out[G_F0E] = F0_from_ior(eta)
    for c in range(3):
        out[G_F0 + c] = min(F0g * max(q[M_STINT + c], 0.0), 1.0)


@kernel
def _glass_E_at(g, sd, mu):
    """tables.glass_E's E at view cosine mu for the material and side of glass_terms'
    row g[sd]: the same bits."""
    if g[sd, G_INV] != 0.0:
        return tables.lookup3_at(tables.GLASS_INV_E, g[sd, G_I], g[sd, G_FX], mu, g[sd, G_K],
                                 g[sd, G_FZ])
    return tables.lookup3_at(tables.GLASS_E, g[sd, G_I], g[sd, G_FX], mu, g[sd, G_K],
                             g[sd, G_FZ])


@kernel
def _remap(f0, c, eta):
    """Principled's Fresnel: mix(f0, 1, s(c)) with the real Fresnel curve of eta."""
    return f0 + (1.0 - f0) * schlick_remap(c, eta)


@kernel
def _glass_F(f0, c, eta):
    """The glass lobe's Fresnel reflectance: _remap, or 0 for a Refraction BSDF (f0 < 0,
    setup's marker: it transmits everything it does not absorb)."""
    if f0 < 0.0:
        return 0.0
    return _remap(f0, c, eta)


@kernel
def _glass_F_s(f0, s):
    """_glass_F with its remap s = schlick_remap(c, eta) given (one per hit, not per
    channel)."""
    if f0 < 0.0:
        return 0.0
    return f0 + (1.0 - f0) * s


@kernel
def _to_glossy(prm, i, x, y, z):
    """A direction in the shading normal's frame -> the glossy lobes' frame (P_GN)."""
    g0, g1, g2 = prm[i, P_GN], prm[i, P_GN + 1], prm[i, P_GN + 2]
    if g0 == 0.0 and g1 == 0.0 and g2 == 0.0:
        return x, y, z
    return frame_local(g0, g1, g2, x, y, z)


@kernel
def _from_glossy(prm, i, x, y, z):
    """The inverse of _to_glossy."""
    g0, g1, g2 = prm[i, P_GN], prm[i, P_GN + 1], prm[i, P_GN + 2]
    if g0 == 0.0 and g1 == 0.0 and g2 == 0.0:
        return x, y, z
    return frame_world(g0, g1, g2, x, y, z)


@kernel
def glossy_normals(ns, ng, wo, local, cos_o):
    """Cycles' maybe_ensure_valid_specular_reflection (kernel/closure/bsdf_util.h) for N
    hits: where the shading normal ns (N,3) differs from the geometric normal ng (on the
    viewer's side) and the mirror direction of wo about ns falls below
    min(0.9 wo.ng, 0.01) over the surface, the glossy lobes (metal, specular, coat, and
    glass: Cycles' Principled transmission lobe and Glass BSDF take valid_reflection_N too)
    take a normal N' rotated towards ng just enough to lift it to that height; the diffuse
    and sheen lobes keep ns. Writes N' in ns's frame to local (N,3) (rows left as they are
    where nothing is raised: zeros = ns itself, prm's P_GN) and wo.N' to cos_o (N,), the
    view cosine the closure set-up then estimates the lobes' albedo with (as Cycles sets
    its glossy closures up on N')."""
    for i in range(ns.shape[0]):
        raised, l0, l1, l2, c = glossy_normal_row(ns, ng, wo, i)
        if raised:
            local[i, 0], local[i, 1], local[i, 2] = l0, l1, l2
            cos_o[i] = c


@kernel
def glossy_normal_row(ns, ng, wo, i):
    """glossy_normals for row i: (raised, N' in ns's frame (3 values), wo.N'); raised
    False: the glossy lobes keep ns (the other values unused)."""
    n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
    w0, w1, w2 = wo[i, 0], wo[i, 1], wo[i, 2]
    raised, p0, p1, p2 = valid_reflection_normal(n0, n1, n2, ng[i, 0], ng[i, 1], ng[i, 2],
                                                 w0, w1, w2)
    if not raised:
        return False, 0.0, 0.0, 0.0, 0.0
    l0, l1, l2 = frame_local(n0, n1, n2, p0, p1, p2)
    ln = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    if not ln > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    return True, l0 / ln, l1 / ln, l2 / ln, (w0 * p0 + w1 * p1 + w2 * p2) / ln


@kernel
def valid_reflection_normal(n0, n1, n2, g0, g1, g2, w0, w1, w2):
    """Cycles' ensure_valid_specular_reflection (kernel/closure/bsdf_util.h) for one
    unit shading normal n, geometric normal g (both on the viewer's side) and unit view
    direction w: (raised, N') with N' (world, unit up to rounding) rotated from n towards
    g just enough that the mirror direction of w about it rises min(0.9 w.g, 0.01) over
    the surface; raised False where n == g or the mirror direction about n is that high
    already (N' then unused: n is kept)."""
    if n0 == g0 and n1 == g1 and n2 == g2:
        return False, 0.0, 0.0, 0.0
    ni = n0 * w0 + n1 * w1 + n2 * w2
    r0, r1, r2 = 2.0 * ni * n0 - w0, 2.0 * ni * n1 - w1, 2.0 * ni * n2 - w2
    iz = w0 * g0 + w1 * g1 + w2 * g2
    t = min(0.9 * iz, 0.01)
    if r0 * g0 + r1 * g1 + r2 * g2 >= t:
        return False, 0.0, 0.0, 0.0
    ng_dot = n0 * g0 + n1 * g1 + n2 * g2
    x0, x1, x2 = n0 - ng_dot * g0, n1 - ng_dot * g1, n2 - ng_dot * g2
    ln = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if ln > 0.0:
        x0, x1, x2 = x0 / ln, x1 / ln, x2 / ln
    else:
        x0, x1, x2 = n0, n1, n2
    ix = w0 * x0 + w1 * x1 + w2 * x2
    a = ix * ix + iz * iz
    if a <= 0.0:
        return False, 0.0, 0.0, 0.0
    b = 2.0 * (a + iz * t)
    c = (t + iz) * (t + iz)
    disc = math.sqrt(max(b * b - 4.0 * a * c, 0.0))
    nz2 = 0.25 * (b + disc) / a if ix < 0.0 else 0.25 * (b - disc) / a
    nx = math.sqrt(max(1.0 - nz2, 0.0))
    nz = math.sqrt(max(nz2, 0.0))
    return True, nx * x0 + nz * g0, nx * x1 + nz * g1, nx * x2 + nz * g2


@kernel
def eval_reflection(prm, i, ox, oy, oz, ix, iy, iz):
    """f * cos_i (RGB) of hit i's rough reflective lobes (spec, metal, coat and glass
    reflection on the glossy normal P_GN; sheen on the shading normal) for local wo, wi;
    mirror-like lobes contribute nothing (delta): eval_reflection_parts' two parts summed."""
    r0, r1, r2, s0, s1, s2 = eval_reflection_parts(prm, i, ox, oy, oz, ix, iy, iz)
    return r0 + s0, r1 + s1, r2 + s2


@kernel
def eval_reflection_parts(prm, i, ox, oy, oz, ix, iy, iz):
    """eval_reflection in two parts by the bounce kind Cycles counts (path_state_next's
    labels): (glossy (RGB): spec, metal, coat and glass reflection; sheen (RGB): a
    diffuse bounce, LABEL_DIFFUSE). For the lobes' separate Light Paths limits through
    flat glass passages (directlight.accumulate_bsdf)."""
    r0 = r1 = r2 = 0.0
    qx, qy, qz = _to_glossy(prm, i, ox, oy, oz)
    jx, jy, jz = _to_glossy(prm, i, ix, iy, iz)
    if qz > 0.0 and jz > 0.0:
        r0, r1, r2 = _eval_glossy(prm, i, qx, qy, qz, jx, jy, jz)
        # Rough glass reflects about the raised normal too (raised_rough_glass); its
        # side test is the raised normal's (Cycles' cos_NI, cos_NO on the closure's N).
        a = prm[i, P_GLASS_ALPHA]
        if a >= ggx.ALPHA_MIN and (prm[i, P_GLASS_RW] > 0 or prm[i, P_GLASS_RW + 1] > 0
                                   or prm[i, P_GLASS_RW + 2] > 0):
            e, _, c = ggx.reflect_eval(qx, qy, qz, jx, jy, jz, a)
            eta = prm[i, P_GLASS_ETA]
            r0 += prm[i, P_GLASS_RW] * _glass_F(prm[i, P_GLASS_F0], c, eta) * e
            r1 += prm[i, P_GLASS_RW + 1] * _glass_F(prm[i, P_GLASS_F0 + 1], c, eta) * e
            r2 += prm[i, P_GLASS_RW + 2] * _glass_F(prm[i, P_GLASS_F0 + 2], c, eta) * e
    # The sheen tests the light's side only (Cycles' bsdf_sheen_eval; smooth55).
    if iz <= 0.0:
        return r0, r1, r2, 0.0, 0.0, 0.0
    if (prm[i, P_SHEEN_W] > 0 or prm[i, P_SHEEN_W + 1] > 0
            or prm[i, P_SHEEN_W + 2] > 0):
        e, _ = sheen.sheen_eval(prm[i, P_SHEEN_A], prm[i, P_SHEEN_B], ox, oy, oz, ix, iy, iz)
        return (r0, r1, r2, prm[i, P_SHEEN_W] * e, prm[i, P_SHEEN_W + 1] * e,
                prm[i, P_SHEEN_W + 2] * e)
    return r0, r1, r2, 0.0, 0.0, 0.0


@kernel
def _eval_glossy(prm, i, ox, oy, oz, ix, iy, iz):
    """eval_reflection's metal, specular and coat lobes, in the glossy normal's frame
    (oz, iz > 0)."""
    r0 = r1 = r2 = 0.0
    a = prm[i, P_SPEC_ALPHA]
    if a >= ggx.ALPHA_MIN and (prm[i, P_SPEC_W] > 0 or prm[i, P_SPEC_W + 1] > 0
                               or prm[i, P_SPEC_W + 2] > 0):
        e, _, c = _glossy_eval(prm, i, ox, oy, oz, ix, iy, iz, a)
        eta = prm[i, P_SPEC_ETA]
        r0 += prm[i, P_SPEC_W] * _remap(prm[i, P_SPEC_F0], c, eta) * e
        r1 += prm[i, P_SPEC_W + 1] * _remap(prm[i, P_SPEC_F0 + 1], c, eta) * e
        r2 += prm[i, P_SPEC_W + 2] * _remap(prm[i, P_SPEC_F0 + 2], c, eta) * e
    a = prm[i, P_METAL_ALPHA]
    if a >= ggx.ALPHA_MIN and (prm[i, P_METAL_W] > 0 or prm[i, P_METAL_W + 1] > 0
                               or prm[i, P_METAL_W + 2] > 0):
        e, _, c = _glossy_eval(prm, i, ox, oy, oz, ix, iy, iz, a)
        r0 += prm[i, P_METAL_W] * fresnel_f82(c, prm[i, P_METAL_F0], prm[i, P_METAL_B]) * e
        r1 += prm[i, P_METAL_W + 1] * fresnel_f82(c, prm[i, P_METAL_F0 + 1],
                                                  prm[i, P_METAL_B + 1]) * e
        r2 += prm[i, P_METAL_W + 2] * fresnel_f82(c, prm[i, P_METAL_F0 + 2],
                                                  prm[i, P_METAL_B + 2]) * e
    a = prm[i, P_COAT_ALPHA]
    if a >= ggx.ALPHA_MIN and (prm[i, P_COAT_W] > 0 or prm[i, P_COAT_W + 1] > 0
                               or prm[i, P_COAT_W + 2] > 0):
        e, _, c = ggx.reflect_eval(ox, oy, oz, ix, iy, iz, a)
        F = fresnel_dielectric(c, prm[i, P_COAT_ETA]) * e
        r0 += prm[i, P_COAT_W] * F
        r1 += prm[i, P_COAT_W + 1] * F
        r2 += prm[i, P_COAT_W + 2] * F
    return r0, r1, r2


@kernel
def _glass_reflect_share(prm, i, c, eta, inv_eta):
    """Probability that _glass_sample reflects at a microfacet with wo.h = c."""
    # _glass_F per channel, the remap (a real Fresnel, the same for every channel)
    # computed once: the same bits.
    s = schlick_remap(c, eta)
    F0 = _glass_F_s(prm[i, P_GLASS_F0], s)
    F1 = _glass_F_s(prm[i, P_GLASS_F0 + 1], s)
    F2 = _glass_F_s(prm[i, P_GLASS_F0 + 2], s)
    sr = prm[i, P_GLASS_RW] * F0 + prm[i, P_GLASS_RW + 1] * F1 + prm[i, P_GLASS_RW + 2] * F2
    if inv_eta * inv_eta * (1.0 - c * c) >= 1.0:
        return 1.0 if sr > 0.0 else 0.0
    st = (prm[i, P_GLASS_TW] * (1.0 - F0) + prm[i, P_GLASS_TW + 1] * (1.0 - F1)
          + prm[i, P_GLASS_TW + 2] * (1.0 - F2))
    return sr / (sr + st) if sr + st > 0.0 else 0.0


@kernel
def bsdf_pdf(prm, sel, i, ox, oy, oz, ix, iy, iz):
    """Solid-angle pdf with which the continuation (sample_lobe, the lobe chosen with
    probability sel[i, lobe]) samples the reflected direction wi of hit i: the mixture of
    its rough reflective lobes (mirror-like lobes have no density; the metal, specular,
    coat and glass lobes on the glossy normal P_GN, sheen on the shading normal)."""
    pdf = 0.0
    qx, qy, qz = _to_glossy(prm, i, ox, oy, oz)
    jx, jy, jz = _to_glossy(prm, i, ix, iy, iz)
    if qz > 0.0 and jz > 0.0:
        for lobe, a_col in ((L_SPEC, P_SPEC_ALPHA), (L_METAL, P_METAL_ALPHA),
                            (L_COAT, P_COAT_ALPHA)):
            w = sel[i, lobe]
            a = prm[i, a_col]
            if w > 0.0 and a >= ggx.ALPHA_MIN:
                if lobe == L_COAT:
                    _, p, _ = ggx.reflect_eval(qx, qy, qz, jx, jy, jz, a)
                else:
                    _, p, _ = _glossy_eval(prm, i, qx, qy, qz, jx, jy, jz, a)
                pdf += w * p
        w = sel[i, L_GLASS_R] + sel[i, L_GLASS_T]
        a = prm[i, P_GLASS_ALPHA]
        if w > 0.0 and a >= ggx.ALPHA_MIN:  # (raised_rough_glass)
            _, p, c = ggx.reflect_eval(qx, qy, qz, jx, jy, jz, a)
            eta = prm[i, P_GLASS_ETA]
            pdf += w * p * _glass_reflect_share(prm, i, c, eta, 1.0 / eta)
    if iz <= 0.0:  # the sheen's side test: the light's only (smooth55)
        return pdf
    w = sel[i, L_SHEEN]
    if w > 0.0:
        _, p = sheen.sheen_eval(prm[i, P_SHEEN_A], prm[i, P_SHEEN_B], ox, oy, oz, ix, iy, iz)
        pdf += w * p
    return pdf


@kernel
def bsdf_pdf_many(prm, sel, ns, wo, wi, out):
    """Batch of bsdf_pdf in world space."""
    for i in range(ns.shape[0]):
        n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
        ox, oy, oz = frame_local(n0, n1, n2, wo[i, 0], wo[i, 1], wo[i, 2])
        ix, iy, iz = frame_local(n0, n1, n2, wi[i, 0], wi[i, 1], wi[i, 2])
        out[i] = bsdf_pdf(prm, sel, i, ox, oy, oz, ix, iy, iz)


@kernel
def has_translucent(prm, i):
    """Hit i has a translucent lobe (diffuse transmission with some weight)."""
    return prm[i, P_TL_W] > 0 or prm[i, P_TL_W + 1] > 0 or prm[i, P_TL_W + 2] > 0


@kernel
def _has_rough_glass_t(prm, i):
    """Hit i's glass lobe refracts with a density (rough, not index-matched, some
    transmission weight)."""
    return (prm[i, P_GLASS_ALPHA] >= ggx.ALPHA_MIN and abs(prm[i, P_GLASS_ETA] - 1.0) >= 1e-4
            and (prm[i, P_GLASS_TW] > 0 or prm[i, P_GLASS_TW + 1] > 0
                 or prm[i, P_GLASS_TW + 2] > 0))


@kernel
def has_rough_transmission(prm, i):
    """Hit i transmits with a density: its glass lobe refracts roughly (_has_rough_glass_t)
    or it has a translucent lobe. Light sampling can reach it through the surface."""
    return _has_rough_glass_t(prm, i) or has_translucent(prm, i)


@kernel
def eval_translucent(prm, i, oz, iz):
    """Hit i's translucent lobe for local wo above (oz > 0) and wi below (iz < 0) the
    shading normal: (f * |cos_i| RGB = P_TL_W |cos_i| / pi, the lobe's own solid-angle
    pdf |cos_i| / pi: cosine sampling of the far hemisphere). Cycles' bsdf_translucent
    (kernel/closure/bsdf_diffuse.h). Zeros on the same side or without the lobe."""
    if oz <= 0.0 or iz >= 0.0 or not has_translucent(prm, i):
        return 0.0, 0.0, 0.0, 0.0
    k = -iz / math.pi
    return prm[i, P_TL_W] * k, prm[i, P_TL_W + 1] * k, prm[i, P_TL_W + 2] * k, k


@kernel
def eval_transmission(prm, i, ox, oy, oz, ix, iy, iz):
    """The glass refraction (eval_glass_transmission) plus the translucent lobe
    (eval_translucent) for local wo above and wi below the shading normal: (f * |cos_i|
    RGB summed, the glass lobe's own pdf (eval_glass_transmission's), the translucent
    lobe's own pdf)."""
    t0, t1, t2, pg = eval_glass_transmission(prm, i, ox, oy, oz, ix, iy, iz)
    l0, l1, l2, pl = eval_translucent(prm, i, oz, iz)
    return t0 + l0, t1 + l1, t2 + l2, pg, pl


@kernel
def eval_glass_transmission(prm, i, ox, oy, oz, ix, iy, iz):
    """Hit i's rough glass refraction for local wo above (oz > 0) and wi below (iz < 0)
    the shading normal: (f * |cos_i| RGB, the solid-angle pdf with which the glass lobe's
    sampling (_glass_sample, the lobe alone) refracts into wi). Walter et al. 2007 with
    the half vector h = -(wo + eta wi), as ggx.glass_eval, with the lobe's transmission
    colours TW x (1 - F) (F Principled's remap at wo.h); the pdf takes the refraction's
    share 1 - p_r at h, so that f / pdf is _glass_sample's weight t G2/G1 / (1 - p_r).
    The lobe's normal is the raised one (raised_rough_glass): wo, wi are taken to its
    frame first, the sides and |cos_i| are against it. As Cycles' bsdf_microfacet_eval,
    pairs whose h sees wo from its back or wi from its front are evaluated too, with |wo.h|
    and |wi.h| (the sampler never makes them; light sampling reads them). Zeros where the
    pair is no refraction (wrong sides, total internal reflection at h, eta 1)."""
    if not _has_rough_glass_t(prm, i):
        return 0.0, 0.0, 0.0, 0.0
    ox, oy, oz = _to_glossy(prm, i, ox, oy, oz)
    ix, iy, iz = _to_glossy(prm, i, ix, iy, iz)
    if oz <= 0.0 or iz >= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    alpha = prm[i, P_GLASS_ALPHA]
    eta = prm[i, P_GLASS_ETA]
    hx, hy, hz = -(ox + eta * ix), -(oy + eta * iy), -(oz + eta * iz)
    ln = math.sqrt(hx * hx + hy * hy + hz * hz)
    if ln <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    hx, hy, hz = hx / ln, hy / ln, hz / ln
    if hz < 0.0:
        hx, hy, hz = -hx, -hy, -hz
    # Cycles' bsdf_microfacet_eval takes |wo.h| and |wi.h| and does not refuse the pairs
    # whose h sees wo from its back or wi from its front (its "TODO: check if the
    # refraction configuration is valid"): its sampler never makes them, its light
    # sampling lights through them (a sun behind roughness-1 glass: +21 % at 30 degrees;
    # roughglass47, docs/accuracy.md "roughglass47"). So do ours.
    c_h = ox * hx + oy * hy + oz * hz
    ch_i = ix * hx + iy * hy + iz * hz
    c = abs(c_h)
    if c <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    inv_eta = 1.0 / eta
    if inv_eta * inv_eta * (1.0 - c * c) >= 1.0:  # total internal reflection at h
        return 0.0, 0.0, 0.0, 0.0
    a2 = alpha * alpha
    denom = c_h + eta * ch_i  # (+- |wo + eta wi|)
    # D(h) |wo.h| / cos_o x |dh / dwi| (Walter's Jacobian of the refraction)
    common = ggx.d_ggx(hz, a2) * c / oz * (eta * eta) * abs(ch_i) / (denom * denom)
    lo = ggx.lambda_ggx(oz, a2)
    g2 = common / (1.0 + lo + ggx.lambda_ggx(-iz, a2))
    t0 = prm[i, P_GLASS_TW] * (1.0 - _glass_F(prm[i, P_GLASS_F0], c, eta)) * g2
    t1 = prm[i, P_GLASS_TW + 1] * (1.0 - _glass_F(prm[i, P_GLASS_F0 + 1], c, eta)) * g2
    t2 = prm[i, P_GLASS_TW + 2] * (1.0 - _glass_F(prm[i, P_GLASS_F0 + 2], c, eta)) * g2
    pdf = common / (1.0 + lo) * (1.0 - _glass_reflect_share(prm, i, c, eta, inv_eta))
    return t0, t1, t2, pdf


@kernel
def transmission_pdf(prm, sel, i, ox, oy, oz, ix, iy, iz):
    """Solid-angle pdf with which the continuation (the glass lobe chosen with probability
    sel[i, L_GLASS_R] + sel[i, L_GLASS_T], the translucent lobe with sel[i, L_TRANSL])
    goes through the surface into wi (local, iz < 0) at hit i: bsdf_pdf's counterpart
    through the surface; inf where the transmission has no density (smooth or
    index-matched glass alone: light sampling cannot produce it)."""
    if not has_rough_transmission(prm, i):
        return np.inf
    _, _, _, pg, pl = eval_transmission(prm, i, ox, oy, oz, ix, iy, iz)
    return (sel[i, L_GLASS_R] + sel[i, L_GLASS_T]) * pg + sel[i, L_TRANSL] * pl


@kernel
def reverse_transmission_pdf(prm, sel, i, ox, oy, oz, ix, iy, iz):
    """transmission_pdf seen from the far side: the solid-angle pdf with which a path
    arriving from wi's side (local, iz < 0: the camera side coming from a photon's next
    vertex) samples wo (oz > 0) through hit i, whose lobes are set up at wo's side (the
    photon's arrival). A refraction's pdf is not symmetric: Cycles' bsdf_microfacet.h
    takes D G1(wi) |wi.h wo.h| / (cos_i (wi.h + eta' wo.h)^2 / eta'^2) with eta' = 1 /
    eta, wi's side's own IOR, which is transmission_pdf's glass pdf (Walter et al. 2007,
    wo's side) x cos_o (1 + Lambda(cos_o)) / (|cos_i| eta^2 (1 + Lambda(|cos_i|))) on the
    glossy normal; the reflect / refract share at h is the same from both sides (a
    dielectric's Fresnel is). The translucent lobe's pdf is cos_o / pi (the far side's
    cosine sampling of wo). inf where the transmission has no density."""
    if not has_rough_transmission(prm, i):
        return np.inf
    _, _, _, pg, pl = eval_transmission(prm, i, ox, oy, oz, ix, iy, iz)
    if pg > 0.0:
        _, _, qz = _to_glossy(prm, i, ox, oy, oz)
        _, _, jz = _to_glossy(prm, i, ix, iy, iz)
        a2 = prm[i, P_GLASS_ALPHA] * prm[i, P_GLASS_ALPHA]
        eta = prm[i, P_GLASS_ETA]
        pg *= (qz * (1.0 + ggx.lambda_ggx(qz, a2))
               / (-jz * eta * eta * (1.0 + ggx.lambda_ggx(-jz, a2))))
    if pl > 0.0:
        pl = oz / math.pi
    return (sel[i, L_GLASS_R] + sel[i, L_GLASS_T]) * pg + sel[i, L_TRANSL] * pl


@kernel
def rough_transmission_rows(prm, cand, out):
    """Writes the rows of cand (int64) with has_rough_transmission into out; returns
    their count."""
    k = 0
    for i in cand:
        if has_rough_transmission(prm, i):
            out[k] = i
            k += 1
    return k


@kernel
def accumulate_transmission(L, contrib, row, kidx, ray, ksamples, blocked, m_all, wdir, lpdf,
                            kmode, prm, ns, wo, sel):
    """Radiance through rough glass and translucent surfaces from light samples taken on
    the far side of the surface (engine/glasslight.py): L[row] += contrib x f_t x visible
    / samples, entry by entry, with f_t the glass lobe's refraction plus the translucent
    lobe (eval_transmission; prm, sel per row of
    L, ns (N,3) the shading normals on wo's side, wo (N,3)); contrib holds the light's
    radiance x |cos_i| / light pdf (directlight.sample_lights, taken with the normals
    flipped). kmode[k] as directlight.accumulate_bsdf's: 1 full weight (a delta light),
    2 power heuristic against the continuation's transmission_pdf, 0 left to the
    continuation, 3 a light the light tree picked (1, 2 or 0 by lpdf)."""
    for j in range(m_all):
        r = ray[j]
        if r >= 0 and blocked[r]:
            continue
        k = kidx[j]
        mode = kmode[k]
        if mode == 3:
            mode = 1 if lpdf[j] == np.inf else (2 if lpdf[j] > 0.0 else 0)
        if mode == 0:
            continue
        i = row[j]
        n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
        ix, iy, iz = frame_local(n0, n1, n2, wdir[j, 0], wdir[j, 1], wdir[j, 2])
        if iz >= 0.0:
            continue
        ox, oy, oz = frame_local(n0, n1, n2, wo[i, 0], wo[i, 1], wo[i, 2])
        t0, t1, t2, pg, pl = eval_transmission(prm, i, ox, oy, oz, ix, iy, iz)
        s = ksamples[k]
        w = 1.0
        if mode == 2:
            pb = (sel[i, L_GLASS_R] + sel[i, L_GLASS_T]) * pg + sel[i, L_TRANSL] * pl
            pl = s * lpdf[j]
            w = pl * pl / (pl * pl + pb * pb) if pl > 0.0 else 0.0
        w = w / (-iz * s)  # contrib holds |cos_i|, f_t * |cos_i| is the eval
        L[i, 0] = L[i, 0] + contrib[j, 0] * t0 * w
        L[i, 1] = L[i, 1] + contrib[j, 1] * t1 * w
        L[i, 2] = L[i, 2] + contrib[j, 2] * t2 * w


@kernel
def eval_transmission_many(prm, ns, wo, wi, out):
    """Batch of eval_glass_transmission in world space: out (N,4) = f * |cos_i| RGB, pdf
    of the glass refraction alone."""
    for i in range(ns.shape[0]):
        n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
        ox, oy, oz = frame_local(n0, n1, n2, wo[i, 0], wo[i, 1], wo[i, 2])
        ix, iy, iz = frame_local(n0, n1, n2, wi[i, 0], wi[i, 1], wi[i, 2])
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = eval_glass_transmission(
            prm, i, ox, oy, oz, ix, iy, iz)


@kernel
def eval_translucent_many(prm, ns, wo, wi, out):
    """Batch of eval_translucent in world space: out (N,4) = f * |cos_i| RGB, pdf."""
    for i in range(ns.shape[0]):
        n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
        _, _, oz = frame_local(n0, n1, n2, wo[i, 0], wo[i, 1], wo[i, 2])
        _, _, iz = frame_local(n0, n1, n2, wi[i, 0], wi[i, 1], wi[i, 2])
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = eval_translucent(prm, i, oz, iz)


@kernel
def is_rough(prm, i, l):
    """Lobe l (L_* index) of hit i has a density (is not mirror-like)."""
    if l == L_SPEC:
        a = prm[i, P_SPEC_ALPHA]
    elif l == L_METAL:
        a = prm[i, P_METAL_ALPHA]
    elif l == L_COAT:
        a = prm[i, P_COAT_ALPHA]
    elif l == L_GLASS_R or l == L_GLASS_T:
        a = prm[i, P_GLASS_ALPHA]
    elif l == L_SHEEN or l == L_TRANSL:
        a = 1.0
    else:
        a = 0.0
    return a >= ggx.ALPHA_MIN


@kernel
def lobe_is_rough(prm, lobe):
    """Per row: the sampled lobe (L_* index) has a density (not mirror-like)."""
    out = np.zeros(lobe.shape[0], np.bool_)
    for i in range(lobe.shape[0]):
        out[i] = is_rough(prm, i, lobe[i])
    return out


@kernel
def has_rough_reflection(prm, i):
    if prm[i, P_SHEEN_W] > 0 or prm[i, P_SHEEN_W + 1] > 0 or prm[i, P_SHEEN_W + 2] > 0:
        return True
    for a_col, w_col in ((P_SPEC_ALPHA, P_SPEC_W), (P_METAL_ALPHA, P_METAL_W),
                         (P_COAT_ALPHA, P_COAT_W), (P_GLASS_ALPHA, P_GLASS_RW)):
        if prm[i, a_col] >= ggx.ALPHA_MIN and (prm[i, w_col] > 0 or prm[i, w_col + 1] > 0
                                              or prm[i, w_col + 2] > 0):
            return True
    return False


@kernel
def rough_reflection_rows(prm, out):
    """out[i] = has_rough_reflection(prm, i) for every row."""
    for i in range(prm.shape[0]):
        out[i] = has_rough_reflection(prm, i)


@kernel
def glass_microfacet(prm, i, ox, oy, oz, u1, u2):
    """The glass lobe's first step, shared by sampling one half (_glass_sample) and both
    (camerakernels.glass_both): the microfacet normal h (visible-normal sampled from u1, u2
    on rough glass, about z: its callers give wo in the raised normal's frame,
    raised_rough_glass; the raised normal P_GN or the shading normal on smooth glass),
    c = wo . h, and the Fresnel-weighted
    reflection and transmission colours there. Returns (rough, alpha, eta, hx, hy, hz, c,
    r0, r1, r2, t0, t1, t2); c <= 0: wo sees the microfacet's back (no sample, colours 0)."""
    alpha = prm[i, P_GLASS_ALPHA]
    eta = prm[i, P_GLASS_ETA]
    rough = alpha >= ggx.ALPHA_MIN
    if rough:
        hx, hy, hz = ggx.sample_vndf(ox, oy, oz, alpha, u1, u2)
    elif prm[i, P_GN] != 0.0 or prm[i, P_GN + 1] != 0.0 or prm[i, P_GN + 2] != 0.0:
        # Smooth glass on a raised normal (glossy_normals; rough glass samples in
        # its frame instead: raised_rough_glass): the mirror and the refraction about it.
        hx, hy, hz = prm[i, P_GN], prm[i, P_GN + 1], prm[i, P_GN + 2]
    else:
        hx, hy, hz = 0.0, 0.0, 1.0
    c = ox * hx + oy * hy + oz * hz
    if c <= 0.0:
        return rough, alpha, eta, hx, hy, hz, c, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # _glass_F per channel, the remap (a real Fresnel, the same for every channel)
    # computed once: the same bits.
    s = schlick_remap(c, eta)
    F0 = _glass_F_s(prm[i, P_GLASS_F0], s)
    F1 = _glass_F_s(prm[i, P_GLASS_F0 + 1], s)
    F2 = _glass_F_s(prm[i, P_GLASS_F0 + 2], s)
    r0, r1, r2 = prm[i, P_GLASS_RW] * F0, prm[i, P_GLASS_RW + 1] * F1, prm[i, P_GLASS_RW + 2] * F2
    t0 = prm[i, P_GLASS_TW] * (1.0 - F0)
    t1 = prm[i, P_GLASS_TW + 1] * (1.0 - F1)
    t2 = prm[i, P_GLASS_TW + 2] * (1.0 - F2)
    return rough, alpha, eta, hx, hy, hz, c, r0, r1, r2, t0, t1, t2


@kernel
def raised_rough_glass(prm, i):
    """Hit i's glass lobe is rough and works in the raised normal's frame (P_GN set by
    glossy_normals; Cycles replaces the microfacet closure's N with valid_reflection_N,
    bsdf_util.h / bsdf_microfacet.h): its sampling, eval and pdf take wo and wi to that
    frame (_to_glossy) and its directions back (_from_glossy). False on smooth glass
    (glass_microfacet reflects and refracts about P_GN itself) and where nothing is
    raised (P_GN zeros: the frames are the same, the same bits)."""
    return prm[i, P_GLASS_ALPHA] >= ggx.ALPHA_MIN and (
        prm[i, P_GN] != 0.0 or prm[i, P_GN + 1] != 0.0 or prm[i, P_GN + 2] != 0.0)


@kernel
def _glass_sample(prm, i, ox, oy, oz, u1, u2, u3):
    """The glass lobe (reflection + refraction) as one, as Cycles samples it: a visible
    normal, then reflect or refract with probability in proportion to the average
    reflectance / transmittance there (the macro-surface Fresnel can be 1 - total internal
    reflection - where a rough surface still transmits). Rough glass on a raised normal
    samples in its frame (raised_rough_glass): a reflection below it or a refraction
    above it is refused (weight 0), as Cycles refuses them against its N."""
    if raised_rough_glass(prm, i):
        qx, qy, qz = _to_glossy(prm, i, ox, oy, oz)
        ix, iy, iz, w0, w1, w2, tr = _glass_sample_local(prm, i, qx, qy, qz, u1, u2, u3)
        ix, iy, iz = _from_glossy(prm, i, ix, iy, iz)
        return ix, iy, iz, w0, w1, w2, tr
    return _glass_sample_local(prm, i, ox, oy, oz, u1, u2, u3)


@kernel
def _glass_sample_local(prm, i, ox, oy, oz, u1, u2, u3):
    """_glass_sample with wo in the lobe's frame (rough: z its normal)."""
    (rough, alpha, eta, hx, hy, hz, c, r0, r1, r2, t0, t1, t2) = glass_microfacet(
        prm, i, ox, oy, oz, u1, u2)
    if c <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, False
    inv_eta = 1.0 / eta
    s2 = inv_eta * inv_eta * (1.0 - c * c)
    if s2 >= 1.0:  # total internal reflection at this microfacet
        t0 = t1 = t2 = 0.0
    sr = r0 + r1 + r2
    st = t0 + t1 + t2
    if sr + st <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, False
    p_r = sr / (sr + st)
    a2 = alpha * alpha
    lo = ggx.lambda_ggx(oz, a2) if rough else 0.0
    if u3 < p_r:
        ix, iy, iz = 2.0 * c * hx - ox, 2.0 * c * hy - oy, 2.0 * c * hz - oz
        # (Against the lobe's normal: z on rough glass, the raised h on smooth.)
        if (iz if rough else ix * hx + iy * hy + iz * hz) <= 0.0:
            return ix, iy, iz, 0.0, 0.0, 0.0, False
        g = (1.0 + lo) / (1.0 + lo + ggx.lambda_ggx(iz, a2)) if rough else 1.0
        k = g / p_r
        return ix, iy, iz, r0 * k, r1 * k, r2 * k, False
    ct = math.sqrt(1.0 - s2)
    kk = inv_eta * c - ct
    ix, iy, iz = -inv_eta * ox + kk * hx, -inv_eta * oy + kk * hy, -inv_eta * oz + kk * hz
    if (iz if rough else ix * hx + iy * hy + iz * hz) >= 0.0:
        return ix, iy, iz, 0.0, 0.0, 0.0, True
    g = 1.0
    if rough and abs(eta - 1.0) >= 1e-4:
        g = (1.0 + lo) / (1.0 + lo + ggx.lambda_ggx(-iz, a2))
    k = g / (1.0 - p_r)
    return ix, iy, iz, t0 * k, t1 * k, t2 * k, True


@kernel
def sample_lobe(prm, i, lobe, ox, oy, oz, u1, u2, u3):
    """Sample lobe `lobe` (L_METAL, L_SPEC, L_COAT, L_SHEEN, L_TRANSL, or L_GLASS_R /
    L_GLASS_T: both mean the whole glass lobe) of hit i for local wo: (ix, iy, iz,
    weight RGB = f cos / pdf of that lobe alone, transmitted). Weight 0: no sample. The
    metal, specular, coat and glass lobes sample about the glossy normal (P_GN), sheen
    and translucent about the shading normal."""
    if lobe == L_SHEEN:
        return _sample_sheen(prm, i, ox, oy, oz, u1, u2)
    if lobe == L_TRANSL:
        return _sample_translucent(prm, i, oz, u1, u2)
    if lobe == L_GLASS_R or lobe == L_GLASS_T:
        return _glass_sample(prm, i, ox, oy, oz, u1, u2, u3)
    qx, qy, qz = _to_glossy(prm, i, ox, oy, oz)
    ix, iy, iz, w0, w1, w2, tr = _sample_glossy(prm, i, lobe, qx, qy, qz, u1, u2, u3)
    ix, iy, iz = _from_glossy(prm, i, ix, iy, iz)
    return ix, iy, iz, w0, w1, w2, tr


@kernel
def _sample_sheen(prm, i, ox, oy, oz, u1, u2):
    ix, iy, iz, pdf = sheen.sheen_sample(prm[i, P_SHEEN_A], prm[i, P_SHEEN_B], ox, oy, oz,
                                         u1, u2)
    if iz <= 0.0 or pdf <= 0.0:
        return ix, iy, iz, 0.0, 0.0, 0.0, False
    return ix, iy, iz, prm[i, P_SHEEN_W], prm[i, P_SHEEN_W + 1], prm[i, P_SHEEN_W + 2], False


@kernel
def _sample_translucent(prm, i, oz, u1, u2):
    """The translucent lobe: a cosine-distributed direction in the far hemisphere (Cycles'
    bsdf_translucent_sample); weight f cos / pdf = the lobe's colour weight P_TL_W."""
    if oz <= 0.0:
        return 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, True
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    iz = -math.sqrt(max(0.0, 1.0 - u1))
    if iz >= 0.0:
        return 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, True
    return (r * math.cos(phi), r * math.sin(phi), iz, prm[i, P_TL_W], prm[i, P_TL_W + 1],
            prm[i, P_TL_W + 2], True)


@kernel
def _sample_glossy(prm, i, lobe, ox, oy, oz, u1, u2, u3):
    """sample_lobe's metal, specular and coat lobes in the glossy normal's frame."""
    if lobe == L_SPEC:
        a_col = P_SPEC_ALPHA
    elif lobe == L_METAL:
        a_col = P_METAL_ALPHA
    else:
        a_col = P_COAT_ALPHA
    if lobe == L_SPEC or lobe == L_METAL:
        ix, iy, iz, w, pdf, c = _glossy_sample(prm, i, ox, oy, oz, prm[i, a_col], u1, u2)
    else:
        ix, iy, iz, w, pdf, c = ggx.reflect_sample(ox, oy, oz, prm[i, a_col], u1, u2)
    if w <= 0.0:
        return ix, iy, iz, 0.0, 0.0, 0.0, False
    if lobe == L_SPEC:
        eta = prm[i, P_SPEC_ETA]
        return (ix, iy, iz, w * prm[i, P_SPEC_W] * _remap(prm[i, P_SPEC_F0], c, eta),
                w * prm[i, P_SPEC_W + 1] * _remap(prm[i, P_SPEC_F0 + 1], c, eta),
                w * prm[i, P_SPEC_W + 2] * _remap(prm[i, P_SPEC_F0 + 2], c, eta), False)
    if lobe == L_METAL:
        return (ix, iy, iz,
                w * prm[i, P_METAL_W] * fresnel_f82(c, prm[i, P_METAL_F0], prm[i, P_METAL_B]),
                w * prm[i, P_METAL_W + 1] * fresnel_f82(c, prm[i, P_METAL_F0 + 1],
                                                        prm[i, P_METAL_B + 1]),
                w * prm[i, P_METAL_W + 2] * fresnel_f82(c, prm[i, P_METAL_F0 + 2],
                                                        prm[i, P_METAL_B + 2]), False)
    F = w * fresnel_dielectric(c, prm[i, P_COAT_ETA])
    return ix, iy, iz, F * prm[i, P_COAT_W], F * prm[i, P_COAT_W + 1], \
        F * prm[i, P_COAT_W + 2], False


@kernel
def sample_lobes(prm, lobe, ns, wo, u1, u2, u3, d, weight, transmitted):
    """Batch of sample_lobe in world space: lobe (N,) (L_* indices), ns, wo (N,3) unit,
    u1, u2, u3 (N,) uniform numbers; writes d (N,3) world directions, weight (N,3),
    transmitted (N,)."""
    for i in range(lobe.shape[0]):
        n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
        ox, oy, oz = frame_local(n0, n1, n2, wo[i, 0], wo[i, 1], wo[i, 2])
        ix, iy, iz, w0, w1, w2, tr = sample_lobe(prm, i, lobe[i], ox, oy, oz, u1[i], u2[i],
                                                  u3[i])
        x, y, z = frame_world(n0, n1, n2, ix, iy, iz)
        ln = math.sqrt(x * x + y * y + z * z)
        if ln > 0:
            x, y, z = x / ln, y / ln, z / ln
        d[i, 0], d[i, 1], d[i, 2] = x, y, z
        weight[i, 0], weight[i, 1], weight[i, 2] = w0, w1, w2
        transmitted[i] = tr


@kernel
def eval_reflection_many(prm, ns, wo, wi, out):
    """Batch of eval_reflection in world space: out (N,3) = f * cos_i."""
    for i in range(ns.shape[0]):
        n0, n1, n2 = ns[i, 0], ns[i, 1], ns[i, 2]
        ox, oy, oz = frame_local(n0, n1, n2, wo[i, 0], wo[i, 1], wo[i, 2])
        ix, iy, iz = frame_local(n0, n1, n2, wi[i, 0], wi[i, 1], wi[i, 2])
        out[i, 0], out[i, 1], out[i, 2] = eval_reflection(prm, i, ox, oy, oz, ix, iy, iz)


def setup_np(params, mat, base, cos_o, front, alpha=None):
    """numpy entry of `setup`: returns (prm (N, N_PACK), weights (N, N_LOBES, 3)).
    alpha (N,): per-hit alpha; None = the materials' own (params' M_ALPHA column)."""
    n = len(mat)
    mat = np.ascontiguousarray(mat, np.int64)
    if alpha is None:
        alpha = params[mat, M_ALPHA] if n else np.zeros(0)
    prm = np.empty((n, N_PACK))
    weights = np.empty((n, N_LOBES, 3))
    setup(mat, params, np.ascontiguousarray(base, np.float64),
          np.ascontiguousarray(cos_o, np.float64), np.ascontiguousarray(front, np.bool_),
          np.ascontiguousarray(alpha, np.float64), prm, weights)
    return prm, weights


@register_warm_up
def _warm_up():
    """Compile (or load) the closure kernels a render calls, on one hit of a material with
    every lobe."""
    params = np.zeros((1, N_MAT))
    params[0, [M_ALPHA, M_METALLIC, M_ROUGH, M_TRANS, M_IOR, M_SPEC, M_LEVEL]] = (
        0.9, 0.3, 0.4, 0.3, 1.5, 1.0, 0.5)
    params[0, M_STINT:M_STINT + 3] = 1.0
    params[0, [M_COAT_W, M_COAT_ROUGH, M_COAT_IOR, M_MULTI]] = (0.5, 0.2, 1.5, 1.0)
    params[0, M_CTINT:M_CTINT + 3] = 1.0
    params[0, [M_SHEEN_W, M_SHEEN_ROUGH]] = (0.5, 0.5)
    params[0, M_SHEEN_TINT:M_SHEEN_TINT + 3] = 1.0
    params[0, M_TTINT:M_TTINT + 3] = 1.0
    params[0, M_TL] = 0.2
    one = np.ones(1)
    prm, _ = setup_np(params, np.zeros(1, np.int64), np.full((1, 3), 0.5), np.full(1, 0.8),
                      np.ones(1, np.bool_))
    n = np.array([[0.0, 0.0, 1.0]])
    wo = np.array([[0.6, 0.0, 0.8]])
    d, w = np.empty((1, 3)), np.empty((1, 3))
    sample_lobes(prm, np.full(1, L_SPEC, np.int64), n, wo, 0.3 * one, 0.6 * one, 0.5 * one,
                 d, w, np.empty(1, np.bool_))
    sel = np.full((1, N_LOBES), 0.1)
    bsdf_pdf_many(prm, sel, n, wo, d, np.empty(1))
    eval_reflection_many(prm, n, wo, d, np.empty((1, 3)))
    lobe_is_rough(prm, np.full(1, L_SPEC, np.int64))
    set_tangents(prm, np.zeros(1, np.int64), n, np.array([[1.0, 0.0, 0.0]]), np.zeros(1))
    rough_reflection_rows(prm, np.empty(1, np.bool_))
    glossy_normals(n, np.array([[0.0, 0.6, 0.8]]), wo, np.zeros((1, 3)), np.ones(1))
    wt = np.array([[-0.3, 0.0, -0.95]])
    eval_transmission_many(prm, n, wo, wt, np.empty((1, 4)))
    eval_translucent_many(prm, n, wo, wt, np.empty((1, 4)))
    rows = np.empty(1, np.int64)
    rough_transmission_rows(prm, np.zeros(1, np.int64), rows)
    accumulate_transmission(np.zeros((1, 3)), np.ones((1, 3)), np.zeros(1, np.int64),
                            np.zeros(1, np.int64), np.full(1, -1, np.int64), np.ones(1),
                            np.zeros(1, np.bool_), 1, wt, np.ones(1), np.full(1, 2, np.int64),
                            prm, n, wo, sel)
