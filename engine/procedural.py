"""Blender's procedural textures, evaluated per hit in compiled kernels: Noise, Voronoi,
Wave, White Noise and Gabor.

These must reproduce Cycles' patterns, not just look alike: a marble floor made with a
Noise Texture has to put its veins where Cycles puts them. So the building blocks follow
Cycles' definitions exactly (intern/cycles/util/hash.h, kernel/svm/noise.h,
fractal_noise.h, noisetex.h, voronoi.h):

- hashing: Bob Jenkins' lookup3 final()/mix() on 32-bit words (hash_uint .. hash_uint4);
  floats are hashed through their IEEE-754 single-precision bit patterns;
- Perlin gradient noise in 1-4 D (Ken Perlin's improved noise: quintic fade, the OSL
  gradient sets), scaled to about [-1, 1] by OSL's measured constants and repeated every
  1e5 units (Cycles' guard against float precision loss);
- fractal sums: fBM (optionally normalised to 0..1), multifractal, hybrid multifractal,
  ridged multifractal, heterogeneous terrain; Detail's fractional part blends in one
  more octave;
- the Noise node: coordinates x Scale, domain Distortion by noise at seeded offsets,
  Color = (value, two more noise values at seeded offsets);
- Voronoi (Worley) cells: one feature point per unit cell, jittered by Randomness (a
  signed-integer PCG hash of the cell index in 2-4D, as Cycles since Blender 4.2); F1,
  F2, Smooth F1 (Quilez' smooth minimum), Distance to Edge, N-Sphere Radius; Euclidean,
  Manhattan, Chebychev and Minkowski metrics; fractal octaves as in Cycles;
- the Wave node (svm_wave.h): bands or rings along an axis (or diagonal / spherical),
  Phase Offset, a sine, saw or triangle profile, and Distortion by normalised fBM
  (lacunarity 2) of the same Perlin noise;
- the Gabor node (svm/gabor.h): 8 windowed Gabor kernels per cell at hashed centres with
  hashed signs and turns, summed as a phasor (Value, Phase, Intensity).

Arithmetic is float64 here where Cycles uses float32: the patterns agree except within
rounding distance of cell borders. Every batch kernel takes per-hit input arrays (any
socket may be linked) and writes into caller-owned outputs.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up

MASK = 0xFFFFFFFF

NOISE_TYPES = ("FBM", "MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL",
               "HETERO_TERRAIN")
VORONOI_FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")
VORONOI_METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
WAVE_TYPES = ("BANDS", "RINGS")
WAVE_BANDS_DIRECTIONS = ("X", "Y", "Z", "DIAGONAL")
WAVE_RINGS_DIRECTIONS = ("X", "Y", "Z", "SPHERICAL")
WAVE_PROFILES = ("SIN", "SAW", "TRI")


# ---------------------------------------------------------------- hashing (lookup3)

@kernel
def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & MASK


@kernel
def _final(a, b, c):
    c = (c ^ b) & MASK
    c = (c - _rot(b, 14)) & MASK
    a = (a ^ c) & MASK
    a = (a - _rot(c, 11)) & MASK
    b = (b ^ a) & MASK
    b = (b - _rot(a, 25)) & MASK
    c = (c ^ b) & MASK
    c = (c - _rot(b, 16)) & MASK
    a = (a ^ c) & MASK
    a = (a - _rot(c, 4)) & MASK
    b = (b ^ a) & MASK
    b = (b - _rot(a, 14)) & MASK
    c = (c ^ b) & MASK
    c = (c - _rot(b, 24)) & MASK
    return c


@kernel
def _mix(a, b, c):
    a = (a - c) & MASK
    a ^= _rot(c, 4)
    c = (c + b) & MASK
    b = (b - a) & MASK
    b ^= _rot(a, 6)
    a = (a + c) & MASK
    c = (c - b) & MASK
    c ^= _rot(b, 8)
    b = (b + a) & MASK
    a = (a - c) & MASK
    a ^= _rot(c, 16)
    c = (c + b) & MASK
    b = (b - a) & MASK
    b ^= _rot(a, 19)
    a = (a + c) & MASK
    c = (c - b) & MASK
    c ^= _rot(b, 4)
    b = (b + a) & MASK
    return a, b, c


@kernel
def hash_uint(dims, k0, k1, k2, k3):
    """lookup3 hash of dims (1-4) 32-bit words (ints; negatives as two's complement)."""
    init = (0xDEADBEEF + (dims << 2) + 13) & MASK
    a = init
    b = init
    c = init
    if dims == 1:
        a = (a + (k0 & MASK)) & MASK
    elif dims == 2:
        b = (b + (k1 & MASK)) & MASK
        a = (a + (k0 & MASK)) & MASK
    elif dims == 3:
        c = (c + (k2 & MASK)) & MASK
        b = (b + (k1 & MASK)) & MASK
        a = (a + (k0 & MASK)) & MASK
    else:
        a = (a + (k0 & MASK)) & MASK
        b = (b + (k1 & MASK)) & MASK
        c = (c + (k2 & MASK)) & MASK
        a, b, c = _mix(a, b, c)
        a = (a + (k3 & MASK)) & MASK
    return _final(a, b, c)


@kernel
def float_bits(x):
    """IEEE-754 single-precision bit pattern of x (rounded to float32), as an int."""
    f = np.float32(x)
    if f == 0.0:
        return 0x80000000 if math.copysign(1.0, f) < 0 else 0
    sign = 0x80000000 if f < 0 else 0
    m, e = math.frexp(abs(float(f)))  # |f| = m 2^e, 0.5 <= m < 1
    exponent = e - 1 + 127
    if exponent <= 0:  # subnormal: the hashes only ever see cell indices and seeds
        return sign
    mantissa = int(round((m * 2.0 - 1.0) * 8388608.0))
    return sign | (exponent << 23) | mantissa


@kernel
def hash_float(dims, x0, x1, x2, x3):
    """Cycles' hash_floatN_to_float: [0, 1] from the bit patterns of dims floats."""
    h = hash_uint(dims, float_bits(x0), float_bits(x1), float_bits(x2), float_bits(x3))
    return h / 4294967295.0


@kernel
def _i32(x):
    """x wrapped to a signed 32-bit integer (C's int overflow on two's complement)."""
    return ((x + 0x80000000) & MASK) - 0x80000000


@kernel
def hash_pcg(dims, k0, k1, k2, k3):
    """Cycles' signed-integer PCG hash of dims (2-4) ints (hash_pcgNd_i: Jarzynski and
    Olano, "Hash Functions for GPU Rendering", JCGT 2020, made signed so OSL can run it):
    dims non-negative 31-bit ints, as a 4-tuple (unused entries 0)."""
    v0 = _i32(_i32(k0) * 1664525 + 1013904223)
    v1 = _i32(_i32(k1) * 1664525 + 1013904223)
    v2 = _i32(_i32(k2) * 1664525 + 1013904223)
    v3 = _i32(_i32(k3) * 1664525 + 1013904223)
    for rnd in range(2):
        if dims == 2:
            v0 = _i32(v0 + v1 * 1664525)
            v1 = _i32(v1 + v0 * 1664525)
        elif dims == 3:
            v0 = _i32(v0 + v1 * v2)
            v1 = _i32(v1 + v2 * v0)
            v2 = _i32(v2 + v0 * v1)
        else:
            v0 = _i32(v0 + v1 * v3)
            v1 = _i32(v1 + v2 * v0)
            v2 = _i32(v2 + v0 * v1)
            v3 = _i32(v3 + v1 * v2)
        if rnd == 0:  # arithmetic shift, as on C's signed int
            v0 = _i32(v0 ^ (v0 >> 16))
            v1 = _i32(v1 ^ (v1 >> 16))
            v2 = _i32(v2 ^ (v2 >> 16))
            v3 = _i32(v3 ^ (v3 >> 16))
    return v0 & 0x7FFFFFFF, v1 & 0x7FFFFFFF, v2 & 0x7FFFFFFF, v3 & 0x7FFFFFFF


# float(0x7FFFFFFF) rounds to 2^31 in single precision: Cycles divides by that.
PCG_SCALE = 1.0 / 2147483648.0


@kernel
def hash_cell(dims, x0, x1, x2, x3):
    """A Voronoi cell's jitter in [0, 1]^dims, from its integer index x (held in floats):
    1D hashes the float's bits (hash_float_to_float), 2-4D the ints (hash_intN_to_floatN,
    Cycles since Blender 4.2 — OSL has no bit casts)."""
    if dims == 1:
        return hash_float(1, x0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0
    h0, h1, h2, h3 = hash_pcg(dims, int(x0), int(x1), int(x2), int(x3))
    # Unused components are exactly 0, so they add nothing to any distance.
    return (h0 * PCG_SCALE, h1 * PCG_SCALE, h2 * PCG_SCALE if dims > 2 else 0.0,
            h3 * PCG_SCALE if dims > 3 else 0.0)


@kernel
def hash_color(dims, x0, x1, x2, x3):
    """A Voronoi cell's colour in [0, 1]^3 (hash_float_to_float3 in 1D, else
    hash_intN_to_float3: 2D hashes (x, y, 0) in 3D, 4D keeps xyz of its hash)."""
    if dims == 1:
        return (hash_float(1, x0, 0.0, 0.0, 0.0), hash_float(2, x0, 1.0, 0.0, 0.0),
                hash_float(2, x0, 2.0, 0.0, 0.0))
    if dims == 2:
        h0, h1, h2, _ = hash_pcg(3, int(x0), int(x1), 0, 0)
    else:
        h0, h1, h2, _ = hash_pcg(dims, int(x0), int(x1), int(x2), int(x3))
    return h0 * PCG_SCALE, h1 * PCG_SCALE, h2 * PCG_SCALE


# ---------------------------------------------------------------- Perlin noise

@kernel
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@kernel
def _grad(dims, h, x, y, z, w):
    """OSL's gradient dot products (noise.h grad1..grad4)."""
    if dims == 1:
        h &= 15
        g = 1.0 + (h & 7)
        return (-g if h & 8 else g) * x
    if dims == 2:
        h &= 7
        u = x if h < 4 else y
        v = 2.0 * (y if h < 4 else x)
        return (-u if h & 1 else u) + (-v if h & 2 else v)
    if dims == 3:
        h &= 15
        u = x if h < 8 else y
        vt = x if (h == 12 or h == 14) else z
        v = y if h < 4 else vt
        return (-u if h & 1 else u) + (-v if h & 2 else v)
    h &= 31
    u = x if h < 24 else y
    v = y if h < 16 else z
    s = z if h < 8 else w
    return (-u if h & 1 else u) + (-v if h & 2 else v) + (-s if h & 4 else s)


@kernel
def perlin(dims, x, y, z, w):
    """Unscaled Perlin noise in dims (1-4) dimensions at (x, y, z, w): the multilinear
    blend, with quintic fade weights, of the 2^dims corner gradients."""
    fx = math.floor(x)
    fy = math.floor(y) if dims > 1 else 0.0
    fz = math.floor(z) if dims > 2 else 0.0
    fw = math.floor(w) if dims > 3 else 0.0
    X, Y, Z, W = int(fx), int(fy), int(fz), int(fw)
    rx, ry, rz, rw = x - fx, y - fy, z - fz, w - fw
    ux, uy, uz, uw = _fade(rx), _fade(ry), _fade(rz), _fade(rw)
    total = 0.0
    for c in range(1 << dims):
        bx, by, bz, bw = c & 1, (c >> 1) & 1, (c >> 2) & 1, (c >> 3) & 1
        weight = ux if bx else 1.0 - ux
        if dims > 1:
            weight *= uy if by else 1.0 - uy
        if dims > 2:
            weight *= uz if bz else 1.0 - uz
        if dims > 3:
            weight *= uw if bw else 1.0 - uw
        h = hash_uint(dims, X + bx, Y + by, Z + bz, W + bw)
        total += weight * _grad(dims, h, rx - bx, ry - by, rz - bz, rw - bw)
    return total


@kernel
def _wrap(p):
    # Cycles repeats the noise every 1e5 units (fmod keeps the sign) and shifts huge
    # coordinates by half a cell so they do not all land on lattice points.
    corr = 0.5 if abs(p) >= 1000000.0 else 0.0
    return np.fmod(p, 100000.0) + corr


@kernel
def snoise(dims, x, y, z, w):
    """Signed noise, about [-1, 1] (Cycles snoise_Nd)."""
    v = perlin(dims, _wrap(x), _wrap(y), _wrap(z), _wrap(w))
    if dims == 1:
        return 0.25 * v
    if dims == 2:
        return 0.6616 * v
    if dims == 3:
        return 0.9820 * v
    return 0.8344 * v


@kernel
def fractal(dims, kind, x, y, z, w, detail, roughness, lacunarity, offset, gain, normalize):
    """The Noise node's fractal of type `kind` (index into NOISE_TYPES) at (x, y, z, w)."""
    octaves = int(detail)
    rmd = detail - math.floor(detail)
    if kind == 0:  # fBM
        fscale = 1.0
        amp = 1.0
        maxamp = 0.0
        total = 0.0
        for _ in range(octaves + 1):
            t = snoise(dims, fscale * x, fscale * y, fscale * z, fscale * w)
            total += t * amp
            maxamp += amp
            amp *= roughness
            fscale *= lacunarity
        if rmd != 0.0:
            t = snoise(dims, fscale * x, fscale * y, fscale * z, fscale * w)
            sum2 = total + t * amp
            if normalize:
                a = 0.5 * total / maxamp + 0.5
                b = 0.5 * sum2 / (maxamp + amp) + 0.5
                return a * (1.0 - rmd) + b * rmd
            return total * (1.0 - rmd) + sum2 * rmd
        return 0.5 * total / maxamp + 0.5 if normalize else total
    if kind == 1:  # multifractal
        value = 1.0
        pwr = 1.0
        for _ in range(octaves + 1):
            value *= pwr * snoise(dims, x, y, z, w) + 1.0
            pwr *= roughness
            x *= lacunarity; y *= lacunarity; z *= lacunarity; w *= lacunarity
        if rmd != 0.0:
            value *= rmd * pwr * snoise(dims, x, y, z, w) + 1.0
        return value
    if kind == 2:  # hybrid multifractal
        pwr = 1.0
        value = 0.0
        weight = 1.0
        i = 0
        while weight > 0.001 and i <= octaves:
            weight = min(weight, 1.0)
            signal = (snoise(dims, x, y, z, w) + offset) * pwr
            pwr *= roughness
            value += weight * signal
            weight *= gain * signal
            x *= lacunarity; y *= lacunarity; z *= lacunarity; w *= lacunarity
            i += 1
        if rmd != 0.0 and weight > 0.001:
            weight = min(weight, 1.0)
            signal = (snoise(dims, x, y, z, w) + offset) * pwr
            value += rmd * weight * signal
        return value
    if kind == 3:  # ridged multifractal
        pwr = roughness
        signal = offset - abs(snoise(dims, x, y, z, w))
        signal *= signal
        value = signal
        for _ in range(1, octaves + 1):
            x *= lacunarity; y *= lacunarity; z *= lacunarity; w *= lacunarity
            weight = min(max(signal * gain, 0.0), 1.0)
            signal = offset - abs(snoise(dims, x, y, z, w))
            signal *= signal
            signal *= weight
            value += signal * pwr
            pwr *= roughness
        return value
    # heterogeneous terrain
    pwr = roughness
    value = offset + snoise(dims, x, y, z, w)
    x *= lacunarity; y *= lacunarity; z *= lacunarity; w *= lacunarity
    for _ in range(1, octaves + 1):
        value += (snoise(dims, x, y, z, w) + offset) * pwr * value
        pwr *= roughness
        x *= lacunarity; y *= lacunarity; z *= lacunarity; w *= lacunarity
    if rmd != 0.0:
        value += rmd * (snoise(dims, x, y, z, w) + offset) * pwr * value
    return value


def noise_offsets(dims: int) -> np.ndarray:
    """(6, 4) seeded coordinate offsets of the Noise node (noisetex.h
    random_floatN_offset(seed) for seeds 0..5): components in [100, 200]."""
    out = np.zeros((6, 4))
    for seed in range(6):
        if dims == 1:
            out[seed, 0] = 100.0 + hash_float(1, float(seed), 0.0, 0.0, 0.0) * 100.0
        else:
            for j in range(dims):
                out[seed, j] = 100.0 + hash_float(2, float(seed), float(j), 0.0, 0.0) * 100.0
    return out


@kernel
def noise_texture(dims, kind, normalize, points, scale, w_in, detail, roughness,
                  lacunarity, offset, gain, distortion, offsets, want_color,
                  value_out, color_out):
    """The Noise Texture node for a batch of hits.

    points (N,3) texture coordinates; scale, w_in, detail, roughness, lacunarity, offset,
    gain, distortion (N,) socket values per hit; offsets (6,4) from noise_offsets(dims).
    Writes value_out (N,) (the Fac output) and, if want_color, color_out (N,3)."""
    for i in range(points.shape[0]):
        s = scale[i]
        x = points[i, 0] * s
        y = points[i, 1] * s
        z = points[i, 2] * s
        w = w_in[i] * s
        if dims == 1:  # the 1D node reads W only
            x = w
        d = min(max(detail[i], 0.0), 15.0)
        r = max(roughness[i], 0.0)
        lac = lacunarity[i]
        dist = distortion[i]
        q = (x, y, z, w) if dims == 4 else (x, y, z, 0.0)
        if dist != 0.0:
            n0 = snoise(dims, q[0] + offsets[0, 0], q[1] + offsets[0, 1],
                        q[2] + offsets[0, 2], q[3] + offsets[0, 3]) * dist
            n1 = 0.0
            n2 = 0.0
            n3 = 0.0
            if dims > 1:
                n1 = snoise(dims, q[0] + offsets[1, 0], q[1] + offsets[1, 1],
                            q[2] + offsets[1, 2], q[3] + offsets[1, 3]) * dist
            if dims > 2:
                n2 = snoise(dims, q[0] + offsets[2, 0], q[1] + offsets[2, 1],
                            q[2] + offsets[2, 2], q[3] + offsets[2, 3]) * dist
            if dims > 3:
                n3 = snoise(dims, q[0] + offsets[3, 0], q[1] + offsets[3, 1],
                            q[2] + offsets[3, 2], q[3] + offsets[3, 3]) * dist
            q = (q[0] + n0, q[1] + n1, q[2] + n2, q[3] + n3)
        value = fractal(dims, kind, q[0], q[1], q[2], q[3], d, r, lac, offset[i], gain[i],
                        normalize)
        value_out[i] = value
        if want_color:
            # Seeds after the distortion ones: 1, 2 (1D); 2, 3 (2D); 3, 4 (3D); 4, 5 (4D).
            sa = dims
            sb = dims + 1
            color_out[i, 0] = value
            color_out[i, 1] = fractal(dims, kind, q[0] + offsets[sa, 0], q[1] + offsets[sa, 1],
                                      q[2] + offsets[sa, 2], q[3] + offsets[sa, 3], d, r, lac,
                                      offset[i], gain[i], normalize)
            color_out[i, 2] = fractal(dims, kind, q[0] + offsets[sb, 0], q[1] + offsets[sb, 1],
                                      q[2] + offsets[sb, 2], q[3] + offsets[sb, 3], d, r, lac,
                                      offset[i], gain[i], normalize)


# ---------------------------------------------------------------- Voronoi

@kernel
def _metric_distance(dims, metric, exponent, a0, a1, a2, a3):
    """Length of the difference vector a under the metric (index into VORONOI_METRICS);
    1D cells always use |a| (Cycles)."""
    if dims == 1:
        return abs(a0)
    if metric == 0:
        return math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
    if metric == 1:
        return abs(a0) + abs(a1) + abs(a2) + abs(a3)
    if metric == 2:
        return max(max(abs(a0), abs(a1)), max(abs(a2), abs(a3)))
    total = abs(a0) ** exponent + abs(a1) ** exponent
    if dims > 2:
        total += abs(a2) ** exponent
    if dims > 3:
        total += abs(a3) ** exponent
    return total ** (1.0 / exponent)


@kernel
def _cells(dims, radius):
    return (2 * radius + 1) ** dims


@kernel
def _cell_offset(dims, idx, radius):
    """The idx-th cell offset of the (2 radius + 1)^dims window, x fastest."""
    span = 2 * radius + 1
    o0 = float(idx % span - radius)
    o1 = float((idx // span) % span - radius) if dims > 1 else 0.0
    o2 = float((idx // (span * span)) % span - radius) if dims > 2 else 0.0
    o3 = float((idx // (span * span * span)) % span - radius) if dims > 3 else 0.0
    return o0, o1, o2, o3


@kernel
def _local(dims, l0, l1, l2, l3):
    """A point's position in its cell, unused dimensions 0."""
    return (l0, l1 if dims > 1 else 0.0, l2 if dims > 2 else 0.0, l3 if dims > 3 else 0.0)


@kernel
def _smoothstep(x):
    if x < 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return (3.0 - 2.0 * x) * x * x


@kernel
def voronoi_octave(dims, feature, metric, exponent, randomness, smoothness,
                   x0, x1, x2, x3):
    """One Voronoi octave (F1, F2 or Smooth F1) at (x0..x3): returns
    (distance, r, g, b, p0, p1, p2, p3) with p the feature point's position."""
    c0 = math.floor(x0)
    c1 = math.floor(x1) if dims > 1 else 0.0
    c2 = math.floor(x2) if dims > 2 else 0.0
    c3 = math.floor(x3) if dims > 3 else 0.0
    l0, l1, l2, l3 = _local(dims, x0 - c0, x1 - c1, x2 - c2, x3 - c3)
    if feature == 2:  # smooth F1 over a 5^dims window
        sd = 0.0
        sr = 0.0; sg = 0.0; sb = 0.0
        s0 = 0.0; s1 = 0.0; s2 = 0.0; s3 = 0.0
        h = -1.0
        for idx in range(_cells(dims, 2)):
            o0, o1, o2, o3 = _cell_offset(dims, idx, 2)
            j0, j1, j2, j3 = hash_cell(dims, c0 + o0, c1 + o1, c2 + o2, c3 + o3)
            p0 = o0 + j0 * randomness
            p1 = o1 + j1 * randomness
            p2 = o2 + j2 * randomness
            p3 = o3 + j3 * randomness
            d = _metric_distance(dims, metric, exponent, p0 - l0, p1 - l1, p2 - l2, p3 - l3)
            if h == -1.0:
                h = 1.0
            else:
                h = _smoothstep(0.5 + 0.5 * (sd - d) / smoothness)
            corr = smoothness * h * (1.0 - h)
            sd = sd * (1.0 - h) + d * h - corr
            corr /= 1.0 + 3.0 * smoothness
            r, g, b = hash_color(dims, c0 + o0, c1 + o1, c2 + o2, c3 + o3)
            sr = sr * (1.0 - h) + r * h - corr
            sg = sg * (1.0 - h) + g * h - corr
            sb = sb * (1.0 - h) + b * h - corr
            s0 = s0 * (1.0 - h) + p0 * h - corr
            s1 = s1 * (1.0 - h) + p1 * h - corr
            s2 = s2 * (1.0 - h) + p2 * h - corr
            s3 = s3 * (1.0 - h) + p3 * h - corr
        return sd, sr, sg, sb, c0 + s0, c1 + s1, c2 + s2, c3 + s3
    d1 = 3.4e38
    d2 = 3.4e38
    t1 = (0.0, 0.0, 0.0, 0.0)
    t2 = (0.0, 0.0, 0.0, 0.0)
    q1 = (0.0, 0.0, 0.0, 0.0)
    q2 = (0.0, 0.0, 0.0, 0.0)
    for idx in range(_cells(dims, 1)):
        o = _cell_offset(dims, idx, 1)
        j0, j1, j2, j3 = hash_cell(dims, c0 + o[0], c1 + o[1], c2 + o[2], c3 + o[3])
        p = (o[0] + j0 * randomness, o[1] + j1 * randomness, o[2] + j2 * randomness,
             o[3] + j3 * randomness)
        d = _metric_distance(dims, metric, exponent, p[0] - l0, p[1] - l1, p[2] - l2,
                             p[3] - l3)
        if d < d1:
            d2 = d1
            t2 = t1
            q2 = q1
            d1 = d
            t1 = o
            q1 = p
        elif d < d2:
            d2 = d
            t2 = o
            q2 = p
    if feature == 1:
        d1 = d2
        t1 = t2
        q1 = q2
    r, g, b = hash_color(dims, c0 + t1[0], c1 + t1[1], c2 + t1[2], c3 + t1[3])
    return d1, r, g, b, c0 + q1[0], c1 + q1[1], c2 + q1[2], c3 + q1[3]


@kernel
def voronoi_edge_distance(dims, randomness, x0, x1, x2, x3):
    """Distance to the nearest cell border (Cycles voronoi_distance_to_edge, Euclidean)."""
    c0 = math.floor(x0)
    c1 = math.floor(x1) if dims > 1 else 0.0
    c2 = math.floor(x2) if dims > 2 else 0.0
    c3 = math.floor(x3) if dims > 3 else 0.0
    l0, l1, l2, l3 = _local(dims, x0 - c0, x1 - c1, x2 - c2, x3 - c3)
    if dims == 1:
        mid = hash_float(1, c0, 0.0, 0.0, 0.0) * randomness
        left = -1.0 + hash_float(1, c0 - 1.0, 0.0, 0.0, 0.0) * randomness
        right = 1.0 + hash_float(1, c0 + 1.0, 0.0, 0.0, 0.0) * randomness
        return min(abs((mid + left) / 2.0 - l0), abs((mid + right) / 2.0 - l0))
    best = 3.4e38
    v = (0.0, 0.0, 0.0, 0.0)
    for idx in range(_cells(dims, 1)):
        o = _cell_offset(dims, idx, 1)
        j0, j1, j2, j3 = hash_cell(dims, c0 + o[0], c1 + o[1], c2 + o[2], c3 + o[3])
        t = (o[0] + j0 * randomness - l0, o[1] + j1 * randomness - l1,
             o[2] + j2 * randomness - l2, o[3] + j3 * randomness - l3)
        d = t[0] * t[0] + t[1] * t[1] + t[2] * t[2] + t[3] * t[3]
        if d < best:
            best = d
            v = t
    best = 3.4e38
    for idx in range(_cells(dims, 1)):
        o = _cell_offset(dims, idx, 1)
        j0, j1, j2, j3 = hash_cell(dims, c0 + o[0], c1 + o[1], c2 + o[2], c3 + o[3])
        t0 = o[0] + j0 * randomness - l0
        t1 = o[1] + j1 * randomness - l1
        t2 = o[2] + j2 * randomness - l2
        t3 = o[3] + j3 * randomness - l3
        e0, e1, e2, e3 = t0 - v[0], t1 - v[1], t2 - v[2], t3 - v[3]
        ee = e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3
        if ee > 0.0001:
            inv = 1.0 / math.sqrt(ee)
            dd = ((v[0] + t0) * e0 + (v[1] + t1) * e1 + (v[2] + t2) * e2
                  + (v[3] + t3) * e3) * 0.5 * inv
            best = min(best, dd)
    return best


@kernel
def voronoi_sphere_radius(dims, randomness, x0, x1, x2, x3):
    """Half the distance from the nearest feature point to its own nearest neighbour
    (Cycles voronoi_n_sphere_radius, Euclidean)."""
    c0 = math.floor(x0)
    c1 = math.floor(x1) if dims > 1 else 0.0
    c2 = math.floor(x2) if dims > 2 else 0.0
    c3 = math.floor(x3) if dims > 3 else 0.0
    l0, l1, l2, l3 = _local(dims, x0 - c0, x1 - c1, x2 - c2, x3 - c3)
    best = 3.4e38
    cp = (0.0, 0.0, 0.0, 0.0)
    co = (0.0, 0.0, 0.0, 0.0)
    for idx in range(_cells(dims, 1)):
        o = _cell_offset(dims, idx, 1)
        j0, j1, j2, j3 = hash_cell(dims, c0 + o[0], c1 + o[1], c2 + o[2], c3 + o[3])
        p = (o[0] + j0 * randomness, o[1] + j1 * randomness, o[2] + j2 * randomness,
             o[3] + j3 * randomness)
        d = _metric_distance(dims, 0, 1.0, p[0] - l0, p[1] - l1, p[2] - l2, p[3] - l3)
        if d < best:
            best = d
            cp = p
            co = o
    best = 3.4e38
    nn = (0.0, 0.0, 0.0, 0.0)
    for idx in range(_cells(dims, 1)):
        o = _cell_offset(dims, idx, 1)
        if o[0] == 0.0 and o[1] == 0.0 and o[2] == 0.0 and o[3] == 0.0:
            continue
        o = (o[0] + co[0], o[1] + co[1], o[2] + co[2], o[3] + co[3])
        j0, j1, j2, j3 = hash_cell(dims, c0 + o[0], c1 + o[1], c2 + o[2], c3 + o[3])
        p = (o[0] + j0 * randomness, o[1] + j1 * randomness, o[2] + j2 * randomness,
             o[3] + j3 * randomness)
        d = _metric_distance(dims, 0, 1.0, cp[0] - p[0], cp[1] - p[1], cp[2] - p[2],
                             cp[3] - p[3])
        if d < best:
            best = d
            nn = p
    return _metric_distance(dims, 0, 1.0, nn[0] - cp[0], nn[1] - cp[1], nn[2] - cp[2],
                            nn[3] - cp[3]) / 2.0


@kernel
def _max_distance(dims, feature, metric, exponent, randomness):
    # Cycles' normalisation constant: the metric length of (0.5 + 0.5 randomness)^dims,
    # doubled for F2.
    a = 0.5 + 0.5 * randomness
    if dims == 1:
        d = a
    else:
        d = _metric_distance(dims, metric, exponent, a, a if dims > 1 else 0.0,
                             a if dims > 2 else 0.0, a if dims > 3 else 0.0)
    return d * (2.0 if feature == 1 else 1.0)


@kernel
def voronoi_texture(dims, feature, metric, normalize, points, w_in, scale, detail,
                    roughness, lacunarity, smoothness, exponent, randomness,
                    distance_out, color_out, position_out, w_out, radius_out):
    """The Voronoi Texture node for a batch of hits.

    points (N,3) texture coordinates; w_in, scale, detail, roughness, lacunarity,
    smoothness, exponent, randomness (N,) socket values per hit. Writes distance_out (N,),
    color_out (N,3), position_out (N,3), w_out (N,), radius_out (N,)."""
    for i in range(points.shape[0]):
        s = scale[i]
        d = min(max(detail[i], 0.0), 15.0)
        rough = min(max(roughness[i], 0.0), 1.0)
        lac = lacunarity[i]
        rnd = min(max(randomness[i], 0.0), 1.0)
        smooth = min(max(smoothness[i] / 2.0, 0.0), 0.5)
        ex = exponent[i]
        x0 = points[i, 0] * s
        x1 = points[i, 1] * s
        x2 = points[i, 2] * s
        x3 = w_in[i] * s
        if dims == 1:
            x0 = x3
        if feature == 4:
            radius_out[i] = voronoi_sphere_radius(dims, rnd, x0, x1, x2, x3)
            continue
        zero_input = d == 0.0 or rough == 0.0
        if feature == 3:
            maxd = 0.5 + 0.5 * rnd
            amp = 1.0
            max_amp = maxd
            sc = 1.0
            dist = 8.0
            for octave in range(int(math.ceil(d)) + 1):
                od = voronoi_edge_distance(dims, rnd, x0 * sc, x1 * sc, x2 * sc, x3 * sc)
                if zero_input:
                    dist = od
                    break
                if octave <= d:
                    max_amp = max_amp * (1.0 - amp) + (maxd / sc) * amp
                    dist = dist * (1.0 - amp) + min(dist, od / sc) * amp
                    sc *= lac
                    amp *= rough
                else:
                    rem = d - math.floor(d)
                    if rem != 0.0:
                        la = max_amp * (1.0 - amp) + (maxd / sc) * amp
                        max_amp = max_amp * (1.0 - rem) + la * rem
                        ld = dist * (1.0 - amp) + min(dist, od / sc) * amp
                        dist = dist * (1.0 - rem) + min(dist, ld) * rem
            distance_out[i] = dist / max_amp if normalize else dist
            continue
        feat = 0 if (feature == 2 and smooth == 0.0) else feature
        amp = 1.0
        max_amp = 0.0
        sc = 1.0
        od = 0.0
        r = 0.0; g = 0.0; b = 0.0
        p0 = 0.0; p1 = 0.0; p2 = 0.0; p3 = 0.0
        for octave in range(int(math.ceil(d)) + 1):
            (vd, vr, vg, vb, v0, v1, v2, v3) = voronoi_octave(
                dims, feat, metric, ex, rnd, smooth, x0 * sc, x1 * sc, x2 * sc, x3 * sc)
            if zero_input:
                max_amp = 1.0
                od, r, g, b, p0, p1, p2, p3 = vd, vr, vg, vb, v0, v1, v2, v3
                break
            if octave <= d:
                max_amp += amp
                od += vd * amp
                r += vr * amp; g += vg * amp; b += vb * amp
                p0 = p0 * (1.0 - amp) + (v0 / sc) * amp
                p1 = p1 * (1.0 - amp) + (v1 / sc) * amp
                p2 = p2 * (1.0 - amp) + (v2 / sc) * amp
                p3 = p3 * (1.0 - amp) + (v3 / sc) * amp
                sc *= lac
                amp *= rough
            else:
                rem = d - math.floor(d)
                if rem != 0.0:
                    max_amp = max_amp * (1.0 - rem) + (max_amp + amp) * rem
                    od = od * (1.0 - rem) + (od + vd * amp) * rem
                    r = r * (1.0 - rem) + (r + vr * amp) * rem
                    g = g * (1.0 - rem) + (g + vg * amp) * rem
                    b = b * (1.0 - rem) + (b + vb * amp) * rem
                    p0 = p0 * (1.0 - rem) + (p0 * (1.0 - amp) + (v0 / sc) * amp) * rem
                    p1 = p1 * (1.0 - rem) + (p1 * (1.0 - amp) + (v1 / sc) * amp) * rem
                    p2 = p2 * (1.0 - rem) + (p2 * (1.0 - amp) + (v2 / sc) * amp) * rem
                    p3 = p3 * (1.0 - rem) + (p3 * (1.0 - amp) + (v3 / sc) * amp) * rem
        if normalize:
            od /= max_amp * _max_distance(dims, feat, metric, ex, rnd)
            r /= max_amp; g /= max_amp; b /= max_amp
        distance_out[i] = od
        color_out[i, 0] = r
        color_out[i, 1] = g
        color_out[i, 2] = b
        inv = 1.0 / s if s != 0.0 else 0.0
        if dims == 1:  # the 1D position is W only
            position_out[i, 0] = 0.0
            position_out[i, 1] = 0.0
            position_out[i, 2] = 0.0
            w_out[i] = p0 * inv
        else:
            position_out[i, 0] = p0 * inv
            position_out[i, 1] = p1 * inv
            position_out[i, 2] = p2 * inv
            w_out[i] = p3 * inv if dims == 4 else 0.0


# ---------------------------------------------------------------- Wave

@kernel
def wave_texture(kind, direction, profile, points, scale, distortion, detail, detail_scale,
                 detail_roughness, phase, fac_out):
    """The Wave Texture node for a batch of hits (Cycles svm_wave, kernel/svm/wave.h).

    kind: index into WAVE_TYPES; direction: into WAVE_BANDS_DIRECTIONS (bands) or
    WAVE_RINGS_DIRECTIONS (rings); profile: into WAVE_PROFILES. points (N,3) texture
    coordinates; scale, distortion, detail, detail_scale, detail_roughness, phase (N,)
    socket values per hit. Writes fac_out (N,), in [0, 1] (the Color output is it as grey).
    """
    for i in range(points.shape[0]):
        s = scale[i]
        # Cycles nudges the scaled coordinates off unit values (precision on cell edges).
        x = (points[i, 0] * s + 0.000001) * 0.999999
        y = (points[i, 1] * s + 0.000001) * 0.999999
        z = (points[i, 2] * s + 0.000001) * 0.999999
        if kind == 0:  # bands
            if direction == 0:
                n = x * 20.0
            elif direction == 1:
                n = y * 20.0
            elif direction == 2:
                n = z * 20.0
            else:
                n = (x + y + z) * 10.0
        else:  # rings: distance from the axis (or the origin: spherical)
            rx = 0.0 if direction == 0 else x
            ry = 0.0 if direction == 1 else y
            rz = 0.0 if direction == 2 else z
            n = math.sqrt(rx * rx + ry * ry + rz * rz) * 20.0
        n += phase[i]
        dist = distortion[i]
        if dist != 0.0:
            ds = detail_scale[i]
            # Cycles leaves Detail unclamped (its UI keeps it in 0..15); clamped here so a
            # linked value cannot run away (below 0 its fBM would divide by zero).
            d = min(max(detail[i], 0.0), 15.0)
            fbm = fractal(3, 0, x * ds, y * ds, z * ds, 0.0, d, detail_roughness[i], 2.0,
                          0.0, 0.0, True)
            n += dist * (fbm * 2.0 - 1.0)
        if profile == 0:  # sine
            fac_out[i] = 0.5 + 0.5 * math.sin(n - 0.5 * math.pi)
        elif profile == 1:  # saw
            n /= 2.0 * math.pi
            fac_out[i] = n - math.floor(n)
        else:  # triangle
            n /= 2.0 * math.pi
            fac_out[i] = abs(n - math.floor(n + 0.5)) * 2.0


@kernel
def white_noise_texture(dims, points, w_in, value_out, color_out):
    """The White Noise Texture node for a batch of hits (Cycles svm_node_tex_white_noise,
    kernel/svm/white_noise.h): Value = hash_floatN_to_float of the dims-D input (1D: W;
    2D: x, y; 3D: x, y, z; 4D: x, y, z, W), Color = hash_floatN_to_float3 (util/hash.h:
    the value, then the same hash with the constants 1 and 2 appended, or in 4D the
    inputs permuted). points (N,3), w_in (N,); writes value_out (N,), color_out (N,3).
    A hash of the float32 bits: it matches Cycles where the inputs round to the same
    float32 (integer or snapped coordinates, object random numbers), not elsewhere."""
    for i in range(points.shape[0]):
        x, y, z, w = points[i, 0], points[i, 1], points[i, 2], w_in[i]
        if dims == 1:
            a = hash_float(1, w, 0.0, 0.0, 0.0)
            b = hash_float(2, w, 1.0, 0.0, 0.0)
            c = hash_float(2, w, 2.0, 0.0, 0.0)
        elif dims == 2:
            a = hash_float(2, x, y, 0.0, 0.0)
            b = hash_float(3, x, y, 1.0, 0.0)
            c = hash_float(3, x, y, 2.0, 0.0)
        elif dims == 3:
            a = hash_float(3, x, y, z, 0.0)
            b = hash_float(4, x, y, z, 1.0)
            c = hash_float(4, x, y, z, 2.0)
        else:
            a = hash_float(4, x, y, z, w)
            b = hash_float(4, z, x, w, y)
            c = hash_float(4, w, z, y, x)
        value_out[i] = a
        color_out[i, 0] = a
        color_out[i, 1] = b
        color_out[i, 2] = c


# ---------------------------------------------------------------- Gabor (svm/gabor.h)

GABOR_IMPULSES = 8  # Cycles' IMPULSES_COUNT: kernels per cell (stratified Poisson)


@kernel
def _hash32(dims, x0, x1, x2, x3):
    """hash_floatN_to_float as Cycles rounds it: (float)h / (float)0xFFFFFFFF in float32
    (the Gabor impulses' centres, signs and turns)."""
    h = hash_uint(dims, float_bits(x0), float_bits(x1), float_bits(x2), float_bits(x3))
    return float(np.float32(h) / np.float32(4294967295.0))


@kernel
def _gabor_kernel(dx, dy, dz, fx, fy, fz):
    """Cycles' compute_2d/3d_gabor_kernel at offset d from the impulse, frequency vector
    f: the Hann-windowed Gaussian exp(-pi |d|^2) (0.5 + 0.5 cos(pi |d|^2)) times the
    phasor of 2 pi d . f. Returns (cos part, sin part)."""
    d2 = dx * dx + dy * dy + dz * dz
    env = math.exp(-math.pi * d2) * (0.5 + 0.5 * math.cos(math.pi * d2))
    angle = 2.0 * math.pi * (dx * fx + dy * fy + dz * fz)
    return env * math.cos(angle), env * math.sin(angle)


@kernel
def _gabor_cell_table(dims, cx, cy, cz, table):
    """The impulses of the 3^dims cells around cell (cx, cy, cz) as Cycles seeds them
    (compute_2d/3d_gabor_noise_cell): table[c * GABOR_IMPULSES + k] = (centre x, y, z,
    sign, turn 1, turn 2) of impulse k of neighbour c (x fastest, then y, then z)."""
    c = 0
    for kk in range(-1, 2) if dims == 3 else range(0, 1):
        for j in range(-1, 2):
            for i in range(-1, 2):
                x, y, z = cx + i, cy + j, cz + kk
                for k in range(GABOR_IMPULSES):
                    s0, s1, s2 = 3.0 * k, 3.0 * k + 1.0, 3.0 * k + 2.0
                    row = table[c * GABOR_IMPULSES + k]
                    if dims == 2:
                        row[0] = _hash32(3, x, y, s1, 0.0)
                        row[1] = _hash32(3, s1, x, y, 0.0)
                        row[2] = 0.0
                        row[3] = -1.0 if _hash32(3, x, y, s2, 0.0) < 0.5 else 1.0
                        row[4] = (_hash32(3, x, y, s0, 0.0) - 0.5) * math.pi
                        row[5] = 0.0
                    else:
                        row[0] = _hash32(4, x, y, z, s1)
                        row[1] = _hash32(4, z, x, s1, y)
                        row[2] = _hash32(4, s1, z, y, x)
                        row[3] = -1.0 if _hash32(4, x, y, z, s2) < 0.5 else 1.0
                        row[4] = _hash32(4, x, y, z, s0) * math.pi
                        row[5] = _hash32(4, z, x, s0, y) * math.pi
                c += 1


@kernel
def gabor_texture(dims, points, scale, frequency, anisotropy, orientation_2d,
                  orientation_3d, output, order, out):
    """The Gabor Texture node for a batch of hits (Cycles svm_node_tex_gabor,
    kernel/svm/gabor.h: Lagae et al. 2009 sparse Gabor convolution, Tavernier et al. 2019
    Bernoulli weights and normalisation, Tricard et al. 2019 phasor). dims 2 or 3;
    points (N,3) coordinates, scale, frequency, anisotropy, orientation_2d (radians) (N,),
    orientation_3d (N,3) (normalised here); output 0 Value, 1 Phase, 2 Intensity into
    out (N,). Each cell of the 3^dims neighbourhood of the scaled point holds
    GABOR_IMPULSES kernels at hashed centres, of hashed sign and, with isotropy = 1 -
    anisotropy > 0, hashed turns of the orientation; the seeds are the cell's float
    coordinates and 3 i, 3 i + 1, 3 i + 2 (the impulse i), hashed as Cycles hashes them,
    so the pattern is Cycles'. The hits are visited in `order` (N,) (sorted by cell: the
    hashes of a cell's neighbourhood are computed once per run of hits in it)."""
    if dims == 2:
        norm = 6.0 * math.sqrt(GABOR_IMPULSES * 0.5 * 0.25)
        cells = 9
    else:
        norm = 6.0 * math.sqrt(GABOR_IMPULSES * 0.5 / (4.0 * math.sqrt(2.0)))
        cells = 27
    table = np.empty((cells * GABOR_IMPULSES, 6))
    have = False
    lx, ly, lz = 0.0, 0.0, 0.0
    for m in range(order.shape[0]):
        n = order[m]
        s = scale[n]
        px, py, pz = points[n, 0] * s, points[n, 1] * s, points[n, 2] * s
        if dims == 2:
            pz = 0.0
        cx, cy, cz = math.floor(px), math.floor(py), math.floor(pz)
        if not have or cx != lx or cy != ly or cz != lz:
            _gabor_cell_table(dims, cx, cy, cz, table)
            have = True
            lx, ly, lz = cx, cy, cz
        iso = 1.0 - min(max(anisotropy[n], 0.0), 1.0)
        f = max(0.001, frequency[n])
        if dims == 2:
            ox, oy, oz = math.cos(orientation_2d[n]), math.sin(orientation_2d[n]), 0.0
            inclination, azimuth = 0.0, 0.0
        else:
            ox, oy, oz = orientation_3d[n, 0], orientation_3d[n, 1], orientation_3d[n, 2]
            ln = math.sqrt(ox * ox + oy * oy + oz * oz)
            if ln > 0.0:
                ox, oy, oz = ox / ln, oy / ln, oz / ln
            inclination = math.acos(min(max(oz, -1.0), 1.0))
            lxy = math.sqrt(ox * ox + oy * oy)
            azimuth = math.nan  # Cycles' 0 / 0 for an orientation along z
            if lxy > 0.0:
                azimuth = (-1.0 if oy < 0.0 else 1.0) * math.acos(min(max(ox / lxy, -1.0),
                                                                     1.0))
        re = 0.0
        im = 0.0
        c = 0
        for kk in range(-1, 2) if dims == 3 else range(0, 1):
            for j in range(-1, 2):
                for i in range(-1, 2):
                    qx, qy, qz = px - cx - i, py - cy - j, pz - cz - kk
                    for k in range(GABOR_IMPULSES):
                        row = table[c * GABOR_IMPULSES + k]
                        dx, dy, dz = qx - row[0], qy - row[1], qz - row[2]
                        if dx * dx + dy * dy + dz * dz >= 1.0:
                            continue
                        ux, uy, uz = ox, oy, oz
                        if dims == 2:
                            o = orientation_2d[n] + row[4] * iso
                            ux, uy = math.cos(o), math.sin(o)
                        elif iso != 0.0:  # compute_3d_orientation
                            inc = inclination + row[4] * iso
                            azi = azimuth + row[5] * iso
                            ux = math.sin(inc) * math.cos(azi)
                            uy = math.sin(inc) * math.sin(azi)
                            uz = math.cos(inc)
                        a, b = _gabor_kernel(dx, dy, dz, f * ux, f * uy, f * uz)
                        re += row[3] * a
                        im += row[3] * b
                    c += 1
        if output == 0:
            out[n] = im / norm * 0.5 + 0.5
        elif output == 1:
            out[n] = (math.atan2(im, re) + math.pi) / (2.0 * math.pi)
        else:
            out[n] = math.sqrt(re * re + im * im) / norm


@register_warm_up
def _warm_up():
    pts = np.zeros((1, 3))
    one = np.ones(1)
    val = np.zeros(1)
    col = np.zeros((1, 3))
    for dims in (1, 2, 3, 4):
        noise_texture(dims, 0, True, pts, one, one, one, one, one, one, one, one,
                      noise_offsets(dims), True, val, col)
        voronoi_texture(dims, 0, 0, False, pts, one, one, one, one, one, one, one, one,
                        val, col, np.zeros((1, 3)), np.zeros(1), np.zeros(1))
    wave_texture(0, 0, 0, pts, one, one, one, one, one, one, val)
    for dims in (1, 2, 3, 4):
        white_noise_texture(dims, pts, one, val, col)
    for dims in (2, 3):
        gabor_texture(dims, pts, one, one, one, one, np.ones((1, 3)), 0,
                      np.zeros(1, np.int64), val)
