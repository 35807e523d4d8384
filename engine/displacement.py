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

import copy

import numpy as np

from .sampling import dot, normalize

SPACES = ("OBJECT", "WORLD")
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # linear Rec. 709, as bump.Bump


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
    engine.bump.Bump of a DisplacementHeight) sets sd->N, the normal every closure
    and every view-dependent node reads; `then` (the BSDF's own Bump node, or None) bumps
    that normal again. engine.bsdf.surface_hit reads the two apart (the bump shadowing
    term compares a closure's normal with sd->N, so a displacement alone adds none);
    perturb gives the final normal, as NormalMap.perturb."""

    def __init__(self, bump, then=None):
        self.bump, self.then = bump, then

    def perturb(self, geo, prim, u, v, n: np.ndarray) -> np.ndarray:
        out = self.bump.perturb(geo, prim, u, v, n)
        return out if self.then is None else self.then.perturb(geo, prim, u, v, out)


# --- True displacement: "Displacement Only" and "Displacement and Bump" -------------------
METHODS = ("BUMP", "DISPLACEMENT", "BOTH")


def _face_material_names(mesh) -> np.ndarray:
    """(F,) object array: the material name of each face of `mesh`."""
    names = np.asarray(list(mesh.materials), dtype=object)
    if mesh.material_ids is None or not len(names):
        return np.full(len(mesh.faces), names[0] if len(names) else "default", dtype=object)
    return names[np.clip(np.asarray(mesh.material_ids, np.int64), 0, len(names) - 1)]


def moves_vertices(material) -> bool:
    """True for a material (engine.scene.Material) whose true displacement moves the
    vertices of its faces ("DISPLACEMENT" or "BOTH" with a displacement node)."""
    return (material is not None and getattr(material, "displacement", None) is not None
            and getattr(material, "displacement_method", "BUMP") in ("DISPLACEMENT", "BOTH"))


def _vertex_offsets(mesh, materials, moved_faces) -> np.ndarray:
    """(V,3) world-space displacement (m) of each vertex of the world-space `mesh` (a copy,
    not a placement) that a moved face uses; zeros elsewhere. As Cycles'
    GeometryManager::displace (intern/cycles/scene/mesh_displace.cpp): each vertex once,
    by the first moved triangle in face order that uses it, at that triangle's corner
    (its attributes, its smooth normal or, flat, its face normal); non-finite vectors
    read 0 (ensure_finite)."""
    from . import geometry
    from .scene import Scene
    offsets = np.zeros((len(mesh.vertices), 3))
    faces = np.asarray(mesh.faces, np.int64)
    rows = np.nonzero(moved_faces)[0]
    if not len(rows):
        return offsets
    # The mesh alone, its materials without displacement (no recursion), re-centred as
    # prepare does: the nodes read positions, normals, UVs and object data from it.
    mats = {}
    for name in dict.fromkeys(mesh.materials):
        m = copy.copy(materials[name])
        m.displacement = None
        mats[name] = m
    geo, _ = geometry.prepare(Scene(meshes=[mesh], materials=mats))
    if geo.count != len(faces):
        raise ValueError(f"mesh '{mesh.name}': its triangles could not be matched for "
                         "displacement")
    corners = faces[rows].reshape(-1)
    vert, first = np.unique(corners, return_index=True)
    prim = rows[first // 3]
    corner = first % 3
    u = (corner == 1).astype(np.float64)  # barycentrics of corners 1 and 2
    v = (corner == 2).astype(np.float64)
    face_mat = _face_material_names(mesh)[prim]
    for name in dict.fromkeys(face_mat):
        sel = face_mat == name
        d = _eval(materials[name].displacement, geo, prim[sel], u[sel], v[sel])
        if d.ndim == 1:  # a value v displaces by (v, v, v), Cycles' float-to-vector
            d = np.repeat(d[:, None], 3, axis=1)
        offsets[vert[sel]] = np.where(np.isfinite(d), d, 0.0)
    return offsets


def _vertex_normals(vertices, faces) -> np.ndarray:
    """(V,3) Blender's vertex normals of a mesh: the faces' unit normals weighted by the
    corner angle at the vertex (zero where no face uses it)."""
    f = np.asarray(faces, np.int64)
    tri = np.asarray(vertices, np.float64)[f]
    fn = normalize(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    fn = np.where(np.isfinite(fn), fn, 0.0)
    acc = np.zeros((len(vertices), 3))
    for c in range(3):
        a = normalize(tri[:, (c + 1) % 3] - tri[:, c])
        b = normalize(tri[:, (c + 2) % 3] - tri[:, c])
        angle = np.arccos(np.clip(np.nan_to_num(dot(a, b)), -1.0, 1.0))
        np.add.at(acc, f[:, c], fn * angle[:, None])
    n = normalize(acc)
    return np.where(np.isfinite(n), n, 0.0)


def _recomputed_normals(vertices, faces, normals, true_faces, both_faces=None,
                        original=None):
    """Mesh normals after displacement, as Cycles shades them. Where a face's method is
    "Displacement Only" (true_faces (F,) bool) a vertex of such faces takes the
    normalised sum of their unit face normals (Cycles sums them unweighted); normals of
    "Displacement and Bump" faces (both_faces) stay (their bump already bends the
    shading normal), and on a flat-shaded mesh they become the undisplaced mesh's vertex
    normals (original: its (V,3) vertices): Cycles shades such faces smooth with the
    normals from before the move (measured: flat and smooth shading render the same).
    normals: None (flat: kept flat elsewhere), (V,3) per vertex, or (F,3,3) per corner
    (corners that shared a normal share the new one: sharp edges stay sharp)."""
    if normals is None and both_faces is not None and both_faces.any() and original is not None:
        f = np.asarray(faces, np.int64)
        tri = np.asarray(vertices, np.float64)[f]
        fn = normalize(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
        corner = np.repeat(np.where(np.isfinite(fn), fn, 0.0)[:, None, :], 3, axis=1)
        corner[both_faces] = _vertex_normals(original, f)[f[both_faces]]
        return corner
    if normals is None or not true_faces.any():
        return normals
    f = np.asarray(faces, np.int64)[true_faces]
    tri = vertices[f]
    fn = normalize(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    fn = np.where(np.isfinite(fn), fn, 0.0)
    normals = np.array(normals, np.float64)
    if normals.ndim == 2:
        acc = np.zeros((len(vertices), 3))
        np.add.at(acc, f.reshape(-1), np.repeat(fn, 3, axis=0))
        touched = np.unique(f)
        new = normalize(acc[touched])
        good = np.isfinite(new).all(axis=1)
        normals[touched[good]] = new[good]
        return normals
    # Per corner: a group is a vertex with one original normal.
    old = normals[true_faces].reshape(-1, 3)
    key = np.column_stack([f.reshape(-1), np.round(old * 1e5).astype(np.int64)])
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.reshape(-1)
    acc = np.zeros((group.max() + 1, 3))
    np.add.at(acc, group, np.repeat(fn, 3, axis=0))
    new = normalize(acc[group])
    new = np.where(np.isfinite(new).all(axis=1)[:, None], new, old)
    normals[true_faces] = new.reshape(-1, 3, 3)
    return normals


def displace_meshes(meshes, materials, should_cancel=None) -> list:
    """`meshes` (engine.scene.Mesh list) with the vertices that faces of a material with
    true displacement (Material.displacement, displacement_method "DISPLACEMENT" or
    "BOTH") use moved by its world-space vectors, normals recomputed for "DISPLACEMENT"
    (_recomputed_normals); the list itself when nothing moves. New Mesh objects: the
    caller's are not changed. Instances share their prototype's displacement, as Cycles
    displaces mesh data once (evaluated at the first placement, brought back to object
    space). Raises engine.parallel.Cancelled when should_cancel() says so between meshes.
    The surface moves only as finely as it is tessellated (a Subdivision modifier in
    Blender): each vertex is displaced, not each shading point."""
    from dataclasses import replace
    from .parallel import Cancelled
    from .scene import Mesh, Prototype, place
    if not any(moves_vertices(m) for m in materials.values()):
        return meshes
    stop = should_cancel if should_cancel is not None else (lambda: False)
    out = list(meshes)
    displaced = {}  # id(prototype) -> displaced Prototype

    def face_flags(mesh):
        """(moved, Displacement Only) (F,) bool per face of mesh."""
        names = _face_material_names(mesh)
        moved = np.array([moves_vertices(materials.get(n)) for n in names], bool)
        true = np.array([moves_vertices(materials.get(n)) and materials[n].displacement_method
                         == "DISPLACEMENT" for n in names], bool)
        return moved, true

    for i, mesh in enumerate(meshes):
        if not len(mesh.faces):
            continue
        if stop():
            raise Cancelled()
        P = mesh.prototype
        if P is None:
            moved, true = face_flags(mesh)
            if not moved.any():
                continue
            verts = np.asarray(mesh.vertices, np.float64) + _vertex_offsets(mesh, materials, moved)
            out[i] = replace(mesh, vertices=verts, normals=_recomputed_normals(
                verts, mesh.faces, mesh.normals, true, moved & ~true, mesh.vertices))
            continue
        if id(P) not in displaced:
            world = mesh.expanded()
            moved, true = face_flags(world)
            if not moved.any():
                displaced[id(P)] = P
                continue
            m3 = np.asarray(mesh.matrix, np.float64)[:3, :3]
            d_obj = _vertex_offsets(world, materials, moved) @ np.linalg.inv(m3).T
            pv = np.asarray(P.vertices, np.float64) + d_obj
            normals = _recomputed_normals(pv, P.faces, P.normals, true, moved & ~true,
                                          P.vertices)
            displaced[id(P)] = Prototype(P.name, pv, P.faces, normals=normals, uvs=P.uvs,
                                         material_ids=P.material_ids)
        Pd = displaced[id(P)]
        if Pd is P:
            continue
        if mesh.copyless:
            flags = {k: getattr(mesh, k) for k in _PLACEMENT_FLAGS}
            out[i] = Mesh.place(mesh.name, Pd, mesh.matrix, materials=list(mesh.materials),
                                **flags)
        else:
            verts, _ = place(Pd, mesh.matrix)
            moved, true = face_flags(mesh)
            out[i] = replace(mesh, vertices=verts, prototype=Pd, normals=_recomputed_normals(
                verts, mesh.faces, mesh.normals, true, moved & ~true, mesh.vertices))
    return out


# What a placement carries besides its prototype, matrix and materials (Mesh.expanded's).
_PLACEMENT_FLAGS = ("visible_camera", "visible_diffuse", "visible_glossy",
                    "visible_transmission", "visible_shadow", "holdout",
                    "shadow_terminator_offset", "shadow_terminator_shading_offset",
                    "cryptomatte_object", "cryptomatte_asset", "pass_index", "random",
                    "object_color", "location", "object_linear", "object_attributes")
