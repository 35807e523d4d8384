"""Cycles' Vector pass: motion vectors in pixels per frame (View Layer > Passes > Vector).

Cycles 5.0 makes it only with motion blur off (blender/sync.cpp: the pass and motion
blur exclude each other; scene/object.cpp exports each object's transform, and the
camera's, one frame before and after). At the first surface the camera ray meets where
the data passes' "single pass" is done (film_write_data_passes: the UV pass' surface,
the Alpha Threshold's) it writes (kernel/geom/primitive.h primitive_motion_vector)

    pre  = raster(P_prev, camera_prev) - raster(P, camera)
    post = raster(P, camera) - raster(P_next, camera_next)
    Vector = (pre.x, pre.y, post.x, post.y)

P the hit, P_prev / P_next the same point of the object one frame before / after,
raster(.) the image position in pixels of the full frame, x right, y up (Cycles'
worldtoraster: ndc x the frame's width and height, from its lower left corner; a
panorama's image coordinates likewise). Both vectors point the way the image moved
*from*: a surface moving right by 2 pixels a frame reads (-2, 0, -2, 0). The film
divides by the samples that wrote (film_get_pass_pixel_motion: the motion weight), so
the background reads 0 and a pixel half covered the covered half's motion.

Here: each mesh moves with its object's transform (Mesh.location and object_linear at
the three frames, matched by name): P_prev = A_prev A^-1 P. A mesh whose vertices move
within the object (an armature, shape keys, a modifier: Cycles' deformation motion,
its motion vertex attributes interpolated by the barycentrics) carries its vertices'
world displacements to the two frames (SceneMotion.deform): P_prev = P + sum_k w_k
(V_prev,k - V_k) over the hit triangle's corners, w its barycentric weights. (Traced
two-level, instanced rows take their object's transform.) A mesh whose vertex count
changes between frames has its object's motion only: the add-on warns
(addon/motionvectors.py). Each write adds (x, y, 1) into two Accumulator.data sums
(KEYS), the third channel the motion weight; shown() divides.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Accumulator.data keys: sums of (pre.x, pre.y, 1) and (post.x, post.y, 1).
KEYS = ("vector_pre", "vector_post")


@dataclass
class SceneMotion:
    """The motion the Vector pass reads (Scene.vector_motion). prev_camera /
    next_camera: scene.Camera one frame before / after (None: the frame's camera);
    objects: {mesh name: ((3,4) prev, (3,4) next)} affine maps taking a world point of
    the mesh at the frame to the same point one frame before / after (identity for a
    mesh not listed); deform: {mesh name: ((V,3) prev, (V,3) next)} world displacements
    of a deforming mesh's vertices (Mesh.vertices' order) to the frame before / after,
    used instead of its object's map."""

    prev_camera: object = None
    next_camera: object = None
    objects: dict = field(default_factory=dict)
    deform: dict = field(default_factory=dict)

    @staticmethod
    def object_map(linear, location, linear_other, location_other) -> np.ndarray:
        """(3,4) the affine map world -> world taking a point of an object whose
        object-to-world matrix is (linear (3,3), location (3,)) to where the object at
        (linear_other, location_other) puts it: A_other A^-1. A singular matrix (a
        scale 0) maps nothing: the identity."""
        a = np.asarray(linear if linear is not None else np.eye(3), np.float64)
        b = np.asarray(linear_other if linear_other is not None else np.eye(3), np.float64)
        out = np.zeros((3, 4))
        try:
            m = b @ np.linalg.inv(a)
        except np.linalg.LinAlgError:
            out[:, :3] = np.eye(3)
            return out
        if not np.all(np.isfinite(m)):
            out[:, :3] = np.eye(3)
            return out
        out[:, :3] = m
        out[:, 3] = np.asarray(location_other, np.float64) - m @ np.asarray(location,
                                                                            np.float64)
        return out


class VectorMotion:
    """SceneMotion resolved for one render's Geometry: per object row (the Geometry's
    object_names), the maps to the previous and next frame, and the three cameras'
    views (shadernodes.CameraView) of the full frame."""

    def __init__(self, scene, geo):
        from .shadernodes import CameraView
        sm = scene.vector_motion or SceneMotion()
        w, h = int(scene.width), int(scene.height)
        self.size = np.array([w, h], np.float64)
        cam = scene.camera
        self.view = CameraView(cam, w, h) if cam is not None else None
        self.prev = CameraView(sm.prev_camera or cam, w, h) if cam is not None else None
        self.next = CameraView(sm.next_camera or cam, w, h) if cam is not None else None
        names = list(geo.object_names)
        ident = np.zeros((3, 4))
        ident[:, :3] = np.eye(3)
        self.maps = np.tile(ident, (max(len(names), 1), 2, 1, 1))  # (O,2,3,4)
        for i, name in enumerate(names):
            pair = sm.objects.get(name)
            if pair is not None:
                self.maps[i, 0], self.maps[i, 1] = pair
        # Deforming meshes (row-wise triangles, not two-level): object row -> (faces,
        # prev, next displacements) and the object's first triangle row.
        self.deform = {}
        if sm.deform and getattr(geo, "shared", None) is None and geo.count:
            faces = {m.name: m.faces for m in scene.meshes if m.vertices is not None}
            oid = np.asarray(geo.object_id)
            rows, first = np.unique(oid, return_index=True)
            start = dict(zip(rows.tolist(), first.tolist()))
            for i, name in enumerate(names):
                moved = sm.deform.get(name)
                f = faces.get(name)
                if moved is None or f is None or i not in start:
                    continue
                dprev, dnext = (np.asarray(x, np.float64) for x in moved)
                if len(dprev) > int(np.max(f, initial=-1)):
                    self.deform[i] = (start[i], np.asarray(f, np.int64), dprev, dnext)

    def _raster(self, view, p):
        return view.to_ndc(p)[:, :2] * self.size

    def vectors(self, p, obj, prim=None, u=None, v=None):
        """(pre (K,3), post (K,3)): (x, y, 1) of the motion vectors (module docstring) at
        world points p (K,3) of object rows obj (K,), on triangles prim (K,) at
        barycentrics u, v (K,) (for the deforming meshes; None: objects' maps only)."""
        k = len(p)
        pre = np.zeros((k, 3))
        post = np.zeros((k, 3))
        pre[:, 2] = post[:, 2] = 1.0
        if self.view is None or k == 0:
            return pre, post
        m = self.maps[np.asarray(obj, np.int64)]
        p = np.asarray(p, np.float64)
        p_prev = np.einsum("kij,kj->ki", m[:, 0, :, :3], p) + m[:, 0, :, 3]
        p_next = np.einsum("kij,kj->ki", m[:, 1, :, :3], p) + m[:, 1, :, 3]
        if self.deform and prim is not None:
            obj = np.asarray(obj, np.int64)
            for i, (start, faces, dprev, dnext) in self.deform.items():
                rows = np.flatnonzero(obj == i)
                if not len(rows):
                    continue
                local = np.asarray(prim, np.int64)[rows] - start
                ok = (local >= 0) & (local < len(faces))
                rows, corners = rows[ok], faces[local[ok]]
                uu = np.asarray(u, np.float64)[rows][:, None]
                vv = np.asarray(v, np.float64)[rows][:, None]
                w0 = 1.0 - uu - vv
                for d, out in ((dprev, p_prev), (dnext, p_next)):
                    out[rows] = p[rows] + (w0 * d[corners[:, 0]] + uu * d[corners[:, 1]]
                                           + vv * d[corners[:, 2]])
        center = self._raster(self.view, p)
        with np.errstate(invalid="ignore", divide="ignore"):
            pre[:, :2] = self._raster(self.prev, p_prev) - center
            post[:, :2] = center - self._raster(self.next, p_next)
        pre[:, :2] = np.nan_to_num(pre[:, :2], nan=0.0, posinf=0.0, neginf=0.0)
        post[:, :2] = np.nan_to_num(post[:, :2], nan=0.0, posinf=0.0, neginf=0.0)
        return pre, post


def for_context(ctx) -> VectorMotion:
    """The render's VectorMotion (made once per context)."""
    vm = getattr(ctx, "_vector_motion", None)
    if vm is None:
        vm = VectorMotion(ctx.scene, ctx.geo)
        try:
            ctx._vector_motion = vm
        except AttributeError:  # (a context that takes no attributes: made per call)
            pass
    return vm


def shown(data) -> np.ndarray | None:
    """(H,W,4) the Vector pass as Blender shows it from Film.data (per-sample averages
    of the KEYS sums): each vector divided by its motion weight, 0 where no sample
    wrote; None when the film has no Vector pass."""
    if KEYS[0] not in data:
        return None
    pre, post = np.asarray(data[KEYS[0]], np.float64), np.asarray(data[KEYS[1]], np.float64)
    wt = pre[..., 2:3]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.concatenate([pre[..., :2], post[..., :2]], axis=-1) / wt
    return np.where(wt > 0.0, out, 0.0).astype(np.float32)
