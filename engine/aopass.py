"""Cycles' Ambient Occlusion render pass (View Layer > Passes > Ambient Occlusion).

Cycles 5.0 (intern/cycles/kernel/integrator/shade_surface.h integrate_surface_ao,
kernel/film/light_passes.h film_write_direct_light's PATH_RAY_SHADOW_FOR_AO branch,
scene/integrator.cpp ao_bounces_distance, blender/sync.cpp: the World's Settings >
Ambient Occlusion > Distance, `world.light_settings.distance`, 10 m without a world):
at every surface the camera ray meets, directly or through transparent surfaces (its
PATH_RAY_CAMERA visibility), one direction is drawn cosine-weighted about the surface's
normal (surface_shader_ao: the diffuse closures' normal, else sd->N, the shading normal
on the side the ray arrived from) and a shadow ray traced up to that distance; where
it gets through, the pass adds
    path throughput x surface alpha x the shadow ray's transmittance
(transparent surfaces let it through with their transparency, Cycles' transparent
shadows; anything else blocks it). The film divides by the samples: a fully open
opaque surface seen directly reads 1, the background and holdout surfaces 0.

Here: the shading normal (hit.ns, the Normal Map / Bump nodes' included) stands for
the diffuse closures' normal; the direction is ambientocclusion.ao_directions' single
sample shifted by a hash of the hit (its own salt), so the pass draws no number from
the render's streams: the image keeps its bits, and a hit gets the same direction for
any worker count. The shadow ray is the direct light's: Embree's occlusion query, then
the transparent walk (engine/shadowtransmittance.py) for the blocked ones.

Shapes: pix (N,) int64 pixel rows; tp (N,3) float64 path throughput; the pass is the
Accumulator.data key KEY, (P,3) float64 sums.
"""
from __future__ import annotations

import numpy as np

from .ambientocclusion import ao_directions
from .camerakernels import film_add
from .visibility import SHADOW

KEY = "ao"
# Cycles' AO distance without a World (blender/sync.cpp sync_integrator).
DEFAULT_DISTANCE = 10.0
# Salt of the hit hash for the pass' direction (the AO node uses the default salt).
SALT = 0x5DEECE66DA3B1F27


def add_ao(acc, ctx, hit, prim, u, v, pix, tp, rows, distance: float, counters=None,
           used=None):
    """The AO pass' samples at the camera-chain hits rows (K,) int64 of a bounce: hit
    (the batch's SurfaceHit: p, ns, ng, offset, mat, alpha), prim, u, v (N,) their
    triangles and barycentrics, pix (N,), tp (N,3). distance: the rays' length (m,
    > 0; 0 or less: nothing is unoccluded, the pass stays 0); counters: the camera
    pass' Counters (its shadow rays counted), or None. used: (N,) int64 the transparent
    bounces each hit's camera path made (None: 0): its AO ray crosses Light Paths > Max
    Bounces > Transparent minus that many transparent surfaces, as its shadow rays
    (Cycles' AO ray is a shadow path with the path's transparent_bounce; Blender 5.0.1,
    measured: docs/compatibility.md "### translimit49")."""
    if len(rows) == 0 or not distance > 0.0:
        return
    rows = np.ascontiguousarray(rows, np.int64)
    # A holdout surface ends the path before its AO (integrate_surface_holdout).
    rows = rows[~np.asarray(np.take(ctx.geo.holdout, np.asarray(prim)[rows]), bool)]
    if len(rows) == 0:
        return
    alpha = (np.take(ctx.table.alpha, np.asarray(hit.mat)[rows])
             if getattr(hit, "alpha", None) is None
             else np.asarray(hit.alpha, np.float64)[rows])
    ns = np.asarray(hit.ns, np.float64)[rows]
    d = ao_directions(ns, 1, np.asarray(prim)[rows], np.asarray(u, np.float64)[rows],
                      np.asarray(v, np.float64)[rows], salt=SALT)[:, 0]
    o = hit.clear(rows, d)
    o32 = np.ascontiguousarray(o, np.float32)
    d32 = np.ascontiguousarray(d, np.float32)
    t32 = np.full(len(rows), distance, np.float32)
    blocked = np.empty(len(rows), np.bool_)
    ctx.accel.occluded_into(o32, d32, t32.copy(), blocked, cls=SHADOW)
    trans = np.ones((len(rows), 3))
    trans[blocked] = 0.0
    shadow = getattr(ctx, "shadow", None)
    if shadow is not None and blocked.any():
        bl = np.nonzero(blocked)[0]
        trans[bl] = shadow.transmittance(
            o32[bl], d32[bl], t32[bl], cls=SHADOW,
            used=None if used is None else np.take(np.asarray(used, np.int64), rows[bl]))
    if counters is not None:
        counters.shadow_rays += len(rows)
    buf = acc.data.get(KEY)
    if buf is None:
        buf = acc.data[KEY] = np.zeros((acc.npix, 3))
    film_add(buf, acc.lo, np.ascontiguousarray(pix, np.int64), rows,
             np.ascontiguousarray(tp, np.float64),
             np.ascontiguousarray(trans * alpha[:, None]))
