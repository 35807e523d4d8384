"""Light for glossy lobes on a raised normal, and photons arriving at a bent normal (issue
14, nmap37). Cycles gives a Principled BSDF's glossy lobes a normal raised towards the
geometric one where the view's mirror direction about the shading normal would fall below
the surface (maybe_ensure_valid_specular_reflection); each closure then takes light above
its own normal. directlight.sample_lights / accumulate_bsdf serve the diffuse lobe on the
(bent) shading normal and the glossy lobes on the raised one. photons.bent_arrival weighs a
photon arriving at a bent normal by Cycles' bump shadowing term and |wi.ns| / |wi.ng|."""
import math

import numpy as np
import pytest

from engine import directlight as dl
from engine.closures import principled as pr
from engine.geometry import closure_params
from engine.lights import SunLight
from engine.lights.packing import pack_lights
from engine.photons import bent_arrival
from engine.scene import Material


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _sun(wi, irradiance=3.0):
    """A sun of angle 0 whose light arrives from the unit direction wi."""
    d = -np.asarray(wi, np.float64)
    base = dict(pos=np.zeros(3), dir=d, u=np.array([1.0, 0, 0]), v=np.array([0, 1.0, 0]),
                du=np.array([1.0, 0, 0]), dv=np.array([0, 1.0, 0]), radius=0.0, size_x=1.0,
                size_y=1.0, area=1.0, spread=1.0, shape="RECTANGLE", spot_size=1.0,
                spot_blend=0.1, spot_frame=np.eye(3), intensity=np.ones(3),
                radiance=np.ones(3), irradiance=np.full(3, irradiance), cos_half_angle=1.0)
    return SunLight("sun", **base)


class _Clear:
    def occluded_into(self, o32, d32, t32, blocked, cls=None):
        blocked[:] = False
        return blocked


def _radiance(ns, nsm, prm, wo, wi):
    """Outgoing radiance (3,) of one hit at the origin (geometric normal +z) lit by a sun
    from wi, its closures prm (1, N_PACK) (no diffuse lobe: fd 0)."""
    ng = np.array([[0.0, 0.0, 1.0]])
    hit = (np.zeros((1, 3)), np.array([ns], np.float64), dl.NO_ROWS3, ng, np.full(1, 1e-6),
           dl.NO_ROWS, dl.NO_ROWS, dl.NO_ROWS3, np.array([nsm], np.float64))
    u = np.full(1, 0.5)
    L, _ = dl.direct_light(pack_lights([_sun(wi)]), hit, [(0, True, 1, u, u, None)],
                           _Clear(), None, 1,
                           bsdf=(np.zeros((1, 3)), prm, np.array([wo], np.float64),
                                 np.ones(1, np.int64), np.full((1, pr.N_LOBES), 0.2)))
    return L[0].copy()


def _metal(cos_o):
    prm, _ = pr.setup_np(closure_params([Material("metal", metallic=1.0, roughness=0.8)]),
                         np.zeros(1, np.int64), np.array([[0.9, 0.7, 0.4]]),
                         np.array([cos_o]), np.ones(1, np.bool_))
    return prm


def test_raised_metal_takes_light_below_the_bent_normal():
    """Seen from straight above, a normal bent 70 degrees towards +x puts the view's mirror
    direction below the surface: the metal lobe works on a normal raised to about 45
    degrees. A sun 25 degrees from the zenith on the -x side lies below the bent normal
    but above the raised one: Cycles lights the metal (its bsdf_eval on the raised
    normal), as it lights a metal whose shading normal is the raised one - to the last
    bits. (Before: no light at all.)"""
    ng = np.array([[0.0, 0.0, 1.0]])
    wo = np.array([0.0, 0.0, 1.0])
    ns = _unit([math.sin(math.radians(70)), 0.0, math.cos(math.radians(70))])
    local, cos_o = np.zeros((1, 3)), np.array([wo @ ns])
    pr.glossy_normals(ns[None], ng, wo[None], local, cos_o)
    gn = np.empty((1, 3))
    prm = _metal(cos_o[0])
    prm[0, pr.P_GN:pr.P_GN + 3] = local[0]
    assert dl.raised_glossy_normals(prm, ns[None], gn) == 1
    raised = gn[0]
    assert raised @ raised == pytest.approx(1.0, abs=1e-12)
    assert 40.0 < math.degrees(math.acos(raised[2])) < 50.0
    wi = _unit([-math.sin(math.radians(25)), 0.0, math.cos(math.radians(25))])
    assert wi @ ns < 0.0 < wi @ raised
    lit = _radiance(ns, ng[0], prm, wo, wi)
    same = _radiance(raised, raised, _metal(wo @ raised), wo, wi)
    assert lit.min() > 0.0
    assert np.allclose(lit, same, rtol=1e-9, atol=0.0), (lit, same)


def test_unraised_rows_keep_no_normal_and_count_none():
    prm = _metal(1.0)
    ns = np.array([[0.0, 0.6, 0.8]])
    gn = np.full((1, 3), 7.0)
    assert dl.raised_glossy_normals(prm, ns, gn) == 0
    assert np.all(gn == 0.0)


def _g1_bump(cos_d, cos_i):
    """Cycles' bump shadowing term on a diffuse closure (GGX G1 of the smooth normal,
    alpha^2 = tan^2(theta_d) / 8)."""
    alpha2 = min((1.0 / cos_d ** 2 - 1.0) / 8.0, 1.0)
    lam = 0.5 * (math.sqrt(1.0 + alpha2 * (1.0 / cos_i ** 2 - 1.0)) - 1.0)
    return 1.0 / (1.0 + lam)


def test_bent_arrival_is_bump_term_times_cosine_ratio():
    """A normal bent 30 degrees towards +x; photons arriving from 20 degrees off the
    zenith on either side: G1(bump) x cos(wi, ns) / cos(wi, ng). An unbent row keeps 1;
    a photon below the bent normal stores nothing."""
    up = np.array([0.0, 0.0, 1.0])
    ns = _unit([math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))])
    rows = []
    for side in (1.0, -1.0):
        rows.append(_unit([side * math.sin(math.radians(20)), 0.0,
                           math.cos(math.radians(20))]))
    below = _unit([-math.sin(math.radians(70)), 0.0, math.cos(math.radians(70))])
    wi = np.array(rows + [below, rows[0]])
    n_smooth = np.array([up, up, up, up])
    bent = np.array([ns, ns, ns, up])
    ng = np.array([up, up, up, up])
    got = bent_arrival(n_smooth, bent, ng, wi)
    for k in range(2):
        want = (_g1_bump(ns @ up, wi[k] @ up) * (wi[k] @ ns) / (wi[k] @ up))
        assert got[k] == pytest.approx(want, rel=1e-12)
    assert below @ ns < 0.0 and got[2] == 0.0
    assert got[3] == 1.0


@pytest.mark.parametrize("tilt", [20.0, 50.0, 80.0])
def test_diffuse_bounce_needs_no_outgoing_ratio(tilt):
    """bent_arrival's claim: a photon's diffuse bounce (cosine-distributed about ns, cut
    off below ng) leaves the same power with or without the adjoint's outgoing
    |wo.ng| / |wo.ns|: both are the lune's share (1 + cos tilt) / 2."""
    rng = np.random.default_rng(5)
    n = 400_000
    u1, u2 = rng.random(n), rng.random(n)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    t = math.radians(tilt)
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], axis=1)
    # ns = (sin t, 0, cos t): the frame (cos t, 0, -sin t), (0, 1, 0), ns
    wo = (local[:, :1] * [math.cos(t), 0, -math.sin(t)] + local[:, 1:2] * [0, 1, 0]
          + local[:, 2:] * [math.sin(t), 0, math.cos(t)])
    ok = wo[:, 2] > 0
    plain = ok.mean()
    adjoint = np.where(ok, wo[:, 2] / local[:, 2], 0.0).mean()
    lune = (1 + math.cos(t)) / 2
    assert plain == pytest.approx(lune, abs=0.003)
    assert adjoint == pytest.approx(lune, abs=0.01)
