"""Clamp Indirect per photon (engine/photonclamp.py): each photon of a caustic / glow /
secondary estimate weighed by w_p = min(1, limit / |tp x albedo x L_p|_1), as Cycles
clamps the path the photon ends; L_p (Photons.radiance) carried by the photon pass."""
import math

import numpy as np
import pytest

from engine import RenderSettings, photonclamp, photonvisibility
from engine.accel import Accel
from engine.api import PaperScene
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photonlayout import decode_power
from engine.photonmap import PhotonMap
from engine.photons import CAUSTIC, DIRECT, INDIRECT, Photons, trace_photons
from engine.render import Context, prepare_context
from engine.lights.mesh import MESH
from engine.lights.world import WORLD
from engine.scene import AREA, Material

SUN_E, ANGLE = 3.0, 1.0  # W/m^2, degrees


def test_photon_weight_is_the_limit_over_the_path_contribution():
    power = np.array([[1.0, 2.0, 1.0], [1.0, 2.0, 1.0], [3.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    # |L_p|_1 = 60 at scale 1 against a limit of 30: half; 30: whole; 0 (a delta
    # light's): whole; a coloured scale reads the flux's colour (a grey photon of 20 at a
    # red scale 1.5: 10, under 15).
    rad = np.array([60.0, 30.0, 0.0, 20.0])
    w = photonclamp.photon_weights(rad, power, np.ones(3), 30.0)
    assert np.array_equal(w[:3], [0.5, 1.0, 1.0])
    w = photonclamp.photon_weights(rad[2:], power[2:], np.array([1.5, 0.0, 0.0]), 15.0)
    assert np.array_equal(w, [1.0, 1.0])
    # A red photon of |L_p|_1 20 at a red scale 3: 60 over a limit of 15.
    w = photonclamp.photon_weights(np.array([20.0]), power[2:3], np.array([3.0, 0.0, 0.0]),
                                   15.0)
    assert np.array_equal(w, [0.25])



def _cycles_roulette(t0, hits, first_bounce, min_light_bounces=0):
    """prod q along a white chain of `hits` surface hits after the camera's diffuse
    bounce, the first at path bounce first_bounce, walked as Cycles walks it: at each hit
    q = 1 where bounce <= min_light_bounces + 1 (kintegrator->min_bounce), else min(1,
    sqrt(max throughput)); the throughput divided by q (path_state.h,
    path_state_continuation_probability; shade_surface.h, integrate_surface)."""
    t, prod = t0, 1.0
    for bounce in range(first_bounce, first_bounce + hits):
        step = 1.0 if bounce <= min_light_bounces + 1 else min(1.0, math.sqrt(t))
        prod *= step
        t /= step
    return prod


def test_roulette_share_is_cycles_continuation_along_a_white_chain():
    """Read at the camera's first hit (bounce 0), a photon's chain of k scatters is the
    path's hits at bounces 1..k; Cycles plays no roulette at bounce <= Min Light Bounces
    + 1 = 1, so the chain's first hit is free and Q = t0^(1 - 2^-(k - 1)); 1 from t0 >= 1,
    k = 0 or k = 1 (a glow's single rough scatter, reached by next-event estimation or
    by the BSDF ray: the roulette is played at the hit, before either). Read at bounce
    b >= 1 no hit is free. The weight's limit is Q x the limit."""
    t = 0.8
    for k in range(6):
        want = _cycles_roulette(t, k, first_bounce=1)
        share = photonclamp.roulette_share(np.array([0.2, t, 0.5]), k)
        assert share == pytest.approx(want, rel=1e-12)
        # read deeper (past a camera-side mirror: the chain's first hit at bounce 2 or
        # 3): none free
        for bounce in (1, 2):
            assert photonclamp.roulette_share(np.array([0.2, t, 0.5]), k, bounce) \
                == pytest.approx(_cycles_roulette(t, k, first_bounce=bounce + 1),
                                 rel=1e-12)
    assert photonclamp.roulette_share(np.full(3, t), 4) == pytest.approx(t ** (7 / 8),
                                                                         rel=1e-12)
    assert photonclamp.roulette_share(np.full(3, 0.5), 1) == 1.0
    assert np.array_equal(photonclamp.roulette_share(
        np.array([[1.5, 0.1, 0.1], [t, 0.0, 0.0], [0.0, 0.0, 0.0], [t, t, t]]),
        np.array([3, 0, 5, 1])), [1.0, 1.0, 1.0, 1.0])
    power = np.array([[1.0, 1.0, 1.0]])
    # |C|_1 = 0.8 x 60 = 48 over 30 x Q(0.8, 3 hits, the first free) = 30 x 0.8^0.75
    w = photonclamp.photon_weights(np.array([60.0]), power, np.full(3, t), 30.0,
                                   np.array([3]))
    assert w[0] == pytest.approx(30.0 * t ** 0.75 / 48.0, rel=1e-12)
    assert photonclamp.photon_weights(np.array([60.0]), power, np.full(3, t), 30.0)[0] \
        == pytest.approx(30.0 / 48.0, rel=1e-12)

def _flat_map(rad, n=400, seed=1):
    """A map of n photons on the unit square at z = 0 (arriving straight down), each of
    power (0.01, 0.02, 0.01) W and |L_p|_1 rad (None: not kept)."""
    rng = np.random.default_rng(seed)
    pos = np.c_[rng.random((n, 2)), np.zeros(n)].astype(np.float32)
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    ph = Photons(pos, np.tile(np.float32([0.01, 0.02, 0.01]), (n, 1)), -up, up.copy(),
                 np.full(n, CAUSTIC, np.uint8),
                 radiance=None if rad is None else np.full(n, rad, np.float32))
    return PhotonMap(ph)


def _estimate(pmap, clamp):
    p = np.array([[0.5, 0.5, 0.0], [0.3, 0.6, 0.0], [0.7, 0.4, 0.0]])
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    return photonvisibility.visible_irradiance(pmap, None, p, n, None, 0.2, 50, 8,
                                               "knn_simpson", clamp=clamp)


def test_estimate_weighs_each_photon_and_keeps_bits_below_the_limit():
    plain = _estimate(_flat_map(None), None)
    assert (plain > 0).all()
    scale = np.tile([0.5, 0.5, 0.5], (3, 1))  # clamp throughput x albedo
    # |scale x L_p|_1 = 0.5 x 120 = 60 = 2 x the limit 30: every photon counts half.
    half = _estimate(_flat_map(120.0), (scale, 30.0))
    assert np.allclose(half, 0.5 * plain, rtol=1e-12, atol=0)
    # At or below the limit (and without a clamp): the estimate's very bits.
    assert np.array_equal(_estimate(_flat_map(60.0), (scale, 30.0)), plain)
    assert np.array_equal(_estimate(_flat_map(120.0), None), plain)
    # A row whose throughput is 0 reads nothing over any limit.
    assert np.array_equal(_estimate(_flat_map(120.0), (0 * scale, 30.0)), plain)


def _slab_scene():
    """A sun of angle ANGLE straight down onto an 8 x 8 m floor (albedo 0.5) under a
    4 x 4 m, 5 cm slab of clear glass (IOR 1.5) raised 0.5 m."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_material(Material("glass", (1, 1, 1), transmission=1.0, ior=1.5))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_box((0, 0, 0.525), (4.0, 4.0, 0.05), "glass", name="slab")
    s.add_sun((0, 0, -1), strength=SUN_E, angle_degrees=ANGLE)
    s.set_camera((0, -5, 3), (0, 0, 0))
    return s


def _shot(settings, photons=60_000):
    scene = _slab_scene()
    geo, table = prepare(scene)
    ctx = Context(scene, settings, geo, table, Accel(geo.vertices32, geo.faces32, 1),
                  prepare_lights(scene, geo, table))
    return trace_photons(ctx, ctx.lights, allocate_photons(ctx.lights, photons), False, 1)


def test_photon_pass_carries_the_radiance_of_the_reversed_path():
    # No clamp: nothing kept.
    assert _shot(RenderSettings(photons=20_000, seed=3), 20_000).radiance is None
    ph = _shot(RenderSettings(photons=60_000, seed=3, clamp_indirect=10))
    # The sun's disc radiance E / (pi sin^2(angle / 2)), x 3 channels.
    Le = 3 * SUN_E / (math.pi * math.sin(math.radians(ANGLE) / 2) ** 2)
    # Every photon lies on the floor (the slab is clear glass): its centre's photons came
    # through the slab, the rim's straight from the sun.
    xy = ph.position[:, :2].astype(np.float64)
    r = np.abs(xy - (xy.max(axis=0) + xy.min(axis=0)) / 2).max(axis=1)
    ratio = ph.radiance / Le
    first = ph.kind != INDIRECT
    out = first & (r > 2.2)
    assert out.sum() > 10_000
    assert np.allclose(ratio[out], 1.0, rtol=1e-6)
    # Through the slab: Cycles' path refracts twice, each side picked by its Fresnel
    # share (throughput 1, eta^2 left to the photon's flux), as the photon's own
    # pick: Le again; the roulette's probabilities and the refractions' eta^2 divide
    # the flux alone. (Some reflect inside the slab: those too.)
    under = first & (r < 1.8)
    assert under.sum() > 5_000
    assert np.allclose(ratio[under], 1.0, rtol=1e-5)
    # Past a diffuse bounce (the floor, albedo 0.5, to the slab's underside and back,
    # or further): Le x 0.5^k, the roulette's pick of the diffuse lobe the flux's alone,
    # where the first scatter was the glass (delta: Cycles' BSDF sample alone); where it
    # was the floor, x nee_share(1 / Omega, cos / pi) (Cycles' light sample beside it;
    # the sun straight down: cos within 1e-4 of 1).
    nee = photonclamp.nee_share(1.0 / _solid_angle(), 1.0 / math.pi)
    k = np.log2(ratio[~first])
    k_nee = np.log2(ratio[~first] / nee)
    glass_first = np.abs(k - np.round(k)) < 1e-5
    floor_first = np.abs(k_nee - np.round(k_nee)) < 2e-4
    assert (~first).sum() > 100 and (glass_first | floor_first).all()
    assert glass_first.sum() > 100 and floor_first.sum() > 10
    assert (np.round(k[glass_first]) <= -1).all()
    assert (np.round(k_nee[floor_first]) <= -1).all()
    # The switch off: the floor's first scatter as its BSDF sample alone (Le x 0.5^k).
    was = photonclamp.NEE_FIRST_SCATTER
    photonclamp.NEE_FIRST_SCATTER = False
    try:
        off = _shot(RenderSettings(photons=60_000, seed=3, clamp_indirect=10))
    finally:
        photonclamp.NEE_FIRST_SCATTER = was
    k = np.log2(off.radiance[off.kind == INDIRECT] / Le)
    assert np.allclose(k, np.round(k), atol=1e-5)


def _solid_angle():
    """The sun's solid angle (sr): 2 pi (1 - cos(angle / 2))."""
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(ANGLE) / 2))


def test_mis_clamped_share_is_cycles_clamped_pair_at_one_vertex():
    """One vertex of a Lambertian surface (albedo 0.7, tp 1) under a sun of half-angle
    10 degrees, 40 degrees off the normal (|Le|_1 constant): Cycles' two strategies
    simulated as it runs them (a light sample uniform in the sun's cone, pdf p_l =
    1 / Omega, power-heuristic weight, and a cosine-sampled BSDF ray, pdf p_b = cos /
    pi, that lands in the cone, weight 1 - w_l; each value clamped on its own) average to
    the integral of g x mis_clamped_share over the cone, g = f cos Le; the pair is over
    the limit in part (W < 1). nee_share's single weight min(1, x / k) is W where both
    samples are clamped and where neither is, above it in between."""
    rng = np.random.default_rng(7)
    n = 400_000
    half, tilt, rho, Le = math.radians(10.0), math.radians(40.0), 0.7, 3.0
    omega = 2.0 * math.pi * (1.0 - math.cos(half))
    axis = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    t = np.cross(axis, [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(axis, t)

    def cone(u1, u2):
        c = 1.0 - u1 * (1.0 - math.cos(half))
        s = np.sqrt(1.0 - c * c)
        return (c[:, None] * axis + (s * np.cos(2 * math.pi * u2))[:, None] * t
                + (s * np.sin(2 * math.pi * u2))[:, None] * b)

    p_l = 1.0 / omega

    def g(w):
        return rho / math.pi * np.maximum(w[:, 2], 0.0) * Le

    limit = 0.6 * rho / math.pi * math.cos(tilt) * Le * omega  # (the light sample's scale)
    wl = cone(rng.random(n), rng.random(n))
    pb_l = np.maximum(wl[:, 2], 0.0) / math.pi
    v_light = np.minimum(g(wl) / p_l * p_l ** 2 / (p_l ** 2 + pb_l ** 2), limit)
    u1, u2 = rng.random(n), rng.random(n)
    r = np.sqrt(u1)
    wb = np.c_[r * np.cos(2 * math.pi * u2), r * np.sin(2 * math.pi * u2), np.sqrt(1 - u1)]
    inside = wb @ axis >= math.cos(half)
    pb = wb[:, 2] / math.pi
    v_bsdf = np.where(inside, np.minimum(g(wb) / pb * pb ** 2 / (p_l ** 2 + pb ** 2),
                                         limit), 0.0)
    cycles = v_light.mean() + v_bsdf.mean()
    # The integral over the cone by the same light samples: g W / p_l.
    x = limit * pb_l / g(wl)
    share = photonclamp.mis_clamped_share(x, p_l, pb_l)
    formula = (g(wl) * share / p_l).mean()
    assert 0.3 < share.mean() < 0.9
    assert formula == pytest.approx(cycles, rel=0.01)
    # Unclamped the pair sums to the integral of g (MIS weights summing to 1).
    assert (g(wl) / p_l).mean() > 1.2 * cycles
    # The single weight: equal at both ends, not below between.
    pl, pb1 = 3.0, 1.0
    a = pl * pl / (pl * pl + pb1 * pb1)
    k = photonclamp.nee_share(pl, pb1)
    assert k == pytest.approx(0.25, rel=1e-12)
    xs = np.array([0.01, 1 - a, 0.2, a / 3.0, 0.5, 2.0])
    W = photonclamp.mis_clamped_share(xs, pl, pb1)
    one = np.minimum(1.0, xs / k)
    assert np.allclose(one[[0, 1, 3, 4, 5]], W[[0, 1, 3, 4, 5]], rtol=1e-12)
    assert one[2] == pytest.approx(0.8) and W[2] == pytest.approx(0.7)
    # No light sample: 1 (c kept).
    assert photonclamp.nee_share(0.0, 0.4) == 1.0


def test_light_pdfs_are_the_camera_sides_light_pdfs():
    """photonclamp.light_pdfs: a sun's 1 / Omega (its pick 1: one light), a sphere lamp's
    cone 1 / (2 pi (1 - cos a)), an area light's t^2 / (A cos) (a disk, t the distance
    along wi to its plane); 0 for a sun without angle. Two lights: each times the
    probability that a light tree over both picks it (Cycles' light tree; our camera
    side gives each its own shadow rays), the two picks summing to 1."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_sun((0, 0, -1), strength=SUN_E, angle_degrees=ANGLE)
    s.set_camera((0, -5, 3), (0, 0, 0))
    ctx = prepare_context(s, RenderSettings(workers=1))
    sun = ctx.lights[0]
    x = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.0]])
    up = np.tile([0.0, 0.0, 1.0], (2, 1))
    assert np.allclose(photonclamp.light_pdfs(ctx, sun, x, up, up), 1.0 / _solid_angle(),
                       rtol=1e-9)
    sun.cos_half_angle = 1.0
    assert not photonclamp.light_pdfs(ctx, sun, x, up, up).any()
    s2 = PaperScene(width=8, height=8)
    s2.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s2.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s2.add_point_light((0, 0, 2), power=100.0, radius=0.5, soft_falloff=False)
    s2.add_rect_area_light((0, 0, 3), size=1.0, power=100.0, disk=True)
    s2.set_camera((0, -5, 3), (0, 0, 0))
    ctx = prepare_context(s2, RenderSettings(workers=1))
    lamp = next(li for li in ctx.lights if li.kind != AREA)
    area = next(li for li in ctx.lights if li.kind == AREA)
    off = ctx.geo.offset
    pick = photonclamp.cycles_light_pick(ctx)
    il, ia = ctx.lights.index(lamp), ctx.lights.index(area)
    got = photonclamp.light_pdfs(ctx, lamp, x - off, up, up)
    d2 = np.array([4.0, 9.0])  # (squared distances to the lamp's centre)
    cone = 1.0 / (2.0 * math.pi * (1.0 - np.sqrt(1.0 - 0.25 / d2)))
    p_lamp = pick.pmf(x - off, up, il)
    assert np.all((p_lamp > 0.0) & (p_lamp < 1.0))
    assert np.allclose(p_lamp + pick.pmf(x - off, up, ia), 1.0, rtol=1e-9)
    assert np.allclose(got, cone * p_lamp, rtol=1e-9)
    wi = np.array([[0.0, 0.0, 1.0], [-0.1, -0.2, 1.0]])
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    x2 = np.array([[0.0, 0.0, 0.0], [0.3, 0.6, 0.0]])
    got = photonclamp.light_pdfs(ctx, area, x2 - off, wi, up)
    t = 3.0 / wi[:, 2]
    assert np.allclose(got, t * t / (math.pi * 0.25 * wi[:, 2]) * pick.pmf(x2 - off, up, ia),
                       rtol=1e-9)


def test_a_constant_world_takes_no_light_sample_in_cycles():
    """Cycles switches a constant world's light samples off (no environment map, no
    portals: "Background MIS has been disabled"): p_l 0, so a world-lit photon's first
    scatter keeps its clamp ratio, and the world joins no light pick."""
    s = PaperScene(width=8, height=8, background=(0.4, 0.5, 0.6))
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_rect_area_light((0, 0, 3), size=1.0, power=100.0)
    s.set_camera((0, -5, 3), (0, 0, 0))
    ctx = prepare_context(s, RenderSettings(workers=1, clamp_indirect=1.0))
    world = next(li for li in ctx.lights if li.kind == WORLD)
    assert not photonclamp.cycles_samples_world(world)
    x = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.0]])
    up = np.tile([0.0, 0.0, 1.0], (2, 1))
    assert not photonclamp.light_pdfs(ctx, world, x, up, up).any()
    # (the area light alone is sampled: its pick 1, no selector)
    assert photonclamp.cycles_light_pick(ctx) is None


def test_emitted_radiance_is_each_light_kinds_own():
    """|Le|_1 along emitted photons: an area light's flux / (pi A), a point / spot light
    of radius r its intensity / (pi r^2) (x the spot's mask), a constant world's colour;
    0 for a delta light (a point of radius 0: Cycles cannot meet it)."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_rect_area_light((0, 0, 2), (0.5, 0.2), power=40.0, color=(1.0, 0.5, 0.25))
    s.add_point_light((1, 0, 2), power=30.0, radius=0.1)
    s.add_point_light((-1, 0, 2), power=30.0, radius=0.1, soft_falloff=False)
    s.add_spot_light((0, 1, 2), (0, 1, 0), power=30.0, radius=0.05, blend=0.0)
    s.add_point_light((0, -1, 2), power=30.0)
    s.set_camera((0, -5, 3), (0, 0, 0))
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    rng = np.random.default_rng(2)
    got = {}
    for li in lights:
        o, d, power = li.emit(2000, rng)
        got[li.name] = photonclamp.emitted_radiance(li, o, d)
    area, sphere, ball, spot, delta = got.values()
    assert np.allclose(area, 1.75 * 40.0 / (math.pi * 0.1), rtol=1e-9)
    for le, r in ((sphere, 0.1), (ball, 0.1)):
        assert np.allclose(le, 3 * 30.0 / (4 * math.pi) / (math.pi * r * r), rtol=1e-9)
    inside = spot > 0
    assert inside.mean() > 0.9
    assert np.allclose(spot[inside], 3 * 30.0 / (4 * math.pi) / (math.pi * 0.05 ** 2),
                       rtol=1e-9)
    assert not delta.any()


def test_emitted_radiance_of_a_narrow_area_light_and_a_constant_world():
    """An area light of spread 60 degrees: |Le|_1 along each photon is what a ray meeting
    the light against it reads (the light's own intersect, Cycles' spread attenuation),
    wherever the light stands (no short ray from the float32 origin: a light 1 km out);
    a constant world: its colour x strength along every direction."""
    s = PaperScene(width=8, height=8, background=(0.2, 0.3, 0.5))
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    near = s.add_rect_area_light((0, 0, 2), (0.5, 0.2), power=40.0, name="near")
    near.spread = math.radians(60.0)
    far = s.add_rect_area_light((1000.0, 0, 2), (0.1, 0.1), power=40.0, name="far")
    far.spread = math.radians(60.0)
    s.set_camera((0, -5, 3), (0, 0, 0))
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    rng = np.random.default_rng(3)
    seen = 0
    for li in lights:
        o, d, _ = li.emit(2000, rng)
        le = photonclamp.emitted_radiance(li, o, d)
        if li.kind == AREA:
            seen += 1
            start = np.asarray(o, np.float64) + 0.5 * d
            mask, _, L = li.intersect(start, -d, np.full(len(d), 1.0))
            hit = np.flatnonzero(mask)
            assert len(hit) > 0.9 * len(d)
            assert np.allclose(le[hit], np.abs(np.asarray(L)[hit]).sum(axis=1), rtol=1e-9)
            assert le.min() > 0.0
        elif li.kind == WORLD:
            seen += 1
            assert np.allclose(le, 1.0, rtol=1e-9)
    assert seen == 3


# --- clampleft55: the ratio c = |L|_1 / |flux|_1 per ray, the mesh light's per triangle,
# the weights folded into the visible sums ---

def _sun_le():
    """The sun's disc radiance |Le|_1 = 3 E / (pi sin^2(angle / 2))."""
    return 3 * SUN_E / (math.pi * math.sin(math.radians(ANGLE) / 2) ** 2)


def _traced(scene, settings, photons):
    ctx = prepare_context(scene, settings)
    ph = trace_photons(ctx, ctx.lights, allocate_photons(ctx.lights, photons), False, 1)
    return ph, ph.position.astype(np.float64) + ctx.geo.offset


def test_a_copy_passing_behind_a_surface_keeps_its_own_radiance():
    """A sun straight down onto a 0.5 floor under a 0.5 card (4 x 4 m at 1 m) that shadow
    rays do not see: the photons' shadow kind passes on behind the card in a copy (its
    slot the photon's, whose diffuse continuation off the card takes c / 2). The copy's
    path has not scattered: on the floor under the card it carries the sun's Le, as the
    photons beside the card (it read Le / 2 where it shared the continuation's slot)."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    card = s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, "floor", name="card")
    card.visible_shadow = False
    s.add_sun((0, 0, -1), strength=SUN_E, angle_degrees=ANGLE)
    s.set_camera((0, -5, 3), (0, 0, 0))
    ph, pos = _traced(s, RenderSettings(photons=30_000, seed=4, clamp_indirect=10,
                                        workers=1), 30_000)
    on_floor = np.abs(pos[:, 2]) < 1e-3
    under = on_floor & (np.abs(pos[:, :2]).max(axis=1) < 1.8) & (ph.kind == DIRECT)
    beside = on_floor & (np.abs(pos[:, :2]).max(axis=1) > 2.2) & (ph.kind == DIRECT)
    assert under.sum() > 3_000 and beside.sum() > 3_000
    assert np.allclose(ph.radiance[beside] / _sun_le(), 1.0, rtol=1e-5)
    assert np.allclose(ph.radiance[under] / _sun_le(), 1.0, rtol=1e-5)


def test_a_volume_scatter_takes_the_medium_albedo_into_the_radiance():
    """A sun through a grey fog slab (albedo 0.8, Volume bounces 64) onto a near-black
    floor: a photon scattered k times in the fog carries L = Le x 0.8^k (Cycles' path
    reversed takes sigma_s Tr / pdf = the albedo at each scatter; the photon's power,
    0.8 / p_keep with p_keep = 0.8, stays). It read Le: the fog's light over-clamped by
    1 / 0.8^k."""
    s = PaperScene(8, 8)
    s.add_material(Material("fog", volume_only=True, absorption=(0.1, 0.1, 0.1),
                            scattering=(0.4, 0.4, 0.4)))
    s.add_material(Material("soot", (0.001, 0.001, 0.001)))
    s.add_box((0, 0, 0.6), (40.0, 40.0, 1.0), "fog", name="slab")
    s.add_plane((0, 0, 0), (0, 0, 1), 60.0, "soot", name="floor")
    s.add_sun((0, 0, -1), strength=SUN_E, angle_degrees=ANGLE)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    ph, pos = _traced(s, RenderSettings(photons=20_000, seed=5, clamp_indirect=10,
                                        workers=1, volume_bounces=64, max_bounces=256,
                                        max_photon_depth=256), 20_000)
    k = ph.bounces[:, 0].astype(np.int64)
    ratio = ph.radiance / _sun_le()
    # (a photon the floor sent on, one in a thousand, carries its 0.001: left out, as
    # the fog's scatters alone are counted in k up to 15, 0.8^15 = 0.035)
    fog = (np.abs(pos[:, 2]) < 1e-3) & (k <= 15) & (ratio > 0.01)
    assert (k[fog] >= 1).sum() > 500 and (k[fog] >= 3).sum() > 50
    assert np.allclose(ratio[fog], 0.8 ** k[fog], rtol=1e-4)


def _two_lamps():
    """Two emissive cards facing down 2 m over a floor, |L|_1 30 (x < 0) and 12 (x > 0)."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_material(Material("white", (0.0, 0.0, 0.0), emission=(10.0, 10.0, 10.0)))
    s.add_material(Material("blue", (0.0, 0.0, 0.0), emission=(2.0, 4.0, 6.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_plane((-1.0, 0, 2.0), (0, 0, -1), 0.5, "white", name="white")
    s.add_plane((1.0, 0, 2.0), (0, 0, -1), 0.5, "blue", name="blue")
    s.set_camera((0, -5, 3), (0, 0, 0))
    return s


def test_mesh_light_of_several_radiances_gives_each_photon_its_triangle():
    """A mesh light of two radiances: each emitted photon's c x |power|_1 is the
    radiance of the card it left (emitted_triangles: emit_mesh's own choice); stored
    photons straight from a card carry it (before: 0, no clamp, for the whole light)."""
    from engine.lights.emission import EmissionBuffers
    s = _two_lamps()
    ctx = prepare_context(s, RenderSettings(workers=1))
    mesh = [li for li in ctx.lights if getattr(li, "kind", None) == MESH][0]
    out = EmissionBuffers(4000)
    m = mesh.emit_into(np.uint64(21), 100, 4000, 4000, out, 0)
    o32, _, d, power, slot = out.head(m)
    c = photonclamp.emission_ratios(mesh, o32, d, power, slot, np.uint64(21))
    le = c * np.abs(power).sum(axis=1)
    x = o32[:, 0].astype(np.float64) + ctx.geo.offset[0]
    assert (x < 0).sum() > 1000 and (x > 0).sum() > 1000
    assert np.allclose(le[x < 0], 30.0, rtol=1e-9)
    assert np.allclose(le[x > 0], 12.0, rtol=1e-9)
    ph, pos = _traced(s, RenderSettings(photons=20_000, seed=2, clamp_indirect=10,
                                        workers=1), 20_000)
    direct = ph.radiance[(ph.kind == DIRECT) & (np.abs(pos[:, 2]) < 1e-3)]
    assert np.isclose(direct, 30.0, rtol=1e-5).sum() > 1000
    assert np.isclose(direct, 12.0, rtol=1e-5).sum() > 1000
    assert (np.isclose(direct, 30.0, rtol=1e-5) | np.isclose(direct, 12.0, rtol=1e-5)).all()


@pytest.mark.parametrize("focus", [False, True])
def test_clamp_weights_in_the_visible_sums_are_the_numpy_sums(focus):
    """Clamp Indirect folded into photonvisibility._visible_rows: each row whose read
    list holds a photon over the limit is factor x sum(weight x w_p x power) over its
    photons not left out (here by a reject callable, as hidden ones are), the numpy
    sum photonclamp.clamp_rows took before, within float64 reordering; every other row
    keeps the plain estimate's bits. focus: 300 more photons in a spot 1e-4 wide with
    rows on it, estimated by the radius estimator, so they read more than READ_WIDTH x
    k photons and are read again whole (_estimate_read's wide rows, summed by their own
    pass). Each row at a camera path bounce of 0-2 (roulette_share's: the clamp tuple's
    third element)."""
    rng = np.random.default_rng(7)
    n = 600
    pos = np.c_[rng.random((n, 2)), np.zeros(n)]
    if focus:
        spot = 300
        pos = np.r_[pos, np.c_[0.7 + 1e-4 * rng.random((spot, 2)), np.zeros(spot)]]
        n += spot
    pos = pos.astype(np.float32)
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    power = (0.005 + 0.02 * rng.random((n, 3))).astype(np.float32)
    # (|L_p|_1 20 is under the limit 30 x Q at any scale <= 1: the rows left of x 0.35
    # read no photon over it)
    rad = np.where((pos[:, 0] > 0.5) & (rng.random(n) < 0.3), 200.0, 20.0).astype(np.float32)
    bounces = np.zeros((n, 4), np.uint8)
    bounces[:, 0] = rng.integers(1, 5, n)
    ph = Photons(pos, power, -up, up.copy(), np.full(n, CAUSTIC, np.uint8), bounces=bounces,
                 radiance=rad)
    pmap = PhotonMap(ph)
    m = 40
    p = np.c_[0.1 + 0.8 * rng.random((m, 2)), np.zeros(m)]
    if focus:
        p[-8:, :2] = 0.70005 + 2e-5 * rng.random((8, 2))
    # (the radius estimator reads every photon within the radius: the rows on the spot
    # read ~340, more than READ_WIDTH x k)
    estimator = "radius" if focus else "knn_simpson"
    nrm = np.tile([0.0, 0.0, 1.0], (m, 1))
    scale = 0.3 + 0.7 * rng.random((m, 3))
    scale[:5] = 0.0  # (rows over no limit: their bits kept)

    def reject(rows, photons):
        return (np.asarray(rows) + np.asarray(photons)) % 5 == 0

    args = (pmap, None, p, nrm, None, 0.15, 40, 8, estimator)
    plain = photonvisibility.visible_irradiance(*args, reject=reject)
    # (each row's camera path bounce: 0 spares the chains' first hits the roulette)
    bounce = rng.integers(0, 3, m)
    got = photonvisibility.visible_irradiance(*args, reject=reject,
                                              clamp=(scale, 30.0, bounce))
    _, count, lists, weight, factor, wide = photonvisibility._estimate_read(
        pmap, None, None, p, nrm, 0.15, 40, 8, estimator, None)
    count, lists, weight, factor = count.copy(), lists.copy(), weight.copy(), factor.copy()
    if focus:
        assert set(range(m - 8, m)) <= set(wide[0]), wide[0]  # (and rows near the spot)
        wide_lists = {int(r): (wide[2][j, :wide[1][j]], wide[3][j, :wide[1][j]], wide[4][j])
                      for j, r in enumerate(wide[0])}
    else:
        assert not len(wide[0]) and (count > 0).all()
        wide_lists = {}
    want = np.empty((m, 3))
    over = np.zeros(m, bool)
    mp = pmap.photons  # (the map's own order)
    for i in range(m):
        js, wt, fac = wide_lists.get(i, (lists[i, :count[i]], weight[i, :count[i]], factor[i]))
        keep = ~reject(np.full(len(js), i), js)
        pw = (decode_power(mp.power[js]) if mp.power.dtype == np.uint8
              else mp.power[js].astype(np.float64))  # (a compact map's RGBE)
        w = photonclamp.photon_weights(mp.radiance[js].astype(np.float64), pw,
                                       scale[i], 30.0,
                                       None if mp.bounces is None else mp.bounces[js, 0],
                                       bounce[i])
        over[i] = (w < 1).any()
        want[i] = (np.where(keep, wt * w, 0.0)[:, None] * pw).sum(axis=0) * fac
    assert 10 < over.sum() <= m - 10
    if focus:
        assert over[m - 8:].sum() >= 4  # (wide rows the clamp sums again)
    assert np.allclose(got[over], want[over], rtol=1e-12, atol=0.0)
    assert np.array_equal(got[~over], plain[~over])
    assert np.allclose(plain[~over], want[~over], rtol=1e-12, atol=0.0)  # (the reference)


def test_a_region_emitters_photons_take_its_lights_radiance():
    """Visual importance's RegionEmitter (aimed and natural photons of one light): each
    photon's c x |flux|_1 is its light's radiance, as the light's own photons' (it read
    0: the emitter has no light kind of its own; clampleft55's switch that kept it so is
    gone with clampnee56's first-scatter pair)."""
    from engine.lights.emission import EmissionBuffers
    from engine.visualimportance import Region, RegionEmitter
    s = _two_lamps()
    ctx = prepare_context(s, RenderSettings(workers=1))
    mesh = [li for li in ctx.lights if getattr(li, "kind", None) == MESH][0]
    region = Region(np.array([[0.0, 0.0, 0.0]]) - ctx.geo.offset, np.array([0.5]), 1.0, 1)
    emitter = RegionEmitter(mesh, region, 0.5)
    out = EmissionBuffers(4000)
    m = emitter.emit_into(np.uint64(5), 0, 4000, 4000, out, 0)
    o32, _, d, power, slot = out.head(m)
    le = photonclamp.emission_ratios(emitter, o32, d, power, slot, np.uint64(5)) \
        * np.abs(power).sum(axis=1)
    x = o32[:, 0].astype(np.float64) + ctx.geo.offset[0]
    assert m > 2000 and (x < 0).sum() > 500 and (x > 0).sum() > 500
    assert np.allclose(le, np.where(x < 0, 30.0, 12.0), rtol=1e-9)
