"""Cycles' light passes (RenderSettings.data_passes "light"): Diffuse / Glossy /
Transmission Direct and Indirect, Emission and Environment, split from the camera paths'
light so that, with the Color passes (engine/datapasses.py),

    Combined = (DiffDir + DiffInd) x DiffCol + (GlossDir + GlossInd) x GlossCol
             + (TransDir + TransInd) x TransCol + Emission + Environment (+ volume light)

as Blender's compositor recombines them.

Definitions, from Cycles' kernel (kernel/film/light_passes.h: film_write_direct_light,
film_write_emission_or_background_pass; kernel/closure/bsdf.h bsdf_eval_init /
bsdf_eval_accum, bsdf_eval_pass_diffuse_weight / _glossy_weight; the shade_surface
bounce that sets the path's pass_diffuse_weight / pass_glossy_weight at bounce 0):

- A path's first bent bounce (transparent passes do not count: Cycles' transparent
  bounces leave `bounce` at 0) decides which light pass its later light goes to: the
  BSDF's split of that bounce into diffuse, glossy and transmission (Cycles: the ratio of
  the diffuse / glossy closures' eval to their sum in the sampled direction, transmission
  = 1 - diffuse - glossy; a glass closure counts as glossy on the reflection side). Here
  the camera path continues one lobe per ray with weight f / p of that lobe, so the
  split is the continued ray's class (GLOSSY: metal, specular layer, coat, the glass
  lobe's reflection; TRANSMISSION: the glass lobe's refraction; DIFFUSE: sheen): the same
  expectation, lobe by lobe.
- Light sampled at the first hit (next-event estimation, bounce 0) is Direct, split by
  the lobes that take it: the diffuse lobe's (and sheen's) into Diffuse Direct, the rough
  reflective lobes' into Glossy Direct, the rough glass's transmitted light
  (engine/glasslight.py) into Transmission Direct. An emitter or the world met by the ray
  the first bounce sent (Cycles' bounce 1) is Direct of the path's class; everything
  later (more bounces) Indirect. The photon-map estimates at the first hit (global map or
  final gather, caustics, regathers) carry light that took bounces before it came:
  Diffuse Indirect.
- Emission: emitters (surfaces, lamps, suns' discs, emitting media) met by camera rays
  and their transparent continuations; Environment: the world they meet.
- Light scattered in media (engine/volumescatter.py, volumewalk.py) before the first
  bent bounce is kept in the "volume" sum; past it, it is the path's Indirect (Cycles:
  the surface bounce came first). Cycles splits the media's light into Volume Direct /
  Indirect by the scattering vertex's bounce: at Volume bounces 0 (its default) all of
  it is single scattering of the lights, Volume Direct (shown); with more bounces the
  walks' multiple scattering is not told apart and the two passes stay unmade.

The sums (per-sample averages in Film.data, as Cycles' render buffer) are written raw;
Blender shows Direct / Indirect divided by the Color pass of their kind
(kernel/film/read.h film_get_pass_pixel_divide_even_color: safe_divide_even_color, a
zero channel of the colour takes the others' ratio): shown().

Shapes: pix (N,) int64 pixel rows; rgb (K,3) float64 radiance (W m^-2 sr^-1) before the
path throughput tp (N,3); rows (K,) int64 rows of pix / tp (None: K = N, every row).
"""
from __future__ import annotations

import numpy as np

from .camerakernels import film_add
from .closures import principled as pr
from .visibility import DIFFUSE, GLOSSY, TRANSMISSION

# Data keys (Film.data / Accumulator.data), by index: Direct of a class c is c,
# Indirect c + 3 (c: 0 diffuse, 1 glossy, 2 transmission).
KEYS = ("diffuse_direct", "glossy_direct", "transmission_direct",
        "diffuse_indirect", "glossy_indirect", "transmission_indirect",
        "emission", "environment", "volume")
DIFFUSE_DIRECT, GLOSSY_DIRECT, TRANSMISSION_DIRECT = 0, 1, 2
DIFFUSE_INDIRECT = 3
EMISSION, ENVIRONMENT, VOLUME = 6, 7, 8
# (Blender 5's pass name, data key, channels), the order Cycles' add-on lists them in.
PASSES = (("Diffuse Direct", "diffuse_direct", 3), ("Diffuse Indirect", "diffuse_indirect", 3),
          ("Glossy Direct", "glossy_direct", 3), ("Glossy Indirect", "glossy_indirect", 3),
          ("Transmission Direct", "transmission_direct", 3),
          ("Transmission Indirect", "transmission_indirect", 3),
          ("Emission", "emission", 3), ("Environment", "environment", 3),
          ("Volume Light", "volume", 3))
# Direct / Indirect key -> the Color pass Blender divides it by (Cycles' divide_type).
DIVIDE = {"diffuse_direct": "diffuse_color", "diffuse_indirect": "diffuse_color",
          "glossy_direct": "glossy_color", "glossy_indirect": "glossy_color",
          "transmission_direct": "transmission_color",
          "transmission_indirect": "transmission_color"}
_NO_ROWS = np.zeros(0, np.int64)
_NO_TP = np.zeros((0, 3))
# Ray class of a continued ray -> light-pass class (-1: a camera ray or a transparent
# continuation, undecided).
_CLASS = {DIFFUSE: 0, GLOSSY: 1, TRANSMISSION: 2}


def classes(ray_cls) -> np.ndarray:
    """(N,) int64 light-pass class (0 diffuse, 1 glossy, 2 transmission, -1 none) of
    continued rays by their ray class ray_cls (N,) int64 (engine/visibility.py)."""
    ray_cls = np.asarray(ray_cls)
    out = np.full(ray_cls.shape, -1, np.int64)
    for kind, c in _CLASS.items():
        out[ray_cls == kind] = c
    return out


class PathPasses:
    """The camera paths' light-pass state, kept in step with _trace_paths' batch: cls
    (N,) int64, each path's class from its first bent bounce (-1 before it), and bends
    (N,) int64, its bent bounces (the chain's total: integrator's chain[:, 0])."""

    def __init__(self, acc, n):
        self.acc = acc
        self.cls = np.full(n, -1, np.int64)
        self.bends = np.zeros(n, np.int64)

    def take(self, idx):
        """The paths idx (K,) int64 (a compaction or continuation) go on."""
        self.cls = np.take(self.cls, idx)
        self.bends = np.take(self.bends, idx)

    def bend(self, bent, ray_cls):
        """After a continuation: bent (N,) bool the rays turned (not a transparent pass),
        ray_cls (N,) their class; the first bend decides the path's class."""
        new = bent & (self.cls < 0)
        if new.any():
            self.cls = np.where(new, classes(ray_cls), self.cls)
        self.bends = self.bends + bent

    def _add(self, index, pix, rgb, tp, rows):
        """rgb (K,3) into the passes index (K,) int64 (KEYS' positions)."""
        if len(rgb) == 0:
            return
        rows = np.arange(len(rgb), dtype=np.int64) if rows is None else np.asarray(rows, np.int64)
        pix = np.ascontiguousarray(pix, np.int64)
        tp = _NO_TP if tp is None else np.ascontiguousarray(tp, np.float64)
        rgb = np.asarray(rgb, np.float64)
        for k in np.unique(index):
            sel = np.flatnonzero(index == k)
            buf = self.acc.data.get(KEYS[k])
            if buf is None:
                buf = self.acc.data[KEYS[k]] = np.zeros((self.acc.npix, 3))
            film_add(buf, self.acc.lo, pix, np.ascontiguousarray(rows[sel]), tp,
                     np.ascontiguousarray(rgb[sel]))

    def _at(self, rows, n):
        # (A bent path always has a class; max(.., 0) keeps an index in range.)
        if rows is None:
            return np.maximum(self.cls[:n], 0), self.bends[:n]
        return np.maximum(np.take(self.cls, rows), 0), np.take(self.bends, rows)

    def met(self, pix, rgb, tp, rows, source):
        """Light rgb an emitter or the world sends along the paths' rays (before tp):
        source (EMISSION / ENVIRONMENT) for camera rays and transparent continuations,
        Direct of the path's class one bend on, Indirect further."""
        cls, bends = self._at(rows, len(rgb))
        index = np.where(bends == 0, source, np.where(bends == 1, cls, cls + 3))
        self._add(index, pix, rgb, tp, rows)

    def shaded(self, pix, rgb, tp, rows, first):
        """Light rgb arriving at the paths' hits through their lobes (before tp): into
        `first` (a KEYS index) at a path's first bent bounce, else the path's Indirect."""
        cls, bends = self._at(rows, len(rgb))
        index = np.where(bends == 0, first, cls + 3)
        self._add(index, pix, rgb, tp, rows)

    def volume(self, pix, rgb, tp, rows):
        """Light scattered in a medium towards the paths (before tp): VOLUME before the
        first bent bounce, the path's Indirect after it."""
        self.shaded(pix, rgb, tp, rows, VOLUME)


def _translucent(table) -> np.ndarray:
    """(M,) bool: the table's rows with a translucent lobe (MaterialTable.translucent)."""
    share = getattr(table, "translucent", None)
    return np.zeros(len(table.names), bool) if share is None else np.asarray(share) > 0.0


def pass_classes(table, mat, d, ng, ray_cls) -> np.ndarray:
    """The continued rays' classes for the light passes (K,) int64: ray_cls (K,), except
    that a ray through the surface (d (K,3) below the geometric normal ng (K,3)) of a
    material with a translucent lobe and no glass (table rows mat (K,)) is DIFFUSE: the
    translucent lobe's bounce, which Cycles counts among its diffuse closures (measured:
    a sheet lit from behind by a lit floor, Cycles' Diffuse Indirect 1.329, Transmission
    0). A material with both lobes keeps the ray's own class (which lobe sent it is not
    kept)."""
    only = _translucent(table) & ~(np.asarray(table.transmission) > 0.0)
    if not only.any():
        return ray_cls
    mat = np.asarray(mat, np.int64)
    below = np.einsum("ij,ij->i", d, ng) < 0.0
    swap = only[mat] & below & (np.asarray(ray_cls) == TRANSMISSION)
    return np.where(swap, DIFFUSE, ray_cls) if swap.any() else ray_cls


def translucent_share(table, hit, rows) -> np.ndarray:
    """(K,3) the translucent lobe's share of the light the hits rows (K,) int64 take
    through their far side (engine/glasslight.py: the translucent lobe and the rough
    glass refraction together): its albedo over the two lobes' (principled.setup's
    estimates, datapasses.lobe_albedo); 0 without a translucent lobe, 1 without a
    glass one."""
    from .datapasses import lobe_albedo
    rows = np.asarray(rows, np.int64)
    if not _translucent(table).any():  # (rough glass alone: no albedo of the batch)
        return np.zeros((len(rows), 3))
    _, albedo = lobe_albedo(table, hit)
    tl = albedo[rows, pr.L_TRANSL]
    both = tl + albedo[rows, pr.L_GLASS_T]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(both > 0.0, tl / both, 0.0)


def split_direct(direct, glossy, keep=None):
    """(diffuse, glossy) shares of a direct term direct (K,3) whose rough reflective
    lobes' part, before any clamp, is glossy (K,3) (None: none): keep (K,3) the clamped
    direct (None: not clamped) scales the glossy part by the clamp's ratio."""
    if glossy is None:
        return (direct if keep is None else keep), None
    if keep is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(direct != 0.0, keep / direct, 0.0)
        glossy = glossy * ratio
        direct = keep
    return direct - glossy, glossy


def shown(data, volume_bounces=None) -> dict:
    """Blender's light passes from Film.data's raw per-sample averages (key -> (H,W,3)):
    Direct / Indirect divided by their Color pass (safe_divide_even_color, Cycles' read),
    Emission, Environment and the volume light as they are. Keys absent stay absent.
    volume_bounces 0 (Cycles' default Light Paths > Volume bounces): also "volume_direct"
    = the volume light and "volume_indirect" = 0, Cycles' split there (the camera
    segments' single scattering of the lights is Volume Direct; nothing scatters twice).
    None or more bounces: not split (the walks' multiple scattering is not told apart)."""
    out = {}
    for key in KEYS:
        if key not in data:
            continue
        col = DIVIDE.get(key)
        out[key] = (data[key] if col is None else
                    divide_even_color(data[key], data.get(col, np.zeros_like(data[key]))))
    if volume_bounces == 0 and "volume" in data:
        out["volume_direct"] = data["volume"]
        out["volume_indirect"] = np.zeros_like(data["volume"])
    return out


def divide_even_color(a, b):
    """Cycles' safe_divide_even_color (util/math_float3.h) over (..., 3) arrays: a / b by
    channel, 0 where b is 0, then a zero channel of b takes the mean of the other
    channels' ratios (all but one zero: that one's ratio)."""
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    zero = b == 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(zero, np.float32(0.0), a / np.where(zero, np.float32(1.0), b))
    x, y, z = q[..., 0].copy(), q[..., 1].copy(), q[..., 2].copy()
    bx, by, bz = zero[..., 0], zero[..., 1], zero[..., 2]
    half = np.float32(0.5)
    # (The branches of safe_divide_even_color, in its order.)
    m = bx & by
    x[m], y[m] = q[..., 2][m], q[..., 2][m]
    m = bx & ~by & bz
    x[m], z[m] = q[..., 1][m], q[..., 1][m]
    m = bx & ~by & ~bz
    x[m] = half * (q[..., 1][m] + q[..., 2][m])
    m = ~bx & by & bz
    y[m], z[m] = q[..., 0][m], q[..., 0][m]
    m = ~bx & by & ~bz
    y[m] = half * (q[..., 0][m] + q[..., 2][m])
    m = ~bx & ~by & bz
    z[m] = half * (q[..., 0][m] + q[..., 1][m])
    return np.stack([x, y, z], axis=-1)
