"""engine/glassadjoint.py: photons at smooth glass with bent shading normals leave along
the directions Cycles' glass sends to their arrival, with the flux Cycles' camera paths
see (docs/accuracy.md, smoothglass43)."""
import math
import sys

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
        k = ga.candidates(_gprm(rq), -s, -nq, -gq, out, True)  # the photon travels along -s
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
        k = ga.candidates(gprm, d, -nq, -gq, out, True)
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


def _main_directions(d, n, g, eta):
    """The directions photonkernels' own smooth glass sample can send a photon arriving
    along d (n, g on its side; eta = eta_to / eta_from) and keep: the mirror direction
    about n if it leaves above Ng, the refraction about n (none at total internal
    reflection) if it leaves below."""
    cs = -float(d @ n)
    out = []
    m = d + 2.0 * cs * n
    if m @ g > 0.0:
        out.append((m, 0.0))
    ok, t0, t1, t2 = ga.refract_dir(*d, *n, 1.0 / eta)
    if ok and t0 * g[0] + t1 * g[1] + t2 * g[2] < 0.0:
        out.append((np.array([t0, t1, t2]), 1.0))
    return out


@pytest.mark.parametrize("bend_deg", [0.5, 2.0, 10.0, 45.0])
def test_where_no_turn_is_possible_the_adjoint_sends_photons_mains_ways(bend_deg):
    """turn_possible False (photonkernels then skips the root search) only where the
    adjoint's candidates are exactly the glass lobe's two directions about n: no
    turned-normal refraction, the mirror and the refraction about n not turned away.
    Random arrivals from air and from glass at shading normals bent bend_deg from Ng."""
    rng = np.random.default_rng(3)
    g = np.array([0.0, 0.0, 1.0])
    out = np.zeros((ga.MAX_W, 7))
    kept = differs = 0
    tilt = math.radians(bend_deg)
    for i in range(600):
        eta = IOR if i % 2 else 1.0 / IOR  # arriving from air, from glass
        az = rng.uniform(0.0, 2.0 * math.pi)
        n = np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az),
                      math.cos(tilt)])
        z, a = rng.uniform(0.0, 1.0), rng.uniform(0.0, 2.0 * math.pi)
        s = np.array([math.sqrt(1 - z * z) * math.cos(a), math.sqrt(1 - z * z) * math.sin(a), z])
        d = -s
        k = ga.candidates(_gprm(eta), d, n, g, out, True)
        if ga.turn_possible(*d, *n, *g, eta):
            guarded = n if -float(d @ n) > 1e-6 else g  # photon_surfaces' guard
            main = _main_directions(d, guarded, g, eta)
            differs += not (k == len(main) and all(
                min(np.linalg.norm(out[j, :3] - w) for w, _ in main) < 1e-9
                for j in range(k)))
            continue
        kept += 1
        main = _main_directions(d, n, g, eta)
        assert k == len(main), (d, n, eta, k, main)
        rows = out[:k].copy()  # the same rows without the root search
        assert ga.candidates(_gprm(eta), d, n, g, out, False) == k
        assert np.array_equal(out[:k], rows)
        for w, transmitted in main:
            j = int(np.argmin(np.linalg.norm(out[:k, :3] - w, axis=1)))
            assert np.linalg.norm(out[j, :3] - w) < 1e-12 and out[j, 6] == transmitted
    # The bound keeps most arrivals on main's rule at a ball's few degrees of bend, and
    # is not vacuous where the bend is strong (the adjoint does differ there).
    if bend_deg <= 2.0:
        assert kept > 0.9 * 600, kept
    else:
        assert differs > 20, differs


MAX_DEPTH = 8


def _slab(bend_deg, material=None):
    """A 2 x 2 x 0.5 m glass slab over a floor under a sun 30 degrees off the vertical; the slab's top face smooth-shaded with its
    corner normals leaning bend_deg outwards (a pillow), its other faces flat. material:
    the slab's (an engine.scene.Material) instead of the glass."""
    from engine.api import PaperScene, box_mesh
    from engine.scene import Material
    s = PaperScene(width=8, height=8)
    slab = material or Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=IOR)
    s.add_material(slab)
    s.add_material(Material("floor", (0.8, 0.8, 0.8)))
    v, f = box_mesh((0.0, 0.0, 0.75), (2.0, 2.0, 0.5))
    normals = np.zeros((len(f), 3, 3))
    tilt = math.radians(bend_deg)
    for i, face in enumerate(f):
        e = np.cross(v[face[1]] - v[face[0]], v[face[2]] - v[face[0]])
        normals[i] = e / np.linalg.norm(e)
        if normals[i, 0, 2] > 0.9:  # the top face: lean each corner out by bend_deg
            for c, vi in enumerate(face):
                out = v[vi, :2] / np.linalg.norm(v[vi, :2])
                normals[i, c] = (math.sin(tilt) * out[0], math.sin(tilt) * out[1],
                                 math.cos(tilt))
    s.add_triangles(v, f, slab.name, name="Slab", normals=normals)
    s.add_plane((0, 0, 0), (0, 0, 1), 3.0, "floor", name="Floor")
    s.add_sun(direction=(-0.5, 0.0, -math.sqrt(0.75)), strength=3.0)
    s.set_camera((0, -6, 3), (0, 0, 1))
    return s


def _photons(monkeypatch, bend_deg, mode, min_bend=None):
    """The caustic shot's photons (stopped at their first diffuse hit: none comes back
    up into the slab from the floor) as bytes, scatter's rule set to mode (and
    GLASS_ADJOINT_MIN_BEND_DEG to min_bend, unless None)."""
    from engine import RenderSettings
    from engine import photonkernels as pk
    from engine.accel import Accel
    from engine.geometry import prepare
    from engine.lights import allocate_photons, prepare_lights
    from engine.photons import trace_photons
    from engine.render import Context
    monkeypatch.setattr(pk, "GLASS_ADJOINT_MODE", mode)
    if min_bend is not None:
        monkeypatch.setattr(pk, "GLASS_ADJOINT_MIN_BEND_DEG", min_bend)
    scene = _slab(bend_deg)
    settings = RenderSettings(photons=20_000, seed=4, max_photon_depth=MAX_DEPTH)
    scene.validate()
    geo, table = prepare(scene)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, settings, geo, table, Accel(geo.vertices32, geo.faces32, 1), lights)
    ph = trace_photons(ctx, lights, allocate_photons(lights, settings.photons), True, 1)
    assert len(ph) > 2000
    return np.concatenate([ph.position.ravel(), ph.power.ravel()]).tobytes()


def test_smooth_glass_photons_by_bend(monkeypatch):
    """A glass slab whose top face's shading normals lean outwards, lit at 30 degrees.
    1.5 degrees (under GLASS_ADJOINT_MIN_BEND_DEG, as a tessellated ball's): scatter
    keeps the glass lobe's own sample, the photons are those of the rule without the
    adjoint (GLASS_ADJOINT_NEVER, main's before smoothglass43) bit for bit, while
    smoothglass43's rule (the adjoint at every bent hit) moves them. 10 degrees, the
    adjoint at every hit bent > 0.1 degree, photons stopped at their third hit: each
    meets the face far from grazing and from the critical angle, where Cycles turns no
    normal, so skipping the root search there (turn_possible) gives the same photons as
    searching at every hit (smoothglass43); the adjoint's flux ratio moves them from
    main's. 40 degrees: the default rule moves them too."""
    from engine import photonkernels as pk
    assert 1.5 < pk.GLASS_ADJOINT_MIN_BEND_DEG < 10.0
    never, every, where = (pk.GLASS_ADJOINT_NEVER, pk.GLASS_ADJOINT_EVERY_BENT,
                           pk.GLASS_ADJOINT_WHERE_TURNED)
    mild = _photons(monkeypatch, 1.5, where)
    assert mild == _photons(monkeypatch, 1.5, never)
    assert mild != _photons(monkeypatch, 1.5, every)
    monkeypatch.setattr(sys.modules[__name__], "MAX_DEPTH", 3)
    flat_deg = math.degrees(math.acos(pk._FLAT_NORMAL_COS))
    bent = _photons(monkeypatch, 10.0, where, min_bend=flat_deg)
    assert bent == _photons(monkeypatch, 10.0, every)
    assert bent != _photons(monkeypatch, 10.0, never)
    assert _photons(monkeypatch, 40.0, where) != _photons(monkeypatch, 40.0, never)


@pytest.mark.parametrize("tilt", [0.0, 0.3, 0.8])
def test_photon_reflected_flux_matches_cycles_unturned_reflections(tilt):
    """Uniform radiance on side P: the photons' reflected flux (cosine-weighted arrivals,
    the mirror candidates' weights F |w.Ng| / |s.Ng|) equals the flux Cycles' camera
    paths see by reflection about the untouched shading normal (the integral of
    F |w.Ng| over the w Cycles does not turn the normal for, whose mirror s arrives
    from above Ng), flat or bent; the turned-normal reflections, which squeeze a solid
    angle onto a band no photon arrives from, are left out of both (module doc;
    review44: only the refraction's flux was checked)."""
    rng = np.random.default_rng(3)
    m = 64
    n = m * m
    grid = (np.arange(n) // m, np.arange(n) % m)
    eta = IOR  # the photon arrives from the air
    g = np.array([0.0, 0.0, 1.0])
    ns = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    z = (grid[0] + rng.random(n)) / m
    a = (grid[1] + rng.random(n)) / m * 2.0 * math.pi
    cam = 0.0
    for zi, ai in zip(z, a):  # w uniform over P's hemisphere, pdf 1 / (2 pi)
        w = np.array([math.sqrt(1 - zi * zi) * math.cos(ai),
                      math.sqrt(1 - zi * zi) * math.sin(ai), zi])
        raised = pr.valid_reflection_normal(*ns, *g, *w)[0]
        c = float(w @ ns)
        s = 2.0 * c * ns - w
        if raised or c <= 0.0 or s @ g <= 0.0:
            continue
        cam += pr._glass_F_s(F0, schlick_remap(c, eta)) * zi * 2.0 * math.pi / n
    u = (grid[0] + rng.random(n)) / m
    a = (grid[1] + rng.random(n)) / m * 2.0 * math.pi
    out = np.zeros((ga.MAX_W, 7))
    gprm = _gprm(eta)
    photon = 0.0
    # Arrivals s uniform over P's hemisphere, each carrying flux |s.Ng| 2 pi / n (not
    # cosine-distributed ones of flux pi / n: the weights' 1 / |s.Ng| near grazing left
    # 2 % of noise at this count).
    for ui, ai in zip(u, a):
        r = math.sqrt(1.0 - ui * ui)
        d = np.array([r * math.cos(ai), r * math.sin(ai), -ui])
        k = ga.candidates(gprm, d, ns, g, out, True)
        for i in range(k):
            if out[i, 6] < 0.5:
                photon += out[i, 3] * ui * 2.0 * math.pi / n
    assert cam > 0.03
    assert photon == pytest.approx(cam, rel=0.02)
