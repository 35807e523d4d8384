"""The regathered ends' secondary caustic from their lookups' gather points (regather29).

- GatherMap's secondary share (a mask of the map build's own estimate pass) is, bit for
  bit, the E of a map whose irradiance keeps that mask's photons alone, and the map's own
  E does not change with it; the shares of a mask and of its complement add up to E;
- GatherMap.lookup(points=True) names the point each row took: its E and flag are the
  row's (hidden candidates included), -1 where none was found, and the answers are those
  of a lookup without points;
- _secondary_irradiance takes the known rows as they are and estimates the others (NaN
  rows, and rows whose counts after a specular chain drop some of the map's photons)
  exactly as without them (the same random numbers);
- on the Cornell box with a glass ball, the gather points' secondary share and the
  secondary map's k-NN estimate at the same points agree in the mean.
"""
import copy
import os
import sys

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.integrator import (MAX_GATHER_LEVEL, _deeper, _point_secondary,
                               _secondary_irradiance)
from engine.photonmap import GatherMap
from engine.photons import CAUSTIC_DIFFUSE, Photons
from engine.render import _photon_pass, level_maps, prepare_context

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from helpers import hits_from_inside  # noqa: E402


def _two_planes(rng, n=30000):
    """A floor (z = 0, up) and a wall (x = 0, facing +x) meeting at a corner; a third of
    the photons CAUSTIC_DIFFUSE."""
    pos = np.r_[np.c_[rng.random((n, 2)), np.zeros(n)],
                np.c_[np.zeros(n // 2), rng.random((n // 2, 2))]].astype(np.float32)
    m = len(pos)
    nrm = np.r_[np.tile([0.0, 0.0, 1.0], (n, 1)),
                np.tile([1.0, 0.0, 0.0], (n // 2, 1))].astype(np.float32)
    d = rng.normal(size=(m, 3))
    dn = (d * nrm).sum(1)
    d -= (np.abs(dn) + dn + 0.05)[:, None] * nrm  # arriving from the front: d.n < 0
    d /= np.linalg.norm(d, axis=1)[:, None]
    kind = np.where(rng.random(m) < 1 / 3, CAUSTIC_DIFFUSE, 2).astype(np.uint8)
    return Photons(pos, rng.random((m, 3)).astype(np.float32), d.astype(np.float32), nrm,
                   kind)


def test_secondary_share_is_the_kept_maps_E_and_E_is_unchanged():
    rng = np.random.default_rng(3)
    ph = _two_planes(rng)
    sec = ph.kind == CAUSTIC_DIFFUSE
    args = (ph, 0.05, 32, 1, "knn_simpson")
    plain = GatherMap(*args, max_points=4000)
    g = GatherMap(*args, max_points=4000, secondary=[sec, ~sec])
    kept = GatherMap(*args, max_points=4000, keep=sec)
    assert np.array_equal(g.position, plain.position)
    assert np.array_equal(g.E, plain.E) and np.array_equal(g.boundary, plain.boundary)
    assert len(g.secondary_levels) == 2 and not plain.secondary_levels
    assert np.array_equal(g.secondary_levels[0], kept.E)
    # (float32 levels, each within 2^-24 of its float64 estimate, their float32 sum
    # rounded once more: within 3 x 2^-24 of E)
    np.testing.assert_allclose(g.secondary_levels[0] + g.secondary_levels[1], g.E,
                               rtol=2.0 ** -22, atol=1e-12)
    share = g.secondary_levels[0].sum() / g.E.sum()
    assert 0.25 < share < 0.42  # a third of the photons, their power uniform
    assert g.secondary_E is None  # set by the render, per level


@pytest.fixture(scope="module")
def box():
    ctx = prepare_context(cornell_box(32, 24, glass_sphere=True),
                          RenderSettings(workers=1, photons=30_000, caustic_photons=10_000,
                                         seed=2))
    _photon_pass(ctx, {}, None, None)
    yield ctx
    ctx.accel.close()


def test_lookup_points_name_the_taken_point(box):
    g = box.gather_map
    hit = hits_from_inside(box, 4000, seed=13)
    E, B = g.lookup(hit.p, hit.ng, offset=hit.offset)
    E2, B2, point = g.lookup(hit.p, hit.ng, offset=hit.offset, points=True)
    assert np.array_equal(E, E2) and np.array_equal(B, B2)
    found = point >= 0
    assert 0.5 < found.mean() < 1.0  # both kinds of rows
    assert np.array_equal(E[found], g.E[point[found]])
    assert np.array_equal(B[found], g.boundary[point[found]])
    assert not E[~found].any() and B[~found].all()
    near = np.linalg.norm(g.position[point[found]] - hit.p[found], axis=1)
    assert near.max() <= g.radius * (1 + 1e-6)
    # Without visibility rays each row takes its first candidate: rows whose first was
    # hidden took another (_next_visible / _pick_visible), or none.
    blind = copy.copy(g)
    blind.accel = None
    first = blind.lookup(hit.p, hit.ng, offset=hit.offset, points=True)[2]
    moved = (first >= 0) & (point != first)
    assert moved.any() and (point[moved] >= 0).any()


def test_render_sets_each_regathering_levels_secondary_share(box):
    ctx = box
    assert ctx.secondary_map is not None and len(ctx.secondary_map) > 100
    ctx.gather_map.complete()  # (every point's estimates: the arrays are read whole)
    for level in range(MAX_GATHER_LEVEL):
        gmap = _deeper(ctx.gather_map, ctx.regather_maps, level)
        assert gmap.secondary_E is not None and gmap.secondary_E.shape == gmap.E.shape
        assert (gmap.secondary_E >= 0).all() and (gmap.secondary_E <= gmap.E + 1e-9).all()


def test_known_rows_are_taken_and_the_others_estimated_as_before(box):
    ctx = box
    hit = hits_from_inside(ctx, 3000, seed=7)
    n = len(hit.p)
    rng = np.random.default_rng(0)
    known = rng.random((n, 3))
    known[rng.random(n) < 0.3] = np.nan
    have = ~np.isnan(known[:, 0])
    want = _secondary_irradiance(ctx, hit, np.random.default_rng(5), 1)
    got = _secondary_irradiance(ctx, hit, np.random.default_rng(5), 1, known=known)
    assert np.array_equal(got[have], known[have])
    assert np.array_equal(got[~have], want[~have])
    assert (want[~have] > 0).any()
    point = np.where(have, np.arange(n), -1)
    table = np.nan_to_num(known)
    np.testing.assert_array_equal(_point_secondary(table, point)[have], known[have])
    assert np.isnan(_point_secondary(table, point)[~have]).all()


def test_point_share_agrees_with_the_secondary_maps_estimate(box):
    """At the gather points, the secondary share of their own estimate and the secondary
    map's k-NN estimate (its own radius, photon visibility) of the same photons: the
    same light, so the same mean within the estimates' noise."""
    ctx = box
    g = ctx.gather_map.complete()  # (every point's estimates: read whole)
    s = ctx.settings
    from engine.photonvisibility import visible_irradiance
    from engine.integrator import smooth_min_photons
    free = ~g.boundary
    p, n = g.position[free], g.normal[free]
    E = visible_irradiance(ctx.regather_secondary[0], ctx.accel, p, n, None,
                           ctx.secondary_radius, s.k_nearest, smooth_min_photons(s),
                           s.estimator, limits=s.bounce_limits, geo=ctx.geo)
    share = g.secondary_E[free]
    assert E.sum() > 0
    ratio = share.sum() / E.sum()
    assert 0.85 < ratio < 1.15, ratio


def test_rows_whose_counts_drop_photons_are_estimated(box):
    """A row past a specular chain whose counts leave some of the secondary map's photons
    unusable takes the map's masked estimate, not its point's share; one whose counts
    keep them all takes the share."""
    ctx = box
    hit = hits_from_inside(ctx, 2000, seed=9)
    n = len(hit.p)
    pmap = ctx.regather_secondary[0]
    assert pmap.photons.bounces is not None
    extra = np.zeros((n, 4), np.int64)
    deep = np.arange(n) % 2 == 1
    extra[deep, 2] = 1  # one transmission bounce beyond the level's own
    extra[deep, 0] = int(ctx.settings.bounce_limits[0])  # the total limit: drops photons
    known = np.random.default_rng(1).random((n, 3))
    want = _secondary_irradiance(ctx, hit, np.random.default_rng(4), 1, extra)
    got = _secondary_irradiance(ctx, hit, np.random.default_rng(4), 1, extra, known)
    assert np.array_equal(got[~deep], known[~deep])
    assert np.array_equal(got[deep], want[deep])


def test_levels_that_share_a_map_share_its_secondary_share():
    """Limits no photon reaches: every level reads the level-0 map itself (no subset, no
    view) and its one secondary share serves every regathering level."""
    ctx = prepare_context(cornell_box(16, 12, glass_sphere=True),
                          RenderSettings(workers=1, photons=20_000, caustic_photons=5_000,
                                         seed=3, max_bounces=1024, diffuse_bounces=1024,
                                         glossy_bounces=1024, transmission_bounces=1024))
    try:
        _photon_pass(ctx, {}, None, None)
        g = ctx.gather_map.complete()  # (every point's estimates: read whole)
        assert all(m is g for m in ctx.regather_maps)
        assert g.secondary_E is not None and len(g.secondary_levels) == 1
        assert (g.secondary_E > 0).any()
    finally:
        ctx.accel.close()


def test_a_gather_map_of_caustic_photons_only_renders():
    """Every stored photon caustic-kind (a floor lit only through a rough Refraction BSDF
    sheet, which reflects nothing back): the global map has no point, so no secondary
    levels; the render indexed them anyway (IndexError) and now regathers as before.
    The floor is lit and finite. (Caustic Photons 0: the global shot carries the sheet's
    caustic photons; with a caustic shot they are aimed at it, effects.rough_refractors.)"""
    from engine.api import PaperScene
    from engine.scene import Material
    s = PaperScene(width=16, height=16)
    s.add_material(Material("frost", (1, 1, 1), transmission=1.0, roughness=0.6,
                            specular=1.0, node="refraction", ior=1.0001))
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 1.0), (0, 0, 1), 8, "frost", name="ceiling")
    s.add_plane((0, 0, 0), (0, 0, 1), 8, "grey", name="floor")
    s.add_sun(direction=(0, 0, -1), strength=2.0)
    s.set_camera((0, 0, 0.6), (0, 0, 0), up=(0, 1, 0), view_angle=60)
    film = s.render(RenderSettings(spp=2, photons=100_000, caustic_photons=0, seed=1))
    # (every stored photon is of the caustic kind)
    assert film.stats["caustic_photons"] == film.stats["global_photons"] > 0
    assert np.all(np.isfinite(film.combined))
    # Most of the sun's light reaches the floor through the index-matched sheet.
    assert film.combined.mean() > 0.5 * 0.5 / np.pi * 2.0


def test_a_map_without_points_serves_every_level():
    """A gather map of fewer than two non-caustic photons has no points, subset maps or
    secondary shares (GatherMap's early return): level_maps hands that map to every level
    and sets no share, where indexing its empty lists raised IndexError (feature case
    visibility_light_diffuse_off at seed 2: its shot held one caustic photon). With points
    the same call reads the subset maps and sets each level's share."""
    ph = _two_planes(np.random.default_rng(5), n=3000)
    sec = ph.kind == CAUSTIC_DIFFUSE
    level_of = [0] * MAX_GATHER_LEVEL          # every deeper level: subset map 0
    secondary_of = list(range(MAX_GATHER_LEVEL))  # a share of its own per level
    args = (ph, 0.05, 32, 1, "knn_simpson")
    kw = dict(subsets=[~sec], secondary=[sec] * MAX_GATHER_LEVEL)
    for rows in (np.zeros(0, np.int64), np.array([7])):
        g = GatherMap(*args, rows=rows, **kw)
        assert g.tree is None and not g.subset_maps and not g.secondary_levels
        maps = level_maps(g, level_of, secondary_of)
        assert len(maps) == MAX_GATHER_LEVEL and all(m is g for m in maps)
        assert g.secondary_E is None
        E, boundary, point = g.lookup(ph.position[:5].astype(np.float64),
                                      ph.normal[:5].astype(np.float64), points=True)
        assert not E.any() and boundary.all() and (point == -1).all()
    g = GatherMap(*args, max_points=400, **kw)
    maps = level_maps(g, level_of, secondary_of)
    assert all(m.E is g.subset_maps[0].E for m in maps)
    assert g.secondary_E is g.secondary_levels[0]
    for level in range(1, MAX_GATHER_LEVEL):
        assert maps[level - 1].secondary_E is g.secondary_levels[level]
