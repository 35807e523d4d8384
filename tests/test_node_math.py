"""Map Range, Blackbody and Wave Texture (engine/shadernodes.py, engine/procedural.py)
against Cycles' formulas: map_range.h (and the Clamp node Cycles puts after a clamped Map
Range), math_util.h svm_math_blackbody_color_rec709 with kernel/tables.h, wave.h. The
patterns against Cycles' renders: feature-matrix cases texture_wave and
texture_map_range_blackbody (tests/blender)."""
import math

import numpy as np
import pytest

from engine.shadernodes import (Blackbody, MapRange, Wave, blackbody_rec709, map_range,
                                vector_map_range)


def _eval(node, n):
    return node.evaluate(None, np.arange(n), np.zeros(n), np.zeros(n))


class _Points:
    def __init__(self, pts):
        self.pts = np.asarray(pts, np.float64)

    def evaluate(self, geo, prim, u, v):
        return self.pts[prim]


# --- Blackbody ------------------------------------------------------------------------

# Cycles' svm_math_blackbody_color_rec709 as written in C (if-chain of segment bounds,
# float32 coefficients of kernel/tables.h), transcribed scalar by scalar.
_R = [(1.61919106e+03, -2.05010916e-03, 5.02995757e+00),
      (2.48845471e+03, -1.11330907e-03, 3.22621544e+00),
      (3.34143193e+03, -4.86551192e-04, 1.76486769e+00),
      (4.09461742e+03, -1.27446582e-04, 7.25731635e-01),
      (4.67028036e+03, 2.91258199e-05, 1.26703442e-01),
      (4.59509185e+03, 2.87495649e-05, 1.50345020e-01),
      (3.78717450e+03, 9.35907826e-06, 3.99075871e-01)]
_G = [(-4.88999748e+02, 6.04330754e-04, -7.55807526e-02),
      (-7.55994277e+02, 3.16730098e-04, 4.78306139e-01),
      (-1.02363977e+03, 1.20223470e-04, 9.36662319e-01),
      (-1.26571316e+03, 4.87340896e-06, 1.27054498e+00),
      (-1.42529332e+03, -4.01150431e-05, 1.43972784e+00),
      (-1.17554822e+03, -2.16378048e-05, 1.30408023e+00),
      (-5.00799571e+02, -4.59832026e-06, 1.09098763e+00)]
_B = [(5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03),
      (2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02),
      (-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02),
      (-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01),
      (-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02),
      (-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01),
      (6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01)]


def _cycles_blackbody(t):
    if t >= 12000.0:
        return (0.8262954810464208, 0.9945080501520986, 1.566307710274283)
    if t < 800.0:
        return (5.413294490189271, -0.20319390035873933, -0.0822535242887164)
    i = (6 if t >= 6365.0 else 5 if t >= 3315.0 else 4 if t >= 1902.0 else
         3 if t >= 1449.0 else 2 if t >= 1167.0 else 1 if t >= 965.0 else 0)
    r, g, b = _R[i], _G[i], _B[i]
    return (r[0] / t + r[1] * t + r[2], g[0] / t + g[1] * t + g[2],
            ((b[0] * t + b[1]) * t + b[2]) * t + b[3])


@pytest.mark.parametrize("kelvin", [800.0, 1500.0, 6500.0, 12000.0])
def test_blackbody_is_cycles_fit(kelvin):
    got = blackbody_rec709([kelvin])[0]
    np.testing.assert_allclose(got, _cycles_blackbody(kelvin), rtol=1e-12, atol=1e-12)
    # The node clamps the out-of-gamut (negative) channels to 0.
    node = _eval(Blackbody(kelvin), 1)[0]
    np.testing.assert_allclose(node, np.maximum(_cycles_blackbody(kelvin), 0.0))


def test_blackbody_values_cycles_prints():
    """Cycles 5.x Blackbody node outputs (after its clamp to >= 0), float32 printouts:
    800 K deep red, 6500 K about white, 12000 K blue."""
    got = _eval(Blackbody(800.0), 1)
    np.testing.assert_allclose(got[0], [5.41385937, 0.0, 0.0], rtol=1e-6)
    np.testing.assert_allclose(blackbody_rec709([6500.0])[0],
                               [1.04255211, 0.984052539, 1.03527153], rtol=1e-6)
    np.testing.assert_allclose(blackbody_rec709([12000.0])[0],
                               [0.826295495, 0.994508028, 1.56630771], rtol=1e-6)


def test_blackbody_fit_is_continuous_with_unit_luminance():
    """The fit's segments join (each bound within 2e-3) and it is luminance-normalised
    (Rec.709 luminance 1 within 0.1 %) from 800 K up: temperature sets hue, not power."""
    edges = np.array([965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0])
    lo, hi = blackbody_rec709(edges - 1e-6), blackbody_rec709(edges)
    assert np.abs(lo - hi).max() < 2e-3
    lum = blackbody_rec709(np.linspace(800, 12000, 500)) @ [0.2126, 0.7152, 0.0722]
    assert np.abs(lum - 1.0).max() < 1e-3


# --- Map Range ------------------------------------------------------------------------

def _smoothstep(a, b, x):
    if x < a:
        return 0.0
    if x >= b:
        return 1.0
    t = (x - a) / (b - a)
    return (3.0 - 2.0 * t) * t * t


def _smootherstep(a, b, x):
    t = min(max((x - a) / (b - a), 0.0), 1.0)
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _cycles_map_range(x, fmin, fmax, tmin, tmax, steps, kind, clamp):
    if fmax == fmin:
        return 0.0
    if kind == "LINEAR":
        f = (x - fmin) / (fmax - fmin)
    elif kind == "STEPPED":
        f = (x - fmin) / (fmax - fmin)
        f = math.floor(f * (steps + 1.0)) / steps if steps > 0 else 0.0
    elif kind == "SMOOTHSTEP":
        f = 1.0 - _smoothstep(fmax, fmin, x) if fmin > fmax else _smoothstep(fmin, fmax, x)
    else:
        f = (1.0 - _smootherstep(fmax, fmin, x) if fmin > fmax
             else _smootherstep(fmin, fmax, x))
    r = tmin + f * (tmax - tmin)
    if clamp:  # Cycles' Clamp node (Range) after a clamped Map Range
        r = min(max(r, min(tmin, tmax)), max(tmin, tmax))
    return r


@pytest.mark.parametrize("kind", ["LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"])
@pytest.mark.parametrize("clamp", [True, False])
def test_map_range_modes_are_cycles(kind, clamp):
    xs = np.linspace(-1.0, 2.0, 61)
    for fmin, fmax, tmin, tmax, steps in [(0.0, 1.0, 0.0, 1.0, 4.0),
                                          (0.2, 0.8, 1.0, -0.5, 3.0),
                                          (0.9, 0.1, 0.25, 0.75, 2.5),
                                          (0.5, 0.5, 0.0, 1.0, 4.0),
                                          (0.0, 1.0, 0.0, 1.0, 0.0)]:
        got = map_range(xs, fmin, fmax, tmin, tmax, steps, kind=kind, clamp=clamp)
        want = [_cycles_map_range(x, fmin, fmax, tmin, tmax, steps, kind, clamp)
                for x in xs]
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def _cycles_vector_map_range(x, fmin, fmax, tmin, tmax, steps, kind, clamp):
    """One component of Cycles' svm_node_vector_map_range (kernel/svm/map_range.h):
    safe_divide (0 for an empty range), the smooth kinds clamp the factor and ignore
    Clamp; no edge swap for reversed ranges."""
    f = (x - fmin) / (fmax - fmin) if fmax != fmin else 0.0
    if kind == "STEPPED":
        f = math.floor(f * (steps + 1.0)) / steps if steps > 0 else 0.0
    elif kind == "SMOOTHSTEP":
        f = min(max(f, 0.0), 1.0)
        f = (3.0 - 2.0 * f) * (f * f)
    elif kind == "SMOOTHERSTEP":
        f = min(max(f, 0.0), 1.0)
        f = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    r = tmin + f * (tmax - tmin)
    if clamp and kind in ("LINEAR", "STEPPED"):
        r = min(max(r, tmax), tmin) if tmin > tmax else min(max(r, tmin), tmax)
    return r


@pytest.mark.parametrize("kind", ["LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"])
@pytest.mark.parametrize("clamp", [True, False])
def test_vector_map_range_modes_are_cycles(kind, clamp):
    """Per component, each with its own range (reversed, empty, zero steps among them)."""
    xs = np.linspace(-1.0, 2.0, 61)
    value = np.c_[xs, xs[::-1], 0.5 * xs]
    fmin, fmax = np.array([0.0, 0.9, 0.5]), np.array([1.0, 0.1, 0.5])
    tmin, tmax = np.array([0.0, 1.0, 0.2]), np.array([1.0, -0.5, 0.8])
    steps = np.array([4.0, 2.5, 0.0])
    got = vector_map_range(value, fmin, fmax, tmin, tmax, steps, kind=kind, clamp=clamp)
    assert got.shape == (61, 3)
    want = [[_cycles_vector_map_range(value[i, c], fmin[c], fmax[c], tmin[c], tmax[c],
                                      steps[c], kind, clamp) for c in range(3)]
            for i in range(61)]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_vector_map_range_node_per_hit():
    pts = np.array([[-0.5, 0.1, 0.6], [0.2, 1.4, 0.9]])
    node = MapRange({"Vector": _Points(pts), "To_Min_FLOAT3": (0.2, 0.0, 1.0),
                     "To_Max_FLOAT3": (0.9, 2.0, 0.0)}, kind="LINEAR", clamp=True,
                    vector=True)
    want = np.clip(np.array([0.2, 0.0, 1.0]) + pts * np.array([0.7, 2.0, -1.0]),
                   [0.2, 0.0, 0.0], [0.9, 2.0, 1.0])
    np.testing.assert_allclose(_eval(node, 2), want)


def test_map_range_known_values():
    assert map_range(0.25, 0, 1, 10, 20) == pytest.approx(12.5)
    assert map_range(1.5, 0, 1, 10, 20) == pytest.approx(20.0)           # clamped
    assert map_range(1.5, 0, 1, 10, 20, clamp=False) == pytest.approx(25.0)
    assert map_range(0.3, 0, 1, 0, 1, 4, kind="STEPPED") == pytest.approx(0.25)
    assert map_range(0.5, 0, 1, 0, 1, kind="SMOOTHSTEP") == pytest.approx(0.5)
    assert map_range(0.25, 0, 1, 0, 1, kind="SMOOTHSTEP") == pytest.approx(0.15625)
    assert map_range(0.25, 0, 1, 0, 1, kind="SMOOTHERSTEP") == pytest.approx(0.103515625)


def test_map_range_node_per_hit():
    vals = np.array([-0.5, 0.1, 0.6, 1.4])
    node = MapRange({"Value": _Points(np.c_[vals, vals, vals]), "To Min": 0.2,
                     "To Max": 0.9}, kind="LINEAR", clamp=True)
    # A colour into the Value socket is read as its luminance (equal channels: itself).
    np.testing.assert_allclose(_eval(node, 4), np.clip(0.2 + vals * 0.7, 0.2, 0.9))
    with pytest.raises(ValueError):
        MapRange(kind="CUBIC")


# --- Wave Texture ---------------------------------------------------------------------

def _cycles_wave(p, kind, direction, profile, phase):
    """svm_wave without distortion, in float64."""
    p = (p + 0.000001) * 0.999999
    if kind == "BANDS":
        n = {"X": p[:, 0] * 20, "Y": p[:, 1] * 20, "Z": p[:, 2] * 20,
             "DIAGONAL": p.sum(axis=1) * 10}[direction]
    else:
        keep = {"X": [0, 1, 1], "Y": [1, 0, 1], "Z": [1, 1, 0], "SPHERICAL": [1, 1, 1]}
        n = np.linalg.norm(p * keep[direction], axis=1) * 20
    n = n + phase
    if profile == "SIN":
        return 0.5 + 0.5 * np.sin(n - np.pi / 2)
    n = n / (2 * np.pi)
    return n - np.floor(n) if profile == "SAW" else np.abs(n - np.floor(n + 0.5)) * 2


@pytest.mark.parametrize("kind,direction", [("BANDS", d) for d in ("X", "Y", "Z", "DIAGONAL")]
                         + [("RINGS", d) for d in ("X", "Y", "Z", "SPHERICAL")])
@pytest.mark.parametrize("profile", ["SIN", "SAW", "TRI"])
def test_wave_without_distortion_is_cycles(kind, direction, profile):
    pts = np.random.default_rng(5).uniform(-1, 1, (500, 3))
    node = Wave(_Points(pts), {"Scale": 2.0, "Phase Offset": 0.7}, kind, direction, profile)
    got = _eval(node, len(pts))
    np.testing.assert_allclose(got, _cycles_wave(pts * 2.0, kind, direction, profile, 0.7),
                               atol=1e-12)
    assert got.min() >= 0.0 and got.max() <= 1.0


def test_wave_distortion_is_bounded_continuous_and_colour_is_grey():
    """Distortion shifts the phase by distortion x (2 fBM - 1): at most |distortion| since
    the normalised fBM is within about [0, 1]; the shift is continuous in position."""
    pts = np.random.default_rng(6).uniform(-2, 2, (3000, 3))
    base = _eval(Wave(_Points(pts), {"Scale": 1.0}, profile="SAW"), len(pts))
    dist = Wave(_Points(pts), {"Scale": 1.0, "Distortion": 1.5, "Detail": 2.5,
                               "Detail Scale": 1.3}, profile="SAW")
    d = _eval(dist, len(pts))
    assert 0.0 <= d.min() and d.max() <= 1.0
    shift = (d - base) * 2 * np.pi                      # phase shift, modulo 2 pi
    shift = (shift + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(shift).max() <= 1.5 * 1.1 and np.abs(shift).mean() > 0.1
    near = Wave(_Points(pts + 1e-5), dist.inputs, profile="SAW")
    step = np.abs(_eval(near, len(pts)) - d)
    assert np.minimum(step, 1 - step).max() < 1e-2   # saw wraps 1 -> 0: modulo 1
    col = _eval(Wave(_Points(pts), dist.inputs, profile="SAW", output="COLOR"), len(pts))
    np.testing.assert_array_equal(col, np.repeat(d[:, None], 3, axis=1))
    with pytest.raises(ValueError):
        Wave(_Points(pts), kind="RINGS", direction="DIAGONAL")
