"""engine/turnedlight.py: final-gather chains add the suns they reach through Cycles'
turned-normal glass reflections, exactly the paths the photons cannot carry
(docs/accuracy.md, turnednormal44)."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from engine import glassadjoint as ga
from engine import photonkernels as pk
from engine import turnedlight
from engine.closures import principled as pr
from test_glass_adjoint import IOR, _gprm


def _unit(rng, z_lo, z_hi):
    z, a = rng.uniform(z_lo, z_hi), rng.uniform(0.0, 2.0 * math.pi)
    r = math.sqrt(1.0 - z * z)
    return np.array([r * math.cos(a), r * math.sin(a), z])


def _reflections(rng, n, bend_lo, bend_hi):
    """n camera-side reflections at smooth glass as Cycles makes them: normals ns bent
    bend_lo..bend_hi degrees from g = +z, directions w above g, the mirror direction of
    w about Cycles' normal (turned or not). Returns (ns, g, d_in, d_out, raised)."""
    ns, g, d_in, d_out, raised = [], [], [], [], []
    for _ in range(n):
        t = math.radians(rng.uniform(bend_lo, bend_hi))
        a = rng.uniform(0.0, 2.0 * math.pi)
        nn = np.array([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)])
        w = _unit(rng, 0.02, 1.0)
        up, p0, p1, p2 = pr.valid_reflection_normal(*nn, 0.0, 0.0, 1.0, *w)
        m = np.array([p0, p1, p2]) if up else nn
        m = m / np.linalg.norm(m)
        r = 2.0 * float(w @ m) * m - w
        ns.append(nn)
        g.append((0.0, 0.0, 1.0))
        d_in.append(-w)
        d_out.append(r)
        raised.append(up)
    return (np.array(ns), np.array(g), np.array(d_in), np.array(d_out),
            np.array(raised, bool))


def _turned(mat_glass, ns, g, d_in, d_out, mats=None):
    bend_cos = math.cos(math.radians(pk.GLASS_ADJOINT_MIN_BEND_DEG))
    tr = turnedlight.TurnedReflections(np.array(mat_glass, bool), bend_cos, [])
    y = SimpleNamespace(mat=np.zeros(len(ns), np.int64) if mats is None else mats,
                        ns=ns, ng=g)
    return tr.turned(y, np.arange(len(ns)), d_in, d_out)


def test_turned_flags_cycles_turned_reflections_at_bent_smooth_glass():
    """The flag is Cycles' own test (principled.valid_reflection_normal raised) for
    reflections at smooth glass bent more than GLASS_ADJOINT_MIN_BEND_DEG; never for
    refractions, other materials or milder bends (where photons keep main's rule)."""
    rng = np.random.default_rng(0)
    ns, g, d_in, d_out, raised = _reflections(rng, 2000, 8.0, 60.0)
    flag = _turned([True], ns, g, d_in, d_out)
    assert raised.sum() > 200 and (~raised).sum() > 200
    np.testing.assert_array_equal(flag, raised)
    assert not _turned([False], ns, g, d_in, d_out).any()
    below = d_out * np.array([1.0, 1.0, -1.0])  # the same rows as refractions (below Ng)
    assert not _turned([True], ns, g, d_in, below).any()
    ns2, g2, d_in2, d_out2, raised2 = _reflections(rng, 2000, 0.0, 5.9)
    assert raised2.any()  # Cycles turns some at mild bends too: left to the photons' rule
    assert not _turned([True], ns2, g2, d_in2, d_out2).any()


def test_flagged_reflections_are_exactly_those_photons_cannot_take():
    """The split with the photon maps: a photon arriving along the reflection's way back
    (-d_out, on the camera's side) leaves along the camera's w among the glass adjoint's
    candidates (engine/glassadjoint.py, the rule photons follow at these bends) exactly
    where the reflection is not flagged; a flagged (turned) reflection has no photon
    counterpart, so adding its light double counts nothing."""
    rng = np.random.default_rng(1)
    ns, g, d_in, d_out, _ = _reflections(rng, 600, 8.0, 50.0)
    flag = _turned([True], ns, g, d_in, d_out)
    out = np.zeros((ga.MAX_W, 7))
    carried = np.zeros(len(ns), bool)
    for i in range(len(ns)):
        w = -d_in[i]
        # the photon travels along -d_out, arriving on the camera's side (from air)
        k = ga.candidates(_gprm(IOR), -d_out[i], ns[i], g[i], out, True)
        carried[i] = any(out[j, 6] < 0.5 and np.linalg.norm(out[j, :3] - w) < 1e-6
                         for j in range(k))
    assert flag.sum() > 50 and (~flag).sum() > 50
    np.testing.assert_array_equal(carried, ~flag)


def test_escaped_sun_radiance_integrates_to_its_irradiance():
    """The radiance escaped() gives inside a sun's disc, integrated over directions
    (uniform over the sphere) with the cosine to its axis, is the sun's irradiance;
    rays of a class the sun is invisible to see none."""
    from engine.lights.sun import SunLight
    sun = SimpleNamespace(dir=np.array([0.0, 0.0, -1.0]), cos_half_angle=math.cos(
        math.radians(15.0)), sun_radiance=np.array([4.0, 2.0, 1.0]) / (
        math.pi * math.sin(math.radians(15.0)) ** 2), ray_kinds=2)
    sun.seen_at_infinity = lambda d: SunLight.seen_at_infinity(sun, d)
    tr = turnedlight.TurnedReflections(np.zeros(1, bool), 1.0, [sun])
    rng = np.random.default_rng(2)
    n = 400_000
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    L = tr.escaped(d, 2)
    E = (L * np.maximum(d[:, 2:3], 0.0)).sum(axis=0) * 4.0 * math.pi / n
    np.testing.assert_allclose(E, [4.0, 2.0, 1.0], rtol=0.02)
    assert not tr.escaped(d[:100], 4).any()


def _slab_context(bend_deg, sun_angle_deg=10.0):
    """tests/test_glass_adjoint.py's glass slab (top face's normals leaning bend_deg)
    under a sun of the given disc, prepared: the render Context."""
    from test_glass_adjoint import _slab
    from engine import RenderSettings
    from engine.accel import Accel
    from engine.geometry import prepare
    from engine.lights import prepare_lights
    from engine.render import Context
    scene = _slab(bend_deg)
    for light in scene.lights:
        light.angle = math.radians(sun_angle_deg)
    scene.validate()
    geo, table = prepare(scene)
    lights = prepare_lights(scene, geo, table)
    return Context(scene, RenderSettings(photons=1000, seed=0), geo, table,
                   Accel(geo.vertices32, geo.faces32, 1), lights)


@pytest.mark.parametrize("bend_deg,expect", [(1.5, False), (5.0, False), (20.0, True)])
def test_only_glass_bent_past_the_threshold_takes_part(bend_deg, expect, monkeypatch):
    """for_context is None (no work, the same bits) for glass bent no more than
    GLASS_ADJOINT_MIN_BEND_DEG (a tessellated ball's few degrees) and with the module
    switched off; a sun without a disc is not among the suns escapes see. Hits on the
    slab's bent top face are unguarded where their own normal bends past the threshold,
    its flat faces never."""
    ctx = _slab_context(bend_deg)
    tr = turnedlight.TurnedReflections.for_context(ctx)
    assert (tr is not None) == expect
    if expect:
        assert len(tr.suns) == 1
        top = np.flatnonzero(tr.glass_tri)
        assert len(top) == 2  # the top face's two triangles
        prim = np.repeat(top, 50)
        rng = np.random.default_rng(3)
        u, v = rng.random((2, len(prim)))
        flip = u + v > 1.0
        u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
        n = ctx.geo.shading_normals(prim, u, v)
        g = np.asarray(ctx.geo.ng[prim])
        want = np.abs(np.einsum("ij,ij->i", n, g)) < tr.bend_cos
        assert want.any() and not want.all()  # the pillow flattens towards its middle
        np.testing.assert_array_equal(tr.unguarded(ctx.geo, prim, u, v), want)
        flat = np.flatnonzero(~tr.glass_tri)[:4]
        assert not tr.unguarded(ctx.geo, flat, u[:4], v[:4]).any()
        no_disc = turnedlight.TurnedReflections.for_context(_slab_context(bend_deg, 0.0))
        assert no_disc is not None and no_disc.suns == []
        monkeypatch.setattr(turnedlight, "ENABLED", False)
        assert turnedlight.TurnedReflections.for_context(_slab_context(bend_deg)) is None


def test_camera_paths_unguard_the_same_hits_as_the_gather_chains(monkeypatch):
    """camera_unguarded (integrator._trace_paths' rows that keep their shading normal,
    turnedcamera45) is unguarded's rows, minus rows whose Light Path material variant is
    not smooth glass; None where no row is (the fused kernel then runs: the same bits)
    and with turnedlight.CAMERA off (the guard as before)."""
    ctx = _slab_context(20.0)
    tr = turnedlight.TurnedReflections.for_context(ctx)
    top = np.flatnonzero(tr.glass_tri)
    prim = np.repeat(top, 50)
    rng = np.random.default_rng(5)
    u, v = rng.random((2, len(prim)))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    want = tr.unguarded(ctx.geo, prim, u, v)
    assert want.any()
    np.testing.assert_array_equal(tr.camera_unguarded(ctx.geo, prim, u, v), want)
    mats = np.asarray(ctx.geo.material)[prim].copy()
    other = int(np.flatnonzero(~tr.glass_mat)[0])  # a material that is not smooth glass
    mats[::2] = other
    got = tr.camera_unguarded(ctx.geo, prim, u, v, mats)
    np.testing.assert_array_equal(got, want & (np.arange(len(prim)) % 2 == 1))
    flat = np.flatnonzero(~tr.glass_tri)[:4]
    assert tr.camera_unguarded(ctx.geo, flat, u[:4], v[:4]) is None
    monkeypatch.setattr(turnedlight, "CAMERA", False)
    assert tr.camera_unguarded(ctx.geo, prim, u, v) is None


def test_instanced_glass_is_unguarded_as_its_copies(monkeypatch):
    """Instances whose rows are shared (engine/sharedrows.py; a mirrored one among them)
    give the same bent glass rows and unguarded hits as their world-space copies (the
    photons take glassadjoint's rule at every hit, instanced or not), and no (T,)
    column: glass_tri None, the rows kept as glass_rows (for_context was None for any
    scene with instances; vase48)."""
    from test_turned_glossy import _grazing, _placed_slabs
    from engine.scene import Material
    glass = Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=IOR)
    (gi, ti), (gc, tc), top = _placed_slabs(monkeypatch, glass, 20.0)
    tr_c = turnedlight.TurnedReflections.for_context(SimpleNamespace(geo=gc, table=tc,
                                                                     lights=[]))
    tr_i = turnedlight.TurnedReflections.for_context(SimpleNamespace(geo=gi, table=ti,
                                                                     lights=[]))
    assert tr_c is not None and tr_i is not None and tr_i.glass_tri is None
    np.testing.assert_array_equal(tr_i.glass_rows, np.flatnonzero(tr_c.glass_tri))
    np.testing.assert_array_equal(np.sort(top), tr_i.glass_rows)  # the top faces alone
    prim, u, v, _ = _grazing(top)
    want = tr_c.unguarded(gc, prim, u, v)
    assert want.any() and not want.all()
    np.testing.assert_array_equal(tr_i.unguarded(gi, prim, u, v), want)
    np.testing.assert_array_equal(tr_i.camera_unguarded(gi, prim, u, v), want)
    others = np.setdiff1d(np.arange(gi.count), top)
    assert not tr_i.bent_triangles(others).any()
