"""Generate engine/closures/ggx_tables.npz: the directional-albedo tables of the GGX closures.

    .venv/bin/python tools/make_closure_tables.py [--samples 96]

(the stored file is made with the default: the tool reproduces it bit for bit).

Each entry is a stratified Monte Carlo estimate (samples^2 visible-normal samples, the
closure's own sampling, engine/closures/ggx.py) of a single-scattering albedo, as Cycles'
intern/cycles/app/cycles_precompute.cpp computes its tables. Grids are uniform over [0, 1]
in each coordinate (engine/closures/tables.py interpolates linearly, like Cycles'
lookup_table_read):
    rough = sqrt(alpha) (Blender's roughness), mu = cos(theta_o) (floored at MU_MIN),
    z = sqrt((ior - 1) / (ior + 1)) for ior >= 1 (z capped at Z_MAX).
Tables:
    ggx_E (32, 32)[rough, mu]      white reflection lobe
    ggx_Eavg (32,)                 2 * int E(mu) mu dmu
    glass_E (16, 16, 16)[rough, mu, z], glass_Eavg (16, 16): glass (reflection +
                                   refraction, real Fresnel) entered from the lower-index side
    glass_inv_E, glass_inv_Eavg    the same from the higher-index side (eta = 1 / ior)
                                   The glass tables follow the procedure of the tables Cycles
                                   5.0 ships (ggx_glass_E / ggx_glass_inv_E in
                                   intern/cycles/scene/shader.tables, Blender Foundation,
                                   Apache-2.0), not our lobe's albedo: mu is floored at
                                   GLASS_MU_MIN = 1e-4 (Cycles' clamp) instead of MU_MIN, and
                                   a refraction sample that leaves on the incident side of
                                   the macro-surface counts with weight G2/G1, as the Cycles
                                   sampler that made those tables kept it (its 5.0 sampler,
                                   like ours, drops it: LABEL_NONE). So E is a little high
                                   where such samples are common (rough, eta < 1, grazing) and
                                   the compensated lobe loses light there, as Cycles' does
                                   (docs/design.md, Glass albedo tables).
    schlick_ior_s (16, 16, 16)     reflection lobe with Principled's Fresnel remap s(wo.h)
                                   = inverse_lerp(F0, 1, F(wo.h)): int s f cos / E, so the
                                   compensated lobe's albedo is mix(f0, f90, s)
    schlick5_s (16, 16)            the same with s = (1 - wo.h)^5 (F82 metals' estimate)
"""
from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
os.environ["PHOTONMAP_CLOSURE_TABLES_BOOTSTRAP"] = "1"  # tables may not exist yet

from engine.closures import ggx  # noqa: E402
from engine.closures.fresnel import schlick_remap  # noqa: E402
from engine.closures.tables import (GLASS_MU_MIN, MU_MIN, TABLE_PATH, Z_MAX,  # noqa: E402
                                    ior_from_z)
import numba  # noqa: E402

# Not cached: numba does not notice when a cached caller's callee (engine/closures/ggx.py)
# changes, and the tables must come from the current closures.
kernel = numba.njit(nogil=True)


@kernel
def _reflect_albedos(rough, mu, eta, S):
    """(E, int s_ior f cos, int (1-wo.h)^5 f cos) of the white lobe for S x S strata."""
    alpha = rough * rough
    ox, oy, oz = math.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu
    e = 0.0
    s_ior = 0.0
    s5 = 0.0
    for a in range(S):
        for b in range(S):
            u1 = (a + 0.5) / S
            u2 = (b + 0.5) / S
            ix, iy, iz, w, pdf, c = ggx.reflect_sample(ox, oy, oz, alpha, u1, u2)
            if w <= 0.0:
                continue
            e += w
            s_ior += w * schlick_remap(c, eta)
            m = 1.0 - c
            s5 += w * (m * m) * (m * m) * m
    n = S * S
    return e / n, s_ior / n, s5 / n


@kernel
def _glass_albedo(rough, mu, eta, S):
    """E of the white glass lobe as Cycles' tables define it (module docstring): the lobe's
    own samples, plus the refractions that leave on wo's side (our sampler gives them
    weight 0) at their G2/G1 = (1 + Lambda_o) / (1 + Lambda_o + Lambda_i)."""
    alpha = rough * rough
    a2 = alpha * alpha
    ox, oy, oz = math.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu
    e = 0.0
    for a in range(S):
        for b in range(S):
            u1 = (a + 0.5) / S
            u2 = (b + 0.5) / S
            # the reflect / refract choice stratified along the second axis too
            u3 = ((b * 7 + a * 3) % S + 0.5) / S
            ix, iy, iz, w, pdf, refr = ggx.glass_sample(ox, oy, oz, alpha, eta, u1, u2, u3)
            if refr and w == 0.0 and iz >= 0.0 and alpha >= ggx.ALPHA_MIN:
                lo = ggx.lambda_ggx(oz, a2)
                w = (1.0 + lo) / (1.0 + lo + ggx.lambda_ggx(iz, a2))
            e += w
    return e / (S * S)


def _grid(n):
    return np.linspace(0.0, 1.0, n)


def _avg(E, mus):
    """2 int_0^1 E(mu) mu dmu along the last axis (trapezoid on the table's grid)."""
    return np.trapz(2.0 * E * mus, mus, axis=-1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=96, help="strata per axis")
    args = ap.parse_args(argv)
    S = args.samples
    r32, m32 = _grid(32), np.maximum(_grid(32), MU_MIN)
    ggx_E = np.array([[_reflect_albedos(r, m, 1.5, S)[0] for m in m32] for r in r32])
    r16, m16 = _grid(16), np.maximum(_grid(16), MU_MIN)
    m16_glass = np.maximum(_grid(16), GLASS_MU_MIN)
    z16 = np.minimum(_grid(16), Z_MAX)
    iors = ior_from_z(z16)
    glass_E = np.empty((16, 16, 16))
    glass_inv_E = np.empty((16, 16, 16))
    s_ior = np.empty((16, 16, 16))
    s5 = np.empty((16, 16))
    for i, r in enumerate(r16):
        for j, m in enumerate(m16):
            for k, ior in enumerate(iors):
                glass_E[i, j, k] = _glass_albedo(r, m16_glass[j], ior, S)
                glass_inv_E[i, j, k] = _glass_albedo(r, m16_glass[j], 1.0 / ior, S)
                e, si, s5_ = _reflect_albedos(r, m, ior, S)
                s_ior[i, j, k] = si / e
                s5[i, j] = s5_ / e
    # Eavg integrates over mu on [0, 1]; the grid's first point stands for mu = 0.
    glass_Eavg = _avg(np.moveaxis(glass_E, 1, -1), _grid(16))
    glass_inv_Eavg = _avg(np.moveaxis(glass_inv_E, 1, -1), _grid(16))
    np.savez_compressed(TABLE_PATH, ggx_E=ggx_E.astype(np.float32),
                        ggx_Eavg=_avg(ggx_E, _grid(32)).astype(np.float32),
                        glass_E=glass_E.astype(np.float32),
                        glass_Eavg=glass_Eavg.astype(np.float32),
                        glass_inv_E=glass_inv_E.astype(np.float32),
                        glass_inv_Eavg=glass_inv_Eavg.astype(np.float32),
                        schlick_ior_s=s_ior.astype(np.float32),
                        schlick5_s=s5.astype(np.float32), samples=np.int64(S))
    print(f"wrote {TABLE_PATH} ({os.path.getsize(TABLE_PATH)} bytes, {S}x{S} samples/entry)")


if __name__ == "__main__":
    main()
