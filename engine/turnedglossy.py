"""Camera paths at smooth-shaded glossy-only surfaces: Cycles' turned normal, not Veach's
guard (glossyguard45).

camerakernels.face_shading_normals replaces a shading normal that puts the viewer below
the surface by the face's normal (Veach's guard). Cycles keeps the interpolated normal
and turns only the glossy closures' normal (ensure_valid_specular_reflection,
kernel/closure/bsdf_util.h), which principled.glossy_normals does whenever the normal is
kept. On a leaning smooth cap (a lathe's top, seen from above: docs/accuracy.md, vase45)
the guard made the metal reflect like the flat face, towards a light above it: 1.22 of
Cycles there.

Here a camera path's hits on materials whose lobes are all glossy (Principled Metallic 1
or a Glossy BSDF: no diffuse, sheen, translucent or transmission lobe) keep their shading
normal where the guard would replace it (bsdf.surface_hit's `unguarded` rows), and so do
Principled materials with a diffuse lobe and no translucent or transmission lobe
(plastic, paint: `diffuse_reflective`, vase47; with a sheen too since smooth55): as in
Cycles their glossy lobes take the turned normal and their diffuse and sheen lobes the
interpolated one as it is (the sheen read at a view cosine of 0 where the viewer is
below it, and tested on the light's side only, as bsdf_sheen_setup / bsdf_sheen_eval). With the guard a
smooth plastic vase under a Spot from above read 1.075 of Cycles (its cap's top quarter
of rows 1.89; docs/accuracy.md, vase47); smooth glass follows
turnedlight.camera_unguarded (the photons' adjoint threshold). Rows where the guard
would not act are never marked, so a batch with no such hit returns None and the fused
plain-table kernel runs: the same bits as without this module.

Instanced geometry is covered (the hits' rows gathered, world-space normals and the
instance's material slot: engine/sharedrows.py), so instances render as their copies
(tests/test_scenefile_instances.py). Shading normals pointing into the surface (ns . ng
<= 0: broken custom normals) keep the guard's fall-back to the face at every row kind:
Cycles would light such a diffuse lobe only from below the face (black); ours stays
stable (tests/test_stability_geometry.py; docs/accuracy.md, vase48).

Not covered: texture-driven Metallic (the material's table row decides), the
final-gather chains and the photon pass (they keep the guard).
"""
from __future__ import annotations

import numpy as np

from .closures import principled as pr

# False: camera paths keep the guard at glossy-only hits (as before glossyguard45; A/B runs).
ENABLED = True
# True: Principled materials with a diffuse lobe (Metallic < 1: plastic, paint) keep their
# shading normal too, their glossy lobes turned and their diffuse lobe on the normal as it
# is, as Cycles' svm/closure.h sets them up (vase47); False: the guard there (glossyguard45,
# for A/B runs). On since vase48 (instances covered, broken normals keep the guard).
DIFFUSE = True
# True: Principled materials with a sheen (and a diffuse lobe) keep their shading normal
# too, the sheen set up and evaluated on it as Cycles' bsdf_sheen_setup / _eval do (the
# view below it read at cos 0, only the light's side tested: closures/sheen.py); False:
# the guard there (before smooth55, for A/B runs). A Shade Smooth cap's far rows read
# 0.73-0.82 of Cycles with the guard (docs/accuracy.md, newuser55 / smooth55).
SHEEN = True
_GUARD_EPS = 1e-6  # face_shading_normals' threshold on wo . ns


def glossy_only(params: np.ndarray) -> np.ndarray:
    """(M,) bool per material row of params (MaterialTable.closure_params (M, N_MAT)):
    Principled with Metallic >= 1 or a Glossy BSDF node, without transmission, sheen or
    translucency (every lobe is one principled.glossy_normals turns)."""
    params = np.asarray(params)
    node = params[:, pr.M_NODE]
    metal = (((node == pr.NODE_PRINCIPLED) & (params[:, pr.M_METALLIC] >= 1.0))
             | (node == pr.NODE_GLOSSY))
    return (metal & (params[:, pr.M_TRANS] <= 0.0) & (params[:, pr.M_SHEEN_W] <= 0.0)
            & (params[:, pr.M_TL] <= 0.0))


def diffuse_reflective(params: np.ndarray) -> np.ndarray:
    """(M,) bool per material row: Principled without transmission or translucency
    whose Metallic is below 1 (a diffuse lobe under the specular and coat layers, a
    sheen over them when SHEEN, else no sheen): Cycles turns the glossy closures' normal
    and leaves the diffuse and sheen closures' N as it is (svm/closure.h:
    `maybe_ensure_valid_specular_reflection(sd, N)` for the specular layers, the diffuse
    and sheen bsdfs on N)."""
    params = np.asarray(params)
    node = params[:, pr.M_NODE]
    ok = ((node == pr.NODE_PRINCIPLED) & (params[:, pr.M_METALLIC] < 1.0)
          & (params[:, pr.M_TRANS] <= 0.0) & (params[:, pr.M_TL] <= 0.0))
    return ok if SHEEN else ok & (params[:, pr.M_SHEEN_W] <= 0.0)


def camera_unguarded(geo, table, prim, u, v, d, material=None) -> np.ndarray | None:
    """(N,) bool: camera-path hits (triangles prim (N,), barycentrics u, v (N,), ray
    directions d (N,3); material (N,) the Light Path variant rows or None: the
    triangles') on glossy_only materials whose interpolated shading normal puts the
    viewer wo = -d below it (wo . ns <= 1e-6 on the ray's side: where
    face_shading_normals would use the face normal), unless that normal points into the
    surface (ns . ng <= 0: the guard stays); None where no row is. geo may share its
    instanced rows (engine/sharedrows.py): only the hits' rows are read."""
    if not ENABLED:
        return None
    cn = getattr(geo, "corner_normals", None)
    if cn is None or not len(cn):
        return None
    ok = glossy_only(table.closure_params)  # (a few comparisons a material row)
    if DIFFUSE:
        ok = ok | diffuse_reflective(table.closure_params)
    if not ok.any():
        return None
    prim = np.asarray(prim, np.int64)
    # (geo.material[prim] gathers only the hits' rows: an instance's material slot where
    # the rows are shared, engine/sharedrows.py; the whole column is never built.)
    mat = geo.material[prim] if material is None else np.asarray(material)
    rows = np.flatnonzero(ok[mat])
    if not len(rows):
        return None
    if getattr(geo, "shared", None) is None:
        # One compiled pass, the same operations (camerakernels.glossy_unguarded_rows):
        # the numpy stage below took ~3 % of Figure 6's camera pass (docs/performance.md,
        # hotspots53). Shared instances keep it (their rows' world-space tables).
        from .camerakernels import glossy_unguarded_rows
        out = np.zeros(len(prim), bool)
        n = glossy_unguarded_rows(rows, prim, np.ascontiguousarray(u, np.float64),
                                  np.ascontiguousarray(v, np.float64),
                                  np.ascontiguousarray(d, np.float64), geo.e1, geo.e2, cn,
                                  _GUARD_EPS, out)
        return out if n else None
    p = prim[rows]
    ns = geo.shading_normals(p, np.asarray(u, np.float64)[rows],
                             np.asarray(v, np.float64)[rows])
    ng = np.asarray(geo.ng[p], np.float64)
    dd = np.asarray(d, np.float64)[rows]
    # The ray's side of the winding normal (hit_geometry's front), then the guard's test;
    # a shading normal pointing into the surface (ns . ng <= 0: broken custom normals,
    # on either side, as both turn together) keeps the guard's fall-back to the face:
    # Cycles would light a diffuse lobe on it only from below the face (vase48).
    side = np.where(np.einsum("ij,ij->i", dd, ng) < 0.0, 1.0, -1.0)
    below = ((side * np.einsum("ij,ij->i", ns, -dd) <= _GUARD_EPS)
             & (np.einsum("ij,ij->i", ns, ng) > 0.0))
    if not below.any():
        return None
    out = np.zeros(len(prim), bool)
    out[rows[below]] = True
    return out
