"""A script-built Blender mesh in one fixed element order, the same in every process.

Blender 5.0.1's UV-sphere builders (`bpy.ops.mesh.primitive_uv_sphere_add`,
`bmesh.ops.create_uvsphere`) make the same vertices and faces in another face order, each
face starting at another corner, in every process; Blender's loop triangles (which
diagonal splits a quad) and vertex normals (summed in face order) follow that order, so a
scene built by a script rendered differently run to run, in Cycles and in our engine
alike (docs/design.md, Blender facts; docs/performance.md, "### determinism51"). The
cube, ico sphere, cylinder, torus, monkey and cone were the same in every process.

Used by the benches, the Blender tests, tools/ and example_blends/make_blends.py (each puts
the repository root on sys.path); it needs bpy only through the mesh it is given (the
engine never imports bpy).
"""
from __future__ import annotations

import numpy as np

# Attribute data type -> (foreach key, values per element, numpy dtype).
_LAYOUT = {
    "FLOAT": ("value", 1, np.float32), "INT": ("value", 1, np.int32),
    "INT8": ("value", 1, np.int32), "BOOLEAN": ("value", 1, bool),
    "FLOAT2": ("vector", 2, np.float32), "FLOAT_VECTOR": ("vector", 3, np.float32),
    "INT32_2D": ("value", 2, np.int32), "INT16_2D": ("value", 2, np.int32),
    "FLOAT_COLOR": ("color", 4, np.float32), "QUATERNION": ("value", 4, np.float32),
    "FLOAT4X4": ("value", 16, np.float32),
}


def _permute(me, domain, perm):
    """Reorder every attribute of `domain` ('EDGE', 'FACE', 'CORNER'): new[i] = old[perm[i]]."""
    for a in list(me.attributes):
        if a.domain != domain:
            continue
        if a.data_type not in _LAYOUT:
            # BYTE_COLOR would round-trip through floats, STRING has no foreach.
            raise ValueError(f"canonical_faces: cannot reorder {a.data_type} attribute "
                             f"{a.name!r}")
        key, width, dtype = _LAYOUT[a.data_type]
        old = np.empty(len(a.data) * width, dtype)
        a.data.foreach_get(key, old)
        a.data.foreach_set(key, old.reshape(len(a.data), width)[perm].ravel())


def canonical_faces(me):
    """Put Mesh `me`'s edges and faces in a fixed order, in place; vertices untouched.

    Each face starts at its smallest vertex index (winding kept) and the faces are sorted
    by their vertex tuples; each edge's vertex pair is (smaller, larger) and the edges are
    sorted by it. Every edge, face and face-corner attribute (UV maps, `sharp_face`,
    `material_index`, selections) moves with its element, so nothing but the order changes.
    Call it right after building the mesh (before modifiers read it).
    Source: the order problem is Blender 5.0.1's `create_uvsphere` (see the module text).
    """
    n_faces, n_corners, n_edges = len(me.polygons), len(me.loops), len(me.edges)
    start = np.empty(n_faces, np.int32)
    total = np.empty(n_faces, np.int32)
    me.polygons.foreach_get("loop_start", start)
    me.polygons.foreach_get("loop_total", total)
    corner_vert = np.empty(n_corners, np.int32)
    me.loops.foreach_get("vertex_index", corner_vert)
    keys, corners = [], []
    for s, t in zip(start.tolist(), total.tolist()):
        ring = corner_vert[s:s + t]
        idx = s + (np.arange(t) + int(np.argmin(ring))) % t
        keys.append(tuple(corner_vert[idx].tolist()))
        corners.append(idx)
    face_order = sorted(range(n_faces), key=keys.__getitem__)
    corner_order = (np.concatenate([corners[f] for f in face_order])
                    if n_faces else np.empty(0, np.int64))
    new_start = np.zeros(n_faces, np.int32)
    np.cumsum(total[face_order][:-1], out=new_start[1:])
    _permute(me, "FACE", np.asarray(face_order, np.int64))
    _permute(me, "CORNER", corner_order)
    me.polygons.foreach_set("loop_start", new_start)

    verts = np.empty(2 * n_edges, np.int32)
    me.edges.foreach_get("vertices", verts)
    verts = np.sort(verts.reshape(n_edges, 2), axis=1)
    edge_order = np.lexsort((verts[:, 1], verts[:, 0]))
    _permute(me, "EDGE", edge_order)  # .edge_verts among them, pairs still unsorted
    me.edges.foreach_set("vertices", verts[edge_order].ravel())
    new_edge = np.empty(n_edges, np.int32)
    new_edge[edge_order] = np.arange(n_edges, dtype=np.int32)
    corner_edge = np.empty(n_corners, np.int32)
    me.loops.foreach_get("edge_index", corner_edge)
    me.loops.foreach_set("edge_index", new_edge[corner_edge])
    me.update()
    return me


def primitive_uv_sphere_add(**kwargs):
    """`bpy.ops.mesh.primitive_uv_sphere_add(**kwargs)`, its mesh then `canonical_faces`:
    the same object (returned, the active one) in every process."""
    import bpy
    bpy.ops.mesh.primitive_uv_sphere_add(**kwargs)
    obj = bpy.context.active_object
    canonical_faces(obj.data)
    return obj
