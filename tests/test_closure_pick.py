"""engine.shadernodes.ClosurePick: a Mix Shader's one-sample closure choice per hit
(Cycles' closure sampling) takes the second closure with probability the factor, the
same way at every evaluation of one hit, and independently of the hit's position."""
import numpy as np
import pytest

from engine import shadernodes as sn


def _hits(n, seed):
    rng = np.random.default_rng(seed)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    return rng.integers(0, 50, n), s * (1.0 - r2), s * r2


@pytest.mark.parametrize("f", [0.0, 0.2, 0.5, 0.9, 1.0])
def test_second_closure_taken_with_probability_the_factor(f):
    prim, u, v = _hits(200_000, 1)
    pick = sn.ClosurePick(f).evaluate(None, prim, u, v)
    assert set(np.unique(pick)) <= {0.0, 1.0}
    # Binomial: 5 standard deviations of the mean of 200k draws.
    assert abs(pick.mean() - f) <= 5 * np.sqrt(f * (1 - f) / len(pick)) + 1e-12


class _U:
    """A node whose value is the hit's barycentric u."""

    def evaluate(self, geo, prim, u, v):
        return np.asarray(u, np.float64)


def test_factor_is_clamped_and_read_per_hit():
    prim, u, v = _hits(200_000, 2)
    # Factor u per hit: P(pick | u) = u, so E[pick] = E[u] = 1/3, E[pick u] = E[u^2] = 1/6.
    pick = sn.ClosurePick(_U()).evaluate(None, prim, u, v)
    assert abs(pick.mean() - 1 / 3) < 0.005
    assert abs((pick * u).mean() - 1 / 6) < 0.005
    assert sn.ClosurePick(1.5).evaluate(None, prim, u, v).min() == 1.0
    assert sn.ClosurePick(-0.5).evaluate(None, prim, u, v).max() == 0.0


def test_one_hit_always_picks_the_same_closure():
    prim, u, v = _hits(10_000, 3)
    a = sn.hit_random(prim, u, v)
    b = sn.hit_random(prim.copy(), np.array(u, np.float64), np.array(v, np.float64))
    np.testing.assert_array_equal(a, b)
    assert a.min() >= 0.0 and a.max() < 1.0


def test_hit_random_is_uniform_and_uncorrelated_with_the_position():
    prim, u, v = _hits(200_000, 4)
    r = sn.hit_random(prim, u, v)
    counts = np.histogram(r, bins=20, range=(0, 1))[0]
    expected = len(r) / 20
    chi2 = ((counts - expected) ** 2 / expected).sum()
    assert chi2 < 60.0  # 19 degrees of freedom: p < 1e-6 above 60
    for x in (u, v, prim.astype(float)):
        assert abs(np.corrcoef(r, x)[0, 1]) < 0.02
    # Neighbouring hits (a camera's jittered samples in one pixel) decorrelate too.
    r2 = sn.hit_random(prim, u + 1e-9, v)
    assert abs(np.corrcoef(r, r2)[0, 1]) < 0.02
