"""Cycles' Bump node: the shading normal tilted against a height's gradient along the
surface, the height sampled over the ray's footprint as Cycles samples it.

A `Bump` takes a height h (any engine.textures / engine.shadernodes node; colours read as
their luminance) and tilts the normal N:
  n' = normalize(N - distance grad h),   n'' = normalize(s n' + (1 - s) N)
with grad h Cycles' one-sided differences of h over filter_width x the ray's footprint
(svm_node_set_bump), the footprint Cycles' compact ray differential: a camera pixel's
angle times the distance its path travelled (transfer_footprint; `ViewFootprint` where
no camera path reaches the hit). The differences are taken
in the triangle's barycentric coordinates, mapped to the surface through the dual basis
of the triangle's edges, so any height node works. engine/normalmap.py holds the Normal
Map node and the bump shadowing term, which applies to both.
"""
from __future__ import annotations

import numpy as np

from .normalmap import NormalMapError
from .sampling import dot, normalize


# The footprint of hits no camera path is followed to (photons, Bevel's probes, a
# subsurface walk's exits), as a multiple of the camera's differential times the hit's
# distance from it (ViewFootprint.deeper). The gather rays' ends take their path's own
# (transfer_footprint). A photon's hit stands for Cycles' vertices at and past the one
# that reads it (a gather ray's end, dD x (camera distance + gather length): in
# roomglossy49's box 4.0 x its camera distance at the median, 1.2 / 29 at the 10th /
# 90th percentile) and its bounce for the one past that, longer still; which reader, and
# so which footprint, is not known when the photon is traced. Measured (docs/accuracy.md
# "### footprint51"): the box's bumped / unbumped 0.9924 / 0.9984 / 0.9999 at 2 / 6 / 0
# (unbent) against Cycles' 0.9980.
DEEPER = 6.0


class Bump:
    """height    an object with evaluate(geo, prim, u, v) -> (N,) or (N,3)
    strength     0..1 blend towards the bumped normal (Cycles' Strength)
    distance     height scale in scene units (Cycles' Distance), negated by invert
    filter_width the Bump node's Filter Width (Blender 4.5+, default 0.1): the height's
                 differences are taken that fraction of the ray's footprint away

    The height is sampled as Cycles' svm_node_set_bump samples it (Blender 5.0,
    kernel/svm/displace.h): at the hit and at P + filter_width dP/dx, P + filter_width
    dP/dy, dP/dx, dP/dy the ray's compact differential (a radius r, the footprint) along
    two orthonormal tangents of the geometric normal (differential_from_compact). A
    one-sided difference over a step of filter_width x footprint, not the height's
    derivative: where the height is steeper than that step resolves (a Brick Texture's
    grout, a 1 mm ramp of height 1) the normal tilts over the step's width with the
    step's slope, which is what Cycles shades (docs/accuracy.md, "### bump50").
    Where no footprint is known (no view_footprint on the geometry, no footprint
    passed) the gradient is the height's derivative by central differences at a
    barycentric step STEP."""

    STEP = 1e-4  # barycentric step of the central differences without a footprint

    def __init__(self, height, strength: float = 1.0, distance: float = 1.0,
                 invert: bool = False, filter_width: float = 0.1):
        if height is None or not hasattr(height, "evaluate"):
            raise NormalMapError("bump: height must be an engine texture or shader node, got "
                                 f"{type(height).__name__}")
        vals = [float(strength), float(distance), float(filter_width)]
        if not np.all(np.isfinite(vals)):
            raise NormalMapError("bump strength / distance / filter width: must be finite, "
                                 f"got {vals}")
        self.height = height
        self.strength = min(max(vals[0], 0.0), 1.0)
        self.distance = -vals[1] if invert else vals[1]
        self.filter_width = vals[2]

    def _h(self, geo, prim, u, v):
        h = np.asarray(self.height.evaluate(geo, prim, u, v), np.float64)
        return h @ np.array([0.2126, 0.7152, 0.0722]) if h.ndim == 2 else h

    def perturb(self, geo, prim, u, v, n: np.ndarray, footprint=None) -> np.ndarray:
        """(N,3) unit shading normals at hits; n (N,3) the unperturbed ones (winding side).
        footprint (N,) m: each hit's ray footprint (Cycles' compact sd->dP); None: the
        geometry's view_footprint (engine/normalmap.ViewFootprint) where it has one, else
        the derivative at STEP.
        Seen from a back face the bumped normal is turned over with the rest
        (engine.bsdf.surface_hit), which is what Cycles renders: the bands of a bumped
        plane seen from below under a sun from below read as Cycles' (column profiles
        correlate 0.99; a tilt mirrored instead would read -0.99:
        tests/blender/test_bump_back_face_cycles.py)."""
        e1 = np.take(geo.e1, prim, axis=0)
        e2 = np.take(geo.e2, prim, axis=0)
        ng = np.take(geo.ng, prim, axis=0)
        # Dual basis of (e1, e2) in the triangle's plane: g1.e1 = 1, g1.e2 = 0, ...
        c2 = np.cross(e2, ng)
        c1 = np.cross(ng, e1)
        g1 = c2 / dot(e1, c2)[:, None]
        g2 = c1 / dot(e2, c1)[:, None]
        if footprint is None:
            view = getattr(geo, "view_footprint", None)
            if view is not None:
                footprint = view.at(np.take(geo.v0, prim, axis=0) + u[:, None] * e1
                                    + v[:, None] * e2)
        if footprint is None:
            bumped = self._derivative(geo, prim, u, v, n, g1, g2)
        else:
            bumped = self._differences(geo, prim, u, v, n, ng, g1, g2,
                                       np.broadcast_to(np.asarray(footprint, np.float64),
                                                       (len(prim),)))
        out = normalize(self.strength * bumped + (1.0 - self.strength) * n)
        bad = ~np.isfinite(out).all(axis=1) | (np.linalg.norm(out, axis=1) < 0.5)
        out[bad] = n[bad]
        return out

    def _derivative(self, geo, prim, u, v, n, g1, g2):
        """normalize(n - distance grad h): the height's surface gradient by central
        differences at the barycentric STEP (no footprint known)."""
        e = self.STEP
        dh_du = (self._h(geo, prim, u + e, v) - self._h(geo, prim, u - e, v)) / (2 * e)
        dh_dv = (self._h(geo, prim, u, v + e) - self._h(geo, prim, u, v - e)) / (2 * e)
        grad = dh_du[:, None] * g1 + dh_dv[:, None] * g2
        return normalize(n - self.distance * grad)

    def _differences(self, geo, prim, u, v, n, ng, g1, g2, r):
        """Cycles' svm_node_set_bump with dP/dx, dP/dy = r a, r b (a, b: make_orthonormals
        of the geometric normal): the height at P + filter_width dP/dx and P +
        filter_width dP/dy (barycentrics extrapolated on the hit's triangle, as Cycles'
        differentials extrapolate its UVs), and
          n' = normalize(fw |det| n - distance sign(det) ((h_x - h_c) R_x + (h_y - h_c) R_y))
        with R_x = dP/dy x n, R_y = n x dP/dx, det = dP/dx . R_x. A zero footprint or
        filter width leaves n (Cycles' zero normal falls back to its input)."""
        a, b = make_orthonormals(ng)
        dpx = r[:, None] * a
        dpy = r[:, None] * b
        fw = self.filter_width
        h_c = self._h(geo, prim, u, v)
        h_x = self._h(geo, prim, u + fw * dot(g1, dpx), v + fw * dot(g2, dpx))
        h_y = self._h(geo, prim, u + fw * dot(g1, dpy), v + fw * dot(g2, dpy))
        rx = np.cross(dpy, n)
        ry = np.cross(n, dpx)
        det = dot(dpx, rx)
        surfgrad = (h_x - h_c)[:, None] * rx + (h_y - h_c)[:, None] * ry
        m = (fw * np.abs(det))[:, None] * n - (self.distance * np.sign(det))[:, None] * surfgrad
        ln = np.linalg.norm(m, axis=1)
        return np.where((ln > 0)[:, None], m / np.maximum(ln, 1e-300)[:, None], n)


def make_orthonormals(nv: np.ndarray):
    """(a, b) (N,3): Cycles' make_orthonormals (util/math_float3.h) of unit normals nv
    (N,3): a = normalize((1,1,1) x N) (or (-1,1,1) x N where N's components are equal),
    b = N x a - the frame differential_from_compact lays a compact differential along."""
    x, y, z = nv[:, 0], nv[:, 1], nv[:, 2]
    same = (x == y) & (x == z)
    a = np.where(same[:, None], np.column_stack([z - y, x + z, -y - x]),
                 np.column_stack([z - y, x - z, y - x]))
    a = normalize(a)
    return a, np.cross(nv, a)


def camera_differential(camera, width: int, height: int, d: np.ndarray) -> np.ndarray:
    """(N,) Cycles' compact ray differential of camera rays of unit world directions d
    (N,3), for an engine.scene.Camera rendering width x height: a perspective camera's
    dD = (|dD/dx| + |dD/dy|) / 2 (kernel/camera/camera.h, differential_make_compact),
    |dD/dx| = pixel cos(theta) sqrt(1 - (d.x)^2) to first order (pixel: one pixel's width
    on the image plane at distance 1, theta the angle off the view axis, x the camera's
    right axis; y likewise); a panorama's its pixel angle; an orthographic camera's dP,
    its pixel's width (its dD is 0)."""
    hw, _ = camera.half_extents(width, height)
    pixel = 2.0 * hw / width
    n = len(d)
    if camera.kind != "PERSP":
        return np.full(n, pixel)
    rot = np.asarray(camera.rotation, np.float64)
    cos_t = np.abs(d @ rot[:, 2])
    sx = np.sqrt(np.maximum(1.0 - (d @ rot[:, 0]) ** 2, 0.0))
    sy = np.sqrt(np.maximum(1.0 - (d @ rot[:, 1]) ** 2, 0.0))
    return pixel * cos_t * 0.5 * (sx + sy)


class ViewFootprint:
    """Cycles' ray footprint (the compact differential sd->dP, m) at points the camera's
    rays reach, for hits whose path is not followed from the camera (photons, nodes' own
    rays; the gather rays' ends take their path's, transfer_footprint): the camera
    differential towards the point
    (camera_differential) times its distance from the camera times `deeper` (>= 1; an
    orthographic camera: its pixel's width). Cycles (5.0) carries a camera path's dD
    through every bounce unchanged, so a deeper vertex's footprint is dD times the whole
    path's length (docs/accuracy.md, "### bump50").
    camera: engine.scene.Camera; offset (3,) the geometry's re-centring (Geometry.offset:
    points are world minus offset); width, height: the image's pixels."""

    def __init__(self, camera, offset, width: int, height: int, deeper: float = 1.0):
        self.camera = camera
        self.position = (np.asarray(camera.position, np.float64).reshape(3)
                         - np.asarray(offset, np.float64).reshape(3))
        self.width, self.height = int(width), int(height)
        self.deeper = float(deeper)

    def at(self, p: np.ndarray) -> np.ndarray:
        """(N,) footprints (m) at re-centred points p (N,3)."""
        v = p - self.position
        dist = np.linalg.norm(v, axis=1)
        d = v / np.maximum(dist, 1e-300)[:, None]
        dd = camera_differential(self.camera, self.width, self.height, d)
        if self.camera.kind == "ORTHO":
            return dd
        return dd * dist * self.deeper


def transfer_footprint(footprint, spread, t) -> np.ndarray:
    """(N,) m the ray footprint at the ends of rays of length t (N,) m that leave points
    of footprint (N,) m with compact ray dD spread (N,) rad: Cycles'
    differential_transfer_compact (kernel/util/differential.h), dP + t dD. A bounce
    leaves both as they are (Blender 4.2-5.1, kernel/integrator/shade_surface.h: the
    new ray's dP is the hit's sd->dP, its dD the path's, diffuse or glossy alike), so a
    gather ray's end from a camera hit has dD x (camera distance + gather length); an
    orthographic camera's dD is 0 and every vertex keeps its pixel's width."""
    return (np.asarray(footprint, np.float64)
            + np.asarray(t, np.float64) * np.asarray(spread, np.float64))


def attach_view(geo, scene, deeper: float = DEEPER) -> None:
    """Give Geometry geo the ViewFootprint of scene's camera (None without one): what
    Bump.perturb reads where no footprint is passed."""
    cam = getattr(scene, "camera", None)
    geo.view_footprint = (None if cam is None else
                          ViewFootprint(cam, geo.offset, scene.width, scene.height, deeper))
