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
transparent closure weight). Glass, refraction and mirrors are opaque to shadow
rays; the light that reaches a surface through them is a caustic (the photon maps'),
docs/design.md, Transparent shadows.

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

import threading

import numpy as np

from .accel import Accel
from .geometry import ALL_RAYS
from .jit import kernel, register_warm_up
from .rayoffset import offset_along_normal
from .textures import material_alpha

# Cycles' default transparent_max_bounces (Render Properties > Light Paths).
DEFAULT_MAX_HITS = 8

CLEAR, BLOCKED, GOING = 0, 1, 2


def transparent_tints(table) -> np.ndarray:
    """(M,3) the materials' Transparent BSDF colour (principled.M_TTINT columns of the
    closure table; white without one)."""
    from .closures import principled as pr
    params = getattr(table, "closure_params", None)
    if params is None:
        return np.ones((len(table.alpha), 3))
    return np.asarray(params[:, pr.M_TTINT:pr.M_TTINT + 3], np.float64)


@kernel
def shadow_step(prim, tri_material, mat_alpha, mat_tint, node_alpha, slot, trans, count,
                max_hits, state):
    """One surface along each travelling shadow ray.

    prim (n,) the triangle hit (-1: none before the ray's end); tri_material (T,);
    mat_alpha (M,) the materials' constant alpha, mat_tint (M,3) their Transparent BSDF
    colour; node_alpha (n,) the per-hit factor of a material's alpha texture (1 where it
    has none); slot (n,) the ray's row in trans (R,3) (RGB transmittance so far,
    multiplied in place) and count (R,) (transparent surfaces crossed so far). Writes
    state (n,): CLEAR (reached its end), BLOCKED (opaque surface, a black tint, or one
    transparent surface more than max_hits), GOING (crossed a transparent surface)."""
    for i in range(prim.shape[0]):
        p = prim[i]
        r = slot[i]
        if p < 0:
            state[i] = CLEAR
            continue
        m = tri_material[p]
        a = mat_alpha[m] * node_alpha[i]
        through = 1.0 - min(max(a, 0.0), 1.0)
        t0 = through * mat_tint[m, 0]
        t1 = through * mat_tint[m, 1]
        t2 = through * mat_tint[m, 2]
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
        # Shared instances (engine/sharedrows.py): no per-triangle tables; the rays walk
        # the class's two-level BVH surface by surface instead (_walk_bvh).
        self.shared = getattr(geo, "shared", None) is not None
        if not self.shared:
            self.tri_material = np.ascontiguousarray(geo.material, np.int64)
            self.tri_transparent = self.transparent_materials(table)[geo.material]
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
        used = geo.used_materials()
        if not cls.transparent_materials(table)[used].any():
            return None
        return cls(geo, table, max_hits)

    def transmittance(self, o32, d32, t32, rows=None, cls=None) -> np.ndarray:
        """(R,3) RGB transmittance of the shadow rays `rows` (default: all) from o32 (R,3)
        along d32 (R,3) to distance t32 (R,) (units of |d|; re-centred world space),
        through transparent surfaces: the product of (1 - alpha) x transparent tint of the
        surfaces crossed, 0 where an opaque surface or more than max_hits transparent ones
        lie in the way. cls: the rays' class (engine/visibility.py; None: every triangle
        is seen)."""
        if rows is None:
            rows = np.arange(len(o32))
        rows = np.asarray(rows, np.int64)
        n = len(rows)
        trans = np.ones((n, 3))
        count = np.zeros(n, np.int64)
        if n == 0:
            return trans
        o = np.asarray(o32, np.float64)[rows]
        d = np.asarray(d32, np.float64)[rows]
        t = np.asarray(t32, np.float64)[rows]
        end = o + d * t[:, None]
        dd = np.maximum((d * d).sum(axis=1), 1e-300)
        slot = np.arange(n, dtype=np.int64)
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
            return trans
        for _ in range(self.max_hits + 1):
            if len(slot) == 0:
                break
            _, prim, u, v = clear.intersect(o, d, t)
            hit = prim >= 0
            if clear_idx is not None:
                prim[hit] = clear_idx[prim[hit]]
            # The hits' material rows (gathered for shared instances: hit_tables).
            rows, (tri_material,) = (geo.hit_tables(prim, "material") if self.shared
                                     else (prim, (self.tri_material,)))
            node_alpha = np.ones(len(prim))
            if hit.any():
                hp, hu, hv = prim[hit], u[hit], v[hit]
                node_alpha[hit] = material_alpha(self.table, geo, np.take(geo.material, hp),
                                                 hp, hu, hv, constant=False)
            state = np.empty(len(prim), np.int64)
            shadow_step(rows, np.ascontiguousarray(tri_material, np.int64), self.mat_alpha,
                        self.mat_tint, node_alpha, slot, trans, count, self.max_hits, state)
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
            slot = slot[go]
            d = dg
            t = ((end[slot] - o) * d).sum(axis=1) / dd[slot]
            past = t <= 0.0  # the surface lies at the ray's end: nothing more to cross
            if past.any():
                keep = ~past
                o, d, t, slot = o[keep], d[keep], t[keep], slot[keep]
        else:
            # Unreachable: each step blocks a ray at its (max_hits + 1)-th surface.
            trans[slot] = 0.0
        return trans

    def pass_blocked(self, o32, d32, t32, blocked, contrib, ray, m_all, cls=None):
        """After an OCCLUDED query: re-trace the blocked shadow rays through transparent
        surfaces; rays that get through are marked unblocked in `blocked` and the entries
        (j < m_all) of `contrib` that use them scaled by their transmittance (the layout
        of directlight.sample_lights). t32 must hold the rays' distances as they were
        before the query (Embree overwrites them)."""
        rows = np.nonzero(blocked)[0]
        if len(rows) == 0:
            return
        trans = self.transmittance(o32, d32, t32, rows, cls)
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
                DEFAULT_MAX_HITS, state)
    scale_entries(np.ones((1, 3)), np.zeros(1, np.int64), 1, np.full((1, 3), 0.5))
