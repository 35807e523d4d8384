"""Shading-normal perturbation from textures: Cycles' Normal Map node, and the
bump shadowing term Cycles applies to closures whose normal they bent.

A `NormalMap` turns a texture's colour c (read as stored, normally Non-Color) into a
direction 2c - 1 and that into the shading normal:
  TANGENT  n' = normalize(x T + y B + z N) (Cycles svm_node_normal_map): N the smooth
           normal and T Blender's MikkTSpace tangent, both interpolated and not
           normalised, B = sign cross(N, T) with sign the UV map's orientation (the
           render UV map's, or the one the node names: NormalMap.uv_map); without
           exported tangents T is the triangle's UV tangent dP/du made orthogonal to N
           (render map only).
           Strength s scales x and y and blends z from 1: (s x, s y, 1 + (z - 1) min(s, 1));
  WORLD    n' = normalize(2c - 1) (world-space directions); strength s != 1 blends the
           normals: n'' = normalize(N + s (n' - N)).
The Bump node is engine/bump.py's `Bump` (its perturb has the same signature).
`bump_shadowing_term` is Cycles 5.0's factor on such closures (docs/textures.md, "Bump
shadowing"): engine/directlight.py applies it per light sample, engine/integrator.py to
gather rays and engine/photons.py to the photons' diffuse storage and bounce.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up
from .sampling import dot, normalize

SPACES = ("TANGENT", "WORLD")


@kernel
def bump_shadowing_term(m0, m1, m2, n0, n1, n2, i0, i1, i2, diffuse):
    """Cycles' bump shadowing term for one closure and one light direction: the factor
    (0..1) on the BSDF value of a closure whose normal n was bent by a Normal Map / Bump
    node away from the smooth (interpolated, pre-bump) normal m, for the unit direction
    i towards the light. Blender 5.0, intern/cycles/kernel/closure/bsdf.h,
    bump_shadowing_term() with is_eval (light samples; the diffuse lobe's own sampled
    directions take the same value):
      0 where i and n lie on different sides of the smooth surface (light leaking to the
        rear of opaque geometry), for every closure;
      for diffuse closures, the GGX shadowing G1 (Heitz 2014, eq. 72) of the smooth normal
        with alpha^2 = clamp(tan^2(theta_d) / 8, 0, 1), theta_d the angle between m and n
        (Conty Estevez, Lecocq and Stein 2019, "A Microfacet-Based Shadowing Function to
        Solve the Bump Terminator Problem", Ray Tracing Gems ch. 12).
    1 where n equals m (no bump)."""
    if m0 == n0 and m1 == n1 and m2 == n2:
        return 1.0
    cos_mi = m0 * i0 + m1 * i1 + m2 * i2
    cos_mn = m0 * n0 + m1 * n1 + m2 * n2
    cos_ni = n0 * i0 + n1 * i1 + n2 * i2
    if cos_mi * cos_mn * cos_ni < 0.0:
        return 0.0
    if not diffuse:
        return 1.0
    return _diffuse_bump_shadowing(cos_mi, cos_mn)


@kernel
def bump_shadowing_terms(m0, m1, m2, n0, n1, n2, i0, i1, i2):
    """(bump_shadowing_term(..., False), bump_shadowing_term(..., True)) from one
    evaluation: the side test every closure takes and the diffuse closures' factor, for
    a light sample that weighs both (engine/directlight.py)."""
    if m0 == n0 and m1 == n1 and m2 == n2:
        return 1.0, 1.0
    cos_mi = m0 * i0 + m1 * i1 + m2 * i2
    cos_mn = m0 * n0 + m1 * n1 + m2 * n2
    cos_ni = n0 * i0 + n1 * i1 + n2 * i2
    if cos_mi * cos_mn * cos_ni < 0.0:
        return 0.0, 0.0
    return 1.0, _diffuse_bump_shadowing(cos_mi, cos_mn)


@kernel
def _diffuse_bump_shadowing(cos_mi, cos_mn):
    """bump_shadowing_term's diffuse factor past the side test: G1 of the smooth normal
    (cos_mi: with the light direction, cos_mn: with the bent normal)."""
    cos_i = abs(cos_mi)
    cos_d = abs(cos_mn)
    if cos_d >= 1.0 or cos_i >= 1.0:
        return 1.0
    if cos_i < 1e-6:
        return 0.0
    # tan^2(theta_d) / 8 reaches the clamp at cos^2 = 1/9: there (a normal bent 90
    # degrees, as a Bevel at an axis-aligned cube's edge gives) 1, without dividing by 0.
    if cos_d * cos_d <= 1.0 / 9.0:
        alpha2 = 1.0
    else:
        alpha2 = min(max(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0), 1.0)
    lam = 0.5 * (math.sqrt(1.0 + alpha2 * max(1.0 / (cos_i * cos_i) - 1.0, 0.0)) - 1.0)
    return 1.0 / (1.0 + lam)


@kernel
def _bump_shadowing_rows(m, n, wi, diffuse, out):
    for k in range(m.shape[0]):
        out[k] = bump_shadowing_term(m[k, 0], m[k, 1], m[k, 2], n[k, 0], n[k, 1], n[k, 2],
                                     wi[k, 0], wi[k, 1], wi[k, 2], diffuse)


def bump_shadowing(n_smooth, ns, wi, diffuse: bool = True) -> np.ndarray:
    """(N,) bump_shadowing_term row by row: n_smooth (N,3) the hits' smooth normals before
    Normal Map / Bump nodes, ns (N,3) their shading normals, wi (N,3) unit directions
    towards the light (a photon's reversed direction, a gather ray's direction)."""
    def c(a):  # C-contiguous, writable float64: the one type _bump_shadowing_rows is warmed for
        return np.require(a, np.float64, ["C", "W"])
    out = np.empty(len(ns))
    _bump_shadowing_rows(c(n_smooth), c(ns), c(wi), bool(diffuse), out)
    return out


@register_warm_up
def _warm_up():
    # Normal-mapped scenes call this from photons.py and integrator.py (not from a kernel).
    z = np.array([[0.0, 0.0, 1.0]])
    bump_shadowing(z, z, z, True)


class NormalMapError(ValueError):
    """Bad normal-map input (names the argument)."""


class _ConstantColour:
    """A Normal Map's colour that is the same at every hit (an RGB node, a socket value)."""

    def __init__(self, colour):
        self.colour = np.array(colour, np.float64)

    def evaluate(self, geo, prim, u, v):
        return np.broadcast_to(self.colour, (len(prim), 3))


class NormalMap:
    """texture  an object with evaluate(geo, prim, u, v) -> (N,3) colours or (N,) values
                (engine.textures, engine.shadernodes: an image or a procedural tree; a
                value reads as grey), or a constant colour (3,)
    strength    >= 0 (Cycles' Strength input)
    space       TANGENT or WORLD
    uv_map      TANGENT only: "" the render UV map's tangents ('tangent', 'tangent_sign'
                corner coordinates, else per triangle from the UVs); a name: that UV map's
                MikkTSpace tangents, the corner coordinates 'tangent:NAME' and
                'tangent_sign:NAME' (Cycles' attributes NAME.tangent / NAME.tangent_sign,
                NormalMapNode::attributes); where a mesh lacks them the normal stays
                unperturbed, as svm_node_normal_map falls back when the attribute is
                not found."""

    def __init__(self, texture, strength: float = 1.0, space: str = "TANGENT",
                 uv_map: str = ""):
        if texture is None:
            raise NormalMapError("normal map: texture must be an engine texture / shader "
                                 "node or a constant colour, got None")
        if not hasattr(texture, "evaluate"):
            try:
                const = np.broadcast_to(np.asarray(texture, np.float64).ravel()[:3], (3,))
            except (TypeError, ValueError):
                raise NormalMapError("normal map: texture must be an engine texture / shader "
                                     "node or a constant colour (3,), got "
                                     f"{type(texture).__name__}") from None
            if not np.all(np.isfinite(const)):
                raise NormalMapError(f"normal map colour: must be finite, got {const}")
            texture = _ConstantColour(const)
        strength = float(strength)
        if not np.isfinite(strength):
            raise NormalMapError(f"normal map strength: must be finite, got {strength}")
        space = str(space).upper()
        if space not in SPACES:
            raise NormalMapError(f"normal map space: expected one of {SPACES}, got {space!r}")
        self.texture = texture
        self.strength = max(strength, 0.0)
        self.space = space
        self.uv_map = str(uv_map or "")

    def perturb(self, geo, prim, u, v, n: np.ndarray) -> np.ndarray:
        """(N,3) unit shading normals at hits (triangle prim, barycentrics u, v), from the
        unperturbed unit shading normals n (N,3), both on the winding-order side."""
        c = np.asarray(self.texture.evaluate(geo, prim, u, v), np.float64)
        if c.ndim == 1:  # a value into the Color socket reads as grey (Cycles' convert)
            c = np.repeat(c[:, None], 3, axis=1)
        c = 2.0 * c[:, :3] - 1.0
        if self.space == "WORLD":
            out = normalize(c)
            if self.strength != 1.0:
                out = normalize(n + (out - n) * self.strength)
        else:
            # Strength in tangent space, as Cycles' svm_node_normal_map: x and y scaled,
            # z blended towards 1 (a linear blend of the normals tilts differently).
            s = self.strength
            c = np.column_stack([c[:, 0] * s, c[:, 1] * s,
                                 1.0 + (c[:, 2] - 1.0) * min(s, 1.0)])
            named = bool(self.uv_map)
            key, sign_key = (("tangent:" + self.uv_map, "tangent_sign:" + self.uv_map)
                             if named else ("tangent", "tangent_sign"))
            if named:  # only that map's tangents: none, no perturbation (Cycles)
                t, sign = np.zeros_like(n), np.ones(len(n))
                ok = np.zeros(len(n), bool)
            else:
                t, sign = geo.uv_tangents(prim)
                t = t - n * dot(n, t)[:, None]
                tl = np.linalg.norm(t, axis=1)
                ok = tl > 1e-12  # no usable UVs: keep the normal (Cycles reads zero)
                t = t / np.maximum(tl, 1e-300)[:, None]
            nz = n
            mikk = (geo.corner_coordinates or {}).get(key) is not None
            if mikk:
                # Blender's MikkTSpace tangents (exported per corner) and the smooth
                # normal, both interpolated and NOT normalised, as Cycles'
                # svm_node_normal_map uses them: on a curved low-poly mesh both are
                # shorter than 1 inside a face, which changes the mapped direction.
                tm = geo.coordinates(key, prim, u, v)
                sm = geo.coordinates(sign_key, prim, u, v)[:, 0]
                # meshes without them: per triangle (render map) or unperturbed (named)
                has = np.linalg.norm(tm, axis=1) > 1e-12
                t = np.where(has[:, None], tm, t)
                sign = np.where(has, np.where(sm < 0, -1.0, 1.0), sign)
                ok = ok | has
                if len(geo.corner_normals):
                    nu = _interpolated_normals(geo, prim, u, v)
                    # The unnormalised normal points along n (n is it normalised, or the
                    # geometric normal where it degenerates): keep n's length-free side.
                    nz = np.where((has & (dot(nu, n) > 0))[:, None], nu, n)
            b = sign[:, None] * np.cross(nz, t)
            mapped = np.where(ok[:, None], c[:, 0:1] * t + c[:, 1:2] * b + c[:, 2:3] * nz, n)
            out = normalize(mapped)
        bad = ~np.isfinite(out).all(axis=1) | (np.linalg.norm(out, axis=1) < 0.5)
        out[bad] = n[bad]
        return out


def _interpolated_normals(geo, prim, u, v) -> np.ndarray:
    """(N,3) the corners' shading normals interpolated at the hits, not normalised
    (Cycles' triangle_smooth_normal_unnormalized; flat faces: their geometric normal)."""
    cn = np.take(geo.corner_normals, prim, axis=0).astype(np.float64)
    w = (1.0 - u - v)[:, None]
    return w * cn[:, 0] + u[:, None] * cn[:, 1] + v[:, None] * cn[:, 2]
