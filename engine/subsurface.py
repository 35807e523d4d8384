"""Principled Subsurface as a diffuse base of the albedo Cycles' random walk yields.

The engine has no subsurface transport (no light walks beneath the surface). A Principled
BSDF with Subsurface Weight w renders as its diffuse base with the colour
(1 - w) c + w A(c), where A(c) is the diffuse reflectance (directional-hemispherical:
reflected over incident power) Cycles' random-walk subsurface scattering (Blender 4.2+
defaults: Random Walk, Subsurface IOR and Anisotropy at their defaults) gives a half-space
of Base Color c, per channel. Measured on a thick slab whose mean free path is 1 cm
(bench/bench_subsurface_albedo.py: the radiance ratio a(c, view) = c (sss - spec) /
(dif - spec) at view zenith angles 0, 30, 45, 60, 75, 80, 85 degrees, the same at sun
angles 30 and 60; A = 2 int a mu dmu, trapezoids in mu = cos(view)). Cycles' random walk
keeps less than the colour asks (A(0.5) = 0.471) and holds A at 0.906 from c = 0.92 on.

What a diffuse base cannot follow (docs/accuracy.md, "mixpale"): Cycles' subsurface
radiance depends on the view (for c = 0.5: 0.89 c straight on, 1.08 c at 85 degrees; a
Lambertian base is A(c) at every angle), the light that leaves through thin parts or the
back (Suzanne at Subsurface Scale 0.3: red 0.82 of a thick object's) and the light
spread into shadows and across edges (a softer terminator).
"""
from __future__ import annotations

import numpy as np

# Base Color c -> Cycles' random-walk half-space albedo A(c), per channel (Blender 4.2
# bpy wheel, Cycles CPU, 128-256 spp x 576 pixels per view, seed 0:
# bench/bench_subsurface_albedo.py --view V, V = 0 .. 85).
TABLE_C = np.array([0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.88,
                    0.9, 0.92, 1.0])
TABLE_A = np.array([0.0, 0.0438, 0.0883, 0.1328, 0.1786, 0.2727, 0.3709, 0.4708, 0.5732,
                    0.6793, 0.7896, 0.8444, 0.8734, 0.8917, 0.9064, 0.9064])


def random_walk_albedo(c) -> np.ndarray:
    """Cycles' random-walk subsurface reflectance of a half-space of Base Color c (any
    shape, values per channel; below 0 taken as 0, above 1 as 1): piecewise linear in
    the measured TABLE_C -> TABLE_A."""
    return np.interp(np.clip(np.asarray(c, np.float64), 0.0, 1.0), TABLE_C, TABLE_A)


def diffuse_color(c, weight) -> np.ndarray:
    """The diffuse base colour standing in for Principled Subsurface: (1 - w) c + w a(c)
    with w = weight clamped to [0, 1] (Cycles mixes the diffuse and subsurface lobes by
    Subsurface Weight). c (..., 3), weight scalar or (...,)."""
    c = np.asarray(c, np.float64)
    w = np.clip(np.asarray(weight, np.float64), 0.0, 1.0)
    if w.ndim:
        w = w[..., None]
    return (1.0 - w) * c + w * random_walk_albedo(c)


class SubsurfaceColor:
    """A colour node (engine/shadernodes.py protocol, evaluate(geo, prim, u, v) -> (N,3))
    for a textured Base Color or a texture-driven Subsurface Weight: diffuse_color of the
    colour node's value and the weight (a node or a constant) at each hit."""

    def __init__(self, color, weight):
        self.color, self.weight = color, weight

    def evaluate(self, geo, prim, u, v):
        from .shadernodes import _eval
        return diffuse_color(_eval(self.color, geo, prim, u, v, 3),
                             _eval(self.weight, geo, prim, u, v, 1))
