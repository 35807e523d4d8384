"""Photon-guided final-gather directions (engine/guiding.py, setting gather_guiding;
Jensen 1995): the mixture's warp and weights, the grids, and renders: the same mean as the
cosine gather (a closed room lit by a small spot patch; a closed furnace), less noise
there, deterministic for any worker count."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, box_mesh
from engine.guiding import CELLS, COLS, ROWS, GatherGuide, warp
from engine.photons import DIRECT, INDIRECT, Photons
from engine.sampling import orthonormal_basis
from engine.scene import Material


def _tables(rng, n):
    rp = rng.random((1, ROWS)) + 0.01
    rp /= rp.sum()
    cp = rng.random((1, ROWS, COLS)) + 0.01
    cp /= cp.sum(axis=-1, keepdims=True)
    return np.repeat(rp, n, 0), np.repeat(cp, n, 0)


def test_warp_samples_the_tables_density_and_weights_by_its_inverse():
    rng = np.random.default_rng(3)
    n = 400_000
    rp, cp = _tables(rng, n)
    u1, u2 = rng.random(n), rng.random(n)
    v1, v2, w = warp(u1, u2, rp, cp)
    assert v1.min() >= 0 and v1.max() < 1 and v2.min() >= 0 and v2.max() < 1
    # each cell gets its probability
    h, _, _ = np.histogram2d(v1, v2, bins=[ROWS, COLS], range=[[0, 1], [0, 1]])
    want = rp[0][:, None] * cp[0]
    np.testing.assert_allclose(h / n, want, atol=5 * np.sqrt(want.max() / n))
    # weight = 1 / q(u'), q = CELLS x the cell's probability
    cell_i = (v1 * ROWS).astype(int)
    cell_j = (v2 * COLS).astype(int)
    np.testing.assert_allclose(w, 1.0 / (CELLS * want[cell_i, cell_j]), rtol=1e-12)

    # an integral over the square: the weighted estimate has the plain one's mean
    def f(a, b):
        return np.sin(3 * a) + b ** 2 + 5.0 * (a > 0.8) * (b < 0.1)

    exact = (1 - np.cos(3.0)) / 3 + 1 / 3 + 5.0 * 0.2 * 0.1
    est = w * f(v1, v2)
    assert abs(est.mean() - exact) < 4 * est.std() / np.sqrt(n)


def test_warp_is_monotone_so_strata_stay_strata():
    rng = np.random.default_rng(4)
    rp, cp = _tables(rng, 1000)
    u = np.linspace(0, 1, 1000, endpoint=False)
    v1, _, _ = warp(u, np.full(1000, 0.3), rp, cp)
    assert np.all(np.diff(v1) >= 0)
    _, v2, _ = warp(np.full(1000, 0.3), u, rp, cp)
    assert np.all(np.diff(v2) >= 0)


def _photons(wi, normal, kind, n=200):
    d = -np.asarray(wi, np.float32)
    f32 = lambda a: np.ascontiguousarray(np.broadcast_to(np.asarray(a, np.float32), (n, 3)))
    rng = np.random.default_rng(0)
    pos = np.zeros((n, 3), np.float32)
    pos[:, :2] = rng.uniform(-0.05, 0.05, (n, 2))
    return Photons(pos, f32((1.0, 1.0, 1.0)), f32(d), f32(normal), np.full(n, kind, np.uint8))


def test_grid_puts_the_indirect_photons_flux_in_their_cell():
    """Photons arriving from one direction fill its cell: that cell's probability is
    (1 - share) / CELLS + share; DIRECT photons (light the shadow rays take) count nothing,
    nor do photons on a surface facing another way."""
    n = np.array([[0.0, 0.0, 1.0]])
    t, b = orthonormal_basis(n)
    theta, phi = np.radians(50.0), np.radians(100.0)
    wi = (np.sin(theta) * np.cos(phi) * t[0] + np.sin(theta) * np.sin(phi) * b[0]
          + np.cos(theta) * n[0])
    share = 0.6
    g = GatherGuide(np.zeros((1, 3)), n, _photons(wi, n[0], INDIRECT), radius=0.1,
                    share=share)
    row = int(np.sin(theta) ** 2 * ROWS)
    col = int(phi / (2 * np.pi) * COLS)
    prob = g.row_prob[0][:, None] * g.col_prob[0]
    assert prob[row, col] == pytest.approx((1 - share) / CELLS + share)
    others = np.delete(prob.ravel(), row * COLS + col)
    np.testing.assert_allclose(others, (1 - share) / CELLS)
    assert g.guided_points == 1
    for photons in (_photons(wi, n[0], DIRECT), _photons(wi, (0.0, 1.0, 0.0), INDIRECT)):
        g = GatherGuide(np.zeros((1, 3)), n, photons, radius=0.1, share=share)
        np.testing.assert_allclose(g.row_prob[0][:, None] * g.col_prob[0], 1.0 / CELLS)
        assert g.guided_points == 0
    # a hit takes the point only facing its way and within reach
    g = GatherGuide(np.zeros((1, 3)), n, _photons(wi, n[0], INDIRECT), radius=0.1)
    p = np.array([[0.01, 0.0, 0.0], [0.01, 0.0, 0.0], [5.0, 0.0, 0.0]])
    ns = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(g.points_for(p, ns), [0, -1, -1])


def test_flux_grid_points_at_a_lit_patch():
    """source="flux": the stored photons as small emitters; a point under a lit patch
    (facing it) puts the patch's form factor in the patch's cell, the rest nothing (the
    mixture's floor); a patch behind the point (facing away) counts nothing."""
    n = np.array([[0.0, 0.0, -1.0]])  # a ceiling point at the origin, facing down
    rng = np.random.default_rng(1)
    k = 400
    pos = np.zeros((k, 3), np.float32)
    pos[:, :2] = rng.uniform(-0.05, 0.05, (k, 2)) + [0.8, 0.3]
    pos[:, 2] = -1.0  # a floor patch 1 m below, lit (its photons face up)
    f32 = lambda a: np.ascontiguousarray(np.broadcast_to(np.asarray(a, np.float32), (k, 3)))
    photons = Photons(pos, f32((1.0, 1.0, 1.0)), f32((0.0, 0.0, -1.0)), f32((0.0, 0.0, 1.0)),
                      np.full(k, DIRECT, np.uint8))
    g = GatherGuide(np.zeros((1, 3)), n, photons, radius=0.05, share=0.5, source="flux",
                    emitters=64)
    prob = g.row_prob[0][:, None] * g.col_prob[0]
    t, b = orthonormal_basis(n)
    v = np.array([0.8, 0.3, -1.0]) / np.linalg.norm([0.8, 0.3, -1.0])
    l0, l1 = v @ t[0], v @ b[0]
    row = int((l0 * l0 + l1 * l1) * ROWS)
    col = int((np.arctan2(l1, l0) / (2 * np.pi) % 1.0) * COLS)
    assert prob[row, col] == pytest.approx(0.5 / CELLS + 0.5)
    photons.normal[:] = (0.0, 0.0, -1.0)  # the patch faces away from the point
    g = GatherGuide(np.zeros((1, 3)), n, photons, radius=0.05, source="flux", emitters=64)
    np.testing.assert_allclose(g.row_prob[0][:, None] * g.col_prob[0], 1.0 / CELLS)


def _patch_room(size=24, **st):
    """A closed grey room (albedo 0.6) lit only by a narrow spot on a small floor patch:
    the walls and ceiling the camera sees take nearly all their light from that patch."""
    s = PaperScene(width=size, height=size)
    s.add_material(Material("wall", (0.6,) * 3))
    v, f = box_mesh((0, 0, 0), 2.0)
    s.add_triangles(v, f, "wall", name="room")
    s.add_spot_light((0.5, 0.5, 0.9), (0.5, 0.5, -1.0), power=200.0, spot_size_degrees=15.0,
                     blend=0.0)
    s.set_camera((0, -0.9, -0.2), (0, 1, 0.6), view_angle=80)
    d = dict(photons=20_000, caustic_photons=0, spp=8, seed=1, workers=1)
    d.update(st)
    return s.render(RenderSettings(**d))


def _indirect(film):
    return np.asarray(film.passes()["indirect"], np.float64)[..., :3].mean(axis=-1)


@pytest.mark.parametrize("source", ["indirect", "flux"])
def test_guided_gather_has_the_plain_gathers_mean_and_less_noise(source):
    """Paired over seeds (the same photon maps): the guided and cosine gathers' mean
    indirect light agree within 3 standard errors; the guided per-pixel spread across
    seeds is well below the cosine one's (measured 0.32 / 0.32 (indirect / flux) against
    0.67 of the mean at 32 x 32, 16 spp, 8 seeds)."""
    seeds = range(1, 9)
    plain = np.array([_indirect(_patch_room(seed=s, gather_guiding=False))
                      for s in seeds])
    guided = np.array([_indirect(_patch_room(seed=s, gather_guiding=True,
                                             gather_guide_source=source)) for s in seeds])
    d = guided.mean(axis=(1, 2)) - plain.mean(axis=(1, 2))
    se = d.std(ddof=1) / np.sqrt(len(d))
    assert abs(d.mean()) < 3 * se + 1e-4 * plain.mean(), (d.mean(), se)
    noise_plain = plain.std(axis=0).mean() / plain.mean()
    noise_guided = guided.std(axis=0).mean() / guided.mean()
    assert noise_guided < 0.7 * noise_plain, (noise_guided, noise_plain)


@pytest.mark.parametrize("rho", [0.5])
def test_guided_furnace_reads_the_geometric_series(rho):
    """A closed box whose walls emit Le and reflect rho: radiance Le / (1 - rho)
    everywhere (tests/test_furnace.py's set-up), with guided gather rays."""
    s = PaperScene(width=24, height=24)
    s.add_material(Material("glow", (rho,) * 3, emission=(1.0,) * 3))
    v, f = box_mesh((0, 0, 0), 2.0)
    s.add_triangles(v, f, "glow", name="furnace_box")
    s.set_camera((0, -0.5, 0), (0, 1, 0.1), view_angle=90)
    film = s.render(RenderSettings(
        photons=40_000, caustic_photons=0, spp=16, max_photon_depth=200, seed=1,
        light_samples=16, max_bounces=1024, diffuse_bounces=1024, glossy_bounces=1024,
        transmission_bounces=1024, gather_guiding=True))
    c = np.asarray(film.combined, np.float64)[..., :3]
    assert abs(c.mean() * (1 - rho) - 1.0) < 0.01, c.mean()


def test_guided_gather_is_deterministic_for_any_worker_count():
    a = np.asarray(_patch_room(size=16, gather_guiding=True, workers=1).combined)
    b = np.asarray(_patch_room(size=16, gather_guiding=True, workers=1).combined)
    c = np.asarray(_patch_room(size=16, gather_guiding=True, workers=2).combined)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)
    plain = np.asarray(_patch_room(size=16, workers=1, gather_guiding=False).combined)
    assert not np.array_equal(a, plain)  # the setting changes the rays


@pytest.mark.parametrize("share", [-0.1, 1.0, "half", True])
def test_guide_share_out_of_range_is_refused(share):
    with pytest.raises(ValueError, match="gather_guide_share"):
        RenderSettings(gather_guide_share=share)


def test_guide_source_and_share_one_are_refused():
    with pytest.raises(ValueError, match="gather_guide_source"):
        RenderSettings(gather_guide_source="paths")
    with pytest.raises(ValueError, match="share"):  # q = 0 in a cell without flux
        GatherGuide(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), None, 1.0,
                            share=1.0)


def test_guided_gather_with_specular_chains():
    """A smooth metal ball and a glossy one in the patch room: the gathers after the
    camera's mirror and glossy chains run guided too; the image mean agrees with the
    cosine gather's (paired seeds, 4 standard errors)."""
    def room(seed, **st):
        s = PaperScene(width=16, height=16)
        s.add_material(Material("wall", (0.6,) * 3))
        s.add_material(Material("chrome", (0.9,) * 3, metallic=1.0, roughness=0.0))
        s.add_material(Material("satin", (0.9,) * 3, metallic=1.0, roughness=0.3))
        v, f = box_mesh((0, 0, 0), 2.0)
        s.add_triangles(v, f, "wall", name="room")
        s.add_sphere((-0.3, 0.2, -0.6), 0.35, "chrome", name="chrome_ball")
        s.add_sphere((0.4, 0.3, -0.7), 0.3, "satin", name="satin_ball")
        s.add_spot_light((0.5, 0.5, 0.9), (0.5, 0.5, -1.0), power=200.0,
                         spot_size_degrees=15.0, blend=0.0)
        s.set_camera((0, -0.9, -0.2), (0, 1, -0.3), view_angle=80)
        return np.asarray(s.render(RenderSettings(photons=20_000, caustic_photons=2000,
                                                  spp=8, seed=seed, workers=1, **st))
                          .combined, np.float64)[..., :3].mean()
    d = np.array([room(s, gather_guiding=True) - room(s, gather_guiding=False)
                  for s in range(1, 7)])
    assert np.isfinite(d).all()
    assert abs(d.mean()) < 4 * d.std(ddof=1) / np.sqrt(len(d)) + 1e-4, d
