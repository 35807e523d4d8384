"""Shadow rays through transparent surfaces: Cycles' transparent shadows.

A shadow ray that meets a surface whose material is transparent to shadows continues past
it with the surface's transparency multiplied in, up to `max_hits` transparent surfaces
(Cycles' Light Paths > Max Bounces > Transparent, default 8); the next one blocks it, as
does any opaque surface. As in Cycles (intern/cycles/kernel/integrator/intersect_shadow.h
and shade_shadow.h: `shader_bsdf_transparency` sums only the transparent closures), only
the transparent part of a material lets a shadow ray through: alpha < 1 (Principled
Alpha, a Mix Shader with a Transparent BSDF) and per-hit alpha from a texture
(engine/textures.py, material_alpha), tinted by the Transparent BSDF's colour
(Material.transparent_tint: the transmittance per channel is (1 - alpha) x tint, Cycles'
transparent closure weight). Mirrors and glass are opaque to shadow rays (the light that
reaches a surface through them is a caustic, the photon maps'), except a *flat passage*
through thin smooth glass (photonkernels.flat_exit): a shadow ray crosses it with the two
refractions' transmittance, as photons that cross it keep their path's kind, and camera
paths that cross it keep their MIS state (CameraPassages); docs/design.md, Transparent
shadows.

The work is split so the common case stays one cheap query per shadow ray: the caller
runs Embree's OCCLUDED query first (unblocked rays and rays blocked in a scene without
transparent materials are done); only the blocked rays of a scene with transparent
materials come here. They take a second OCCLUDED query against a BVH of the opaque
triangles only (blocked there: blocked, whatever else lies in the way), and the rest walk
a BVH of the transparent triangles only, surface by surface: closest hit, the hit's
transparency (kernel `shadow_step`), compaction of the rays still travelling, a new origin
just past the surface (engine/rayoffset.py) and the rest of the segment. Both BVHs are
built on first use, per ray class (engine/visibility.py), from the triangles that class
sees. A scene whose instances share their tables (engine/sharedrows.py) walks its
two-level BVH (engine/instancing.py) instead, every surface in order: an opaque one
blocks the ray where it is met, which gives the same transmittance.
"""
from __future__ import annotations

import math
import threading

import numpy as np

from . import media, raymaterials
from . import photonkernels as pk
from .accel import Accel
from .blurredpassage import factor_lookup
from .closures import principled as pr
from .closures import tables
from .coincident import CoincidentSurfaces
from .geometry import ALL_RAYS, SHADOW
from .jit import kernel, register_warm_up
from .rayoffset import offset_along_normal, winding_normal
from .textures import material_alpha

# Cycles' default transparent_max_bounces (Render Properties > Light Paths).
DEFAULT_MAX_HITS = 8

CLEAR, BLOCKED, GOING = 0, 1, 2
# Columns of the flat-passage glass table (glass_crossings), per material and side
# (0: a refraction from outside, 1: from inside): the glass lobe's eta, roughness and
# Multiscatter flag, its transmission weight before the energy compensation (3), the
# compensation's Fss = the transmission tint (3), and its Fresnel f0 (3; < 0: Refraction).
G_ETA, G_ROUGH, G_MULTI, G_TW, G_TT, G_F0 = 0, 1, 2, 3, 6, 9
G_N = 12
_NO_E, _NO_T = np.zeros((0, 3)), np.zeros(0)  # no media: the medium arguments' stand-ins
_NO_FLAT = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)),
            np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.bool_),
            np.zeros(0), np.zeros((0, 2, G_N)), np.zeros(0))


def transparent_tints(table) -> np.ndarray:
    """(M,3) the materials' Transparent BSDF colour (principled.M_TTINT columns of the
    closure table; white without one)."""
    from .closures import principled as pr
    params = getattr(table, "closure_params", None)
    if params is None:
        return np.ones((len(table.alpha), 3))
    return np.asarray(params[:, pr.M_TTINT:pr.M_TTINT + 3], np.float64)


def glass_crossings(params, base_color) -> np.ndarray:
    """(M, 2, G_N) float64: the smooth glass lobe's per-material constants of a refraction
    from outside (side 0) and from inside (side 1), for _crossing; params (M, N_MAT) the
    material table's closure columns, base_color (M,3). Built once per prepared scene
    (ShadowTransmittance), by principled.setup itself (the one place of the lobe's
    weights) at any angle: eta and f0 do not depend on it; the weight before the
    angle-dependent energy compensation is setup's with Multiscatter off (x 1.0, exact),
    and the compensation's Fss (the transmission tint) that weight with transmission 1 as
    well, exact for the materials a flat passage crosses (photonkernels.
    flat_glass_materials: alpha 1, no Add Shader, coat, sheen or metal above the glass,
    so the layers above leave it weight 1.0). Rows of other materials are unused."""
    params = np.ascontiguousarray(params, np.float64)
    base = np.ascontiguousarray(base_color, np.float64)
    M = len(params)
    out = np.zeros((M, 2, G_N))
    if M == 0:
        return out
    plain = params.copy()
    plain[:, pr.M_MULTI] = 0.0
    unit = plain.copy()
    unit[:, pr.M_TRANS] = 1.0
    mat = np.arange(M, dtype=np.int64)
    prm = np.empty((M, pr.N_PACK))
    weights = np.empty((M, pr.N_LOBES, 3))
    for side in range(2):
        front = np.full(M, side == 0)
        pr.setup(mat, plain, base, np.ones(M), front, np.ones(M), prm, weights)
        out[:, side, G_ETA] = prm[:, pr.P_GLASS_ETA]
        out[:, side, G_TW:G_TW + 3] = prm[:, pr.P_GLASS_TW:pr.P_GLASS_TW + 3]
        out[:, side, G_F0:G_F0 + 3] = prm[:, pr.P_GLASS_F0:pr.P_GLASS_F0 + 3]
        pr.setup(mat, unit, base, np.ones(M), front, np.ones(M), prm, weights)
        out[:, side, G_TT:G_TT + 3] = prm[:, pr.P_GLASS_TW:pr.P_GLASS_TW + 3]
    out[:, :, G_ROUGH] = params[:, None, pr.M_ROUGH]
    out[:, :, G_MULTI] = params[:, None, pr.M_MULTI]
    return out


@kernel
def _crossing(glass, m, side, cos_o, out):
    """out (3,) *= the smooth glass lobe's transmittance (RGB) for one refraction of
    material m at cos_o (the cosine on the arriving side), from outside (side 0) or
    inside (side 1): the weight the photons' glass sampling gives a refraction on
    average, TW x (1 - F) (principled._glass_sample), with TW as principled.setup sets
    it up for a hit: the table's weight (glass_crossings) x the energy compensation at
    this angle (none for a Refraction BSDF, f0 < 0). The same arithmetic as setup."""
    eta = glass[m, side, G_ETA]
    mu = min(max(cos_o, 0.0), 1.0)
    Eg, Eg_avg = tables.glass_E(glass[m, side, G_ROUGH], mu, eta)
    multi = glass[m, side, G_MULTI]
    for c in range(3):
        f0 = glass[m, side, G_F0 + c]
        tw = glass[m, side, G_TW + c]
        if f0 >= 0.0:
            tw = tw * pr._compensation(multi, Eg, Eg_avg, glass[m, side, G_TT + c])[0]
        out[c] *= tw * (1.0 - pr._glass_F(f0, cos_o, eta))


@kernel
def shadow_step(prim, tri_material, mat_alpha, mat_tint, node_alpha, slot, trans, count,
                max_hits, state, entry, o, d, thit, v0, e1, e2, object_id, flat_mat,
                flat_limit, glass, mat_ior, mat_sigma, seg_d, seg_t, seg_e1, seg_e2):
    """One surface along each travelling shadow ray.

    prim (n,) the triangle hit (-1: none before the ray's end); tri_material (T,);
    mat_alpha (M,) the materials' constant alpha, mat_tint (M,3) their Transparent BSDF
    colour; node_alpha (n,) the per-hit factor of a material's alpha texture (1 where it
    has none); slot (n,) the ray's row in trans (R,3) (RGB transmittance so far,
    multiplied in place) and count (R,) (transparent surfaces crossed so far). Writes
    state (n,): CLEAR (reached its end), BLOCKED (opaque surface, a black tint, or one
    transparent surface more than max_hits), GOING (crossed a transparent surface).

    Flat passages (flat_mat (M,) bool non-empty: photonkernels.flat_glass_materials):
    entry (R,) the triangle through which each ray entered smooth glass (-1: none; read
    and written); o, d (n,3) and thit (n,) the rays and their hit distances (units of
    |d|), v0, e1, e2 (T,3), object_id (T,), flat_limit (objects,) (photonkernels.
    flat_exit); glass (M, 2, G_N) the materials' glass_crossings, mat_ior (M,) their IOR. A ray entering such glass crosses it (two surfaces counted) if its next
    surface is the exit of a flat passage, with the transmittance of the two refractions
    (_crossing at the entry and the refracted angle); otherwise (another surface, or
    none: single-plane glass) it is blocked.

    Absorbing media (mat_sigma (M,3) media.absorption_table, 0 rows: none): a ray that
    crosses a surface it meets on its back face (it leaves the object: a flat passage's
    exit, a volume-only box's far side) was inside that object's medium since its last
    surface and keeps exp(-sigma_a s) of it (media.leaving_transmittance); seg_d (n,3)
    the rays' directions, seg_t (n,) their hit distances (units of |d|), seg_e1, seg_e2
    the edge tables read by prim's rows."""
    flat_on = flat_mat.shape[0] > 0
    media_on = mat_sigma.shape[0] > 0
    med = np.empty(3)
    out = np.empty(3)
    for i in range(prim.shape[0]):
        p = prim[i]
        r = slot[i]
        if flat_on and entry[r] >= 0:
            # Inside glass: the next surface must be the slab's other face.
            en = entry[r]
            entry[r] = -1
            ok = False
            if p >= 0 and count[r] < max_hits:
                px = o[i, 0] + d[i, 0] * thit[i]
                py = o[i, 1] + d[i, 1] * thit[i]
                pz = o[i, 2] + d[i, 2] * thit[i]
                ok = pk.flat_exit(v0, e1, e2, tri_material, object_id, flat_mat,
                                  flat_limit, en, p, d[i, 0], d[i, 1], d[i, 2], px, py, pz)
            if ok:
                m = tri_material[en]
                nx, ny, nz = winding_normal(e1, e2, en)
                ln = math.sqrt(nx * nx + ny * ny + nz * nz)
                dl = math.sqrt(d[i, 0] ** 2 + d[i, 1] ** 2 + d[i, 2] ** 2)
                ci = min(abs(d[i, 0] * nx + d[i, 1] * ny + d[i, 2] * nz) / max(ln * dl, 1e-300),
                         1.0)
                ior = max(mat_ior[m], 1e-5)
                s2 = (1.0 - ci * ci) / (ior * ior)
                ct = math.sqrt(max(1.0 - s2, 0.0))
                out[0] = out[1] = out[2] = 1.0
                _crossing(glass, m, 0, ci, out)
                _crossing(glass, m, 1, ct, out)
                if media_on and media.leaving_transmittance(
                        seg_e1, seg_e2, p, tri_material[p], mat_sigma, seg_d[i, 0],
                        seg_d[i, 1], seg_d[i, 2], seg_t[i], med):
                    # The way through the slab's medium (the refracted segment).
                    out[0] *= med[0]
                    out[1] *= med[1]
                    out[2] *= med[2]
                ok = out[0] > 0.0 or out[1] > 0.0 or out[2] > 0.0
            if not ok:
                trans[r, 0] = 0.0
                trans[r, 1] = 0.0
                trans[r, 2] = 0.0
                state[i] = BLOCKED
                continue
            trans[r, 0] = trans[r, 0] * out[0]
            trans[r, 1] = trans[r, 1] * out[1]
            trans[r, 2] = trans[r, 2] * out[2]
            count[r] += 1
            state[i] = GOING
            continue
        if p < 0:
            state[i] = CLEAR
            continue
        m = tri_material[p]
        if flat_on and flat_mat[m]:
            # Into smooth glass: room for both surfaces, arriving on its outside.
            if count[r] + 2 > max_hits or not pk.flat_entry(e1, e2, tri_material, flat_mat,
                                                            p, d[i, 0], d[i, 1], d[i, 2]):
                trans[r, 0] = 0.0
                trans[r, 1] = 0.0
                trans[r, 2] = 0.0
                state[i] = BLOCKED
                continue
            entry[r] = p
            count[r] += 1
            state[i] = GOING
            continue
        a = mat_alpha[m] * node_alpha[i]
        through = 1.0 - min(max(a, 0.0), 1.0)
        t0 = through * mat_tint[m, 0]
        t1 = through * mat_tint[m, 1]
        t2 = through * mat_tint[m, 2]
        if media_on and media.leaving_transmittance(seg_e1, seg_e2, p, m, mat_sigma,
                                                    seg_d[i, 0], seg_d[i, 1], seg_d[i, 2],
                                                    seg_t[i], med):
            t0 *= med[0]
            t1 *= med[1]
            t2 *= med[2]
        if not (t0 > 0.0 or t1 > 0.0 or t2 > 0.0) or count[r] >= max_hits:
            trans[r, 0] = 0.0
            trans[r, 1] = 0.0
            trans[r, 2] = 0.0
            state[i] = BLOCKED
            continue
        trans[r, 0] = trans[r, 0] * t0
        trans[r, 1] = trans[r, 1] * t1
        trans[r, 2] = trans[r, 2] * t2
        count[r] += 1
        state[i] = GOING


@kernel
def camera_passage(v0, e1, e2, material, object_id, flat_mat, flat_limit, mat_pass, prim,
                   d_in, p, keep, d_out, pdf_in, ns_in, p_in, entry, pre_pdf, pre_ns, pre_p,
                   pdf_out, ns_out, p_out, entry_out, pre_pdf_out, pre_ns_out, pre_p_out):
    """The camera paths' side of flat passages (integrator._trace_paths), after a
    specular continuation: the rows keep (K,) of the N hits (triangle prim, arriving
    direction d_in, point p; pdf_in, ns_in, p_in: the arriving rays' continuation pdf and
    the shading normal and point they left, for MIS; entry, pre_*: the glass each ray is
    inside and the MIS state it had before it) went on along d_out (K,3) with
    pdf_out, ns_out, p_out (K,) (the new state, rewritten in place). A refraction into
    flat-passage glass records the state before it (entry_out, pre_*_out (K,)); the
    refraction out of a flat passage (photonkernels.flat_exit) gives the ray its state
    from before the glass back, so a light met after a window takes the MIS weight of
    the surface whose lobe sampled it, as the shadow rays from that surface pass the
    window (otherwise both strategies would count that light in full). The same for a
    transparent pass (a continuation straight on through a material of mat_pass (M,)
    bool, those shadow rays cross; empty: none): the ray keeps its state, as the shadow
    rays from where it left cross that surface. flat_mat empty: no flat passages."""
    flat_on = flat_mat.shape[0] > 0
    pass_on = mat_pass.shape[0] > 0
    for k in range(keep.shape[0]):
        i = keep[k]
        t = prim[i]
        entry_out[k] = -1
        pre_pdf_out[k] = math.inf
        for c in range(3):
            pre_ns_out[k, c] = 0.0
            pre_p_out[k, c] = 0.0
        if t < 0:
            continue
        if pass_on and mat_pass[material[t]]:
            li = math.sqrt(d_in[i, 0] ** 2 + d_in[i, 1] ** 2 + d_in[i, 2] ** 2)
            lo = math.sqrt(d_out[k, 0] ** 2 + d_out[k, 1] ** 2 + d_out[k, 2] ** 2)
            cs = (d_in[i, 0] * d_out[k, 0] + d_in[i, 1] * d_out[k, 1]
                  + d_in[i, 2] * d_out[k, 2])
            if cs >= (1.0 - 1e-12) * li * lo:
                # Straight on through a transparent pass: the state goes on with the ray
                # (its glass entry too: an alpha card inside glass is no passage).
                entry_out[k] = entry[i]
                pre_pdf_out[k] = pre_pdf[i]
                for c in range(3):
                    pre_ns_out[k, c] = pre_ns[i, c]
                    pre_p_out[k, c] = pre_p[i, c]
                pdf_out[k] = pdf_in[i]
                for c in range(3):
                    ns_out[k, c] = ns_in[i, c]
                    p_out[k, c] = p_in[i, c]
                continue
        if not flat_on:
            continue
        nx, ny, nz = winding_normal(e1, e2, t)
        a = d_in[i, 0] * nx + d_in[i, 1] * ny + d_in[i, 2] * nz
        b = d_out[k, 0] * nx + d_out[k, 1] * ny + d_out[k, 2] * nz
        if not ((a < 0.0 and b < 0.0) or (a > 0.0 and b > 0.0)):
            continue  # reflected: no passage
        e = entry[i]
        if e >= 0:
            if pk.flat_exit(v0, e1, e2, material, object_id, flat_mat, flat_limit, e, t,
                            d_in[i, 0], d_in[i, 1], d_in[i, 2], p[i, 0], p[i, 1], p[i, 2]):
                pdf_out[k] = pre_pdf[i]
                for c in range(3):
                    ns_out[k, c] = pre_ns[i, c]
                    p_out[k, c] = pre_p[i, c]
            continue
        if pk.flat_entry(e1, e2, material, flat_mat, t, d_in[i, 0], d_in[i, 1], d_in[i, 2]):
            entry_out[k] = t
            pre_pdf_out[k] = pdf_in[i]
            for c in range(3):
                pre_ns_out[k, c] = ns_in[i, c]
                pre_p_out[k, c] = p_in[i, c]


class CameraPassages:
    """Per-path flat-passage state of integrator._trace_paths (camera_passage), or None
    for a scene without flat-passage glass (then nothing changes)."""

    @classmethod
    def for_context(cls, ctx, n):
        """None unless shadow rays cross some surface (ctx.shadow: flat passages, when
        they may cross both faces of a slab, or transparent passes)."""
        shadow = getattr(ctx, "shadow", None)
        if shadow is None or shadow.shared:
            return None
        flat_mat, flat_limit = shadow.flat_mat, shadow.flat_limit
        if not shadow.flat_on or shadow.max_hits < 2:
            flat_mat, flat_limit = pk._NO_FLAT_MAT, pk._NO_FLAT_LIMIT
        mat_pass = np.ascontiguousarray(shadow.transparent_materials(ctx.table), np.bool_)
        if not mat_pass.any():
            mat_pass = np.zeros(0, np.bool_)
        if not len(flat_mat) and not len(mat_pass):
            return None
        self = cls()
        geo = ctx.geo
        self.tables = (geo.v0, geo.e1, geo.e2, np.ascontiguousarray(geo.material, np.int64),
                       np.ascontiguousarray(geo.object_id, np.int64), flat_mat, flat_limit,
                       mat_pass)
        self.entry = np.full(n, -1, np.int64)
        self.pre_pdf = np.full(n, np.inf)
        self.pre_ns = np.zeros((n, 3))
        self.pre_p = np.zeros((n, 3))
        # Rays whose MIS state (org_p) is not the point they left: a flat passage or a
        # transparent pass lies between (mis_origin).
        self.moved = np.zeros(n, np.bool_)
        return self

    def compact(self, kept):
        if kept is not None:
            self.entry, self.pre_pdf = self.entry[kept], self.pre_pdf[kept]
            self.pre_ns, self.pre_p = self.pre_ns[kept], self.pre_p[kept]
            self.moved = self.moved[kept]

    def step(self, prim, d_in, p, keep, d_out, pdf_in, ns_in, p_in, pdf_out, ns_out, p_out):
        """After continue_specular: pdf_out, ns_out, p_out (K,) rewritten where a flat
        passage ends; the state carried to the continued rows."""
        c = np.ascontiguousarray
        K = len(keep)
        entry = np.empty(K, np.int64)
        pre_pdf = np.empty(K)
        pre_ns = np.empty((K, 3))
        pre_p = np.empty((K, 3))
        camera_passage(*self.tables, c(prim, np.int64), c(d_in, np.float64), c(p, np.float64),
                       c(keep, np.int64), c(d_out, np.float64), c(pdf_in, np.float64),
                       c(ns_in, np.float64), c(p_in, np.float64), self.entry, self.pre_pdf,
                       self.pre_ns, self.pre_p, pdf_out, ns_out, p_out, entry, pre_pdf,
                       pre_ns, pre_p)
        self.entry, self.pre_pdf, self.pre_ns, self.pre_p = entry, pre_pdf, pre_ns, pre_p
        self.moved = np.any(p_out != np.take(p, keep, axis=0), axis=1)

    def mis_origin(self, rows, o, d, t, org_p):
        """(o, t) for the light pdf of continuation rays rows (K,) (into this step's rows)
        from o (K,3) along d (K,3) that met a light at t (K,) (units of |d|), against the
        shadow rays from org_p (K,3), the point whose lobe sampled them: the same arrays,
        except where a flat passage or transparent pass lay between (moved), where the
        pdf is the light's seen from org_p along d, at t plus the way from org_p to o
        along d (the slab shifts the ray sideways by at most its thickness). Taken from o,
        a window 1 m below a light gave the pdf at a fraction of that distance, the
        continuation most of the MIS weight, and the light through the window counted
        twice in part (rough glass under a pane read 1.05x the light without the pane)."""
        far = self.moved[rows]
        if not far.any():
            return o, t
        o, t = o.copy(), np.array(t, np.float64)
        src, df = org_p[far], d[far]
        t[far] = t[far] + ((o[far] - src) * df).sum(axis=1) / (df * df).sum(axis=1)
        o[far] = src
        return o, t


def _blur_passages(trans, slots, blur, entered, d, ng, tri_material, mat_ior):
    """trans[slots] (rays just out of a flat passage entered through triangles `entered`
    along d (K,3)) *= blurredpassage.factor_lookup at the ray's cosine to the entry face
    (ng: the geometry's unit face normals, geometry.Geometry.ng),
    its blur alpha blur[slots] and the glass's IOR (mat_ior (M,) of tri_material (T,)):
    Cycles' blurred slab
    at Filter Glossy (docs/compatibility.md "fgslab49")."""
    a = blur[slots]
    on = np.flatnonzero(a > 0.0)
    if len(on) == 0:
        return
    g = entered[on]
    n = ng[g]
    dd = d[on]
    c = np.abs((n * dd).sum(axis=1)) / np.maximum(np.linalg.norm(dd, axis=1), 1e-300)
    f = factor_lookup(np.minimum(c, 1.0), a[on], np.take(mat_ior, np.take(tri_material, g)))
    trans[slots[on]] *= f[:, None]


@kernel
def scale_entries(contrib, ray, m_all, ray_trans):
    """contrib[j] *= ray_trans[ray[j]] (RGB) for the entries j < m_all with a traced
    shadow ray (directlight.sample_lights' layout: ray[j] = -1 when none was traced)."""
    for j in range(m_all):
        r = ray[j]
        if r < 0:
            continue
        contrib[j, 0] = contrib[j, 0] * ray_trans[r, 0]
        contrib[j, 1] = contrib[j, 1] * ray_trans[r, 1]
        contrib[j, 2] = contrib[j, 2] * ray_trans[r, 2]


class ShadowTransmittance:
    """Transparent shadows for one prepared scene (engine.geometry Geometry, MaterialTable).

    Build it with `for_scene`, which returns None for a scene without a material that is
    transparent to shadows (then shadow rays stay one OCCLUDED query each)."""

    def __init__(self, geo, table, max_hits: int = DEFAULT_MAX_HITS):
        max_hits = int(max_hits)
        if max_hits < 0:
            raise ValueError(f"ShadowTransmittance: max_hits must be >= 0, got {max_hits}")
        self.geo = geo
        self.table = table
        self.max_hits = max_hits
        self.mat_alpha = np.ascontiguousarray(table.alpha, np.float64)
        self.mat_tint = np.ascontiguousarray(transparent_tints(table))
        # Absorbing media inside objects (engine/media.py; 0 rows: none).
        self.sigma = media.absorption_table(table)
        # Shared instances (engine/sharedrows.py): no per-triangle tables; the rays walk
        # the class's two-level BVH surface by surface instead (_walk_bvh).
        self.shared = getattr(geo, "shared", None) is not None
        # Flat passages through thin smooth glass (empty tables: none in the scene, or
        # shared instances).
        self.flat_mat, self.flat_limit = pk.flat_tables(geo, table)
        self.flat_on = len(self.flat_mat) > 0
        if not self.shared:
            # The material shadow rays meet (a Light Path variant: a window transparent
            # to shadow rays; engine/raymaterials.py), triangle by triangle.
            shadow_mat = raymaterials.triangle_materials(geo, table, SHADOW)
            self.tri_material = np.ascontiguousarray(shadow_mat, np.int64)
            self.tri_transparent = self.transparent_materials(table)[shadow_mat]
            if self.flat_on:
                self.tri_transparent = self.tri_transparent | self.flat_mat[shadow_mat]
                self.object_id = np.ascontiguousarray(geo.object_id, np.int64)
                self.glass = glass_crossings(table.closure_params, table.base_color)
                self.mat_ior = np.ascontiguousarray(table.ior, np.float64)
        self._subsets = {}
        self._lock = threading.Lock()

    def _walk_bvh(self, cls):
        """A shared Geometry's BVH of the triangles rays of class cls see (None: all):
        two-level over the prototypes (engine/instancing.py), single-threaded, built once.
        Every surface is walked in order: an opaque one blocks in shadow_step."""
        key = ALL_RAYS if cls is None else int(cls)
        acc = self._subsets.get(key)
        if acc is None:
            with self._lock:
                acc = self._subsets.get(key)
                if acc is None:
                    from .instancing import InstanceAccel
                    geo = self.geo
                    ins = geo.instances
                    full = self._subsets.get(ALL_RAYS)
                    if full is None:
                        full = InstanceAccel(geo.vertices32, geo.faces32, ins, threads=1)
                        self._subsets[ALL_RAYS] = full
                    acc = full
                    if key != ALL_RAYS:
                        vis = np.asarray(np.take(geo.visibility, ins.static), np.int64)
                        acc = full.subset(geo.vertices32, geo.faces32,
                                          (ins.visibility & key) != 0,
                                          ins.static[(vis & key) != 0])
                    self._subsets[key] = acc
        return acc

    def _bvhs(self, cls):
        """(opaque, transparent) for rays of class cls (None: every triangle): each an
        (Accel or None when empty, triangle indices) over the triangles the class sees.
        Built once, single-threaded Accels (safe to share between worker threads)."""
        key = ALL_RAYS if cls is None else int(cls)
        pair = self._subsets.get(key)
        if pair is None:
            with self._lock:
                pair = self._subsets.get(key)
                if pair is None:
                    seen = (self.geo.visibility.astype(np.int64) & key) != 0
                    pair = []
                    for mask in (seen & ~self.tri_transparent, seen & self.tri_transparent):
                        idx = np.nonzero(mask)[0].astype(np.int64)
                        acc = (Accel(self.geo.vertices32, self.geo.faces32[idx], threads=1)
                               if len(idx) else None)
                        pair.append((acc, idx))
                    pair = tuple(pair)
                    self._subsets[key] = pair
        return pair

    @staticmethod
    def transparent_materials(table) -> np.ndarray:
        """(M,) bool: materials a shadow ray may pass (constant alpha < 1, or an alpha
        texture)."""
        nodes = getattr(table, "alpha_textures", None) or [None] * len(table.alpha)
        return (np.asarray(table.alpha) < 1.0) | np.array([n is not None for n in nodes], bool)

    @classmethod
    def for_scene(cls, geo, table, max_hits: int = DEFAULT_MAX_HITS):
        """A ShadowTransmittance, or None when no triangle's material is transparent to
        shadow rays (or max_hits is 0: every surface blocks, as Cycles with 0 transparent
        bounces)."""
        if geo.count == 0 or int(max_hits) <= 0:
            return None
        used = raymaterials.remap_rows(table, SHADOW, geo.used_materials())
        if not cls.transparent_materials(table)[used].any() and not len(
                pk.flat_tables(geo, table)[0]):
            return None
        return cls(geo, table, max_hits)

    # Heterogeneous media (engine/heterogeneous.py; set by render.prepare_context):
    # the rays that get through take their ratio-tracked correction (transmittance).
    hetero = None

    def transmittance(self, o32, d32, t32, rows=None, cls=None, passages=None,
                      crossed_out=None, used=None, blur=None) -> np.ndarray:
        """_transmittance's (R,3), with the heterogeneous media's correction
        (heterogeneous.HeterogeneousMedia.correction: ratio tracking over the parts inside
        a medium with a density texture) on the rays that get through."""
        trans = self._transmittance(o32, d32, t32, rows, cls, passages, crossed_out, used,
                                    blur)
        het = self.hetero
        if het is not None and len(trans):
            r = np.arange(len(o32)) if rows is None else np.asarray(rows, np.int64)
            through = np.flatnonzero(np.any(trans > 0.0, axis=1))
            if len(through):
                rr = r[through]
                trans[through] *= het.correction(np.asarray(o32, np.float64)[rr],
                                                 np.asarray(d32, np.float64)[rr],
                                                 np.asarray(t32, np.float64)[rr], salt=3)
        return trans

    def _transmittance(self, o32, d32, t32, rows=None, cls=None, passages=None,
                       crossed_out=None, used=None, blur=None) -> np.ndarray:
        """(R,3) RGB transmittance of the shadow rays `rows` (default: all) from o32 (R,3)
        along d32 (R,3) to distance t32 (R,) (units of |d|; re-centred world space),
        through transparent surfaces: the product of (1 - alpha) x transparent tint of the
        surfaces crossed, 0 where an opaque surface or more than max_hits transparent ones
        lie in the way. cls: the rays' class (engine/visibility.py; None: every triangle
        is seen). passages: (R,) int64 per ray (as o32), the most flat passages it may
        cross (Cycles' bounce limits: each passage stands for two refractions,
        chaincounts.flat_passages); more: blocked. None: no cap. crossed_out: (R,) int64
        or None: written at rows with the flat passages each ray crossed (with a cap only;
        a ray blocked past its cap counts the passage that blocked it). used: (R,) int64
        per ray (as o32), the transparent bounces its camera path made before the point
        it leaves (Cycles copies the path's transparent_bounce to the shadow path and
        lets it cross transparent_max_bounce minus that many: intersect_shadow.h,
        integrate_shadow_max_transparent_hits); None: 0, max_hits each. blur: (R,) float64
        per ray (as o32) or None, the Filter Glossy alpha Cycles gives window glass on the
        ray's way (filterglossy.blur_alpha of its diffuse hit's pdf towards the light;
        0: none): each flat passage it crosses keeps blurredpassage.factor_lookup of the
        smooth slab's light (docs/compatibility.md "fgslab49"); None: none blurs."""
        if rows is None:
            rows = np.arange(len(o32))
        rows = np.asarray(rows, np.int64)
        ray_rows = rows  # (the walk below reuses the name for the hits' table rows)
        n = len(rows)
        trans = np.ones((n, 3))
        # (The walk blocks a ray once its count reaches max_hits: a path's earlier passes
        # start it there.)
        count = (np.zeros(n, np.int64) if used is None
                 else np.asarray(used, np.int64)[rows].copy())
        if n == 0:
            return trans
        # The flat passages each ray has crossed, against its cap (None: no cap).
        cap = (None if passages is None or not self.flat_on
               else np.asarray(passages, np.int64)[rows])
        crossed = None if cap is None else np.zeros(n, np.int64)
        ray_blur = (None if blur is None or not self.flat_on
                    else np.asarray(blur, np.float64)[rows])
        o = np.asarray(o32, np.float64)[rows]
        d = np.asarray(d32, np.float64)[rows]
        t = np.asarray(t32, np.float64)[rows]
        end = o + d * t[:, None]
        dd = np.maximum((d * d).sum(axis=1), 1e-300)
        slot = np.arange(n, dtype=np.int64)
        entry = np.full(n, -1, np.int64)  # the glass each ray is inside (-1: none)
        # The medium each ray entered through a front face and has not left (-1: none),
        # and where: a ray that ends inside it (a lamp inside a fog box, lit from outside)
        # keeps exp(-sigma_t distance) from there to its end (the back-face rule in
        # shadow_step sees no exit).
        in_medium = np.full(n, -1, np.int64) if self.sigma.shape[0] else None
        entered_at = np.zeros((n, 3)) if in_medium is not None else None
        geo = self.geo
        if self.shared:
            opaque, clear, clear_idx = None, self._walk_bvh(cls), None
        else:
            (opaque, _), (clear, clear_idx) = self._bvhs(cls)
        if opaque is not None:
            # An opaque surface in the way blocks the ray whatever else does.
            stop = opaque.occluded(o, d, t)
            if stop.any():
                trans[stop] = 0.0
                go = ~stop
                o, d, t, slot = o[go], d[go], t[go], slot[go]
        if clear is None:
            if crossed_out is not None and crossed is not None:
                crossed_out[ray_rows] = crossed
            return trans
        if self.flat_on and not self.shared and len(slot):
            # Rays from a surface a glass slab lies on (engine/coincident.py) start just
            # inside the glass, past its face: they entered it there (counted as the
            # walk counts an entry; the two refractions are weighed at the exit).
            co = CoincidentSurfaces.for_context(self)
            if co is not None:
                k, g = co.started_inside(o, d)
                flat = self.flat_mat[np.take(self.tri_material, g)]
                entry[slot[k[flat]]] = g[flat]
                count[slot[k[flat]]] += 1
        for _ in range(self.max_hits + 1):
            if len(slot) == 0:
                break
            thit, prim, u, v = clear.intersect(o, d, t)
            hit = prim >= 0
            if clear_idx is not None:
                prim[hit] = clear_idx[prim[hit]]
            # The hits' material rows (gathered for shared instances: hit_tables).
            media_on = self.sigma.shape[0] > 0
            if self.shared:
                rows, tabs = geo.hit_tables(prim, *(("material", "e1", "e2") if media_on
                                                    else ("material",)))
                tri_material = raymaterials.remap_rows(self.table, SHADOW, tabs[0])
                seg_e = tuple(np.ascontiguousarray(x, np.float64) for x in tabs[1:])
            else:
                rows, tri_material = prim, self.tri_material
                seg_e = ((np.ascontiguousarray(geo.e1, np.float64),
                          np.ascontiguousarray(geo.e2, np.float64)) if media_on else ())
            if not media_on:
                seg_e = (_NO_E, _NO_E)
            seg = ((np.ascontiguousarray(d, np.float64), np.ascontiguousarray(thit, np.float64))
                   if media_on else (_NO_E, _NO_T))
            node_alpha = np.ones(len(prim))
            if hit.any():
                hp, hu, hv = prim[hit], u[hit], v[hit]
                node_alpha[hit] = material_alpha(self.table, geo,
                                                 np.take(tri_material, rows[hit]),
                                                 hp, hu, hv, constant=False)
            state = np.empty(len(prim), np.int64)
            # Rays inside glass now: GOING after the step means out of a flat passage.
            inside = None if cap is None and ray_blur is None else entry[slot] >= 0
            entered = entry[slot] if ray_blur is not None else None
            if self.flat_on:
                flat = (o, d, np.ascontiguousarray(thit, np.float64), geo.v0, geo.e1, geo.e2,
                        self.object_id, self.flat_mat, self.flat_limit, self.glass,
                        self.mat_ior)
            else:
                flat = _NO_FLAT
            shadow_step(rows, np.ascontiguousarray(tri_material, np.int64), self.mat_alpha,
                        self.mat_tint, node_alpha, slot, trans, count, self.max_hits, state,
                        entry, *flat, self.sigma, *seg, *seg_e)
            if inside is not None and inside.any():
                out = np.flatnonzero(inside & (state == GOING))
                if ray_blur is not None:
                    _blur_passages(trans, slot[out], ray_blur, entered[out], d[out],
                                   geo.ng, self.tri_material, self.mat_ior)
            if cap is not None and inside is not None and inside.any():
                crossed[slot[out]] += 1
                over = out[crossed[slot[out]] > cap[slot[out]]]
                if len(over):
                    # One passage more than the limits allow: the light it carries is
                    # past a transmission / total bounce limit (Cycles has none there).
                    trans[slot[over]] = 0.0
                    state[over] = BLOCKED
            go = np.nonzero(state == GOING)[0]
            if len(go) == 0:
                break
            # Past the surface: the hit point moved off its triangle to the far side
            # (the side the ray leaves to), then the rest of the segment to its end.
            gp, gu, gv = prim[go], u[go], v[go]
            p = geo.hit_points(gp, gu, gv)
            ng = np.take(geo.ng, gp, axis=0)
            off = geo.origin_offset(gp, gu, gv, p, ng)
            dg = d[go]
            o = offset_along_normal(p, ng, dg, off)
            if in_medium is not None:
                # Crossings of a medium's surface: a front face enters it, a back face
                # leaves it (shadow_step attenuated the way inside).
                r = rows[go]
                mm = np.asarray(tri_material, np.int64)[r]
                has = self.sigma[mm].max(axis=1) > 0.0
                if has.any():
                    e1r, e2r = seg_e[0][r], seg_e[1][r]
                    front = (dg * np.cross(e1r, e2r)).sum(axis=1) < 0.0
                    sg = slot[go]
                    enter = has & front
                    in_medium[sg[enter]] = mm[enter]
                    entered_at[sg[enter]] = p[enter]
                    in_medium[sg[has & ~front]] = -1
            slot = slot[go]
            d = dg
            t = ((end[slot] - o) * d).sum(axis=1) / dd[slot]
            past = t <= 0.0  # the surface lies at the ray's end: nothing more to cross
            if past.any():
                # ... but a ray that ends inside glass has no way out of it.
                trans[slot[past & (entry[slot] >= 0)]] = 0.0
                keep = ~past
                o, d, t, slot = o[keep], d[keep], t[keep], slot[keep]
        else:
            # Unreachable: each step blocks a ray at its (max_hits + 1)-th surface.
            trans[slot] = 0.0
        if in_medium is not None:
            ends_in = np.flatnonzero((in_medium >= 0) & (trans.max(axis=1) > 0.0))
            if len(ends_in):
                length = np.linalg.norm(end[ends_in] - entered_at[ends_in], axis=1)
                trans[ends_in] *= np.exp(-self.sigma[in_medium[ends_in]] * length[:, None])
        if crossed_out is not None and crossed is not None:
            crossed_out[ray_rows] = crossed
        return trans

    def pass_blocked(self, o32, d32, t32, blocked, contrib, ray, m_all, cls=None,
                     passages=None, crossed_out=None, used=None, blur=None):
        """After an OCCLUDED query: re-trace the blocked shadow rays through transparent
        surfaces; rays that get through are marked unblocked in `blocked` and the entries
        (j < m_all) of `contrib` that use them scaled by their transmittance (the layout
        of directlight.sample_lights). t32 must hold the rays' distances as they were
        before the query (Embree overwrites them). passages: (R,) the rays' most flat
        passages (transmittance's; None: no cap). crossed_out: (R,) int64 or None, the
        flat passages each re-traced ray crossed (transmittance's; the rest untouched).
        used: (R,) the transparent bounces each ray's path made before (transmittance's;
        None: 0). blur: (R,) the rays' window-glass blur alphas (transmittance's; None:
        none)."""
        rows = np.nonzero(blocked)[0]
        if len(rows) == 0:
            return
        trans = self.transmittance(o32, d32, t32, rows, cls, passages, crossed_out, used,
                                   blur)
        through = np.any(trans > 0.0, axis=1)
        if not through.any():
            return
        ray_trans = np.ones((len(blocked), 3))
        ray_trans[rows[through]] = trans[through]
        blocked[rows[through]] = False
        scale_entries(contrib, ray, m_all, ray_trans)


@register_warm_up
def _warm_up():
    """Compile (or load) the kernels on a one-ray batch."""
    trans = np.ones((1, 3))
    count = np.zeros(1, np.int64)
    state = np.empty(1, np.int64)
    shadow_step(np.zeros(1, np.int64), np.zeros(1, np.int64), np.full(1, 0.5),
                np.ones((1, 3)), np.ones(1), np.zeros(1, np.int64), trans, count,
                DEFAULT_MAX_HITS, state, np.full(1, -1, np.int64), *_NO_FLAT,
                np.ones((1, 3)), np.array([[0.0, 0.0, 1.0]]), np.ones(1),
                np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    params = np.zeros((1, pr.N_MAT))
    params[0, pr.M_TRANS] = params[0, pr.M_ALPHA] = 1.0
    params[0, pr.M_IOR] = 1.5
    tri = np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    shadow_step(np.zeros(1, np.int64), np.zeros(1, np.int64), np.ones(1),
                np.ones((1, 3)), np.ones(1), np.zeros(1, np.int64), trans, count,
                DEFAULT_MAX_HITS, state, np.zeros(1, np.int64), np.zeros((1, 3)),
                np.array([[0.0, 0.0, 1.0]]), np.full(1, 0.01), np.zeros((1, 3)), *tri,
                np.zeros(1, np.int64), np.ones(1, np.bool_), np.full(1, 0.1),
                glass_crossings(params, np.ones((1, 3))), np.full(1, 1.5), _NO_E,
                _NO_E, _NO_T, _NO_E, _NO_E)
    # called from Python too: panelight._transmittance_table (the panes' T tables)
    _crossing(glass_crossings(params, np.ones((1, 3))), 0, 0, 0.5, np.ones(3))
    scale_entries(np.ones((1, 3)), np.zeros(1, np.int64), 1, np.full((1, 3), 0.5))
    one3 = np.zeros((1, 3))
    camera_passage(np.zeros((1, 3)), *tri, np.zeros(1, np.int64), np.zeros(1, np.int64),
                   np.ones(1, np.bool_), np.full(1, 0.1), np.ones(1, np.bool_),
                   np.zeros(1, np.int64),
                   np.array([[0.0, 0.0, -1.0]]), one3, np.zeros(1, np.int64),
                   np.array([[0.0, 0.0, -1.0]]), np.ones(1), one3, one3,
                   np.full(1, -1, np.int64), np.ones(1), one3, one3, np.ones(1), one3.copy(),
                   one3.copy(), np.empty(1, np.int64), np.empty(1), np.empty((1, 3)),
                   np.empty((1, 3)))
