"""The shading normals Cycles renders an evaluated Blender mesh with, read with foreach_get.

Cycles does not shade with the normals Blender's viewport draws (`Mesh.corner_normals`,
what `Mesh.normals_domain` describes). Its mesh sync (intern/cycles/blender/mesh.cpp,
create_mesh, Blender 4.2 to 5.0) asks for the domain with ``normals_domain(true)``
(blenkernel mesh_normals.cc, `support_sharp_face`), and:

- domain CORNER: every triangle interpolates the mesh's corner normals;
- otherwise (POINT or FACE) each triangle is smooth or flat on its own: smooth = not the
  face's ``sharp_face`` when the mesh has that attribute, else smooth = (domain is POINT).
  A smooth triangle interpolates the *vertex* normals (`Mesh.vertex_normals`: the
  angle-weighted mean of all faces around a vertex, flat ones included; custom normals
  when they are stored per point), a flat triangle uses its geometric normal Ng.

`normals_domain(true)` differs from the domain Python reads (`normals_domain(false)`) in
one case: no custom normals, no sharp edge, and some faces flat while others are smooth.
Python says CORNER (the flat faces split their edges, as Workbench draws them); Cycles
says POINT, so the smooth faces next to a flat one lean towards it: a cylinder with
smooth sides and flat caps (no edge marked sharp) has its side normals tilted towards the
caps near the rims, and that tilt makes the highlight Cycles shows on the side.

A second consequence of the rule: a mesh whose every edge is marked sharp (domain FACE)
but whose faces are marked smooth in a ``sharp_face`` attribute renders smooth in Cycles
(vertex normals), while the same mesh without the attribute (Shade Smooth removes it)
renders flat. Both are followed here as Cycles does them.

Not covered: Cycles' adaptive subdivision (it dices the cage mesh itself), and a custom
normal stored on edges (Blender never writes one).
"""
from __future__ import annotations

import numpy as np


def _foreach(collection, attr, count, width, dtype):
    buf = np.empty(count * width, dtype=dtype)
    if count:
        collection.foreach_get(attr, buf)
    return buf.reshape(count, width) if width > 1 else buf


def _boolean_attribute(me, name: str, domain: str, count: int):
    """(count,) bool values of the mesh's boolean attribute `name` on `domain`, or None
    when the mesh has no such attribute (Blender then reads False everywhere)."""
    attr = me.attributes.get(name)
    if attr is None or attr.domain != domain or attr.data_type != "BOOLEAN":
        return None
    return _foreach(attr.data, "value", count, 1, bool)


def cycles_normals_domain(me) -> str:
    """'POINT', 'FACE' or 'CORNER': the normals domain Cycles syncs `me` with
    (blenkernel Mesh::normals_domain(support_sharp_face=true))."""
    domain = me.normals_domain  # normals_domain(false): custom normals, all-sharp cases
    if domain != "CORNER" or me.has_custom_normals:
        return domain
    sharp_edge = _boolean_attribute(me, "sharp_edge", "EDGE", len(me.edges))
    if sharp_edge is None or not sharp_edge.any():
        # CORNER only because flat and smooth faces mix: Cycles keeps POINT.
        return "POINT"
    return domain


def shading_normals(me, co: np.ndarray, faces: np.ndarray, loops: np.ndarray):
    """The normals Cycles shades the mesh's loop triangles with.

    me: the evaluated bpy Mesh; co (V,3) float64 local vertex positions; faces (F,3) int
    vertex indices and loops (F,3) int corner indices of me.loop_triangles.
    Returns None (every triangle flat: the engine uses geometric normals), (V,3) float64
    unit vertex normals (every triangle smooth), or (F,3,3) float64 unit normals at each
    triangle's corners (a flat triangle's three corners hold its geometric normal)."""
    domain = cycles_normals_domain(me)
    if domain == "CORNER":
        corner = _foreach(me.corner_normals, "vector", len(me.loops), 3, np.float32)
        return corner[loops].astype(np.float64)
    nt = len(faces)
    sharp_face = _boolean_attribute(me, "sharp_face", "FACE", len(me.polygons))
    if sharp_face is None:
        smooth = np.full(nt, domain == "POINT")
    else:
        poly = _foreach(me.loop_triangles, "polygon_index", nt, 1, np.int32)
        smooth = ~sharp_face[poly]
    if not smooth.any():
        return None
    vertex = _foreach(me.vertex_normals, "vector", len(me.vertices), 3, np.float32)
    vertex = vertex.astype(np.float64)
    if smooth.all():
        return vertex
    # Flat triangles among smooth ones: Cycles' Ng, the winding normal of the triangle
    # (per triangle, so both halves of a non-planar quad keep their own).
    tri = co[faces]
    ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ng /= np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-300)
    return np.where(smooth[:, None, None], vertex[faces], ng[:, None, :])
