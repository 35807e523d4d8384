"""The only module that talks to embreex: BVH build, closest-hit and occlusion queries.

embreex does no shape checks (fewer direction rows than origins segfaults), ignores tnear
(always 0) and overwrites `dists`; this wrapper validates and copies so callers cannot
crash the process. Queries are split across threads: embreex releases the GIL.
"""
from __future__ import annotations

import copy
from concurrent.futures import ThreadPoolExecutor

import numpy as np

try:
    from embreex import rtcore_scene as _rtcs
    from embreex.mesh_construction import TriangleMesh as _TriangleMesh
except ImportError as exc:  # pragma: no cover - reported to the user by the caller
    _rtcs = None
    _IMPORT_ERROR = exc
else:
    _IMPORT_ERROR = None

MIN_PER_THREAD = 4096  # below this, threading costs more than it saves


class Accel:
    def __init__(self, vertices: np.ndarray, faces: np.ndarray, threads: int = 1):
        if _rtcs is None:
            raise RuntimeError(f"embreex is not available: {_IMPORT_ERROR}")
        vertices = np.ascontiguousarray(vertices, dtype=np.float32)
        faces = np.ascontiguousarray(faces, dtype=np.int32)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError("Accel: vertices must be (V,3) and faces (F,3)")
        if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise ValueError("Accel: face index out of range")
        if not np.all(np.isfinite(vertices)):
            raise ValueError("Accel: vertices must be finite")
        self.threads = max(1, int(threads))
        self.count = len(faces)
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self._scene = None
        if self.count:
            self._scene = _rtcs.EmbreeScene(robust=True)
            _TriangleMesh(self._scene, vertices, faces)
            # Commit the BVH now, single-threaded, before threads share the scene.
            one = np.zeros((1, 3), np.float32)
            self._scene.run(one, np.array([[0, 0, 1]], np.float32), dists=np.ones(1, np.float32))

    def serial(self) -> "Accel":
        """A view of the same BVH that answers on the calling thread: for work that is
        already split over threads chunk by chunk (engine/parallel.py)."""
        view = copy.copy(self)
        view.threads = 1
        view._pool = None
        return view

    def close(self, wait: bool = False):
        """Shut the query threads down; wait=True returns after they have ended."""
        if self._pool is not None:
            self._pool.shutdown(wait=wait)
            self._pool = None

    def __del__(self):
        self.close()

    @staticmethod
    def _prepare(origins, directions, tmax):
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
            raise ValueError(f"Accel: origins {o.shape} and directions {d.shape} must both be (N,3)")
        n = len(o)
        if tmax is None:
            t = np.full(n, np.finfo(np.float32).max, np.float32)
        else:
            t = np.array(np.broadcast_to(np.asarray(tmax, np.float32), (n,)), np.float32)
            t = np.where(np.isnan(t), 0.0, np.minimum(t, np.finfo(np.float32).max)).astype(np.float32)
        return o, d, t

    def _split(self, n):
        parts = min(self.threads, max(1, n // MIN_PER_THREAD))
        return [(n * i // parts, n * (i + 1) // parts) for i in range(parts)]

    def intersect(self, origins, directions, tmax=None):
        """Closest hits. Returns (t, prim, u, v); prim = -1 where the ray misses.
        Directions should be unit length: t is in units of |direction|."""
        o, d, tf = self._prepare(origins, directions, tmax)
        n = len(o)
        t = np.full(n, np.inf)
        prim = np.full(n, -1, np.int64)
        u = np.zeros(n)
        v = np.zeros(n)
        if self._scene is None or n == 0:
            return t, prim, u, v

        def work(a, b):
            res = self._scene.run(o[a:b], d[a:b], dists=tf[a:b].copy(), output=True)
            hit = res["geomID"] >= 0
            prim[a:b] = np.where(hit, res["primID"], -1)
            t[a:b] = np.where(hit, res["tfar"], np.inf)
            u[a:b] = res["u"]
            v[a:b] = res["v"]

        self._run(work, n)
        return t, prim, u, v

    def occluded(self, origins, directions, tmax=None) -> np.ndarray:
        """True where something lies between the origin and distance tmax."""
        o, d, tf = self._prepare(origins, directions, tmax)
        n = len(o)
        out = np.zeros(n, bool)
        if self._scene is None or n == 0:
            return out

        def work(a, b):
            # OCCLUDED must be called without output (docs/design.md, Embree (embreex)
            # facts): 0 = blocked, -1 = clear.
            res = self._scene.run(o[a:b], d[a:b], dists=tf[a:b].copy(), query="OCCLUDED")
            out[a:b] = np.asarray(res) == 0

        self._run(work, n)
        return out

    def occluded_into(self, o32, d32, tmax32, blocked) -> np.ndarray:
        """Accel.occluded for rays already in Embree's layout, written by a kernel: o32,
        d32 (N,3) and tmax32 (N,) C-contiguous float32 (tmax finite, >= 0; Embree
        overwrites it), blocked (N,) bool receives the answer (and is returned). Raises
        ValueError on other shapes or types (embreex does not check: a short array crashes
        the process)."""
        n = len(o32)
        for name, a, shape in (("origins", o32, (n, 3)), ("directions", d32, (n, 3)),
                               ("tmax", tmax32, (n,))):
            if a.dtype != np.float32 or a.shape != shape or not a.flags.c_contiguous:
                raise ValueError(f"Accel.occluded_into: {name} must be C-contiguous float32 "
                                 f"{shape}, got {a.dtype} {a.shape}")
        if blocked.dtype != np.bool_ or blocked.shape != (n,):
            raise ValueError(f"Accel.occluded_into: blocked must be bool ({n},), got "
                             f"{blocked.dtype} {blocked.shape}")
        if self._scene is None or n == 0:
            blocked[:] = False
            return blocked

        def work(a, b):
            res = self._scene.run(o32[a:b], d32[a:b], dists=tmax32[a:b], query="OCCLUDED")
            blocked[a:b] = np.asarray(res) == 0

        self._run(work, n)
        return blocked

    def _run(self, work, n):
        chunks = self._split(n)
        if self._pool is None or len(chunks) == 1:
            for a, b in chunks:
                work(a, b)
        else:
            list(self._pool.map(lambda ab: work(*ab), chunks))
