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


class _CountingU(_U):
    """_U that counts its evaluations."""

    def __init__(self):
        self.calls = 0

    def evaluate(self, geo, prim, u, v):
        self.calls += 1
        return super().evaluate(geo, prim, u, v)


class _Geo:
    """A stand-in Geometry (ClosurePick only needs its identity)."""

    ng = np.tile([0.0, 0.0, 1.0], (50, 1))


def test_pick_is_evaluated_once_per_batch_and_unchanged():
    """mixsides: every parameter of a picked mix reads the pick; the same batch of hits
    (equal prim, u, v, view) evaluates the factor and the hash once, and a changed batch
    (other hits, a buffer refilled in place, another view, another Geometry) again."""
    prim, u, v = _hits(5_000, 6)
    geo = _Geo()
    factor = _CountingU()
    node = sn.ClosurePick(factor)
    first = node.evaluate(geo, prim, u, v)
    expect = sn.ClosurePick(_U()).evaluate(None, prim, u, v)  # no cache without a geo
    np.testing.assert_array_equal(first, expect)
    assert not first.flags.writeable  # shared by its readers: none may write into it
    # A Math tree of the kind the add-on builds per parameter: (1 - f) xa + f xb.
    g = sn.Math("SUBTRACT", 1.0, node)
    tree = sn.Math("ADD", sn.Math("MULTIPLY", g, 1.5), sn.Math("MULTIPLY", node, 2.4))
    val = tree.evaluate(geo, prim.copy(), u.copy(), v.copy())  # equal copies: one batch
    np.testing.assert_array_equal(val, np.where(expect == 1.0, 2.4, 1.5))
    assert factor.calls == 1
    u2 = u.copy()
    u2[7] = 0.5 * u2[7]
    np.testing.assert_array_equal(node.evaluate(geo, prim, u2, v),
                                  sn.ClosurePick(_U()).evaluate(None, prim, u2, v))
    assert factor.calls == 2
    node.evaluate(_Geo(), prim, u2, v)
    assert factor.calls == 3
    # A ShadingGeometry's view is part of the batch (Layer Weight, Fresnel factors).
    n = np.tile([0.0, 0.0, 1.0], (len(prim), 1))
    sg = sn.ShadingGeometry(geo, n, n.copy(), np.zeros(len(prim), bool))
    node.evaluate(sg, prim, u, v)
    node.evaluate(sg.rows(np.arange(len(prim))), prim, u, v)
    assert factor.calls == 4
    wi = n.copy()
    wi[3] = (0.0, 0.6, 0.8)
    node.evaluate(sn.ShadingGeometry(geo, n, wi, np.zeros(len(prim), bool)), prim, u, v)
    assert factor.calls == 5


def test_cached_pick_is_not_pickled():
    import pickle
    prim, u, v = _hits(100, 7)
    node = sn.ClosurePick(0.5)
    node.evaluate(_Geo(), prim, u, v)
    copy = pickle.loads(pickle.dumps(node))
    assert copy._last is None and copy.factor == 0.5
    np.testing.assert_array_equal(copy.evaluate(None, prim, u, v),
                                  node.evaluate(None, prim, u, v))
