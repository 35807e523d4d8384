"""Cryptomatte ID mattes (Psyop's Cryptomatte, as Blender's Cycles and EEVEE write them):
per pixel, the objects, materials or assets its camera samples hit, ranked by coverage, so
a compositor's Cryptomatte node can pull an antialiased matte for any of them.

The layout is Blender's (intern/cycles/kernel/film/cryptomatte_passes.h; blenkernel
cryptomatte.cc): a layer of `levels` ranks (View Layer > Passes > Cryptomatte > Levels,
default 6) is stored in ceil(levels / 2) RGBA passes "CryptoObject00", "CryptoObject01",
..., each holding two ranks as (id, coverage, id, coverage); an id is the MurmurHash3_32
of the name (seed 0) with its float exponent kept off 0 and 255 ("uint32_to_float32"), and
coverage is the fraction of the pixel's samples whose first surface has that id. The
render result's metadata names each layer and lists its manifest (name -> hex hash).

How ours differs from Cycles', on purpose:
- The mattes come from a pass of primary rays of their own (engine/integrator.camera_rays,
  the same pixel filter by importance: every sample weight 1, as Cycles), traced after the
  image; the coverage is exact integer counts per (pixel, id), so it is the same for any
  worker count, adaptive rounds or chunking. Cycles adds samples into its slots as they
  come and lumps ids past the last slot into it; we keep the `levels` most covered ids.
- A sample counts its first surface fully; Cycles splits a Transparent BSDF surface's
  weight by its transparency and lets the rest reach the surface behind.
- Samples per pixel: the render's, capped at MAX_SAMPLES (coverage steps of 1/64 are
  finer than an 8-bit matte's; each is one Embree ray, no shading).

Shapes: ids (K,) float32 by object / material index; the pass arrays (H, W, 4) float32,
rows top-down (the Film's order).
"""
from __future__ import annotations

import json
import math

import numpy as np

# Blender's pass prefixes by kind (RE_PASSNAME_CRYPTOMATTE_OBJECT / _MATERIAL / _ASSET).
KINDS = {"object": "CryptoObject", "material": "CryptoMaterial", "asset": "CryptoAsset"}
MAX_LEVELS = 16      # Blender's limit for Levels (min(16, depth) in Cycles' sync)
MAX_SAMPLES = 64     # samples a pixel for the mattes at most (see above)
CHUNK_RAYS = 1 << 18  # primary rays traced per call (~40 MB of arrays in flight)


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32 (Austin Appleby's reference; Blender's BLI_hash_mm3) of data."""
    c1, c2 = 0xCC9E2D51, 0x1B873593
    h = seed & 0xFFFFFFFF
    n = len(data)
    for i in range(0, n - n % 4, 4):
        k = int.from_bytes(data[i:i + 4], "little")
        k = (k * c1) & 0xFFFFFFFF
        k = ((k << 15) | (k >> 17)) & 0xFFFFFFFF
        k = (k * c2) & 0xFFFFFFFF
        h ^= k
        h = ((h << 13) | (h >> 19)) & 0xFFFFFFFF
        h = (h * 5 + 0xE6546B64) & 0xFFFFFFFF
    tail = data[n - n % 4:]
    if tail:
        k = int.from_bytes(tail, "little")
        k = (k * c1) & 0xFFFFFFFF
        k = ((k << 15) | (k >> 17)) & 0xFFFFFFFF
        k = (k * c2) & 0xFFFFFFFF
        h ^= k
    h ^= n
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & 0xFFFFFFFF
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & 0xFFFFFFFF
    h ^= h >> 16
    return h


def name_hash(name: str) -> int:
    """The Cryptomatte hash of a name (its UTF-8 bytes), as Blender's CryptomatteHash."""
    return murmur3_32(name.encode("utf-8"))


def hash_to_float(h: int) -> float:
    """The id a pass stores for hash h: its bits as a float32 with the exponent clamped to
    1..254 (no denormal, infinity or NaN; Cryptomatte's "uint32_to_float32")."""
    exponent = min(max((h >> 23) & 0xFF, 1), 254)
    bits = (h & 0x807FFFFF) | (exponent << 23)
    return float(np.array([bits], np.uint32).view(np.float32)[0])


def manifest(names) -> str:
    """The layer's manifest: JSON {name: 8-digit hex hash} (Blender's to_manifest)."""
    return json.dumps({n: f"{name_hash(n):08x}" for n in sorted(set(names))},
                      separators=(",", ":"))


def metadata(view_layer: str, kind: str, names) -> dict:
    """The render-result metadata of one layer: {key: value} for the keys Blender's
    compositor reads (cryptomatte/<7 hex of the layer name's hash>/name, hash, conversion,
    manifest; blenkernel cryptomatte.cc, BKE_cryptomatte_store_metadata)."""
    layer = f"{view_layer}.{KINDS[kind]}"
    prefix = f"cryptomatte/{murmur3_32(layer.encode('utf-8')):08x}"[:len("cryptomatte/") + 7]
    return {f"{prefix}/name": layer, f"{prefix}/hash": "MurmurHash3_32",
            f"{prefix}/conversion": "uint32_to_float32", f"{prefix}/manifest": manifest(names)}


def pass_count(levels: int) -> int:
    """RGBA passes a layer of `levels` ranks takes (two ranks a pass)."""
    return (min(max(int(levels), 1), MAX_LEVELS) + 1) // 2


def layer_names(scene, kind: str) -> list[str]:
    """The name each object index (scene.meshes' order, Geometry.object_id) or material
    index (scene.materials' order, Geometry.material) has in a layer of `kind`."""
    if kind == "material":
        return list(scene.materials.keys())
    if kind == "object":
        return [m.cryptomatte_object or m.name for m in scene.meshes]
    return [m.cryptomatte_asset or m.cryptomatte_object or m.name for m in scene.meshes]


def ranked_coverage(pix: np.ndarray, ids: np.ndarray, npix: int, samples: int,
                    ranks: int) -> tuple[np.ndarray, np.ndarray]:
    """The `ranks` most covered ids of each pixel. pix (N,) int64 pixel of each sample (a
    sample that hit nothing is left out), ids (N,) uint32 the hash of what it hit,
    samples: samples a pixel. Returns (id_bits (npix, ranks) uint32, coverage (npix, ranks)
    float32): ranked by coverage, ties by id; empty ranks 0 / 0."""
    id_bits = np.zeros((npix, ranks), np.uint32)
    coverage = np.zeros((npix, ranks), np.float32)
    if len(pix) == 0:
        return id_bits, coverage
    keys = (np.asarray(pix, np.int64) << 32) | np.asarray(ids, np.int64)
    uniq, counts = np.unique(keys, return_counts=True)
    p = uniq >> 32
    h = uniq & 0xFFFFFFFF
    order = np.lexsort((h, -counts, p))
    p, h, counts = p[order], h[order], counts[order]
    first = np.searchsorted(p, p, side="left")
    rank = np.arange(len(p)) - first
    keep = rank < ranks
    id_bits[p[keep], rank[keep]] = h[keep].astype(np.uint32)
    coverage[p[keep], rank[keep]] = counts[keep] / float(samples)
    return id_bits, coverage


def _float_ids(hashes: np.ndarray) -> np.ndarray:
    """hash_to_float on an array of uint32 hashes (the bits of the float32 ids)."""
    h = np.asarray(hashes, np.uint32)
    exponent = np.clip((h >> 23) & 0xFF, 1, 254).astype(np.uint32)
    return ((h & np.uint32(0x807FFFFF)) | (exponent << np.uint32(23))).view(np.float32)


def render_mattes(ctx, region, kinds, levels: int, samples: int, seed: int,
                  should_cancel=None) -> dict:
    """The Cryptomatte passes of `kinds` ("object", "material", "asset") over region
    (x0, y0, x1, y1) of the image: {kind: [(H, W, 4) float32 passes]}, pass_count(levels)
    each. ctx: engine.render.Context (scene, geo, accel, settings); samples a pixel
    min(samples, MAX_SAMPLES), stratified in a randomly permuted grid (seeded by seed).
    Raises engine.parallel.Cancelled when should_cancel() turns True between chunks."""
    from .geometry import CAMERA
    from .integrator import camera_rays
    from .parallel import Cancelled
    from .pixelfilter import filter_table

    kinds = [k for k in KINDS if k in kinds]
    if not kinds:
        return {}
    x0, y0, x1, y1 = region
    w, h = x1 - x0, y1 - y0
    npix = w * h
    spp = max(1, min(int(samples), MAX_SAMPLES))
    m = int(math.ceil(math.sqrt(spp)))
    ranks = 2 * pass_count(levels)
    s = ctx.settings
    table = filter_table(s.pixel_filter, s.filter_width)
    geo = ctx.geo
    hashes = {k: np.array([name_hash(n) for n in layer_names(ctx.scene, k)] or [0], np.uint32)
              for k in kinds}
    rng = np.random.default_rng([int(seed), 0x63727970])  # "cryp": a stream of its own
    chunk = max(1, CHUNK_RAYS // spp)
    bits = {k: np.zeros((npix, ranks), np.uint32) for k in kinds}
    cover = {k: np.zeros((npix, ranks), np.float32) for k in kinds}
    for a in range(0, npix, chunk):
        if should_cancel is not None and should_cancel():
            raise Cancelled()
        b = min(npix, a + chunk)
        local = np.repeat(np.arange(b - a, dtype=np.int64), spp)
        # Each pixel's spp cells of an m x m grid (a random choice of them when spp is
        # not a square), jittered.
        if spp == m * m:
            cells = np.tile(np.arange(spp), b - a)
        else:
            cells = np.argsort(rng.random((b - a, m * m)), axis=1)[:, :spp].reshape(-1)
        jx = (cells % m + rng.random(len(cells))) / m
        jy = (cells // m + rng.random(len(cells))) / m
        px = ((local + a) % w + x0).astype(np.float64)
        py = ((local + a) // w + y0).astype(np.float64)
        # With depth of field the mattes blur as the image does (Cycles' cryptomatte
        # accumulates its lens-sampled camera rays); drawn only then (a pinhole camera's
        # stream is unchanged).
        lens = rng.random((2, len(jx))) if ctx.scene.camera.has_dof else None
        o, d, tmax = camera_rays(ctx.scene.camera, geo.offset, ctx.scene.width,
                                 ctx.scene.height, px, py, jx, jy, table, lens)
        _t, prim, _u, _v = ctx.accel.intersect(o, d, tmax, cls=CAMERA)
        hit = prim >= 0
        rows, (object_id, material) = geo.hit_tables(prim[hit], "object_id", "material")
        for k in kinds:
            index = np.asarray(material if k == "material" else object_id)[rows]
            # Whole pixels per chunk: their ranks are final (memory: one chunk's rays).
            bits[k][a:b], cover[k][a:b] = ranked_coverage(local[hit], hashes[k][index],
                                                          b - a, spp, ranks)
    out = {}
    for k in kinds:
        ids = _float_ids(bits[k])
        ids[cover[k] == 0] = 0.0  # an empty rank: id 0, coverage 0 (Cycles' ID_NONE)
        cov = cover[k]
        out[k] = [np.stack([ids[:, 2 * i], cov[:, 2 * i], ids[:, 2 * i + 1],
                            cov[:, 2 * i + 1]], axis=1).reshape(h, w, 4)
                  for i in range(ranks // 2)]
    return out
