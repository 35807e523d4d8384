"""principled.setup's glass layer with its per-material terms computed once a run of hits
(principled.glass_terms, tables.lookup3_at): the same bits as the per-hit formulas it
replaced (tables.glass_E, tables.schlick_ior_s, fresnel.schlick_remap, F0_from_ior),
whatever the order of materials and sides in the batch."""
import math

import numpy as np
import pytest

from engine.closures import principled as pr
from engine.closures import tables
from engine.closures.fresnel import F0_from_ior, schlick_remap


def _bits(x):
    return np.ascontiguousarray(x, np.float64).view(np.int64)


@pytest.mark.parametrize("name", ["GLASS_E", "GLASS_INV_E", "SCHLICK_IOR_S"])
def test_lookup3_at_is_lookup3(name):
    tab = getattr(tables, name)
    assert np.isfinite(tab).all()  # lookup3_at's skipped terms are 0 x a finite value
    rng = np.random.default_rng(3)
    for x in (0.0, 1.0 / 15.0, 0.2, 0.37, 1.0, 1.3):
        for z in (0.0, 0.4472135954999579, 0.6, 0.98):
            i, fx = tables._coord(x, tab.shape[0])
            k, fz = tables._coord(z, tab.shape[2])
            for y in np.concatenate([rng.random(50), [0.0, 1.0, 1e-4, -0.5]]):
                want = tables.lookup3(tab, x, y, z)
                got = tables.lookup3_at(tab, float(i), fx, y, float(k), fz)
                assert _bits(got) == _bits(want), (x, y, z)


def _materials(rng, m):
    """Glass materials: Principled, Glass BSDF and Refraction BSDF nodes, smooth and rough,
    IOR above and below 1, with and without Multiscatter GGX, tinted specular."""
    P = np.zeros((m, pr.N_MAT))
    P[:, pr.M_ALPHA] = 1.0
    P[:, pr.M_ROUGH] = rng.choice([0.0, 0.0, 1.0 / 15.0, 0.25, 0.6], m)
    P[:, pr.M_TRANS] = rng.choice([1.0, 1.0, 0.7], m)
    P[:, pr.M_IOR] = rng.choice([1.5, 1.33, 0.8, 1.0, 2.4, 60.0], m)
    P[:, pr.M_LEVEL] = 0.5
    P[:, pr.M_STINT:pr.M_STINT + 3] = rng.choice([1.0, 0.5, 3.0, -1.0], (m, 3))
    P[:, pr.M_MULTI] = rng.choice([0.0, 1.0], m)
    P[:, pr.M_NODE] = rng.choice([pr.NODE_PRINCIPLED, pr.NODE_GLASS, pr.NODE_REFRACTION], m)
    return P


def _glass_per_hit(q, base, mu, front):
    """setup's glass columns and albedos for one hit of a material whose layers above the
    glass leave it weight 1 (alpha 1, no sheen, coat or metal), the per-hit way."""
    rough, tr, multi, node = q[pr.M_ROUGH], q[pr.M_TRANS], q[pr.M_MULTI], q[pr.M_NODE]
    ior = max(q[pr.M_IOR], 1e-5)
    eta = ior if front else 1.0 / ior
    Eg, Eg_avg = tables.glass_E(rough, mu, eta)
    F0g = F0_from_ior(ior)
    s_n = tables.schlick_ior_s(rough, mu, ior) if eta >= 1.0 else schlick_remap(mu, eta)
    rw, tw, f0s, wr, wt = [], [], [], [], []
    for c in range(3):
        if node == pr.NODE_REFRACTION:
            tt = max(base[c], 0.0)
            rw.append(0.0), tw.append(tr * 1.0 * tt), f0s.append(-1.0)
            wr.append(0.0), wt.append(tr * 1.0 * tt)
            continue
        if node == pr.NODE_GLASS:
            rt = tt = max(base[c], 0.0)
            f0 = F0g
        else:
            rt = 1.0
            tt = math.sqrt(min(max(base[c], 0.0), 1.0))
            f0 = min(F0g * max(q[pr.M_STINT + c], 0.0), 1.0)
        fac, dark = pr._compensation(multi, Eg, Eg_avg, tt)
        rw.append(tr * 1.0 * rt * fac), tw.append(tr * 1.0 * tt * fac), f0s.append(f0)
        wr.append(tr * 1.0 * rt * dark * (f0 + (1.0 - f0) * s_n))
        wt.append(tr * 1.0 * tt * dark * (1.0 - (f0 + (1.0 - f0) * s_n)))
    return rw, tw, f0s, eta, wr, wt


def test_setup_glass_is_the_per_hit_formulas():
    rng = np.random.default_rng(11)
    P = _materials(rng, 24)
    n = 1200
    # runs of one material (the cached case), then materials and sides at random
    mat = np.concatenate([np.repeat(rng.integers(0, 24, 60), 10),
                          rng.integers(0, 24, n - 600)]).astype(np.int64)
    front = np.concatenate([np.repeat(rng.random(60) < 0.5, 10), rng.random(n - 600) < 0.5])
    base = rng.choice([0.0, 0.25, 0.8, 1.0, 1.4, -0.3], (n, 3))
    cos = np.concatenate([rng.uniform(-0.1, 1.1, n - 4), [0.0, 1.0, 1e-4, 0.5]])
    prm, w = pr.setup_np(P, mat, base, cos, front)
    for i in range(n):
        mu = min(max(cos[i], 0.0), 1.0)
        rw, tw, f0s, eta, wr, wt = _glass_per_hit(P[mat[i]], base[i], mu, bool(front[i]))
        assert (_bits(prm[i, pr.P_GLASS_RW:pr.P_GLASS_RW + 3]) == _bits(rw)).all(), i
        assert (_bits(prm[i, pr.P_GLASS_TW:pr.P_GLASS_TW + 3]) == _bits(tw)).all(), i
        assert (_bits(prm[i, pr.P_GLASS_F0:pr.P_GLASS_F0 + 3]) == _bits(f0s)).all(), i
        assert _bits(prm[i, pr.P_GLASS_ETA]) == _bits(eta), i
        assert (_bits(w[i, pr.L_GLASS_R]) == _bits(wr)).all(), i
        assert (_bits(w[i, pr.L_GLASS_T]) == _bits(wt)).all(), i
    # Each hit alone (glass_terms computed afresh every time): the same bits.
    for i in range(0, n, 7):
        p1, w1 = pr.setup_np(P, mat[i:i + 1], base[i:i + 1], cos[i:i + 1], front[i:i + 1])
        assert (_bits(p1[0]) == _bits(prm[i])).all() and (_bits(w1[0]) == _bits(w[i])).all()
