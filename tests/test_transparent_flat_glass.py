"""Flat passages through thin glass (docs/design.md, Transparent shadows): shadow rays
cross a thin smooth glass slab with the transmittance of its two refractions,
TW^2 (1 - F)^2 (Glass BSDF: TW = its colour), and photons that pass straight through
it keep their path state (direct light, not caustic); a glass cube and a ball keep
blocking shadow rays and keep their caustics (single-plane glass under a sun is a
next-event pane: engine/panelight.py)."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.integrator import Counters, direct_irradiance
from engine.photonkernels import flat_glass_materials
from engine.photons import CAUSTIC, DIRECT, trace_photons
from engine.render import prepare_context
from engine.scene import Material

from test_transparent_shadows import _floor_hits

IOR = 1.5


def _fresnel(cos_i, eta):
    """Unpolarised dielectric Fresnel reflectance from outside (eta = n_t / n_i)."""
    s2 = (1.0 - cos_i * cos_i) / (eta * eta)
    ct = math.sqrt(1.0 - s2)
    rs = (cos_i - eta * ct) / (cos_i + eta * ct)
    rp = (eta * cos_i - ct) / (eta * cos_i + ct)
    return 0.5 * (rs * rs + rp * rp)


def _glass(color=(1.0, 1.0, 1.0), roughness=0.0):
    return Material("glass", color, transmission=1.0, roughness=roughness, ior=IOR,
                    node="glass", multiscatter=False)


def _sun_under(shape, sun_dir=(0.0, 0.0, -1.0), color=(1.0, 1.0, 1.0), **settings):
    """A white floor at z = 0 under a sun of 2 W/m^2 and one glass object centred over
    the origin: "slab" (2 x 2 m, 2 cm thick, at z = 1), "cube" (1 m, at z = 1),
    "plane" (a single 2 x 2 m plane at z = 1) or "ball" (radius 0.5 at z = 1)."""
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    glass = _glass(color)
    if shape == "slab":
        s.add_box((0, 0, 1.0), (2.0, 2.0, 0.02), glass, name="pane")
    elif shape == "cube":
        s.add_box((0, 0, 1.0), (1.0, 1.0, 1.0), glass, name="cube")
    elif shape == "plane":
        s.add_plane((0, 0, 1.0), (0, 0, 1), 2.0, glass, name="pane")
    elif shape == "ball":
        s.add_sphere((0, 0, 1.0), 0.5, glass, name="ball")
    s.add_sun(sun_dir, 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    return prepare_context(s, RenderSettings(workers=1, **settings))


def test_only_smooth_pure_glass_can_form_a_flat_passage():
    from engine.geometry import MaterialTable
    table = MaterialTable.build([_glass(), _glass(roughness=0.3),
                                 Material("white", (0.8, 0.8, 0.8)),
                                 Material("half", (1, 1, 1), transmission=0.5, roughness=0.0)])
    assert list(flat_glass_materials(table)) == [True, False, False, False]


def test_sun_through_thin_slab_reaches_floor_with_two_refractions():
    """Analytic: E = E_sun cos(theta) TW^2 (1 - F(theta))^2 on the floor under the slab
    (the exit's Fresnel at the refracted angle equals the entry's), per channel with a
    tinted Glass BSDF; beside the slab the open sun."""
    for theta_deg, color in ((0.0, (1.0, 1.0, 1.0)), (30.0, (0.9, 0.6, 0.3))):
        th = math.radians(theta_deg)
        ctx = _sun_under("slab", (math.sin(th), 0.0, -math.cos(th)), color)
        assert ctx.shadow is not None and ctx.shadow.flat_on
        hit = _floor_hits(ctx, 300, half=0.3)  # under the slab (its shadow is 0.58 m off)
        E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
        T = (1.0 - _fresnel(math.cos(th), IOR)) ** 2
        expect = 2.0 * math.cos(th) * T * np.square(color)
        np.testing.assert_allclose(E, np.broadcast_to(expect, E.shape), rtol=2e-3)
        # Exact and the same for every ray (no noise: the sun has angle 0).
        assert np.ptp(E, axis=0).max() < 1e-12


def test_photons_through_thin_slab_are_direct_with_the_same_transmittance():
    """The photon pass: photons that refract in and out of the slab keep their direct
    kind (only those reflected inside it are caustic: ~R^2 = 0.2 % of them); the flux
    reaching the floor under the slab, over the flux beside it on an equal area, is the
    shadow rays' T = (1 - F)^2 within the photons' noise (Russian roulette at each
    interface: unbiased)."""
    ctx = _sun_under("slab")
    ph = trace_photons(ctx, ctx.lights, [200_000], caustic_only=False, stream=1)
    pos = ph.position.astype(np.float64) + ctx.geo.offset
    on_floor = np.abs(pos[:, 2]) < 1e-3
    under = on_floor & np.all(np.abs(pos[:, :2]) < 0.9, axis=1)
    # An equal area (1.8 x 1.8 m) beside the slab in the open sun.
    beside = on_floor & (np.abs(pos[:, 0] - 2.5) < 0.9) & (np.abs(pos[:, 1]) < 0.9)
    direct_under = ph.power[under & (ph.kind == DIRECT)].astype(np.float64).sum(axis=0)
    caustic_under = ph.power[under & (ph.kind == CAUSTIC)].astype(np.float64).sum(axis=0)
    open_sun = ph.power[beside & (ph.kind == DIRECT)].astype(np.float64).sum(axis=0)
    assert open_sun.min() > 0
    T = (1.0 - _fresnel(1.0, IOR)) ** 2
    n_under = int(np.count_nonzero(under & (ph.kind == DIRECT)))
    # Relative noise of a sum of ~n roulette-weighted photons: a few / sqrt(n).
    assert n_under > 5000
    np.testing.assert_allclose(direct_under / open_sun, T, rtol=4.0 / math.sqrt(n_under))
    assert np.all(caustic_under < 0.01 * direct_under)


def test_glass_cube_and_ball_still_block_and_cast_caustics():
    """A 1 m glass cube (thickness 58 % of its diagonal) and a ball are not flat: shadow
    rays under them are blocked, the light there is caustic. (Single-plane glass under a
    sun is a next-event pane since pane31: test_single_plane_is_a_sun_pane.)"""
    for shape in ("cube", "ball"):
        ctx = _sun_under(shape)
        hit = _floor_hits(ctx, 200, half=0.2)
        E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
        assert np.all(E == 0.0), shape
        ph = trace_photons(ctx, ctx.lights, [40_000], caustic_only=False, stream=1)
        pos = ph.position.astype(np.float64) + ctx.geo.offset
        under = (np.abs(pos[:, 2]) < 1e-3) & np.all(np.abs(pos[:, :2]) < 0.3, axis=1)
        assert np.any(under & (ph.kind == CAUSTIC)), shape
        assert not np.any(under & (ph.kind == DIRECT)), shape


def test_single_plane_is_a_sun_pane():
    """Single-plane glass bends the sun's light for good: not a flat passage, but a pane
    (engine/panelight.py): the sun's shadow rays refract through it, E = E_sun (1 - F0)
    / n^2 at normal incidence (the photons' convention, docs/units.md), and the sun's
    photons through it are direct, not caustic."""
    ctx = _sun_under("plane")
    hit = _floor_hits(ctx, 200, half=0.2)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    np.testing.assert_allclose(E, 2.0 * (1.0 - _fresnel(1.0, IOR)) / IOR ** 2, rtol=1e-3)
    ph = trace_photons(ctx, ctx.lights, [40_000], caustic_only=False, stream=1)
    pos = ph.position.astype(np.float64) + ctx.geo.offset
    under = (np.abs(pos[:, 2]) < 1e-3) & np.all(np.abs(pos[:, :2]) < 0.3, axis=1)
    assert np.any(under & (ph.kind == DIRECT))
    assert not np.any(under & (ph.kind == CAUSTIC))


def test_slab_counts_two_transparent_bounces():
    """The slab's two surfaces count against transparent_max_bounces (Cycles counts each
    surface a shadow ray crosses): limit 1 blocks, 2 passes."""
    for cap, lit in ((1, False), (2, True)):
        ctx = _sun_under("slab", transparent_max_bounces=cap)
        E = direct_irradiance(ctx, _floor_hits(ctx, 50, half=0.5), np.random.default_rng(1),
                              Counters())
        assert (E.min() > 0) == lit and (E.max() > 0) == lit, cap


def test_glossy_floor_under_slab_counts_the_light_once():
    """Camera paths: a rough metal floor under the slab, lit by a small area light above
    it, seen from under the slab (ray tracing only). The light reaches the floor's glossy
    lobe by shadow rays through the slab (the direct pass: T = (1 - F)^2 of the open
    floor) and by the lobe's sampled rays refracted through it (MIS-weighted against the
    shadow rays: the camera path keeps the floor's MIS state across the passage). Without
    that, both counted the light in full: 1.60 x the open floor (measured); with it, T
    plus the light reflected between floor and slab (0.951, measured)."""
    def scene(slab):
        s = PaperScene(24, 18)
        s.add_plane((0, 0, 0), (0, 0, 1), 6.0,
                    Material("metal", (0.8, 0.8, 0.8), metallic=1.0, roughness=0.3),
                    name="floor")
        if slab:
            s.add_box((0, 0, 1.0), (4.0, 4.0, 0.02), _glass(), name="pane")
        s.add_rect_area_light((0.0, 0.0, 3.0), (0.5, 0.5), power=200.0)
        s.set_camera((0, -0.6, 0.6), (0, 0.3, 0), view_angle=50.0)
        return s.render(RenderSettings(spp=16, photon_mapping=False, seed=1, workers=1))
    slab, open_ = scene(True), scene(False)
    T = (1.0 - _fresnel(1.0, IOR)) ** 2
    # The same light samples: the direct pass is T x the open floor's (T varies by < 0.1 %
    # over the light's 5-degree half-width).
    assert slab.direct.mean() / open_.direct.mean() == pytest.approx(T, rel=2e-3)
    ratio = slab.combined.mean() / open_.combined.mean()
    assert T < ratio < T + 0.05, ratio


def test_point_and_area_light_through_thin_slab():
    """Every light kind's shadow rays take the slab's transmittance: a point light and a
    small area light 3 m above the floor, floor points within 10 cm of the axis (angles
    below 5 degrees: T within 1e-4 of its normal value), the same light samples with and
    without the slab."""
    T = (1.0 - _fresnel(1.0, IOR)) ** 2
    for kind in ("point", "area"):
        E = {}
        for slab in (True, False):
            s = PaperScene(8, 6)
            s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
            if slab:
                s.add_box((0, 0, 1.0), (2.0, 2.0, 0.02), _glass(), name="pane")
            if kind == "point":
                s.add_point_light((0.0, 0.0, 3.0), power=100.0)
            else:
                s.add_rect_area_light((0.0, 0.0, 3.0), (0.3, 0.3), power=100.0)
            s.set_camera((0, -6, 3), (0, 0, 0))
            ctx = prepare_context(s, RenderSettings(workers=1))
            hit = _floor_hits(ctx, 200, half=0.1)
            E[slab] = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
        assert E[False].min() > 0
        np.testing.assert_allclose(E[True], T * E[False], rtol=1e-3)
