"""Cycles' Bevel shader node: a shading normal averaged from the surface around the hit,
found by rays while the node is evaluated (Blender, intern/cycles/kernel/svm/bevel.h,
svm_bevel / svm_node_bevel), so hard edges shade as if rounded over Radius.

For each of Samples samples at a hit P: an axis of the frame (Ng, T, B) is picked with
probability 1/2, 1/4, 1/4 (the first random number), a point of the disk perpendicular to
it at distance r from the planar cubic falloff 10 (R - r)^3 / (pi R^5) (the second random
number, through svm_bevel_cubic_sample's quintic root), and a probe ray crosses the disk
there along the axis, 2 h long, h = sqrt(R^2 - r^2). Every surface of the hit's own
object it meets (scene_intersect_local; Cycles keeps a random 4 of them and scales, here
all are kept: the same expectation) adds its smooth normal N_hit weighted by multiple
importance over the three axes (power heuristic, pick pdf x |axis . Ng_hit|) and by
cubic(|P_hit - P|) / cubic(r). The bevelled normal is the normalised sum (the hit's own
normal where the sum vanishes). With the node's Normal input linked (a Normal Map, a
Bump): normalize(n_in + (n_bevel - N)).

Differences from Cycles: Cycles bevels only camera rays and sharp specular continuations
(its path's min_ray_pdf >= 8); here every evaluation bevels (photon and final-gather hits
too), which changes indirect light near bevelled edges slightly. The random numbers are
a stratified pattern shifted by a hash of the hit (as engine/ambientocclusion.py): a hit
always gets the same normal, for any worker count. The BVH is the Geometry's tracer
(ambientocclusion.attach_tracer); without it the normal stays the hit's own.
"""
from __future__ import annotations

import numpy as np

from .ambientocclusion import hash_pair
from .rayoffset import offset_along_normal

# The most surfaces one probe ray collects (closest-hit queries along it)
PROBE_LAYERS = 8
_GOLDEN = 0.6180339887498949


def cubic_eval(radius, r):
    """svm_bevel_cubic_eval: 10 (R - r)^3 / (pi R^5) for r < R, else 0 (broadcast)."""
    R = np.asarray(radius, np.float64)
    r = np.asarray(r, np.float64)
    f = np.maximum(R - r, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 10.0 * f * f * f / (R ** 5 * np.pi)
    return np.where(r < R, out, 0.0)


def cubic_sample(radius, xi):
    """svm_bevel_cubic_sample: (r, h) for uniforms xi, r the root of 10x^2 - 20x^3 +
    15x^4 - 4x^5 = xi (Newton-Raphson from 0.25, at most 10 steps, as Cycles) times R and
    h = sqrt(R^2 - r^2)."""
    xi = np.asarray(xi, np.float64)
    x = np.full(xi.shape, 0.25)
    active = np.ones(xi.shape, bool)
    for _ in range(10):
        x2 = x * x
        x3 = x2 * x
        nx = 1.0 - x
        f = 10.0 * x2 - 20.0 * x3 + 15.0 * x2 * x2 - 4.0 * x2 * x3 - xi
        fd = 20.0 * (x * nx) * (nx * nx)
        active &= ~((np.abs(f) < 1e-6) | (fd == 0.0))
        if not active.any():
            break
        step = np.where(active, f / np.where(fd == 0.0, 1.0, fd), 0.0)
        x = np.clip(x - step, 0.0, 1.0)
    R = np.asarray(radius, np.float64)
    r = x * R
    return r, np.sqrt(np.maximum(R * R - r * r, 0.0))


def _frame(n):
    """Cycles' make_orthonormals: (T, B) (N,3) each for unit normals n (N,3)."""
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    use_xy = (nx != ny) | (nx != nz)
    t = np.where(use_xy[:, None], np.column_stack([nz, nz, -nx - ny]),
                 np.column_stack([nz - ny, nx + nz, -nx - ny]))
    t = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    return t, np.cross(n, t)


class Bevel:
    """radius  the node's Radius (m): a constant or a node (per hit)
    samples    its Samples (1..128; Blender's default 4)
    normal     None, or a NormalMap / Bump whose normal the bevel offsets (the node's
               Normal input)
    perturb(geo, prim, u, v, n) as NormalMap.perturb: (N,3) unit normals on the winding
    side, n the hits' unperturbed ones."""

    def __init__(self, radius=0.05, samples: int = 4, normal=None):
        self.radius = radius
        self.samples = int(min(max(int(samples), 1), 128))
        self.normal = normal

    def perturb(self, geo, prim, u, v, n: np.ndarray) -> np.ndarray:
        from .shadernodes import _eval
        prim = np.asarray(prim, np.int64)
        u = np.asarray(u, np.float64)
        v = np.asarray(v, np.float64)
        n = np.asarray(n, np.float64)
        out = n.copy()
        tracer = getattr(geo, "tracer", None)
        if tracer is not None and len(prim):
            radius = np.broadcast_to(_eval(self.radius, geo, prim, u, v, 1), (len(prim),))
            rows = np.nonzero(radius > 0)[0]
            if len(rows):
                out[rows] = self._bevel(geo, tracer, prim[rows], u[rows], v[rows], n[rows],
                                        radius[rows])
        if self.normal is not None:
            ref = self.normal.perturb(geo, prim, u, v, n)
            mixed = ref + (out - n)
            ln = np.linalg.norm(mixed, axis=1, keepdims=True)
            out = np.where(ln > 0, mixed / np.where(ln > 0, ln, 1.0), ref)
        return out

    def _bevel(self, geo, tracer, prim, u, v, n, radius):
        m, S = len(prim), self.samples
        p = geo.hit_points(prim, u, v)
        ng = np.asarray(np.take(geo.ng, prim, axis=0), np.float64).reshape(-1, 3)
        t, b = _frame(ng)
        h1, h2 = hash_pair(prim, u, v, salt=0x64C6A40E)
        s = np.arange(S, dtype=np.float64)
        xa = np.mod((s[None, :] + 0.5) / S + h1[:, None], 1.0).ravel()
        xr = np.mod(s[None, :] * _GOLDEN + h2[:, None], 1.0).ravel()
        rep = np.repeat(np.arange(m), S)
        # The axis picked: N (xa < 1/2), T (< 3/4) or B; disk_u rescaled to [0, 1)
        pick = np.where(xa < 0.5, 0, np.where(xa < 0.75, 1, 2))
        du = np.where(pick == 0, xa * 2.0, np.where(pick == 1, (xa - 0.5) * 4.0,
                                                    (xa - 0.75) * 4.0))
        axes = np.stack([ng[rep], t[rep], b[rep]], axis=1)  # (R,3,3): N, T, B
        order = np.array([[0, 1, 2], [1, 0, 2], [2, 1, 0]])[pick]  # swapped as Cycles
        dn = np.take_along_axis(axes, order[:, 0, None, None].repeat(3, 2), 1)[:, 0]
        dt = np.take_along_axis(axes, order[:, 1, None, None].repeat(3, 2), 1)[:, 0]
        db = np.take_along_axis(axes, order[:, 2, None, None].repeat(3, 2), 1)[:, 0]
        pdfs = np.array([[0.5, 0.25, 0.25], [0.25, 0.5, 0.25], [0.25, 0.25, 0.5]])[pick]
        disk_r, height = cubic_sample(radius[rep], xr)
        phi = 2.0 * np.pi * du
        disk_p = (disk_r * np.cos(phi))[:, None] * dt + (disk_r * np.sin(phi))[:, None] * db
        origin = p[rep] + dn * height[:, None] + disk_p
        d = -dn
        tmax = 2.0 * height
        own = np.asarray(np.take(geo.object_id, prim), np.int64)[rep]
        sum_n = np.zeros((m, 3))
        disk_pdf = cubic_eval(radius[rep], disk_r)
        live = np.nonzero((tmax > 0) & (disk_pdf > 0))[0]
        o = origin.copy()
        left = tmax.copy()
        for _ in range(PROBE_LAYERS):
            if not len(live):
                break
            th, hp, hu, hv = tracer.intersect(o[live], d[live], left[live])
            hit = hp >= 0
            live, th, hp, hu, hv = live[hit], th[hit], hp[hit], hu[hit], hv[hit]
            if not len(live):
                break
            hit_p = geo.hit_points(hp, hu, hv)
            hit_ng = np.asarray(np.take(geo.ng, hp, axis=0), np.float64).reshape(-1, 3)
            mine = np.asarray(np.take(geo.object_id, hp), np.int64) == own[live]
            if mine.any():
                k = live[mine]
                g = hit_ng[mine]
                pn = pdfs[k, 0] * np.abs(np.einsum("ij,ij->i", dn[k], g))
                pt = pdfs[k, 1] * np.abs(np.einsum("ij,ij->i", dt[k], g))
                pb = pdfs[k, 2] * np.abs(np.einsum("ij,ij->i", db[k], g))
                den = pn * pn + pt * pt + pb * pb
                w = np.where(den > 0, pn / np.where(den > 0, den, 1.0), 0.0)
                r = np.linalg.norm(hit_p[mine] - p[rep[k]], axis=1)
                w = w * cubic_eval(radius[rep[k]], r) / disk_pdf[k]
                nh = geo.shading_normals(hp[mine], hu[mine], hv[mine])
                np.add.at(sum_n, rep[k], w[:, None] * nh)
            # On past this surface, whichever object it belongs to.
            o[live] = offset_along_normal(hit_p, hit_ng, d[live],
                                          geo.origin_offset(hp, hu, hv, hit_p, hit_ng))
            left[live] = left[live] - th
            live = live[left[live] > 0]
        ln = np.linalg.norm(sum_n, axis=1, keepdims=True)
        return np.where(ln > 0, sum_n / np.where(ln > 0, ln, 1.0), n)
