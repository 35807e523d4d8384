"""Visual importance for the global photon shot (engine/visualimportance.py): the photons
go where the camera's gather rays end, and the expected power arriving anywhere is kept.

A large plane under a uniform world of radiance L receives irradiance pi L on its top
(and on its underside) wherever nothing shades it, and under a sun of strength S straight
down, S: the photons' power per area must say so both inside the camera's region (where
the photons crowd) and far outside it (where fewer, brighter photons arrive), within the
photons' own statistical error. A closed room, where the region is most of the scene,
keeps its photons exactly as without visual importance.
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, box_mesh
from engine.photons import DIRECT
from engine.render import prepare_context, shoot_photons
from engine import visualimportance as vi

L_WORLD = 0.1


def _ground(background=(L_WORLD,) * 3, sun=None, area=False):
    """A 40 m x 40 m plane with three balls in a row near its centre, the camera looking
    at the balls from 9 m (it sees a few metres of the plane round them)."""
    s = PaperScene(width=64, height=48, background=background)
    s.add_plane((0, 0, 0), size=40.0, name="ground")
    for i in range(3):
        s.add_sphere(((i - 1) * 1.2, 0, 0.5), 0.5, name=f"ball{i}")
    if sun is not None:
        s.add_sun(direction=(0, 0, -1), strength=sun)
    if area:
        s.add_rect_area_light((-2, -3, 5), size=(2, 2), power=500.0)
    s.set_camera((0, -9, 3), (0, 0, 0.4), view_angle=30)
    return s


def _shoot(scene, importance, photons=150_000, seed=3, workers=1):
    st = RenderSettings(photons=photons, caustic_photons=0, seed=seed, workers=workers,
                        photon_importance=importance)
    ctx = prepare_context(scene, st)
    try:
        stats = {}
        ph = shoot_photons(ctx, stats)[0]  # the shots (global, caustic): global
        return ph, ph.position.astype(np.float64) + ctx.geo.offset, stats
    finally:
        ctx.accel.close()


def _irradiance(ph, p, box, up=True):
    """Power per area (W/m^2, red channel) of the DIRECT photons on the plane's top (or
    underside) inside box = (x0, x1, y0, y1), and its standard error (the photons' own
    scatter: sqrt of the sum of squared powers)."""
    x0, x1, y0, y1 = box
    side = ph.normal[:, 2] > 0.5 if up else ph.normal[:, 2] < -0.5
    sel = (side & (np.abs(p[:, 2]) < 1e-3) & (ph.kind == DIRECT) & (p[:, 0] > x0)
           & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1))
    w = ph.power[sel, 0].astype(np.float64)
    area = (x1 - x0) * (y1 - y0)
    return w.sum() / area, math.sqrt((w * w).sum()) / area, int(sel.sum())


NEAR = (-2.5, 2.5, -2.5, -1.0)    # in front of the balls, in the camera's region
FAR = (6.0, 18.0, 6.0, 18.0)      # behind and beside them, outside it
UNDER = (-15.0, 15.0, -15.0, 15.0)


@pytest.fixture(scope="module")
def world_shots():
    scene = _ground()
    return _shoot(scene, True), _shoot(scene, False)


def test_a_plane_under_a_uniform_world_gets_pi_L_inside_and_outside_the_region(world_shots):
    (ph, p, stats), _ = world_shots
    assert stats["photon_importance"].startswith("visual importance: "), stats["photon_importance"]
    expect = math.pi * L_WORLD
    for box, up in ((NEAR, True), (FAR, True), (UNDER, False)):
        E, err, n = _irradiance(ph, p, box, up)
        assert n > 200, (box, n)
        assert abs(E - expect) < 4 * err + 0.005 * expect, (box, up, E, expect, err)


def test_the_region_gets_denser_photons_and_the_rest_fewer_brighter_ones(world_shots):
    (ph, p, _), (nat, pn, _) = world_shots
    _, _, near = _irradiance(ph, p, NEAR)
    _, _, near_nat = _irradiance(nat, pn, NEAR)
    _, _, far = _irradiance(ph, p, FAR)
    _, _, far_nat = _irradiance(nat, pn, FAR)
    assert near > 4 * near_nat, (near, near_nat)
    assert far < far_nat, (far, far_nat)


def test_a_plane_under_a_sun_gets_its_strength_inside_and_outside_the_region():
    S = 2.0
    ph, p, stats = _shoot(_ground(background=(0, 0, 0), sun=S), True)
    assert stats["photon_importance"].startswith("visual importance: "), stats["photon_importance"]
    for box in (NEAR, FAR):
        E, err, n = _irradiance(ph, p, box)
        assert n > 200, (box, n)
        assert abs(E - S) < 4 * err + 0.005 * S, (box, E, S, err)


def test_an_area_light_delivers_the_same_power_as_without_importance():
    """An area light and the world together (issue 14's scene in small): per patch, the
    power with visual importance matches the natural shot's within their errors."""
    scene = _ground(area=True)
    ph, p, stats = _shoot(scene, True, seed=5)
    nat, pn, _ = _shoot(scene, False, seed=6)
    assert stats["photon_importance"].startswith("visual importance: "), stats["photon_importance"]
    for box in (NEAR, FAR, (-6.0, 6.0, 1.0, 4.0)):
        E, err, _ = _irradiance(ph, p, box)
        En, errn, _ = _irradiance(nat, pn, box)
        assert abs(E - En) < 4 * math.hypot(err, errn), (box, E, En, err, errn)


def test_the_split_emitters_keep_each_lights_power():
    """A RegionEmitter's aimed and natural parts together carry the light's flux in
    expectation (here: the mean over many photons), for a finite and an infinite light."""
    scene = _ground(area=True)
    ctx = prepare_context(scene, RenderSettings(photons=1000, workers=1))
    try:
        region = vi.region_of_interest(ctx)
        assert region is not None and region.inside >= vi.ROI_COVER - 1e-9
        for light in ctx.lights:
            em = vi.RegionEmitter(light, region, 0.8)
            rng = np.random.default_rng(11)
            n = 100_000
            _, _, power = em_arrays(em, n, rng)
            flux = np.asarray(light.photon_flux, np.float64)
            got = power.sum(axis=0)
            err = np.sqrt((power ** 2).sum(axis=0))
            assert np.all(np.abs(got - flux) < 4 * err + 1e-3 * flux), (light.name, got, flux)
    finally:
        ctx.accel.close()


def em_arrays(emitter, n, rng):
    from engine.lights.base import emit_arrays
    return emit_arrays(emitter, n, rng)


def test_a_closed_room_keeps_its_natural_photons():
    """The region of a closed room is most of it: the shot stays natural, photon for
    photon."""
    s = PaperScene(width=48, height=36)
    v, f = box_mesh((0, 0, 0), 4.0)
    s.add_triangles(v, f, name="room")
    s.add_sphere((0.5, 0.5, -1.4), 0.6, name="ball")
    s.add_rect_area_light((0, 0, 1.95), size=(1, 1), power=100.0)
    s.set_camera((0, -1.9, 0), (0, 1, -0.2), view_angle=60)
    ph, _, stats = _shoot(s, True, photons=20_000)
    nat, _, _ = _shoot(s, False, photons=20_000)
    text = stats["photon_importance"]
    assert text.startswith("no visual importance: "), text
    assert np.array_equal(ph.position, nat.position)
    assert np.array_equal(ph.power, nat.power)


def test_a_spot_light_is_named_as_the_reason_it_stays_natural():
    """A spot light lighting a wide ground and the balls the camera sees: its photons
    cannot be aimed (can_aim), and the report says so, not that it sends none of its light
    there (a new user's scene read "none" while its spot lit what the camera saw)."""
    s = _ground(background=(0.0, 0.0, 0.0))
    s.add_spot_light((0, -2, 6), (0, 0, 0), power=800.0, spot_size_degrees=120.0)
    ph, _, stats = _shoot(s, True, photons=20_000)
    text = stats["photon_importance"]
    assert text.startswith("no visual importance: "), text
    assert "(spot) cannot aim" in text, text
    assert "none of their light" not in text


def test_the_shot_is_the_same_for_any_worker_count():
    scene = _ground(area=True)
    a, _, sa = _shoot(scene, True, photons=60_000, workers=1)
    b, _, sb = _shoot(scene, True, photons=60_000, workers=2)
    assert sa["photon_importance"] == sb["photon_importance"]
    assert np.array_equal(a.position, b.position) and np.array_equal(a.power, b.power)


@pytest.mark.parametrize("infinite", [False, True])
def test_sphere_meets_is_the_cone_and_disk_test(infinite):
    """meets_spheres / meets_region (one kernel, lights/emission.sphere_meets) against the
    test written out in numpy: a light at infinity meets a sphere when the line passes
    within its radius of the centre; a finite light when the direction lies in the cone
    from the origin that holds the sphere, or the origin lies inside it."""
    from engine.visualimportance import meets_region, meets_spheres
    rng = np.random.default_rng(7)
    n, K = 20_000, 12
    o = rng.normal(size=(n, 3))
    o[:50] = 0.0  # some origins inside a sphere
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    centers = rng.normal(size=(K, 3)) * 2.0
    centers[0] = 0.0
    radii = rng.uniform(0.05, 0.5, K)
    want = np.zeros((n, K), bool)
    for k in range(K):
        t = centers[k] - o
        along = (t * d).sum(axis=1)
        dist2 = (t * t).sum(axis=1)
        if infinite:
            want[:, k] = dist2 - along ** 2 <= radii[k] ** 2
        else:
            dist = np.sqrt(dist2)
            cos_max = np.sqrt(np.maximum(0.0, 1.0 - radii[k] ** 2 / np.maximum(dist2, 1e-300)))
            want[:, k] = (dist <= radii[k]) | (along >= cos_max * dist)
    got = meets_spheres(o, d, centers, radii, infinite)
    assert 0.03 < want.any(axis=1).mean() < 0.9  # both outcomes well represented
    # Ties at the boundary could round either way between numpy's and the kernel's sums.
    assert (got != want).sum() <= 2
    assert np.array_equal(meets_region(o, d, centers, radii, infinite), got.any(axis=1))
    assert np.array_equal(meets_region(o, d, centers[:1], radii[:1], infinite), got[:, 0])
    assert meets_region(o, d, centers[:0], radii[:0], infinite).shape == (n,)


def _cone_meets_exact(dist2, along, r):
    """The cone test of lights/emission written out as both kernels compute it (IEEE
    doubles, no shortcut): (sphere_meets' answer, _cone_cos / aim_direction's answer)."""
    dist = math.sqrt(dist2)
    cos_max = math.sqrt(max(0.0, 1.0 - r * r / max(dist2, 1e-300)))
    meets = dist <= r or along >= cos_max * dist
    ds = max(dist, 1e-300)
    ck = -1.0 if dist <= r else math.sqrt(max(0.0, 1.0 - (r / ds) ** 2))
    return meets, along >= ck * dist


def test_the_cone_tests_quick_miss_never_drops_a_direction_the_exact_test_keeps():
    """lights/emission.cone_misses answers "misses" without square roots only where the
    exact cone test (sphere_meets, aim_direction's mixture pdf) says so too: origins
    from deep inside to just outside the sphere (distance r (1 +- 1e-16 .. 10)),
    directions from far outside to exactly on the cone's edge (+- 1e-16 .. 1e-1), and
    tiny scales. Where it says "misses" the kernels skip the exact test, so a wrong
    answer would drop photons or change the aimed pdf (the stored photons are bit for
    bit those of the test without it)."""
    from engine.lights.emission import cone_misses
    rng = np.random.default_rng(3)
    quick = cases = 0
    for r in (0.0, 1e-120, 1e-3, 0.37, 1.0, 250.0):
        for rel in np.concatenate([-np.logspace(-16, -0.1, 12), [0.0],
                                   np.logspace(-16, 1, 24)]):
            dist2 = (r * r) * (1.0 + rel) if r > 0 else 10.0 ** rng.uniform(-320, 2)
            edge = math.sqrt(max(dist2 - r * r, 0.0))
            alongs = [0.0, -0.0, -edge, edge, math.sqrt(dist2), -math.sqrt(dist2)]
            for e in np.logspace(-16, -1, 16):
                alongs += [edge * (1 - e), edge * (1 + e), np.nextafter(edge, 0.0)]
            for along in alongs:
                along = float(along)
                cases += 1
                if cone_misses(float(dist2), along, float(r)):
                    quick += 1
                    assert not any(_cone_meets_exact(float(dist2), along, float(r))), (
                        r, dist2, along)
    assert quick > 0
    # Away from the edge it answers: random directions from 3 radii out (cone half-angle
    # 19.5 degrees), nearly every exact miss found quickly.
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    misses = quick = 0
    for along in 3.0 * d[:, 0]:
        if not any(_cone_meets_exact(9.0, float(along), 1.0)):
            misses += 1
            quick += bool(cone_misses(9.0, float(along), 1.0))
    assert quick >= 0.99 * misses


def test_the_region_emitters_cull_keeps_the_rows_meets_region_keeps():
    """lights/emission.drop_meeting (the region emitter's cull, in place) keeps exactly
    the rows meets_region says miss every sphere, in their order, each row whole."""
    from engine.lights.emission import drop_meeting
    from engine.visualimportance import meets_region
    rng = np.random.default_rng(11)
    n, K = 5000, 9
    centers = rng.normal(size=(K, 3)) * 2.0
    radii = rng.uniform(0.05, 0.8, K)
    for infinite in (False, True):
        o32 = rng.normal(size=(n, 3)).astype(np.float32)
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        d32 = d.astype(np.float32)
        power = rng.uniform(size=(n, 3))
        slot = np.arange(n, dtype=np.int64) * 3
        lo, hi = 100, n - 50
        keep = ~meets_region(o32[lo:hi].astype(np.float64), d[lo:hi], centers, radii,
                             infinite)
        assert 0.05 < keep.mean() < 0.95
        want = [a.copy() for a in (o32, d32, d, power, slot)]
        got = [a.copy() for a in want]
        end = drop_meeting(*got, lo, hi, centers, radii, infinite)
        assert end == lo + keep.sum()
        for g, w in zip(got, want):
            assert np.array_equal(g[:lo], w[:lo])
            assert np.array_equal(g[lo:end], w[lo:hi][keep])


def _pane_scene():
    """A 1 m x 1 m pane of 2 cm window glass standing on a floor, an area light above
    and in front of it: light enters its top rim face and is piped down inside it."""
    from engine.scene import Material
    s = PaperScene(width=32, height=24)
    s.add_material(Material("pane", (1, 1, 1), transmission=1.0, ior=1.5))
    s.add_plane((0, 0, 0), size=4.0, name="floor")
    s.add_box((0, 0, 0.6), (1.0, 0.02, 1.0), "pane", name="Window")
    s.add_rect_area_light((0, -0.8, 2.0), size=(1.0, 1.0), power=200.0,
                          direction=(0, 0.4, -1))
    s.set_camera((0, -3, 1.5), (0, 0, 0.5), view_angle=40)
    return s


def _first_hits_rim(ctx, rim_tri, o, d):
    t, prim, _, _ = ctx.accel.intersect(o, d, np.full(len(o), np.inf))
    hit = prim >= 0
    hit[hit] = rim_tri[prim[hit]]
    return hit


def test_window_rims_get_aimed_photons_and_keep_their_power():
    """visualimportance.aim_at_rims: the spheres cover the pane's rim faces; the aimed
    emitter carries the light's flux and the power entering the rim faces (first hit a
    rim face) of the natural emission (the split emission is unbiased), with many more
    photons entering them."""
    from engine.effects import window_glass
    from engine.lights.base import emit_arrays
    from engine.sampling import luminance
    ctx = prepare_context(_pane_scene(), RenderSettings(photons=1000, workers=1))
    try:
        geo = ctx.geo
        window = window_glass(geo, ctx.table)
        assert window.any()
        rim_tri = vi.rim_faces(geo, window)
        assert rim_tri.sum() == 8  # a box's four thin faces, two triangles each
        centers, radii = vi.rim_spheres(geo, window)
        assert 0 < len(radii) <= vi.RIM_MAX_SPHERES
        # The rim faces lie in the spheres (all but slivers between the sampled points).
        rng = np.random.default_rng(1)
        idx = np.flatnonzero(rim_tri)
        r = idx[rng.integers(len(idx), size=4000)]
        u = rng.random((2, len(r)))
        fold = u.sum(axis=0) > 1
        u[:, fold] = 1 - u[:, fold]
        p = geo.v0[r] + u[0, :, None] * geo.e1[r] + u[1, :, None] * geo.e2[r]
        dist = np.linalg.norm(p[:, None] - centers[None], axis=2)
        assert (dist <= radii[None]).any(axis=1).mean() > 0.995
        light = ctx.lights[0]
        emitters, counts, said = vi.aim_at_rims(ctx, [light], [100_000], window)
        assert "thin edges of window glass 'Window'" in said, said
        em = emitters[0]
        assert isinstance(em, vi.RegionEmitter) and 0 < em.share <= vi.RIM_MAX_SHARE
        n = 200_000
        flux = float(luminance(np.asarray(light.photon_flux, np.float64)))
        o, d, power = emit_arrays(em, n, np.random.default_rng(2))
        on, dn, pn = emit_arrays(light, n, np.random.default_rng(3))
        w, wn = luminance(power), luminance(pn)
        assert abs(w.sum() - flux) < 4 * math.sqrt((w * w).sum()) + 1e-3 * flux
        hit, hitn = _first_hits_rim(ctx, rim_tri, o, d), _first_hits_rim(ctx, rim_tri, on, dn)
        E, En = w[hit].sum(), wn[hitn].sum()
        err = math.hypot(math.sqrt((w[hit] ** 2).sum()), math.sqrt((wn[hitn] ** 2).sum()))
        assert abs(E - En) < 4 * err, (E, En, err)
        assert hit.sum() > 10 * hitn.sum(), (hit.sum(), hitn.sum())
    finally:
        ctx.accel.close()


def _lookups(scene):
    ctx = prepare_context(scene, RenderSettings(photons=1000, workers=1))
    try:
        region = vi.region_of_interest(ctx)
        centers = None if region is None else region.centers + ctx.geo.offset
        return vi.lookup_points(ctx) + ctx.geo.offset, centers, ctx.table
    finally:
        ctx.accel.close()


def test_a_fog_box_round_the_scene_is_seen_through_by_the_pre_pass(monkeypatch):
    """A volume-only fog box round the balls and the plane (camera outside it): its walls
    are invisible to every ray, so the pre-pass' camera rays and the gather rays pass
    them: the same lookups as without the box. It mirrored camera rays there and ended
    gather rays on them: "no visual importance: the camera's final-gather rays reach no
    surface that stores photons" with a floor in view (newuser36's fog box)."""
    from engine.scene import Material

    def fogged():
        scene = _ground(area=True)
        scene.add_material(Material("fog", volume_only=True, scattering=(0.05, 0.05, 0.05)))
        scene.add_box((0, 0, 2.0), (12.0, 12.0, 4.2), "fog", name="fog box")
        return scene
    clear, clear_region, _ = _lookups(_ground(area=True))
    points, region, table = _lookups(fogged())
    assert vi.invisible_materials(table)[table.names.index("fog")]
    assert len(points) == len(clear) > 1000, (len(points), len(clear))
    assert np.abs(points - clear).max() < 1e-3  # (the walls' origin offsets aside)
    assert region is not None and np.allclose(region, clear_region, atol=1e-3)
    monkeypatch.setattr(vi, "INVISIBLE_DEPTH", 0)  # the walls as before: no lookups
    points, region, _ = _lookups(fogged())
    assert len(points) == 0 and region is None, len(points)


def test_cells_of_is_np_unique_over_rows():
    """cover_cells' cells (_cells_of: one mixed-radix int64 per row) are np.unique's over
    the rows, inverse and counts alike: for keys with negative values, for a span too
    large for one int64 (np.unique's own then) and for a single row."""
    rng = np.random.default_rng(5)
    for key in (rng.integers(-40, 40, (5000, 3)),
                np.concatenate([rng.integers(0, 3, (300, 3)),
                                [[-2 ** 40, 0, 2 ** 40], [2 ** 40, 5, -2 ** 40]]]),
                np.array([[7, -3, 2]])):
        _, member, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        got_member, got_count = vi._cells_of(key.astype(np.int64))
        assert np.array_equal(got_member, member.ravel())
        assert np.array_equal(got_count, count)
