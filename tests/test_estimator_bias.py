"""Bias of the photon-map estimates (issue 4: fix blotches and dark corners at the estimator).

A uniform photon density on a plane has a known irradiance, so every estimate can be
checked against the exact value:
- the k-NN estimate counts the k nearest photons *of the query's surface*, so photons of a
  crowded neighbouring surface (a wall, an object resting on the floor) neither starve it
  nor darken it;
- the gather map's lookups are unbiased: points are a thinned share of the photons and
  their estimate comes from the other photons (no own-photon peak, no sparse-cell
  correlation), and a surface lit far more thinly than the brightest still has gather
  points within a lookup's reach;
- gather points whose estimate met another surface are flagged, so final gathering can
  gather again there;
- emissive meshes do not hit themselves when they emit photons.
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene, box_mesh
from engine.photonmap import GatherMap, PhotonMap, auto_radius
from engine.photons import Photons
from engine.render import _photon_pass, prepare_context
from engine.scene import Material

N = 200_000


def _plane(n, rng, z=0.0, normal=(0, 0, 1), size=1.0, power=1.0):
    """n photons uniform on a size x size square at height z, arriving against `normal`;
    total power `power` (irradiance = power / size^2)."""
    pos = np.c_[rng.random(n) * size, rng.random(n) * size, np.full(n, z)]
    nrm = np.tile(np.float32(normal), (n, 1))
    return Photons(pos.astype(np.float32), np.full((n, 3), power / n, np.float32),
                   -nrm, nrm, np.zeros(n, np.uint8))


def _wall(n, rng, x=0.5, power=1.0):
    """n photons on the wall x = const (facing -x), 0 <= z <= 0.2, spanning the square."""
    pos = np.c_[np.full(n, x), rng.random(n), rng.random(n) * 0.2]
    nrm = np.tile(np.float32([-1, 0, 0]), (n, 1))
    return Photons(pos.astype(np.float32), np.full((n, 3), power / n, np.float32),
                   -nrm, nrm, np.zeros(n, np.uint8))


def _join(a, b):
    return Photons(*(np.concatenate([getattr(a, f), getattr(b, f)])
                     for f in ("position", "power", "direction", "normal", "kind")))


def _interior(q, margin=0.1):
    return np.all((q[:, :2] > margin) & (q[:, :2] < 1 - margin), axis=1)


def test_knn_estimate_is_unbiased_on_a_uniform_plane():
    rng = np.random.default_rng(1)
    pm = PhotonMap(_plane(N, rng), workers=2)
    q = np.c_[rng.random(20000), rng.random(20000), np.zeros(20000)]
    n = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    E = pm.irradiance(q, n, 0.2, 64, 8, "knn_simpson")[:, 0]
    inner = _interior(q)
    assert abs(E[inner].mean() - 1.0) < 0.005, E[inner].mean()


@pytest.mark.parametrize("estimator", ["radius", "classic"])
def test_fixed_radius_estimates_stay_unbiased_with_more_photons_than_they_gather(estimator):
    """~25,000 photons in the radius, more than MAX_CLASSIC_K (4096) are gathered: the box
    kernel scales by all / gathered, the Simpson kernel narrows to the gathered photons'
    disc (scaling it read 1.8x: the nearest photons weigh most)."""
    rng = np.random.default_rng(4)
    pm = PhotonMap(_plane(N, rng), workers=2)
    q = np.c_[0.3 + 0.4 * rng.random(200), 0.3 + 0.4 * rng.random(200), np.zeros(200)]
    n = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    E = pm.irradiance(q, n, 0.2, 64, 8, estimator)[:, 0]
    assert abs(E.mean() - 1.0) < 0.02, E.mean()


def test_photons_of_a_crowded_neighbour_surface_do_not_starve_the_estimate():
    """A wall with 20x the floor's photon density stands across the floor. Floor points
    near its foot used to find mostly wall photons among their 64 nearest: too few floor
    photons left, the estimate zeroed by the minimum count (the dark contact umbra under
    the Figure 3 sphere). Now the query widens until it has 64 floor photons."""
    rng = np.random.default_rng(2)
    floor = _plane(N, rng)
    wall = _wall(N, rng, x=0.5, power=4.0)  # 200k photons on 0.2 m^2 (vs 200k on 1 m^2)
    # Floor points up to 2 k-NN radii from the wall's foot (r_64 ~ 0.01 on the floor).
    m = 4000
    gap = rng.uniform(0.0005, 0.02, m)
    q = np.c_[0.5 - gap, rng.uniform(0.2, 0.8, m), np.zeros(m)]
    n = np.tile([0.0, 0.0, 1.0], (m, 1))
    alone = PhotonMap(floor, workers=2).irradiance(q, n, 0.2, 64, 8, "knn_simpson")
    pm = PhotonMap(_join(floor, wall), workers=2)
    E, boundary = pm.irradiance(q, n, 0.2, 64, 8, "knn_simpson", return_boundary=True)
    # With the wall the query widens while fewer than 32 floor photons are among the
    # nearest; where 32-63 are, it uses the disc it has seen (unbiased, a little noisier).
    # Either way the floor's estimate does not depend on the wall.
    assert np.count_nonzero(E[:, 0] == 0) == 0
    assert abs(E[:, 0].mean() / alone[:, 0].mean() - 1) < 0.01
    assert np.median(np.abs(E[:, 0] / alone[:, 0] - 1)) < 0.1
    assert boundary[gap < 0.005].mean() > 0.95  # these estimates met the wall
    far = np.c_[rng.uniform(0.1, 0.3, m), rng.uniform(0.2, 0.8, m), np.zeros(m)]
    _, boundary_far = pm.irradiance(far, n, 0.2, 64, 8, "knn_simpson", return_boundary=True)
    assert boundary_far.mean() < 0.01


def test_gather_map_lookups_are_unbiased():
    """Lookups at uniform random points of a uniform plane average the exact irradiance.
    Estimating at the gather points from all photons was biased both ways: counting the
    point's own photon +4.8 % (k = 64), leaving it out -4 % (sparse patches have larger
    cells and lower estimates)."""
    rng = np.random.default_rng(3)
    g = GatherMap(_plane(N, rng), 0.2, 64, 8, "knn_simpson", workers=2)
    q = np.c_[rng.random(40000), rng.random(40000), np.zeros(40000)]
    E, boundary = g.lookup(q, np.tile([0.0, 0.0, 1.0], (len(q), 1)))
    inner = _interior(q)
    assert abs(E[inner, 0].mean() - 1.0) < 0.005, E[inner, 0].mean()
    # Inside the plane an estimate is flagged only when its photons happen to lie off to
    # one side (noise of the centroid test); near the open edges most are.
    assert boundary[inner].mean() < 0.02
    edge = q[:, 0] < 0.003
    assert boundary[edge].mean() > 0.9


def test_a_thinly_lit_surface_keeps_its_gather_points():
    """Half a plane lit 30x more thinly than the other half (the far side of a room lit
    through a slot, Figure 7 with a mirror floor): at the renderer's radius (from the
    photons' median spacing, set by the bright half) a lookup disc on the dim half holds
    ~8 photons. With every step-th photon as a gather point, 29 % of its lookups found no
    point and returned 0 (regathered, and dark after the last regather: that half of the
    room read 5 % dark against Cycles); points taken in proportion to sparseness
    (measured by independent probe photons), with the estimating photons weighted for
    it, leave ~4 % without (3 % of them a point whose disc held no photon) and the found
    ones unbiased."""
    rng = np.random.default_rng(11)
    n_bright = 400_000
    n_dim = n_bright // 30
    bright = _plane(n_bright, rng, power=0.5)
    bright.position[:, 0] *= 0.5                     # x in [0, 0.5): irradiance 1
    dim = _plane(n_dim, rng, power=0.5 * n_dim / n_bright)
    dim.position[:, 0] = 0.5 + 0.5 * dim.position[:, 0]  # x in [0.5, 1): 1 / 30
    photons = _join(bright, dim)
    radius = auto_radius(1.0, len(photons), 64, math.sqrt(2.0), photons.position)
    g = GatherMap(photons, radius, 64, 1, "knn_simpson", workers=2)
    m = 40000
    q = np.c_[rng.uniform(0.55, 0.95, m), rng.uniform(0.05, 0.95, m), np.zeros(m)]
    E, boundary = g.lookup(q, np.tile([0.0, 0.0, 1.0], (m, 1)))
    none = (E[:, 0] == 0) & boundary  # no point in reach, or a point that saw no photon
    assert none.mean() < 0.05, none.mean()
    assert 0.95 < E[:, 0].mean() * 30 < 1.03, E[:, 0].mean() * 30  # the 0s included
    assert abs(E[~none, 0].mean() * 30 - 1.0) < 0.03, E[~none, 0].mean() * 30
    # The bright half as before: unbiased, its points every step-th photon.
    qb = np.c_[rng.uniform(0.05, 0.45, m), rng.uniform(0.05, 0.95, m), np.zeros(m)]
    Eb, _ = g.lookup(qb, np.tile([0.0, 0.0, 1.0], (m, 1)))
    assert abs(Eb[:, 0].mean() - 1.0) < 0.005, Eb[:, 0].mean()


def _emitting_box(rho):
    s = PaperScene(width=8, height=8)
    s.add_material(Material("glow", (rho,) * 3, emission=(1.0,) * 3))
    v, f = box_mesh((0, 0, 0), 2.0)
    s.add_triangles(v, f, "glow", name="furnace_box")
    s.set_camera((0, -0.5, 0), (0, 1, 0.1), view_angle=90)
    return s


@pytest.mark.parametrize("rho", [0.5, 0.9])
def test_emissive_meshes_do_not_hit_themselves_and_the_photon_power_balances(rho):
    """In a closed room with walls emitting Le and reflecting rho, the irradiance is
    pi Le / (1 - rho) everywhere: the stored photon power per area must say so, and every
    photon must arrive on the inside. Emitted from the triangle itself, photons used to hit
    their own emitter from behind (a third of them) and leave the room."""
    # (every bounce: the balance below is the unlimited series)
    st = RenderSettings(photons=20000, caustic_photons=0, max_photon_depth=200, seed=4,
                        show_photons=True, workers=2, max_bounces=1024, diffuse_bounces=1024,
                        glossy_bounces=1024, transmission_bounces=1024)
    ctx = prepare_context(_emitting_box(rho), st)
    photons, caustic = _photon_pass(ctx, {}, None, None)  # the shots (global, caustic)
    ctx.accel.close()
    assert len(caustic) == 0  # caustic_photons=0: every photon is in the global shot
    p = photons.position.astype(np.float64) + ctx.geo.offset
    inward = np.einsum("ij,ij->i", photons.normal.astype(np.float64), -np.sign(p) * (np.abs(p) > 0.999))
    assert (inward > 0.99).all()
    area = 6 * 2.0 * 2.0
    E = photons.power[:, 0].astype(np.float64).sum() / area
    assert abs(E / (math.pi / (1 - rho)) - 1) < 0.03


def test_a_sparse_surface_next_to_a_dense_one_still_finds_its_gather_points():
    """The underside of a ball resting on a lit floor holds few gather points, and the
    floor's crowd them out of a lookup's 8 nearest: the lookup widens instead of returning
    0 (that made the contact umbra under the Figure 3 sphere 20 % dark). A point with no
    gather point of its own surface in range is flagged for gathering again."""
    rng = np.random.default_rng(5)
    floor = _plane(N, rng)
    wall = _wall(2000, rng, x=0.5, power=0.01)  # sparse: 100x fewer per area than the floor
    g = GatherMap(_join(floor, wall), 0.2, 16, 1, "knn_simpson", workers=2)
    q = np.c_[np.full(200, 0.5), rng.uniform(0.3, 0.7, 200), rng.uniform(0.0, 0.01, 200)]
    E, boundary = g.lookup(q, np.tile([-1.0, 0.0, 0.0], (200, 1)))
    assert (E[:, 0] > 0).mean() > 0.7  # 8 candidates alone found 0.4 of them
    assert ((E[:, 0] > 0) | boundary).all()  # the rest gather again
    lone = np.array([[0.5, 0.5, 0.05]])
    E, boundary = g.lookup(lone, np.array([[0.0, 1.0, 0.0]]))  # no surface faces +y here
    assert E.max() == 0.0 and boundary.all()


@pytest.mark.parametrize("n", [640, 6400])
def test_a_focus_is_spread_over_a_small_disc_and_keeps_its_power(n):
    """n photons piled into a 1 mm spot (a lens focusing a point light). The k-NN radius
    is floored at 1 % of the search radius: below that, the focus seen through a ball made
    one pixel of Figure 8 939x the image mean. All photons inside the floored disc count,
    so the estimate integrated over the plane is the photons' power (a review found the
    first version kept only k of them: 13 % and 1.3 % of the power)."""
    from engine.photonmap import MIN_RADIUS_FRACTION
    rng = np.random.default_rng(9)
    radius = 0.1
    pos = np.zeros((n, 3), np.float32)
    pos[:, :2] = (rng.random((n, 2)) - 0.5) * 0.001
    focus = Photons(pos, np.full((n, 3), 1.0 / n, np.float32),
                    np.tile(np.float32([0, 0, -1]), (n, 1)), np.tile(np.float32([0, 0, 1]), (n, 1)),
                    np.zeros(n, np.uint8))
    pm = PhotonMap(focus, workers=1)
    half, m = 3 * MIN_RADIUS_FRACTION * radius, 121
    g = np.linspace(-half, half, m)
    x, y = np.meshgrid(g, g)
    q = np.c_[x.ravel(), y.ravel(), np.zeros(m * m)]
    E = pm.irradiance(q, np.tile([0.0, 0.0, 1.0], (len(q), 1)), radius, 64, 8,
                      "knn_simpson")[:, 0]
    assert np.isfinite(E).all()
    total = E.sum() * (g[1] - g[0]) ** 2
    assert abs(total - 1.0) < 0.05, total
    # and spread: the peak is that of all the power over the floored disc, not a point's
    r = MIN_RADIUS_FRACTION * radius
    assert E.max() <= 3.0 / (math.pi * r * r) * 1.05
    # A camera sample's pixel footprint floors the radius too (wider disc, same power).
    foot = np.full(len(q), 2 * r)
    E2 = pm.irradiance(q, np.tile([0.0, 0.0, 1.0], (len(q), 1)), radius, 64, 8,
                       "knn_simpson", r_floor=foot)[:, 0]
    assert abs(E2.sum() * (g[1] - g[0]) ** 2 - 1.0) < 0.05
    assert E2.max() <= 1.0 / (math.pi * (2 * r) ** 2) * 1.05
