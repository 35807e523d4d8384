"""An equirectangular environment map (Cycles' Environment Texture in a world's Background
node): radiance lookup along directions and a 2D piecewise-constant distribution for
importance sampling it (pbrt-v4's PiecewiseConstant2D, ImageInfiniteLight; Cycles'
kernel/light/background.h).

Conventions, as Cycles renders them (checked against Cycles 5.0 through the bpy wheel,
docs/compatibility.md, world cases):
  d_tex = rotation @ d          rotation: the Mapping node in front of the texture
                                (world direction -> texture direction); identity without
  u = 0.5 - atan2(y, x) / 2pi   of d_tex = (x, y, z): +X looks at the image's centre,
  v = 1 - acos(z) / pi          +Y at u = 0.25, up (+Z) at the top row
Texel centres sit at (i + 0.5) / width; Linear (bilinear) or Closest lookups with the
image repeated in both directions (the node's fixed extension mode).

An image Cycles keeps stored as sRGB (srgb=True: an 8-bit sRGB image, or a float file
tagged sRGB such as the EXR Blender 5's Image.save() writes; addon/materials.py
cycles_stores_srgb) is looked up as Cycles does: the stored encoded texels are
interpolated and the result decoded after (scene/image.cpp ImageMetaData::detect_colorspace
sets compress_as_srgb; svm/image.h svm_image_texture applies color_srgb_to_linear_v4 to
the interpolated value), then times the strength. Decoding after is darker than decoding
first wherever neighbouring texels differ (the decode is convex): newuser32's sky read a
horizon band 1.105 of Cycles decoded first, 8 x 8 pixel blocks at a sharp sun's edge up
to 1.62 (tests/blender/test_srgb_float_cycles.py). Closest lookups read one texel, for
which both orders agree.

Sampling: the distribution's function on texel (row i, column j) is the mean of the
bilinearly interpolated luminance of the linear (decoded) texels over the texel (a 3 x 3
filter of texel luminances, so every direction with radiance has a non-zero pdf;
Closest: the texel's luminance)
times sin(theta) at the row centre. Within the texel a Linear map's directions follow
the bilinear interpolation of the luminance itself (texel_warp: a tent in each axis,
sampled exactly), so a direction's pdf is proportional to the radiance it looks up, and
a sun's edge texels, where the interpolated radiance falls from the sun's to the sky's,
no longer weigh their directions unevenly (they were 70 % of the variance of a
map x cosine shadow ray under a 2-degree sun of radiance 1200: issue 14); a Closest
map's are uniform over the texel.
A direction's solid-angle pdf is pdf_uv x ratio / (2 pi^2 sin theta), ratio the
interpolated luminance over its mean over the texel (1 for Closest). For an sRGB-stored
map the radiance is the decoded interpolation of the encoded texels, which the
interpolation of the decoded texels bounds from above and follows closely; the pdf is
the distribution's own, exactly, so the estimators stay unbiased.

The lookups and the sampling are compiled kernels (engine/jit.py) shared by the
direct-light kernel (engine/directlight.py), photon emission and escaped rays, so the
three agree to the last bit; but for photon emission's radiance, read at the drawn point
of its texel (texel_radiance) rather than through the direction: the same value up to
the direction's round trip's rounding.
"""
from __future__ import annotations

import math

import numpy as np

from ..imageio import srgb_decode
from ..jit import kernel, register_warm_up
from ..sampling import luminance

PI = math.pi
TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi
# Lookup codes of the kernels: INTERP_LINEAR_SRGB is a Linear lookup of sRGB-encoded
# texels, decoded after the interpolation and scaled by the strength (Cycles'
# NODE_IMAGE_COMPRESS_AS_SRGB); the sampling kernels treat it as INTERP_LINEAR.
INTERP_CLOSEST, INTERP_LINEAR, INTERP_LINEAR_SRGB = 0, 1, 2
INTERPOLATIONS = {"Closest": INTERP_CLOSEST, "Linear": INTERP_LINEAR}


class Environment:
    """An equirectangular image lighting the scene from infinity.

    pixels         (H, W, 3) (or (H, W, 4): alpha ignored) linear RGB radiance per unit
                   strength, top row first (the sky's zenith); kept as float32. With
                   srgb: the sRGB-encoded values the image stores (see the module
                   docstring; >= 0, may exceed 1)
    strength       scalar or RGB multiplier (the Background node's Strength x colour)
    rotation       (3, 3) rotation taking world directions to texture directions (the
                   Mapping node); None = identity. Must be a rotation (orthonormal, det 1)
    interpolation  "Linear" (default, Cycles' default) or "Closest"
    srgb           the image is stored sRGB-encoded and Cycles decodes after
                   interpolating (module docstring)
    Raises ValueError naming `name` and the argument for bad input.

    Attributes: `pixels` (H, W, 3) float32 linear radiance texels x strength (decoded
    for an sRGB map: the sampling distribution and the integral read these);
    `stored` (H, W, 3) float32 the texels the lookup interpolates (`pixels` itself, or
    the encoded values of an sRGB map looked up Linear); `scale` (3,) float64 what
    multiplies a decoded lookup (the strength; ones when `stored` is `pixels`, whose
    texels hold it); `interp_code` the kernels' lookup code (INTERP_*).
    """

    def __init__(self, pixels, strength=1.0, rotation=None, interpolation="Linear",
                 name="environment", srgb=False):
        self.name = name
        who = f"environment '{name}'"
        a = np.asarray(pixels, dtype=np.float32)
        if a.ndim == 2:
            a = np.repeat(a[:, :, None], 3, axis=2)
        if a.ndim != 3 or a.shape[2] not in (3, 4) or a.shape[0] < 1 or a.shape[1] < 1:
            raise ValueError(f"{who}: expected an HxWx3 image, got shape {a.shape}")
        a = a[:, :, :3]
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{who}: the image has NaN or infinite texels")
        if np.any(a < 0):
            raise ValueError(f"{who}: the image has negative texels (radiance must be >= 0)")
        s = np.broadcast_to(np.asarray(strength, np.float64), (3,)).copy()
        if not (np.all(np.isfinite(s)) and np.all(s >= 0)):
            raise ValueError(f"{who} strength: expected finite values >= 0, got {strength!r}")
        R = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)) or not np.allclose(
                R @ R.T, np.eye(3), atol=1e-6) or not np.linalg.det(R) > 0:
            raise ValueError(f"{who} rotation: expected a 3x3 rotation matrix, got {R.tolist()}")
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"{who} interpolation: expected one of {tuple(INTERPOLATIONS)}, "
                             f"got {interpolation!r}")
        self.srgb = bool(srgb)
        encoded = a
        if self.srgb:
            a = srgb_decode(a).astype(np.float32)
        # Strength folded in: radiance texels, float32 like the image files (an 8k x 4k
        # HDRI: 400 MB as float32, twice that as float64).
        self.pixels = np.ascontiguousarray(a * s.astype(np.float32))
        if not np.all(np.isfinite(self.pixels)):
            raise ValueError(f"{who}: image x strength overflows float32 radiance")
        self.strength = s
        self.rotation = np.ascontiguousarray(R)
        self.interpolation = interpolation
        self.interp_code = INTERPOLATIONS[interpolation]
        self.stored = self.pixels
        self.scale = np.ones(3)
        if self.srgb and interpolation == "Linear":
            # The encoded texels are interpolated, decoded after and scaled by the
            # strength (a Closest lookup reads one texel: decoded first is the same).
            self.stored = np.ascontiguousarray(encoded)
            self.scale = s.copy()
            self.interp_code = INTERP_LINEAR_SRGB
        self._distribution = None
        self._cosine = None

    def __setstate__(self, state):
        # A pickle from before sRGB-stored maps (e.g. tools/film_hashes' exported
        # scenes) holds linear texels only: its lookup reads them.
        self.__dict__.update(state)
        if "stored" not in state:
            self.stored, self.scale, self.srgb = self.pixels, np.ones(3), False

    @property
    def height(self) -> int:
        return self.pixels.shape[0]

    @property
    def width(self) -> int:
        return self.pixels.shape[1]

    @property
    def is_black(self) -> bool:
        return not np.any(self.pixels > 0)

    # ------------------------------------------------------------------ distribution
    @property
    def distribution(self):
        """(row cdf (H+1,), per-row column cdfs (H, W+1) float64, pdf_uv (H, W) float32) of the 2D
        piecewise-constant distribution (see the module docstring); built once."""
        if self._distribution is None:
            self._distribution = build_distribution(self.pixels,
                                                    self.interp_code != INTERP_CLOSEST)
        return self._distribution

    @property
    def cosine_distributions(self):
        """build_cosine_distributions of this map (rows, cols, mass, prefix, cell); built
        once."""
        if getattr(self, "_cosine", None) is None:
            self._cosine = build_cosine_distributions(self.pixels,
                                                      self.interp_code != INTERP_CLOSEST)
        return self._cosine

    def cosine_pdf(self, wi: np.ndarray, ns: np.ndarray) -> np.ndarray:
        """Solid-angle pdf (N,) (1/sr) with which `cosine_sample` picks world directions
        wi (N,3) at shading normals ns (N,3)."""
        # np.require(..., "W"): one kernel type whether ns was broadcast (a readonly view)
        # or copied (numba compiles readonly arrays apart: a compile inside a render).
        wi = np.require(np.asarray(wi, np.float64).reshape(-1, 3), None, ["C", "W"])
        ns = np.require(np.broadcast_to(np.asarray(ns, np.float64).reshape(-1, 3), wi.shape),
                        None, ["C", "W"])
        out = np.empty(len(wi))
        _, _, mass, prefix, cell = self.cosine_distributions
        cosine_pdf_many(wi, ns, self.rotation, self.pixels, self.interp_code, mass, prefix,
                        cell, N_OCT, out)
        return out

    def cosine_sample(self, u1: np.ndarray, u2: np.ndarray, ns: np.ndarray):
        """Directions wi (N,3) drawn from the cosine-weighted distribution of the cluster
        of each shading normal ns (N,3) (build_cosine_distributions), with their
        solid-angle pdfs (N,)."""
        u1 = np.require(u1, np.float64, ["C", "W"])
        u2 = np.require(u2, np.float64, ["C", "W"])
        ns = np.require(np.broadcast_to(np.asarray(ns, np.float64).reshape(-1, 3),
                                        (len(u1), 3)), None, ["C", "W"])
        wi = np.empty((len(u1), 3))
        pdf = np.empty(len(u1))
        cosine_sample_many(u1, u2, ns, self.rotation, self.pixels, self.interp_code,
                           *self.cosine_distributions, N_OCT, wi, pdf)
        return wi, pdf

    def integral(self) -> np.ndarray:
        """RGB integral of radiance over the sphere (W / m^2): the sum of texel radiance x
        texel solid angle (of the decoded texels for an sRGB map: an upper bound of its
        decoded-after interpolation's, by a few % at sharp edges; it only apportions
        photons and light choices, whose estimators divide by what they chose). The flux
        crossing a disk of radius R from all directions is this x pi R^2 (the world's
        photon flux)."""
        H, W = self.height, self.width
        theta0 = PI * np.arange(H) / H
        theta1 = PI * (np.arange(H) + 1) / H
        omega = (np.cos(theta0) - np.cos(theta1)) * TWO_PI / W  # per texel of each row
        return np.einsum("hwc,h->c", self.pixels.astype(np.float64), omega)

    def average(self) -> np.ndarray:
        """Mean radiance over the sphere (RGB)."""
        return self.integral() / (4.0 * PI)

    # ------------------------------------------------------------------ numpy front ends
    def radiance(self, d: np.ndarray) -> np.ndarray:
        """Radiance (N,3) seen along world directions d (N,3) (need not be unit)."""
        d = np.ascontiguousarray(np.asarray(d, np.float64).reshape(-1, 3))
        out = np.empty((len(d), 3))
        radiance_many(d, self.rotation, self.stored, self.interp_code, self.scale, out)
        return out

    def pdf(self, wi: np.ndarray) -> np.ndarray:
        """Solid-angle pdf (N,) (1/sr) with which `sample` picks world directions wi (N,3)."""
        wi = np.ascontiguousarray(np.asarray(wi, np.float64).reshape(-1, 3))
        out = np.empty(len(wi))
        _, _, pdf_uv = self.distribution
        pdf_many(wi, self.rotation, self.pixels, self.interp_code, pdf_uv, out)
        return out

    def sample(self, u1: np.ndarray, u2: np.ndarray):
        """Directions wi (N,3) drawn in proportion to the distribution from uniform
        numbers u1, u2 (N,), with their solid-angle pdfs (N,)."""
        u1 = np.ascontiguousarray(u1, np.float64)
        u2 = np.ascontiguousarray(u2, np.float64)
        wi = np.empty((len(u1), 3))
        pdf = np.empty(len(u1))
        rows, cols, pdf_uv = self.distribution
        sample_many(u1, u2, self.rotation, self.pixels, self.interp_code, rows, cols, pdf_uv,
                    wi, pdf)
        return wi, pdf


def texel_function(pixels: np.ndarray, bilinear: bool = True) -> np.ndarray:
    """(H, W) float64: the map distribution's function on each texel of radiance texels
    (H, W, 3): luminance (the mean of its bilinear interpolation over the texel when
    `bilinear`) x sin(theta) at the row centre (see the module docstring)."""
    H = pixels.shape[0]
    f = np.maximum(luminance(np.asarray(pixels, np.float64)), 0.0)
    if bilinear:
        # Mean of the bilinear interpolation over a texel: weights 3/4, 1/8, 1/8 per axis
        # (texels wrap around, as the lookup's Repeat extension).
        f = 0.75 * f + 0.125 * (np.roll(f, 1, axis=1) + np.roll(f, -1, axis=1))
        f = 0.75 * f + 0.125 * (np.roll(f, 1, axis=0) + np.roll(f, -1, axis=0))
    sin_t = np.sin(PI * (np.arange(H) + 0.5) / H)
    return f * sin_t[:, None]


def build_distribution(pixels: np.ndarray, bilinear: bool = True):
    """The sampling distribution of radiance texels (H, W, 3): see Environment.distribution.
    bilinear: the lookups interpolate (a texel's function is the mean of the interpolated
    luminance over it); else each texel's own luminance (Closest)."""
    H, W = pixels.shape[:2]
    f = texel_function(pixels, bilinear)
    row_sum = f.sum(axis=1)
    total = row_sum.sum()
    if not total > 0:
        z = np.zeros((H, W), np.float32)
        return np.linspace(0.0, 1.0, H + 1), np.tile(np.linspace(0.0, 1.0, W + 1), (H, 1)), z
    rows = np.concatenate([[0.0], np.cumsum(row_sum)]) / total
    rows[-1] = 1.0
    safe = np.where(row_sum > 0, row_sum, 1.0)
    cols = np.concatenate([np.zeros((H, 1)), np.cumsum(f, axis=1)], axis=1) / safe[:, None]
    cols[row_sum <= 0] = np.linspace(0.0, 1.0, W + 1)
    cols[:, -1] = 1.0
    pdf_uv = f * (H * W) / total
    return (np.ascontiguousarray(rows), np.ascontiguousarray(cols),
            np.ascontiguousarray(pdf_uv, dtype=np.float32))



# Cosine-weighted distributions (shadow rays of diffuse and rough lobes): the map's
# function times the cosine to a shading normal, so no sample is spent below the
# surface's horizon and a bright patch low over it gets what its irradiance is worth.
# Shading normals fall into N_OCT x N_OCT clusters of an octahedral grid (odd: +Z, a
# floor's normal, is the centre of a cell); each cluster has a distribution over a coarse
# grid of at most COARSE_H x COARSE_W cells of texels, proportional to the map's function
# summed over the cell times the largest cosine to the cluster's normal over the cell's
# corners, edge midpoints and centre, plus a share of the largest to any normal of the
# cluster (SPREAD_SHARE). Within a cell a texel is drawn in proportion to the map's function
# (the per-row prefix sums), so a sun of a few texels is found as exactly as by the map's
# own distribution. The shadow rays mix this with cosine-hemisphere sampling
# (engine/lights/world.py), a safety net for what the coarse cells' bound misses.
N_OCT = 9
# A cell's weight: the cosine to the cluster's centre plus SPREAD_SHARE x the largest
# cosine to any normal of the cluster (the centre's at the angle less the cluster's
# spread, 11-25 degrees). Without the second term a normal near the cluster's edge saw a
# sun that sets for the centre (a ball's terminator) only through the cosine hemisphere's
# rare hits: fireflies, per-sample relative variance up to ~6000 at 80-88 degrees from a
# 2-degree sun. With 0.1: at most 0.44 there, 0.039 -> 0.045 facing the sun (0.05: 1.04
# and 0.042; 0.15: 0.40 and 0.048; the bound alone: 0.98 and 0.13; docs/performance.md).
SPREAD_SHARE = 0.1
COARSE_H, COARSE_W = 64, 128


def _octahedral_decode(a, b):
    """Unit vectors (..., 3) at octahedral coordinates a, b in [-1, 1] (arrays)."""
    a, b = np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(b, np.float64))
    z = 1.0 - np.abs(a) - np.abs(b)
    fold = z < 0
    a, b = (np.where(fold, (1.0 - np.abs(b)) * np.where(a >= 0, 1.0, -1.0), a),
            np.where(fold, (1.0 - np.abs(a)) * np.where(b >= 0, 1.0, -1.0), b))
    v = np.stack([a, b, z], -1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def octahedral_centre(k: int, n_oct: int = N_OCT) -> np.ndarray:
    """Unit normal (3,) at the centre of octahedral cell k = row * n_oct + column."""
    return _octahedral_decode((k % n_oct + 0.5) / n_oct * 2.0 - 1.0,
                              (k // n_oct + 0.5) / n_oct * 2.0 - 1.0)


def octahedral_spread(k: int, n_oct: int = N_OCT, steps: int = 17) -> float:
    """Largest angle (radians) between cell k's centre normal and the normals of its cell,
    from a steps x steps grid over the cell, edges included (the cells are small, so the
    grid finds the largest within a fraction of a degree)."""
    t = np.linspace(0.0, 1.0, steps)
    a = (k % n_oct + t) / n_oct * 2.0 - 1.0
    b = (k // n_oct + t) / n_oct * 2.0 - 1.0
    v = _octahedral_decode(a[None, :], b[:, None]).reshape(-1, 3)
    return float(np.arccos(np.clip(v @ octahedral_centre(k, n_oct), -1.0, 1.0)).max())


def _cell_directions(theta, u):
    """Texture directions (..., 3) at polar angles theta and image u (arrays)."""
    theta, u = np.broadcast_arrays(theta, u)
    phi = TWO_PI * (0.5 - u)
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], -1)


def build_cosine_distributions(pixels: np.ndarray, bilinear: bool = True,
                               n_oct: int = N_OCT, coarse=(COARSE_H, COARSE_W)):
    """The cosine-weighted distributions of radiance texels (H, W, 3) (see above):
    (rows (K, Hc+1), cols (K, Hc, Wc+1) cdfs and mass (K, Hc, Wc) probabilities of the
    coarse cells per cluster, float64; prefix (H, W+1) float64 per-row prefix sums of the
    map's function; cell (Hc, Wc) float64 the function summed over each cell, from the
    prefix sums), K = n_oct^2. Cell I spans texel rows I H // Hc .. (I+1) H // Hc."""
    H, W = pixels.shape[:2]
    f = texel_function(pixels, bilinear)
    prefix = np.concatenate([np.zeros((H, 1)), np.cumsum(f, axis=1)], axis=1)
    Hc, Wc = min(H, coarse[0]), min(W, coarse[1])
    rb = np.arange(Hc + 1) * H // Hc
    cb = np.arange(Wc + 1) * W // Wc
    per_row = prefix[:, cb[1:]] - prefix[:, cb[:-1]]                     # (H, Wc)
    cell = np.add.reduceat(per_row, rb[:-1], axis=0)                     # (Hc, Wc)
    # Cosine factor: the largest cosine over 3 x 3 points of each cell (corners, edge
    # midpoints, centre), clamped at 0.
    th = PI * rb / H
    uu = cb / W
    th3 = np.stack([th[:-1], 0.5 * (th[:-1] + th[1:]), th[1:]], -1)   # (Hc, 3)
    u3 = np.stack([uu[:-1], 0.5 * (uu[:-1] + uu[1:]), uu[1:]], -1)     # (Wc, 3)
    pts = _cell_directions(th3[:, None, :, None], u3[None, :, None, :])  # (Hc, Wc, 3, 3, 3)
    K = n_oct * n_oct
    normals = np.array([octahedral_centre(k, n_oct) for k in range(K)])
    rows = np.empty((K, Hc + 1))
    cols = np.empty((K, Hc, Wc + 1))
    mass = np.empty((K, Hc, Wc))
    flat = pts.reshape(Hc, Wc, 9, 3)
    for k in range(K):
        # The centre's cosine, plus a share of the largest over the cluster (SPREAD_SHARE).
        cmax = (flat @ normals[k]).max(axis=2)
        angle = np.arccos(np.clip(cmax, -1.0, 1.0))
        c = (np.maximum(cmax, 0.0) + SPREAD_SHARE
             * np.cos(np.minimum(np.maximum(angle - octahedral_spread(k, n_oct), 0.0), HALF_PI)))
        m = cell * c
        if not m.sum() > 0:
            m = cell  # nothing above this cluster's horizon: the map's own (any is unbiased)
        total = m.sum()
        if not total > 0:
            m = np.ones((Hc, Wc))
            total = m.sum()
        rs = m.sum(axis=1)
        rows[k] = np.concatenate([[0.0], np.cumsum(rs)]) / total
        rows[k, -1] = 1.0
        safe = np.where(rs > 0, rs, 1.0)
        cc = np.concatenate([np.zeros((Hc, 1)), np.cumsum(m, axis=1)], axis=1) / safe[:, None]
        cc[rs <= 0] = np.linspace(0.0, 1.0, Wc + 1)
        cc[:, -1] = 1.0
        cols[k] = cc
        mass[k] = m / total
    return (np.ascontiguousarray(rows), np.ascontiguousarray(cols), np.ascontiguousarray(mass),
            np.ascontiguousarray(prefix), np.ascontiguousarray(cell))

# ---------------------------------------------------------------------- kernels
@kernel
def env_uv(x, y, z):
    """Texture direction (need not be unit) -> (u, v) as Cycles' equirectangular map."""
    length = math.sqrt(x * x + y * y + z * z)
    if not length > 0:
        return 0.5, 0.5
    c = min(max(z / length, -1.0), 1.0)
    return 0.5 - math.atan2(y, x) / TWO_PI, 1.0 - math.acos(c) / PI


@kernel
def env_rotate(R, d0, d1, d2):
    """R @ d."""
    return (R[0, 0] * d0 + R[0, 1] * d1 + R[0, 2] * d2,
            R[1, 0] * d0 + R[1, 1] * d1 + R[1, 2] * d2,
            R[2, 0] * d0 + R[2, 1] * d1 + R[2, 2] * d2)


@kernel
def _wrap(i, n):
    """i mod n (Repeat; Python's sign convention), n >= 1. Texel indices are at most one
    texel outside [0, n) (a neighbour, or u = 1 / v = 0 exactly): those are wrapped by a
    compare, the general case by `%`. Same value as `i % n`, but the sampling kernels do
    ~20 of these a sample and a 64-bit integer division costs ~40-90 cycles on this
    machine's Intel cores (the world light's sampling was ~390 ns a row, issue 13)."""
    if i >= 0:
        if i < n:
            return i
        if i == n:
            return 0
    elif i == -1:
        return n - 1
    return i % n


@kernel
def srgb_decode_value(c):
    """Cycles' color_srgb_to_linear (util/color.h) of one value (imageio.srgb_decode's
    kernel): 0 below 0, no clip above 1."""
    if c < 0.04045:
        return c / 12.92 if c > 0.0 else 0.0
    return ((c + 0.055) / 1.055) ** 2.4


@kernel
def env_lookup(px, interp, u, v):
    """Texel values (r, g, b) at image coordinates (u, v): texel centres at (i + 0.5) / W,
    v = 1 at the top row; Repeat extension. Closest (interp 0) or bilinear (else)."""
    H = px.shape[0]
    W = px.shape[1]
    x = u * W
    y = (1.0 - v) * H
    if interp == 0:
        ix = _wrap(int(math.floor(x)), W)
        iy = _wrap(int(math.floor(y)), H)
        return px[iy, ix, 0], px[iy, ix, 1], px[iy, ix, 2]
    x -= 0.5
    y -= 0.5
    fx0 = math.floor(x)
    fy0 = math.floor(y)
    fx = x - fx0
    fy = y - fy0
    x0 = _wrap(int(fx0), W)
    y0 = _wrap(int(fy0), H)
    x1 = x0 + 1 if x0 + 1 < W else 0
    y1 = y0 + 1 if y0 + 1 < H else 0
    w00 = (1.0 - fx) * (1.0 - fy)
    w10 = fx * (1.0 - fy)
    w01 = (1.0 - fx) * fy
    w11 = fx * fy
    r = w00 * px[y0, x0, 0] + w10 * px[y0, x1, 0] + w01 * px[y1, x0, 0] + w11 * px[y1, x1, 0]
    g = w00 * px[y0, x0, 1] + w10 * px[y0, x1, 1] + w01 * px[y1, x0, 1] + w11 * px[y1, x1, 1]
    b = w00 * px[y0, x0, 2] + w10 * px[y0, x1, 2] + w01 * px[y1, x0, 2] + w11 * px[y1, x1, 2]
    return r, g, b


@kernel
def env_radiance(R, stored, interp, scale, d0, d1, d2):
    """Radiance along world direction d: the lookup of Environment.stored, decoded after
    and times scale (3,) for INTERP_LINEAR_SRGB (svm_image_texture's order)."""
    t0, t1, t2 = env_rotate(R, d0, d1, d2)
    u, v = env_uv(t0, t1, t2)
    r, g, b = env_lookup(stored, interp, u, v)
    if interp == INTERP_LINEAR_SRGB:
        return (srgb_decode_value(r) * scale[0], srgb_decode_value(g) * scale[1],
                srgb_decode_value(b) * scale[2])
    return r, g, b


ONE_BELOW = 0.9999999999999999  # the largest float64 below 1


@kernel
def _texel_lum(px, i, j):
    """Luminance of texel (row i, column j), both wrapped (Repeat), as sampling.luminance."""
    return _lum_at(px, _wrap(i, px.shape[0]), _wrap(j, px.shape[1]))


@kernel
def _lum_at(px, a, b):
    """Luminance of texel (row a, column b), both in range, as sampling.luminance."""
    return px[a, b, 0] * 0.2126 + px[a, b, 1] * 0.7152 + px[a, b, 2] * 0.0722


@kernel
def _lum9(px, i, j):
    """Luminances of the 3 x 3 texels around (row i, column j), wrapped (Repeat):
    (lmm, lm0, lmp, l0m, l00, l0p, lpm, lp0, lpp), lXY at row offset X, column offset Y
    (m / 0 / p: -1 / 0 / +1). The neighbours' rows and columns are wrapped once each (4
    wraps, not 18 as nine _texel_lum calls would)."""
    H = px.shape[0]
    W = px.shape[1]
    i0 = _wrap(i, H)
    j0 = _wrap(j, W)
    im = i0 - 1 if i0 > 0 else H - 1
    ip = i0 + 1 if i0 + 1 < H else 0
    jm = j0 - 1 if j0 > 0 else W - 1
    jp = j0 + 1 if j0 + 1 < W else 0
    return (_lum_at(px, im, jm), _lum_at(px, im, j0), _lum_at(px, im, jp),
            _lum_at(px, i0, jm), _lum_at(px, i0, j0), _lum_at(px, i0, jp),
            _lum_at(px, ip, jm), _lum_at(px, ip, j0), _lum_at(px, ip, jp))


@kernel
def _sample_linear(u, a, b):
    """x in [0, 1) with density proportional to (1 - x) a + x b, a, b >= 0 (pbrt-v4's
    SampleLinear); u where both are 0."""
    s = a + b
    if not s > 0:
        return u
    den = a + math.sqrt((1.0 - u) * a * a + u * b * b)
    if not den > 0:
        return 0.0
    return min(u * s / den, ONE_BELOW)


@kernel
def _sample_tent(u, v0, vm, v1):
    """x in [0, 1) with density proportional to the piecewise-linear function of values
    v0 at 0, vm at 1/2 and v1 at 1 (all >= 0); u where it is 0 everywhere."""
    a0 = v0 + vm
    a1 = vm + v1
    t = a0 + a1
    if not t > 0:
        return u
    x = u * t
    if x < a0:
        return 0.5 * _sample_linear(min(x / a0, ONE_BELOW), v0, vm)
    return min(0.5 + 0.5 * _sample_linear(min((x - a0) / a1, ONE_BELOW), vm, v1), ONE_BELOW)


@kernel
def _hats(x):
    """Bilinear weights of the neighbours -1, 0, +1 at offset x in [0, 1] across a texel
    (its centre at 1/2)."""
    return max(0.5 - x, 0.0), 1.0 - abs(x - 0.5), max(x - 0.5, 0.0)


@kernel
def texel_warp(px, interp, i, j, ux, uy):
    """(fx, fy, ratio): the point (fx, fy) in [0,1)^2 of texel (row i, column j) for
    uniform (ux, uy), distributed as the bilinearly interpolated luminance over the texel
    (fy from its marginal, then fx given fy; each a tent through the texel's centre),
    and the density there: that luminance over its mean over the texel. Closest (interp
    0): (ux, uy, 1)."""
    if interp == 0:
        return ux, uy, 1.0
    # The 3 x 3 neighbourhood's luminances, read once (lXY: row X, column Y; m / 0 / p
    # for -1 / 0 / +1): the marginal and the conditional below both use all nine.
    lmm, lm0, lmp, l0m, l00, l0p, lpm, lp0, lpp = _lum9(px, i, j)
    # row sums M_b of the three rows (b = -1, 0, +1) over the texel's width
    m_m = 0.125 * lmm + 0.75 * lm0 + 0.125 * lmp
    m_0 = 0.125 * l0m + 0.75 * l00 + 0.125 * l0p
    m_p = 0.125 * lpm + 0.75 * lp0 + 0.125 * lpp
    mean = 0.125 * m_m + 0.75 * m_0 + 0.125 * m_p
    if not mean > 0:
        return ux, uy, 1.0
    fy = _sample_tent(uy, 0.5 * (m_m + m_0), m_0, 0.5 * (m_0 + m_p))
    fx, value = _tent_given_row(lmm, lm0, lmp, l0m, l00, l0p, lpm, lp0, lpp, fy, ux)
    return fx, fy, value / mean


@kernel
def _tent_given_row(lmm, lm0, lmp, l0m, l00, l0p, lpm, lp0, lpp, fy, ux):
    """(fx, value): fx drawn from the interpolated luminance along row offset fy of a
    texel whose 3 x 3 neighbourhood has luminances lXY (row X, column Y, m / 0 / p for
    -1 / 0 / +1: texel_warp), and the luminance at (fx, fy)."""
    hm, h0, hp = _hats(fy)
    r_m = hm * lmm + h0 * l0m + hp * lpm
    r_0 = hm * lm0 + h0 * l00 + hp * lp0
    r_p = hm * lmp + h0 * l0p + hp * lpp
    fx = _sample_tent(ux, 0.5 * (r_m + r_0), r_0, 0.5 * (r_0 + r_p))
    gm, g0, gp = _hats(fx)
    return fx, gm * r_m + g0 * r_0 + gp * r_p


@kernel
def texel_ratio(px, interp, i, j, fx, fy):
    """The density of texel_warp at (fx, fy) in texel (i, j): the interpolated luminance
    there over its mean over the texel (1 for Closest or a black neighbourhood)."""
    if interp == 0:
        return 1.0
    hm, h0, hp = _hats(fy)
    gm, g0, gp = _hats(fx)
    lmm, lm0, lmp, l0m, l00, l0p, lpm, lp0, lpp = _lum9(px, i, j)
    # sum over rows b (-1, 0, +1), then columns a, of the hats' weights (value) and of the
    # tents' means (mean, 1/8 3/4 1/8) times the luminances, in that order (its rounding)
    c1 = 0.125
    c0 = 0.75
    value = 0.0
    mean = 0.0
    value += hm * gm * lmm
    mean += c1 * c1 * lmm
    value += hm * g0 * lm0
    mean += c1 * c0 * lm0
    value += hm * gp * lmp
    mean += c1 * c1 * lmp
    value += h0 * gm * l0m
    mean += c0 * c1 * l0m
    value += h0 * g0 * l00
    mean += c0 * c0 * l00
    value += h0 * gp * l0p
    mean += c0 * c1 * l0p
    value += hp * gm * lpm
    mean += c1 * c1 * lpm
    value += hp * g0 * lp0
    mean += c1 * c0 * lp0
    value += hp * gp * lpp
    mean += c1 * c1 * lpp
    if not mean > 0:
        return 1.0
    return value / mean


@kernel
def _texel_at(t0, t1, t2, H, W):
    """(i, j, fx, fy, sin theta) of texture direction t: its texel and the offsets in it;
    sin theta 0 for a zero or polar direction."""
    length = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    if not length > 0:
        return 0, 0, 0.5, 0.5, 0.0
    sin_t = math.sqrt(t0 * t0 + t1 * t1) / length
    u, v = env_uv(t0, t1, t2)
    x = u * W
    y = (1.0 - v) * H
    j = min(max(int(x), 0), W - 1)
    i = min(max(int(y), 0), H - 1)
    fx = min(max(x - j, 0.0), 1.0)
    fy = min(max(y - i, 0.0), 1.0)
    return i, j, fx, fy, sin_t


@kernel
def env_pdf(R, px, interp, pdf_uv, d0, d1, d2):
    """Solid-angle pdf of world direction d under the distribution (px, interp: the
    radiance texels and interpolation, for the density within the texel)."""
    t0, t1, t2 = env_rotate(R, d0, d1, d2)
    H = pdf_uv.shape[0]
    W = pdf_uv.shape[1]
    i, j, fx, fy, sin_t = _texel_at(t0, t1, t2, H, W)
    if not sin_t > 0:
        return 0.0
    p = pdf_uv[i, j]
    if not p > 0:
        return 0.0
    return p * texel_ratio(px, interp, i, j, fx, fy) / (2.0 * PI * PI * sin_t)


@kernel
def _find_interval(cdf, n, x):
    """Largest index i in [0, n-1] with cdf[i] <= x (cdf has n + 1 entries, non-decreasing);
    0 when there is none. Branch-free halving (the select compiles to a conditional move):
    x is random, so a branching search mispredicts about half its steps."""
    base = 0
    length = n
    while length > 1:
        half = length >> 1
        if cdf[base + half] <= x:
            base += half
        length -= half
    return base


@kernel
def env_sample(R, px, interp, rows, cols, pdf_uv, u1, u2):
    """A world direction drawn from the distribution with its solid-angle pdf:
    (d0, d1, d2, pdf); pdf 0 when the environment is black."""
    d0, d1, d2, pdf, i, j, fx, fy = env_sample_texel(R, px, interp, rows, cols, pdf_uv, u1, u2)
    return d0, d1, d2, pdf


@kernel
def env_sample_texel(R, px, interp, rows, cols, pdf_uv, u1, u2):
    """env_sample's direction and pdf, and where in the map it was drawn: (d0, d1, d2,
    pdf, i, j, fx, fy), texel row i, column j and the offsets (fx, fy) in [0,1]^2 inside
    it (texel_radiance reads the radiance there without the direction's round trip)."""
    H = pdf_uv.shape[0]
    W = pdf_uv.shape[1]
    i = _find_interval(rows, H, u1)
    span = rows[i + 1] - rows[i]
    fy = (u1 - rows[i]) / span if span > 0 else 0.5
    fy = min(max(fy, 0.0), 1.0)
    j = _find_interval(cols[i], W, u2)
    span = cols[i, j + 1] - cols[i, j]
    fx = (u2 - cols[i, j]) / span if span > 0 else 0.5
    fx = min(max(fx, 0.0), 1.0)
    fx, fy, ratio = texel_warp(px, interp, i, j, fx, fy)
    d0, d1, d2, pdf = texel_direction(i, j, fx, fy, H, W, R, pdf_uv[i, j] * ratio)
    return d0, d1, d2, pdf, i, j, fx, fy


@kernel
def texel_radiance(stored, interp, scale, i, j, fx, fy):
    """Radiance at the point (fx, fy) in [0,1]^2 of texel (row i, column j), as
    env_radiance reads it along that point's direction (texel_direction), without the
    direction: no rotation, square root, atan2 or acos (the photons of a map light,
    issue 13: ~30 % of their emission). Closest: the texel itself; Linear: the bilinear
    weights of env_lookup's four texels from the offsets (a neighbour row or column on
    the offset's side of the centre, wrapped: Repeat); INTERP_LINEAR_SRGB decoded after
    and times scale. Equal to env_radiance of texel_direction's direction up to the
    round trip's rounding (the point's u, v recovered through atan2 and acos: relative
    ~1e-15, at most ~1e-11 where a weight is nearly 0); at a texel's very edge the round
    trip may land in the neighbour, where Closest reads the neighbour's value and this
    the texel's own, the one the pdf was drawn from."""
    H = stored.shape[0]
    W = stored.shape[1]
    if interp == 0:
        return np.float64(stored[i, j, 0]), np.float64(stored[i, j, 1]), np.float64(stored[i, j, 2])
    if fx < 0.5:
        x0 = j - 1 if j > 0 else W - 1
        x1 = j
        ax = fx + 0.5
    else:
        x0 = j
        x1 = j + 1 if j + 1 < W else 0
        ax = fx - 0.5
    if fy < 0.5:
        y0 = i - 1 if i > 0 else H - 1
        y1 = i
        ay = fy + 0.5
    else:
        y0 = i
        y1 = i + 1 if i + 1 < H else 0
        ay = fy - 0.5
    w00 = (1.0 - ax) * (1.0 - ay)
    w10 = ax * (1.0 - ay)
    w01 = (1.0 - ax) * ay
    w11 = ax * ay
    r = (w00 * stored[y0, x0, 0] + w10 * stored[y0, x1, 0] + w01 * stored[y1, x0, 0]
         + w11 * stored[y1, x1, 0])
    g = (w00 * stored[y0, x0, 1] + w10 * stored[y0, x1, 1] + w01 * stored[y1, x0, 1]
         + w11 * stored[y1, x1, 1])
    b = (w00 * stored[y0, x0, 2] + w10 * stored[y0, x1, 2] + w01 * stored[y1, x0, 2]
         + w11 * stored[y1, x1, 2])
    if interp == INTERP_LINEAR_SRGB:
        return (srgb_decode_value(r) * scale[0], srgb_decode_value(g) * scale[1],
                srgb_decode_value(b) * scale[2])
    return r, g, b


@kernel
def texel_direction(i, j, fx, fy, H, W, R, p):
    """The world direction at (fx, fy) in [0,1]^2 inside texel (row i, column j) of an
    H x W equirectangular map rotated by R (3,3), and the solid-angle pdf of texel pdf p
    (per unit of the map's uv square): p / (2 pi^2 sin theta); 0 where p or sin theta is
    0. Returns (d0, d1, d2, pdf)."""
    theta = PI * (i + fy) / H
    u = (j + fx) / W
    phi = TWO_PI * (0.5 - u)
    st = math.sin(theta)
    t0, t1, t2 = st * math.cos(phi), st * math.sin(phi), math.cos(theta)
    # back to world: R is a rotation, its inverse its transpose
    d0 = R[0, 0] * t0 + R[1, 0] * t1 + R[2, 0] * t2
    d1 = R[0, 1] * t0 + R[1, 1] * t1 + R[2, 1] * t2
    d2 = R[0, 2] * t0 + R[1, 2] * t1 + R[2, 2] * t2
    if not (p > 0 and st > 0):
        return d0, d1, d2, 0.0
    return d0, d1, d2, p / (2.0 * PI * PI * st)


@kernel
def octahedral_cell(n_oct, x, y, z):
    """Octahedral cell (row * n_oct + column) of direction (x, y, z) (need not be unit;
    0: cell of +Z)."""
    s = abs(x) + abs(y) + abs(z)
    if not s > 0:
        return (n_oct // 2) * n_oct + n_oct // 2
    a = x / s
    b = y / s
    if z < 0:
        a, b = (1.0 - abs(y / s)) * (1.0 if x >= 0 else -1.0), (1.0 - abs(x / s)) * (
            1.0 if y >= 0 else -1.0)
    ix = min(max(int((a + 1.0) * 0.5 * n_oct), 0), n_oct - 1)
    iy = min(max(int((b + 1.0) * 0.5 * n_oct), 0), n_oct - 1)
    return iy * n_oct + ix


@kernel
def _cosine_texel_pdf(c_mass, prefix, cell, k, i, j):
    """pdf_uv of texel (i, j) under cluster k's cosine-weighted distribution."""
    H = prefix.shape[0]
    W = prefix.shape[1] - 1
    Hc = cell.shape[0]
    Wc = cell.shape[1]
    # the texel's cell: the largest I with I H // Hc <= i (i itself when the map is no
    # larger than the coarse grid: then cells are texels, and no integer division)
    if Hc == H:
        I = i
    else:
        I = min((i * Hc + Hc - 1) // H, Hc - 1)
        while I > 0 and (I * H) // Hc > i:
            I -= 1
        while I < Hc - 1 and ((I + 1) * H) // Hc <= i:
            I += 1
    if Wc == W:
        J = j
    else:
        J = min((j * Wc + Wc - 1) // W, Wc - 1)
        while J > 0 and (J * W) // Wc > j:
            J -= 1
        while J < Wc - 1 and ((J + 1) * W) // Wc <= j:
            J += 1
    return _cell_texel_pdf(c_mass, prefix, cell, k, I, J, i, j)


@kernel
def _cell_texel_pdf(c_mass, prefix, cell, k, I, J, i, j):
    """_cosine_texel_pdf of texel (i, j) given its coarse cell (I, J) (env_cosine_sample
    knows it: the search there costs integer divisions)."""
    H = prefix.shape[0]
    W = prefix.shape[1] - 1
    cf = cell[I, J]
    if not cf > 0:
        return 0.0
    return c_mass[k, I, J] * (prefix[i, j + 1] - prefix[i, j]) / cf * (H * W)


@kernel
def _cell_start(I, n, n_coarse):
    """First texel I n // n_coarse of coarse cell I (build_cosine_distributions); I itself,
    without the integer division, when cells are texels (n == n_coarse)."""
    if n == n_coarse:
        return I
    return (I * n) // n_coarse


@kernel
def env_cosine_pdf(R, px, interp, c_mass, prefix, cell, n_oct, d0, d1, d2, s0, s1, s2):
    """Solid-angle pdf of world direction d under the cosine-weighted distribution of the
    cluster of shading normal s (world space); px, interp as env_pdf."""
    t0, t1, t2 = env_rotate(R, d0, d1, d2)
    H = prefix.shape[0]
    W = prefix.shape[1] - 1
    i, j, fx, fy, sin_t = _texel_at(t0, t1, t2, H, W)
    if not sin_t > 0:
        return 0.0
    m0, m1, m2 = env_rotate(R, s0, s1, s2)
    k = octahedral_cell(n_oct, m0, m1, m2)
    p = _cosine_texel_pdf(c_mass, prefix, cell, k, i, j)
    if not p > 0:
        return 0.0
    return p * texel_ratio(px, interp, i, j, fx, fy) / (2.0 * PI * PI * sin_t)


@kernel
def env_cosine_sample(R, px, interp, c_rows, c_cols, c_mass, prefix, cell, n_oct, s0, s1, s2,
                      u1, u2):
    """A world direction drawn from the cosine-weighted distribution of the cluster of
    shading normal s: (d0, d1, d2, pdf); pdf 0 where nothing can be drawn."""
    H = prefix.shape[0]
    W = prefix.shape[1] - 1
    Hc = cell.shape[0]
    Wc = cell.shape[1]
    m0, m1, m2 = env_rotate(R, s0, s1, s2)
    k = octahedral_cell(n_oct, m0, m1, m2)
    rows = c_rows[k]
    I = _find_interval(rows, Hc, u1)
    span = rows[I + 1] - rows[I]
    a = (u1 - rows[I]) / span if span > 0 else 0.5
    a = min(max(a, 0.0), 0.9999999999999999)
    cols = c_cols[k, I]
    J = _find_interval(cols, Wc, u2)
    span = cols[J + 1] - cols[J]
    b = (u2 - cols[J]) / span if span > 0 else 0.5
    b = min(max(b, 0.0), 0.9999999999999999)
    i0 = _cell_start(I, H, Hc)
    i1 = _cell_start(I + 1, H, Hc)
    j0 = _cell_start(J, W, Wc)
    j1 = _cell_start(J + 1, W, Wc)
    # The texel row within the cell: rows in proportion to their function over the cell.
    target = a * cell[I, J]
    acc = 0.0
    i = -1
    fy = 0.5
    for r in range(i0, i1):
        w = prefix[r, j1] - prefix[r, j0]
        if w > 0:
            i = r
            if target < acc + w:
                fy = (target - acc) / w
                break
            fy = 0.9999999999999999  # (rounding at the cell's end: its last row)
        acc += w
    if i < 0:
        return 0.0, 0.0, 1.0, 0.0
    fy = min(max(fy, 0.0), 0.9999999999999999)
    # The texel column: the row's prefix sums restricted to the cell.
    lo_v = prefix[i, j0]
    x = lo_v + b * (prefix[i, j1] - lo_v)
    lo, hi = j0, j1
    while lo < hi:
        mid = (lo + hi) // 2
        if prefix[i, mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    j = min(max(lo - 1, j0), j1 - 1)
    w = prefix[i, j + 1] - prefix[i, j]
    fx = (x - prefix[i, j]) / w if w > 0 else 0.5
    fx = min(max(fx, 0.0), 1.0)
    fx, fy, ratio = texel_warp(px, interp, i, j, fx, fy)
    # (i, j) lies in cell (I, J) by construction (i0 <= i < i1, j0 <= j < j1, the cell
    # non-empty), which _cosine_texel_pdf's search would find again.
    return texel_direction(i, j, fx, fy, H, W, R,
                           _cell_texel_pdf(c_mass, prefix, cell, k, I, J, i, j) * ratio)


@kernel
def cosine_pdf_many(d, ns, R, px, interp, c_mass, prefix, cell, n_oct, out):
    for n in range(d.shape[0]):
        out[n] = env_cosine_pdf(R, px, interp, c_mass, prefix, cell, n_oct, d[n, 0], d[n, 1],
                                d[n, 2], ns[n, 0], ns[n, 1], ns[n, 2])


@kernel
def cosine_sample_many(u1, u2, ns, R, px, interp, c_rows, c_cols, c_mass, prefix, cell, n_oct,
                       wi, pdf):
    for n in range(u1.shape[0]):
        wi[n, 0], wi[n, 1], wi[n, 2], pdf[n] = env_cosine_sample(
            R, px, interp, c_rows, c_cols, c_mass, prefix, cell, n_oct, ns[n, 0], ns[n, 1],
            ns[n, 2], u1[n], u2[n])


@kernel
def radiance_many(d, R, stored, interp, scale, out):
    for n in range(d.shape[0]):
        out[n, 0], out[n, 1], out[n, 2] = env_radiance(R, stored, interp, scale, d[n, 0],
                                                       d[n, 1], d[n, 2])


@kernel
def pdf_many(d, R, px, interp, pdf_uv, out):
    for n in range(d.shape[0]):
        out[n] = env_pdf(R, px, interp, pdf_uv, d[n, 0], d[n, 1], d[n, 2])


@kernel
def sample_many(u1, u2, R, px, interp, rows, cols, pdf_uv, wi, pdf):
    for n in range(u1.shape[0]):
        wi[n, 0], wi[n, 1], wi[n, 2], pdf[n] = env_sample(R, px, interp, rows, cols, pdf_uv,
                                                          u1[n], u2[n])


@register_warm_up
def _warm_up():
    env = Environment(np.ones((2, 4, 3)))
    d = np.array([[0.0, 0.0, 1.0]])
    env.radiance(d)
    Environment(np.ones((2, 4, 3)), srgb=True).radiance(d)
    env.pdf(d)
    env.sample(np.full(1, 0.3), np.full(1, 0.6))
    env.cosine_pdf(d, d)
    env.cosine_sample(np.full(1, 0.3), np.full(1, 0.6), d)
