"""Photons that scatter in homogeneous media (engine/photonmedium.py, volphotons38):
energy kept by an albedo-1 fog, the light a chromatic, anisotropic fog slab sends onto
the floor under a lamp against an independent brute-force photon tracer in numpy, the
Volume bounces limit, the same photons for any worker count, and the camera walk's
surface term (engine/volumewalk.py)."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.photonmedium import max_scatters, uniforms
from engine.photons import DIRECT, INDIRECT, trace_photons
from engine.render import prepare_context
from engine.scene import Material

SLAB = (0.1, 1.1)  # z range of the fog slab over the floor at z 0
LIGHT_Z = 1.6
R = 1.0  # the floor disc tallied, about the lamp's foot


def _settings(**kw):
    base = dict(workers=1, volume_bounces=64, max_bounces=256, max_photon_depth=256)
    base.update(kw)
    return RenderSettings(**base)


def _slab_scene(sigma_a, sigma_s, g):
    """A 40 x 40 m fog slab (volume-only) z 0.1..1.1 over a near-black floor (base 0.001:
    photons are stored at their first floor hit and almost never go on), a point light
    above it."""
    s = PaperScene(8, 8)
    s.add_material(Material("fog", volume_only=True, absorption=sigma_a, scattering=sigma_s,
                            anisotropy=g))
    s.add_material(Material("soot", (0.001, 0.001, 0.001)))
    s.add_box((0, 0, 0.5 * (SLAB[0] + SLAB[1])), (40.0, 40.0, SLAB[1] - SLAB[0]), "fog",
              name="slab")
    s.add_plane((0, 0, 0), (0, 0, 1), 60.0, "soot", name="floor")
    s.add_point_light((0.0, 0.0, LIGHT_Z), power=100.0)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    return s


def _floor_tally(scene, settings, n, stream=3):
    """(power (3,) of the photons stored on the floor within R of the lamp's foot, the
    photons) for n photons."""
    ctx = prepare_context(scene, settings)
    ph = trace_photons(ctx, ctx.lights, [n], caustic_only=False, stream=stream)
    pos = ph.position.astype(np.float64) + ctx.geo.offset
    on = (np.abs(pos[:, 2]) < 1e-3) & (np.hypot(pos[:, 0], pos[:, 1]) < R)
    return ph.power[on].astype(np.float64).sum(axis=0), ph


def _hg_numpy(d, g, rng):
    """Henyey-Greenstein directions about d (n,3), written afresh (pbrt-v4's formula and
    a Frisvad frame), for the brute-force tracer."""
    n = len(d)
    u1, u2 = rng.random(n), rng.random(n)
    if abs(g) < 1e-3:
        c = 1.0 - 2.0 * u1
    else:
        sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1)
        c = (1.0 + g * g - sq * sq) / (2.0 * g)
    c = np.clip(c, -1.0, 1.0)
    sn = np.sqrt(1.0 - c * c)
    phi = 2.0 * math.pi * u2
    a = np.where((np.abs(d[:, 0]) > 0.9)[:, None], np.array([[0.0, 1.0, 0.0]]),
                 np.array([[1.0, 0.0, 0.0]]))
    t1 = np.cross(d, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(d, t1)
    return (sn * np.cos(phi))[:, None] * t1 + (sn * np.sin(phi))[:, None] * t2 + c[:, None] * d


def brute_force_fraction(sig_t, sig_s, g, n, scatters, seed):
    """The fraction of an isotropic point source's power at z = LIGHT_Z that reaches the
    floor z = 0 within R after crossing an infinite grey slab SLAB (extinction sig_t,
    scattering sig_s, HG g), an analog random walk in numpy: exponential free flights,
    weight x albedo per scatter, at most `scatters` scatters (a flight that would scatter
    once more is lost, as Cycles' Volume bounces cut), the light leaving the slab's top
    lost (nothing above reflects)."""
    rng = np.random.default_rng(seed)
    z0, z1 = SLAB
    mu = 1.0 - 2.0 * rng.random(n)
    phi = 2.0 * math.pi * rng.random(n)
    s = np.sqrt(1.0 - mu * mu)
    d = np.stack([s * np.cos(phi), s * np.sin(phi), mu], axis=1)
    keep = d[:, 2] < 0.0  # the photons going up are lost
    d = d[keep]
    t = (LIGHT_Z - z1) / -d[:, 2]
    p = np.array([0.0, 0.0, LIGHT_Z]) + t[:, None] * d  # on the slab's top
    w = np.ones(len(d))
    tally = 0.0
    for k in range(scatters + 1):
        if len(d) == 0:
            break
        flight = -np.log1p(-rng.random(len(d))) / sig_t
        exit_t = np.where(d[:, 2] < 0.0, (p[:, 2] - z0) / np.maximum(-d[:, 2], 1e-300),
                          (z1 - p[:, 2]) / np.maximum(d[:, 2], 1e-300))
        leaves = flight >= exit_t
        down = leaves & (d[:, 2] < 0.0)
        # out through the bottom: on to the floor through clear air
        pf = p[down] + (p[down, 2] / -d[down, 2])[:, None] * d[down]
        tally += np.sum(w[down][np.hypot(pf[:, 0], pf[:, 1]) < R])
        if k == scatters:
            break
        sc = ~leaves
        p = p[sc] + flight[sc][:, None] * d[sc]
        w = w[sc] * (sig_s / sig_t)
        d = _hg_numpy(d[sc], g, rng)
    return tally / n


def _clear_fraction():
    """The share of an isotropic source's power falling on the floor disc R from LIGHT_Z."""
    return 0.5 * (1.0 - LIGHT_Z / math.hypot(LIGHT_Z, R))


def test_uniforms_are_uniform_and_keyed():
    a = uniforms(np.uint64(7), np.arange(200_000), 3, 1)
    assert a.min() >= 0.0 and a.max() < 1.0
    assert a.mean() == pytest.approx(0.5, abs=3e-3)
    assert np.histogram(a, 10, (0, 1))[0].min() > 19_000
    b = uniforms(np.uint64(7), np.arange(200_000), 3, 2)
    c = uniforms(np.uint64(8), np.arange(200_000), 3, 1)
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.01 and abs(np.corrcoef(a, c)[0, 1]) < 0.01
    np.testing.assert_array_equal(a, uniforms(np.uint64(7), np.arange(200_000), 3, 1))


def test_max_scatters_follows_cycles_volume_bounces():
    assert max_scatters(0) == 0  # default: photons as before (single scattering)
    assert max_scatters(1) == 2 and max_scatters(32) == 33


def test_albedo_one_fog_keeps_the_photons_energy():
    """A lamp at the centre of an albedo-1 fog box (2 m, sigma_s 1 / 1.5 / 0.7 per
    channel, g 0.4) inside a closed near-black room: every photon leaves the fog and is
    stored at its first wall hit, so the walls' stored power equals the clear box's (the
    same lamp, the same count) within the noise of the scattered paths (0.5 %)."""
    sig_s = np.array([1.0, 1.5, 0.7])

    def room(sigma_s):
        s = PaperScene(8, 8)
        s.add_material(Material("fog", volume_only=True, absorption=(0.0, 0.0, 0.0),
                                scattering=sigma_s, anisotropy=0.4))
        s.add_material(Material("soot", (0.001, 0.001, 0.001)))
        s.add_box((0, 0, 0), (2.0, 2.0, 2.0), "fog", name="fog")
        for c, nrm in (((0, 0, -3), (0, 0, 1)), ((0, 0, 3), (0, 0, -1)),
                       ((-3, 0, 0), (1, 0, 0)), ((3, 0, 0), (-1, 0, 0)),
                       ((0, -3, 0), (0, 1, 0)), ((0, 3, 0), (0, -1, 0))):
            s.add_plane(c, nrm, 6.2, "soot")
        s.add_point_light((0.0, 0.0, 0.0), power=100.0)
        s.set_camera((0, 0, 2.5), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
        return s

    def stored(sigma_s):
        ctx = prepare_context(room(sigma_s), _settings())
        ph = trace_photons(ctx, ctx.lights, [60_000], caustic_only=False, stream=5)
        return ph
    fog, clear = stored(sig_s), stored(np.full(3, 1e-9))
    np.testing.assert_allclose(fog.power.astype(np.float64).sum(axis=0),
                               clear.power.astype(np.float64).sum(axis=0), rtol=5e-3)
    # the scattered ones are indirect light (the global map's), the others direct (the
    # clear box's indirect photons: the walls' 0.1 % second bounce)
    def indirect_share(ph):
        p = ph.power.astype(np.float64).sum(axis=1)
        return p[ph.kind == INDIRECT].sum() / p.sum()
    assert indirect_share(fog) > 0.5 and indirect_share(clear) < 0.01


@pytest.mark.parametrize("g", [0.0, 0.6])
def test_fog_slab_over_a_floor_matches_a_brute_force_tracer(g):
    """The floor disc under a lamp over a chromatic absorbing and scattering slab (sigma_s
    0.5 / 1 / 1.6, sigma_a 0.2 / 0.1 / 0.05; one free-flight channel per photon,
    spectral MIS): the stored power over the clear slab's (the lamp's power on the
    disc) against brute_force_fraction per channel over the clear share, within 3 %
    (150k photons here, 600k there: each side's noise ~0.6-1 %; measured at 300k / 1M,
    two streams: within 0.1-2 %). Without photon scattering the disc gets only the
    unscattered part (40-70 % of it)."""
    sig_a = np.array([0.2, 0.1, 0.05])
    sig_s = np.array([0.5, 1.0, 1.6])
    fog, _ = _floor_tally(_slab_scene(sig_a, sig_s, g), _settings(), 150_000)
    clear, _ = _floor_tally(_slab_scene(np.full(3, 1e-9), np.zeros(3), g), _settings(),
                            150_000)
    ours = fog / clear
    ref = np.array([brute_force_fraction(sig_a[c] + sig_s[c], sig_s[c], g, 600_000, 65,
                                         seed=c) for c in range(3)]) / _clear_fraction()
    np.testing.assert_allclose(ours, ref, rtol=0.03)
    single, _ = _floor_tally(_slab_scene(sig_a, sig_s, g), _settings(volume_bounces=0),
                             60_000)
    assert np.all(single / clear < 0.9 * ref)


def test_volume_bounces_zero_keeps_photons_unscattered():
    """At Volume bounces 0 no photon scatters (the gather rays carry the fog's single
    scattering): every floor photon is direct, dimmed by exp(-sigma_t l)."""
    _, ph = _floor_tally(_slab_scene(np.zeros(3), np.full(3, 1.0), 0.0),
                         _settings(volume_bounces=0), 20_000)
    assert len(ph.kind) and np.all(ph.kind == DIRECT)


def test_the_same_photons_for_any_worker_count():
    scene = _slab_scene(np.array([0.1, 0.1, 0.1]), np.array([0.8, 1.0, 1.2]), 0.3)

    def photons(workers):
        ctx = prepare_context(scene, _settings(workers=workers, chunk_size=4096))
        ph = trace_photons(ctx, ctx.lights, [30_000], caustic_only=False, stream=3)
        rows = np.lexsort(np.concatenate([ph.position, ph.power], axis=1).T)
        return ph.position[rows], ph.power[rows], ph.kind[rows]
    one, three = photons(1), photons(3)
    for a, b in zip(one, three):
        np.testing.assert_array_equal(a, b)
    again = photons(1)
    for a, b in zip(one, again):
        np.testing.assert_array_equal(a, b)


def _lit_floor_under_fog():
    """Looking down (orthographic) through a fog slab z 0.3..0.8 at a white floor lit by a
    lamp between them (z 0.15): the fog above is lit by the lamp and by the bright floor,
    whose light the camera walk takes at its segments' ends (engine/volumewalk.py)."""
    s = PaperScene(16, 16)
    s.add_material(Material("fog", volume_only=True, absorption=(0.05, 0.05, 0.05),
                            scattering=(0.8, 1.0, 1.2), anisotropy=0.2))
    s.add_box((0, 0, 0.55), (20.0, 20.0, 0.5), "fog", name="slab")
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "white_diffuse", name="floor")
    s.add_point_light((0.0, 0.0, 0.15), power=50.0)
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=2.0)
    return s


def test_walks_take_the_floor_light_and_the_image_is_the_same_for_any_worker_count():
    """At Volume bounces 4 the camera walk's segments that end on the floor add its
    light (the gather map's): the image is brighter than with that term switched off,
    and the same on 1 and 2 workers."""
    from engine import volumewalk
    from engine.render import render
    settings = dict(spp=4, seed=1, photons=20_000, volume_bounces=4)
    a, b = (render(_lit_floor_under_fog(), RenderSettings(workers=w, **settings))
            for w in (1, 2))
    np.testing.assert_array_equal(np.asarray(a.combined), np.asarray(b.combined))
    keep = volumewalk.WalkingScattering.surface_light
    volumewalk.WalkingScattering.surface_light = (
        lambda self, gmap, x, *rest: (np.zeros(0, np.int64), np.zeros((0, 3))))
    try:
        c = render(_lit_floor_under_fog(), RenderSettings(workers=1, **settings))
    finally:
        volumewalk.WalkingScattering.surface_light = keep
    with_floor = np.asarray(a.combined, np.float64)[..., :3].mean()
    without = np.asarray(c.combined, np.float64)[..., :3].mean()
    assert with_floor > 1.05 * without, (with_floor, without)
