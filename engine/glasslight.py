"""Light sampling through rough glass: next-event estimation at a camera path's rough glass
hits for the light their refraction lobe lets through (issue 14, docs/performance.md
"Rough glass: light sampling through the surface").

A camera path that leaves a rough glass ball towards a small light (a sun of 1 degree
behind the camera, seen through the ball after one inner reflection: the rough ball's
bright lower half in Cycles) found it only when the refraction's sampled direction hit
the light's disc: most samples missed it and a few carried its full radiance (the lower
half's median 0.57x Cycles', fireflies around it). Cycles samples the light at every
non-delta vertex, refraction included; so do we now, by the same kernels as the
reflective lobes' light sampling (directlight.sample_lights) run with the hits' normals
flipped: the lights on the far side of the surface are sampled, the shadow rays leave
from that side, and principled.accumulate_transmission weights each sample by the lobe's
refraction f_t and, for lights the continuation can also hit, by the power heuristic
against the continuation's refraction pdf (principled.transmission_pdf, which
camerakernels._emit_ray now gives refracted rough-glass rays instead of inf).
"""
from __future__ import annotations

import numpy as np

from . import chaincounts
from .closures import principled as pr
from .lightlinking import receiver_link
from .directlight import NO_ROWS, NO_ROWS3, direct_light
from .lights.packing import pack_lights
from .lights.selection import selector_for
from .visibility import SHADOW

MODE_TREE = 3  # integrator.light_modes': a light the light tree picks


def rough_transmission_rows(prm, cand) -> np.ndarray:
    """(K,) int64: the rows of cand (int64, rows of the packed lobes prm that were set up)
    whose glass lobe refracts with a density (principled.has_rough_transmission)."""
    out = np.empty(len(cand), np.int64)
    k = pr.rough_transmission_rows(prm, np.ascontiguousarray(cand, np.int64), out)
    return out[:k]


def transmitted_light(ctx, hit, rows, prm, sel, psum, modes, samples, counters,
                      counts=None, used=None) -> np.ndarray:
    """Radiance (K,3) towards wo that the rough glass hits rows (K,) int64 of the batch
    `hit` (bsdf.SurfaceHit; prm (N, N_PACK) their packed lobes, sel (N, N_LOBES) the
    continuation's lobe-choice probabilities, valid where psum (N,) > 0: elsewhere no
    continuation, light sampling takes all) let through from the lights behind their
    surface: one shadow ray per light sample, from the far side, weighted by the
    refraction f_t and, against the continuation, by multiple importance sampling.
    samples: the K rows' light samples (integrator.light_sample_list with modes: the
    plan's counts, as the reflective lobes take them; lights left to the continuation take
    none). modes: integrator.light_modes(ctx).
    counts: (K,4) int64, the camera-side bounce counts the rows are reached with (B_TOTAL
    order; None: none, the camera's first hits): shadow rays through flat glass passages
    cross only as many as the limits allow after the refraction's own transmission bounce
    (chaincounts.flat_passages, TRANSMISSION: Cycles finds a light behind a pane beyond
    rough glass by that refraction and the pane's two). used: (K,) int64, the transparent
    bounces the rows' camera paths made before them (directlight.direct_light's; None: 0)."""
    k_rows = len(rows)
    if k_rows == 0 or not samples:
        return np.zeros((k_rows, 3))
    c = np.ascontiguousarray
    # The hits as seen from the far side: flipped normals (the gate is the flipped
    # geometric normal; no shading offset, terminator lift or bump term: those belong to
    # the lit side of an opaque surface).
    p = c(hit.p[rows], np.float64)
    ns = c(hit.ns[rows], np.float64)
    back_ns = c(-ns)
    arrays = (p, back_ns, NO_ROWS3, c(-hit.ng[rows], np.float64),
              c(hit.offset[rows], np.float64), NO_ROWS, NO_ROWS, NO_ROWS3, back_ns)
    sel_k = np.where((psum[rows] > 0)[:, None], sel[rows], 0.0)
    chosen = selector_for(ctx)
    # Each sample's weighting (accumulate_transmission's kmode): the light's mode, or
    # the tree's per-hit choice.
    mode = (np.full(len(ctx.lights), MODE_TREE, np.int64) if chosen is not None
            else np.asarray(modes, np.int64))
    transmission = (c(prm[rows]), ns, c(hit.wo[rows], np.float64), mode, sel_k)
    shadow = getattr(ctx, "shadow", None)
    passages = None
    if shadow is not None and shadow.flat_on:
        cap = chaincounts.flat_passages((0, 0, 0, 0) if counts is None else counts,
                                        ctx.settings.bounce_limits, chaincounts.TRANSMISSION)
        # Caps at or above max_hits // 2 never bind (integrator.direct_irradiance's).
        if cap.min() < shadow.max_hits // 2:
            passages = c(np.broadcast_to(cap, (k_rows,)), np.int64)
    out, rays = direct_light(ctx.packed_lights or pack_lights(ctx.lights), arrays, samples,
                             ctx.accel, SHADOW, k_rows, shadow=shadow,
                             tree=None if chosen is None else chosen[1],
                             transmission=transmission, passages=passages,
                             link=receiver_link(ctx, hit, rows), used=used)
    counters.shadow_rays += rays
    return out
