"""The tangent of anisotropic GGX lobes per hit (Cycles' default Tangent input).

A Principled BSDF's or Glossy BSDF's Tangent socket left unlinked is fed, in Cycles
(scene/shader_graph.cpp, LINK_TANGENT), by a Tangent node of direction Radial, axis Z:
svm_node_tangent takes the generated coordinate g (0..1 over the object's texture space),
T = (-(g.y - 0.5), g.x - 0.5, 0) in object space, carried to world space by the object's
normal transform, then T = cross(N, normalize(cross(T, N))) (T projected onto the shading
normal's plane). T is linear in g, and g in the barycentrics, so a per-corner T in world
space interpolated over a triangle is the same vector: the add-on exports it as the
corner attribute "radial_tangent" (addon/export.py). Without it (scene files, meshes
exported before) the tangent is radial about the world Z axis through the centre of the
object's bounding box, which is Cycles' for an object that is not rotated and whose texture
space is its bounding box (Blender's default auto texture space).

The projection, the rotation (Anisotropic Rotation) and the glossy-normal frame are
principled.set_tangents' (compiled); this module finds the world-space T.
"""
from __future__ import annotations

import numpy as np

from .closures import principled as pr

TANGENT_ATTRIBUTE = "radial_tangent"


def anisotropic_materials(params: np.ndarray) -> np.ndarray:
    """(M,) bool: material rows (M, N_MAT) whose metal or specular layer is anisotropic
    (principled.aniso_alphas gives alpha_x != alpha_y for some roughness)."""
    a = params[:, pr.M_ANISO]
    glossy = params[:, pr.M_NODE] == pr.NODE_GLOSSY
    on = np.where(glossy, np.abs(a) > 1e-4, a > 0.0)
    return on & ((params[:, pr.M_METALLIC] > 0.0) | (params[:, pr.M_SPEC] > 0.0))


def _object_centres(geo) -> np.ndarray:
    """(O,3) world-space centre of each object's bounding box (cached on the Geometry)."""
    c = getattr(geo, "_aniso_centres", None)
    if c is None:
        n_obj = max(len(geo.object_names), int(np.max(geo.object_id, initial=-1)) + 1)
        lo = np.full((n_obj, 3), np.inf)
        hi = np.full((n_obj, 3), -np.inf)
        oid = np.asarray(geo.object_id, np.int64)
        for corner in (np.asarray(geo.v0), np.asarray(geo.v0) + np.asarray(geo.e1),
                       np.asarray(geo.v0) + np.asarray(geo.e2)):
            np.minimum.at(lo, oid, corner)
            np.maximum.at(hi, oid, corner)
        c = np.where(np.isfinite(lo), 0.5 * (lo + hi), 0.0)
        geo._aniso_centres = c
    return c


def hit_tangents(geo, prim, u, v, p) -> np.ndarray:
    """(N,3) world-space tangent (not unit, not yet projected) at hits on triangles prim
    (N,) with barycentrics u, v (N,) and positions p (N,3): the exported radial tangent,
    else the radial tangent about world Z through the object's bounding-box centre."""
    prim = np.asarray(prim, np.int64)
    cc = (geo.corner_coordinates or {}).get(TANGENT_ATTRIBUTE)
    if cc is not None:
        t = geo.coordinates(TANGENT_ATTRIBUTE, prim, np.asarray(u, np.float64),
                            np.asarray(v, np.float64))
        if np.any(t != 0.0):
            missing = ~np.any(t != 0.0, axis=1)
            if not missing.any():
                return t
            t[missing] = hit_tangents_radial(geo, prim[missing], p[missing])
            return t
    return hit_tangents_radial(geo, prim, p)


def hit_tangents_radial(geo, prim, p) -> np.ndarray:
    """The fallback of hit_tangents: (-(y - cy), x - cx, 0) about the object's centre."""
    d = np.asarray(p, np.float64) - _object_centres(geo)[np.take(geo.object_id, prim)]
    return np.stack([-d[:, 1], d[:, 0], np.zeros(len(d))], axis=1)


def set_hit_tangents(geo, params, hit, prm, u=None, v=None) -> None:
    """Write the anisotropic lobes' tangents into prm (N, N_PACK) (set up by
    principled.setup with the glossy normal) for the SurfaceHit `hit` whose material
    rows are params (M, N_MAT), or (N, N_MAT) one per hit (hit.params). u, v: the hits'
    barycentrics (default hit.bary). Nothing when no hit's material is anisotropic (the
    isotropic lobes are left exactly as they were)."""
    n = len(hit.mat)
    if n == 0:
        return
    per_hit = params.shape[0] == n and getattr(hit, "params", None) is not None
    aniso = anisotropic_materials(params)
    on = aniso if per_hit else aniso[np.asarray(hit.mat, np.int64)]
    rows = np.flatnonzero(on)
    if len(rows) == 0:
        return
    if u is None and hit.bary is not None:
        u, v = hit.bary[:, 0], hit.bary[:, 1]
    prim = np.asarray(hit.prim, np.int64)[rows]
    tangent = np.zeros((n, 3))
    p = np.asarray(hit.p)[rows]
    if u is None:
        tangent[rows] = hit_tangents_radial(geo, prim, p)
    else:
        tangent[rows] = hit_tangents(geo, prim, np.asarray(u)[rows], np.asarray(v)[rows], p)
    rot = np.zeros(n)
    src = params[rows] if per_hit else params[np.asarray(hit.mat, np.int64)[rows]]
    rot[rows] = src[:, pr.M_AROT]
    pr.set_tangents(prm, rows.astype(np.int64), np.ascontiguousarray(hit.ns, np.float64),
                    tangent, rot)


_NO_TANGENTS = np.zeros((0, 3, 3))


def triangle_tangents(geo, params) -> np.ndarray:
    """(T,3,3) per-corner world tangents of the triangles whose material (rows params
    (M, N_MAT)) is anisotropic (zeros on the others), for the photon pass's scatter kernel
    (photonkernels._scatter interpolates them at the hit as hit_tangents does); (0,3,3)
    when no material is anisotropic or the Geometry has shared instances (their rows are
    not the scene's own: their photons then scatter off an isotropic lobe). Cached on the
    Geometry per material table."""
    aniso = anisotropic_materials(params)
    if not aniso.any() or geo.shared is not None:
        return _NO_TANGENTS
    cached = getattr(geo, "_aniso_tangents", None)
    if cached is not None and cached[0] is params:
        return cached[1]
    tri = np.flatnonzero(aniso[np.asarray(geo.material, np.int64)])
    out = np.zeros((geo.count, 3, 3))
    cc = (geo.corner_coordinates or {}).get(TANGENT_ATTRIBUTE)
    v0 = np.asarray(geo.v0, np.float64)[tri]
    corners = (v0, v0 + np.asarray(geo.e1, np.float64)[tri],
               v0 + np.asarray(geo.e2, np.float64)[tri])
    for k in range(3):
        out[tri, k] = hit_tangents_radial(geo, tri, corners[k])
    if cc is not None:
        ex = np.asarray(cc, np.float64)[tri]
        has = np.any(ex.reshape(len(tri), -1) != 0.0, axis=1)
        out[tri[has]] = ex[has]
    try:
        geo._aniso_tangents = (params, out)
    except AttributeError:
        pass
    return out
