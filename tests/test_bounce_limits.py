"""Cycles' Light Paths bounce limits (max_bounces, diffuse / glossy / transmission bounces;
docs/design.md, Bounce limits): the photons' counts, the maps' filtering and the camera
chain, against geometric series and simple optics."""
import copy

import numpy as np
import pytest

from engine import RenderSettings
from engine import photonkernels as pk
from engine.api import PaperScene
from engine.photonlayout import vectors
from engine.scene import Material
from engine.photons import DIRECT
from test_energy import closed_box, shoot

HIGH = dict(max_bounces=1024, diffuse_bounces=1024, glossy_bounces=1024,
            transmission_bounces=1024)


def test_settings_default_to_cycles_light_paths():
    s = RenderSettings()
    assert (s.max_bounces, s.diffuse_bounces, s.glossy_bounces, s.transmission_bounces) == \
        (12, 4, 4, 12)
    assert s.bounce_limits.tolist() == [12, 4, 4, 12]
    with pytest.raises(ValueError):
        RenderSettings(diffuse_bounces=-1)
    with pytest.raises(ValueError):
        RenderSettings(max_bounces=2000)


def test_photon_counts_follow_its_bounces_in_a_closed_box():
    """Closed Lambertian box of albedo a: Russian roulette keeps a photon's power and
    continues it with probability a, so the photons stored after s scatters carry P a^s
    in all, and each photon's counts say s (total) and s - 1 diffuse bounces after the
    first (0 for direct photons)."""
    a, P, n = 0.6, 100.0, 20000
    ph = shoot(closed_box(a, P), RenderSettings(photons=n, max_photon_depth=80, **HIGH))
    b = ph.bounces.astype(np.int64)
    assert ph.bounces.dtype == np.uint8 and b.shape == (len(ph), 4)
    assert np.all(b[:, 2:] == 0)  # no glossy or transmission bounce in a Lambert box
    assert np.all(b[:, 1] == np.maximum(b[:, 0] - 1, 0))
    assert np.all((b[:, 0] == 0) == (ph.kind == DIRECT))
    power = ph.power.astype(np.float64).sum(axis=1) / 3
    for s in range(5):
        # sum of Bernoulli(a^s) x P / n: standard error P sqrt(a^s (1 - a^s) / n)
        got = power[b[:, 0] == s].sum()
        sigma = P * np.sqrt(a ** s * (1 - a ** s) / n) + 1e-6 * P  # (float32 sums)
        assert abs(got - P * a ** s) < 5 * sigma, (s, got, P * a ** s)


@pytest.mark.parametrize("diffuse", [0, 1, 3])
def test_photon_pass_stops_at_the_diffuse_limit(diffuse):
    """With diffuse_bounces = D the stored power is the geometric series cut after D
    scatters, P (1 + a + ... + a^D) (a lookup after s >= 1 scatters is the path's
    (s + 1)-th diffuse vertex, s of them bounces); no photon is stored past it."""
    a, P, n = 0.6, 100.0, 20000
    ph = shoot(closed_box(a, P), RenderSettings(photons=n, max_photon_depth=80,
                                                **dict(HIGH, diffuse_bounces=diffuse)))
    assert ph.bounces[:, 0].max() == diffuse
    total = ph.power.astype(np.float64).sum() / 3
    want = P * sum(a ** k for k in range(diffuse + 1))
    assert abs(total - want) < 0.02 * want, (total, want)
    # The total limit cuts the same way.
    ph2 = shoot(closed_box(a, P), RenderSettings(photons=n, max_photon_depth=80,
                                                 **dict(HIGH, max_bounces=diffuse)))
    np.testing.assert_array_equal(ph.power, ph2.power)


def test_bounce_usable_counts_the_camera_side_and_the_lookup_vertex():
    lim = np.array([3, 2, 1, 5])
    counts = np.array([[0, 0, 0, 0],   # direct photon: the camera side's bounces only
                       [1, 0, 0, 0],   # one scatter: the lookup vertex is a diffuse bounce
                       [2, 1, 0, 0],
                       [3, 0, 1, 1],
                       [2, 0, 2, 0]], np.uint8)
    assert pk.bounce_usable(counts, lim).tolist() == [True, True, True, True, False]
    # A final-gather ray's end: one more diffuse bounce and one more in all.
    assert pk.bounce_usable(counts, lim, (1, 1, 0, 0)).tolist() == \
        [True, True, False, False, False]


def _inside_sphere(albedo):
    """A closed sphere of albedo a with a point light at its centre, seen from inside:
    in a sphere every diffuse reflection spreads its power evenly over the inner surface
    (the form factor from any point to dA is dA / (4 pi R^2)), so each bounce adds
    a^k of the direct irradiance everywhere: indirect / direct = a + a^2 + ... + a^D with D
    diffuse bounces (Cycles: D diffuse scatters, then the light sample at the next hit)."""
    s = PaperScene(width=24, height=18)
    s.add_material(Material("wall", (albedo,) * 3))
    s.add_sphere((0, 0, 0), 1.0, "wall", name="ball", segments=64)
    s.add_point_light((0, 0, 0), power=100.0)
    s.set_camera((0, -0.5, 0.1), (0, 1, 0.1), view_angle=70)
    return s


@pytest.mark.parametrize("diffuse", [1, 2])
def test_inside_a_sphere_indirect_light_is_the_cut_geometric_series(diffuse):
    a = 0.5
    st = dict(photons=30000, caustic_photons=0, spp=4, seed=3, **HIGH)
    st["diffuse_bounces"] = diffuse
    film = _inside_sphere(a).render(RenderSettings(**st))
    ratio = film.indirect.mean() / film.direct.mean()
    want = sum(a ** k for k in range(1, diffuse + 1))
    assert abs(ratio - want) < 0.03 * want, (ratio, want)
    # The same cut by the total limit.
    st.update(diffuse_bounces=1024, max_bounces=diffuse)
    film2 = _inside_sphere(a).render(RenderSettings(**st))
    ratio2 = film2.indirect.mean() / film2.direct.mean()
    assert abs(ratio2 - want) < 0.03 * want, (ratio2, want)


def test_no_diffuse_bounce_leaves_direct_light_only():
    """diffuse_bounces = 0: no indirect light and no caustic (Cycles reaches a caustic
    only through a diffuse bounce at the lit surface); the direct light is untouched."""
    st = dict(photons=20000, caustic_photons=5000, spp=2, seed=2, **HIGH)
    high = _inside_sphere(0.5).render(RenderSettings(**st))
    zero = _inside_sphere(0.5).render(RenderSettings(**dict(st, diffuse_bounces=0)))
    assert high.indirect.max() > 0
    assert zero.indirect.max() == 0.0 and zero.caustic.max() == 0.0
    np.testing.assert_allclose(zero.direct.mean(), high.direct.mean(), rtol=1e-9)


def test_high_limits_keep_the_unlimited_image():
    """Limits no path reaches change nothing, bit for bit."""
    st = dict(photons=8000, spp=2, seed=5, max_photon_depth=40)
    a = _inside_sphere(0.7).render(RenderSettings(**st, **HIGH))
    b = _inside_sphere(0.7).render(RenderSettings(**st, **{k: 900 for k in HIGH}))
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def _mirror_view(mirror: Material):
    """The camera looks down at a 45-degree surface that shows (by a mirror reflection
    or straight through) a lit diffuse wall; nothing else is lit."""
    s = PaperScene(width=16, height=12)
    s.add_material(Material("wall", (0.8, 0.8, 0.8)))
    s.add_material(mirror)
    s.add_plane((0, 0, 0), normal=(0, 1, 1), size=1.0, material=mirror.name, name="m")
    s.add_plane((0, 3, 0), normal=(0, -1, 0), size=4.0, material="wall", name="wall")
    s.add_plane((0, 0, -3), normal=(0, 0, 1), size=4.0, material="wall", name="floor")
    s.add_point_light((0, 1.5, 0.0), power=200.0)
    s.set_camera((0, 0, 2), (0, 0, 0), up=(0, 1, 0), view_angle=15)
    return s


def test_camera_chain_honours_the_glossy_and_transmission_limits():
    """A mirror seen by the camera shows the lit wall with one glossy bounce allowed, and
    nothing with none; glass (two refractions through a slab's faces: here a single
    plane, one refraction) likewise with transmission bounces."""
    st = dict(photons=2000, caustic_photons=0, spp=2, seed=1, caustics="off",
              indirect="off", **HIGH)
    mirror = Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0)
    on = _mirror_view(mirror).render(RenderSettings(**dict(st, glossy_bounces=1)))
    off = _mirror_view(mirror).render(RenderSettings(**dict(st, glossy_bounces=0)))
    assert on.specular.mean() > 0.01
    assert off.specular.max() == 0.0
    np.testing.assert_array_equal(on.direct, off.direct)
    total0 = _mirror_view(mirror).render(RenderSettings(**dict(st, max_bounces=0)))
    assert total0.specular.max() == 0.0
    glass = Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=1.5)
    on = _mirror_view(glass).render(RenderSettings(**dict(st, transmission_bounces=1)))
    off = _mirror_view(glass).render(RenderSettings(**dict(st, transmission_bounces=0)))
    # Through the pane the floor is seen; the pane's reflection (glossy) stays.
    assert on.specular.mean() > off.specular.mean() * 1.5


def test_scene_file_and_command_line_set_the_limits(tmp_path):
    import os
    from engine import cli
    from engine.scenefile import load_scene
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    text = open(os.path.join(root, "scenes", "figure6.toml")).read()
    path = tmp_path / "room.toml"
    path.write_text(text.replace("[render]\n", "[render]\ndiffuse_bounces = 2\n"
                                 "max_bounces = 9\n", 1))
    _, overrides = load_scene(str(path))
    s = RenderSettings(**overrides)
    assert (s.max_bounces, s.diffuse_bounces, s.glossy_bounces) == (9, 2, 4)
    args = cli.build_parser().parse_args(["render", str(path), "-o", str(tmp_path / "x.png"),
                                          "--glossy-bounces", "1",
                                          "--transmission-bounces", "3"])
    _, kw = cli._scene_and_overrides(args)
    s = RenderSettings(**kw)
    assert s.bounce_limits.tolist() == [9, 2, 1, 3]


def test_gather_map_subsets_estimate_their_photons_alone_at_the_same_points():
    """The regathers' maps (GatherMap subset_maps): the level-0 map's points, trees and
    discs with the irradiance of a subset's photons. Every photon kept: the map's own
    numbers bit for bit; none: zero; a photon in two by a fair coin: half the irradiance
    on average (the other photons' power counted as 0, an unbiased subset estimate)."""
    from engine.photonmap import GatherMap
    ph = shoot(closed_box(0.6, 100.0), RenderSettings(photons=20000, **HIGH))
    n = len(ph)
    coin = np.random.default_rng(5).random(n) < 0.5
    g = GatherMap(ph, 0.2, 32, 1, "knn_simpson", workers=1,
                  subsets=[np.ones(n, bool), np.zeros(n, bool), coin])
    same, none, half = g.subset_maps
    assert np.array_equal(same.E, g.E) and np.array_equal(same.boundary, g.boundary)
    assert same.tree is g.tree and same.neighbours is g.neighbours
    assert not none.E.any()
    lit = g.E.sum(axis=1) > 0
    ratio = half.E[lit].sum() / g.E[lit].sum()
    assert abs(ratio - 0.5) < 0.02, ratio
    assert g.subset_maps and not same.subset_maps


def _regather_maps(scene, **limits):
    from engine.render import prepare_context, shoot_photons
    ctx = prepare_context(scene, RenderSettings(photons=40000, caustic_photons=0, workers=1,
                                                **limits))
    try:
        shoot_photons(ctx, {})
        if ctx.gather_map is not None:
            ctx.gather_map.complete()  # (every point's estimates: the arrays are read whole)
        return ctx.gather_map, ctx.regather_maps
    finally:
        ctx.accel.close()


def test_regathers_get_maps_of_their_depth_wherever_the_limits_drop_light():
    """A closed bright box loses a large share of its photons' power at each deeper level:
    each regather level reads a subset map of its own. A ball on a floor open to the sky
    drops far less (0.02 / 0.25 % of the power at levels 1 / 2), all of it near the
    ball's contact: its regathers get their subsets too (they read the level-0 map while
    the drop was under 0.5 %: a house on a lawn, whose deep photons are a sliver of the
    shot's power but most of its rooms' light, read 1.2x Cycles at Diffuse 4;
    tests/blender/test_blender_bounces.py). A subset holds the level's photons alone:
    nowhere brighter than the level above. With limits no photon reaches, no subset."""
    g, deeper = _regather_maps(closed_box(0.8))
    assert len(deeper) == 2 and all(m is not g for m in deeper) and deeper[0] is not deeper[1]
    assert all(m.tree is g.tree for m in deeper)
    s = PaperScene(width=16, height=12)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 10.0, "grey", name="floor")
    s.add_sphere((0, 0, 0.5), 0.5, "grey", name="ball")
    s.add_point_light((1.0, -1.0, 5.0), power=2000.0)
    s.set_camera((0, -4, 2), (0, 0, 0.4), view_angle=50)
    g, deeper = _regather_maps(s)
    assert g is not None and len(deeper) == 2
    assert all(m is not g and m.tree is g.tree for m in deeper) and deeper[0] is not deeper[1]
    assert np.all(deeper[0].E <= g.E + 1e-12) and np.all(deeper[1].E <= deeper[0].E + 1e-12)
    assert (deeper[0].E < g.E).any()
    g, deeper = _regather_maps(s, max_bounces=1024, diffuse_bounces=1024)
    assert g is not None and all(m is g for m in deeper)


def _inside_sphere_through_a_mirror(albedo):
    """_inside_sphere with the camera's view filled by a flat mirror that camera rays
    alone see (every other ray kind, shadow rays and photons pass it): each pixel shows
    the sphere's wall after one glossy bounce, lit as in _inside_sphere."""
    s = _inside_sphere(albedo)
    s.add_material(Material("mirror", (1.0, 1.0, 1.0), metallic=1.0, roughness=0.0))
    m = s.add_plane((0, 0.2, 0.1), normal=(0, -1, 0), size=1.2, material="mirror",
                    name="mirror")
    m.visible_diffuse = m.visible_glossy = m.visible_transmission = False
    m.visible_shadow = False
    return s


@pytest.mark.parametrize("final_gather", [True, False])
def test_lookups_after_a_mirror_count_its_bounce(final_gather):
    """Seen through a mirror (one glossy bounce), the sphere's wall with Max Bounces T
    shows direct + indirect light of T - 1 bounces: radiance x (1 + a + ... + a^(T-1)),
    so T = 2 against T = 3 reads (1 + a) / (1 + a + a^2) (0.857 at a = 0.5). Lookups
    that used the photons of the camera's first hit (c = 0) read (1 + a + a^2) / (1 + a
    + a^2 + a^3) (0.933): the k-NN maps' photons are counted for the chain's counts
    (chaincounts.irradiance: the global map without final gathering), the gather map's
    lookups gather again from their ends (chaincounts.GatherCounts.reroute)."""
    a = 0.5
    st = dict(photons=30000, caustic_photons=0, spp=4, seed=3, final_gather=final_gather,
              **dict(HIGH, diffuse_bounces=1024))
    spec = {}
    for total in (2, 3):
        film = _inside_sphere_through_a_mirror(a).render(
            RenderSettings(**dict(st, max_bounces=total)))
        assert film.direct.max() == 0.0  # every pixel sees the mirror
        spec[total] = film.specular.mean()
    ratio = spec[2] / spec[3]
    want = (1 + a) / (1 + a + a * a)
    assert abs(ratio - want) < 0.02 * want, (ratio, want)


def test_chain_lookups_count_only_the_photons_usable_for_each_rows_counts():
    """chaincounts.irradiance: rows whose counts keep every photon read the map's own
    estimate (bit for bit), rows whose counts keep none read 0, and the others the
    estimate of their usable photons alone from the same disc: the bits of a map whose
    other photons carry no power."""
    from engine import chaincounts
    from engine.render import _counted_map
    ph = shoot(closed_box(0.6, 100.0), RenderSettings(photons=20000, **HIGH))
    lim = np.array([3, 3, 3, 3])
    pm = _counted_map(ph, 1, np.flatnonzero(ph.usable(lim)))  # as render._build_maps
    assert pm.photons.bounces is not None
    rng = np.random.default_rng(2)
    p = pm.photons.position[rng.choice(len(pm), 64, replace=False)].astype(np.float64)
    n = vectors(pm.photons.normal, rng.choice(len(pm), 64, replace=False))  # (either layout)
    n = np.where(np.sum(n * n, axis=1, keepdims=True) > 0, n, (0, 0, 1))
    counts = np.zeros((64, 4), np.int64)
    counts[16:32] = (1, 1, 0, 0)
    counts[32:48] = (9, 0, 0, 0)  # past every photon's use
    counts[48:] = (2, 1, 0, 0)
    args = (0.3, 32, 1, "knn_simpson")
    got = chaincounts.irradiance(pm, lim, counts, p, n, *args)
    plain = pm.irradiance(p, n, *args)
    np.testing.assert_array_equal(got[:16], plain[:16])  # (0, 0, 0, 0) keeps all (limits 3)
    assert not got[32:48].any()
    for rows, key in ((slice(16, 32), (1, 1, 0, 0)), (slice(48, 64), (2, 1, 0, 0))):
        ok = pm.photons.usable(lim, key)
        assert 0 < ok.sum() < len(ok)
        zeroed = copy.copy(pm)
        zeroed.photons = copy.copy(pm.photons)
        # (a compact map's RGBE row of zeros is a power of 0: the same decoded values)
        zeroed.photons.power = np.where(ok[:, None], pm.photons.power, 0).astype(
            pm.photons.power.dtype)
        np.testing.assert_array_equal(got[rows], zeroed.irradiance(p[rows], n[rows], *args))
    # Without counts: the map's own call.
    np.testing.assert_array_equal(chaincounts.irradiance(pm, lim, None, p, n, *args), plain)


def test_unique_counts_are_numpys_unique_rows():
    """chaincounts.unique_counts: the distinct count rows and each row's index, the very
    arrays of np.unique(axis=0, return_inverse=True) (whose structured-row sort it
    replaces), on all-equal rows, packed keys (counts < 2^15) and the general fallback."""
    from engine.chaincounts import unique_counts
    rng = np.random.default_rng(3)
    mixed = np.tile(np.array([[1, 1, 0, 0]]), (500, 1))
    mixed[::7, 2] += 1
    mixed[::11, 0] = 1024
    # (and rows enough for the table of keys: a shot's uint8 counts with saturated
    # ones, small int64 counts, all-equal rows; counts too large or negative for it)
    shot = rng.integers(0, 6, (20000, 4)).astype(np.uint8)
    shot[::97] = pk.BOUNCE_SATURATED
    cases = (np.zeros((0, 4), np.int64), np.tile(np.array([[2, 2, 0, 0]]), (300, 1)), mixed,
             rng.integers(0, 4, (2000, 4)), rng.integers(0, 40000, (200, 4)),
             rng.integers(-2, 3, (200, 4)), shot, rng.integers(0, 3, (9000, 4)).astype(np.uint16),
             np.tile(np.array([[1, 1, 0, 0]], np.uint8), (5000, 1)),
             rng.integers(0, 5000, (6000, 4)), rng.integers(-1, 3, (6000, 4)))
    for c in cases:
        want_keys, want_which = np.unique(c, axis=0, return_inverse=True)
        keys, which = unique_counts(c)
        assert keys.dtype == np.int64 and which.dtype == np.int64
        np.testing.assert_array_equal(keys, want_keys)
        np.testing.assert_array_equal(which, want_which.reshape(-1))


def test_photons_usable_by_count_classes_is_bounce_usable():
    """Photons.usable of a shot (at least USABLE_BY_CLASS photons) reads its count
    classes (made once, kept while the bounces are the same array, not pickled): the
    very mask of bounce_usable over every photon, at any camera counts."""
    import pickle
    from engine.photons import USABLE_BY_CLASS, Photons
    rng = np.random.default_rng(5)
    n = USABLE_BY_CLASS + 3000
    b = rng.integers(0, 6, (n, 4)).astype(np.uint8)
    b[::89] = pk.BOUNCE_SATURATED
    z = np.zeros((n, 3), np.float32)
    ph = Photons(z, z, z, z, np.zeros(n, np.uint8), bounces=b)
    lim = np.array([8, 4, 4, 6])
    for cam in ((0, 0, 0, 0), (1, 1, 0, 0), (3, 1, 1, 1), (5, 2, 2, 1), (9, 5, 0, 0)):
        np.testing.assert_array_equal(ph.usable(lim, cam), pk.bounce_usable(b, lim, cam))
    assert "_classes" not in pickle.loads(pickle.dumps(ph)).__dict__
    ph.bounces = b2 = b[::-1].copy()  # (a new array: its own classes)
    np.testing.assert_array_equal(ph.usable(lim, (2, 1, 1, 0)), pk.bounce_usable(b2, lim,
                                                                                 (2, 1, 1, 0)))


def test_exact_class_sums_are_the_correctly_rounded_sums():
    """chaincounts.exact_class_sums: math.fsum of a class's partial sums is the correctly
    rounded sum of its values (against math.fsum over the values, with values 1e12 apart
    that float64 summation loses), for any union of classes; a non-finite value counts
    as 0 instead of making every class NaN (review of review53)."""
    import math
    from engine.chaincounts import exact_class_sums
    rng = np.random.default_rng(7)
    n = 5000
    values = rng.random(n) * 10.0 ** rng.integers(-6, 7, n)
    which = rng.integers(0, 5, n)
    parts = exact_class_sums(which, values, 5)
    for classes in ((0,), (1, 3), (0, 1, 2, 3, 4)):
        sel = np.isin(which, classes)
        assert math.fsum(parts[list(classes)].ravel()) == math.fsum(values[sel])
    bad = values.copy()
    bad[10], bad[20] = np.inf, np.nan
    parts = exact_class_sums(which, bad, 5)
    assert np.isfinite(parts).all()
    keep = np.isfinite(bad)
    assert math.fsum(parts.ravel()) == math.fsum(bad[keep])


def test_gather_counts_decide_as_the_photons_own_sums():
    """GatherCounts.drops reads the photons by their distinct count rows; every decision
    is the photon-by-photon one on the correctly rounded float64 sums (the power of the
    level's usable photons that the key's counts drop, against share of the level's),
    also at a share set on one key's ratio and a rounding step either side of it."""
    import math
    from engine.chaincounts import GatherCounts
    rng = np.random.default_rng(4)
    n = 20000
    bounces = rng.integers(0, 5, (n, 4)).astype(np.uint8)
    bounces[::97] = pk.BOUNCE_SATURATED
    power = rng.random(n) * rng.random(n)
    lim = np.array([6, 4, 4, 4])
    keys = [(a, b, c, d) for a in range(1, 5) for b in range(1, a + 1) for c in (0, 1)
            for d in (0, 2)]

    def sums(level, key):
        nominal = pk.bounce_usable(bounces, lim, (level + 1, level + 1, 0, 0))
        ok = pk.bounce_usable(bounces, lim, key)
        return math.fsum(power[nominal & ~ok]), math.fsum(power[nominal])

    def by_photons(level, key, share):
        dropped, kept = sums(level, key)
        return dropped > share * kept

    g = GatherCounts(bounces, power, lim, 0.005)
    got = [g.drops(level, key) for level in (0, 1) for key in keys]
    assert got == [by_photons(level, key, 0.005) for level in (0, 1) for key in keys]
    assert 0 < sum(got) < len(got)
    key = (3, 2, 1, 0)
    dropped, kept = sums(0, key)
    ratio = dropped / kept
    for share in (ratio, np.nextafter(ratio, 0.0), np.nextafter(ratio, 1.0)):
        assert GatherCounts(bounces, power, lim, share).drops(0, key) == by_photons(
            0, key, share)
    assert GatherCounts(bounces, power, lim, np.nextafter(ratio, 0.0)).drops(0, key)
    assert not GatherCounts(bounces, power, lim, np.nextafter(ratio, 1.0)).drops(0, key)
    np.testing.assert_allclose(g.kept_share(0, key), 1.0 - ratio, rtol=1e-15)


def test_the_renders_gather_counts_decide_on_float64_powers(monkeypatch):
    """The render's GatherCounts decides on the gather photons' float64 powers (each a
    float64 sum of three float32 channels): at a share a little either side of a key's
    float64 ratio (1e-12 relative) its decisions are those of the float64 sums. It was
    given them rounded to float32 (hdri52), which moved that ratio by ~1e-8 relative
    and flipped one of the two (review53)."""
    import importlib
    import math
    from engine.api import cornell_box
    from engine.photons import CAUSTIC
    render_mod = importlib.import_module("engine.render")  # (engine.render: a function too)
    built = []
    real = render_mod._build_maps

    def record(ctx, shot, *args, **kwargs):
        built.append(shot)
        return real(ctx, shot, *args, **kwargs)
    monkeypatch.setattr(render_mod, "_build_maps", record)
    ctx = render_mod.prepare_context(cornell_box(16, 12), RenderSettings(
        photons=20_000, caustic_photons=2_000, seed=1, workers=1, max_bounces=3))
    try:
        render_mod.shoot_photons(ctx, {})
    finally:
        ctx.accel.close()
    g = ctx.gather_counts
    assert g is not None and len(built) == 1
    shot = built[0]
    rows = np.flatnonzero(shot.kind != CAUSTIC)
    power = shot.power.astype(np.float64).sum(axis=1)[rows]
    bounces = shot.bounces[rows]
    level, key = 0, (2, 2, 0, 0)
    nominal = pk.bounce_usable(bounces, g.limits, (level + 1, level + 1, 0, 0))
    ok = pk.bounce_usable(bounces, g.limits, key)
    ratio = math.fsum(power[nominal & ~ok]) / math.fsum(power[nominal])
    p32 = power.astype(np.float32).astype(np.float64)
    ratio32 = math.fsum(p32[nominal & ~ok]) / math.fsum(p32[nominal])
    assert 0.0 < ratio < 1.0 and abs(ratio32 / ratio - 1.0) > 1e-10  # (not vacuous)
    for scale, want in ((1.0 - 1e-12, True), (1.0 + 1e-12, False)):
        g.share = ratio * scale
        g._cache.clear()
        assert g.drops(level, key) == want, (scale, ratio, ratio32)


def _lit_through(surface: str, floor=None):
    """A floor lit only by way of one smooth surface: a point light above a flat glass
    pane (2 cm thick, a flat passage: shadow rays cross it, engine/shadowtransmittance.py)
    or below a mirror that faces down (the floor sees no light straight from it: a ring
    blocks it), the camera looking down at the floor under it. floor: its Material
    (named "floor"; None: diffuse 0.8 grey)."""
    s = PaperScene(width=16, height=12)
    s.add_material(floor or Material("floor", (0.8, 0.8, 0.8)))
    s.add_plane((0, 0, 0), normal=(0, 0, 1), size=6.0, material="floor", name="floor")
    if surface == "pane":
        s.add_material(Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=1.5))
        s.add_box((0, 0, 1.0), (3.0, 3.0, 0.02), "glass", name="pane")
        s.add_point_light((0, 0, 1.6), power=100.0)
    else:
        s.add_material(Material("mirror", (1, 1, 1), metallic=1.0, roughness=0.0))
        s.add_plane((0, 0, 3.0), normal=(0, 0, -1), size=3.0, material="mirror", name="m")
        # a black disc under the light: the floor sees the light only in the mirror
        s.add_material(Material("black", (0, 0, 0)))
        s.add_plane((0, 0, 1.95), normal=(0, 0, 1), size=0.4, material="black", name="cap")
        s.add_plane((0, 0, 1.95), normal=(0, 0, -1), size=0.4, material="black", name="cap2")
        s.add_point_light((0, 0, 2.0), power=100.0)
    s.set_camera((0, -0.4, 0.8), (0, 0, 0), view_angle=40)
    return s


def test_flat_passages_need_two_transmission_bounces_but_one_counted():
    """Light through a flat pane reaches the floor by shadow rays; Cycles reaches it by
    the floor's diffuse bounce and two refractions, the second of which hits the light
    (path_state_next: a count at the limit + 1 still collects the emission it meets). So
    the pane's light needs Transmission >= 1, Total >= 2 and Diffuse >= 1, and is whole
    there (live Cycles, 40 x 30: 0.0028 / 1.370 / 1.370 at Transmission 0 / 1 / 2, the
    mean of a floor lit through a pane; ours read 1.397 at all three). The caps are
    chaincounts.flat_passages: diffuse + 1 <= D, total + 2k <= T, transmission + 2k - 1
    <= Tr for k passages."""
    from engine.chaincounts import flat_passages
    lim = np.array([12, 4, 4, 12])
    assert flat_passages([[0, 0, 0, 0]], lim).tolist() == [6]
    assert flat_passages([[0, 0, 0, 0]], [12, 4, 4, 0]).tolist() == [0]
    assert flat_passages([[0, 0, 0, 0]], [12, 4, 4, 1]).tolist() == [1]
    assert flat_passages([[0, 0, 0, 0]], [1, 4, 4, 12]).tolist() == [0]
    assert flat_passages([[0, 0, 0, 0]], [2, 4, 4, 12]).tolist() == [1]
    assert flat_passages([[0, 0, 0, 0]], [12, 0, 4, 12]).tolist() == [0]
    assert flat_passages([[3, 3, 0, 1], [2, 1, 1, 0]], lim).tolist() == [4, 5]
    st = dict(photons=4000, caustic_photons=0, spp=2, seed=1, **HIGH)
    films = {}
    for key, extra in (("high", {}), ("t0", dict(transmission_bounces=0)),
                       ("t1", dict(transmission_bounces=1)), ("total1", dict(max_bounces=1)),
                       ("total2", dict(max_bounces=2)), ("d0", dict(diffuse_bounces=0))):
        films[key] = _lit_through("pane").render(RenderSettings(**dict(st, **extra))).direct
    assert films["high"].mean() > 0.5
    for key in ("t1", "total2"):
        np.testing.assert_array_equal(films[key], films["high"])
    for key in ("t0", "total1", "d0"):
        assert films[key].mean() < 0.01 * films["high"].mean(), key


def test_flat_passage_caps_count_the_hits_own_bounce_by_its_lobe():
    """The hit's own bounce before the passages counts as its lobe's kind (path_state_next's
    labels): a glossy lobe needs glossy + 1 <= Glossy, rough glass's refraction is a
    transmission bounce (transmission + 2k <= Transmission: it and all but the last of the
    pane's refractions within the limit); a diffuse lobe as before."""
    from engine.chaincounts import DIFFUSE, GLOSSY, TRANSMISSION, flat_passages
    lim = np.array([12, 4, 4, 12])
    zero = [[0, 0, 0, 0]]
    assert flat_passages(zero, lim, GLOSSY).tolist() == [6]
    assert flat_passages(zero, [12, 4, 0, 12], GLOSSY).tolist() == [0]
    assert flat_passages(zero, [12, 4, 1, 12], GLOSSY).tolist() == [6]
    assert flat_passages(zero, [12, 0, 1, 12], GLOSSY).tolist() == [6]
    assert flat_passages(zero, [12, 0, 1, 12], DIFFUSE).tolist() == [0]
    assert flat_passages([[2, 0, 1, 1]], [12, 4, 1, 12], GLOSSY).tolist() == [0]
    for t, k in ((0, 0), (1, 0), (2, 1), (3, 1), (4, 2)):
        assert flat_passages(zero, [12, 4, 4, t], TRANSMISSION).tolist() == [k], t
    assert flat_passages([[3, 1, 0, 2]], lim, TRANSMISSION).tolist() == [4]
    assert flat_passages([[3, 1, 0, 2]], [4, 4, 4, 12], TRANSMISSION).tolist() == [0]


def _glossy_floor_under_a_pane():
    """_lit_through("pane") with a glossy floor (Principled specular 1, roughness 0.3):
    its diffuse and glossy lobes both take the point light's shadow rays through the
    pane."""
    return _lit_through("pane", Material("floor", (0.5, 0.5, 0.5), specular=1.0,
                                         roughness=0.3))


def test_a_glossy_floors_lobes_take_the_panes_light_within_their_own_limits():
    """A glossy floor under a pane (a point light: shadow rays only): Cycles reaches the
    light through the pane by the floor's bounce, diffuse or glossy by the lobe it
    samples, so at Glossy 0 its glossy lobe has none of the pane's light and at Diffuse 0
    its diffuse lobe none; the two limits together split the image into its two lobes'
    parts (direct(high) = direct(Glossy 0) + direct(Diffuse 0), the same shadow rays).
    Before, the cap counted the hit's bounce as diffuse for both: Glossy 0 read the whole
    image and Diffuse 0 nothing."""
    st = dict(photons=2000, caustic_photons=0, spp=2, seed=1, indirect="off", **HIGH)
    films = {}
    for key, extra in (("high", {}), ("g0", dict(glossy_bounces=0)),
                       ("g1", dict(glossy_bounces=1)), ("d0", dict(diffuse_bounces=0)),
                       ("t0", dict(transmission_bounces=0))):
        scene = _glossy_floor_under_a_pane()
        films[key] = scene.render(RenderSettings(**dict(st, **extra))).direct
    high, g0, d0 = films["high"], films["g0"], films["d0"]
    assert high.mean() > 0.2
    np.testing.assert_array_equal(films["g1"], high)
    # each lobe a real share of the light (0.5 grey diffuse, specular 1 at roughness 0.3)
    assert 0.2 * high.mean() < g0.mean() < 0.95 * high.mean()
    assert 0.05 * high.mean() < d0.mean() < 0.8 * high.mean()
    np.testing.assert_allclose(g0 + d0, high, rtol=1e-6)  # (float32 films)
    assert films["t0"].mean() < 0.01 * high.mean()


def _rough_glass_under_a_pane():
    """A rough glass sheet (roughness 0.3, one plane: light entering it stays inside) seen
    from below, a flat pane above it and a point light above that: the camera's rough
    glass hits sample the light on the far side (engine/glasslight.py), their shadow
    rays crossing the pane."""
    s = PaperScene(width=16, height=12)
    s.add_material(Material("rough", (1, 1, 1), transmission=1.0, roughness=0.3, ior=1.5))
    s.add_plane((0, 0, 1.0), normal=(0, 0, -1), size=4.0, material="rough", name="sheet")
    s.add_material(Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=1.5))
    s.add_box((0, 0, 1.5), (3.0, 3.0, 0.02), "glass", name="pane")
    s.add_point_light((0, 0, 2.0), power=100.0)
    s.set_camera((0, -0.3, 0.2), (0, 0, 1.0), view_angle=40)
    return s


def test_rough_glass_light_samples_count_the_refraction_and_the_panes_two():
    """Rough glass samples the lights behind it (engine/glasslight.py); behind a pane
    Cycles finds that light by the glass's refraction (a transmission bounce) and the
    pane's two refractions, the last of which reaches the light: Transmission 2 reads it
    all, Transmission 1 and 0 none (the pane's entry is past the limit). Before, these
    shadow rays had no cap: all of it at every limit."""
    st = dict(photons=2000, caustic_photons=0, spp=2, seed=1, indirect="off", **HIGH)
    films = {}
    for key, extra in (("high", {}), ("t0", dict(transmission_bounces=0)),
                       ("t1", dict(transmission_bounces=1)),
                       ("t2", dict(transmission_bounces=2)), ("total2", dict(max_bounces=2)),
                       ("total1", dict(max_bounces=1))):
        films[key] = _rough_glass_under_a_pane().render(
            RenderSettings(**dict(st, **extra))).direct
    high = films["high"]
    assert high.mean() > 0.05
    for key in ("t2", "total2"):
        np.testing.assert_array_equal(films[key], high, err_msg=key)
    for key in ("t0", "t1", "total1"):
        assert films[key].mean() < 0.01 * high.mean(), key


def test_a_mirror_as_the_photons_first_scatter_is_the_light_vertex():
    """A floor lit only by way of a mirror (its caustic): Cycles reaches the light from
    the floor by its diffuse bounce and the mirror's, which hits the light; that glossy
    bounce is the light-sample vertex (a count at the limit + 1 still collects the
    emission), so Glossy 0 reads what Glossy 4 reads (live Cycles, 40 x 30 with an area
    light: 0.6486 at both, 0 at Total 0 or Diffuse 0; tests/blender/
    test_blender_bounces.py). The photon's first scatter counts toward Total only
    (photonkernels.B_TOTAL): the caustic stays at Glossy 0 and goes at Total 0 and
    Diffuse 0."""
    st = dict(photons=2000, caustic_photons=20000, spp=2, seed=1, indirect="off", **HIGH)
    films = {}
    for key, extra in (("high", {}), ("g0", dict(glossy_bounces=0)),
                       ("total1", dict(max_bounces=1)), ("total0", dict(max_bounces=0)),
                       ("d0", dict(diffuse_bounces=0))):
        films[key] = _lit_through("mirror").render(RenderSettings(**dict(st, **extra)))
    high = films["high"].caustic.mean()
    assert high > 0.02 and films["high"].direct.max() == 0.0
    for key in ("g0", "total1"):
        # (photons past a second mirror hit stop earlier: the same light within 1 %)
        assert abs(films[key].caustic.mean() / high - 1.0) < 0.01, key
    for key in ("total0", "d0"):
        assert films[key].caustic.max() == 0.0, key


def test_gather_counts_tell_the_lookups_that_drop_some_of_the_maps_photons():
    """GatherCounts.partial: the lookups whose counts drop any photon their level's map
    keeps (they read their usable photons alone at their gather point,
    chaincounts.subset_irradiance; tests/test_gather_level_subsets.py); reroute: those
    that drop more than the share of its power. Level 2's map (counts (3, 3, 0, 0))
    keeps the photons of <= 2 scatters at Total 5; a lookup after a glass ball keeps
    those of <= 1. Before gatherlevel44 the last level scaled the map by the whole map's
    kept share instead (a room with a mirror and a glass ball at Total 5 read 1.024x
    Cycles unscaled, 0.998x scaled: tests/blender/test_blender_bounces.py)."""
    from engine.chaincounts import GatherCounts
    rng = np.random.default_rng(5)
    n = 5000
    total = rng.integers(0, 4, n)
    bounces = np.zeros((n, 4), np.uint8)
    bounces[:, 0] = total
    bounces[:, 1] = np.maximum(total - 1, 0)
    power = rng.random(n)
    lim = np.array([5, 1024, 1024, 1024])
    g = GatherCounts(bounces, power, lim, 0.005)
    level = 2  # its map: counts (3, 3, 0, 0), photons of <= 2 scatters
    counts = np.array([[3, 3, 0, 0], [4, 3, 0, 1], [5, 3, 1, 1], [4, 3, 0, 1], [6, 3, 0, 3]])
    assert g.partial(level, counts).tolist() == [False, True, True, True, True]
    assert g.reroute(level, counts).tolist() == [False, True, True, True, True]
    # Dropping only a sliver of the power: partial, not rerouted.
    few = np.zeros((n, 4), np.uint8)
    few[:3, 0] = 2
    g2 = GatherCounts(few, np.ones(n), lim, 0.005)
    assert g2.partial(level, counts[:3]).tolist() == [False, True, True]
    assert g2.reroute(level, counts[:3]).tolist() == [False, False, False]
    assert not g2.partial(level, np.zeros((0, 4), np.int64)).size


def _floor_under_ior1_panes(k, transmission):
    """A grey floor (z = 0) whose indirect light comes from a grey ceiling (z = 1) lit by a
    point lamp (z = 0.7) through k smooth IOR 1 glass slabs (2 cm thick, centred at
    z = 0.1, 0.15, ...; 40 m wide: they span the floor's hemisphere but for ~1e-5 of its
    cosine-weighted rays) that bend nothing; an orthographic camera under them sees the
    floor. Returns the
    film's indirect (final gather) image at Transmission `transmission`, Max Bounces
    1024."""
    from engine.render import render
    from engine.scene import Camera
    s = PaperScene(8, 8)
    s.add_material(Material("grey", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "grey", name="floor")
    s.add_plane((0, 0, 1.0), (0, 0, -1), 8.0, "grey", name="ceiling")
    s.add_material(Material("pane", (1.0, 1.0, 1.0), transmission=1.0, roughness=0.0,
                            ior=1.0, node="glass"))
    for i in range(k):
        s.add_box((0, 0, 0.1 + 0.05 * i), (40.0, 40.0, 0.02), "pane", name=f"pane{i}")
    s.add_point_light((0, 0, 0.7), power=100.0)
    s.camera = Camera(position=(0, 0, 0.05), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=0.5)
    film = render(s, RenderSettings(spp=4, workers=1, seed=1, photons=20_000,
                                    caustic_photons=2_000, max_bounces=1024,
                                    diffuse_bounces=1024, glossy_bounces=1024,
                                    transmission_bounces=transmission))
    return film.indirect


def test_gather_chains_count_unbent_refractions_and_go_on_to_the_limits():
    """The floor's gather chains reach the ceiling after 2 k = 10 refractions of IOR 1,
    each a transmission bounce (Cycles' path_state_next counts the refraction lobe's ray
    whether it bends or not; the camera chain and the photons count it so too): at
    Transmission 9 the ceiling is past the limit (no indirect light: 0.0), at 10 it is
    within (0.66: the lamp's light on it), at 1024 it adds the light that came back to
    it through the slabs (0.82). Before glasswater51 the chains stopped after 8
    continuations of their own (dark at 10 and 1024: a glass of water read 4 % dark at
    Max Bounces 16-64) and counted an unbent refraction as no bounce."""
    dark = _floor_under_ior1_panes(5, 9)
    lit = _floor_under_ior1_panes(5, 10)
    high = _floor_under_ior1_panes(5, 1024)
    assert lit.mean() > 0.3, lit.mean()
    assert dark.mean() < 0.01 * lit.mean(), (dark.mean(), lit.mean())
    assert high.mean() > 1.1 * lit.mean(), (high.mean(), lit.mean())
