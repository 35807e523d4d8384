"""engine.subsurface: Principled Subsurface as a diffuse base of Cycles' random-walk
albedo (the table measured by bench/bench_subsurface_albedo.py)."""
import numpy as np

from engine import subsurface as ss


def test_table_is_a_reflectance_that_never_exceeds_the_colour():
    assert ss.TABLE_C[0] == 0.0 and ss.TABLE_A[0] == 0.0 and ss.TABLE_C[-1] == 1.0
    assert np.all(np.diff(ss.TABLE_C) > 0) and np.all(np.diff(ss.TABLE_A) >= 0)
    # Cycles' random walk keeps less than a Lambertian base of the same colour.
    assert np.all(ss.TABLE_A[1:] < ss.TABLE_C[1:])


def test_albedo_interpolates_the_table_and_clamps_the_colour():
    np.testing.assert_allclose(ss.random_walk_albedo(ss.TABLE_C), ss.TABLE_A)
    np.testing.assert_allclose(ss.random_walk_albedo([-0.5, 0.45, 2.0]),
                               [0.0, 0.5 * (0.3709 + 0.4708), 0.9064])


def test_weight_mixes_the_diffuse_and_subsurface_colours():
    c = np.array([0.9, 0.6, 0.5])
    np.testing.assert_array_equal(ss.diffuse_color(c, 0.0), c)
    full = ss.diffuse_color(c, 1.0)
    np.testing.assert_allclose(full, ss.random_walk_albedo(c))
    np.testing.assert_allclose(ss.diffuse_color(c, 0.25), 0.75 * c + 0.25 * full)
    np.testing.assert_allclose(ss.diffuse_color(c, 3.0), full)  # weight clamped to 1


class _Const:
    def __init__(self, value):
        self.value = np.asarray(value, np.float64)

    def evaluate(self, geo, prim, u, v):
        return np.tile(self.value, (len(prim), 1)) if self.value.ndim else \
            np.full(len(prim), float(self.value))


def test_node_per_hit_matches_the_constant_formula():
    prim = np.arange(4)
    u = v = np.full(4, 0.25)
    c = (0.2, 0.5, 0.95)
    got = ss.SubsurfaceColor(_Const(c), _Const(0.5)).evaluate(None, prim, u, v)
    np.testing.assert_allclose(got, np.tile(ss.diffuse_color(c, 0.5), (4, 1)))
    got = ss.SubsurfaceColor(np.array(c), 1.0).evaluate(None, prim, u, v)
    np.testing.assert_allclose(got, np.tile(ss.random_walk_albedo(c), (4, 1)))
