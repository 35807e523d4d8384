"""IES (IESNA LM-63) light profiles as Cycles reads and evaluates them (no bpy).

A point or spot light whose Emission Strength is an IES Texture's Fac emits, along a
unit direction w leaving the lamp (in the lamp's object space), the radiant intensity

    I(w) = power x color / (4 pi) x f(w)          W/sr  (x the spot's mask for a spot)

where f is the profile's candela table times 4 pi / 177.83 (Cycles' util/ies.cpp
IESFile::parse: candela -> W/sr with the luminous efficacy of D65, 177.83 lm/W, and the
4 pi of a light's strength), times the file's candela multiplier, ballast factor and
ballast-lamp photometric factor; no peak normalisation. The table is read as Cycles'
(4.x / 5.0) IESFile::parse + process: photometric types A, B and C; the TILT block
skipped; type C's one quadrant or half of horizontal angles mirrored to 0..360 degrees
(and a missing 360 entry added), B and A turned into C's angles as Cycles does; other
ranges kept, the lookup 0 outside them. It is interpolated as kernel/util/ies.h
kernel_ies_interp: Catmull-Rom cubic in the vertical then the horizontal angle (at a
table's ends the end value repeated, except round v = 0: Cycles' float32 wrap tests
never wrap at 360 or 180 degrees, see ies_interp), negative values cut to 0, 0 outside
the tabulated ranges. The direction convention is kernel/svm/ies.h svm_node_ies with
the node's default Vector (the normal in object space: the direction from the lamp to
the shaded point): v = acos(-z), h = atan2(x, y) + pi, so v = 0 is straight down the
lamp's -Z (the way a Blender light points).

Packed layout (IESProfile.packed, read by the compiled ies_factor): 9 slots of the
world -> lamp matrix (row-major), then H, V, the H horizontal angles, the V vertical
angles (radians), then the H x V intensities (row h, column v).
"""
from __future__ import annotations

import math
import os

import numpy as np

from .jit import kernel, register_warm_up

# Cycles' candela -> W/sr x 4 pi conversion (util/ies.cpp: 4 pi / 177.83).
CANDELA_TO_CYCLES = 0.0706650768394
TYPE_C, TYPE_B, TYPE_A = 1, 2, 3  # LM-63 photometric types
HEADER = 9  # the matrix's slots before the table in a packed profile


class IESError(ValueError):
    """A profile Cycles would refuse (its IES node then emits nothing useful: the engine
    renders the plain light and warns)."""


class IESProfile:
    """A processed profile: h_angles (H,), v_angles (V,) radians (h 0 .. 2 pi, v from 0),
    intensity (H, V) in Cycles' units (candela x 4 pi / 177.83)."""

    def __init__(self, h_angles, v_angles, intensity, name="profile"):
        self.h_angles = np.asarray(h_angles, np.float64)
        self.v_angles = np.asarray(v_angles, np.float64)
        self.intensity = np.asarray(intensity, np.float64).reshape(len(self.h_angles),
                                                                    len(self.v_angles))
        self.name = name

    def table(self) -> np.ndarray:
        """The flat table (2 + H + V + H V,) float64 without the matrix."""
        H, V = len(self.h_angles), len(self.v_angles)
        return np.concatenate([[H, V], self.h_angles, self.v_angles, self.intensity.ravel()])

    def packed(self, world_to_lamp) -> np.ndarray:
        """The matrix world_to_lamp (3,3) (row-major) then the table: the layout ies_factor
        reads (module docstring)."""
        m = np.asarray(world_to_lamp, np.float64).reshape(9)
        return np.concatenate([m, self.table()])

    def evaluate(self, w_lamp) -> np.ndarray:
        """f (N,) along directions w_lamp (N,3) in the lamp's space (need not be unit)."""
        w = np.ascontiguousarray(np.asarray(w_lamp, np.float64).reshape(-1, 3))
        out = np.empty(len(w))
        ies_factors(self.packed(np.eye(3)), 0, w, out)
        return out

    def integral(self, n: int = 256) -> float:
        """The integral of f over the sphere (sr x f): midpoint rule on an n x 2n grid in
        (cos v, h)."""
        cz = (np.arange(n) + 0.5) / n * 2.0 - 1.0
        h = (np.arange(2 * n) + 0.5) / (2 * n) * 2.0 * math.pi
        C, Hh = np.meshgrid(cz, h, indexing="ij")
        w = direction_from_angles(Hh.ravel(), np.arccos(np.clip(-C.ravel(), -1, 1)))
        return float(self.evaluate(w).mean() * 4.0 * math.pi)


def direction_from_angles(h, v):
    """Lamp-space unit directions (N,3) of angles h, v (svm_node_ies inverted:
    v = acos(-z), h = atan2(x, y) + pi)."""
    h = np.asarray(h, np.float64)
    v = np.asarray(v, np.float64)
    s = np.sin(v)
    return np.stack([s * np.sin(h - math.pi), s * np.cos(h - math.pi), -np.cos(v)], axis=-1)


# ---------------------------------------------------------------------- parsing
def load(path: str) -> IESProfile:
    """Read and process the LM-63 file at path; IESError (naming the file) if unreadable
    or refused."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise IESError(f"cannot read IES file '{path}': {e.strerror or e}") from None
    return parse(raw.decode("latin-1"), name=os.path.basename(path))


def parse(text: str, name: str = "profile") -> IESProfile:
    """Parse and process LM-63 text as Cycles' IESFile::parse and process; IESError with
    the reason for what Cycles refuses."""
    text = text.replace("\r\n", "\n").replace("\r", "\n").replace(",", " ")
    at = text.find("\nTILT=")
    if at < 0:
        at = 0 if text.startswith("TILT=") else -1
        if at < 0:
            raise IESError(f"{name}: no 'TILT=' line (not an LM-63 IES file)")
    else:
        at += 1
    line_end = text.find("\n", at)
    tilt = text[at:line_end if line_end >= 0 else len(text)].strip()
    tokens = text[line_end + 1:].split() if line_end >= 0 else []
    pos = 0

    def number(what):
        nonlocal pos
        if pos >= len(tokens):
            raise IESError(f"{name}: the file ends before {what}")
        tok = tokens[pos]
        pos += 1
        try:
            value = float(tok)
        except ValueError:
            raise IESError(f"{name}: '{tok}' is not a number ({what})") from None
        if not math.isfinite(value):
            raise IESError(f"{name}: {what} is not finite")
        return value

    if tilt.upper() == "TILT=INCLUDE":
        number("the lamp-to-luminaire geometry")
        n_tilt = int(number("the number of tilt angles"))
        for _ in range(2 * max(n_tilt, 0)):
            number("the tilt table")
    number("the number of lamps")
    number("the lumens per lamp")
    factor = number("the candela multiplier")
    n_v = int(number("the number of vertical angles"))
    n_h = int(number("the number of horizontal angles"))
    ptype = int(number("the photometric type"))
    if ptype not in (TYPE_A, TYPE_B, TYPE_C):
        raise IESError(f"{name}: photometric type {ptype} is unknown (1: C, 2: B, 3: A)")
    if n_v < 2 or n_h < 1:
        # (Cycles reads such a table, and its lookup then finds no interval: no light.)
        raise IESError(f"{name}: {n_v} vertical and {n_h} horizontal angles (at least 2 "
                       f"and 1 needed)")
    number("the units")
    number("the width")
    number("the length")
    number("the height")
    factor *= number("the ballast factor")
    factor *= number("the ballast-lamp photometric factor")
    number("the input watts")
    factor *= CANDELA_TO_CYCLES
    v = [number("the vertical angles") for _ in range(n_v)]
    h = [number("the horizontal angles") for _ in range(n_h)]
    cand = [[factor * number("the candela values") for _ in range(n_v)] for _ in range(n_h)]
    process = {TYPE_A: _process_type_a, TYPE_B: _process_type_b, TYPE_C: _process_type_c}
    h, v, cand = process[ptype](name, h, v, cand)
    if np.any(np.diff(h) <= 0) or np.any(np.diff(v) <= 0):
        raise IESError(f"{name}: the angles do not increase")
    return IESProfile(np.radians(h), np.radians(v), cand, name)


def _close(a, b):
    """Cycles' angle_close: within 1e-4 degrees."""
    return abs(a - b) < 1e-4


def _process_type_c(name, h, v, cand):
    """IESFile::process_type_c: horizontal angles mirrored to 0 .. 360 degrees (one
    quadrant twice, a half once; a missing 360 entry added where the spacing shows it).
    Other ranges stay as they are: the lookup is 0 outside them (ies_interp)."""
    h = list(h)
    cand = [list(c) for c in cand]
    if _close(h[0], 90.0):  # stored 90..270: rotate to 0..180
        h = [a - 90.0 for a in h]
    if len(h) == 1:
        h = [0.0, 360.0]
        cand.append(cand[0])
    if _close(h[-1], 90.0):  # one quadrant: mirror to the half
        for i in range(len(h) - 2, -1, -1):
            h.append(180.0 - h[i])
            cand.append(cand[i])
    if _close(h[-1], 180.0):  # the half: mirror to the whole
        for i in range(len(h) - 2, -1, -1):
            h.append(360.0 - h[i])
            cand.append(cand[i])
    if _close(h[0], 0.0) and not _close(h[-1], 360.0):
        last, first, gap = h[-1] - h[-2], h[1] - h[0], 360.0 - h[-1]
        if _close(last, gap) or _close(first, gap):
            h.append(360.0)
            cand.append(cand[0])
    return np.array(h), np.array(v), np.array(cand)


def _mirror_about_90(angles):
    """0 .. 90 mirrored to 0 .. 180 round 90 (90 - a reversed, then 90 + a), or
    -90 .. 90 shifted by 90: (new angles, source index of each)."""
    n = len(angles)
    if _close(angles[0], 0.0):
        idx = list(range(n - 1, 0, -1)) + list(range(n))
        return [90.0 - angles[i] for i in range(n - 1, 0, -1)] + [90.0 + a for a in angles], idx
    return [a + 90.0 for a in angles], list(range(n))


def _process_type_b(name, h, v, cand):
    """IESFile::process_type_b: the axes transposed (the polar axis taken as vertical:
    turn the lamp for the standard's horizontal one), both mirrored about 90 degrees."""
    cand = np.array(cand).T  # (file V, file H): the file's vertical angles become h
    h, v = list(v), list(h)
    h, hi = _mirror_about_90(h)
    v, vi = _mirror_about_90(v)
    return np.array(h), np.array(v), cand[np.ix_(hi, vi)]


def _process_type_a(name, h, v, cand):
    """IESFile::process_type_a: vertical angles + 90; horizontal -90 .. 90 mapped to 270
    .. 90 (180 - a), a range from 0 mirrored (180 + a)."""
    cand = np.array(cand)
    v = [a + 90.0 for a in v]
    n = len(h)
    hh = [180.0 - h[i] for i in range(n - 1, -1, -1)]
    idx = list(range(n - 1, -1, -1))
    if _close(h[0], 0.0):
        hh += [180.0 + h[i] for i in range(1, n)]
        idx += list(range(1, n))
    return np.array(hh), np.array(v), cand[idx]


# ---------------------------------------------------------------------- evaluation
@kernel
def _cubic(a, b, c, d, x):
    """Cycles' cubic_interp (Catmull-Rom)."""
    return 0.5 * (((d + 3.0 * (b - c) - a) * x + (2.0 * a - 5.0 * b + 4.0 * c - d)) * x
                  + (c - a)) * x + b


@kernel
def _vertical(tab, ofs, wrap_lo, wrap_hi, v, nv, fv, h):
    """kernel/util/ies.h interpolate_ies_vertical."""
    c = tab[ofs + h * nv + v + 1]
    b = tab[ofs + h * nv + v]
    a = b
    if v > 0:
        a = tab[ofs + h * nv + v - 1]
    elif wrap_lo:
        a = tab[ofs + h * nv + 1]
    d = c
    if v + 2 < nv:
        d = tab[ofs + h * nv + v + 2]
    elif wrap_hi:
        d = tab[ofs + h * nv + nv - 2]
    return _cubic(a, b, c, d, fv)


@kernel
def ies_interp(tab, base, h_angle, v_angle):
    """kernel_ies_interp of the table at tab[base:] (2 + H + V + H V: IESProfile.table)
    at angles (radians)."""
    nh = int(tab[base])
    nv = int(tab[base + 1])
    oh = base + 2
    ov = oh + nh
    v_low, v_high = tab[ov], tab[ov + nv - 1]
    h_low, h_high = tab[oh], tab[oh + nh - 1]
    if v_angle < v_low or v_angle >= v_high or h_angle < h_low or h_angle >= h_high:
        return 0.0
    # Cycles' tests in float32: M_2PI_F - 1e-7f and M_PI_F - 1e-7f round back to 2 pi
    # and pi (1e-7 is below half their ulp), so a table that ends at exactly 360 (180)
    # degrees does not wrap there (its ends fall back to the nearest value: measured
    # against Cycles 5.0, tests/blender/test_ies_cycles.py; wrapping read up to 26 %
    # off near the 0 / 360 degree seam).
    wrap_h = (h_low < 1e-7 and np.float32(h_high)
              > np.float32(np.float32(2.0 * math.pi) - np.float32(1e-7)))
    wrap_lo = v_low < 1e-7
    wrap_hi = np.float32(v_high) > np.float32(np.float32(math.pi) - np.float32(1e-7))
    hi = 0
    while tab[oh + hi + 1] < h_angle:
        hi += 1
    vi = 0
    while tab[ov + vi + 1] < v_angle:
        vi += 1
    fh = (h_angle - tab[oh + hi]) / (tab[oh + hi + 1] - tab[oh + hi])
    fv = (v_angle - tab[ov + vi]) / (tab[ov + vi + 1] - tab[ov + vi])
    ofs = ov + nv
    b = _vertical(tab, ofs, wrap_lo, wrap_hi, vi, nv, fv, hi)
    c = _vertical(tab, ofs, wrap_lo, wrap_hi, vi, nv, fv, hi + 1)
    a = b
    if hi > 0:
        a = _vertical(tab, ofs, wrap_lo, wrap_hi, vi, nv, fv, hi - 1)
    elif wrap_h:
        a = _vertical(tab, ofs, wrap_lo, wrap_hi, vi, nv, fv, nh - 2)
    d = b
    if hi + 2 < nh:
        d = _vertical(tab, ofs, wrap_lo, wrap_hi, vi, nv, fv, hi + 2)
    elif wrap_h:
        d = _vertical(tab, ofs, wrap_lo, wrap_hi, vi, nv, fv, 1)
    return max(_cubic(a, b, c, d, fh), 0.0)


@kernel
def ies_factor(tab, base, w0, w1, w2):
    """f along the world direction w leaving the lamp, for the packed profile at
    tab[base:] (IESProfile.packed: the world -> lamp matrix, then the table)."""
    l0 = tab[base] * w0 + tab[base + 1] * w1 + tab[base + 2] * w2
    l1 = tab[base + 3] * w0 + tab[base + 4] * w1 + tab[base + 5] * w2
    l2 = tab[base + 6] * w0 + tab[base + 7] * w1 + tab[base + 8] * w2
    n = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    if not n > 0:
        return 0.0
    v = math.acos(min(max(-l2 / n, -1.0), 1.0))
    h = math.atan2(l0 / n, l1 / n) + math.pi
    return ies_interp(tab, base + HEADER, h, v)


@kernel
def ies_factors(tab, base, w, out):
    """ies_factor for each row of w (N,3) into out (N,)."""
    for i in range(w.shape[0]):
        out[i] = ies_factor(tab, base, w[i, 0], w[i, 1], w[i, 2])


@register_warm_up
def _warm_up():
    p = IESProfile(np.radians([0.0, 360.0]), np.radians([0.0, 90.0, 180.0]),
                   np.ones((2, 3)))
    ies_factors(p.packed(np.eye(3)), 0, np.ones((1, 3)), np.empty(1))
