"""The surface test of the photon estimates (engine/samesurface.py, issue 14, surfaceid32):
each stored photon keeps its object (Photons.surface) and an estimate accepts another
object's photons only where they continue the query's plane.

- the rule itself, against exact cases;
- a floor of coplanar tiles reads across its seams exactly as one floor (the same bits
  as the normal test alone) and its density there;
- a fold inside one object, and a wall standing on a floor as another object, read what
  they read before (the same bits);
- a ramp (45 degrees: the normal test accepts its photons at the floor) no longer lends
  the floor its photons;
- the gather map's points estimate and are looked up on their own surface;
- traced photons carry the object id of the triangle they lie on, an instance's own.
(The small ball on a floor: tests/test_sparse_caustic.py.)
"""
import math

import numpy as np
import pytest

from engine import samesurface
from engine.photonmap import GatherMap, PhotonMap
from engine.photons import Photons

P = 1e-3
K = 64
CAP = 0.25
UP = (0.0, 0.0, 1.0)


def _plane(rng, density, origin, u, v, su, sv, normal, surface):
    n = rng.poisson(density * su * sv)
    a, b = rng.uniform(0, su, n), rng.uniform(0, sv, n)
    pos = np.asarray(origin) + a[:, None] * np.asarray(u) + b[:, None] * np.asarray(v)
    nrm = np.tile(np.asarray(normal, np.float32), (n, 1))
    return Photons(pos.astype(np.float32), np.full((n, 3), P, np.float32), -nrm, nrm,
                   np.zeros(n, np.uint8), n, surface=np.full(n, surface, np.int32))


def _joined(parts):
    return Photons(*(np.concatenate([getattr(p, f) for p in parts])
                     for f in ("position", "power", "direction", "normal", "kind")),
                   sum(len(p) for p in parts),
                   surface=np.concatenate([p.surface for p in parts]))


def _rule(pos, normal, surface, j, qs, q, n):
    return samesurface.same_surface(np.asarray(surface, np.int32),
                                    np.asarray(pos, np.float32),
                                    np.asarray(normal, np.float32), j, qs, *map(float, q),
                                    *map(float, n))


def test_the_rule_accepts_the_own_object_and_a_coplanar_other_only():
    pos = [[0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.0, 0.01], [0.1, 0.0, 0.0]]
    t = math.radians(2.0)
    nrm = [UP, UP, UP, [math.sin(t), 0.0, math.cos(t)]]
    surf = [3, 4, 4, 4]
    q, n = (0.0, 0.0, 0.0), UP
    assert _rule(pos, nrm, surf, 0, 3, q, n)        # its own object
    assert _rule(pos, nrm, surf, 1, 3, q, n)        # another, in the query's plane
    assert not _rule(pos, nrm, surf, 2, 3, q, n)    # another, 1 cm above it at 10 cm
    assert not _rule(pos, nrm, surf, 3, 3, q, n)    # another, tilted by 2 degrees
    assert _rule(pos, nrm, surf, 2, -1, q, n)       # the query's surface unknown
    assert _rule(pos, nrm, [], 2, 3, q, n)          # the photons' surfaces unknown
    assert _rule(pos, nrm, [3, 4, -1, 4], 2, 3, q, n)  # this photon's unknown
    # Within 1 degree of the plane seen from the query (0.0017 m at 0.1 m): coplanar.
    assert _rule([[0.1, 0.0, 0.0015]], [UP], [4], 0, 3, q, n)
    assert not _rule([[0.1, 0.0, 0.0020]], [UP], [4], 0, 3, q, n)


def test_the_estimates_branchless_test_is_the_rule():
    """photonmap._accepted (the per-photon test of the k-NN rows and the precomputed
    cache, written without branches) flags another surface exactly where the normal test
    or samesurface.same_surface does: random photons near coplanar, tilted and offset
    planes of several objects, queries of known and unknown surface."""
    from engine.photonmap import NORMAL_AGREEMENT, _accepted
    rng = np.random.default_rng(3)
    n = 4000
    pos = np.c_[rng.uniform(-0.3, 0.3, (n, 2)), rng.normal(0, 0.004, n)].astype(np.float32)
    pos[::3, 2] = 0.0  # exactly in the query's plane
    tilt = np.radians(rng.choice([0.0, 0.5, 2.0, 70.0], n))
    nrm = np.c_[np.sin(tilt), np.zeros(n), np.cos(tilt)].astype(np.float32)
    surf = rng.integers(-1, 3, n).astype(np.int32)
    d = -nrm
    kinds = set()
    for qs in (-1, 0, 1):
        q = (0.01, -0.02, 0.0)
        nq = np.float32(0.0), np.float32(0.0), np.float32(1.0)
        for j in range(n):
            ok, other = _accepted(d, nrm, surf, pos, j, *nq, qs, *q)
            facing = float(nrm[j] @ np.float32([0, 0, 1])) > NORMAL_AGREEMENT
            same = samesurface.same_surface(surf, pos, nrm, j, qs, *q, *map(float, nq))
            assert other == (not facing or not same), (qs, j)
            assert ok == (facing and same)
            if facing and qs >= 0 and surf[j] >= 0 and surf[j] != qs:
                kinds.add(bool(same))
    assert kinds == {True, False}  # another object's photons both accepted and not


@pytest.mark.parametrize("tiles", [2, 4])
def test_a_floor_of_coplanar_tiles_reads_as_one_floor_across_its_seams(tiles):
    """Two tiles (x < 0, x >= 0) or four (quadrants), each its own object, uniform
    photons: the estimates are the normal test's bits everywhere (a coplanar photon is
    accepted), so a query at a seam reads a whole disc, not the ~0.5 of its own tile's
    half disc (the "object" column of bench/bench_same_surface.py: 0.68 / 0.58 within
    5 cm of the seam), and the seam reads the density within 3 %."""
    rng = np.random.default_rng(30 + tiles)
    density = 100 / (math.pi * CAP * CAP)
    h = 1.5
    corners = ([(-h, -h, 2 * h), (0, -h, 2 * h)] if tiles == 2 else
               [(-h, -h, h), (0, -h, h), (-h, 0, h), (0, 0, h)])
    parts = [_plane(rng, density, (x0, y0, 0.0), (1, 0, 0), (0, 1, 0), h, sv, UP, i)
             for i, (x0, y0, sv) in enumerate(corners)]
    ph = _joined(parts)
    m = 3000
    q = np.c_[rng.uniform(-0.05, 0.05, m), rng.uniform(-1.0, 1.0, m), np.zeros(m)]
    if tiles == 4:
        q[m // 2:, :2] = q[m // 2:, 1::-1]  # half of them on the other seam
    qs = (q[:, 0] >= 0).astype(np.int32)
    if tiles == 4:
        qs += 2 * (q[:, 1] >= 0)
    qn = np.tile(UP, (m, 1))
    pm = PhotonMap(ph)
    E, b = pm.irradiance(q, qn, CAP, K, 1, "knn_simpson", True, surface=qs)
    E0, b0 = pm.irradiance(q, qn, CAP, K, 1, "knn_simpson", True)
    assert np.array_equal(E, E0) and np.array_equal(b, b0)
    assert abs(E[:, 0].mean() / (density * P) - 1) < 0.03, E[:, 0].mean() / (density * P)
    assert b.mean() < 0.05  # a seam is no boundary


def _fold(rng, angle_deg, same_object):
    """A floor z = 0 over x >= 0 and a plane rising from the y axis at angle_deg over
    x < 0, its normal towards the floor's side (90: a wall), uniform photons on both."""
    density = 100 / (math.pi * CAP * CAP)
    t = math.radians(angle_deg)
    floor = _plane(rng, density, (0, -1.5, 0), (1, 0, 0), (0, 1, 0), 1.5, 3.0, UP, 0)
    other = _plane(rng, density, (0, -1.5, 0), (-math.cos(t), 0, math.sin(t)), (0, 1, 0),
                   1.5, 3.0, (math.sin(t), 0, math.cos(t)), 0 if same_object else 1)
    m = 3000
    q = np.c_[rng.uniform(0.0, 0.3, m), rng.uniform(-1.0, 1.0, m), np.zeros(m)]
    return _joined([floor, other]), q, np.tile(UP, (m, 1)), density


@pytest.mark.parametrize("angle,same_object", [(90.0, True), (45.0, True), (90.0, False)])
def test_a_fold_of_one_object_and_a_wall_on_a_floor_read_as_before(angle, same_object):
    """A box's inside corner (one object, 90 degrees), a 45-degree fold of one object, and
    a wall standing on a floor as another object: the surface test changes nothing there
    (one object: the normal test alone; a wall faces 90 degrees away: the normal test
    rejects it already), the same bits as without surfaces."""
    rng = np.random.default_rng(int(angle) + same_object)
    ph, q, qn, _ = _fold(rng, angle, same_object)
    pm = PhotonMap(ph)
    a = pm.irradiance(q, qn, CAP, K, 1, "knn_simpson", True,
                      surface=np.zeros(len(q), np.int32))
    b = pm.irradiance(q, qn, CAP, K, 1, "knn_simpson", True)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_a_ramp_of_another_object_lends_the_floor_no_photons():
    """A 45-degree ramp standing on a floor as another object: its photons face within
    60 degrees of the floor's normal and the normal test accepted them at floor queries
    near the fold (more photons in each disc than the floor's own: 1.10 of the floor's
    density within 5 cm of the fold, never flagged). With surfaces the floor's estimates
    read the floor's photons alone, as a map of those alone does (an open edge: 0.69
    there, the floor's half disc), and those rows are flagged as boundary (another
    surface's photons inside the disc: the gather map's lookups there gather again).
    The price of telling a ball resting on a floor from a fold: a local test cannot
    (docs/accuracy.md caustic31)."""
    rng = np.random.default_rng(45)
    ph, q, qn, density = _fold(rng, 45.0, False)
    qs = np.zeros(len(q), np.int32)
    E, b = PhotonMap(ph).irradiance(q, qn, CAP, K, 1, "knn_simpson", True, surface=qs)
    E0, b0 = PhotonMap(ph).irradiance(q, qn, CAP, K, 1, "knn_simpson", True)
    Ef = PhotonMap(ph.select(ph.surface == 0)).irradiance(q, qn, CAP, K, 1, "knn_simpson")
    near = q[:, 0] < 0.05
    assert abs(E[near, 0].mean() / Ef[near, 0].mean() - 1) < 0.05
    assert E0[near, 0].mean() > 1.3 * E[near, 0].mean()  # before: the ramp's counted in
    assert b[near].all() and not b0[near].any()
    far = q[:, 0] > 0.25  # beyond the cap: the same bits
    assert np.array_equal(E[far], E0[far])


def test_the_gather_map_points_and_lookups_keep_to_their_surface():
    """25 balls of 5 cm on a floor lit 2x more densely, a gather map of radius 0.25 m:
    each ball point's own estimate counted the floor's photons (they pass the normal test
    under the ball's upper half): lookups near the balls' tops read 0.80 of the ball's
    density. With surfaces the points estimate from their own surface and a lookup takes
    a point on its own: 0.96 (measured), the rare row without one (0.5 %) flagged as
    boundary (it gathers again); the floor's lookups beside the balls read the floor's."""
    rng = np.random.default_rng(7)
    radius = 0.05
    count = 25
    side = 5
    g = np.arange(count)
    centres = np.c_[(g % side) * 1.0, (g // side) * 1.0, np.full(count, radius)]
    ball_density = 40 / (math.pi * radius * radius)
    m = rng.poisson(ball_density * 4 * math.pi * radius * radius, count)
    u = rng.normal(size=(m.sum(), 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    nb = len(u)
    balls = Photons((np.repeat(centres, m, axis=0) + radius * u).astype(np.float32),
                    np.full((nb, 3), P, np.float32), -u.astype(np.float32),
                    u.astype(np.float32), np.zeros(nb, np.uint8), nb,
                    surface=np.repeat(1 + g, m).astype(np.int32))
    floor_density = 2 * ball_density
    floor = _plane(rng, floor_density, (-0.5, -0.5, 0), (1, 0, 0), (0, 1, 0), side, side,
                   UP, 0)
    ph = _joined([balls, floor])
    gm = GatherMap(ph, CAP, K, 1, "knn_simpson")
    gm0 = GatherMap(Photons(ph.position, ph.power, ph.direction, ph.normal, ph.kind,
                            ph.emitted), CAP, K, 1, "knn_simpson")
    assert len(gm.surface) == len(gm.position) and not len(gm0.surface)
    per = 32
    qu = rng.normal(size=(count * per, 3))
    qu[:, 2] = np.abs(qu[:, 2]) + 2.0  # near the top
    qu /= np.linalg.norm(qu, axis=1)[:, None]
    q = np.repeat(centres, per, axis=0) + radius * qu
    qs = np.repeat(1 + g, per).astype(np.int32)
    E, b, pt = gm.lookup(q, qu, surface=qs, points=True)
    found = pt >= 0
    assert found.mean() > 0.98 and b[~found].all()
    assert np.array_equal(gm.surface[pt[found]], qs[found])
    assert abs(E[found, 0].mean() / (ball_density * P) - 1) < 0.06, \
        E[found, 0].mean() / (ball_density * P)
    E0, _ = gm0.lookup(q, qu)
    assert E0[:, 0].mean() / (ball_density * P) < 0.85  # before
    a = rng.uniform(0, 2 * math.pi, count * 8)
    r = rng.uniform(radius, 0.15, count * 8)
    c = np.repeat(centres, 8, axis=0)
    qf = np.c_[c[:, 0] + r * np.cos(a), c[:, 1] + r * np.sin(a), np.zeros(len(c))]
    Ef, _ = gm.lookup(qf, np.tile(UP, (len(qf), 1)), surface=np.zeros(len(qf), np.int32))
    assert abs(Ef[:, 0].mean() / (floor_density * P) - 1) < 0.05, \
        Ef[:, 0].mean() / (floor_density * P)


def test_traced_photons_carry_their_object_an_instance_its_own(monkeypatch):
    """Photons traced in a scene of a floor and 9 instances of one sphere mesh (traced
    two-level): every stored photon's surface is the object id of the object it lies on:
    the floor's on the floor, each instance's own (9 distinct ids) on its sphere."""
    from engine import resources
    from engine.photons import trace_photons
    from engine.lights import allocate_photons
    from engine.render import prepare_context
    from engine import RenderSettings
    from test_instancing import _matrices, _scene
    monkeypatch.setattr(resources, "INSTANCE_BUDGET_FRACTION", 0.0)
    s = _scene()
    ctx = prepare_context(s, RenderSettings(spp=1, photons=20000, seed=3))
    assert ctx.accel.two_level
    ph = trace_photons(ctx, ctx.lights, allocate_photons(ctx.lights, 20000), False, 1)
    assert ph.surface is not None and ph.surface.dtype == np.int32
    assert len(ph.surface) == len(ph) > 1000
    names = ctx.geo.object_names
    world = ph.position.astype(np.float64) + ctx.geo.offset
    on_floor = np.abs(world[:, 2] + 0.5) < 1e-4
    assert on_floor.any()
    assert {names[i] for i in np.unique(ph.surface[on_floor])} == {"floor"}
    seen = set()
    for i, M in enumerate(_matrices(9)):
        local = (world - M[:3, 3]) @ np.linalg.inv(M[:3, :3]).T
        on = np.abs(np.linalg.norm(local, axis=1) - 1.0) < 0.02
        if not on.any():
            continue
        ids = np.unique(ph.surface[on & ~on_floor])
        assert [names[j] for j in ids] == [f"ball.{i:03d}"], (i, ids)
        seen.add(int(ids[0]))
    assert len(seen) >= 6
