"""Fresnel terms of Cycles' closures (intern/cycles/kernel/closure/bsdf_util.h).

eta is always n_transmitted / n_incident, for the side the light arrives from."""
from __future__ import annotations

import math

from ..jit import kernel


@kernel
def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric interface for |cos_i| (cosine between
    the incident direction and the (micro)normal); 1 under total internal reflection."""
    c = abs(cos_i)
    g = eta * eta - 1.0 + c * c
    if g <= 0.0:
        return 1.0
    g = math.sqrt(g)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return min(0.5 * a * a * (1.0 + b * b), 1.0)


@kernel
def refracted_cos(cos_i, eta):
    """|cos| of the refracted direction for |cos_i| (0 under total internal reflection)."""
    s2 = (1.0 - cos_i * cos_i) / (eta * eta)
    return math.sqrt(1.0 - s2) if s2 < 1.0 else 0.0


@kernel
def F0_from_ior(ior):
    r = (ior - 1.0) / (ior + 1.0)
    return r * r


@kernel
def ior_from_F0(f0):
    s = math.sqrt(min(max(f0, 0.0), 0.9999999))
    return (1.0 + s) / (1.0 - s)


@kernel
def fresnel_dielectric_Fss(eta):
    """Average single-scattering Fresnel 2 * int_0^1 F(mu) mu dmu (Kulla & Conty's fit, as
    Cycles)."""
    if eta < 1.0:
        return 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    return (eta - 1.0) / (4.08567 + 1.00071 * eta)


@kernel
def schlick_remap(cos_i, eta):
    """Principled's generalized Schlick with the real Fresnel curve (Cycles' exponent < 0
    case): s in [0, 1] such that F = mix(f0, f90, s)."""
    f = fresnel_dielectric(cos_i, eta)
    f0 = F0_from_ior(eta)
    if f0 >= 1.0:
        return 1.0
    return min(max((f - f0) / (1.0 - f0), 0.0), 1.0)


@kernel
def f82_tint_B(f0, tint):
    """B of the F82-tint metal model (Kutz et al., as Cycles' fresnel_f82tint_B), per channel."""
    f = 6.0 / 7.0
    f5 = (f * f) * (f * f) * f
    schlick = f0 + (1.0 - f0) * f5
    return schlick * (7.0 / (f5 * f)) * (1.0 - tint)


@kernel
def fresnel_f82(cos_i, f0, b):
    """F82-tint reflectance: Schlick minus b cos (1 - cos)^6, clamped to [0, 1]."""
    s = min(max(1.0 - cos_i, 0.0), 1.0)
    s5 = (s * s) * (s * s) * s
    return min(max(f0 + (1.0 - f0) * s5 - b * (cos_i * s5 * s), 0.0), 1.0)


@kernel
def f82_Fss(f0, b):
    """Average single-scattering Fresnel of the F82 model (Cycles' fresnel_f82_Fss)."""
    return f0 + (1.0 - f0) / 21.0 - b / 126.0
