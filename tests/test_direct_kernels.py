"""The compiled direct-light stage (engine/directlight.py): grouping of light samples does
not change a bit, Embree's float32 entry point refuses bad arrays, and every light kind
lights a receiver it faces (energy checks of each kind: test_analytic.py, test_energy.py)."""
import numpy as np
import pytest

import engine.directlight as dl
from engine import RenderSettings
from engine.accel import Accel
from engine.api import PaperScene, cornell_box
from engine.bsdf import surface_hit
from engine.integrator import Counters, direct_irradiance
from engine.render import prepare_context
from engine.scene import Material


def _floor_hits(ctx, n, seed=0):
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-1.8, 1.8, n), rng.uniform(-1.8, 1.8, n), np.full(n, 1.0)])
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    t, prim, u, v = ctx.accel.intersect(o, d)
    keep = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])


def _box_with_every_kind():
    s = cornell_box(8, 6, glass_sphere=False)
    s.add_point_light((-1.0, 0.5, 3.0), 30.0, radius=0.05)
    s.add_spot_light((1.0, -0.5, 3.5), (0, 0, 0), 60.0, radius=0.1)
    s.add_sphere((-1.2, 1.2, 2.5), 0.2, Material("glow", emission=(4, 4, 4)), name="glow",
                 segments=8)
    return s


def test_grouping_of_light_samples_changes_no_bit(monkeypatch):
    ctx = prepare_context(_box_with_every_kind(), RenderSettings(light_samples=5, workers=1))
    hit = _floor_hits(ctx, 3000)
    whole = direct_irradiance(ctx, hit, np.random.default_rng(4), Counters())
    monkeypatch.setattr(dl, "MAX_ENTRIES", 7000)  # two samples per kernel call
    grouped = direct_irradiance(ctx, hit, np.random.default_rng(4), Counters())
    assert np.array_equal(whole, grouped)
    assert np.all(np.isfinite(whole)) and whole[:, 0].mean() > 0


def test_occluded_into_refuses_bad_arrays():
    acc = Accel(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    o = np.zeros((4, 3), np.float32)
    d = np.tile(np.float32([0, 0, 1]), (4, 1))
    t = np.ones(4, np.float32)
    out = np.zeros(4, bool)
    with pytest.raises(ValueError, match="directions must be C-contiguous float32"):
        acc.occluded_into(o, d[:3], t, out)
    with pytest.raises(ValueError, match="tmax must be"):
        acc.occluded_into(o, d, t.astype(np.float64), out)
    with pytest.raises(ValueError, match="blocked must be bool"):
        acc.occluded_into(o, d, t, np.zeros(3, bool))
    o[:, :2] = 0.25
    o[:, 2] = -1.0
    t[:] = 2.0
    acc.occluded_into(o, d, t, out)
    assert out.all()  # the triangle lies 1 m above the origins
    t[:] = 0.5
    acc.occluded_into(o, d, t, out)
    assert not out.any()


def test_sun_and_world_light_a_floor_as_their_formulas_say():
    """Sun of 2 W/m^2 straight down: E = 2; a uniform world of radiance 0.3 seen over the
    upper hemisphere: E = pi 0.3 (one sample per point; exact for these two)."""
    s = PaperScene(8, 6, background=(0.3, 0.3, 0.3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    ctx = prepare_context(s, RenderSettings(workers=1))
    hit = _floor_hits(ctx, 500)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    assert np.allclose(E, 2.0 + np.pi * 0.3, rtol=1e-12)


def test_reused_buffers_change_no_bit():
    """One thread's DirectLightBuffers reused across calls of different sizes (larger,
    smaller, with and without a third random number per sample, with and without glossy
    weights) give the bits of fresh arrays, and the zero rows stay zero."""
    from engine.closures import principled as pr
    from engine.integrator import shade_diffuse

    ctx = prepare_context(_box_with_every_kind(), RenderSettings(light_samples=3, workers=1,
                                                                 photon_mapping=False))
    buffers = dl.DirectLightBuffers()
    for n, seed in ((2000, 1), (3000, 2), (500, 3), (2500, 4)):
        hit = _floor_hits(ctx, n, seed)
        fresh = direct_irradiance(ctx, hit, np.random.default_rng(seed), Counters())
        reused = direct_irradiance(ctx, hit, np.random.default_rng(seed), Counters(),
                                   buffers=buffers)
        assert reused.base is buffers.E or reused is buffers.E
        assert np.array_equal(fresh, reused)
        # The diffuse stage's product f x E, in place in the buffers' sums.
        wd = np.full((len(hit.p), 3), 0.7)
        a = shade_diffuse(ctx, hit, wd, np.random.default_rng(seed), Counters())[0]
        b = shade_diffuse(ctx, hit, wd, np.random.default_rng(seed), Counters(),
                          buffers=buffers)[0]
        assert np.array_equal(a, b) and a[:, 0].mean() > 0
        # Radiance weighted by the BSDF (accumulate_bsdf): every light's glossy mode.
        m = len(hit.p)
        prm = np.zeros((m, pr.N_PACK))
        sel = np.full((m, pr.N_LOBES), 0.1)
        fd = np.full((m, 3), 0.2)
        a = direct_irradiance(ctx, hit, np.random.default_rng(seed), Counters(),
                              bsdf=(fd, prm, sel))
        b = direct_irradiance(ctx, hit, np.random.default_rng(seed), Counters(),
                              bsdf=(fd, prm, sel), buffers=buffers)
        assert np.array_equal(a, b)
    assert not buffers.zero1.any() and not buffers.zero3.any()
