"""Cycles' data passes along the camera paths: Denoising Normal / Albedo / Depth and
Diffuse / Glossy / Transmission Color (RenderSettings.data_passes "denoising", "color").

Extra outputs summed per pixel beside the effect passes and divided by the pixel's
samples (per-sample averages, as Cycles' render buffer): they draw no random number and
change no path, so the image keeps its bits.

Definitions, from Cycles' kernel (intern/cycles/kernel/film/denoising_passes.h,
film_write_denoising_features_surface; kernel/film/data_passes.h, film_write_data_passes;
kernel/integrator/surface_shader.h, surface_shader_diffuse / _glossy / _transmission):

- Denoising features follow a camera path through near-specular surfaces and are written
  at the first surface where the non-specular closures hold more than 25 % of the sample
  weight (a closure is non-specular when its roughness squared alpha^2 exceeds 0.075^2;
  diffuse and sheen always are). There: albedo = feature throughput x the sum of the
  non-specular closures' albedo; normal = the closures' normal (camera space: x right,
  y up, z forward, Cycles' worldtocamera) weighted by sample weight; the path stops
  writing features. At a near-specular surface the feature throughput is multiplied by
  the specular closures' albedo and the path goes on. Denoising Depth adds
  average(feature throughput) x the ray segment's length at every surface the features
  pass (a direct diffuse hit: its distance from the camera).
  Here the feature throughput is the path's own throughput tp (the continued lobe's
  weight / its probability): the same expectation as Cycles' product of specular
  albedos where the surface has specular closures only (mirrors, clear glass, the
  transparent pass); where rough closures share a mostly specular surface it differs
  (Cycles' continuation may take the rough closure, ours never does: docs/compatibility.md).
- Colour passes: at every surface a camera ray meets, directly or through transparent
  passes (our CAMERA ray class), throughput x the albedo of the diffuse closures (diffuse,
  sheen: Cycles counts sheen as diffuse), of the glossy ones (metal, specular layer, coat,
  the glass lobe's reflection) and of the transmission ones (the glass lobe's
  refraction). Albedos are the closures' estimates principled.setup gives (Cycles'
  bsdf_albedo / the closures' sample weights).

- Surface data passes (film_write_data_passes' "single pass" and mist; the film's
  conversion: scene/pass.cpp, kernel/film/get.h): along the camera ray and its
  transparent passes (Cycles' PATH_RAY_TRANSPARENT_BACKGROUND; our CAMERA ray class),
  until the "single pass" is done:
  * Object Index (object.pass_index, an instance's own), Material Index
    (material.pass_index) and Position (world space, m) are written by each pixel's
    first sample only (sample 0, overwriting at every such surface, 0 where it leaves
    for the background) and are not divided by the samples (pass.cpp: use_filter false);
  * UV (the active render UV map: u, v, 1 where a surface has one, else 0, 0, 0:
    kernel/geom/primitive.h primitive_uv) is summed by every sample at the first such
    surface whose alpha reaches the view layer's Alpha Threshold (or any surface with
    threshold 0), which ends the single pass; the film divides by the samples.
  * Mist at every camera-chain surface adds (1 - m) x average(throughput x alpha),
    m = saturate((d - start) / depth) ^ falloff, d the distance from the camera (the
    depth along the view axis for an orthographic camera: camera_distance); the film
    shows saturate(1 - sum / samples) (film_get_pass_pixel_mist): 1 for the background.

- Shader AOVs (RenderSettings.shader_aovs; Cycles' svm_node_aov_color / _value, written
  where svm_node_aov_check passes: the camera ray and its transparent passes until the
  single pass is done, i.e. at every surface of that chain up to and including the one
  that ends it): the material's AOV Output node of that name gives its Color (a colour
  AOV) or Value (a value AOV) at the hit, added unweighted (no throughput), a colour
  AOV's alpha 1 a write (film_write_aov_pass_color's float4); the film divides by the
  samples. A material without that AOV writes nothing (0).

Shapes: pix (N,) int64 pixel rows; tp (N,3) float64 path throughput; t (N,) segment
lengths (m). Passes are stored in Accumulator.data (name -> (P,3) or (P,) float64 sums).
"""
from __future__ import annotations

import numpy as np

from . import aopass, lightpasses, vectorpass
from .camerakernels import film_add, film_add_scalar, hit_closures, view_depth
from .closures import principled as pr

# Blender pass name -> (Accumulator.data key, channels), in the order they are made.
DENOISING = (("Denoising Normal", "denoising_normal", 3),
             ("Denoising Albedo", "denoising_albedo", 3),
             ("Denoising Depth", "denoising_depth", 1))
COLOR = (("Diffuse Color", "diffuse_color", 3),
         ("Glossy Color", "glossy_color", 3),
         ("Transmission Color", "transmission_color", 3))
# One pass each: (Blender 5's pass name, data key, channels); Blender 4 names the two
# index passes IndexOB / IndexMA (addon/engine.py).
SURFACE = {"object_index": (("Object Index", "object_index", 1),),
           "material_index": (("Material Index", "material_index", 1),),
           "position": (("Position", "position", 3),),
           "uv": (("UV", "uv", 3),),
           "mist": (("Mist", "mist", 1),)}
# Cycles' light passes (engine/lightpasses.py: raw sums, divided by colour when shown).
LIGHT = lightpasses.PASSES
# Ambient Occlusion (engine/aopass.py) and Vector (engine/vectorpass.py: two sums, shown
# as one RGBA pass by vectorpass.shown).
AO = (("Ambient Occlusion", aopass.KEY, 3),)
VECTOR = tuple(("Vector", key, 3) for key in vectorpass.KEYS)
PASSES = {"denoising": DENOISING, "color": COLOR, "light": LIGHT, **SURFACE, "ao": AO,
          "vector": VECTOR}
ORDER = ("denoising", "color", "light", "object_index", "material_index", "position", "uv",
         "mist", "ao", "vector")
# Written by each pixel's first sample and kept as written (not per-sample averages).
FIRST_SAMPLE = frozenset(("object_index", "material_index", "position"))

# Cycles' cut between specular-like and diffuse-like closures for the denoising features:
# bsdf_get_specular_roughness_squared(sc) > sqr(0.075f), i.e. GGX alpha > 0.075.
SPECULAR_ALPHA = 0.075
# Lobes (principled.L_*) by colour pass (surface_shader_diffuse / _glossy / _transmission).
DIFFUSE_LOBES = (pr.L_DIFFUSE, pr.L_SHEEN, pr.L_TRANSL)  # (Cycles' diffuse closures)
GLOSSY_LOBES = (pr.L_METAL, pr.L_GLASS_R, pr.L_SPEC, pr.L_COAT)
TRANSMISSION_LOBES = (pr.L_GLASS_T,)
_NO_ROWS = np.zeros(0, np.int64)
_NO_ALPHA = np.zeros(0)
_NO_TP = np.zeros((0, 3))


# Shader AOVs' data keys: AOV_VALUE + name (N,), AOV_COLOR + name (N,3) and its alpha
# AOV_ALPHA + name (N,) (the writes' count: a colour AOV's fourth channel).
AOV_VALUE, AOV_COLOR, AOV_ALPHA = "aov_value:", "aov_color:", "aov_alpha:"


def wanted(settings) -> tuple:
    """What a render's data passes are: RenderSettings.data_passes and, per Shader AOV
    (settings.shader_aovs), its data key (AOV_VALUE / AOV_COLOR + name)."""
    return tuple(settings.data_passes) + tuple(
        (AOV_COLOR if kind == "color" else AOV_VALUE) + name
        for name, kind in getattr(settings, "shader_aovs", ()))


def keys(data_passes) -> list[tuple[str, str, int]]:
    """(Blender name, data key, channels) of the passes `data_passes` (wanted(settings),
    or RenderSettings.data_passes) asks for; a colour AOV brings its alpha key too."""
    out = [p for name in ORDER if name in data_passes for p in PASSES[name]]
    for w in data_passes:
        if w.startswith(AOV_VALUE):
            out.append((w[len(AOV_VALUE):], w, 1))
        elif w.startswith(AOV_COLOR):
            name = w[len(AOV_COLOR):]
            out += [(name, w, 3), (name, AOV_ALPHA + name, 1)]
    return out


def _aov_keys(want) -> list:
    return [w for w in want if w.startswith((AOV_VALUE, AOV_COLOR))]


def surface_wanted(data_passes) -> bool:
    """Some of the surface data passes (SURFACE, Vector) or a Shader AOV is asked for."""
    return (any(name in data_passes for name in SURFACE) or "vector" in data_passes
            or bool(_aov_keys(data_passes)))


def film_value(key, total, inv):
    """A data pass's film value from its sums total ((P,) or (P,3)) over the samples,
    inv = 1 / samples (a number, or (P,) / (P,1) per pixel): per-sample averages;
    FIRST_SAMPLE passes as written; mist as Cycles' film shows it, saturate(1 - mean)."""
    if key in FIRST_SAMPLE:
        return total
    if key == "mist":
        return np.clip(1.0 - total * inv, 0.0, 1.0)
    return total * inv


def add_surface(acc, want, geo, table, hit, prim, u, v, pix, tp, rows, first, done,
                cam_pos, forward, ortho, mist, threshold, pano=False, motion=None):
    """One bounce's camera-chain hits into the Depth pass (acc.depth, always) and the
    surface data passes asked for (module docstring).
    rows (K,) int64: the hits reached by the camera ray or transparent passes only;
    prim, u, v (N,): their triangles and barycentrics; hit.p (N,3) re-centred points
    (world = p + geo.offset); tp (N,3) path throughput; first (N,) bool: the pixel's
    first sample; done (N,) bool: the single pass written; cam_pos (3,) re-centred,
    forward (3,) unit view axis, ortho: orthographic camera; mist: Scene.mist (start m,
    depth m, falloff exponent); threshold: RenderSettings.pass_alpha_threshold; pano: a
    panoramic camera (its Depth is the distance, Cycles' camera_z_depth); motion: the
    Vector pass' vectorpass.VectorMotion (None: no Vector pass).
    Returns done after this bounce (a fresh array where it changed)."""
    if len(rows) == 0:
        return done
    if not surface_wanted(want) and not (first[rows] & ~done[rows]).any():
        return done  # Depth alone, no first sample still writing: most calls
    rows = np.ascontiguousarray(rows, np.int64)
    alpha = (np.take(table.alpha, hit.mat[rows]) if getattr(hit, "alpha", None) is None
             else np.asarray(hit.alpha, np.float64)[rows])
    if "mist" in want:
        rel = hit.p[rows] - cam_pos
        dist = np.abs(rel @ forward) if ortho else np.sqrt(np.einsum("ij,ij->i", rel, rel))
        start, depth, falloff = mist
        inv_depth = 1.0 / depth if depth > 0.0 else 0.0
        m = np.clip((dist - start) * inv_depth, 0.0, 1.0) ** falloff
        w = (1.0 - m) * (tp[rows] * alpha[:, None]).mean(axis=1)
        film_add_scalar(_buf(acc, "mist", 1), acc.lo, np.ascontiguousarray(pix[rows]),
                        np.ascontiguousarray(w))
    pending = ~done[rows]
    if not pending.any():
        return done
    sel = rows[pending]
    aov_keys = _aov_keys(want)
    if aov_keys and getattr(table, "aovs", None) is not None:
        _add_aovs(acc, aov_keys, geo, table, hit.mat, prim, u, v, pix, sel)
    w0 = sel[first[sel]]
    if len(w0):
        b = pix[w0] - acc.lo  # (one first sample a pixel: plain stores overwrite)
        # Cycles' camera_z_depth: along the view axis (its panorama cameras' distance
        # aside), > 0 past the clip start; 0 stays "no surface" (film: inf).
        depth = np.empty(len(w0))
        if pano:
            rel = hit.p[w0] - cam_pos
            depth[:] = np.sqrt(np.einsum("ij,ij->i", rel, rel))
        else:
            view_depth(np.ascontiguousarray(hit.p[w0], np.float64), cam_pos, forward, depth)
        acc.depth[b] = depth
        if "object_index" in want:
            per_object = geo.object_pass_index
            _buf(acc, "object_index", 1)[b] = (
                0.0 if per_object is None
                else np.take(per_object, np.take(geo.object_id, prim[w0])))
        if "material_index" in want:
            _buf(acc, "material_index", 1)[b] = np.take(table.pass_index, hit.mat[w0])
        if "position" in want:
            _buf(acc, "position", 3)[b] = hit.p[w0] + geo.offset
    # Cycles' test: !SD_TRANSPARENT || threshold == 0 || average(alpha) >= threshold.
    ends = (alpha[pending] >= min(threshold, 1.0)) | (threshold == 0.0)
    fin = sel[ends]
    if len(fin):
        if "uv" in want and geo.corner_uvs is not None:
            has = (np.ones(len(fin), bool) if geo.object_has_uvs is None else
                   np.take(geo.object_has_uvs, np.take(geo.object_id, prim[fin])))
            uvw = np.zeros((len(fin), 3))
            uvw[:, :2] = geo.uvs(prim[fin], u[fin], v[fin])
            uvw[:, 2] = 1.0
            uvw[~has] = 0.0
            film_add(_buf(acc, "uv", 3), acc.lo, np.ascontiguousarray(pix, np.int64), fin,
                     _NO_TP, uvw)
        if "vector" in want and motion is not None:
            pre, post = motion.vectors(hit.p[fin] + geo.offset,
                                       np.take(geo.object_id, prim[fin]), prim[fin],
                                       u[fin], v[fin])
            at = np.ascontiguousarray(pix, np.int64)
            for key, vec in zip(vectorpass.KEYS, (pre, post)):
                film_add(_buf(acc, key, 3), acc.lo, at, fin, _NO_TP, vec)
        done = done.copy()
        done[fin] = True
    return done


def _add_aovs(acc, aov_keys, geo, table, mat, prim, u, v, pix, sel):
    """The Shader AOVs (aov_keys: AOV_VALUE / AOV_COLOR + name) the materials of the
    camera-chain hits sel (K,) write (module docstring): each material's AOV Output
    node evaluated at its hits (engine/shadernodes, a colour into a value AOV as its
    luminance), summed into the pixels."""
    from .shadernodes import _eval
    mats = np.asarray(mat)[sel]
    for m in np.unique(mats):
        outputs = table.aovs[int(m)]
        if not outputs:
            continue
        rows = sel[mats == m]
        p, uu, vv = prim[rows], u[rows], v[rows]
        at = np.ascontiguousarray(pix[rows], np.int64)
        for key in aov_keys:
            color = key.startswith(AOV_COLOR)
            name = key[len(AOV_COLOR if color else AOV_VALUE):]
            node = outputs.get(name, {}).get("color" if color else "value")
            if node is None:
                continue
            val = np.nan_to_num(np.asarray(_eval(node, geo, p, uu, vv, 3 if color else 1),
                                           np.float64))
            if color:
                film_add(_buf(acc, key, 3), acc.lo, at, np.arange(len(rows)), _NO_TP,
                         np.ascontiguousarray(val))
                film_add_scalar(_buf(acc, AOV_ALPHA + name, 1), acc.lo, at,
                                np.ones(len(rows)))
            else:
                film_add_scalar(_buf(acc, key, 1), acc.lo, at, np.ascontiguousarray(val))


def add_background(acc, want, pix, rows, first, done):
    """Camera-chain rays rows (K,) that left for the background before the single pass
    was done: their first samples write 0 into Depth (no surface: Cycles' read gives
    1e10), Object / Material Index and Position (Cycles' film_write_data_passes_background),
    over what a transparent surface wrote."""
    sel = rows[first[rows] & ~done[rows]]
    if len(sel) == 0:
        return
    b = pix[sel] - acc.lo
    acc.depth[b] = 0.0
    for key, ch in (("object_index", 1), ("material_index", 1), ("position", 3)):
        if key in want:
            _buf(acc, key, ch)[b] = 0.0


def lobe_albedo(table, hit):
    """(prm (N, N_PACK), albedo (N, N_LOBES, 3)) of the hits, as bsdf.closures computes
    them, in fresh arrays: the hit keeps its own prm (the camera bounce reads it)."""
    n = len(hit.mat)
    per_hit = getattr(hit, "params", None) is not None
    alpha = getattr(hit, "alpha", None)
    alpha = _NO_ALPHA if alpha is None else np.ascontiguousarray(alpha, np.float64)
    prm = np.empty((n, pr.N_PACK))
    albedo = np.empty((n, pr.N_LOBES, 3))
    c = np.ascontiguousarray
    hit_closures(c(hit.ns, np.float64), c(hit.ng, np.float64), c(hit.wo, np.float64),
                 c(hit.mat, np.int32), hit.params if per_hit else table.closure_params,
                 per_hit, c(hit.base, np.float64), c(hit.front, np.bool_),
                 c(table.alpha, np.float64), alpha, prm, albedo, _NO_ALPHA)
    return prm, albedo


def lobe_alpha(prm):
    """(N, N_LOBES) each lobe's GGX alpha (roughness^2); diffuse, sheen, translucent 1, the
    transparent pass 0 (a delta: specular-like, as Cycles' transparent BSDF)."""
    n = prm.shape[0]
    a = np.zeros((n, pr.N_LOBES))
    a[:, pr.L_DIFFUSE] = a[:, pr.L_SHEEN] = a[:, pr.L_TRANSL] = 1.0
    a[:, pr.L_METAL] = prm[:, pr.P_METAL_ALPHA]
    a[:, pr.L_GLASS_R] = a[:, pr.L_GLASS_T] = prm[:, pr.P_GLASS_ALPHA]
    a[:, pr.L_SPEC] = prm[:, pr.P_SPEC_ALPHA]
    a[:, pr.L_COAT] = prm[:, pr.P_COAT_ALPHA]
    return a


def _buf(acc, key, channels):
    buf = acc.data.get(key)
    if buf is None:
        buf = acc.data[key] = np.zeros((acc.npix, 3) if channels == 3 else acc.npix)
    return buf


def add_light(acc, pix, rows, tp, ftp, feat, L):
    """Emission or background radiance L (K,3) met by paths rows (K,) (before tp):
    where the paths still carry denoising features, tp x ftp x L into the albedo
    (Cycles' film_write_emission_or_background_pass: feature throughput x contribution,
    the contribution being path throughput x L x its MIS weight)."""
    if feat is None or len(rows) == 0:
        return
    keep = feat[rows]
    if not keep.any():
        return
    rows = np.ascontiguousarray(rows[keep], np.int64)
    rgb = np.ascontiguousarray(np.asarray(L, np.float64)[keep] * ftp[rows])
    film_add(_buf(acc, "denoising_albedo", 3), acc.lo, np.ascontiguousarray(pix, np.int64),
             rows, np.ascontiguousarray(tp, np.float64), rgb)


def add_hits(acc, want, table, hit, pix, tp, t, feat, ftp, on_camera_chain,
             world_to_camera):
    """One bounce's hits into acc's data passes. want: RenderSettings.data_passes; feat
    (N,) bool: the paths still carrying denoising features (None without "denoising");
    ftp (N,3): their feature throughput, Cycles' product of the specular albedos met
    (None without "denoising"); on_camera_chain (N,) bool: reached by the camera ray or
    transparent passes only; world_to_camera (3,3): rows = the camera's right, up and
    forward axes. Returns (feat, ftp) after this bounce: feat False where the features
    were written, ftp times the specular albedo where they go on.

    Weights, so that the expectation over our lobe choice (tp = the chosen lobe's weight
    / its probability, or a split's weight) is Cycles' over its choice (probability
    sample weight / all): albedo and depth x tp, as Cycles' x feature throughput; the
    normal, which Cycles writes unweighted, x average(tp) / average(ftp). Exact where
    the surfaces passed are specular only."""
    n = len(pix)
    if n == 0:
        return feat, ftp
    rows_c = np.nonzero(on_camera_chain)[0] if "color" in want else _NO_ROWS
    rows_f = np.nonzero(feat)[0] if feat is not None else _NO_ROWS
    if len(rows_c) == 0 and len(rows_f) == 0:
        return feat, ftp
    prm, alb = lobe_albedo(table, hit)
    pix = np.ascontiguousarray(pix, np.int64)
    tp = np.ascontiguousarray(tp, np.float64)
    every_c = len(rows_c) == n  # (the first bounce: every row, no gathers)
    if len(rows_c):
        for (_, key, ch), lobes in zip(COLOR, (DIFFUSE_LOBES, GLOSSY_LOBES,
                                               TRANSMISSION_LOBES)):
            rgb = alb[:, lobes[0]].copy()
            for lobe in lobes[1:]:
                rgb += alb[:, lobe]
            film_add(_buf(acc, key, ch), acc.lo, pix, _NO_ROWS if every_c else rows_c, tp,
                     rgb if every_c else rgb[rows_c])
    if len(rows_f):
        weight = np.abs(alb.sum(axis=2))                  # Cycles' sample_weight (x 3)
        rough = lobe_alpha(prm) > SPECULAR_ALPHA          # diffuse-like lobes
        total = weight.sum(axis=1)
        nonspec = (weight * rough).sum(axis=1)
        depth = tp[rows_f].mean(axis=1) * np.asarray(t, np.float64)[rows_f]
        film_add_scalar(_buf(acc, "denoising_depth", 1), acc.lo,
                        np.ascontiguousarray(pix[rows_f]), np.ascontiguousarray(depth))
        stop = np.zeros(n, bool)
        stop[rows_f] = True
        stop &= (total == 0.0) | (nonspec * 4.0 > total)
        done = np.nonzero(stop)[0]
        if len(done):
            # The closures share the shading normal, turned to the ray's side (hit.ns,
            # as Cycles' sd->N on a back face); with no BSDF closure (an emitter alone)
            # Cycles writes a zero normal.
            w = tp[done].mean(axis=1) / np.maximum(ftp[done].mean(axis=1), 1e-300)
            w[total[done] == 0.0] = 0.0
            nrm = (hit.ns[done] @ world_to_camera.T) * w[:, None]
            film_add(_buf(acc, "denoising_normal", 3), acc.lo,
                     np.ascontiguousarray(pix[done]), _NO_ROWS, np.zeros((0, 3)),
                     np.ascontiguousarray(nrm))
            a, r = alb[done], rough[done]
            diffuse = np.zeros((len(done), 3))
            for lobe in range(pr.N_LOBES):  # (K,8,3) x mask summed lobe by lobe
                diffuse += a[:, lobe] * r[:, lobe, None]
            film_add(_buf(acc, "denoising_albedo", 3), acc.lo, pix, done, tp, diffuse)
            feat = feat.copy()
            feat[done] = False
        go = np.nonzero(feat)[0] if len(done) else rows_f
        if len(go):
            ftp = ftp.copy()
            spec = np.zeros((len(go), 3))
            a, r = alb[go], rough[go]
            for lobe in range(pr.N_LOBES):
                spec += a[:, lobe] * ~r[:, lobe, None]
            ftp[go] *= spec
    return feat, ftp
