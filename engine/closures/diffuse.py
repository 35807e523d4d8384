"""Lambertian diffuse closure (Cycles' bsdf_diffuse.h), local frame (+z = normal)."""
from __future__ import annotations

import math

from ..jit import kernel


@kernel
def lambert_eval(oz, iz):
    """(f * cos_i, pdf) of a white Lambertian lobe: both cos_i / pi above the surface."""
    if oz <= 0.0 or iz <= 0.0:
        return 0.0, 0.0
    v = iz / math.pi
    return v, v


@kernel
def lambert_sample(u1, u2):
    """Cosine-weighted wi: (ix, iy, iz, weight = 1, pdf)."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    iz = math.sqrt(max(0.0, 1.0 - u1))
    return r * math.cos(phi), r * math.sin(phi), iz, 1.0, iz / math.pi
