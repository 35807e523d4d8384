"""Sunlight that final-gather chains find through Cycles' turned-normal glass reflections.

Cycles' glass closure reflects the camera-side direction w about
N' = ensure_valid_specular_reflection(Ng, w, Ns) (kernel/closure/bsdf_util.h;
principled.valid_reflection_normal): where the mirror of w about the shading normal Ns
would not rise min(0.9 w.Ng, 0.01) over the surface, Ns is turned towards Ng until it
does. Such a turned reflection sends a whole solid angle of w into one band of directions
0.01 over the face: no photon arrives from a set of no solid angle, so the photon maps
carry no light along a path with one (engine/glassadjoint.py takes the other two kinds,
the reflection and refraction about Ns and the turned refractions, as their adjoint;
docs/accuracy.md, smoothglass43). A diffuse surface under smooth-sided glass (a glass of
water on a table) takes much of its light in Cycles through such paths: its diffuse ray
meets the glass's inner side from below, reflects at the turned normal up the wall and
out to the sun.

The split with the photon maps is by path: a final-gather ray (gather_indirect, every
level) whose specular chain took at least one turned reflection at a SMOOTH_GLASS hit
bent more than photonkernels.GLASS_ADJOINT_MIN_BEND_DEG (where the photons take the
adjoint) and then escapes adds the radiance of the sun discs (angle > 0) it points into;
every other escaping chain adds nothing, as before (the photons carry its light). The
chain's lookup ends are untouched (a diffuse surface after a turned reflection reads the
map as before: the turn is on the camera side of that lookup). Not served yet: the
world's light and emitting surfaces or lamps met after a turned reflection (left out, as
before); mirrors and rough glass (their photons are not the adjoint either); a world
volume's attenuation of the escaping ray and light linking of the sun (the sun's disc
is added as seen).

For the split to be exact the gather chains must cross such glass by Cycles' rule, the
one the photons take the adjoint of: at those hits (bent more than the threshold) the
shading normal keeps no guard (camerakernels.face_shading_normals replaces a normal that
puts the viewer below it by Ng; Cycles turns it, and so does principled.glossy_normals
when it is kept: unguarded). With the guard, a gather ray from a table meeting a glass's
inner side from below (its normals lean up) reflected and refracted about the flat face:
light that neither Cycles nor the photons have.

Camera paths (integrator._trace_paths) cross such glass by the same rule (camera_unguarded,
turnedcamera45): they trace their own specular chains and see the sun discs they escape
into, so they need no escape term, only Cycles' normal at the glass.

Scenes without such glass (no SMOOTH_GLASS triangle whose corner normals bend more than
the threshold) get None from for_context: no work and the same bits as without this
module; without a sun with a disc the chains are unguarded but add nothing.
"""
from __future__ import annotations

import math
import threading

import numpy as np

from . import photonkernels
from .photonkernels import SMOOTH_GLASS, lobe_classes

_LOCK = threading.Lock()
_RISE = 0.01  # Cycles' height over the surface a mirror direction must keep (bsdf_util.h)
# False: neither part (the gather chains keep the guard and add nothing at their
# escapes, as before). The two parts alone, for A/B runs (bench/bench_turned_light.py):
# UNGUARD (Cycles' turned normal at the bent glass's hits) and ESCAPES (the suns the
# turned chains escape into).
ENABLED = True
UNGUARD = True
ESCAPES = True
# Camera paths (integrator._trace_paths) cross the bent glass by Cycles' rule too
# (camera_unguarded); False: they keep the guard (as before turnedcamera45, for A/B runs).
CAMERA = True


class TurnedReflections:
    """The scene's smooth glass where gather chains may take turned reflections, and the
    suns they may then see. Built once per prepared geometry (for_context)."""

    def __init__(self, glass_mat: np.ndarray, bend_cos: float, suns: list,
                 glass_tri: np.ndarray = None, glass_rows: np.ndarray = None):
        self.glass_mat = glass_mat  # (M,) bool: SMOOTH_GLASS material rows
        self.bend_cos = bend_cos    # cos of GLASS_ADJOINT_MIN_BEND_DEG
        self.suns = suns            # suns with a disc (angle > 0)
        self.glass_tri = glass_tri  # (T,) bool: SMOOTH_GLASS triangles bent past it
        # (R,) int64 ascending: those rows where the Geometry shares its instanced rows
        # (engine/sharedrows.py; glass_tri None there: no (T,) column is built)
        self.glass_rows = glass_rows

    def bent_triangles(self, prim) -> np.ndarray:
        """(N,) bool: the rows prim (N,) int among the SMOOTH_GLASS triangles bent past
        the threshold (glass_tri, or glass_rows where the rows are shared)."""
        prim = np.asarray(prim, np.int64)
        if self.glass_tri is not None:
            return self.glass_tri[prim]
        rows = self.glass_rows
        at = np.minimum(np.searchsorted(rows, prim), max(len(rows) - 1, 0))
        return (rows[at] == prim) if len(rows) else np.zeros(len(prim), bool)

    @classmethod
    def for_context(cls, ctx) -> "TurnedReflections | None":
        """None unless ENABLED and some SMOOTH_GLASS triangle's corner normals bend
        more than photonkernels.GLASS_ADJOINT_MIN_BEND_DEG from its face (an
        interpolated normal bends no more than its corners)."""
        if not ENABLED:
            return None
        geo = ctx.geo
        key = "_turned_reflections"
        cached = geo.__dict__.get(key, False)
        if cached is not False:
            return cached
        with _LOCK:
            cached = geo.__dict__.get(key, False)
            if cached is not False:
                return cached
            geo.__dict__[key] = made = cls._build(ctx)
            return made

    @classmethod
    def _build(cls, ctx):
        suns = [light for light in ctx.lights
                if hasattr(light, "seen_at_infinity") and getattr(light, "has_size", False)
                and getattr(light, "cos_half_angle", 1.0) < 1.0]
        geo = ctx.geo
        cn = getattr(geo, "corner_normals", None)
        if cn is None or not len(cn):
            return None
        glass_mat = lobe_classes(np.asarray(ctx.table.closure_params)) == SMOOTH_GLASS
        # Instanced rows (geometry.Instances) are covered as their copies: the photons
        # take glassadjoint's rule at every hit, instanced or not. Where the rows are
        # shared (engine/sharedrows.py) only the glass rows are gathered, world-space.
        shared = getattr(geo, "shared", None)
        if shared is None:
            tri = np.nonzero(glass_mat[np.asarray(geo.material)])[0]
        else:
            tri = shared.rows_of(np.flatnonzero(glass_mat))
        if not len(tri):
            return None
        bend_cos = math.cos(math.radians(photonkernels.GLASS_ADJOINT_MIN_BEND_DEG))
        # (x[tri] gathers those rows alone, of an array or a shared column alike)
        g = np.cross(geo.e1[tri], geo.e2[tri])
        g /= np.maximum(np.linalg.norm(g, axis=1), 1e-300)[:, None]
        c = np.abs(np.einsum("tkj,tj->tk", cn[tri].astype(np.float64), g))
        bent = (c < bend_cos).any(axis=1)
        if not bent.any():
            return None
        if shared is not None:
            return cls(glass_mat, bend_cos, suns, glass_rows=tri[bent])
        glass_tri = np.zeros(len(cn), bool)
        glass_tri[tri[bent]] = True
        return cls(glass_mat, bend_cos, suns, glass_tri)

    def unguarded(self, geo, prim, u, v) -> np.ndarray:
        """(N,) bool: hits (triangles prim (N,), barycentrics u, v) on SMOOTH_GLASS whose
        interpolated shading normal bends more than the threshold from the face (where the
        photons take glassadjoint's rule): bsdf.surface_hit's unguarded rows."""
        prim = np.asarray(prim, np.int64)
        out = self.bent_triangles(prim) & UNGUARD
        rows = np.flatnonzero(out)
        if len(rows):
            n = geo.shading_normals(prim[rows], np.asarray(u)[rows], np.asarray(v)[rows])
            g = np.asarray(geo.ng[prim[rows]], np.float64)
            out[rows] = np.abs(np.einsum("ij,ij->i", n, g)) < self.bend_cos
        return out

    def camera_unguarded(self, geo, prim, u, v, material=None) -> np.ndarray | None:
        """unguarded for a camera path's hits (material (N,): each hit's material row where
        a Light Path variant replaces its triangle's, engine/raymaterials.py; None: the
        triangles'), only rows still SMOOTH_GLASS there; None where no row is (the
        fused plain-table kernel then runs, the same bits as without this module)."""
        if not CAMERA:
            return None
        out = self.unguarded(geo, prim, u, v)
        if material is not None:
            out &= self.glass_mat[np.asarray(material)]
        return out if out.any() else None

    @property
    def escapes(self) -> bool:
        """Whether the chains' escapes can see a sun here (ESCAPES and a sun's disc)."""
        return ESCAPES and bool(self.suns)

    def turned(self, y, rows, d_in, d_out) -> np.ndarray:
        """(K,) bool: the continued rays (hits rows (K,) of SurfaceHit y, arriving along
        d_in (K,3), leaving along d_out (K,3)) that reflected at a SMOOTH_GLASS hit whose
        shading normal is bent more than the threshold and which Cycles turns for this
        arrival (the mirror of w = -d_in about Ns below min(0.9 w.Ng, 0.01))."""
        mat = np.asarray(y.mat)[rows]
        ns, ng = np.asarray(y.ns)[rows], np.asarray(y.ng)[rows]
        w = -np.asarray(d_in)
        # ng faces the arriving ray (hit_geometry); ns on its side
        iz = np.einsum("ij,ij->i", w, ng)
        ni = np.einsum("ij,ij->i", ns, w)
        r = 2.0 * ni[:, None] * ns - w
        raised = np.einsum("ij,ij->i", r, ng) < np.minimum(0.9 * iz, _RISE)
        bent = np.einsum("ij,ij->i", ns, ng) < self.bend_cos
        reflected = np.einsum("ij,ij->i", np.asarray(d_out), ng) > 0.0
        return self.glass_mat[mat] & bent & raised & reflected

    def escaped(self, d, ray_cls) -> np.ndarray:
        """(K,3) radiance of the sun discs along escaping directions d (K,3), for rays of
        class ray_cls (scalar or (K,)) the suns are visible to (Cycles' ray visibility)."""
        L = np.zeros((len(d), 3))
        cls = np.broadcast_to(np.asarray(ray_cls, np.int64), (len(d),))
        for light in self.suns:
            sun = light.seen_at_infinity(d)
            if sun is not None:
                L += sun * ((cls & int(light.ray_kinds)) != 0)[:, None]
        return L
