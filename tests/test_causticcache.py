"""settings.caustic_lookup = "precomputed" (engine/causticcache.py): the caustic map's
k-NN estimates read from estimates precomputed at the photons (Christensen 1999)."""
import numpy as np
import pytest

from engine import causticcache
from engine.photonmap import PhotonMap
from engine.photons import Photons
from engine.settings import RenderSettings

P = 1e-3  # W a photon


def _plane(pos):
    n = len(pos)
    return Photons(np.asarray(pos, np.float32), np.full((n, 3), P, np.float32),
                   np.tile(np.float32([0, 0, -1]), (n, 1)),
                   np.tile(np.float32([0, 0, 1]), (n, 1)), np.zeros(n, np.uint8), n)


def _maps(ph):
    knn, pre = PhotonMap(ph), PhotonMap(ph)
    pre.lookup = "precomputed"
    return knn, pre


def _queries(rng, m, lo, hi):
    q = np.c_[lo + (hi - lo) * rng.random(m), 0.15 + 0.7 * rng.random(m), np.zeros(m)]
    return q, np.tile([0.0, 0.0, 1.0], (m, 1))


def test_uniform_caustic_is_the_analytic_irradiance():
    """A uniform caustic of N photons of power P on the unit square: E = N P (W/m^2).
    The precomputed lookups' mean is within 1.5 % of it (the map's own fluctuation) and
    within 0.3 % of the k-NN rows' at the same points (the own term derived,
    causticcache.own_term_removed: -0.07 to -0.01 % over seeds 1-3 of a 100k-photon
    plane at k = 64; the fitted 0.17 of s23 read -0.4 %), no NaN, and they answer most
    rows (the k-NN rows answer the rest)."""
    rng = np.random.default_rng(3)
    n = 60_000
    knn, pre = _maps(_plane(np.c_[rng.random(n), rng.random(n), np.zeros(n)]))
    q, qn = _queries(rng, 60_000, 0.15, 0.85)
    ek = knn.irradiance(q, qn, 0.1, 64, 1, "knn_simpson")
    ep, bp = pre.irradiance(q, qn, 0.1, 64, 1, "knn_simpson", return_boundary=True)
    assert np.isfinite(ep).all()
    truth = n * P
    assert abs(ep[:, 0].mean() / truth - 1) < 0.015
    assert abs(ep[:, 0].mean() / ek[:, 0].mean() - 1) < 0.003
    # The same noise level as the k-NN rows (each photon's estimate is a k-NN estimate).
    assert ep[:, 0].std() < 1.1 * ek[:, 0].std()
    stored = next(iter(pre.precomputed.values()))
    assert stored.stored > 0.9 * n
    assert bp.mean() < 0.01


def _simpson(d, r):
    x = np.clip(1 - (d / r[:, None]) ** 2, 0, 1)
    return (3 / np.pi * x * x).sum(1) / r ** 2


def _cone(d, r):
    return (3 / np.pi * np.clip(1 - d / r[:, None], 0, 1)).sum(1) / r ** 2


@pytest.mark.parametrize("estimator,kernel", [("knn_simpson", _simpson), ("knn_cone", _cone)])
def test_own_term_is_the_poisson_models(estimator, kernel):
    """causticcache.own_term_removed's model against a direct simulation, independent of
    the engine's kernels (scipy's kd-tree): on a Poisson caustic (200k points, unit
    square), the nearest point's k = 64 estimate (itself included) read at 100k random
    points has the mean 1 + 3 f / (k - 1) times the points' own k-NN estimates (f the
    model's fraction: the own term minus the empty disc's share), and with f of its own
    term removed their mean (to 0.1 %: the paired difference's noise is ~0.02 %)."""
    from scipy.spatial import cKDTree
    k = 64
    f = causticcache.own_term_removed(k, estimator)
    assert 0 < f < 1
    rng = np.random.default_rng(11)
    pts = rng.random((200_000, 2))
    tree = cKDTree(pts)
    q = 0.2 + 0.6 * rng.random((100_000, 2))
    dq, _ = tree.query(q, k)
    e_rows = kernel(dq, dq[:, -1])
    _, j = tree.query(q, 1)
    dp, _ = tree.query(pts[j], k)
    rk = dp[:, -1]
    e_kept = kernel(dp, rk)
    assert abs(e_kept.mean() / e_rows.mean() - (1 + 3 * f / (k - 1))) < 0.001
    e_removed = e_kept - f * 3 / (np.pi * rk ** 2)
    assert abs(e_removed.mean() / e_rows.mean() - 1) < 0.001


def test_small_k_takes_the_knn_rows():
    """Below causticcache.MIN_K the ACCEPT cut would reject more than 1 % of a uniform
    caustic's rows (its own selection biases: -4 % at k = 16): the k-NN rows' bits."""
    assert (1 - causticcache.ACCEPT ** 2) ** (causticcache.MIN_K - 1) < 0.01
    assert (1 - causticcache.ACCEPT ** 2) ** (causticcache.MIN_K - 2) >= 0.01
    rng = np.random.default_rng(2)
    n = 20_000
    knn, pre = _maps(_plane(np.c_[rng.random(n), rng.random(n), np.zeros(n)]))
    q, qn = _queries(rng, 3000, 0.2, 0.8)
    k = causticcache.MIN_K - 1
    a = knn.irradiance(q, qn, 0.1, k, 1, "knn_simpson", return_boundary=True)
    b = pre.irradiance(q, qn, 0.1, k, 1, "knn_simpson", return_boundary=True)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not pre.precomputed


def test_sharp_edge_profile_follows_the_knn_rows():
    """A caustic on x < 0.5 only (a sharp edge across the plane): the profile across the
    edge (bins of 0.01 m) of the precomputed lookups is the k-NN rows' within 4 % of the
    plateau in every bin (the edge is no softer), and dark beyond the search radius."""
    rng = np.random.default_rng(5)
    n = 60_000
    knn, pre = _maps(_plane(np.c_[0.5 * rng.random(n), rng.random(n), np.zeros(n)]))
    q, qn = _queries(rng, 80_000, 0.3, 0.7)
    ek = knn.irradiance(q, qn, 0.05, 64, 1, "knn_simpson")[:, 0]
    ep = pre.irradiance(q, qn, 0.05, 64, 1, "knn_simpson")[:, 0]
    bins = np.floor((q[:, 0] - 0.3) / 0.01).astype(int)
    pk = np.bincount(bins, ek) / np.bincount(bins)
    pp = np.bincount(bins, ep) / np.bincount(bins)
    plateau = 2 * n * P
    assert abs(pk[:10].mean() / plateau - 1) < 0.03
    assert np.abs(pp - pk).max() < 0.04 * plateau
    assert pp[-10:].max() == 0.0  # x > 0.6: beyond the edge by more than the radius


def test_rows_it_cannot_answer_are_the_knn_rows_bits():
    """A focus (every photon on one point), masked calls and the default setting give the
    k-NN rows' bits; the map's memory grows by causticcache.BYTES_PER_PHOTON a photon."""
    rng = np.random.default_rng(7)
    n = 20_000
    spot = np.zeros((n, 3)) + [0.5, 0.5, 0.0]
    ph = _plane(np.vstack([spot[: n // 2], np.c_[rng.random(n // 2), rng.random(n // 2),
                                                 np.zeros(n // 2)]]))
    knn, pre = _maps(ph)
    q, qn = _queries(rng, 5000, 0.4, 0.6)
    floor = np.full(len(q), 0.002)
    a = knn.irradiance(q, qn, 0.1, 64, 1, "knn_simpson", True, floor)
    before = pre.nbytes
    b = pre.irradiance(q, qn, 0.1, 64, 1, "knn_simpson", True, floor)
    assert pre.nbytes - before == causticcache.BYTES_PER_PHOTON * n
    assert np.isfinite(b[0]).all()
    near = np.linalg.norm(q[:, :2] - 0.5, axis=1) < 0.02  # the focus' rows: k-NN rows
    assert np.array_equal(a[0][near], b[0][near]) and np.array_equal(a[1][near], b[1][near])
    masks = rng.random((2, n)) < 0.5
    ma = knn.irradiance(q, qn, 0.1, 64, 1, "knn_simpson", masks=masks)
    mb = pre.irradiance(q, qn, 0.1, 64, 1, "knn_simpson", masks=masks)
    assert all(np.array_equal(x, y) for x, y in zip(ma, mb))
    pre.lookup = "knn"
    assert np.array_equal(a[0], pre.irradiance(q, qn, 0.1, 64, 1, "knn_simpson", True,
                                               floor)[0])


def test_setting_is_checked():
    assert RenderSettings().caustic_lookup == "knn"
    RenderSettings(caustic_lookup="precomputed")
    with pytest.raises(ValueError, match="caustic_lookup"):
        RenderSettings(caustic_lookup="grid")
