"""Textured media beyond the density: emission along a density field, textured emission
and textured albedo (glowing clouds, fire, coloured clouds, gradient fog).

A material's medium (engine/media.py) may carry, besides a density texture f(p)
(engine/heterogeneous.py), two more fields evaluated at points inside its objects with
the same engine nodes (engine/shadernodes.py, through heterogeneous.PointGeometry: no
second evaluator):

- e(p), `Material.volume_emission_texture` (W m^-2 sr^-1 per metre, clipped at 0): a
  textured Emission Strength / Emission Color / Blackbody of a Principled Volume, or an
  Emission shader's Strength / Color. Cycles does not scale a volume's emission by its
  density (svm_node_principled_volume's emission_setup takes Emission Strength x Emission
  Color alone; svm_node_closure_emission the object's volume density, 1 for a mesh):
  "fire" is a density and an emission driven by the same texture.
- a(p), `Material.albedo_texture`: the single-scattering albedo sigma_s / sigma_t per
  channel, clipped to 0..1. Principled Volume with a black Absorption Color (its default)
  has sigma_t = density x (Color + max(1 - Color, 0)) = density for a Color within 0..1
  and sigma_s = density x Color: a textured Color moves the split between scattering and
  absorption and leaves the extinction alone, so the ratio tracking of
  heterogeneous.py holds as it is (a textured Color that changes the extinction, Volume
  Scatter's or with an Absorption Color, stays warned at export).

The homogeneous machinery keeps its stand-in (the table's rows): the emission's mean
(MediumTextures, from the objects' bounds as heterogeneous.py measures the density's),
sigma_s = f_mean sigma_t_unit a_mean. What each field changes:

Emission along a segment [0, S] of a ray in such a medium (camera segments, final-gather
rays, the volume walks' segments: volumeemission.MediumEmission.along, which calls
`integrate`): the radiance per unit throughput at the segment's start is

    L_c = integral_0^S T_c(s) e_c(s) ds,   T_c(s) = exp(-integral_0^s sigma_t,c).

With T_c(s) = exp(-sigma_c s) C_c(s) (the stand-in's sigma_c and the ratio-tracked
correction C = heterogeneous.HeterogeneousMedia.correction, an unbiased estimate of
T / T_stand-in), EMISSION_SAMPLES stratified distances s_j drawn from the truncated
exponential of the smallest channel's sigma' (pdf(s) = sigma' exp(-sigma' s) / (1 -
exp(-sigma' S)); uniform in a thin or non-extinguishing medium) give the unbiased

    L_c ~= 1/N sum_j exp(-sigma_c s_j) C_c(0, s_j) e_c(p(s_j)) / pdf(s_j)

(weights exp(-(sigma_c - sigma') s) <= 1 times the pdf's normaliser: no channel's
weight grows). A constant density and a constant emission give back the closed form
e (1 - exp(-sigma S)) / sigma within noise (the homogeneous kernel's value,
volumeemission.emission_integral). Cycles integrates the same in
volume_integrate_heterogeneous (shade_volume.h: the emission at every step of its
majorant-bounded march, weighted by the transmittance up to it).

Scattering (heterogeneous.HeterogeneousMedia.scatter_weights: camera single scattering,
the walks, the photons' free flights): the weight drawn for the stand-in takes a(p) /
a_mean per channel (`albedo_ratio`) beside the density's f(p) / f_mean.

Random numbers: the distances' from heterogeneous.py's counter-based hash of the render's
seed and the segment's origin and direction (salt DISTANCE_SALT; their tracking's
EMISSION_SALT): the same seed gives the same image for any worker count, and no other
stream's numbers move.
"""
from __future__ import annotations

import math

import numpy as np

from .heterogeneous import PointGeometry, ray_keys, uniforms
from .shadernodes import _eval

# Stratified distances per segment in a textured medium (each a ratio-tracked
# transmittance where the density is textured, tracked from the segment's start on its
# own). Measured at 1 / 2 / 4 / 8: a 32 x 32 px, 16 spp "fire" slab
# (tests/test_volume_fields.py's; cheap tracking): per-pixel relative std 0.173 / 0.082 /
# 0.054 / 0.047 in 0.51 / 0.63 / 0.72 / 1.22 s (variance x time least at 4); the glowing
# Noise cloud of tests/blender/test_volume_fields_cycles.py at 64 spp, full transport,
# against Cycles 1024 spp: relMSE 0.0089 / 0.0063 / 0.0053 / 0.0045 in 4.9 / 7.4 / 13.2 /
# 17.9 s (relMSE x time 0.044 / 0.046 / 0.070 / 0.081: the tracking dominates). 2 is
# near the best of both.
EMISSION_SAMPLES = 2
# The hash salts: the transmittance's tracking (heterogeneous.correction's salts 1-6 are
# the other ray kinds') and the distances' own numbers, which must not be the tracking's
# (the same key and step would place the first collision where the distance falls).
EMISSION_SALT = 7
DISTANCE_SALT = 8
TEXTURE_SAMPLES = 16 ** 3  # points per object for the emission's and albedo's means
THIN = 1e-6  # below this optical depth sigma' S the distances are uniform
# A stand-in albedo below this in a channel is raised to it (its scatter weights divide
# by it); an albedo texture that is 0 on every sample point but not everywhere would
# otherwise scatter nothing in that channel.
MIN_ALBEDO = 1e-4


def textured_materials(table) -> set:
    """The material rows of table with an emission or albedo texture on their medium."""
    out = set()
    for name in ("volume_emission_textures", "albedo_textures"):
        for m, tex in enumerate(getattr(table, name, None) or ()):
            if tex is not None:
                out.add(m)
    return out


def drop(table, m) -> None:
    """Forget material m's emission and albedo textures (a medium rendered homogeneous:
    a density tree that cannot be evaluated inside a volume)."""
    for name in ("volume_emission_textures", "albedo_textures"):
        lst = getattr(table, name, None)
        if lst is not None and m < len(lst):
            lst[m] = None


def _values(node, pg, n, width) -> np.ndarray:
    """(n,3) a node's colour / value (a value broadcast to 3) at PointGeometry pg's
    points, NaN read as 0."""
    prim = np.arange(n, dtype=np.int64)
    z = np.zeros(n)
    val = np.asarray(_eval(node, pg, prim, z, z, width), np.float64)
    return np.nan_to_num(val, nan=0.0, posinf=0.0, neginf=0.0)


def _textured(field) -> bool:
    """Whether a heterogeneous.Field has a density texture (its transmittance needs
    tracking; a field of constant density 1.0 carries only emission / albedo)."""
    return hasattr(field.node, "evaluate")


class MediumTextures:
    """The emission and albedo fields of one render's heterogeneous media (het:
    heterogeneous.HeterogeneousMedia, whose fields hold every material with a density,
    emission or albedo texture; made once its coordinate maps are fitted, before its
    density is measured). Sets the table's stand-in emission (the mean) and the fields'
    sigma_s_unit at the mean albedo (het's stand-in rows follow from them); `integrate`
    and `albedo_ratio` are the transport's (module docstring)."""

    def __init__(self, het, table, corners):
        self.het = het
        self.table = table
        self.emission = {}  # material row -> node (Material.volume_emission_texture)
        self.albedo = {}  # material row -> node (Material.albedo_texture)
        self.albedo_mean = {}  # material row -> (3,) the stand-in's albedo
        self.warnings: list[str] = []
        for m in het.fields:
            e = (getattr(table, "volume_emission_textures", None) or [None] * (m + 1))[m]
            a = (getattr(table, "albedo_textures", None) or [None] * (m + 1))[m]
            if e is not None and self._evaluates(m, e, "emission"):
                self.emission[m] = e
            if a is not None and self._evaluates(m, a, "Color (albedo)"):
                self.albedo[m] = a
        self._measure(corners)

    def _evaluates(self, m, node, what) -> bool:
        """Whether node evaluates at points inside a volume (a tree reading a surface's
        normal or the camera's view does not): else warned, naming the material, and
        left out (the emission then the export's constant, 0 for a textured one; the
        albedo the Color socket's own value)."""
        try:
            _values(node, self._geometry(np.zeros((2, 3)), np.zeros(2, np.int64)), 2, 3)
            return True
        except Exception as exc:  # noqa: BLE001 - any node's failure, reported
            self.warnings.append(
                f"material '{self.table.names[m]}': its {what} texture cannot be evaluated "
                f"inside the volume ({type(exc).__name__}: {exc}); "
                + ("rendered without it" if what == "emission"
                   else "the Color socket's own value used"))
            return False

    # -- setup ---------------------------------------------------------------------
    def _measure(self, corners):
        """The emission's and albedo's means over TEXTURE_SAMPLES jittered grid points in
        the bounds of each object carrying the material, into the table's stand-in."""
        het = self.het
        rng = np.random.default_rng([het.seed, 40, 14])
        n = round(TEXTURE_SAMPLES ** (1.0 / 3.0))
        g = (np.arange(n) + 0.5) / n
        grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
        for m in sorted(set(self.emission) | set(self.albedo)):
            e_sum, a_sum, cnt, a_top = np.zeros(3), np.zeros(3), 0, 0.0
            for k in np.unique(het.object[het.material == m]):
                sel = (het.object == k) & (het.material == m)
                P = corners[sel].reshape(-1, 3)
                lo, hi = P.min(axis=0), P.max(axis=0)
                pts = lo + (hi - lo) * np.clip(grid + (rng.random(grid.shape) - 0.5) / n,
                                               0.0, 1.0)
                obj = np.full(len(pts), k)
                if m in self.emission:
                    e_sum += self.emission_at(m, pts, obj).sum(axis=0)
                if m in self.albedo:
                    raw = _values(self.albedo[m], self._geometry(pts, obj), len(pts), 3)
                    a_top = max(a_top, float(raw.max()))
                    a_sum += np.clip(raw, 0.0, 1.0).sum(axis=0)
                cnt += len(pts)
            cnt = max(cnt, 1)
            f = het.fields[m]
            if m in self.emission:
                self.table.volume_emission[m] = e_sum / cnt
            if m in self.albedo:
                mean = np.maximum(a_sum / cnt, MIN_ALBEDO)
                self.albedo_mean[m] = mean
                # (the stand-in's rows follow: f_mean x these, heterogeneous.py)
                f.sigma_s_unit = f.sigma_t_unit * mean
                if a_top > 1.0 + 1e-6:
                    self.warnings.append(
                        f"material '{self.table.names[m]}': its Color texture exceeds 1 "
                        f"(up to {a_top:.3g}); read as 1 there (an albedo above 1 would "
                        "raise the extinction, which the density's tracking does not "
                        "follow)")

    def _geometry(self, pts, obj):
        het = self.het
        return PointGeometry(pts, obj, het.maps, np.asarray(het.geo.offset, np.float64),
                             het.volume_grids)

    # -- fields --------------------------------------------------------------------
    def emission_at(self, m, pts, obj) -> np.ndarray:
        """(n,3) material m's emission (W/m^2/sr per m) at points pts (n,3) inside
        objects obj (n,): its texture's, else the table's constant row."""
        m = int(m)
        node = self.emission.get(m)
        if node is None:
            return np.tile(np.asarray(self.table.volume_emission[m], np.float64),
                           (len(pts), 1))
        if len(pts) == 0:
            return np.zeros((0, 3))
        return np.maximum(_values(node, self._geometry(pts, obj), len(pts), 3), 0.0)

    def albedo_ratio(self, m, pts, obj):
        """(n,3) a(p) / a_mean of material m at points pts (n,3) in objects obj (n,), or
        1.0 without an albedo texture (scatter_weights' factor)."""
        m = int(m)
        node = self.albedo.get(m)
        if node is None or len(pts) == 0:
            return 1.0
        a = np.clip(_values(node, self._geometry(pts, obj), len(pts), 3), 0.0, 1.0)
        return a / self.albedo_mean[m]

    def glowing(self) -> set:
        """The materials whose emission must be integrated along a field: an emission
        texture, or a density texture (a tracked field) under a constant emission."""
        emit = np.asarray(self.table.volume_emission, np.float64)
        return {m for m, f in self.het.fields.items()
                if m in self.emission or (_textured(f) and np.any(emit[m] > 0.0))}

    # -- transport -----------------------------------------------------------------
    def integrate(self, o, d, t, src, L, sigma) -> None:
        """Replace, in place, the emission L (K,3) of the segments src (K,) of rays o, d
        (n,3) (t (n,) in units of |d|) computed for the homogeneous stand-in
        (volumeemission.segment_emission) by the field's unbiased estimate where the
        segment lies in a glowing textured medium (module docstring); sigma (M,3) the
        stand-in's extinction (media.absorption_table)."""
        glowing = self.glowing()
        if not glowing or len(src) == 0:
            return
        het = self.het
        o_s = np.take(np.asarray(o, np.float64), src, axis=0)
        d_s = np.take(np.asarray(d, np.float64), src, axis=0)
        dl = np.linalg.norm(d_s, axis=1)
        ok = dl > 0.0
        u = np.where(ok[:, None], d_s / np.where(ok, dl, 1.0)[:, None], 0.0)
        length = np.where(ok, np.take(np.asarray(t, np.float64), src) * dl, 0.0)
        ray, a, b, m, obj = het.intervals(o_s, u, length)
        sel = np.isin(m, list(glowing)) & (b > a)
        if not sel.any():
            return
        ray, a, b, m, obj = ray[sel], a[sel], b[sel], m[sel], obj[sel]
        L[np.unique(ray)] = 0.0
        N = EMISSION_SAMPLES
        P = len(ray)
        keys = ray_keys(het.seed, o_s[ray], d_s[ray], DISTANCE_SALT) ^ a.view(np.uint64)
        # N stratified numbers per part: (j + xi_j) / N
        j = np.repeat(np.arange(N)[None, :], P, axis=0)
        xi = (j + uniforms(np.repeat(keys, N), j.ravel()).reshape(P, N)) / N
        sig = sigma[m]  # (P,3) the stand-in's extinction
        sp = np.maximum(sig.min(axis=1), 0.0)  # sigma' (P,)
        S = b - a
        tau = sp * S
        thick = tau > THIN
        norm = np.where(thick, -np.expm1(-tau), 1.0)  # 1 - exp(-sigma' S)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(thick[:, None],
                         -np.log1p(-xi * norm[:, None]) / np.where(thick, sp, 1.0)[:, None],
                         xi * S[:, None])  # (P,N) from the part's start
            # 1 / pdf: norm / (sigma' exp(-sigma' s)) or S
            inv_pdf = np.where(thick[:, None],
                               norm[:, None] / np.where(thick, sp, 1.0)[:, None]
                               * np.exp(sp[:, None] * s), S[:, None])
        s = np.minimum(s, S[:, None])
        # (P*N) samples: the distance from the segment's origin, the stand-in's
        # transmittance there per channel, over the pdf
        r = np.repeat(np.arange(P), N)
        s_abs = (a[:, None] + s).ravel()
        w = np.exp(-sig[r] * s_abs[:, None]) * inv_pdf.ravel()[:, None]
        pts = o_s[ray][r] + u[ray][r] * s_abs[:, None]
        tracked = np.array([_textured(het.fields[int(x)]) for x in m[r]], np.bool_)
        if tracked.any():
            i = np.flatnonzero(tracked)
            w[i] *= het.correction(o_s[ray][r[i]], u[ray][r[i]], s_abs[i],
                                   salt=EMISSION_SALT)
        e = np.empty((len(r), 3))
        for mm in np.unique(m):
            q = np.flatnonzero(m[r] == mm)
            e[q] = self.emission_at(mm, pts[q], obj[r[q]])
        est = (w * e).reshape(P, N, 3).mean(axis=1)
        np.add.at(L, ray, est)

    def describe(self) -> str:
        """The effect report's words for the emission and albedo fields ('' : none)."""
        parts = []
        for m in sorted(self.emission):
            parts.append(f"emission texture of '{self.table.names[m]}' (mean "
                         f"{float(np.mean(self.table.volume_emission[m])):.3g} W/m^2/sr per m), "
                         "integrated along camera segments and final-gather rays")
        for m in sorted(self.albedo):
            parts.append(f"Color texture of '{self.table.names[m]}' (mean albedo "
                         f"{float(np.mean(self.albedo_mean[m])):.3g}) in every scatter's "
                         "weight")
        return "; ".join(parts)
