"""engine/glassadjoint.py: photons at smooth glass with bent shading normals leave along
the directions Cycles' glass sends to their arrival, with the flux Cycles' camera paths
see (docs/accuracy.md, smoothglass43)."""
import math

import numpy as np
import pytest

from engine import glassadjoint as ga
from engine.closures import principled as pr
from engine.closures.fresnel import schlick_remap

IOR = 1.5
F0 = ((IOR - 1.0) / (IOR + 1.0)) ** 2


def _gprm(eta):
    """A white smooth glass hit's packed columns, eta = eta_to / eta_from of the photon."""
    g = np.zeros((1, pr.N_PACK))
    g[0, pr.P_GLASS_ETA] = eta
    g[0, pr.P_GLASS_RW:pr.P_GLASS_RW + 3] = 1.0
    g[0, pr.P_GLASS_TW:pr.P_GLASS_TW + 3] = 1.0
    g[0, pr.P_GLASS_F0:pr.P_GLASS_F0 + 3] = F0
    return g


def _cycles_refraction(nq, gq, w, rq):
    """Cycles' smooth glass for camera-side direction w on side Q (normals nq, gq facing
    it), rq = eta_Q / eta_P: (the direction its path leaves along on side P or None, the
    turned normal, transmittance)."""
    raised, p0, p1, p2 = pr.valid_reflection_normal(*nq, *gq, *w)
    n = np.array([p0, p1, p2]) if raised else nq
    n = n / np.linalg.norm(n)
    ok, s0, s1, s2 = ga.refract_dir(-w[0], -w[1], -w[2], *n, rq)
    if not ok or s0 * gq[0] + s1 * gq[1] + s2 * gq[2] >= 0.0:
        return None, raised, 0.0
    f = pr._glass_F_s(F0, schlick_remap(float(w @ n), 1.0 / rq))
    return np.array([s0, s1, s2]), raised, 1.0 - f


def test_photon_finds_every_camera_direction_cycles_refracts_to_it():
    """For random bent normals and camera-side directions, Cycles' refraction (turned
    normal or not) sends w to s; a photon arriving from s has w among its candidates."""
    rng = np.random.default_rng(1)
    gq = np.array([0.0, 0.0, 1.0])
    out = np.zeros((ga.MAX_W, 7))
    found = total = turned = 0
    for _ in range(400):
        q_in_air = rng.random() < 0.5
        rq = 1.0 / IOR if q_in_air else IOR
        tilt, az = rng.uniform(0.0, 0.8), rng.uniform(0.0, 2.0 * math.pi)
        nq = np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az),
                       math.cos(tilt)])
        z, a = rng.uniform(0.02, 1.0), rng.uniform(0.0, 2.0 * math.pi)
        w = np.array([math.sqrt(1 - z * z) * math.cos(a), math.sqrt(1 - z * z) * math.sin(a), z])
        s, raised, _ = _cycles_refraction(nq, gq, w, rq)
        if s is None:
            continue
        total += 1
        turned += raised
        k = ga.candidates(_gprm(rq), -s, -nq, -gq, out)  # the photon travels along -s
        err = min([np.linalg.norm(out[i, :3] - w) for i in range(k) if out[i, 6] > 0.5]
                  + [1.0])
        found += err < 1e-6
    assert total > 200 and turned > 30
    assert found >= 0.98 * total, (found, total)


@pytest.mark.parametrize("q_in_air", [True, False])
@pytest.mark.parametrize("tilt", [0.0, 0.8])
def test_photon_flux_matches_cycles_transmittance(q_in_air, tilt):
    """Uniform radiance on side P: the photons' flux leaving into side Q (cosine-weighted
    arrivals, candidates' refraction weights times (eta_P / eta_Q)^2) equals the flux
    Cycles' camera paths see there (the integral of T |w.Ng| over side Q), flat (tilt 0)
    or bent 0.8 rad (where Cycles turns the normal for many w), to Monte Carlo noise."""
    rng = np.random.default_rng(2)
    m = 64  # jittered m x m strata of each sample pair (low noise at few samples)
    n = m * m
    grid = (np.arange(n) // m, np.arange(n) % m)
    rq = 1.0 / IOR if q_in_air else IOR
    gq = np.array([0.0, 0.0, 1.0])
    nq = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    z = (grid[0] + rng.random(n)) / m
    a = (grid[1] + rng.random(n)) / m * 2.0 * math.pi
    cam = 0.0
    for zi, ai in zip(z, a):  # uniform over Q's hemisphere, pdf 1 / (2 pi)
        w = np.array([math.sqrt(1 - zi * zi) * math.cos(ai),
                      math.sqrt(1 - zi * zi) * math.sin(ai), zi])
        s, _, t = _cycles_refraction(nq, gq, w, rq)
        if s is not None:
            cam += t * zi * 2.0 * math.pi / n
    u = (grid[0] + rng.random(n)) / m
    a = (grid[1] + rng.random(n)) / m * 2.0 * math.pi
    out = np.zeros((ga.MAX_W, 7))
    gprm = _gprm(rq)
    photon = 0.0
    for ui, ai in zip(u, a):  # cosine-distributed arrivals from side P: flux pi / n each
        r = math.sqrt(ui)
        d = np.array([-r * math.cos(ai), -r * math.sin(ai), math.sqrt(1.0 - ui)])
        k = ga.candidates(gprm, d, -nq, -gq, out)
        for i in range(k):
            if out[i, 6] > 0.5:
                photon += out[i, 3] * math.pi / n / (rq * rq)
    assert photon == pytest.approx(cam, rel=0.02)


def test_pick_divides_by_its_choice():
    """pick returns a candidate's weights over its probability (largest channel share)."""
    out = np.zeros((ga.MAX_W, 7))
    out[0, :7] = (0.0, 0.0, 1.0, 0.2, 0.2, 0.2, 0.0)
    out[1, :7] = (0.0, 0.0, -1.0, 0.6, 0.6, 0.6, 1.0)
    ok, w0, w1, w2, k0, k1, k2, transmitted = ga.pick(out, 2, 0.5)
    assert ok and transmitted and w2 == -1.0
    assert k0 == pytest.approx(0.8)
    ok, w0, w1, w2, k0, k1, k2, transmitted = ga.pick(out, 2, 0.1)
    assert ok and not transmitted and k0 == pytest.approx(0.8)
    assert not ga.pick(out, 0, 0.5)[0]
