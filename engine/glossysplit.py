"""Cycles' Filter Glossy on the photon maps' paths: the exact split between the caustic /
glow maps and the final-gather chains (docs/compatibility.md, "filterglossy45" parts 2-3,
and "fgsplit46").

A caustic or glow photon's path L S1 ... Sm D is, to Cycles, the camera path D -> Sm ->
... -> S1 -> L, whose lobes Filter Glossy blurs by the camera side's pdfs (Cycles'
surface_shader_prepare_closures: min_ray_pdf / Filter Glossy below 1 widens every later
microfacet lobe to alpha 0.5 sqrt(1 - min_ray_pdf / Filter Glossy)). Cycles blurs the
path iff min(pdf_D, pdf_Sm, ..., pdf_S2) < Filter Glossy, pdf_D the diffuse hit D's pdf
of the direction the photon came from. A photon cannot carry blurred light (a smooth
lobe's sample has no density under the blurred one), so:
- the maps' estimate at D counts only the photons Cycles does not blur;
- the final-gather chains from D (gather_indirect -> continue_specular, vertices since
  D all non-diffuse) blur their lobes by the chain's own min_pdf (starting at D's pdf of
  the gather direction, cos / pi) and add, at every blurred vertex, the light the maps
  now leave out: light sampling through the blurred lobes, reflective and refractive
  (in full), and what the continued rays meet of the emitters light sampling leaves to
  them (a constant world). The same predicate on the same path decides both sides: each
  path is counted once.

Built here for Filter Glossy above 1 / pi (Cycles' default 1.0 among them) with D's pdf
its Lambert lobe's, cos / pi <= 1 / pi: every path is blurred, so the maps' estimates at
D are left out whole and no photon needs its own test. Below 1 / pi the split is off
(the render as without it): the per-photon test needs each photon's reverse pdfs
(docs/compatibility.md, "fgsplit46", what is left).
"""
from __future__ import annotations

import math

import numpy as np

from .closures import principled as pr

# The split on (Filter Glossy above LAMBERT_PDF_MAX, photon mapping with final gathering);
# False: the maps and chains as without it (Cycles at Filter Glossy 0), whatever the
# scene's Filter Glossy.
ENABLED = True
# The largest pdf of a Lambert bounce's direction (cos / pi at the normal), 1/sr.
LAMBERT_PDF_MAX = 1.0 / math.pi


def settings_filter_glossy(settings) -> float:
    """The Filter Glossy the split applies with these RenderSettings
    (cycles_filter_glossy), or 0.0 where it is off: ENABLED false, no photon mapping or
    no final gathering, or Filter Glossy at most LAMBERT_PDF_MAX."""
    fg = float(getattr(settings, "cycles_filter_glossy", 0.0) or 0.0)
    if (not ENABLED or not settings.photon_mapping
            or not getattr(settings, "final_gather", True) or not fg > LAMBERT_PDF_MAX):
        return 0.0
    return fg


def split_filter_glossy(ctx) -> float:
    """settings_filter_glossy of the render's settings, 0.0 also where the render has no
    gather map (no final gathering: nothing to carry the maps' light)."""
    if getattr(ctx, "gather_map", None) is None:
        return 0.0
    return settings_filter_glossy(ctx.settings)


def maps_blurred(ctx) -> bool:
    """Whether the caustic and glow maps' estimates at the camera's diffuse hits are
    left out whole (every photon's path is one Cycles blurs: the split is on)."""
    return split_filter_glossy(ctx) > 0.0


def raise_rows(prm, min_pdf, filter_glossy) -> None:
    """prm (N, principled.N_PACK) hits' packed lobes, in place: each row's microfacet
    alphas raised as filterglossy.raise_alphas raises them, to blur_alpha(filter_glossy,
    min_pdf[i]) (min_pdf (N,) 1/sr); the same values, in numpy (no kernel here: this
    module's edits keep the kernels' cache)."""
    from .effects import filter_glossy_alpha
    blur = np.asarray(filter_glossy_alpha(filter_glossy, min_pdf), np.float64)
    for col in (pr.P_SPEC_ALPHA, pr.P_METAL_ALPHA, pr.P_GLASS_ALPHA, pr.P_COAT_ALPHA):
        np.maximum(prm[:, col], blur, out=prm[:, col])
    aniso = prm[:, pr.P_AX] > 0.0
    if aniso.any():
        for col in (pr.P_AX, pr.P_AY):
            prm[aniso, col] = np.maximum(prm[aniso, col], blur[aniso])


class GatherChains:
    """One level-0 gather_indirect call's chain state for the split: per gathering hit
    row, the min_pdf (1/sr) of its current ray's chain (D's cos / pi, then the minimum
    with each continuation's pdf) and whether the vertex its ray left was blurred. fg:
    split_filter_glossy(ctx) > 0. E (n,3) is the gather's irradiance sum (tp pi L / G per
    ray, as the lookups add).

    The light the maps leave out is found by light sampling alone at each blurred
    vertex (its reflective lobes and its rough refraction, both in full: no multiple
    importance sampling), so the continued rays count only the emitters light sampling
    leaves to the continuation (integrator.MODE_CONTINUATION: a constant world, a light
    without shadow rays) and the mesh sides no shadow ray samples. A delta lamp through
    a blurred glass ball is then found, as Cycles finds it (figure8_caustic's spot)."""

    def __init__(self, ctx, n: int, fg: float):
        from . import integrator as it
        self.ctx, self.fg = ctx, fg
        self.min_pdf = np.full(n, np.inf)
        self.from_blurred = np.zeros(n, bool)
        self.modes = it.light_modes(ctx)
        # The lights the continuations meet in full (those light sampling leaves to them).
        self.continuation_lights = [li for li, m in enumerate(self.modes)
                                    if m == it.MODE_CONTINUATION]
        self.unsampled = it._unsampled_meshes(ctx)

    def start(self, idx, d, ns):
        """The gather rays (hit rows idx (K,), directions d (K,3)) leave D (shading
        normals ns (n,3) by hit row): min_pdf = D's Lambert pdf cos / pi."""
        cos = np.einsum("ij,ij->i", np.asarray(d, np.float64), np.take(ns, idx, axis=0))
        self.min_pdf[idx] = np.maximum(cos, 0.0) / math.pi

    def vertex(self, y, rows_idx, tp, E, G, rng, counters):
        """At chain hits y (the rows that continue: their hit rows rows_idx (M,), ray
        throughputs tp (M,3)): blur y's lobes by the chains' min_pdf (y.prm raised in
        place after the closures' set-up, the albedos kept), add light sampling through
        the blurred lobes (radiance towards y.wo) at the blurred rows to E, and return the
        continuation's lobe choice (integrator.lobe_choice of the unblurred albedos) for
        continue_specular."""
        from . import integrator as it
        from .bsdf import closures
        from .glasslight import rough_transmission_rows, transmitted_light
        ctx = self.ctx
        prm, albedo = closures(ctx.table, y, ctx.geo)
        mp = np.ascontiguousarray(self.min_pdf[rows_idx])
        raise_rows(prm, mp, self.fg)
        choice = it.lobe_choice(albedo, tp)
        blurred = np.flatnonzero(mp < self.fg)
        if not len(blurred):
            return choice
        sub = y if len(blurred) == len(mp) else y.take(blurred)
        if sub is not y:
            sub.prm = np.ascontiguousarray(prm[blurred])
        n = len(blurred)
        # Light sampling by the blurred reflective lobes alone (no diffuse f: the lookups
        # read those), weighted in full (sel 0: the continuation's pdf 0 in the power
        # heuristic).
        no_sel = np.zeros((n, choice[0].shape[1]))
        L = it.direct_irradiance(ctx, sub, rng, counters, bsdf=(np.zeros((n, 3)), sub.prm,
                                                               no_sel))
        # ... and by their rough refraction (engine/glasslight.py), in full as well.
        gl = rough_transmission_rows(sub.prm, np.arange(n, dtype=np.int64))
        if len(gl):
            samples = it.light_sample_list(ctx, len(gl), rng, modes=self.modes)
            L[gl] += transmitted_light(ctx, sub, gl, sub.prm, no_sel, np.ones(n),
                                       self.modes, samples, counters)
        rows = rows_idx[blurred]
        add = np.take(np.asarray(tp, np.float64), blurred, axis=0) * (math.pi / G) * L
        np.add.at(E, rows, add)
        return choice

    def continued(self, rows_idx, pdf):
        """The continued rays' chains (hit rows rows_idx (K,), continuation pdfs (K,),
        inf for mirror-like lobes and refractions): whether the vertex they left was
        blurred, then min_pdf lowered."""
        self.from_blurred[rows_idx] = self.min_pdf[rows_idx] < self.fg
        self.min_pdf[rows_idx] = np.minimum(self.min_pdf[rows_idx], pdf)

    def emission(self, rows_idx, o, d, tp, cls, E, G):
        """The emitters that the continued rays (hit rows rows_idx (K,), origins o,
        directions d (K,3), throughputs tp (K,3), ray classes cls (K,)) leaving a blurred
        vertex meet and light sampling leaves to them: the lights of MODE_CONTINUATION
        (lamp surfaces, sun discs, a constant world) and the mesh sides no shadow ray
        samples. Added to E in full (tp pi Le / G). A background that is no light (no
        photons either) is not counted."""
        from . import integrator as it
        from .bsdf import surface_hit
        from . import worldmedium
        ctx = self.ctx
        if not self.continuation_lights and not self.unsampled:
            return
        go = np.flatnonzero(self.from_blurred[rows_idx])
        if not len(go):
            return
        rows_idx = rows_idx[go]
        k = len(go)
        cls = np.ascontiguousarray(np.broadcast_to(np.asarray(cls, np.int64), (len(d),))[go])
        o = np.ascontiguousarray(np.take(o, go, axis=0), np.float64)
        d = np.ascontiguousarray(np.take(d, go, axis=0), np.float64)
        tp = np.take(np.asarray(tp, np.float64), go, axis=0)
        t, prim, u, v = ctx.accel.intersect(o, d, cls=cls)
        t = np.where(prim >= 0, t, np.inf)
        Le = np.zeros((k, 3))
        at_lamp = np.zeros(k, bool)
        for li in self.continuation_lights:
            light = ctx.lights[li]
            if not light.has_surface:
                continue
            sees = (cls & light.ray_kinds) != 0
            if not sees.any():
                continue
            mask, tl, L = light.intersect(o, d, t)
            if L is None:
                continue
            mask = mask & sees
            if mask.any():
                Le[mask] += L[mask]
                t = np.where(mask, tl, t)
                at_lamp |= mask
        surf = np.flatnonzero((prim >= 0) & ~at_lamp)
        if len(surf) and self.unsampled:
            y = surface_hit(ctx.geo, ctx.table, prim[surf], u[surf], v[surf], d[surf])
            if y.emission is not None and np.any(y.emission > 0):
                Le[surf] += it.unsampled_emission(ctx, self.unsampled, prim[surf], d[surf],
                                                  np.asarray(y.emission, np.float64))
        miss = np.flatnonzero((prim < 0) & ~at_lamp)
        if len(miss):
            dm = np.take(d, miss, axis=0)
            for li in self.continuation_lights:
                light = ctx.lights[li]
                # (the world's light is the background itself; a sun's, its disc)
                sun = (worldmedium.background(ctx.scene, dm) if light.kind == it.WORLD
                       else light.seen_at_infinity(dm))
                if sun is not None:
                    Le[miss] += sun
        add = tp * (math.pi / G) * Le
        np.add.at(E, rows_idx, add)
