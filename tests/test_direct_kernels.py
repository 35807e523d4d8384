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
    monkeypatch.setattr(dl, "MAX_ENTRIES", len(hit.p))  # one: its numbers without a copy
    single = direct_irradiance(ctx, hit, np.random.default_rng(4), Counters())
    assert np.array_equal(whole, single)
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
    weights) give the bits of fresh arrays."""
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


def test_empty_offset_rows_and_unread_directions_change_no_bit():
    """sample_lights with no shading / terminator offset rows (empty arrays) and no
    direction or pdf output (the diffuse lobe alone) writes the same entries and shadow
    rays as with zero rows and every output."""
    from engine.integrator import _hit_arrays
    from engine.lights.packing import pack_lights
    from engine.lights.selection import empty_tree

    ctx = prepare_context(_box_with_every_kind(), RenderSettings(workers=1))
    hit = _floor_hits(ctx, 4000, 7)
    arrays = list(_hit_arrays(ctx.geo, hit))
    assert arrays[5].shape == (0,)  # no object has a shading offset
    n = len(hit.p)
    zeros = list(arrays)
    zeros[5], zeros[6], zeros[7] = np.zeros(n), np.zeros(n), np.zeros((n, 3))
    arrays[6], arrays[7] = dl.NO_ROWS, dl.NO_ROWS3  # nor a terminator offset
    codes, params, mesh = pack_lights(ctx.lights)
    L = len(codes)
    rng = np.random.default_rng(3)
    U1, U2, SEL = rng.random((3, L, n))
    out = []
    for hit_arrays, want_dir in ((zeros, True), (arrays, False)):
        b = dl.DirectLightBuffers().ensure(L * n)
        b.contrib[:] = b.o32[:] = b.d32[:] = b.t32[:] = b.bump[:] = np.nan
        m = dl.sample_lights(*hit_arrays, codes, params, *mesh, *empty_tree(),
                             np.ones(L, np.bool_), np.arange(L), np.ones(L, np.bool_),
                             U1, U2, SEL, b.contrib, b.row, b.kidx, b.ray, b.o32, b.d32,
                             b.t32, b.wdir if want_dir else dl.NO_ROWS3,
                             b.lpdf if want_dir else dl.NO_ROWS, b.bump, dl.NO_HROWS,
                             dl.NO_ROWS3)
        out.append((m, b))
    (m0, a), (m1, b) = out
    assert m0 == m1 and m0[1] > n  # every light lit some of the floor
    j, r = m0
    for name, k in (("contrib", j), ("row", j), ("kidx", j), ("ray", j), ("bump", j),
                    ("o32", r), ("d32", r), ("t32", r)):
        assert np.array_equal(getattr(a, name)[:k], getattr(b, name)[:k]), name


def test_terminator_lift_on_the_shaded_rows_alone():
    """terminator_lift with `only` (a camera bounce's shaded rows, integrator._hit_arrays'
    rows) writes at those rows exactly what the whole batch's pass writes there, and
    nothing elsewhere (the other rows stay as they were: sample_lights never reads them);
    direct_irradiance on rows of a batch with smooth terminator-offset hits gives the same
    sums as on their copy."""
    from helpers import hits_from_inside

    ctx = prepare_context(cornell_box(8, 6, glass_sphere=True),
                          RenderSettings(workers=1, photon_mapping=False))
    geo = ctx.geo
    assert (geo.object_terminator > 0).any()
    hit = hits_from_inside(ctx, 20000, 4)
    n = len(hit.p)
    tri, tabs = geo.hit_tables(hit.prim, "smooth", "object_id", "v0", "e1", "e2",
                               "corner_normals")
    smooth_hits = np.take(geo.smooth, hit.prim)
    assert 100 < smooth_hits.sum() < n - 100
    bary = np.ascontiguousarray(hit.bary, np.float64)
    ng = np.ascontiguousarray(hit.ng, np.float64)
    full_cut, full_lift = np.empty(n), np.empty((n, 3))
    dl.terminator_lift(tri, bary, ng, tabs[0], tabs[1], geo.object_terminator, *tabs[2:],
                       full_cut, full_lift, dl.NO_HROWS)
    assert (full_cut > 0).any() and (full_lift != 0).any()
    rows = np.nonzero(np.random.default_rng(1).random(n) < 0.6)[0]
    cut, lift = np.full(n, np.nan), np.full((n, 3), np.nan)
    dl.terminator_lift(tri, bary, ng, tabs[0], tabs[1], geo.object_terminator, *tabs[2:],
                       cut, lift, rows)
    assert np.array_equal(cut[rows], full_cut[rows])
    assert np.array_equal(lift[rows], full_lift[rows])
    rest = np.ones(n, bool)
    rest[rows] = False
    assert np.isnan(cut[rest]).all() and np.isnan(lift[rest]).all()
    for seed in (1, 2):
        a = direct_irradiance(ctx, hit.take(rows), np.random.default_rng(seed), Counters())
        b = direct_irradiance(ctx, hit, np.random.default_rng(seed), Counters(), rows=rows)
        assert np.array_equal(a, b) and a[:, 0].max() > 0
