"""Cycles' Ambient Occlusion shader node: rays traced from the shading point while the
node tree is evaluated (Blender 5.0, intern/cycles/kernel/svm/ao.h, svm_node_ao / svm_ao).

At a hit P with normal N (the node's Normal input, else sd->N: the smooth shading normal
turned to the side the ray arrived from; negated with Inside), `samples` directions are
drawn cosine-weighted about N (a point d of the unit disk lifted to (d.x, d.y,
sqrt(1 - |d|^2)) in N's frame) and traced up to Distance:
    AO    = (rays that reach Distance unblocked) / samples      (0..1)
    Color = AO x Color input.
A ray is blocked by any surface that casts shadows (Cycles' opaque shadow ray,
PATH_RAY_SHADOW_OPAQUE: transparency is not looked at; Object > Visibility > Shadow off:
passed); with Only Local, by the hit's own object alone (scene_intersect_local), whatever
its visibility. Distance <= 0 or no BVH yet (a texture read before the render's BVH
exists: light preparation's emission averages) gives AO 1, as svm_ao's early outs.

The renderer's BVH reaches the node through the Geometry (`Geometry.tracer`, a view
answering on the calling thread: attach_tracer), so the node works wherever a material
is evaluated (camera hits, photon hits, the shadow rays' alpha) without a stage of its
own. Its random numbers are a hash of the hit (triangle, barycentrics: as
shadernodes.hit_random) that shifts a stratified pattern of the samples (a Fibonacci
lattice), so a hit always gets the same AO: the image is the same for any worker count
and chunking, and needs no seed of its own (the camera's and photons' seeded streams
place the hits). Cycles draws each sample from its path's sampler instead: the expected
value is the same, the noise pattern is not.
"""
from __future__ import annotations

import numpy as np

from .geometry import SHADOW
from .rayoffset import offset_along_normal
from .shadernodes import _PickBatch, _eval, _view

# Only Local: the most surfaces of other objects a ray passes before it counts as
# unblocked (each costs a closest-hit query for the rays still going)
LOCAL_LAYERS = 32
_GOLDEN = 0.6180339887498949  # 1 / phi: the Fibonacci lattice's second coordinate


def attach_tracer(geo, accel) -> None:
    """Let nodes that trace rays (AmbientOcclusion) query the BVH `accel` (an
    engine.visibility.VisibilityAccel) of Geometry `geo`: a view that answers on the
    calling thread (the nodes are evaluated inside the worker threads' chunks)."""
    geo.tracer = None if accel is None else accel.serial()


def hash_pair(prim, u, v, salt: int = 0x94D049BB133111EB):
    """(N,) two independent uniforms in [0, 1) per hit: hashes of the triangle and the
    barycentrics' float64 bits (splitmix64's finaliser, as shadernodes.hit_random, with
    other constants so they do not coincide with a Mix Shader's pick); salt tells the
    nodes that use them apart (AO, Bevel)."""
    from .integrator import _mix64 as mix  # (integrator imports shadernodes)
    p = np.asarray(prim).astype(np.uint64)
    bu = np.ascontiguousarray(u, np.float64).view(np.uint64)
    bv = np.ascontiguousarray(v, np.float64).view(np.uint64)
    with np.errstate(over="ignore"):
        h = mix(p * np.uint64(0xBF58476D1CE4E5B9) + np.uint64(salt))
        h = mix(h ^ bu)
        h = mix(h ^ bv)
        h2 = mix(h ^ np.uint64(0x9E3779B97F4A7C15))
    scale = 1.0 / 9007199254740992.0
    return ((h >> np.uint64(11)).astype(np.float64) * scale,
            (h2 >> np.uint64(11)).astype(np.float64) * scale)


def concentric_disk(a, b):
    """Cycles' sample_uniform_disk (kernel/sample/mapping.h): Shirley's concentric map of
    the unit square (a, b) onto the unit disk, (N,) each -> (N,2)."""
    x, y = 2.0 * a - 1.0, 2.0 * b - 1.0
    big = x * x > y * y
    zero = (x == 0.0) & (y == 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big, x, y)
        phi = np.where(big, 0.25 * np.pi * (y / np.where(big, x, 1.0)),
                       0.5 * np.pi - 0.25 * np.pi * (x / np.where(big, 1.0, y)))
    r = np.where(zero, 0.0, r)
    phi = np.where(zero, 0.0, phi)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)])


def ao_directions(n, samples: int, prim, u, v, salt: int = 0x94D049BB133111EB):
    """(N, S, 3) unit directions, cosine-weighted about the unit normals n (N,3): sample s
    of hit i is the Fibonacci lattice point ((s + 0.5) / S, s / phi) shifted by the hit's
    hash pair (toroidally), mapped to the disk (concentric_disk) and lifted to the
    hemisphere in n's frame (Cycles' make_orthonormals). salt: hash_pair's (another
    user of the directions than the node: engine/aopass.py)."""
    n = np.asarray(n, np.float64)
    s = np.arange(samples, dtype=np.float64)
    h1, h2 = hash_pair(prim, u, v, salt)
    a = np.mod((s[None, :] + 0.5) / samples + h1[:, None], 1.0)
    b = np.mod(s[None, :] * _GOLDEN + h2[:, None], 1.0)
    d = concentric_disk(a.ravel(), b.ravel()).reshape(len(n), samples, 2)
    z = np.sqrt(np.maximum(1.0 - (d * d).sum(axis=2), 0.0))
    # make_orthonormals (util/math.h): T perpendicular to N, B = N x T
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    use_xy = (nx != ny) | (nx != nz)
    t = np.where(use_xy[:, None], np.column_stack([nz, nz, -nx - ny]),
                 np.column_stack([nz - ny, nx + nz, -nx - ny]))
    t = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    bt = np.cross(n, t)
    return (d[..., 0:1] * t[:, None] + d[..., 1:2] * bt[:, None] + z[..., None] * n[:, None])


class OcclusionCore:
    """The Ambient Occlusion node's AO output, (N,) in [0, 1] per hit (module docstring).
    distance: constant or node (m); normal: None (sd->N) or a node giving (N,3);
    samples: Cycles' Samples (1..128); inside, only_local: its two options. The last
    batch's value is kept (the Color and AO outputs of one node read it once)."""

    def __init__(self, distance=1.0, normal=None, samples: int = 16, inside: bool = False,
                 only_local: bool = False):
        self.distance = distance
        self.normal = normal
        self.samples = int(min(max(int(samples), 1), 128))
        self.inside = bool(inside)
        self.only_local = bool(only_local)
        self._last = None

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_last"] = None
        return state

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        last = self._last
        if last is not None and last.matches(geo, prim, u, v):
            return last.pick
        ao = self._trace(geo, prim, u, v)
        ao.flags.writeable = False  # shared by the node's outputs
        if geo is not None:
            self._last = _PickBatch(geo, prim, u, v, ao)
        return ao

    def _trace(self, geo, prim, u, v):
        n_hits = len(prim)
        tracer = getattr(geo, "tracer", None) if geo is not None else None
        if tracer is None or n_hits == 0:
            return np.ones(n_hits)
        u = np.asarray(u, np.float64)
        v = np.asarray(v, np.float64)
        dist = np.broadcast_to(_eval(self.distance, geo, prim, u, v, 1), (n_hits,))
        if self.normal is not None:
            nrm = _eval(self.normal, geo, prim, u, v, 3)
        else:
            nrm = np.asarray(_view(geo, prim)[0], np.float64)
        ln = np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm = np.where(ln > 0, nrm / np.where(ln > 0, ln, 1.0), 0.0)
        if self.inside:
            nrm = -nrm
        ao = np.ones(n_hits)
        rows = np.nonzero((dist > 0) & (ln[:, 0] > 0))[0]
        if not len(rows):
            return ao
        S = self.samples
        d = ao_directions(nrm[rows], S, prim[rows], u[rows], v[rows]).reshape(-1, 3)
        hit_p = geo.hit_points(prim[rows], u[rows], v[rows])
        ng = np.asarray(np.take(geo.ng, prim[rows], axis=0), np.float64).reshape(-1, 3)
        gap = geo.origin_offset(prim[rows], u[rows], v[rows], hit_p, ng)
        # Each ray leaves from the side of its triangle it goes to (Cycles skips the
        # triangle itself: ray.self.prim).
        rp = np.repeat(np.arange(len(rows)), S)
        side = np.where(np.einsum("ij,ij->i", d, ng[rp]) < 0, -1.0, 1.0)
        o = hit_p[rp] + (side * gap[rp])[:, None] * ng[rp]
        tmax = np.repeat(dist[rows], S)
        if self.only_local:
            blocked = self._local(geo, tracer, o, d, tmax, np.repeat(
                np.asarray(np.take(geo.object_id, prim[rows]), np.int64), S))
        else:
            blocked = np.asarray(tracer.occluded(o, d, tmax, cls=SHADOW), bool)
        ao[rows] = 1.0 - blocked.reshape(len(rows), S).mean(axis=1)
        return ao

    @staticmethod
    def _local(geo, tracer, o, d, tmax, own):
        """(R,) bool: the ray meets a triangle of object `own` (R,) within tmax, passing
        other objects' surfaces (up to LOCAL_LAYERS of them)."""
        blocked = np.zeros(len(o), bool)
        live = np.arange(len(o))
        o, tmax = o.copy(), tmax.astype(np.float64).copy()
        for _ in range(LOCAL_LAYERS):
            if not len(live):
                break
            t, hp, hu, hv = tracer.intersect(o[live], d[live], tmax[live])
            hit = hp >= 0
            live, t, hp, hu, hv = live[hit], t[hit], hp[hit], hu[hit], hv[hit]
            mine = np.asarray(np.take(geo.object_id, hp), np.int64) == own[live]
            blocked[live[mine]] = True
            live, t, hp, hu, hv = live[~mine], t[~mine], hp[~mine], hu[~mine], hv[~mine]
            if not len(live):
                break
            # Continue from just beyond the other object's surface.
            p = geo.hit_points(hp, hu, hv)
            ng = np.asarray(np.take(geo.ng, hp, axis=0), np.float64).reshape(-1, 3)
            o[live] = offset_along_normal(p, ng, d[live],
                                          geo.origin_offset(hp, hu, hv, p, ng))
            tmax[live] = tmax[live] - t
            keep = tmax[live] > 0
            live = live[keep]
        return blocked


class AmbientOcclusion:
    """The Ambient Occlusion node's outputs: COLOR (N,3) = AO x color (constant or node),
    AO (N,) (the core's value). Several outputs of one node share one OcclusionCore."""

    def __init__(self, core: OcclusionCore, color=(1.0, 1.0, 1.0), output: str = "COLOR"):
        if output not in ("COLOR", "AO"):
            raise ValueError(f"Ambient Occlusion output: expected COLOR or AO, got {output!r}")
        self.core = core
        self.color = color
        self.output = output

    def evaluate(self, geo, prim, u, v):
        ao = self.core.evaluate(geo, prim, u, v)
        if self.output == "AO":
            return ao
        return ao[:, None] * _eval(self.color, geo, prim, u, v, 3)
