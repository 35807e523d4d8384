"""Material displacement as Cycles renders it by default: "Bump Only".

A material's Material Output > Displacement input is, in Cycles, a world-space displacement
vector per shading point. With Material > Settings > Displacement "Bump Only" (Blender's
default) or "Displacement and Bump", Cycles does not move the surface for shading: it turns
the vector D into a height along the smooth normal N, h = dot(D, N), and bumps the shading
normal with it at distance 1 (intern/cycles/scene/shader_graph.cpp
ShaderGraph::bump_from_displacement: three copies of the displacement graph, dot products
with the Geometry node's Normal, a Bump node with distance 1 whose output sets sd->N before
any closure reads it). So:
  - a BSDF whose Normal input is unlinked shades with the bumped normal;
  - a BSDF fed by a Bump or Bevel node bumps that normal again (their Normal input
    defaults to sd->N);
  - a BSDF fed by a Normal Map keeps the Normal Map's normal (svm_node_normal_map builds
    it from the interpolated vertex normal, not sd->N).

The vectors, as Cycles' nodes make them (intern/cycles/kernel/svm/displace.h):
  Displacement         D = n (height - midlevel) scale, n the Normal input (default: the
                       smooth normal); in Object space n is taken to object space
                       normalised, scaled there and brought back: D = M normalize(M^T n)
                       (height - midlevel) scale, M the object's linear matrix (so an
                       object scaled by k displaces k times further).
  Vector Displacement  D = (vector - midlevel) scale, in World space as is, in Object space
                       M times it (Tangent space: not read; the add-on warns).
  anything else        its vector (a value v: (v, v, v), Cycles' float-to-vector).
Heights are in metres, as the bump's distance is 1.
"""
from __future__ import annotations

import numpy as np

from .sampling import dot, normalize

SPACES = ("OBJECT", "WORLD")
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # linear Rec. 709, as normalmap.Bump


def _object_linear(geo, prim) -> np.ndarray:
    """(N,3,3) the linear part of each hit's object matrix (Geometry.object_linear by
    the triangle's object; identity without one)."""
    table = None if geo is None else getattr(geo, "object_linear", None)
    if table is None or not len(table):
        return np.broadcast_to(np.eye(3), (len(prim), 3, 3))
    oid = np.take(geo.object_id, np.asarray(prim, np.int64))
    return np.take(table, oid, axis=0)


def _smooth_normals(geo, prim, u, v) -> np.ndarray:
    """(N,3) Cycles' sd->N before any bump: the interpolated smooth normal (winding side;
    its sign cancels in dot(D, N) for the default direction)."""
    if geo is None:
        return np.tile([0.0, 0.0, 1.0], (len(prim), 1))
    return geo.shading_normals(np.asarray(prim, np.int64), np.asarray(u, np.float64),
                               np.asarray(v, np.float64))


def _eval(x, geo, prim, u, v):
    if hasattr(x, "evaluate"):
        return np.asarray(x.evaluate(geo, prim, u, v), np.float64)
    return np.broadcast_to(np.asarray(x, np.float64), (len(prim),) + np.shape(x))


def _scalar(x, geo, prim, u, v) -> np.ndarray:
    a = _eval(x, geo, prim, u, v)
    # a colour into a value socket: its luminance (Cycles' NODE_CONVERT_CF, as Bump reads
    # its height; the add-on converts vectors into values itself, by their average)
    return a @ LUMINANCE if a.ndim == 2 else a


class Displacement:
    """Cycles' Displacement node (svm_node_displacement): (N,3) world-space displacement
    vectors (m) at hits. height, midlevel, scale: engine nodes or constants (values);
    normal: a node giving (N,3) world directions, or None for the smooth normal; space
    'OBJECT' (Blender's default) or 'WORLD'."""

    def __init__(self, height, midlevel=0.5, scale=1.0, normal=None, space="OBJECT"):
        if space not in SPACES:
            raise ValueError(f"Displacement space {space!r}: expected one of {SPACES}")
        self.height, self.midlevel, self.scale = height, midlevel, scale
        self.normal, self.space = normal, space

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        amount = ((_scalar(self.height, geo, prim, u, v)
                   - _scalar(self.midlevel, geo, prim, u, v))
                  * _scalar(self.scale, geo, prim, u, v))
        n = (_smooth_normals(geo, prim, u, v) if self.normal is None
             else _eval(self.normal, geo, prim, u, v))
        if self.space == "OBJECT":
            m = _object_linear(geo, prim)
            # object_inverse_normal_transform (M^T, normalised), then object_dir_transform
            n_obj = normalize(np.einsum("nji,nj->ni", m, n))
            n = np.einsum("nij,nj->ni", m, n_obj)
        return n * amount[:, None]


class VectorDisplacement:
    """Cycles' Vector Displacement node (svm_node_vector_displacement), World or Object
    space: (N,3) world-space vectors (m), (vector - midlevel) scale, times the object's
    linear matrix in Object space."""

    def __init__(self, vector, midlevel=0.0, scale=1.0, space="OBJECT"):
        if space not in SPACES:
            raise ValueError(f"Vector Displacement space {space!r}: expected one of {SPACES}")
        self.vector, self.midlevel, self.scale, self.space = vector, midlevel, scale, space

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        vec = _eval(self.vector, geo, prim, u, v)
        if vec.ndim == 1:
            vec = np.repeat(vec[:, None], 3, axis=1)
        d = ((vec - _scalar(self.midlevel, geo, prim, u, v)[:, None])
             * _scalar(self.scale, geo, prim, u, v)[:, None])
        if self.space == "OBJECT":
            d = np.einsum("nij,nj->ni", _object_linear(geo, prim), d)
        return d


class DisplacementHeight:
    """The height Cycles' automatic bump reads from a displacement: dot(D, N) (m), D the
    (N,3) vectors of `displacement` (a value v reads (v, v, v)), N the smooth normal.
    evaluate -> (N,)."""

    def __init__(self, displacement):
        self.displacement = displacement

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        d = _eval(self.displacement, geo, prim, u, v)
        if d.ndim == 1:
            d = np.repeat(d[:, None], 3, axis=1)
        return dot(d, _smooth_normals(geo, prim, u, v))


class DisplacedNormals:
    """A material's normal with Cycles' bump from its displacement: `bump` (an
    engine.normalmap.Bump of a DisplacementHeight) sets sd->N, the normal every closure
    and every view-dependent node reads; `then` (the BSDF's own Bump node, or None) bumps
    that normal again. engine.bsdf.surface_hit reads the two apart (the bump shadowing
    term compares a closure's normal with sd->N, so a displacement alone adds none);
    perturb gives the final normal, as NormalMap.perturb."""

    def __init__(self, bump, then=None):
        self.bump, self.then = bump, then

    def perturb(self, geo, prim, u, v, n: np.ndarray) -> np.ndarray:
        out = self.bump.perturb(geo, prim, u, v, n)
        return out if self.then is None else self.then.perturb(geo, prim, u, v, out)
