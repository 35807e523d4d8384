"""No light leaks out of a closed lamp shade whose rim pierces a wall (issue 14).

A new user's Point light inside a closed metal cone whose bottom rim goes 5 cm into the
back wall (intersecting geometry, everyday modelling) painted a bright blob on the wall
outside the shade: image max 4.27 against Cycles' 1.22 (80x60; with the rim clear of the
wall 1.197 vs 1.190). The blob was the caustic map: photons light -> shade interior ->
the patch of wall inside the shade, gathered by wall points outside it, across the rim
(docs/performance.md, "leak"; engine/photonvisibility.py).

The invariant: with the lamp the only light, nothing the camera sees outside the closed
shade receives any light, so every pass of the film reads exactly 0, although the photon
pass stores caustic photons on the wall inside the shade, within a search radius of the
wall the camera sees.
"""
import numpy as np

from engine import RenderSettings, integrator
from engine.api import PaperScene
from engine.render import prepare_context, render, shoot_photons
from engine.scene import Material

SHADE_Y = 1.75          # the shade's axis (vertical), m; the wall's front face is at y = 2
SHADE_Z = (1.45, 1.75)  # its bottom and top; bottom radius 0.3 (rim 5 cm into the wall)
R_BOTTOM, R_TOP = 0.3, 0.12


def cone_mesh(center, r1, r2, depth, n=32):
    """(vertices (2n,3), faces) of a closed cone along +z like Blender's
    primitive_cone_add: bottom radius r1, top r2, both ends closed by fans (its NGON caps
    triangulated), faces wound outwards."""
    cx, cy, cz = center
    a = np.arange(n) * 2 * np.pi / n
    ring = np.stack([np.cos(a), np.sin(a)], 1)
    bot = np.column_stack([cx + r1 * ring[:, 0], cy + r1 * ring[:, 1], np.full(n, cz - depth / 2)])
    top = np.column_stack([cx + r2 * ring[:, 0], cy + r2 * ring[:, 1], np.full(n, cz + depth / 2)])
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i)]
    for i in range(1, n - 1):
        faces += [(0, i + 1, i), (n, n + i, n + i + 1)]
    return np.concatenate([bot, top]), np.array(faces)


def lamp_scene(width=80, height=60):
    """issue 14's repro (/tmp/newuser23/repro_leak.py, a one-off script) without its sun: floor, a 10 cm
    back wall (front face y = 2), a closed glossy metal shade piercing it, a 60 W Point
    light of radius 5 cm inside, the camera in front."""
    s = PaperScene(width=width, height=height)
    s.add_material(Material("plaster", (0.8, 0.78, 0.72), roughness=0.9, specular=1.0))
    s.add_material(Material("metal", (0.9, 0.6, 0.3), metallic=1.0, roughness=0.4))
    s.add_plane((0, 0, 0), (0, 0, 1), size=4, material="plaster", name="floor")
    s.add_box((0, 2.05, 1.35), (4, 0.1, 2.7), "plaster", name="wall")
    v, f = cone_mesh((0, SHADE_Y, sum(SHADE_Z) / 2), R_BOTTOM, R_TOP, SHADE_Z[1] - SHADE_Z[0])
    s.add_triangles(v, f, "metal", name="shade")
    s.add_point_light((0, SHADE_Y, 1.5), power=60, radius=0.05)
    s.set_camera((1.5, -1.8, 1.4), (0, 1.9, 1.4), view_angle=54.4)
    return s


SETTINGS = dict(spp=4, photons=50_000, caustic_photons=10_000, seed=1, workers=2)


# A photon may still slip through the crack where the shade's rim crosses the wall's
# front face into the solid wall and be stored on that face from behind, away from the
# rim: 1 of ~9,300 glow-shot photons here (render.GLOW_SHOT), one pixel at 0.026 where
# the blob reached 5.6. That is the photon tracer's ray offset at an intersection line,
# not the estimate's disc; the bounds below keep it to a speck.
CRACK_PIXEL_MAX = 0.05
CRACK_PHOTON_SHARE = 1e-3


def test_lamp_shade_piercing_wall_lights_nothing_outside():
    """Every pass of the film is 0 but for a crack photon's speck: no blob on the wall
    around the rim."""
    film = render(lamp_scene(), RenderSettings(**SETTINGS))
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        got = np.asarray(getattr(film, name))
        lit = np.count_nonzero(got.max(axis=2))
        assert got.max() <= CRACK_PIXEL_MAX and lit <= 2, (
            f"{name}: {lit} lit pixels, max {got.max():.3g}")


def test_lamp_shade_leak_conditions(monkeypatch):
    """The leak's conditions hold (else the test above proves nothing): photons are stored
    on the wall inside the shade and (but for crack photons) none on the wall outside it; estimates that take every
    photon of their disc (integrator.PHOTON_VISIBILITY off, as before the fix) light the
    wall outside the shade."""
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    shots = shoot_photons(ctx, {})
    world = np.concatenate([ph.position.astype(np.float64) for ph in shots]) + ctx.geo.offset
    on_wall = np.abs(world[:, 1] - 2.0) < 1e-3
    z = world[:, 2]
    radius = R_BOTTOM + (R_TOP - R_BOTTOM) * (z - SHADE_Z[0]) / (SHADE_Z[1] - SHADE_Z[0])
    inside = (z > SHADE_Z[0]) & (np.hypot(world[:, 0], world[:, 1] - SHADE_Y) < radius)
    assert np.count_nonzero(on_wall & inside) > 100
    assert np.count_nonzero(on_wall & ~inside) <= CRACK_PHOTON_SHARE * np.count_nonzero(
        on_wall & inside)
    monkeypatch.setattr(integrator, "PHOTON_VISIBILITY", False)
    film = render(lamp_scene(), RenderSettings(**SETTINGS))
    assert np.count_nonzero(film.caustic) and np.count_nonzero(film.indirect)


def test_one_surface_cells_skip_only_rows_with_nothing_to_hide():
    """The visibility pre-test (onesurface.OneSurfaceCells) is conservative: every
    row it calls free has no hidden photon when traced anyway, the open wall far from the
    shade is free, and the wall right at the rim is not."""
    from engine.onesurface import one_surface_cells
    from engine.photonvisibility import hidden_photons
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    shots = shoot_photons(ctx, {})
    from engine.photonmap import PhotonMap
    pmap = PhotonMap(shots[-1])
    radius = 0.19
    rng = np.random.default_rng(3)
    off = ctx.geo.offset
    # Points on the wall's front face (y = 2), near and far from the shade.
    x = rng.uniform(-1.9, 1.9, 400)
    z = rng.uniform(0.1, 2.6, 400)
    p = np.column_stack([x, np.full(400, 2.0), z]) - off
    n = np.tile([0.0, -1.0, 0.0], (400, 1))
    cells = one_surface_cells(ctx.geo, radius)
    free = cells.free(p, np.full(400, radius))
    far = np.hypot(x, z - 1.6) > 1.2
    near = np.hypot(x, z - 1.5) < 0.3
    assert free[far & (np.abs(x) < 1.4) & (z > 0.8) & (z < 2.2)].all()
    assert not free[near].any()
    rows, _ = hidden_photons(pmap, ctx.accel, p, n, None, radius, 64)
    assert len(rows) > 0                    # the rim's rows do hide photons
    assert not np.intersect1d(rows, np.flatnonzero(free)).size


def test_visible_irradiance_one_call_matches_a_call_a_row():
    """visible_irradiance re-estimates every row that hides a photon in one estimate call
    (PhotonMap.irradiance's hidden: each row's hidden photons left out for that row alone):
    the same bits as the per-row calls it replaced (a86e7af: one pmap.irradiance a row, its
    hidden photons cleared from the mask), with and without a footprint floor; rows that
    hide nothing keep the unmasked estimate."""
    from engine.photonmap import PhotonMap
    from engine.photonvisibility import hidden_photons, visible_irradiance
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    pmap = PhotonMap(shoot_photons(ctx, {})[-1])
    radius, k = 0.19, 64
    rng = np.random.default_rng(5)
    x = rng.uniform(-0.6, 0.6, 300)
    z = rng.uniform(1.0, 2.1, 300)
    p = np.column_stack([x, np.full(300, 2.0), z]) - ctx.geo.offset
    n = np.tile([0.0, -1.0, 0.0], (300, 1))
    for r_floor in (None, rng.uniform(0.0, 0.3, 300)):
        E = pmap.irradiance(p, n, radius, k, 1, "knn_simpson", r_floor=r_floor)
        got = visible_irradiance(pmap, ctx.accel, p, n, None, radius, k, 1, "knn_simpson",
                                 r_floor=r_floor, geo=ctx.geo)
        rows, photons = hidden_photons(pmap, ctx.accel, p, n, None, radius, k, r_floor,
                                       geo=ctx.geo)
        assert len(np.unique(rows)) > 10
        want = E.copy()
        for i in np.unique(rows):
            mask = np.ones(len(pmap.photons), np.bool_)
            mask[photons[rows == i]] = False
            _, masked = pmap.irradiance(
                p[i:i + 1], n[i:i + 1], radius, k, 1, "knn_simpson",
                r_floor=None if r_floor is None else r_floor[i:i + 1], masks=mask[None])
            want[i] = masked[0, 0]
        assert np.array_equal(got, want)
        assert not np.array_equal(got, E)  # the hidden photons did count before


def test_own_orientation_pretest_keeps_every_hidden_photon():
    """The pre-test with the points' normals (OneSurfaceCells.free's fine grid: a disc that
    meets only triangles parallel to its point's plane) frees more rows than the coarse one,
    and hidden_photons with it finds exactly the pairs it finds tracing every row: points
    on the floor and the wall, near the wall's foot and the shade's rim and far from them."""
    from engine.photonmap import PhotonMap
    from engine.onesurface import one_surface_cells
    from engine.photonvisibility import hidden_photons
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    pmap = PhotonMap(shoot_photons(ctx, {})[-1])
    radius, k = 0.19, 64
    rng = np.random.default_rng(7)
    wall = np.column_stack([rng.uniform(-1.9, 1.9, 300), np.full(300, 2.0),
                            rng.uniform(0.01, 2.6, 300)])
    floor = np.column_stack([rng.uniform(-1.9, 1.9, 300), rng.uniform(0.2, 1.99, 300),
                             np.zeros(300)])
    p = np.concatenate([wall, floor]) - ctx.geo.offset
    n = np.concatenate([np.tile([0.0, -1.0, 0.0], (300, 1)), np.tile([0.0, 0.0, 1.0], (300, 1))])
    cells = one_surface_cells(ctx.geo, radius)
    coarse = cells.free(p, np.full(600, radius))
    fine = cells.free(p, np.full(600, radius), n)
    assert (fine >= coarse).all() and fine.sum() > coarse.sum()
    every = hidden_photons(pmap, ctx.accel, p, n, None, radius, k)
    tested = hidden_photons(pmap, ctx.accel, p, n, None, radius, k, geo=ctx.geo)
    assert len(every[0]) > 0
    for a, b in zip(every, tested):
        assert np.array_equal(a, b)
