"""Shading-normal perturbation from textures: Cycles' Normal Map and Bump nodes.

A `NormalMap` turns a texture's colour c (read as stored, normally Non-Color) into a
direction 2c - 1 and that into the shading normal:
  TANGENT  n' = normalize(x T + y B + z N): N the interpolated shading normal, T the
           UV tangent dP/du made orthogonal to N, B = sign cross(N, T) with sign the
           orientation of the triangle's UV map (Blender's MikkTSpace convention);
  WORLD    n' = normalize(2c - 1) (world-space directions).
Strength s != 1 blends: n'' = normalize(N + s (n' - N)) (Cycles svm_node_normal_map).
A `Bump` takes a height h (any engine.textures / engine.shadernodes node; colours read as
their luminance) and tilts the normal against h's gradient along the surface:
  n' = normalize(N - distance grad_s h),   n'' = normalize(s n' + (1 - s) N)
(Cycles svm_node_set_bump: its screen-space differences dH/dx, dH/dy over the dual basis
of dP/dx, dP/dy are, for small filter widths, this surface gradient). The gradient is taken
by central differences of h in the triangle's barycentric coordinates, mapped to the
surface through the dual basis of the triangle's edges, so any height node works.
Tangents are Blender's MikkTSpace tangents where the mesh carries them (the add-on exports
them per corner as the coordinates 'tangent' / 'tangent_sign' for meshes whose materials
use a tangent-space map), else per triangle from its UVs (exact on flat, affinely mapped
faces; MikkTSpace smooths them across shared vertices, a difference on curved low-poly
meshes).
"""
from __future__ import annotations

import numpy as np

from .sampling import dot, normalize

SPACES = ("TANGENT", "WORLD")


class NormalMapError(ValueError):
    """Bad normal-map input (names the argument)."""


class NormalMap:
    """texture  an object with evaluate(geo, prim, u, v) -> (N,3) (engine.textures)
    strength    >= 0 (Cycles' Strength input)
    space       TANGENT or WORLD"""

    def __init__(self, texture, strength: float = 1.0, space: str = "TANGENT"):
        if texture is None or not hasattr(texture, "evaluate"):
            raise NormalMapError("normal map: texture must be an engine.textures object, "
                                 f"got {type(texture).__name__}")
        strength = float(strength)
        if not np.isfinite(strength):
            raise NormalMapError(f"normal map strength: must be finite, got {strength}")
        space = str(space).upper()
        if space not in SPACES:
            raise NormalMapError(f"normal map space: expected one of {SPACES}, got {space!r}")
        self.texture = texture
        self.strength = max(strength, 0.0)
        self.space = space

    def perturb(self, geo, prim, u, v, n: np.ndarray) -> np.ndarray:
        """(N,3) unit shading normals at hits (triangle prim, barycentrics u, v), from the
        unperturbed unit shading normals n (N,3), both on the winding-order side."""
        c = 2.0 * self.texture.evaluate(geo, prim, u, v) - 1.0
        if self.space == "WORLD":
            mapped = c
        else:
            t, sign = geo.uv_tangents(prim)
            t = t - n * dot(n, t)[:, None]
            tl = np.linalg.norm(t, axis=1)
            ok = tl > 1e-12  # no usable UVs: keep the normal (Cycles reads a zero tangent)
            t = t / np.maximum(tl, 1e-300)[:, None]
            mikk = (geo.corner_coordinates or {}).get("tangent") is not None
            if mikk:
                # Blender's MikkTSpace tangents (exported per corner), interpolated and
                # used as Cycles' svm_node_normal_map does: not re-orthogonalised.
                tm = geo.coordinates("tangent", prim, u, v)
                sm = geo.coordinates("tangent_sign", prim, u, v)[:, 0]
                has = np.linalg.norm(tm, axis=1) > 1e-12  # meshes without them: per triangle
                t = np.where(has[:, None], tm, t)
                sign = np.where(has, np.where(sm < 0, -1.0, 1.0), sign)
                ok = ok | has
            b = sign[:, None] * np.cross(n, t)
            mapped = np.where(ok[:, None], c[:, 0:1] * t + c[:, 1:2] * b + c[:, 2:3] * n, n)
        out = normalize(mapped)
        if self.strength != 1.0:
            out = normalize(n + (out - n) * self.strength)
        bad = ~np.isfinite(out).all(axis=1) | (np.linalg.norm(out, axis=1) < 0.5)
        out[bad] = n[bad]
        return out


class Bump:
    """height    an object with evaluate(geo, prim, u, v) -> (N,) or (N,3)
    strength     0..1 blend towards the bumped normal (Cycles' Strength)
    distance     height scale in scene units (Cycles' Distance), negated by invert"""

    STEP = 1e-4  # barycentric step of the central differences (relative to the triangle)

    def __init__(self, height, strength: float = 1.0, distance: float = 1.0,
                 invert: bool = False):
        if height is None or not hasattr(height, "evaluate"):
            raise NormalMapError("bump: height must be an engine texture or shader node, got "
                                 f"{type(height).__name__}")
        vals = [float(strength), float(distance)]
        if not np.all(np.isfinite(vals)):
            raise NormalMapError(f"bump strength / distance: must be finite, got {vals}")
        self.height = height
        self.strength = min(max(vals[0], 0.0), 1.0)
        self.distance = -vals[1] if invert else vals[1]

    def _h(self, geo, prim, u, v):
        h = np.asarray(self.height.evaluate(geo, prim, u, v), np.float64)
        return h @ np.array([0.2126, 0.7152, 0.0722]) if h.ndim == 2 else h

    def perturb(self, geo, prim, u, v, n: np.ndarray) -> np.ndarray:
        """(N,3) unit shading normals at hits; n (N,3) the unperturbed ones (winding side)."""
        e = self.STEP
        dh_du = (self._h(geo, prim, u + e, v) - self._h(geo, prim, u - e, v)) / (2 * e)
        dh_dv = (self._h(geo, prim, u, v + e) - self._h(geo, prim, u, v - e)) / (2 * e)
        e1 = np.take(geo.e1, prim, axis=0)
        e2 = np.take(geo.e2, prim, axis=0)
        ng = np.take(geo.ng, prim, axis=0)
        # Dual basis of (e1, e2) in the triangle's plane: g1.e1 = 1, g1.e2 = 0, ...
        c2 = np.cross(e2, ng)
        c1 = np.cross(ng, e1)
        g1 = c2 / dot(e1, c2)[:, None]
        g2 = c1 / dot(e2, c1)[:, None]
        grad = dh_du[:, None] * g1 + dh_dv[:, None] * g2
        bumped = normalize(n - self.distance * grad)
        out = normalize(self.strength * bumped + (1.0 - self.strength) * n)
        bad = ~np.isfinite(out).all(axis=1) | (np.linalg.norm(out, axis=1) < 0.5)
        out[bad] = n[bad]
        return out
