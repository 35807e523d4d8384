"""Cycles' Pointiness attribute (Geometry node > Pointiness): a per-vertex measure of how
convex (towards 1) or concave (towards 0) a mesh is at each vertex, 0.5 on a flat region.

Computed once per mesh at export, as Cycles computes it when it syncs a Blender mesh
(Blender 5.0, intern/cycles/blender/mesh.cpp, attr_create_pointiness):
 1. vertices at (almost) the same position are welded: sorted by the float32 sum of their
    coordinates (exact duplicates by descending index), a vertex points to the first later
    vertex whose sum is within 3 FLT_EPSILON and whose squared distance is below
    FLT_EPSILON; chains are followed to their end (the "original" vertex);
 2. the welded vertex normal is the normalised sum of the Blender vertex normals of its
    duplicates;
 3. over the mesh's edges (each welded pair once), the unit edge directions are summed at
    both ends (pointing away from the vertex); raw = acos(N . mean edge direction) / pi;
 4. one blur step: value = (raw + sum of the raw values of its edge neighbours) /
    (edges + 1), copied to the duplicates.
The value is then interpolated over each triangle from its corners, as any vertex
attribute (svm_node_attr). Works in float32 as Cycles does.
"""
from __future__ import annotations

import numpy as np

FLT_EPSILON = np.float32(np.finfo(np.float32).eps)


def weld_map(positions: np.ndarray) -> np.ndarray:
    """(V,) int64: each vertex's original (step 1 above) for positions (V,3).

    Cycles scans forward in the sorted order while the sums stay within the window; a
    mesh whose vertices share sums (a flat grid: every anti-diagonal) makes that scan
    long, so the candidates come from a kd-tree of the pairs closer than sqrt(FLT_EPSILON)
    instead, and each vertex takes the first candidate after it in the sorted order whose
    sum lies in the window (the sums are sorted: the window is a run) - the same choice."""
    from scipy.spatial import cKDTree
    co = np.asarray(positions, np.float32).reshape(-1, 3)
    n = len(co)
    target = np.arange(n, dtype=np.int64)  # vertex -> its original (itself if none)
    if n < 2:
        return target
    total = (co[:, 0] + co[:, 1]) + co[:, 2]  # float32, summed in Cycles' order
    # VertexAverageComparator: ascending sum, exact duplicates by descending index.
    order = np.lexsort((-np.arange(n), total))
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    pairs = cKDTree(co.astype(np.float64)).query_pairs(
        float(np.sqrt(FLT_EPSILON)) * 1.001, output_type="ndarray")
    if not len(pairs):
        return target
    # Each pair from its earlier vertex (in the sorted order) to the later one.
    a, b = pairs[:, 0], pairs[:, 1]
    swap = rank[a] > rank[b]
    a, b = np.where(swap, b, a), np.where(swap, a, b)
    d = co[b] - co[a]
    ok = ((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]) < FLT_EPSILON) & (
        (total[b] - total[a]) <= np.float32(3.0) * FLT_EPSILON)
    a, b = a[ok], b[ok]
    if not len(a):
        return target
    # The first candidate after each vertex in the sorted order.
    pick = np.lexsort((rank[b], a))
    a, b = a[pick], b[pick]
    first = np.ones(len(a), bool)
    first[1:] = a[1:] != a[:-1]
    target[a[first]] = b[first]
    # Follow each chain to the vertex that points to itself.
    while True:
        nxt = target[target]
        if np.array_equal(nxt, target):
            return target
        target = nxt


def pointiness(positions: np.ndarray, vertex_normals: np.ndarray,
               edges: np.ndarray) -> np.ndarray:
    """(V,) float32 Cycles pointiness, 0..1, of a mesh: positions (V,3) and Blender's
    vertex normals (V,3) in object space, edges (E,2) vertex indices (the mesh's edges,
    not its triangles' sides)."""
    co = np.asarray(positions, np.float32).reshape(-1, 3)
    n = len(co)
    if n == 0:
        return np.zeros(0, np.float32)
    orig = weld_map(co)
    nrm = np.zeros((n, 3), np.float32)
    np.add.at(nrm, orig, np.asarray(vertex_normals, np.float32).reshape(-1, 3))
    nrm = nrm[orig]
    ln = np.sqrt((nrm * nrm).sum(axis=1))
    nrm = nrm / np.where(ln > 0, ln, 1.0)[:, None]
    e = orig[np.asarray(edges, np.int64).reshape(-1, 2)]
    # EdgeMap: each welded pair (unordered) once, in the order first met.
    key = np.sort(e, axis=1)
    _, first = np.unique(key[:, 0] * n + key[:, 1], return_index=True)
    e = e[np.sort(first)]
    v0, v1 = e[:, 0], e[:, 1]
    edge = co[v1] - co[v0]
    el = np.sqrt((edge * edge).sum(axis=1))
    edge = np.where(el[:, None] > 0, edge / np.where(el > 0, el, 1.0)[:, None], 0.0)
    edge = edge.astype(np.float32)
    accum = np.zeros((n, 3), np.float32)
    np.add.at(accum, v0, edge)
    np.add.at(accum, v1, -edge)
    count = np.zeros(n, np.int64)
    np.add.at(count, v0, 1)
    np.add.at(count, v1, 1)
    raw = np.zeros(n, np.float32)
    own = (orig == np.arange(n)) & (count > 0)
    mean = accum[own] / count[own][:, None].astype(np.float32)
    cos = np.clip((nrm[own] * mean).sum(axis=1), -1.0, 1.0)
    raw[own] = (np.arccos(cos) / np.pi).astype(np.float32)
    data = raw.copy()
    np.add.at(data, v0, raw[v1])
    np.add.at(data, v1, raw[v0])
    data = data / (count + 1).astype(np.float32)
    return data[orig].astype(np.float32)
