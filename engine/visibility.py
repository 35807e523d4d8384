"""Ray visibility (Cycles' Object > Visibility > Ray Visibility): one BVH per ray class.

Every ray the engine traces belongs to a class: camera rays (and their continuations
through transparent surfaces), diffuse rays (final gathering), glossy rays (mirror and
coat reflections), transmission rays (refraction) and shadow rays. A triangle whose mesh
is invisible to a class must be passed through by rays of that class.

embreex has no per-ray masks or filter callbacks, so each distinct set of visible
triangles gets its own BVH (usually there is one set: every query goes to the one BVH at
no cost). The alternative, re-tracing from just past each invisible hit, costs a traversal
and an origin offset per invisible layer crossed. Measured (bench/bench_visibility.py,
500k rays, 2 shared cores): 1 / 3 camera-invisible layers (141k triangles each) over a floor
of spheres: per-class BVH 0.50 / 0.51 s per million rays, re-tracing 3.5 / 7.4 s; the
extra BVH took 0.53 / 1.08 s to build once.

VisibilityAccel is a drop-in for accel.Accel: intersect / occluded without a class use
every triangle, as before. With instance records (engine.geometry.Geometry.instances)
that engine/resources.py decides not to expand (`two_level_instances`), every BVH is an
engine.instancing.InstanceAccel: the prototypes' BVHs are shared by the classes, a class
that does not see an instance skips it in the top level.
"""
from __future__ import annotations

import numpy as np

from .geometry import ALL_RAYS, CAMERA, DIFFUSE, GLOSSY, SHADOW, TRANSMISSION
from .instancing import InstanceAccel
from .resources import two_level_instances

CLASSES = (CAMERA, DIFFUSE, GLOSSY, TRANSMISSION, SHADOW)
CLASS_NAMES = {CAMERA: "camera", DIFFUSE: "diffuse", GLOSSY: "glossy",
               TRANSMISSION: "transmission", SHADOW: "shadow"}
# Ray class after each specular lobe of bsdf.SPEC_LOBES; 0 = keep the incoming class
# (a transparent pass-through continues the same ray, as in Cycles).
SPEC_LOBE_CLASS = {"pass": 0, "metal": GLOSSY, "glass_r": GLOSSY, "glass_t": TRANSMISSION,
                   "spec": GLOSSY, "coat": GLOSSY, "sheen": DIFFUSE,
                   # Cycles' Translucent BSDF samples LABEL_TRANSMIT | LABEL_DIFFUSE:
                   # path_state_next counts a transmission bounce, and its rays see
                   # what transmission rays see (path_state_ray_visibility drops the
                   # diffuse flag of a transmitted ray)
                   "translucent": TRANSMISSION}


class _Subset:
    """An Accel over some triangles, answering with the full table's triangle indices."""

    def __init__(self, accel, prim_map):
        self.accel = accel
        self.prim_map = prim_map

    def serial(self):
        return _Subset(self.accel.serial(), self.prim_map)

    def close(self, wait: bool = False):
        self.accel.close(wait)

    def intersect(self, o, d, tmax=None):
        t, prim, u, v = self.accel.intersect(o, d, tmax)
        hit = prim >= 0
        prim[hit] = self.prim_map[prim[hit]]
        return t, prim, u, v

    def occluded(self, o, d, tmax=None):
        return self.accel.occluded(o, d, tmax)

    def occluded_into(self, o32, d32, tmax32, blocked):
        return self.accel.occluded_into(o32, d32, tmax32, blocked)


class VisibilityAccel:
    """Closest-hit and occlusion queries that honour each triangle's ray visibility.

    visibility: (T,) uint8 class bits per triangle (engine.geometry); the BVH over all
    triangles is `full`; subsets are built with accel_class(vertices, faces, threads,
    should_cancel=...). should_cancel() is asked between the pieces of each build (raises
    engine.parallel.Cancelled)."""

    def __init__(self, vertices32, faces32, visibility, accel_class, threads=1,
                 should_cancel=None, instances=None):
        self.two_level = instances is not None and (
            instances.two_level if instances.two_level is not None
            else two_level_instances(instances))
        if self.two_level:
            self._two_level(vertices32, faces32, visibility, accel_class, threads,
                            should_cancel, instances)
            return
        self.full = accel_class(vertices32, faces32, threads=threads,
                                should_cancel=should_cancel)
        self.count = self.full.count
        self.threads = threads
        self._by_class = {}
        built = {}
        vis = np.asarray(visibility, np.uint8)
        for cls in CLASSES:
            mask = (vis & cls) != 0
            if mask.all():
                self._by_class[cls] = self.full
                continue
            key = mask.tobytes()
            if key not in built:
                idx = np.nonzero(mask)[0]
                built[key] = _Subset(accel_class(vertices32, faces32[idx], threads=threads,
                                                 should_cancel=should_cancel),
                                     idx.astype(np.int64))
            self._by_class[cls] = built[key]
        self.has_invisible = any(a is not self.full for a in self._by_class.values())

    def _two_level(self, vertices32, faces32, visibility, accel_class, threads,
                   should_cancel, instances):
        """Every class's BVH two-level (engine/instancing.py), sharing the prototypes'."""
        self.full = InstanceAccel(vertices32, faces32, instances, accel_class,
                                  threads=threads, should_cancel=should_cancel)
        self.count = self.full.count
        self.threads = threads
        self._by_class = {}
        built = {}
        static = instances.static
        # np.take reads only the static rows (also of a shared Geometry's RowColumn).
        vis_static = np.asarray(np.take(visibility, static), np.uint8) if len(static) \
            else np.zeros(0, np.uint8)
        for cls in CLASSES:
            use = (instances.visibility & cls) != 0
            rows = static[(vis_static & cls) != 0]
            if use.all() and len(rows) == len(static):
                self._by_class[cls] = self.full
                continue
            key = use.tobytes() + rows.tobytes()
            if key not in built:
                built[key] = self.full.subset(vertices32, faces32, use, rows, accel_class,
                                              should_cancel=should_cancel)
            self._by_class[cls] = built[key]
        self.has_invisible = any(a is not self.full for a in self._by_class.values())

    def serial(self) -> "VisibilityAccel":
        view = VisibilityAccel.__new__(VisibilityAccel)
        view.full = self.full.serial()
        view.count, view.threads, view.has_invisible = self.count, 1, self.has_invisible
        view.two_level = self.two_level
        views = {id(self.full): view.full}
        view._by_class = {}
        for cls, acc in self._by_class.items():
            if id(acc) not in views:
                views[id(acc)] = acc.serial()
            view._by_class[cls] = views[id(acc)]
        return view

    def close(self, wait: bool = False):
        """Shut every BVH's query threads down (wait=True: until they have ended)."""
        seen = set()
        for acc in [self.full, *self._by_class.values()]:
            if id(acc) not in seen:
                seen.add(id(acc))
                acc.close(wait)

    def for_class(self, cls: int):
        return self._by_class[int(cls)]

    def occluded_into(self, o32, d32, tmax32, blocked, cls=None):
        """Accel.occluded_into (float32 rays written by a kernel) for rays of class cls."""
        acc = self.full if cls is None or not self.has_invisible else self._by_class[int(cls)]
        return acc.occluded_into(o32, d32, tmax32, blocked)

    def intersect(self, origins, directions, tmax=None, cls=None):
        """Closest hits (t, prim, u, v) as Accel.intersect, seen by rays of class `cls`:
        None (every triangle), one class, or an (N,) array of classes per ray."""
        if cls is None or not self.has_invisible:
            return self.full.intersect(origins, directions, tmax)
        if np.ndim(cls) == 0:
            return self._by_class[int(cls)].intersect(origins, directions, tmax)
        cls = np.asarray(cls)
        n = len(cls)
        t = np.full(n, np.inf)
        prim = np.full(n, -1, np.int64)
        u = np.zeros(n)
        v = np.zeros(n)
        tm = None if tmax is None else np.broadcast_to(np.asarray(tmax, np.float64), (n,))
        for c in np.unique(cls):
            rows = np.nonzero(cls == c)[0]
            res = self._by_class[int(c)].intersect(origins[rows], directions[rows],
                                                   None if tm is None else tm[rows])
            t[rows], prim[rows], u[rows], v[rows] = res
        return t, prim, u, v

    def occluded(self, origins, directions, tmax=None, cls=None):
        """Accel.occluded for rays of class `cls` (None: every triangle blocks)."""
        if cls is None or not self.has_invisible:
            return self.full.occluded(origins, directions, tmax)
        return self._by_class[int(cls)].occluded(origins, directions, tmax)


def continued_class(lobe: np.ndarray, incoming) -> np.ndarray:
    """Ray class after the specular lobe indices `lobe` (into bsdf.SPEC_LOBES), given the
    incoming class (scalar or per ray)."""
    from .bsdf import SPEC_LOBES
    table = np.array([SPEC_LOBE_CLASS[name] for name in SPEC_LOBES], np.int64)
    out = table[lobe]
    keep = out == 0
    if keep.any():
        inc = np.broadcast_to(np.asarray(incoming, np.int64), out.shape)
        out[keep] = inc[keep]
    return out


def visible_to(geo, prim: np.ndarray, cls) -> np.ndarray:
    """True where triangle prim (>= 0) is seen by rays of class cls (scalar or per row)."""
    return (np.take(geo.visibility, prim).astype(np.int64) & np.asarray(cls, np.int64)) != 0


__all__ = ["VisibilityAccel", "CLASSES", "CLASS_NAMES", "SPEC_LOBE_CLASS", "continued_class",
           "visible_to", "ALL_RAYS"]
