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
  now leave out: light sampling through the blurred reflective lobes (in full: the
  reflected continuations count no emission) and the emitters the continuation meets
  through the transmitting lobes (in full: light sampling takes none through them).
  The same predicate on the same path decides both sides: each path is counted once.

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
    with each continuation's pdf). fg: split_filter_glossy(ctx) > 0. E (n,3) is the
    gather's irradiance sum (tp pi L / G per ray, as the lookups add). added: the same
    sum of what the chains add here alone (a bench and the tests read it)."""

    def __init__(self, ctx, n: int, fg: float):
        from . import integrator as it
        self.ctx, self.fg = ctx, fg
        self.min_pdf = np.full(n, np.inf)
        self.added = np.zeros((n, 3))
        self.modes = it.light_modes(ctx)
        # The lights the reflected continuations meet in full: those light sampling
        # leaves to the continuation (MODE_CONTINUATION: a constant world, a lamp
        # without shadow rays).
        self.continuation_lights = [li for li, m in enumerate(self.modes)
                                    if m == it.MODE_CONTINUATION]
        self.world_light = any(light.kind == it.WORLD for light in ctx.lights)
        self.world_on_reflection = not any(
            light.kind == it.WORLD and self.modes[li] != it.MODE_CONTINUATION
            for li, light in enumerate(ctx.lights))

    def start(self, idx, d, ns):
        """The gather rays (hit rows idx (K,), directions d (K,3)) leave D (shading
        normals ns (n,3) by hit row): min_pdf = D's Lambert pdf cos / pi."""
        cos = np.einsum("ij,ij->i", np.asarray(d, np.float64), np.take(ns, idx, axis=0))
        self.min_pdf[idx] = np.maximum(cos, 0.0) / math.pi

    def vertex(self, y, rows_idx, tp, E, G, rng, counters):
        """At chain hits y (the rows that continue: their hit rows rows_idx (M,), ray
        throughputs tp (M,3)): blur y's lobes by the chains' min_pdf (y.prm raised in
        place after the closures' set-up, the albedos kept), add light sampling through
        the blurred reflective lobes (radiance towards y.wo, in full) to E, and return
        the continuation's lobe choice (integrator.lobe_choice of the unblurred albedos)
        for continue_specular."""
        from . import integrator as it
        from .bsdf import closures
        ctx = self.ctx
        prm, albedo = closures(ctx.table, y, ctx.geo)
        raise_rows(prm, np.ascontiguousarray(self.min_pdf[rows_idx]), self.fg)
        choice = it.lobe_choice(albedo, tp)
        if len(rows_idx):
            n = len(rows_idx)
            # Light sampling by the blurred reflective lobes alone (no diffuse f: the
            # lookups read those), weighted in full (sel 0: the continuation's pdf 0 in
            # the power heuristic), so the reflected continuations count no emission.
            L = it.direct_irradiance(ctx, y, rng, counters, bsdf=(
                np.zeros((n, 3)), prm, np.zeros_like(choice[0])))
            add = np.asarray(tp, np.float64) * (math.pi / G) * L
            np.add.at(E, rows_idx, add)
            np.add.at(self.added, rows_idx, add)
        return choice

    def continued(self, rows_idx, pdf):
        """The continued rays' chains (hit rows rows_idx (K,), continuation pdfs (K,),
        inf for mirror-like lobes and refractions): min_pdf lowered."""
        self.min_pdf[rows_idx] = np.minimum(self.min_pdf[rows_idx], pdf)

    def emission(self, rows_idx, o, d, tp, cls, E, G):
        """The emitters the continued rays (hit rows rows_idx (K,), origins o, directions
        d (K,3), throughputs tp (K,3), ray classes cls (K,)) meet: through a transmitting
        lobe (TRANSMISSION) every lamp surface, emitting mesh and the world; through a
        reflective one only the lights light sampling left to the continuation. Added
        to E in full (tp pi Le / G)."""
        from . import integrator as it
        from .bsdf import surface_hit
        from . import worldmedium
        ctx = self.ctx
        k = len(rows_idx)
        if k == 0:
            return
        cls = np.broadcast_to(np.asarray(cls, np.int64), (k,))
        trans = cls == it.TRANSMISSION
        if not trans.any() and not self.continuation_lights and not (
                self.world_on_reflection and self.world_light):
            return
        o = np.ascontiguousarray(o, np.float64)
        d = np.ascontiguousarray(d, np.float64)
        t, prim, u, v = ctx.accel.intersect(o, d, cls=np.ascontiguousarray(cls))
        t = np.where(prim >= 0, t, np.inf)
        Le = np.zeros((k, 3))
        at_lamp = np.zeros(k, bool)
        for li, light in enumerate(ctx.lights):
            if not light.has_surface:
                continue
            sees = (cls & light.ray_kinds) != 0
            if li not in self.continuation_lights:
                sees = sees & trans
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
        surf = np.flatnonzero((prim >= 0) & trans & ~at_lamp)
        if len(surf):
            y = surface_hit(ctx.geo, ctx.table, prim[surf], u[surf], v[surf], d[surf])
            if y.emission is not None:
                Le[surf] += y.emission
        miss = np.flatnonzero((prim < 0) & ~at_lamp)
        if len(miss):
            dm = np.take(d, miss, axis=0)
            tm = trans[miss]
            env = worldmedium.background(ctx.scene, dm)
            if not self.world_on_reflection:
                env = env * tm[:, None]
            Le[miss] += env
            for li, light in enumerate(ctx.lights):
                sun = light.seen_at_infinity(dm)
                if sun is None:
                    continue
                if li not in self.continuation_lights:
                    sun = sun * tm[:, None]
                Le[miss] += sun
        add = np.asarray(tp, np.float64) * (math.pi / G) * Le
        np.add.at(E, rows_idx, add)
        np.add.at(self.added, rows_idx, add)
