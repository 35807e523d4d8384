"""Cycles' microfiber sheen (intern/cycles/kernel/closure/bsdf_sheen.h): Zeltner, Burley
and Chiang, "Practical Multiple-Scattering Sheen Using Linearly Transformed Cosines"
(2022). The lobe is a cosine distribution under a per-(view angle, roughness) linear
transform (A, B) with directional albedo `albedo`, read from Cycles' fitted table
(sheen_ltc.npz: table_sheen_ltc of intern/cycles/scene/shader.tables, Apache-2.0, as
Blender 5.0 ships it; planes A, B, albedo, each [roughness, cos_o] on uniform 32-point
grids over [0, 1]).

Local frame: +z the normal; the lobe's own frame turns x towards the viewer (wo).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from .tables import load_data, lookup2

_LTC = np.ascontiguousarray(load_data(__file__, "sheen_ltc.npz")["ltc"], np.float64)
LTC_A = np.ascontiguousarray(_LTC[0])
LTC_B = np.ascontiguousarray(_LTC[1])
LTC_ALBEDO = np.ascontiguousarray(_LTC[2])


@kernel
def sheen_params(rough, mu):
    """(A, B, albedo) for roughness rough (clamped to [1e-3, 1]) and cos_o = mu; albedo 0
    where the fit is invalid (Cycles then drops the lobe)."""
    r = min(max(rough, 1e-3), 1.0)
    a = lookup2(LTC_A, r, mu)
    b = lookup2(LTC_B, r, mu)
    alb = lookup2(LTC_ALBEDO, r, mu)
    if abs(a) < 1e-5 or alb < 1e-5:
        return a, b, 0.0
    return a, b, alb


@kernel
def _lobe_frame(ox, oy):
    """Unit tangent towards wo's projection (any when wo is the normal)."""
    ln = math.sqrt(ox * ox + oy * oy)
    if ln < 1e-9:
        return 1.0, 0.0
    return ox / ln, oy / ln


@kernel
def sheen_eval(a, b, ox, oy, oz, ix, iy, iz):
    """(f * cos_i, pdf) of the unit-albedo lobe (the closure weight carries the albedo).
    Only the light's side is tested, as Cycles' bsdf_sheen_eval: a view below the
    shading normal (oz <= 0, a smooth normal kept past the guard: turnedglossy) still
    reflects, the lobe's frame turned towards wo's projection (smooth55)."""
    if iz <= 0.0:
        return 0.0, 0.0
    tx, ty = _lobe_frame(ox, oy)
    x = ix * tx + iy * ty
    y = -ix * ty + iy * tx
    z = iz
    len_sqr = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
    val = z * (a / len_sqr) ** 2 / math.pi
    return val, val


@kernel
def sheen_sample(a, b, ox, oy, oz, u1, u2):
    """(ix, iy, iz, pdf): weight = eval / pdf = 1 for a valid (upper) direction."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    dx, dy = r * math.cos(phi), r * math.sin(phi)
    dz = math.sqrt(max(1.0 - dx * dx - dy * dy, 0.0))
    lx, ly, lz = dx - dz * b, dy, dz * a
    ln = math.sqrt(lx * lx + ly * ly + lz * lz)
    lx, ly, lz = lx / ln, ly / ln, lz / ln
    tx, ty = _lobe_frame(ox, oy)
    ix = lx * tx - ly * ty
    iy = lx * ty + ly * tx
    iz = lz
    len_sqr = (a * lx + b * lz) ** 2 + (a * ly) ** 2 + lz * lz
    val = lz * (a / len_sqr) ** 2 / math.pi if lz > 0.0 else 0.0
    return ix, iy, iz, val
