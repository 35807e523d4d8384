"""Noise and Voronoi kernels (engine/procedural.py): invariants that hold whatever the
hash. Their match with Cycles' patterns is checked against stored Cycles references by the
feature-matrix cases texture_noise and texture_voronoi (tests/blender)."""
import numpy as np
import pytest

from engine import procedural as pc
from engine.shadernodes import Noise, Voronoi


class _Points:
    """A stand-in coordinates node: evaluate() returns fixed points."""

    def __init__(self, pts):
        self.pts = np.asarray(pts, np.float64)

    def evaluate(self, geo, prim, u, v):
        return self.pts[prim]


def _eval(node, pts):
    n = len(pts)
    return node.evaluate(None, np.arange(n), np.zeros(n), np.zeros(n))


def test_float_bits_is_the_single_precision_pattern():
    for x in (0.0, -0.0, 1.0, -2.5, 0.1, 123.456, 1e-30, 5e6, -7.0):
        assert pc.float_bits(x) == int(np.array([x], np.float32).view(np.uint32)[0]), x


def test_pcg_hash_is_31_bit_and_spreads():
    hs = np.array([pc.hash_pcg(3, i, -i, 7, 0)[:3] for i in range(-500, 500)])
    assert hs.min() >= 0 and hs.max() < 2 ** 31
    u = hs * pc.PCG_SCALE
    # uniform in [0, 1): mean 1/2, variance 1/12 (1000 draws per component)
    assert np.all(np.abs(u.mean(axis=0) - 0.5) < 0.04)
    assert np.all(np.abs(u.var(axis=0) - 1 / 12) < 0.01)


def test_fbm_noise_is_normalised_continuous_and_deterministic():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-20, 20, (4000, 3))
    node = Noise(_Points(pts), {"Scale": 1.0, "Detail": 3.0})
    f = _eval(node, pts)
    assert f.min() > -0.05 and f.max() < 1.05 and abs(f.mean() - 0.5) < 0.03
    np.testing.assert_array_equal(f, _eval(node, pts))
    # Perlin noise is C1: a step of 1e-4 changes it by well under 1e-2
    g = _eval(node, pts + 1e-4)
    assert np.abs(f - g).max() < 1e-2


def test_noise_colour_channels_differ_and_start_with_the_value():
    pts = np.random.default_rng(2).uniform(0, 10, (500, 3))
    fac = _eval(Noise(_Points(pts)), pts)
    col = _eval(Noise(_Points(pts), output="COLOR"), pts)
    np.testing.assert_array_equal(col[:, 0], fac)
    assert np.corrcoef(col[:, 1], col[:, 2])[0, 1] < 0.5


@pytest.mark.parametrize("dims", [2, 3])
def test_voronoi_f1_is_the_nearest_feature_point(dims):
    """F1 from the kernel's 3^d window equals a brute-force search over 5^d cells."""
    rng = np.random.default_rng(3)
    pts = rng.uniform(-6, 6, (300, 3))
    if dims == 2:
        pts[:, 2] = 0.0
    node = Voronoi(_Points(pts), {"Scale": 1.0}, dims=dims)
    d = _eval(node, pts)
    for p, got in zip(pts, d):
        cell = np.floor(p[:dims])
        best = np.inf
        for off in np.ndindex(*(5,) * dims):
            c = cell + np.array(off) - 2
            j = np.array(pc.hash_cell(dims, *c, *([0.0] * (4 - dims)))[:dims])
            best = min(best, np.linalg.norm(c + j - p[:dims]))
        assert got == pytest.approx(best, abs=1e-9)


def test_voronoi_f2_exceeds_f1_and_edge_distance_is_bounded():
    pts = np.random.default_rng(4).uniform(0, 8, (2000, 3))

    def vor(**kw):
        return _eval(Voronoi(_Points(pts), {"Scale": 1.0}, **kw), pts)

    f1, f2 = vor(), vor(feature="F2")
    a, b = vor(output="POSITION"), vor(feature="F2", output="POSITION")
    edge = vor(feature="DISTANCE_TO_EDGE")
    assert np.all(f2 >= f1)
    # The nearest cell border is no farther than the bisector of the two nearest feature
    # points a, b: (f2^2 - f1^2) / (2 |a - b|).
    bisector = (f2 ** 2 - f1 ** 2) / (2 * np.linalg.norm(a - b, axis=1))
    assert np.all(edge >= -1e-9) and np.all(edge <= bisector + 1e-9)
    assert np.mean(edge < bisector - 1e-6) > 0.05  # and other borders are sometimes nearer


def test_voronoi_position_is_the_cell_point_and_colour_is_constant_per_cell():
    pts = np.random.default_rng(5).uniform(0, 4, (400, 3))
    pos = _eval(Voronoi(_Points(pts), {"Scale": 2.0}, output="POSITION"), pts)
    col = _eval(Voronoi(_Points(pts), {"Scale": 2.0}, output="COLOR"), pts)
    dist = _eval(Voronoi(_Points(pts), {"Scale": 2.0}), pts)
    # Position is in unscaled coordinates; its distance (scaled) is the F1 distance
    np.testing.assert_allclose(np.linalg.norm((pos - pts) * 2.0, axis=1), dist, atol=1e-9)
    # points sharing a feature point share a colour
    key = np.round(pos, 9)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    for g in np.unique(inv):
        assert np.ptp(col[inv == g], axis=0).max() == 0.0


def test_bad_node_settings_are_refused_with_the_setting_named():
    with pytest.raises(ValueError, match="dimensions"):
        Noise(None, dims=5)
    with pytest.raises(ValueError, match="type"):
        Noise(None, kind="PERLIN")
    with pytest.raises(ValueError, match="feature"):
        Voronoi(None, feature="F3")
    with pytest.raises(ValueError, match="distance"):
        Voronoi(None, metric="COSINE")
