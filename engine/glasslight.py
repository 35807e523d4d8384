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

from .closures import principled as pr
from .directlight import (NO_HROWS, NO_ROWS, NO_ROWS3, ONE_BELOW, DirectLightBuffers,
                          sample_lights)
from .lights.packing import pack_lights
from .lights.selection import empty_tree, selection_samples, selector_for
from .visibility import SHADOW

MODE_CONTINUATION, MODE_DELTA, MODE_MIS, MODE_TREE = 0, 1, 2, 3  # integrator.light_modes'


def rough_transmission_rows(prm, cand) -> np.ndarray:
    """(K,) int64: the rows of cand (int64, rows of the packed lobes prm that were set up)
    whose glass lobe refracts with a density (principled.has_rough_transmission)."""
    out = np.empty(len(cand), np.int64)
    k = pr.rough_transmission_rows(prm, np.ascontiguousarray(cand, np.int64), out)
    return out[:k]


def transmitted_light(ctx, hit, rows, prm, sel, psum, modes, rng, counters) -> np.ndarray:
    """Radiance (K,3) towards wo that the rough glass hits rows (K,) int64 of the batch
    `hit` (bsdf.SurfaceHit; prm (N, N_PACK) their packed lobes, sel (N, N_LOBES) the
    continuation's lobe-choice probabilities, valid where psum (N,) > 0: elsewhere no
    continuation, light sampling takes all) let through from the lights behind their
    surface: one shadow ray per light sample (the plan's counts, as the reflective lobes
    take them), from the far side, weighted by the refraction f_t and, against the
    continuation, by multiple importance sampling. modes: integrator.light_modes(ctx)
    (lights left to the continuation take no sample here). rng draws the numbers (plain,
    not stratified)."""
    k_rows = len(rows)
    out = np.zeros((k_rows, 3))
    if k_rows == 0:
        return out
    c = np.ascontiguousarray
    # The hits as seen from the far side: flipped normals (the gate is the flipped
    # geometric normal; no shading offset, terminator lift or bump term: those belong to
    # the lit side of an opaque surface).
    p = c(hit.p[rows], np.float64)
    ns = c(hit.ns[rows], np.float64)
    back_ns = c(-ns)
    arrays = (p, back_ns, NO_ROWS3, c(-hit.ng[rows], np.float64),
              c(hit.offset[rows], np.float64), NO_ROWS, NO_ROWS, NO_ROWS3, back_ns)
    wo = c(hit.wo[rows], np.float64)
    prm_k = c(prm[rows])
    sel_k = np.where((psum[rows] > 0)[:, None], sel[rows], 0.0)
    chosen = selector_for(ctx)
    samples = []
    if chosen is not None:
        for si in range(selection_samples(ctx.settings)):
            u1, u2, choose = rng.random((3, k_rows))
            samples.append((-1, True, selection_samples(ctx.settings), u1, u2,
                            np.minimum(choose, ONE_BELOW)))
        tree = chosen[1]
    else:
        for li, light in enumerate(ctx.lights):
            if not light.ray_kinds & SHADOW or modes[li] == MODE_CONTINUATION:
                continue
            count = ctx.plan.light_samples.get(light.name, 1)
            traced = ctx.plan.shadows.get(light.name, True)
            for si in range(count):
                if light.needs_choice:
                    u1, u2, third = rng.random((3, k_rows))
                else:
                    (u1, u2), third = rng.random((2, k_rows)), None
                samples.append((li, traced, count, u1, u2, third))
        tree = None
    if not samples:
        return out
    packed = ctx.packed_lights or pack_lights(ctx.lights)
    codes, params, mesh = packed
    if tree is None:
        tree = (*empty_tree(), np.ones(len(codes), np.bool_))
    K = len(samples)
    # Each sample's weighting (accumulate_transmission's kmode): the light's mode, or the
    # tree's per-hit choice.
    kmode = np.array([MODE_TREE if s[0] < 0 else modes[s[0]] for s in samples], np.int64)
    klight = np.array([s[0] for s in samples], np.int64)
    ktrace = np.array([s[1] for s in samples], np.bool_)
    ksamples = np.array([float(s[2]) for s in samples])
    U1 = np.stack([s[3] for s in samples])
    U2 = np.stack([s[4] for s in samples])
    third = any(s[5] is not None for s in samples)
    SEL = (np.stack([np.zeros(k_rows) if s[5] is None else s[5] for s in samples])
           if third else np.zeros((K, 1)))
    buf = DirectLightBuffers().ensure(K * k_rows)
    m_all, m_rays = sample_lights(*arrays, codes, params, *mesh, *tree, klight, ktrace,
                                  c(U1), c(U2), c(SEL), buf.contrib, buf.row, buf.kidx,
                                  buf.ray, buf.o32, buf.d32, buf.t32, buf.wdir, buf.lpdf,
                                  NO_ROWS, NO_HROWS)
    blocked = buf.blocked[:m_rays]
    if m_rays:
        shadow = getattr(ctx, "shadow", None)
        t_keep = buf.t32[:m_rays].copy() if shadow is not None else None
        ctx.accel.occluded_into(buf.o32[:m_rays], buf.d32[:m_rays], buf.t32[:m_rays],
                                blocked, cls=SHADOW)
        if shadow is not None:
            shadow.pass_blocked(buf.o32[:m_rays], buf.d32[:m_rays], t_keep, blocked,
                                buf.contrib, buf.ray, m_all, SHADOW)
    pr.accumulate_transmission(out, buf.contrib, buf.row, buf.kidx, buf.ray, ksamples,
                               blocked, m_all, buf.wdir, buf.lpdf, kmode, prm_k, ns, wo,
                               sel_k)
    counters.shadow_rays += m_rays
    return out
