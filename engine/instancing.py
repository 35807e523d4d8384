"""Instanced geometry traced without world-space copies in the BVH (two-level tracing).

embreex has no instance geometry (docs/performance.md, "Instancing"), so the two levels
are built here: one Embree BVH per prototype mesh in its object space (bottom level), and
a compiled BVH over the instances' world-space boxes (top level). A ray batch is traced
as follows: the triangles that belong to no instance first (one ordinary BVH); then the
top level lists, for each ray, the instance boxes it enters before its nearest hit so
far, sorted nearest first; in round k every ray's k-th box (if it is still nearer than
the ray's nearest hit) is traced: the rays are grouped by instance, transformed into the
instance's object space (directions not normalised, so t stays the world parameter) and
traced up to their nearest hit so far. Hits map back to the merged triangle table's
indices (instance base + prototype triangle), so the answers have Accel's form and the
rest of the engine reads the hit triangle's tables as before.

The transformed rays are rounded to float32 in object space instead of the triangles in
world space, so hits agree with the expanded copies up to float32 rounding (t within
~1e-5 relatively, docs/performance.md), not bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .accel import Accel
from .parallel import Cancelled
from .toplevel import build_top_level, to_object_rays, top_level_candidates


@dataclass
class Instances:
    """Instance records of the merged triangle table (engine/geometry.prepare).

    prototypes  list of (vertices (V,3) float, faces (F,3) int) in object space; the
                triangles of an instance of prototype p are the merged table's rows
                [base, base + F_p), in the prototype's face order
    prototype   (I,) int index into prototypes
    base        (I,) int64 first row of each instance in the merged table
    to_world    (I,3,4) float64 object space -> the merged table's (re-centred) world space
    flip        (I,) bool: the instance mirrors (det < 0) and its rows have the winding
                reversed (corners 0, 2, 1), as addon/export.transform_geometry writes them
    visibility  (I,) uint8 ray-class bits (engine.geometry CAMERA ...), as the rows'
    static      (S,) int64 rows of the merged table that belong to no instance
    two_level   True / False: engine/geometry.prepare chose two-level tracing (and shared
                tables) or expansion (engine/resources.two_level_instances); None: not
                decided yet
    compact_static  the BVH's faces32 holds only the static rows, in `static` order (a
                Geometry with shared tables) instead of every row of the merged table
    """

    prototypes: list
    prototype: np.ndarray
    base: np.ndarray
    to_world: np.ndarray
    flip: np.ndarray
    visibility: np.ndarray
    static: np.ndarray
    two_level: bool | None = None
    compact_static: bool = False

    @property
    def count(self) -> int:
        return len(self.prototype)

    def instanced_triangles(self) -> int:
        sizes = np.array([len(f) for _, f in self.prototypes], np.int64)
        return int(sizes[self.prototype].sum()) if self.count else 0


def _world_boxes(instances: Instances, proto_bounds):
    """(I,3) lo, hi: each instance's prototype box corners taken to world space, padded
    by a relative 1e-6 of the box size plus float32 spacing (the bottom level traces
    float32 rays: a hit on the box face must not be culled)."""
    I = instances.count
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    plo = proto_bounds[0][instances.prototype]      # (I,3)
    phi = proto_bounds[1][instances.prototype]
    pts = plo[:, None, :] + corners[None] * (phi - plo)[:, None, :]   # (I,8,3)
    M = instances.to_world
    w = np.einsum("ijk,ick->icj", M[:, :, :3], pts) + M[:, None, :, 3]
    lo, hi = w.min(axis=1), w.max(axis=1)
    pad = 1e-6 * (hi - lo).max(axis=1, initial=0.0)[:, None] \
        + 4 * np.spacing(np.maximum(np.abs(lo), np.abs(hi)).astype(np.float32)).astype(float)
    return (lo - pad).reshape(I, 3), (hi + pad).reshape(I, 3)


class InstanceAccel:
    """Accel's queries (intersect, occluded, occluded_into, serial, close, count) over a
    merged triangle table whose instances are traced two-level (module docstring).

    vertices32, faces32: the merged table for the triangles of no instance
    (instances.static rows; the instanced rows are not read; None when there are none). instances: Instances.
    use: (I,) bool, the instances this BVH traces (the others are passed through, as a
    ray class that does not see them); static: the static rows it traces (default all).
    accel_class builds the Embree BVHs (bench/ records queries through it). Raises
    engine.parallel.Cancelled when should_cancel() turns True between the builds,
    ValueError for bad arrays or a prototype face index out of range."""

    def __init__(self, vertices32, faces32, instances: Instances, accel_class=Accel,
                 threads: int = 1, should_cancel=None, use=None, static=None,
                 _prototypes=None):
        stop = should_cancel if should_cancel is not None else (lambda: False)
        self.threads = max(1, int(threads))
        self.instances = instances
        sizes = np.array([len(f) for _, f in instances.prototypes], np.int64)
        ends = instances.base + sizes[instances.prototype] if instances.count else [0]
        self.count = max(len(instances.static) if instances.compact_static else
                         0 if faces32 is None else len(faces32), int(np.max(ends)))
        if _prototypes is None:
            built = []
            for verts, faces in instances.prototypes:
                if stop():
                    raise Cancelled()
                built.append(accel_class(np.asarray(verts, np.float32), np.asarray(faces),
                                         threads=self.threads, should_cancel=should_cancel))
            bounds = np.zeros((2, len(built), 3))
            for p, (verts, faces) in enumerate(instances.prototypes):
                if len(faces):
                    corners = np.asarray(verts, np.float64)[np.unique(np.asarray(faces))]
                    bounds[0, p], bounds[1, p] = corners.min(axis=0), corners.max(axis=0)
            _prototypes = (built, bounds)
        self._prototypes = _prototypes
        self._proto_accels = _prototypes[0]
        use = np.ones(instances.count, bool) if use is None else np.asarray(use, bool)
        # Instances with a singular transform are flat: their copies would be degenerate
        # triangles, which Embree never hits; they are left out here too.
        M = instances.to_world
        det = np.linalg.det(M[:, :, :3]) if instances.count else np.zeros(0)
        ok = use & np.isfinite(det) & (np.abs(det) > 0) & (sizes[instances.prototype] > 0)
        self._ids = np.nonzero(ok)[0]
        inv = np.zeros((instances.count, 3, 4))
        if len(self._ids):
            A = np.linalg.inv(M[self._ids, :, :3])
            inv[self._ids, :, :3] = A
            inv[self._ids, :, 3] = -np.einsum("ijk,ik->ij", A, M[self._ids, :, 3])
        self._to_object = inv
        lo, hi = _world_boxes(instances, _prototypes[1])
        self._top = build_top_level(lo[self._ids], hi[self._ids])
        static = instances.static if static is None else np.asarray(static, np.int64)
        self._static_rows = static
        self._static = None
        if len(static):
            if stop():
                raise Cancelled()
            # Compact tables hold only the static rows, in instances.static order.
            pos = (np.searchsorted(instances.static, static) if instances.compact_static
                   else static)
            self._static = accel_class(vertices32, np.asarray(faces32)[pos],
                                       threads=self.threads, should_cancel=should_cancel)

    def subset(self, vertices32, faces32, use, static, accel_class=Accel,
               should_cancel=None) -> "InstanceAccel":
        """The BVH for the instances `use` (I,) bool and the static rows `static` only
        (a ray class that does not see some objects), sharing the prototypes' BVHs."""
        return InstanceAccel(vertices32, faces32, self.instances, accel_class,
                             threads=self.threads, should_cancel=should_cancel, use=use,
                             static=static, _prototypes=self._prototypes)

    def serial(self) -> "InstanceAccel":
        """A view that answers on the calling thread (engine/parallel.py splits work)."""
        view = object.__new__(InstanceAccel)
        view.__dict__.update(self.__dict__)
        view.threads = 1
        view._proto_accels = [a.serial() for a in self._proto_accels]
        view._static = self._static.serial() if self._static is not None else None
        return view

    def close(self, wait: bool = False):
        for a in self._proto_accels:
            a.close(wait)
        if self._static is not None:
            self._static.close(wait)

    # --- queries ------------------------------------------------------------------

    @staticmethod
    def _rays(origins, directions, tmax):
        o = np.ascontiguousarray(origins, dtype=np.float64)
        d = np.ascontiguousarray(directions, dtype=np.float64)
        if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
            raise ValueError(f"InstanceAccel: origins {o.shape} and directions {d.shape} "
                             "must both be (N,3)")
        n = len(o)
        big = float(np.finfo(np.float32).max)
        if tmax is None:
            t = np.full(n, big)
        else:
            t = np.array(np.broadcast_to(np.asarray(tmax, np.float64), (n,)), np.float64)
            t = np.where(np.isnan(t), 0.0, np.minimum(t, big))
        return o, d, t

    def _candidates(self, o, d, far):
        top = self._top
        offsets, local, tent = top_level_candidates(o, d, far, top.node_lo, top.node_hi,
                                                    top.child, top.first, top.count,
                                                    top.order, top.lo, top.hi)
        return offsets, self._ids[local], tent

    def _to_local(self, which, rows, o, d):
        """Rays rows of o, d (N,3) in the object space of instances which (n,): float32
        (n,3) each, as Embree takes them."""
        return to_object_rays(self._to_object, which, rows, o, d)

    def _by_prototype(self, rows, which):
        """(prototype, rows, which) groups: one Embree call per prototype, whatever the
        number of its instances (the rays are transformed per row)."""
        proto = self.instances.prototype[which]
        if len(self._proto_accels) == 1:
            return [(0, rows, which)]
        sort = np.argsort(proto, kind="stable")
        rows, which, proto = rows[sort], which[sort], proto[sort]
        cuts = np.flatnonzero(np.diff(proto)) + 1
        return [(int(proto[g[0]]), rows[g], which[g])
                for g in np.split(np.arange(len(rows)), cuts) if len(g)]

    def intersect(self, origins, directions, tmax=None):
        """Closest hits (t, prim, u, v) as Accel.intersect; prim indexes the merged table."""
        o, d, far = self._rays(origins, directions, tmax)
        n = len(o)
        t = np.full(n, np.inf)
        prim = np.full(n, -1, np.int64)
        u = np.zeros(n)
        v = np.zeros(n)
        if n == 0:
            return t, prim, u, v
        if self._static is not None:
            ts, ps, us, vs = self._static.intersect(o, d, far)
            hit = ps >= 0
            t[hit], prim[hit] = ts[hit], self._static_rows[ps[hit]]
            u[hit], v[hit] = us[hit], vs[hit]
            far[hit] = ts[hit]
        if not len(self._ids):
            return t, prim, u, v
        offsets, inst, tent = self._candidates(o, d, far)
        counts = np.diff(offsets)
        ins = self.instances
        k = 0
        while True:
            # Round k: every ray's k-th nearest box, if it is nearer than its nearest hit
            # so far (a ray appears once in a round, so the updates do not collide).
            rows = np.nonzero(counts > k)[0]
            if not len(rows):
                break
            at = offsets[rows] + k
            near = tent[at] <= far[rows]
            for p, r, which in self._by_prototype(rows[near], inst[at[near]]):
                ol, dl = self._to_local(which, r, o, d)
                tl, pl, ul, vl = self._proto_accels[p].intersect(ol, dl, far[r])
                hit = pl >= 0
                if not hit.any():
                    continue
                r, which = r[hit], which[hit]
                t[r] = far[r] = tl[hit]
                prim[r] = ins.base[which] + pl[hit]
                # Mirrored copies have corners (0, 2, 1): their barycentrics swap.
                flip = ins.flip[which]
                u[r] = np.where(flip, vl[hit], ul[hit])
                v[r] = np.where(flip, ul[hit], vl[hit])
            k += 1
        return t, prim, u, v

    def occluded(self, origins, directions, tmax=None) -> np.ndarray:
        """True where something lies between the origin and distance tmax."""
        o, d, far = self._rays(origins, directions, tmax)
        n = len(o)
        blocked = np.zeros(n, bool)
        if n == 0:
            return blocked
        if self._static is not None:
            blocked[:] = self._static.occluded(o, d, far)
        if not len(self._ids):
            return blocked
        clear = np.nonzero(~blocked)[0]
        offsets, inst, _ = self._candidates(o[clear], d[clear], far[clear])
        counts = np.diff(offsets)
        k = 0
        while True:
            # Round k: the k-th box of every ray not blocked yet.
            live = np.nonzero(counts > k)[0]
            live = live[~blocked[clear[live]]]
            if not len(live):
                break
            for p, r, which in self._by_prototype(clear[live], inst[offsets[live] + k]):
                ol, dl = self._to_local(which, r, o, d)
                blocked[r] = self._proto_accels[p].occluded(ol, dl, far[r])
            k += 1
        return blocked

    def occluded_into(self, o32, d32, tmax32, blocked) -> np.ndarray:
        """Accel.occluded_into: float32 rays written by a kernel, the answer into
        `blocked` (N,) bool. Raises ValueError on other shapes or types."""
        n = len(o32)
        for name, a, shape in (("origins", o32, (n, 3)), ("directions", d32, (n, 3)),
                               ("tmax", tmax32, (n,))):
            if a.dtype != np.float32 or a.shape != shape:
                raise ValueError(f"InstanceAccel.occluded_into: {name} must be float32 "
                                 f"{shape}, got {a.dtype} {a.shape}")
        if blocked.dtype != np.bool_ or blocked.shape != (n,):
            raise ValueError(f"InstanceAccel.occluded_into: blocked must be bool ({n},), "
                             f"got {blocked.dtype} {blocked.shape}")
        blocked[:] = self.occluded(o32, d32, tmax32)
        return blocked
