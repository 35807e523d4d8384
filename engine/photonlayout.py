"""The compact layout of the photons a map holds: 12 B of direction, normal and power a
photon instead of 36 (docs/performance.md "compact49", issue 13's 64 bytes per stored
photon).

- direction and normal: the octahedral map in 2 x int16 (snorm16; Cigolle et al. 2014, "A
  Survey of Efficient Representations for Independent Unit Vectors", "oct16"): (N,2)
  int16. Round-trip error of a unit vector at most OCT_MAX_ANGLE (7e-5 rad, 0.004 deg:
  tests/test_photon_layout.py), ~170x finer than Jensen's theta / phi bytes (0.7 deg
  steps) for the same 4 B a vector as RGBE's power.
- power: Ward's RGBE (Graphics Gems II, "Real Pixels"; Jensen's photon map stores its
  power so), (N,4) uint8: three 8-bit mantissas and a shared exponent. Encoded to the
  nearest step, decoded as m 2^(e - 136), so 0 stays 0 (a zero channel stays exactly
  0), the rounding is unbiased on average and each channel is within 1/255.5 of the
  brightest channel's value (half a step: 2^(E - 9) where the brightest is in
  [2^(E-1), 2^E), 2^(E - 8) where it rounded up to 256 steps, >= 255.5 2^(E - 8)). Channels below 2^-137 of a zero exponent byte decode to 0
  (float32 watts that small do not occur).

The kernels read a map's arrays through read_vector / read_power (numba overloads chosen
by the array's dtype): float arrays ((N,3) float32, the photon pass' own layout, the gather
points' normals) are read as they are, int16 (N,2) as octahedral, uint8 (N,4) as RGBE. One
kernel source serves both layouts, and the float32 layout's arithmetic is the same
expressions as before (its films are unchanged with COMPACT off). Decoding is per photon
read, in the kernels: decoding whole arrays back to float32 would not save the memory.

The k-NN rows' photon tests (photonmap._accepted, _back_face) read a vector through
read_axis instead: the octahedral point unnormalised and its squared length, compared as
cosines by cos_below / cos_at_most without the decode's float32 sqrt and divide, which
cost compact49's rows most of their 1.4-2.1x (docs/performance.md "compact50").

COMPACT: PhotonMap stores its photons in this layout (True, the default since compact51)
or keeps the float32 arrays (False: the float32 films, for references and A/B benches).
Every reader of a map's photon arrays goes through this module: the kernels through the
overloads above, numpy code through vectors / powers / has_power (docs/performance.md
"compact51" lists the readers; the shots, Photons before a map, stay float32). A render's
own estimates replayed take 1.01 / 1.04x the float32 maps' CPU (Figures 6 / 8) for the
24 B a held photon it saves (docs/performance.md "compact49", "compact50").
"""
from __future__ import annotations

import math

import numpy as np
from numba import types
from numba.extending import overload

from .jit import kernel

COMPACT = True

OCT_SCALE = 32767.0
# The round-trip's largest angle between a unit vector and its decoded value (rad):
# half a step of 1/32767 on both axes of the octahedron's square, stretched where the
# square maps to the sphere, and float32 decoding; measured 6.4e-5 over 10^6 random
# float32 directions (tests/test_photon_layout.py checks this bound).
OCT_MAX_ANGLE = 7e-5
RGBE_BIAS = 136  # the exponent byte of m 2^(e - 136): 128 + 8 mantissa bits
# 2^(e - 136) for each exponent byte e: a table read instead of an ldexp per photon
# (numba freezes a global array into the machine code).
RGBE_STEP = np.ldexp(1.0, np.arange(256) - RGBE_BIAS)


def encode_vectors(v: np.ndarray) -> np.ndarray:
    """(N,2) int16: the octahedral code of (N,3) unit vectors (float32 or float64; zero
    rows code as (0, 0), i.e. +z). Each vector maps to the octahedron |x| + |y| + |z| =
    1, the lower half folded over the upper, and the square's coordinates round to the
    nearest of 65,535 steps (_encode_vectors: a kernel, ~50x numpy's whole-array passes
    on a map build's million photons)."""
    v = np.ascontiguousarray(v)
    if v.dtype != np.float32:
        v = v.astype(np.float64)
    out = np.empty((len(v), 2), np.int16)
    _encode_vectors(v, out)
    return out


@kernel
def _round_even(x):
    """x rounded to the nearest integer, ties to even (numpy's np.round): float32
    inputs scaled by powers of two land on ties often enough to bias half-up rounding."""
    r = math.floor(x + 0.5)
    if r - x == 0.5 and r % 2.0 != 0.0:
        r -= 1.0
    return r


@kernel
def _encode_vectors(v, out):
    for i in range(v.shape[0]):
        x, y, z = np.float64(v[i, 0]), np.float64(v[i, 1]), np.float64(v[i, 2])
        s = max(abs(x) + abs(y) + abs(z), 1e-300)
        x, y, z = x / s, y / s, z / s
        if z < 0.0:
            fx = (1.0 - abs(y)) * (1.0 if x >= 0.0 else -1.0)
            fy = (1.0 - abs(x)) * (1.0 if y >= 0.0 else -1.0)
            x, y = fx, fy
        out[i, 0] = np.int16(_round_even(min(max(x, -1.0), 1.0) * OCT_SCALE))
        out[i, 1] = np.int16(_round_even(min(max(y, -1.0), 1.0) * OCT_SCALE))


def decode_vectors(code: np.ndarray, dtype=np.float32) -> np.ndarray:
    """(N,3) unit vectors of (N,2) int16 octahedral codes (encode_vectors), in dtype: the
    kernels' oct_decode values bit for bit (the same float32 operations in the same
    order), then converted to dtype."""
    code = np.asarray(code)
    f = np.float32
    x = code[:, 0].astype(f) * f(1.0 / OCT_SCALE)
    y = code[:, 1].astype(f) * f(1.0 / OCT_SCALE)
    z = f(1.0) - np.abs(x) - np.abs(y)
    t = np.maximum(-z, f(0.0))
    x = np.where(x >= f(0.0), x - t, x + t)
    y = np.where(y >= f(0.0), y - t, y + t)
    inv = f(1.0) / np.sqrt(x * x + y * y + z * z)
    return np.stack([x * inv, y * inv, z * inv], axis=1).astype(dtype)


def encode_power(c: np.ndarray) -> np.ndarray:
    """(N,4) uint8 RGBE of (N,3) non-negative powers (W, float32 or float64): mantissas
    round(c 2^(136 - e)) <= 255 with e the smallest exponent byte that keeps the
    brightest channel's at most 255 (a row of zeros: all 0; below the range, 2^-128 W,
    the nearest steps of e = 0, mostly 0). Negative channels (none in a photon's power)
    encode as 0. A kernel (_encode_power)."""
    c = np.ascontiguousarray(c)
    if c.dtype != np.float32:
        c = c.astype(np.float64)
    out = np.empty((len(c), 4), np.uint8)
    _encode_power(c, out)
    return out


@kernel
def _encode_power(c, out):
    for i in range(c.shape[0]):
        r = max(np.float64(c[i, 0]), 0.0)
        g = max(np.float64(c[i, 1]), 0.0)
        b = max(np.float64(c[i, 2]), 0.0)
        v = max(r, g, b)
        if not v > 0.0:  # (0, or NaN)
            out[i, 0] = out[i, 1] = out[i, 2] = out[i, 3] = 0
            continue
        big = math.frexp(v)[1]  # v = f 2^big, f in [0.5, 1)
        # e - 136 = big - 8: the brightest channel's mantissa in [128, 256); one that
        # rounds up to 256 takes the next exponent.
        e = big + RGBE_BIAS - 8
        if e < 0:
            e = 0
        f = math.ldexp(1.0, RGBE_BIAS - e)
        if _round_even(v * f) > 255.0:
            e += 1
            f *= 0.5
        out[i, 0] = np.uint8(min(_round_even(r * f), 255.0))
        out[i, 1] = np.uint8(min(_round_even(g * f), 255.0))
        out[i, 2] = np.uint8(min(_round_even(b * f), 255.0))
        out[i, 3] = np.uint8(min(e, 255))


def decode_power(code: np.ndarray, dtype=np.float64) -> np.ndarray:
    """(N,3) powers of (N,4) uint8 RGBE codes (encode_power): m 2^(e - 136), exactly the
    kernels' rgbe_decode values (float64)."""
    code = np.asarray(code)
    return (code[:, :3].astype(np.float64) * RGBE_STEP[code[:, 3]][:, None]).astype(dtype)


def vectors(a: np.ndarray, rows=None, dtype=np.float64) -> np.ndarray:
    """(K,3) dtype of a map's direction or normal array a (float (N,3) or octahedral
    (N,2) int16), at rows (K,) int (None: all); rows of any shape S give S + (3,)."""
    if a.dtype != np.int16:
        return (a if rows is None else np.take(a, rows, axis=0)).astype(dtype)
    if rows is None:
        return decode_vectors(a, dtype)
    rows = np.asarray(rows)
    return decode_vectors(np.take(a, rows.ravel(), axis=0), dtype).reshape(rows.shape + (3,))


def powers(a: np.ndarray, rows=None, dtype=np.float64) -> np.ndarray:
    """(K,3) dtype of a map's power array a (float (N,3) or RGBE (N,4) uint8), at rows
    (K,) int (None: all); rows of any shape S give S + (3,)."""
    if a.dtype != np.uint8:
        return (a if rows is None else np.take(a, rows, axis=0)).astype(dtype)
    if rows is None:
        return decode_power(a, dtype)
    rows = np.asarray(rows)
    return decode_power(np.take(a, rows.ravel(), axis=0), dtype).reshape(rows.shape + (3,))


def has_power(a: np.ndarray) -> np.ndarray:
    """(N,) bool: whether each row of a power array a (float (N,3) or RGBE (N,4) uint8)
    has a nonzero channel once decoded, without decoding: a float row's channels != 0; an
    RGBE row's bytes != 0, the same answer because encode_power writes all four bytes 0
    for a powerless photon, a nonzero exponent byte only with the brightest mantissa >=
    128 (nonzero), and exponent byte 0 decodes each mantissa m as m 2^-136 > 0 for m > 0
    (tests/test_photon_layout.py)."""
    return np.any(a != 0, axis=1)


def compact(photons):
    """photons (engine.photons.Photons) with direction and normal as octahedral (N,2)
    int16 and power as RGBE (N,4) uint8, in place (arrays already compact are kept);
    returns photons."""
    if photons.direction.dtype != np.int16:
        photons.direction = encode_vectors(photons.direction)
    if photons.normal.dtype != np.int16:
        photons.normal = encode_vectors(photons.normal)
    if photons.power.dtype != np.uint8:
        photons.power = encode_power(photons.power)
    return photons


def round_trip(photons):
    """A copy of photons (engine.photons.Photons) whose direction, normal and power are
    float32 again but hold the compact layout's values (what the kernels read from a
    compact map): the float32 layout of the same light, for references and benches."""
    import copy
    out = copy.copy(photons)
    out.direction = decode_vectors(encode_vectors(photons.direction))
    out.normal = decode_vectors(encode_vectors(photons.normal))
    out.power = decode_power(encode_power(photons.power), np.float32)
    return out


@kernel
def oct_unfold(u, v):
    """(x, y, z, w) float32 of octahedral code (u, v) (int16 each): the octahedron's
    point, the lower half unfolded without a branch (x -= copysign(max(-z, 0), x)), not
    normalised, and w = x^2 + y^2 + z^2 (its squared length, in [1/3, 1])."""
    x = np.float32(u) * np.float32(1.0 / OCT_SCALE)
    y = np.float32(v) * np.float32(1.0 / OCT_SCALE)
    z = np.float32(1.0) - abs(x) - abs(y)
    t = max(-z, np.float32(0.0))
    x = x - t if x >= np.float32(0.0) else x + t
    y = y - t if y >= np.float32(0.0) else y + t
    return x, y, z, x * x + y * y + z * z


@kernel
def oct_decode(u, v):
    """The unit vector (x, y, z) float32 of octahedral code (u, v) (int16 each):
    oct_unfold's point, normalised."""
    x, y, z, w = oct_unfold(u, v)
    inv = np.float32(1.0) / np.sqrt(w)
    return x * inv, y * inv, z * inv


@kernel
def rgbe_decode(code, j):
    """Photon j's power (float64 x 3, W) of code (N,4) uint8 RGBE: m 2^(e - 136)."""
    f = RGBE_STEP[code[j, 3]]
    return np.float64(code[j, 0]) * f, np.float64(code[j, 1]) * f, np.float64(code[j, 2]) * f


# The next ones are numba overloads in the kernels (chosen by the array's dtype at
# compile time, below); their Python bodies give the same values where a kernel runs as
# its Python function (py_func: tests/test_photon_lookup.py).
def read_vector(a, j):
    """Row j of a direction or normal array as 3 values: a float (N,3) array's own
    elements (its dtype), an int16 (N,2) array's octahedral code decoded (float32)."""
    if a.dtype == np.int16:
        return oct_decode.py_func(a[j, 0], a[j, 1])
    return a[j, 0], a[j, 1], a[j, 2]


def read_power(a, j):
    """Row j of a power array as float64 x 3: a float (N,3) array's values, an (N,4)
    uint8 array's RGBE code decoded."""
    if a.dtype == np.uint8:
        return rgbe_decode.py_func(a, j)
    return np.float64(a[j, 0]), np.float64(a[j, 1]), np.float64(a[j, 2])


def read_axis(a, j):
    """Row j of a direction or normal array as (x, y, z, w): a vector along it and w
    its squared length, for the kernels that only compare cosines (cos_below,
    cos_at_most) or read signs: a float (N,3) array's own elements and w = 1, an int16
    (N,2) array's octahedral point unnormalised (oct_unfold). The octahedral decode's
    float32 sqrt and divide cost the k-NN rows' photon tests most of compact49's 1.4-2.1x
    (docs/performance.md "compact50"): a cosine's threshold test needs neither."""
    if a.dtype == np.int16:
        return oct_unfold.py_func(a[j, 0], a[j, 1])
    return a[j, 0], a[j, 1], a[j, 2], 1.0


def cos_below(a, g, w, t):
    """Whether the cosine g / sqrt(w) is below t, for g the dot product of a unit vector
    with (x, y, z) and w read by read_axis from a: a float array's g < t (the cosine
    itself, exactly as before), the octahedral code's g |g| < t |t| w (x |x| is
    increasing: no sqrt, no divide)."""
    if a.dtype == np.int16:
        return g * abs(g) < t * abs(t) * w
    return g < t


def cos_at_most(a, g, w, t):
    """cos_below with <=: whether the cosine g / sqrt(w) is at most t."""
    if a.dtype == np.int16:
        return g * abs(g) <= t * abs(t) * w
    return g <= t


@overload(read_vector)
def _read_vector(a, j):
    if isinstance(a.dtype, types.Integer):
        def impl(a, j):
            return oct_decode(a[j, 0], a[j, 1])
    else:
        def impl(a, j):
            return a[j, 0], a[j, 1], a[j, 2]
    return impl


@overload(read_power)
def _read_power(a, j):
    if isinstance(a.dtype, types.Integer):
        def impl(a, j):
            return rgbe_decode(a, j)
    else:
        def impl(a, j):
            return np.float64(a[j, 0]), np.float64(a[j, 1]), np.float64(a[j, 2])
    return impl


@overload(read_axis)
def _read_axis(a, j):
    if isinstance(a.dtype, types.Integer):
        def impl(a, j):
            return oct_unfold(a[j, 0], a[j, 1])
    else:
        def impl(a, j):
            return a[j, 0], a[j, 1], a[j, 2], 1.0
    return impl


@overload(cos_below)
def _cos_below(a, g, w, t):
    if isinstance(a.dtype, types.Integer):
        def impl(a, g, w, t):
            return g * abs(g) < t * abs(t) * w
    else:
        def impl(a, g, w, t):
            return g < t
    return impl


@overload(cos_at_most)
def _cos_at_most(a, g, w, t):
    if isinstance(a.dtype, types.Integer):
        def impl(a, g, w, t):
            return g * abs(g) <= t * abs(t) * w
    else:
        def impl(a, g, w, t):
            return g <= t
    return impl


SNAP_CHORD2 = (1.5 * OCT_MAX_ANGLE) ** 2


def snap_chord2(a):
    """The squared chord within which a normal read from a (read_vector) stands for an
    equal one: 0.0 for a float array (its values are exact), (1.5 OCT_MAX_ANGLE)^2 for
    the octahedral code (a photon on the query's own flat surface decodes within
    OCT_MAX_ANGLE of the query's normal, and float32 rounding)."""
    return SNAP_CHORD2 if a.dtype == np.int16 else 0.0


@overload(snap_chord2)
def _snap_chord2(a):
    if isinstance(a.dtype, types.Integer):
        def impl(a):
            return SNAP_CHORD2
    else:
        def impl(a):
            return 0.0
    return impl
