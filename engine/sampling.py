"""Vectorised sampling helpers: frames, hemispheres, disks, cones, Fresnel-free geometry."""
from __future__ import annotations

import numpy as np

from .jit import kernel, register_warm_up


def norm3(v: np.ndarray) -> np.ndarray:
    """|v| over the last axis of length 3. Bitwise equal to np.linalg.norm(v, axis=-1)
    (same products, same left-to-right sum) but ~10x faster: numpy's reductions over a
    short last axis are slow (docs/performance.md)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def max3(v: np.ndarray) -> np.ndarray:
    """v.max(axis=-1) for a last axis of length 3 (same result, NaN included; ~5x faster)."""
    return np.maximum(np.maximum(v[..., 0], v[..., 1]), v[..., 2])


def normalize(v: np.ndarray) -> np.ndarray:
    if v.shape[-1] == 3:
        n = norm3(v)[..., None]
    else:
        n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-300)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two tangents t, b with (t, b, n) right-handed (Duff et al. 2017, branchless)."""
    sign = np.where(n[..., 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1.0 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], axis=-1)
    bt = np.stack([b, sign + n[..., 1] ** 2 * a, -n[..., 1]], axis=-1)
    return t, bt


def to_world(local: np.ndarray, n: np.ndarray) -> np.ndarray:
    """local (x, y, z) in the frame (t, b, n) of orthonormal_basis(n), written component by
    component: bitwise the same as local.x*t + local.y*b + local.z*n, 3.7x faster (no
    (N,3) temporaries for t and b)."""
    n0, n1, n2 = n[..., 0], n[..., 1], n[..., 2]
    sign = np.where(n2 >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    l0, l1, l2 = local[..., 0], local[..., 1], local[..., 2]
    out = np.empty(np.broadcast_shapes(local.shape, n.shape), np.result_type(local, n))
    out[..., 0] = l0 * (1.0 + sign * n0 ** 2 * a) + l1 * b + l2 * n0
    out[..., 1] = l0 * (sign * b) + l1 * (sign + n1 ** 2 * a) + l2 * n1
    out[..., 2] = l0 * (-sign * n0) + l1 * (-n1) + l2 * n2
    return out


def cosine_hemisphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Local directions with pdf cos(theta)/pi around +z."""
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    z = np.sqrt(np.maximum(0.0, 1.0 - u1))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def uniform_sphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def uniform_cone(u1: np.ndarray, u2: np.ndarray, cos_max: float | np.ndarray) -> np.ndarray:
    """Local directions uniform in solid angle within angle acos(cos_max) of +z."""
    z = 1.0 - u1 * (1.0 - cos_max)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def concentric_disk(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Uniform points on the unit disk (Shirley-Chiu), low distortion for jittered input."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    safe_a = np.where(a == 0, 1e-300, a)
    safe_b = np.where(b == 0, 1e-300, b)
    phi = np.where(use_a, (np.pi / 4.0) * (b / safe_a), np.pi / 2.0 - (np.pi / 4.0) * (a / safe_b))
    return r * np.cos(phi), r * np.sin(phi)


def uniform_triangle(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric (b1, b2) uniform over a triangle."""
    s = np.sqrt(u1)
    return 1.0 - s, u2 * s


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    return d - 2.0 * dot(d, n)[..., None] * n


def offset_origin(p: np.ndarray, ng: np.ndarray, direction: np.ndarray, eps) -> np.ndarray:
    """Move p off its surface along the geometric normal, to the side `direction` leaves,
    by eps: (N,) per point (a rounding-error bound, engine/rayoffset.py) or a scalar.

    Offsetting along the normal (not the ray) is what keeps float32 Embree from hitting the
    same triangle again at any angle (pbrt-v4's OffsetRayOrigin)."""
    side = np.where(dot(direction, ng) >= 0.0, 1.0, -1.0)
    return p + (side * eps)[..., None] * ng


class SampleDimensions:
    """The stratified sampler's dimensions, handed out so that no two consumers share one.

    Each consumer of 2-D sample points names its dimension by a key (e.g. ("gather", g),
    ("light", li, si)) and may ask for a preferred number (the numbering images were
    rendered with so far). Requests are resolved together, in their order: a key gets its
    preferred number unless an earlier request holds it; such keys, and keys without a
    preference, get numbers above every preferred one, in request order. Built once per
    pass on one thread, so every chunk and thread count sees the same numbering.

    requests: iterable of (key, preferred int >= 0 or None). Raises ValueError on a key
    requested twice."""

    def __init__(self, requests):
        self._dim: dict = {}
        self.moved: list = []   # keys whose preferred number was taken (for diagnostics)
        pending = []
        taken = set()
        top = -1
        for key, preferred in requests:
            if key in self._dim or any(key == k for k, _ in pending):
                raise ValueError(f"sample dimension {key!r} requested twice")
            if preferred is not None and preferred not in taken:
                self._dim[key] = int(preferred)
                taken.add(int(preferred))
                top = max(top, int(preferred))
            else:
                pending.append((key, preferred))
        for key, preferred in pending:
            top += 1
            self._dim[key] = top
            if preferred is not None:
                self.moved.append(key)

    def __getitem__(self, key) -> int:
        try:
            return self._dim[key]
        except KeyError:
            raise KeyError(f"sample dimension {key!r} was not requested; known: "
                           f"{len(self._dim)} keys") from None

    def __len__(self):
        return len(self._dim)

    def numbers(self) -> dict:
        """key -> dimension number (a copy)."""
        return dict(self._dim)


class StratifiedSampler:
    """2-D sample points stratified across the samples of one pixel.

    Sample `sub` of a pixel takes cell (sub + shift) mod m^2 of an m x m grid
    (m = floor(sqrt(spp))), jittered inside the cell. The shift is a hash of pixel and
    dimension (and of the seed, scrambled: what the camera pass asks for), so dimensions
    (light position, gather direction, ...) are not correlated with each other or with
    the pixel jitter, and their pairing with it changes from seed to seed. Over the spp
    samples of a pixel every cell is visited once, which cuts noise in soft shadows and
    final gathering.

    Dimensions are asked for by key (uv(("light", li, si))); `dims` (SampleDimensions)
    maps keys to numbers, so no two consumers can share a dimension."""

    def __init__(self, sub: np.ndarray, pix: np.ndarray, spp: int, rng: np.random.Generator,
                 dims: SampleDimensions, salt: int = 0):
        self.dims = dims
        self.salt = int(salt) % (1 << 64)
        self.sub = sub
        self.pix = pix
        self.m = max(1, int(np.sqrt(spp)))
        # Samples beyond the last whole round of m*m cells stay unstratified: a partly
        # visited grid would weight some cells twice, a per-pixel bias pattern.
        self.full = (spp // (self.m * self.m)) * self.m * self.m
        self.rng = rng

    def subset(self, idx) -> "StratifiedSampler":
        s = StratifiedSampler.__new__(StratifiedSampler)
        s.sub, s.pix, s.m, s.full, s.rng = self.sub[idx], self.pix[idx], self.m, self.full, self.rng
        s.dims = self.dims
        s.salt = self.salt
        return s

    def for_samples(self, sub, pix) -> "StratifiedSampler":
        """This sampler's stream and dimensions for other rows: sample indices sub (N,)
        and (shifted) pixel ids pix (N,) (paths whose rows are rebuilt from their own
        sample index and pixel)."""
        s = self.subset(slice(0, 0))
        s.sub, s.pix = np.asarray(sub), np.asarray(pix)
        return s

    def uv(self, key, rng=None, scrambled=True) -> tuple[np.ndarray, np.ndarray]:
        """(u1, u2), each (N,) in [0, 1), for the dimension named key (SampleDimensions);
        rng: the generator of the jitter inside the cells (default: the sampler's);
        scrambled: the cell order's offset hashed from pixel, dimension and seed (below);
        False gives the linear shift, kept only to measure what the scramble removes
        (bench/bench_cell_shift.py, tests/test_sampler_scramble.py)."""
        return self._uv(self.dims[key], scrambled, self.rng if rng is None else rng)

    def _uv(self, dim, scrambled, rng):
        n = len(self.sub)
        cells = self.m * self.m
        if cells < 2:
            u1, u2 = rng.random((2, n))  # one draw: the numbers of two
            return u1, u2
        # The pairing of two dimensions' strata within a pixel is a fixed offset. With
        # the linear hash (pixel * 2654435761 + dim * 40503 + 12345) it is the same in
        # every pixel and seed, a fixed pattern no number of seeds averages away: lobe
        # directions paired so stayed 1.8 % off on a glossy floor mirroring a small
        # bright patch (30 seeds), whose few highlight pixels carry the image. Scrambled:
        # a splitmix64 finaliser of (pixel, dimension, seed), the default every consumer
        # takes (the lights' points and the gather were linear until glossy02, -0.65 % /
        # +0.83 % off at 64 spp: docs/performance.md). One compiled pass
        # (_stratified_uv); the jitter is drawn here in the order the numpy stage drew it.
        # One generator call per pair: the same numbers as two calls of n.
        jitter1, jitter2 = rng.random((2, n))
        n_rest = int(np.count_nonzero(self.sub >= self.full))
        rest1, rest2 = rng.random((2, n_rest)) if n_rest else (_EMPTY, _EMPTY)
        if scrambled:
            add = np.uint64(((dim + 1) * 0xBF58476D1CE4E5B9 + self.salt * 0xD6E8FEB86659FD93)
                            % (1 << 64))
        else:
            add = np.uint64(dim * 40503 + 12345)
        u1, u2 = np.empty(n), np.empty(n)
        _stratified_uv(np.ascontiguousarray(self.pix, np.int64),
                       np.ascontiguousarray(self.sub, np.int64), self.m, self.full,
                       bool(scrambled), add, jitter1, jitter2, rest1, rest2, u1, u2)
        return u1, u2


_EMPTY = np.zeros(0)


@kernel
def _stratified_uv(pix, sub, m, full, scrambled, add, jitter1, jitter2, rest1, rest2, u1, u2):
    """StratifiedSampler._uv's numbers: sample sub[i] of pixel pix[i] takes cell
    (sub + shift) mod m^2, shift = a hash of the pixel and `add` (the dimension, and the
    seed when scrambled) in uint64 arithmetic; u1 = (cell mod m + jitter1) / m,
    u2 = (cell div m + jitter2) / m; samples with sub >= full take rest1, rest2 in
    order instead. pix, sub (N,) int64; jitter1, jitter2, u1, u2 (N,); rest1, rest2
    (count of sub >= full,)."""
    cells = np.uint64(m * m)
    # m a power of two (every square spp's side that is one: 64 spp, m = 8): the same
    # remainders and quotients by masks and shifts (the integers are non-negative), not
    # the 64-bit divisions that were most of this kernel's time (~6 -> ~2 ns a row).
    pow2 = m > 0 and (m & (m - 1)) == 0
    mask = cells - np.uint64(1)
    mm = m - 1
    sh = pow2_shift(m)
    j = 0
    for i in range(pix.shape[0]):
        if scrambled:
            x = np.uint64(pix[i]) * np.uint64(0x9E3779B97F4A7C15) + add
            x ^= x >> np.uint64(31)
            x *= np.uint64(0x94D049BB133111EB)
            x ^= x >> np.uint64(29)
        else:
            x = np.uint64(pix[i]) * np.uint64(2654435761) + add
        shift = (x & mask) if pow2 else x % cells
        z = np.uint64(sub[i]) + shift
        cell = np.int64(z & mask) if pow2 else np.int64(z % cells)
        if sub[i] >= full:
            u1[i] = rest1[j]
            u2[i] = rest2[j]
            j += 1
        else:
            cx = (cell & mm) if pow2 else cell % m
            cy = (cell >> sh) if pow2 else cell // m
            u1[i] = (np.float64(cx) + jitter1[i]) / np.float64(m)
            u2[i] = (np.float64(cy) + jitter2[i]) / np.float64(m)


@kernel
def pow2_shift(m):
    """log2(m) for m a power of two (the shift that divides by m); for other m, the
    smallest s with 2^s >= m (callers use it only where m is a power of two)."""
    sh = 0
    while (1 << sh) < m:
        sh += 1
    return sh


@register_warm_up
def _warm_up():
    one = np.ones(1, np.int64)
    for scrambled in (False, True):
        _stratified_uv(one, one, 4, 16, scrambled, np.uint64(7), np.full(1, 0.5),
                       np.full(1, 0.5), _EMPTY, _EMPTY, np.empty(1), np.empty(1))
