"""Shading-normal perturbation from textures: Cycles' Normal Map node.

A `NormalMap` turns a texture's colour c (read as stored, normally Non-Color) into a
direction 2c - 1 and that into the shading normal:
  TANGENT  n' = normalize(x T + y B + z N): N the interpolated shading normal, T the
           UV tangent dP/du made orthogonal to N, B = sign cross(N, T) with sign the
           orientation of the triangle's UV map (Blender's MikkTSpace convention);
  WORLD    n' = normalize(2c - 1) (world-space directions).
Strength s != 1 blends: n'' = normalize(N + s (n' - N)) (Cycles svm_node_normal_map).
Tangents are per triangle from its UVs (exact on flat, affinely mapped faces; MikkTSpace
smooths them across shared vertices, a difference on curved low-poly meshes).
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
            b = sign[:, None] * np.cross(n, t)
            mapped = np.where(ok[:, None], c[:, 0:1] * t + c[:, 1:2] * b + c[:, 2:3] * n, n)
        out = normalize(mapped)
        if self.strength != 1.0:
            out = normalize(n + (out - n) * self.strength)
        bad = ~np.isfinite(out).all(axis=1) | (np.linalg.norm(out, axis=1) < 0.5)
        out[bad] = n[bad]
        return out
