"""Cycles' Filter Glossy on the photon maps' paths: the exact split between the caustic /
glow maps and the final-gather chains (docs/compatibility.md, "filterglossy45" parts 2-3,
and "fgsplit46").

A caustic or glow photon's path L S1 ... Sm D is, to Cycles, the camera path D -> Sm ->
... -> S1 -> L, whose lobes Filter Glossy blurs by the camera side's pdfs (Cycles'
surface_shader_prepare_closures: min_ray_pdf / Filter Glossy below 1 widens every later
microfacet lobe to alpha 0.5 sqrt(1 - min_ray_pdf / Filter Glossy)). Cycles blurs the
path iff min(pdf_D, pdf_Sm, ..., pdf_S2) < Filter Glossy, pdf_D the diffuse hit D's
one-sample MIS pdf (over its closures: the diffuse lobe and any specular layer) of the
direction the photon came from. A photon cannot carry blurred light (a smooth lobe's
sample has no density under the blurred one), so:
- the maps' estimate at D counts only the photons Cycles does not blur: a photon counts
  iff min(pdf_D(wo, -w_photon), its stored min(pdf_Sm .. pdf_S2)) >= Filter Glossy
  (Photons.blur_pdf, photonkernels.reverse_pdf; DiffusePdf.reject_for); a D whose
  largest pdf is below Filter Glossy (a Lambert-only D above 1 / pi) reads no photon;
- the final-gather chains from D (gather_indirect -> continue_specular, vertices since
  D all non-diffuse) blur their lobes by the chain's own min_pdf (starting at pdf_D of
  the gather direction, the same DiffusePdf) and add, at every blurred vertex, the
  light the maps now leave out: light sampling through the blurred lobes, reflective
  and refractive (in full), and what the continued rays meet of the emitters light
  sampling leaves to them (a constant world). The same predicate on the same path
  decides both sides: each path is counted once.

For any Filter Glossy above 0 (fgsplit46 built it above 1 / pi with D's Lambert pdf;
docs/compatibility.md "fgphoton46" the per-photon test). The chains keep the Light Paths
limits as the lookups and the photons count the same path; where no material's pdf_D can
reach Filter Glossy (maps_unread) the caustic / glow shots are not traced; a photon's
reverse pdf through rough glass is the far side's (docs/compatibility.md "splitmaps47").
"""
from __future__ import annotations

import math

import numpy as np


# The split on (Filter Glossy above 0, photon mapping with final gathering); False: the
# maps and chains as without it (Cycles at Filter Glossy 0), whatever the scene's Filter
# Glossy. On by default since splitpane47: the chains leave the lights that next-event
# panes (engine/panelight.py) and lamp shades (engine/shadelight.py) carry to their
# shadow rays (GatherChains.carried); off in s46, when they added that light a second
# time (docs/compatibility.md "fgsplit46" "Off by default", "splitpane47").
ENABLED = True
# The largest pdf of a Lambert bounce's direction (cos / pi at the normal), 1/sr.
LAMBERT_PDF_MAX = 1.0 / math.pi


def settings_filter_glossy(settings) -> float:
    """The Filter Glossy the split applies with these RenderSettings
    (cycles_filter_glossy), or 0.0 where it is off: ENABLED false, no photon mapping or
    no final gathering, or Filter Glossy 0 (or not a number)."""
    fg = float(getattr(settings, "cycles_filter_glossy", 0.0) or 0.0)
    if (not ENABLED or not settings.photon_mapping
            or not getattr(settings, "final_gather", True) or not fg > 0.0):
        return 0.0
    return fg


def split_filter_glossy(ctx) -> float:
    """settings_filter_glossy of the render's settings, 0.0 also where the render has no
    gather map (no final gathering: nothing to carry the maps' light)."""
    if getattr(ctx, "gather_map", None) is None:
        return 0.0
    return settings_filter_glossy(ctx.settings)


def maps_blurred(ctx) -> bool:
    """Whether the split is on: the caustic and glow maps' estimates at the camera's
    diffuse hits count only the photons Cycles does not blur (DiffusePdf), the gather
    chains the rest."""
    return split_filter_glossy(ctx) > 0.0


def largest_pdfs(table) -> np.ndarray:
    """(M,) float64, 1/sr: per material, a bound on DiffusePdf's pdf_D at any hit of it,
    for any view and any direction on the viewer's side (the maps' photons arrive there):
    1/pi for a Lambert-only material (a transparent pass beside it only lowers it);
    max(1/pi, 1 / (2 pi alpha^3)) over its rough isotropic GGX reflective lobes (specular,
    metal, glass reflection: alpha = roughness^2; coat: its roughness^2), the largest
    visible-normal pdf G1(wo) D(h) / (4 cos_o) can take (D <= 1 / (pi alpha^2), G1 /
    cos_o <= 2 / alpha; principled.bsdf_pdf is that pdf); the MIS mixture over the lobes
    and the diffuse one is at most the largest of theirs. A camera path's blur only raises
    the alphas (lowers the bound). inf where no bound is known here: a mirror-like,
    anisotropic, sheen or translucent lobe, a texture-driven closure input, a subsurface
    walk or a NaN. 0 for a material with no diffuse lobe at all (MaterialTable.has_diffuse
    false, untextured): no photon is read there. table: geometry.MaterialTable."""
    from .closures import ggx
    from .closures import principled as pr
    q = np.asarray(table.closure_params, np.float64)
    m = len(q)
    if m == 0:
        return np.zeros(0)

    def flags(items):
        return np.array([x is not None for x in (items or [None] * m)], bool)
    scalar, sss = flags(table.scalar_textures), flags(getattr(table, "subsurface", None))
    textured = flags(table.textures)

    def ggx_bound(weight, rough):
        alpha = rough * rough
        with np.errstate(divide="ignore", invalid="ignore"):
            b = np.where(alpha >= ggx.ALPHA_MIN, 1.0 / (2.0 * math.pi * alpha ** 3), np.inf)
        # (NaN weights compare false: unbounded)
        return np.where(weight <= 0.0, 0.0, np.where(weight > 0.0, b, np.inf))
    spec_w = np.where(q[:, pr.M_LEVEL] == 0.0, 0.0, q[:, pr.M_SPEC])
    rough = q[:, pr.M_ROUGH]
    bound = np.maximum.reduce([
        np.full(m, LAMBERT_PDF_MAX), ggx_bound(spec_w, rough),
        ggx_bound(q[:, pr.M_METALLIC], rough), ggx_bound(q[:, pr.M_TRANS], rough),
        ggx_bound(q[:, pr.M_COAT_W], q[:, pr.M_COAT_ROUGH])])
    unknown = (~(q[:, pr.M_SHEEN_W] <= 0.0) | ~(q[:, pr.M_TL] <= 0.0)
               | ~(q[:, pr.M_ANISO] == 0.0) | scalar | sss | np.isnan(bound))
    bound = np.where(unknown, np.inf, bound)
    # (a colour texture may lift a base colour the table holds as black)
    none = ~np.asarray(table.has_diffuse, bool) & ~textured & ~scalar
    return np.where(none, 0.0, bound)


def scene_materials(geo, table) -> np.ndarray:
    """(K,) int64: the material rows a render's surfaces use (geo.material's, and the
    rows their Light Path variants remap them to: table.ray_remap)."""
    used = np.unique(np.asarray(geo.material, np.int64))
    for rows in (getattr(table, "ray_remap", None) or {}).values():
        used = np.union1d(used, np.take(np.asarray(rows, np.int64), used))
    return used


def maps_unread(settings, table, materials=None) -> bool:
    """Whether no caustic or glow photon can be read anywhere in a render with these
    RenderSettings and geometry.MaterialTable (materials: the rows its surfaces use,
    scene_materials; None: every row), given it builds a gather map (the split's
    condition, split_filter_glossy): the split is on above 1/pi and every material a
    camera path can read the maps at has a largest pdf_D below Filter Glossy
    (largest_pdfs: 1/pi on a Lambert-only one, its rough GGX layers' bound on the others;
    the camera path's min_ray_pdf only lowers it), so every photon there is blurred. Then every
    estimate is left out whole (DiffusePdf.none_unblurred at every lookup) and the caustic
    / glow shots need not be traced (render._photon_pass)."""
    fg = settings_filter_glossy(settings)
    if not fg > LAMBERT_PDF_MAX:
        return False
    bound = largest_pdfs(table)
    return bool(((bound if materials is None else np.take(bound, materials)) < fg).all())


def shots_unread(settings, geo, table, indirect: bool) -> bool:
    """Whether a render with these RenderSettings of geometry geo (MaterialTable table)
    reads no caustic or glow photon: indirect light (indirect: the effect plan's) with
    final gathering, and maps_unread over the materials its surfaces use. The one test
    behind render._photon_pass leaving those shots untraced and the effect report's
    caustics line saying so."""
    return bool(indirect and getattr(settings, "final_gather", True)
                and maps_unread(settings, table, scene_materials(geo, table)))


class DiffusePdf:
    """Cycles' one-sample MIS pdf (1/sr) at the camera's diffuse hits D (hit (N rows),
    bsdf.closures' lobes: the same numbers on the maps' side and the chains' side) of a
    direction wi leaving D, the camera's wo = hit.wo:

        pdf_D(wi) = (sum_l p_l pdf_l(wo, wi) + w_d max(cos_i, 0) / pi) / (sum_l p_l + w_d)

    (filterglossy.mis_pdf's form: p_l the non-diffuse lobes' weights, their albedo's max
    channel as choose_lobes, the pass lobe's included; w_d the diffuse albedo's mean
    channel; pdf_l principled.bsdf_pdf's reflective lobes). A row with no lobe of density
    beside the diffuse one takes w_d cos / pi / (w_d + p_pass), exactly cos / pi without
    a pass lobe (fgsplit46's bits). fg: the split's Filter Glossy.

    largest (N,): an upper bound of each row's pdf_D (1 / pi x that share for those
    rows, inf for the others); rows with largest < fg read no photon."""

    def __init__(self, ctx, hit, fg: float):
        from .bsdf import closures
        from .camerakernels import diffuse_pdf_weights
        from .closures import principled as pr
        # (the hit's cached lobes if it has them; else set up here and not cached, so
        # the camera side's own set-up, blurred or not, is left as it would be. A HitRows
        # view's fields not read yet stay so: reading them would copy its source's rows.)
        state = vars(hit)
        had = {k: state[k] for k in ("prm", "lobe_albedo") if k in state}
        prm, albedo = closures(ctx.table, hit, getattr(ctx, "geo", None))
        for k in ("prm", "lobe_albedo"):
            if k in had:
                setattr(hit, k, had[k])
            else:
                state.pop(k, None)
        albedo = np.ascontiguousarray(albedo, np.float64)
        n = len(albedo)
        self.fg = float(fg)
        self.prm = np.ascontiguousarray(prm, np.float64)
        # (choose_lobes' order: SPEC_LOBES) Each lobe's max channel, their sum, the
        # diffuse weight and the Lambert-only rows in one compiled pass, numpy's bits:
        # the numpy stage took ~2 % of Figure 6's camera pass (docs/performance.md,
        # "slow52", "hotspots53"). (A zero weight may differ in sign from numpy's
        # maximum, which no reader sees: bsdf_pdf weighs a lobe only where w > 0.0.)
        self.sel = np.empty((n, pr.N_LOBES))
        self.psum, self.wd = np.empty(n), np.empty(n)
        self.lambert = np.empty(n, bool)
        diffuse_pdf_weights(albedo, self.sel, self.psum, self.wd, self.lambert)
        self.plain = self.lambert & ~(self.psum > 0.0)  # (cos / pi exactly)
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(self.plain, 1.0, self.wd / (self.wd + self.psum))
        self.largest = np.where(self.lambert, share * LAMBERT_PDF_MAX, np.inf)
        # The camera path's min_ray_pdf before D (SurfaceHit.min_ray_pdf; None: inf, a
        # camera ray's first hit): Cycles' min_ray_pdf is the path's, so camera -> rough
        # metal -> D -> S blurs S by min(pdf_metal, pdf_D), on both sides alike.
        cam = getattr(hit, "min_ray_pdf", None)
        self.camera = None if cam is None else np.asarray(cam, np.float64)
        if self.camera is not None:
            self.largest = np.minimum(self.largest, self.camera)
        self.ns = np.asarray(hit.ns, np.float64)
        self.wo = np.ascontiguousarray(hit.wo, np.float64)

    def none_unblurred(self) -> bool:
        """No row can count a photon (every largest < fg): the maps' estimates are
        left out whole, as fgsplit46 did above 1 / pi on Lambert floors."""
        return not (self.largest >= self.fg).any()

    def pdf(self, rows, wi, ns=None) -> np.ndarray:
        """pdf_D (K,) of directions wi (K,3) (unit, leaving D) at hit rows rows (K,),
        at most the camera path's min_ray_pdf there; ns: the shading normals (N,3) by
        hit row (None: the hit's)."""
        from .camerakernels import bsdf_pdf_rows
        rows = np.asarray(rows, np.int64)
        wi = np.ascontiguousarray(wi, np.float64)
        nsr = np.take(self.ns if ns is None else ns, rows, axis=0)
        cos = np.einsum("ij,ij->i", wi, nsr)
        out = np.maximum(cos, 0.0) / math.pi
        mix = np.flatnonzero(~np.take(self.plain, rows))
        for a in range(0, len(mix), PDF_BLOCK):
            k = mix[a:a + PDF_BLOCK]
            r = rows[k]
            lobes = np.empty(len(k))
            # (the hits' lobes read in place by row: the same bits as bsdf_pdf_many on
            # their gathered rows, without the copies)
            bsdf_pdf_rows(self.prm, self.sel, r, np.ascontiguousarray(nsr[k]), self.wo,
                          np.ascontiguousarray(wi[k]), lobes)
            wd = np.take(self.wd, r)
            with np.errstate(invalid="ignore", divide="ignore"):
                out[k] = (lobes + wd * out[k]) / (np.take(self.psum, r) + wd)
        if self.camera is not None:
            out = np.minimum(out, np.take(self.camera, rows))
        return np.where(np.isnan(out), np.inf, out)

    def reject_for(self, pmap, sel):
        """The maps' per-photon test at the query rows sel (Q,) of the hit (the rows a
        _smooth_estimate reads): a callable (rows (H,) into sel, photons (H,) of pmap)
        -> (H,) bool, True where Cycles blurs the photon's path (min(pdf_D(-w_photon),
        Photons.blur_pdf) < fg: left out of the estimate)."""
        from .camerakernels import NO_CODES, NO_DIRECTIONS, diffuse_reject_pairs
        ph = pmap.photons
        stored = getattr(ph, "blur_pdf", None)
        stored = _NO_BLUR_PDF if stored is None else np.ascontiguousarray(stored)
        c = np.ascontiguousarray
        at = c(sel, np.int64)
        camera = _NO_CAMERA if self.camera is None else c(self.camera, np.float64)
        ns = c(self.ns, np.float64)
        # The photons' directions as the map stores them (float32 (P,3), or photonlayout's
        # (P,2) int16 octahedral codes), read in place by the kernel.
        direction = c(ph.direction)
        code = NO_CODES
        if direction.dtype == np.int16:
            direction, code = NO_DIRECTIONS, direction

        def reject(rows, photons):
            # (the query rows' hit rows, the photons' directions, pdf_D, the minimum with
            # their own min pdf and the test in one compiled pass per call, no
            # temporaries: the numpy test took 6.3 of the candles' 51 camera CPU s under
            # the profiler, docs/performance.md "percost54"; its blocks of 16,384 pairs
            # with their decoded directions 2.3 of 32, "percost55")
            out = np.empty(len(rows), bool)
            diffuse_reject_pairs(self.prm, self.sel, self.plain, self.wd, self.psum,
                                 self.largest, camera, ns, self.wo, float(self.fg), at,
                                 c(rows, np.int64), c(photons, np.int64), direction, code,
                                 stored, out)
            return out
        return reject


def window_glass(ctx):
    """(T,) bool: the window glass triangles (photonkernels.window_triangles) whose flat
    passages the render's shadow rays cross (ctx.shadow.flat_on), or None (none, or no
    passages); found once and kept on ctx."""
    from . import photonkernels as pk
    from .parallel import once_on
    shadow = getattr(ctx, "shadow", None)
    if shadow is None or not shadow.flat_on:
        return None

    def find():
        flat = pk.flat_glass_materials(ctx.table)
        if not len(flat) or not flat[ctx.geo.material].any():
            return None
        window = pk.window_triangles(ctx.geo, flat, pk.flat_thickness_limits(ctx.geo))
        return window if window.any() else None
    return once_on(ctx, "_split_window", find)


_NO_BLUR_PDF = np.zeros(0, np.float32)  # (diffuse_reject_pairs: no stored min pdfs)
_NO_CAMERA = np.zeros(0)  # (diffuse_reject_pairs: no camera path's min_ray_pdf)
PDF_BLOCK = 1 << 16  # DiffusePdf.pdf's pairs per call (its gathered lobe rows' memory)


def shadow_carried(light) -> bool:
    """Whether D's shadow rays sample light (its shadow rays on, lights.selection's
    condition: a constant world among them), so they carry its light through a window
    passage (GatherChains.emission). A mesh's sides no shadow ray samples are never
    carried (integrator._unsampled_meshes)."""
    from .visibility import SHADOW
    return bool(light.ray_kinds & SHADOW) and bool(light.shadow_sampled)


def raise_rows(prm, min_pdf, filter_glossy) -> None:
    """prm (N, principled.N_PACK) hits' packed lobes, in place: each row's microfacet
    alphas raised by filterglossy.raise_alphas to blur_alpha(filter_glossy, min_pdf[i])
    (min_pdf (N,) 1/sr)."""
    from .filterglossy import blur_alphas, raise_alphas_rows
    blur = np.ascontiguousarray(blur_alphas(filter_glossy, min_pdf), np.float64)
    raise_alphas_rows(prm, blur)


class GatherChains:
    """One level-0 gather_indirect call's chain state for the split: per gathering hit
    row, the min_pdf (1/sr) of its current ray's chain (D's pdf, d_pdf: a DiffusePdf of
    the gathering hits, then the minimum with each continuation's pdf) and whether the vertex its ray left was blurred. fg:
    split_filter_glossy(ctx) > 0. E (n,3) is the gather's irradiance sum (tp pi L / G per
    ray, as the lookups add).

    The light the maps leave out is found by light sampling alone at each blurred
    vertex (its reflective lobes and its rough refraction, both in full: no multiple
    importance sampling), so the continued rays count only the emitters light sampling
    leaves to the continuation (integrator.MODE_CONTINUATION: a constant world, a light
    without shadow rays) and the mesh sides no shadow ray samples. A delta lamp through
    a blurred glass ball is then found, as Cycles finds it (figure8_caustic's spot).

    A gather ray's own hit that is a next-event pane (for the suns and the world) or a
    lamp's shade (for that lamp) leaves those lights to their shadow rays at D
    (shadelight.next_event_tri, the photons' F_PANE table): no light sample of them
    through its refraction, no emission of them on the rays it refracts (self.carried;
    docs/compatibility.md "splitpane47"). So do a window glass's entry and exit at the
    first two vertices for every light D's shadow rays sample (a flat passage they
    cross: window_glass; shadow_carried), not for a light without shadow rays or a
    mesh side none samples (splitfix47); so do transparent passes (leaves55) and, in any
    order and number, both (self.passages: gatherpassages.GatherPassages' state, as
    camera_passage steps it; a pane's carried lights stay carried on past transparent
    passes: passages55). A pane met past transparent passes alone carries its lights as
    at the first vertex: its shadow rays cross those passes (panelight._past_passes,
    passages56)."""

    def __init__(self, ctx, n: int, fg: float, d_pdf: DiffusePdf):
        from . import integrator as it
        self.ctx, self.fg = ctx, fg
        self.d_pdf = d_pdf
        self.min_pdf = np.full(n, np.inf)
        self.from_blurred = np.zeros(n, bool)
        self.modes = it.light_modes(ctx)
        # The lights the continuations meet in full (those light sampling leaves to them).
        self.continuation_lights = [li for li, m in enumerate(self.modes)
                                    if m == it.MODE_CONTINUATION]
        # ... but the glossy rays leave a reflection-only lamp (Diffuse visibility off) to
        # the vertex's reflective lobes' shadow rays (integrator.reflection_only_lights).
        self.reflection_only = it.reflection_only_lights(ctx)
        self.unsampled = it._unsampled_meshes(ctx)
        self._vertex = None  # (q, psum, w_diffuse, ns) of vertex()'s hits
        # The lights next-event panes and lamp shades carry by their own shadow rays
        # (shadelight.next_event_tri): (light index, triangle table) for each light with
        # one. Where a chain's first vertex (the gather ray's hit) refracts such a light
        # from a triangle of its table, the path L -> pane / shade -> D is D's direct
        # light (panelight / shadelight at D; its photons are direct-kind, out of the
        # caustic map): the chain neither samples that light there nor counts its
        # emission on the rays refracted there.
        from .shadelight import next_event_tri
        self.carried = []
        for li, light in enumerate(ctx.lights):
            tri = next_event_tri(ctx, light)
            if tri is not None and len(tri):
                self.carried.append((li, tri))
        # Per gathering hit row: a bit per self.carried entry, set where the vertex its
        # ray left (refracted through) carries that light (emission's exclusion).
        self.left_carrier = np.zeros(n, np.int64)
        # Window glass (photonkernels.window_triangles: flat slabs that shadow rays cross
        # as flat passages, engine/shadowtransmittance.py; None: none, or no passages):
        # a gather ray that enters it at its first vertex and leaves by its second
        # crossed a passage, whose light beyond is D's shadow rays' for every light they
        # sample (its photons leave the passage as the kind they entered: not caustic).
        # Those two vertices sample no light through their refraction and the rays
        # refracted there count no emission of those lights (shadow_carried). in_glass: per gathering hit row, whether its ray
        # entered window glass at its first vertex; left_passage: whether it was
        # refracted at such a vertex.
        self.window = window_glass(ctx)
        self.in_glass = np.zeros(n, bool)
        self.left_passage = np.zeros(n, bool)
        # Per gathering hit row: whether its ray has crossed nothing since D but the
        # surfaces D's shadow rays cross - transparent passes (alpha cut-outs, Transparent
        # BSDFs) and window glass, in any order and number: the gather rays' passage
        # state of engine/gatherpassages.py (GatherPassages.clear, camera_passage's rule),
        # stepped at each continuation from the hits vertex() keeps; None: shadow rays
        # cross no surface, so no ray is clear past its first hit. Light through those
        # alone is D's direct light, carried by its shadow rays (docs/design.md,
        # Transparent shadows): such a ray counts no emission of a light they sample, as
        # a window passage's (leaves55: a constant world seen through cut-out leaves was
        # counted twice, the leaves 1.08-1.20x Cycles; passages55: a card behind a window
        # pane, or before it).
        from .gatherpassages import GatherPassages
        self.passages = GatherPassages.for_context(ctx, n)
        self._hits = None  # (prim (M,), wo (M,3), p (M,3), hit rows (M,)) of vertex()'s y
        self._depth = 0
        # At the current vertex: (carried bits (M,) or None, passage (M,) bool or None,
        # ng (M,3), wo (M,3)) by row of vertex()'s hits; None: nothing carried there.
        self._carrier = None

    def start(self, idx, d, ns):
        """The gather rays (hit rows idx (K,), directions d (K,3)) leave D (shading
        normals ns (n,3) by hit row): min_pdf = D's one-sample MIS pdf (DiffusePdf, the
        maps' own predicate; cos / pi on a Lambert-only D)."""
        self.min_pdf[idx] = self.d_pdf.pdf(idx, d, ns)
        if self.passages is not None:
            self.passages.start(idx)

    def clear_rows(self, idx) -> np.ndarray:
        """(K,) bool: per hit row of idx (K,), whether its ray crossed nothing since D but
        transparent passes and window passages (self.passages' state; all False without
        one)."""
        if self.passages is None:
            return np.zeros(len(idx), bool)
        return np.take(self.passages.clear, idx) > 0.0

    def carrier_bits(self, prim, panes_only=False) -> np.ndarray:
        """(K,) int64: per triangle row of prim (K,), bit j set where it carries the light
        of self.carried[j] by next-event shadow rays (shadelight.carried_at; panes_only:
        a next-event pane's triangles alone, not a lamp shade's)."""
        from .shadelight import carried_at
        bits = np.zeros(len(prim), np.int64)
        for j, (_, tri) in enumerate(self.carried):
            at = (np.take(tri, prim) >= 0) if panes_only else carried_at(tri, prim)
            bits |= at.astype(np.int64) << j
        return bits

    def vertex(self, y, rows_idx, tp, E, G, rng, counters, counts=None, depth=0,
               used=None):
        """At chain hits y (the rows that continue: their hit rows rows_idx (M,), ray
        throughputs tp (M,3)): blur y's lobes by the chains' min_pdf (y.prm raised in
        place after the closures' set-up, the albedos kept), add light sampling through
        the blurred lobes (radiance towards y.wo) at the blurred rows to E, and return the
        continuation's lobe choice (integrator.lobe_choice of the unblurred albedos) for
        continue_specular. counts: (M,4) int64 the camera-side bounce counts the hits
        are reached with (B_TOTAL order, D's diffuse bounce included; None: D's alone):
        a hit past the Light Paths limits takes no light sample (Cycles shades no vertex
        a terminated path reaches: docs/design.md, Bounce limits), and the shadow rays
        of the others cross flat passages as those limits allow.
        depth: the chain's vertex number (0: the gather rays' own
        hits), where a next-event pane or lamp shade's refraction leaves its lights to
        panelight / shadelight (self.carried, depth 0; a pane deeper too where the ray
        met it across transparent passes alone: passages56) and window glass its
        passage's to every light's shadow rays (self.window, depths 0 and 1; deeper
        where met clear).
        used: (M,) int64 the transparent passes the hits' paths crossed (camera path and
        chain; None: none): their shadow rays cross only the rest of Light Paths > Max
        Bounces > Transparent, as every shadow ray of a path (transparent48)."""
        from . import integrator as it
        from .bsdf import closures
        from .glasslight import rough_transmission_rows, transmitted_light
        ctx = self.ctx
        prm, albedo = closures(ctx.table, y, ctx.geo)
        mp = np.ascontiguousarray(self.min_pdf[rows_idx])
        raise_rows(prm, mp, self.fg)
        choice = it.lobe_choice(albedo, tp)
        # (continued's Cycles MIS pdfs: the unblurred lobe weights, the diffuse one's mean
        # channel, by row of y)
        from .closures.principled import L_DIFFUSE
        wd = np.asarray(albedo, np.float64)[:, L_DIFFUSE, :].mean(axis=1)  # (as DiffusePdf's)
        self._vertex = (choice[1], choice[3], wd, np.asarray(y.ns, np.float64))
        self._carrier = None
        self._depth = depth
        bits = passage = None
        if self.carried and (depth == 0 or self.passages is not None):
            bits = self.carrier_bits(np.asarray(y.prim, np.int64), panes_only=depth > 0)
            if depth > 0:
                # (deeper: a pane met across transparent passes alone, which its shadow
                # rays cross before it, panelight._past_passes; a shade's cross none)
                bits = np.where(self.passages.passes_only(rows_idx), bits, 0)
            bits = bits if bits.any() else None
        prim_y = np.asarray(y.prim, np.int64)
        if self.passages is not None:
            self._hits = (prim_y, np.asarray(y.wo, np.float64), np.asarray(y.p, np.float64),
                          np.asarray(rows_idx, np.int64))
        if self.window is not None:
            passage = None
            if depth <= 1:
                passage = np.take(self.window, prim_y)
                if depth == 1:
                    passage &= np.take(self.in_glass, rows_idx)
            if depth >= 1 and self.passages is not None:
                # (deeper: window glass met across passages alone, or left from inside
                # glass entered so: a card before the window)
                deep = np.take(self.window, prim_y) & self.passages.at_passage(rows_idx)
                passage = deep if passage is None else passage | deep
            passage = passage if passage is not None and passage.any() else None
        if bits is not None or passage is not None:
            self._carrier = (bits, passage, np.asarray(y.ng, np.float64),
                             np.asarray(y.wo, np.float64))
        counts = self.vertex_counts(len(mp), counts)
        blurred = np.flatnonzero((mp < self.fg) & self.shaded(counts))
        if not len(blurred):
            return choice
        counts = np.ascontiguousarray(counts[blurred])
        if used is not None:
            used = np.ascontiguousarray(np.take(np.asarray(used, np.int64), blurred))
        sub = y if len(blurred) == len(mp) else y.take(blurred)
        if sub is not y:
            sub.prm = np.ascontiguousarray(prm[blurred])
        n = len(blurred)
        # Light sampling by the blurred reflective lobes alone (no diffuse f: the lookups
        # read those), weighted in full (sel 0: the continuation's pdf 0 in the power
        # heuristic).
        no_sel = np.zeros((n, choice[0].shape[1]))
        L = it.direct_irradiance(ctx, sub, rng, counters, bsdf=(np.zeros((n, 3)), sub.prm,
                                                               no_sel), counts=counts,
                                      used=used)
        # ... and by their rough refraction (engine/glasslight.py), in full as well.
        # At a first vertex that is a next-event pane or shade, its carried lights take
        # no sample (their modes MODE_CONTINUATION: light_sample_list skips them), by
        # groups of rows with the same carried set (one group, the plain call, elsewhere).
        gl = rough_transmission_rows(sub.prm, np.arange(n, dtype=np.int64))
        if self._carrier is not None and self._carrier[1] is not None:
            gl = gl[~np.take(self._carrier[1], blurred[gl])]  # (a passage's: none)
        bits = (np.zeros(len(gl), np.int64)
                if self._carrier is None or self._carrier[0] is None
                else np.take(self._carrier[0], blurred[gl]))
        for b in np.unique(bits):
            rows = gl[bits == b]
            modes = self.modes
            if b:
                modes = self.modes.copy()
                for j, (li, _) in enumerate(self.carried):
                    if b >> j & 1:
                        modes[li] = it.MODE_CONTINUATION
            samples = it.light_sample_list(ctx, len(rows), rng, modes=modes)
            L[rows] += transmitted_light(ctx, sub, rows, sub.prm, no_sel, np.ones(n),
                                         modes, samples, counters,
                                         counts=np.ascontiguousarray(counts[rows]),
                                         used=None if used is None else used[rows])
        add = np.take(np.asarray(tp, np.float64), blurred, axis=0) * (math.pi / G) * L
        # (a gather step has one ray a gathering hit: rows_idx holds distinct rows, so the
        # indexed add is np.add.at's sums, without its per-element loop)
        E[rows_idx[blurred]] += add
        return choice

    # D's diffuse bounce: the counts (B_TOTAL order) of a chain's first hit past D on a
    # camera path that reached D with none.
    D_BOUNCE = (1, 1, 0, 0)

    @classmethod
    def vertex_counts(cls, m, counts=None) -> np.ndarray:
        """(m,4) int64: the chain hits' counts as given, or D's bounce alone (None)."""
        if counts is None:
            return np.broadcast_to(np.asarray(cls.D_BOUNCE, np.int64), (m, 4))
        return np.asarray(counts, np.int64)

    def shaded(self, counts) -> np.ndarray:
        """(M,) bool: the chain hits reached with counts (M,4) that Cycles still shades
        (light sample and bounce): every count within the scene's Light Paths limits
        (chaincounts.within, as the lookups and the photons' usable test count them, so
        the maps and the chains drop the same paths)."""
        from . import chaincounts
        return chaincounts.within(counts, self.ctx.settings.bounce_limits)

    def continued(self, rows_idx, pdf, rows_y=None, d=None, passed=None):
        """The continued rays' chains (hit rows rows_idx (K,), continuation pdfs (K,):
        continue_specular's want_pdf, inf for mirror-like lobes and refractions; rows_y
        (K,) the rows of the last vertex's y they left, d (K,3) their directions):
        whether the vertex they left was blurred, then min_pdf lowered by Cycles'
        one-sample MIS pdf of the continuation (filterglossy.mis_pdf, the form the
        photons' reverse pdfs take: one predicate on both sides). rows_y None: by pdf
        itself. passed: (K,) bool, the rays the transparent pass lobe made
        (continue_specular's want_pass; None: none was a pass): a pane's carried lights
        stay carried past those. Whether a ray is still clear (clear_rows) is
        self.passages' step on the vertex's hits (rows_y None: no ray is)."""
        from .filterglossy import mis_pdf
        self.from_blurred[rows_idx] = self.min_pdf[rows_idx] < self.fg
        if self.passages is not None:
            if rows_y is not None and self._hits is not None:
                # (window passages and transparent passes in any order: camera_passage's
                # rule on the vertex's hits)
                prim_y, wo_y, p_y, idx_y = self._hits
                self.passages.step(prim_y, -wo_y, p_y, idx_y, rows_y, d)
            else:
                self.passages.end(rows_idx)  # (no hits known: no passage shown)
        # The rays refracted through a first vertex that carries lights (vertex(first)):
        # those lights' emission is panelight's / shadelight's, and stays theirs on past
        # transparent passes (a pane's shadow rays cross those beyond it: panelight).
        if self._depth == 0 or passed is None:
            self.left_carrier[rows_idx] = 0
        else:
            self.left_carrier[rows_idx] = np.where(np.asarray(passed, bool),
                                                   np.take(self.left_carrier, rows_idx), 0)
        self.left_passage[rows_idx] = False
        if self._depth == 0:
            self.in_glass[rows_idx] = False
        if self._carrier is not None and rows_y is not None and len(rows_idx):
            bits, passage, ng, wo = self._carrier
            rows_y = np.asarray(rows_y, np.int64)
            ngr = np.take(ng, rows_y, axis=0)
            through = (np.einsum("ij,ij->i", ngr, np.asarray(d, np.float64))
                       * np.einsum("ij,ij->i", ngr, np.take(wo, rows_y, axis=0))) < 0.0
            if bits is not None:
                # (|: past transparent passes, an earlier pane's carried lights stay)
                self.left_carrier[rows_idx] |= np.where(through, np.take(bits, rows_y), 0)
            if passage is not None:
                left = through & np.take(passage, rows_y)
                self.left_passage[rows_idx] = left
                if self._depth == 0:
                    self.in_glass[rows_idx] = left
        if rows_y is not None and self._vertex is not None and len(rows_idx):
            q, psum, wd, ns = self._vertex
            rows_y = np.asarray(rows_y, np.int64)
            d = np.asarray(d, np.float64)
            cos_i = np.einsum("ij,ij->i", np.take(ns, rows_y, axis=0), d)
            pdf = mis_pdf(pdf, np.take(q, rows_y), np.take(psum, rows_y),
                          np.take(wd, rows_y), cos_i)
        self.min_pdf[rows_idx] = np.minimum(self.min_pdf[rows_idx], pdf)

    def emission(self, rows_idx, o, d, tp, cls, E, G, counts=None, used=None, left=None):
        """The emitters that the continued rays (hit rows rows_idx (K,), origins o,
        directions d (K,3), throughputs tp (K,3), ray classes cls (K,)) leaving a blurred
        vertex meet and light sampling leaves to them: the lights of MODE_CONTINUATION
        (lamp surfaces, sun discs, a constant world) and the mesh sides no shadow ray
        samples. Added to E in full (tp pi Le / G). A background that is no light (no
        photons either) is not counted. counts: (K,4) the counts the vertex they left was
        reached with (vertex's; None: D's bounce alone): past the limits it took no
        bounce. used: (K,) int64 the transparent passes the rays' paths made so far
        (camera path and chain; None: none): each lamp a ray meets is a pass, as on the
        camera path (integrator._trace_paths: lamp_passes, first_at_each_distance), and the
        pass that reaches Light Paths > Max Bounces > Transparent ends the path at that
        lamp, its light added, nothing past it. left: (K,) int64 the triangles the rays
        left (the vertex's), for Light Linking (integrator.lamps_met: a lamp that does
        not light it is not met; a lamp with Shadow Linking is met past its blockers
        alone, wherever it lies, and is no pass); None: no Light Linking. Returns None
        (no lamp met) or (passes (K,) int64 the lamp passes each ray made, ended (K,)
        bool the rays whose path ended at a lamp: the caller ends those chains)."""
        from . import integrator as it
        from .bsdf import surface_hit
        from . import worldmedium
        ctx = self.ctx
        if not self.continuation_lights and not self.unsampled:
            return None
        go = np.flatnonzero(self.from_blurred[rows_idx]
                            & self.shaded(self.vertex_counts(len(rows_idx), counts)))
        if not len(go):
            return None
        k_all = len(rows_idx)
        rows_idx = rows_idx[go]
        # Rays refracted through a window passage: its light is D's shadow rays' only for
        # the lights they sample (shadow_carried); a light without shadow rays and the
        # mesh sides none samples stay the chains' (splitfix47: Emission Sampling None
        # through a slab was lost, 0.037 for 1.46). So do the rays that crossed only
        # transparent passes and window passages since D (clear_rows: D's shadow rays
        # cross those and carry it).
        passage = np.take(self.left_passage, rows_idx) | self.clear_rows(rows_idx)
        k = len(go)
        cls = np.ascontiguousarray(np.broadcast_to(np.asarray(cls, np.int64), (len(d),))[go])
        o = np.ascontiguousarray(np.take(o, go, axis=0), np.float64)
        d = np.ascontiguousarray(np.take(d, go, axis=0), np.float64)
        tp = np.take(np.asarray(tp, np.float64), go, axis=0)
        t, prim, u, v = ctx.accel.intersect(o, d, cls=cls)
        t = np.where(prim >= 0, t, np.inf)
        Le = np.zeros((k, 3))
        carrier = np.take(self.left_carrier, rows_idx)
        carried = {li: j for j, (li, _) in enumerate(self.carried)}

        def counted(li, sel=slice(None)):
            """(rows,) bool: the rays (of sel) that count light li's emission (not those
            refracted through a first vertex that carries it, nor through a window
            passage where D's shadow rays sample it)."""
            out = np.ones(k, bool)[sel]
            if li in carried:
                out &= (carrier[sel] >> carried[li] & 1) == 0
            if shadow_carried(ctx.lights[li]):
                out &= ~passage[sel]
            return out

        # Every lamp the rays see is a transparent pass (the ray goes on past it, as in
        # Cycles: the camera path's rule, integrator._trace_paths), the light of those of
        # MODE_CONTINUATION added, up to the pass that reaches the limit.
        continuation = set(self.continuation_lights)
        links = getattr(ctx, "links", None)
        met, linked = it.lamps_met(ctx, o, d, t, cls,
                                   None if left is None or links is None
                                   else np.take(np.asarray(left, np.int64), go))
        t_end = None
        passes = np.zeros(k, np.int64)
        if met:
            before = (np.zeros(k, np.int64) if used is None
                      else np.take(np.asarray(used, np.int64), go))
            t_limit = max(int(ctx.settings.transparent_max_bounces), 1)
            t_end, total = it.lamp_passes(met, k, before, t_limit)
            passes = total - before
        for li, light, rows, tl_rows, L in met:
            if li not in continuation:
                continue
            add = counted(li, rows)
            if t_end is not None:
                add &= tl_rows <= np.take(t_end, rows)  # (past the ending pass: not met)
            if self.reflection_only[li]:
                add &= np.take(cls, rows) != it.GLOSSY  # (its light sampled at the vertex)
            Le[rows[add]] += L[add]
        for li, light, rows, _, L in linked:
            # (Shadow Linking: its light past its blockers alone, as _trace_paths adds it)
            if li not in continuation:
                continue
            add = counted(li, rows)
            if self.reflection_only[li]:
                add &= np.take(cls, rows) != it.GLOSSY
            Le[rows[add]] += L[add]
        ended = np.zeros(k, bool) if t_end is None else np.isfinite(t_end)
        prim = np.where(ended, -2, prim)  # (ended at the lamp: nothing behind it)
        surf = np.flatnonzero(prim >= 0)
        if len(surf) and self.unsampled:
            y = surface_hit(ctx.geo, ctx.table, prim[surf], u[surf], v[surf], d[surf])
            if y.emission is not None and np.any(y.emission > 0):
                Le[surf] += it.unsampled_emission(ctx, self.unsampled, prim[surf], d[surf],
                                                  np.asarray(y.emission, np.float64))
        miss = np.flatnonzero(prim == -1)
        if len(miss):
            dm = np.take(d, miss, axis=0)
            for li in self.continuation_lights:
                light = ctx.lights[li]
                # (the world's light is the background itself; a sun's, its disc)
                sun = (worldmedium.background(ctx.scene, dm) if light.kind == it.WORLD
                       else light.seen_at_infinity(dm))
                if sun is not None:
                    use = counted(li, miss)
                    if self.reflection_only[li]:
                        use &= cls[miss] != it.GLOSSY
                    Le[miss] += np.where(np.reshape(use, (-1, 1)), sun, 0.0)
        add = tp * (math.pi / G) * Le
        np.add.at(E, rows_idx, add)
        if not met:
            return None
        out_passes, out_ended = np.zeros(k_all, np.int64), np.zeros(k_all, bool)
        out_passes[go], out_ended[go] = passes, ended
        return out_passes, out_ended
