"""The pixel (reconstruction) filter, sampled by importance as Cycles does.

Cycles does not splat samples into neighbouring pixels with filter weights: it draws each
camera ray's position inside the pixel from the filter's own distribution, and every
sample counts with weight 1 in the pixel it belongs to (Cycles' scene/film.cpp builds a
tabulated inverse CDF, kernel/camera/camera.h looks it up per ray). A pixel's value is then
the filter-weighted mean of the image around its centre, and wide filters soften edges
and thin lines exactly as Cycles' do.

Filters (Blender: Render Properties > Film > Pixel Filter, `scene.cycles.pixel_filter_type`
and `filter_width`, default Blackman-Harris 1.5 px; docs/compatibility.md):
    box              uniform over the pixel (Cycles ignores the width for the box)
    gaussian         exp(-2 (6 x / (3 w))^2) on |x| <= 1.5 w  (sigma = w / 4)
    blackman_harris  the 4-term Blackman-Harris window over |x| <= w
x is the offset from the pixel centre in pixels, w the filter width. A width of 0 puts
every ray through the pixel centre (no anti-aliasing: Blender's filter size 0).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

PIXEL_FILTERS = ("box", "gaussian", "blackman_harris")
TABLE_SIZE = 1024  # entries of the inverse CDF (Cycles' FILTER_TABLE_SIZE)
_DENSE = 16385     # points at which the filter is integrated for its CDF


def filter_radius(kind: str, width: float) -> float:
    """Half the filter's support in pixels (samples land within +- radius of the centre)."""
    if kind == "box":
        return 0.5
    if kind == "gaussian":
        return 1.5 * width
    if kind == "blackman_harris":
        return float(width)
    raise ValueError(f"pixel filter must be one of {', '.join(PIXEL_FILTERS)}, got {kind!r}")


def filter_weight(kind: str, width: float, x: np.ndarray) -> np.ndarray:
    """The filter's (unnormalised) weight at offsets x (pixels from the centre); 0 outside
    its support. Formulas: Cycles' scene/film.cpp (Blackman-Harris: Harris 1978, the
    4-term window; its width there is 2 w, centred)."""
    x = np.asarray(x, np.float64)
    r = filter_radius(kind, width)
    inside = np.abs(x) <= r
    if kind == "box":
        w = np.ones_like(x)
    elif kind == "gaussian":
        v = x * 6.0 / (3.0 * width)
        w = np.exp(-2.0 * v * v)
    else:
        v = 2.0 * math.pi * (x / (2.0 * width) + 0.5)
        w = 0.35875 - 0.48829 * np.cos(v) + 0.14128 * np.cos(2 * v) - 0.01168 * np.cos(3 * v)
    return np.where(inside, np.maximum(w, 0.0), 0.0)


def filter_table(kind: str, width: float, size: int = TABLE_SIZE) -> np.ndarray:
    """See _filter_table; a fresh copy of the cached table."""
    return _filter_table(str(kind), float(width), int(size)).copy()


@lru_cache(maxsize=16)
def _filter_table(kind: str, width: float, size: int) -> np.ndarray:
    """Inverse CDF of the filter along one image axis: (size,) float64 positions inside
    the pixel (0.5 = its centre; values below 0 or above 1 fall in the neighbours) at
    the uniform numbers u = i / (size - 1). A ray's position is the table read at its
    random number with linear interpolation (lookup_filter). Box: the empty table, which
    means "u itself" (uniform over the pixel, bit for bit what plain jitter gives)."""
    if kind not in PIXEL_FILTERS:
        raise ValueError(f"pixel filter must be one of {', '.join(PIXEL_FILTERS)}, got {kind!r}")
    width = float(width)
    if not (math.isfinite(width) and width >= 0.0):
        raise ValueError(f"pixel filter width must be a number >= 0, got {width!r}")
    if kind == "box":
        return np.empty(0)
    if width == 0.0:
        return np.full(size, 0.5)
    r = filter_radius(kind, width)
    x = np.linspace(-r, r, _DENSE)
    f = filter_weight(kind, width, x)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]))])
    cdf /= cdf[-1]
    # Flat stretches of the CDF (zero weight) would make the inverse ambiguous: np.interp
    # needs increasing abscissae, so keep the first point of each run.
    keep = np.concatenate([[True], np.diff(cdf) > 0])
    u = np.linspace(0.0, 1.0, size)
    table = 0.5 + np.interp(u, cdf[keep], x[keep])
    # Exactly symmetric about the centre (the integration's rounding is not).
    return 0.5 * (table + (1.0 - table[::-1]))


def lookup_filter(table: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Positions inside the pixel for uniform numbers u in [0, 1) (numpy; the camera-ray
    kernel does the same per ray): the table read with linear interpolation, u itself
    for the box's empty table."""
    u = np.asarray(u, np.float64)
    if len(table) == 0:
        return u
    return np.interp(np.clip(u, 0.0, 1.0) * (len(table) - 1), np.arange(len(table)), table)
