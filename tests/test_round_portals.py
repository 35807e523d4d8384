"""Round light portals, the portals' exact projected solid angle and the portal tables
kept between prepares (portals36, issue 14).

The room of tests/test_light_portal_shadows.py (4 x 4 x 2 m, closed) with a round hole
of radius W = 0.5 m in its roof (a SIDES-gon) and a round light portal (Cycles' Disk
portal, is_round) over it, under a uniform world of radiance L.

Analytic: a floor point receives E = L x Phi, Phi the hole's projected solid angle, for a
polygon by Lambert's formula Phi = 1/2 |sum_i angle(v_i, v_i+1) N . unit(v_i x v_i+1)|
(Arvo 1995), here in numpy over the hole's vertices (the kernels' own version only sets
the share, never the estimate)."""
import math

import numpy as np
import pytest

import engine.lights.portalmap as portalmap
from engine.scene import Camera, LightPortal
from helpers import assert_unbiased
from test_light_portal_shadows import (H, HALF, L, _context, _floor_and_walls,
                                       _floor_pdfs_agree, _room, _samples, _sun_map)

W = 0.5
SIDES = 64


def _hole():
    """The hole's outline (SIDES, 3): the SIDES-gon of radius W at height H."""
    a = 2 * math.pi * np.arange(SIDES) / SIDES
    return np.column_stack([W * np.cos(a), W * np.sin(a), np.full(SIDES, H)])


def _round_room(portal=True, env=None):
    """The room (module docstring): its roof the ring of quads between the hole and the
    square's edge (the points of the edge at the hole's vertices' angles; SIDES a
    multiple of 8, so the square's corners are among them)."""
    s = _floor_and_walls()
    h = HALF
    inner = _hole()
    d = inner[:, :2] / W
    outer = np.column_stack([d * (h / np.abs(d).max(axis=1))[:, None], np.full(SIDES, H)])
    v = np.vstack([inner, outer])
    i = np.arange(SIDES)
    j = (i + 1) % SIDES
    f = np.vstack([np.column_stack([i, SIDES + i, SIDES + j]),
                   np.column_stack([i, SIDES + j, j])])
    s.add_triangles(v, f, "wall", name="roof")
    if portal:
        s.portals.append(LightPortal("Portal", [(-W, -W, H), (W, -W, H), (W, W, H),
                                                (-W, W, H)], (0.0, 0.0, -1.0), round=True))
    if env is not None:
        from engine.lights.environment import Environment
        s.environment = Environment(env)
    s.camera = Camera(position=(0, 0, 1.5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=2 * HALF - 0.2)
    return s


def _lambert(poly, p, n):
    """Projected solid angle (sr) of the polygon poly (M,3), wholly above p's tangent
    plane, seen from p with unit normal n (module docstring)."""
    v = poly - p
    w = np.roll(v, -1, axis=0)
    c = np.cross(v, w)
    cl = np.linalg.norm(c, axis=1)
    ang = np.arctan2(cl, (v * w).sum(axis=1))
    return 0.5 * abs(float((ang * (c @ n) / cl).sum()))


@pytest.mark.parametrize("point", [(0.0, 0.0), (1.2, -0.7), (-1.8, 1.5)])
def test_floor_under_a_round_opening_gets_L_times_its_projected_solid_angle(point,
                                                                           monkeypatch):
    """The round portal's strategy (a point uniform over its ellipse, pdf by its area
    converted to solid angle) mixed with the cosine one is unbiased: the floor's
    irradiance is L Phi of the hole within 4 standard errors and 1 %."""
    ctx, li = _context(_round_room(), True, monkeypatch)
    light = ctx.lights[li]
    assert len(light.portal_rects) == 1 and light.portal_round.tolist() == [True]
    e = _samples(ctx, li, (*point, 0.0), 200_000, 5)
    want = L * _lambert(_hole(), np.array([*point, 0.0]), np.array([0.0, 0.0, 1.0]))
    assert_unbiased(e, want, point)


def test_round_portal_cuts_the_floor_noise(monkeypatch):
    """Under the round opening the portal's samples are nearly all lit: std/mean under
    1/4 of the cosine sampling's alone (the round portal drawn as its ellipse: under
    0.5 at the centre, where a rectangle over the hole would lose 21 %)."""
    point = (0.2, 0.1)
    ctx, li = _context(_round_room(), True, monkeypatch)
    on = _samples(ctx, li, (*point, 0.0), 100_000, 7)
    ctx, li = _context(_round_room(), False, monkeypatch)
    off = _samples(ctx, li, (*point, 0.0), 100_000, 7)
    r_on, r_off = on.std() / on.mean(), off.std() / off.mean()
    print(f"std/mean with the round portal {r_on:.3f}, without {r_off:.3f}")
    assert r_on < 0.5
    assert r_on < 0.25 * r_off


@pytest.mark.parametrize("env", [False, True])
def test_round_portal_pdf_is_the_continuations(env, monkeypatch):
    """The pdf the kernel's samples carry equals WorldLight.pdf (the continuation's MIS
    weight) at the same point, normal and direction, a round and a square portal
    overlapping (a direction through both sums both terms); under a map the round
    portal turns the map sampling off (uniform: no table)."""
    scene = _round_room(env=_sun_map() if env else None)
    scene.portals.append(LightPortal("Square", [(-0.3, -0.3, H), (0.6, -0.3, H),
                                                (0.6, 0.3, H), (-0.3, 0.3, H)],
                                     (0.0, 0.0, -1.0)))
    ctx, li = _context(scene, True, monkeypatch)
    light = ctx.lights[li]
    assert sorted(light.portal_round.tolist()) == [False, True]
    assert light.portal_tables is None
    _, hit, rows, wdir = _floor_pdfs_agree(ctx, li)
    up = wdir[:, 2] > 0
    pw = hit.p[rows] + ctx.geo.offset
    t = (H - pw[:, 2]) / np.where(up, wdir[:, 2], 1.0)
    x = pw + t[:, None] * wdir
    # (the square inside the round hole leaves the hole open past it: the leaky share
    # bounds, lights.portal_leaks, 0.5 at most)
    assert light.portal_leaks == ["Square"]
    assert (up & (np.hypot(x[:, 0], x[:, 1]) < W)).mean() > 0.4


def _share_and_pdf(ctx, li, p, ns, w):
    from engine.lights.packing import pack_lights
    from engine.lights.world import portal_pdfs
    row = np.zeros(pack_lights(ctx.lights)[1].shape[1])
    ctx.lights[li].pack(row)
    p = np.asarray(p, np.float64) - ctx.geo.offset
    share, pdf = np.empty(len(p)), np.empty(len(p))
    portal_pdfs(row, np.zeros((1, 1, 1)), np.zeros((1, 2, 2)), np.ascontiguousarray(p),
                np.ascontiguousarray(ns, np.float64), np.ascontiguousarray(w, np.float64),
                share, pdf)
    return share, pdf


def _grid_projected(p, n, m=1500):
    """The square portal's [-W, W]^2 at height H projected solid angle from p with
    normal n, by a midpoint grid: sum max(n . w, 0) cos_y / r^2 dA."""
    t = (np.arange(m) + 0.5) / m * 2 * W - W
    X, Y = np.meshgrid(t, t)
    d = np.column_stack([X.ravel() - p[0], Y.ravel() - p[1], np.full(X.size, H - p[2])])
    r = np.linalg.norm(d, axis=1)
    w = d / r[:, None]
    return float((np.maximum(w @ n, 0.0) * w[:, 2] / r ** 2).sum() * (2 * W / m) ** 2)


def test_share_follows_the_exact_projected_solid_angle(monkeypatch):
    """s_p = 1 - Phi / pi within the bounds, Phi the portal's projected solid angle
    clipped to the point's tangent plane: at a wall point level with the roof below the
    opening's edge (half the portal above its horizon) and at points just under the
    opening, Phi equals the grid integral (the centre estimate, lightportal34, counted
    the whole portal or none there, and gave 0.9 1 cm under it)."""
    import engine.lights.world as wl
    monkeypatch.setattr(wl, "PORTAL_SHARE_LO", 0.0)
    monkeypatch.setattr(wl, "PORTAL_SHARE_HI", 1.0)
    ctx, li = _context(_room(), True, monkeypatch)
    pts = np.array([[0.0, 0.0, 1.0], [0.2, -0.1, H - 0.01], [W + 0.2, 0.0, H - 0.3],
                    [0.1, 0.0, H - 0.3]])
    ns = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0],
                   [-math.sqrt(0.5), 0.0, math.sqrt(0.5)]])
    share, _ = _share_and_pdf(ctx, li, pts, ns, ns)
    for k in range(len(pts)):
        want = 1.0 - _grid_projected(pts[k], ns[k]) / math.pi
        print(k, share[k], want)
        assert share[k] == pytest.approx(want, abs=2e-3)
    assert share[1] < 0.2  # 1 cm under the opening most of the hemisphere is the sky


def test_round_share_and_pdf_at_a_point(monkeypatch):
    """Under the round portal the uniform strategy's pdf of a direction through it is the
    area pdf r^2 / (A cos) (one portal: its selection weight cancels), and its share is
    1 - Phi / pi of the inscribed 16-gon (world.ROUND_SIDES)."""
    import engine.lights.world as wl
    monkeypatch.setattr(wl, "PORTAL_SHARE_LO", 0.0)
    monkeypatch.setattr(wl, "PORTAL_SHARE_HI", 1.0)
    ctx, li = _context(_round_room(), True, monkeypatch)
    p = np.array([[0.3, 0.2, 0.5]])
    y = np.array([0.1, -0.2, H])
    d = y - p[0]
    r = np.linalg.norm(d)
    w = (d / r)[None]
    share, pdf = _share_and_pdf(ctx, li, p, [[0.0, 0.0, 1.0]], w)
    assert pdf[0] == pytest.approx(r * r / (math.pi * W * W * w[0, 2]), rel=1e-9)
    a = 2 * math.pi * np.arange(wl.ROUND_SIDES) / wl.ROUND_SIDES
    poly = np.column_stack([W * np.cos(a), W * np.sin(a), np.full(len(a), H)])
    assert share[0] == pytest.approx(1 - _lambert(poly, p[0], np.array([0, 0, 1.0])) / math.pi,
                                     rel=1e-9)
    # a direction past the ellipse but inside its square: not the portal's
    y2 = np.array([0.45, 0.45, H]) - p[0]
    _, pdf2 = _share_and_pdf(ctx, li, p, [[0.0, 0.0, 1.0]], (y2 / np.linalg.norm(y2))[None])
    assert pdf2[0] == 0.0


def test_round_light_portal_photons_start_on_its_ellipse():
    """Photon portals (engine/portal.py): a round light portal is the fan of the
    ROUND_SIDES-gon inscribed in its ellipse: its area pi W^2 within 1 %, every vertex
    in the portal's plane within its circle."""
    from engine.portal import ROUND_SIDES, portals_from

    class _Geo:
        offset = np.zeros(3)
    lp = _round_room().portals[0]
    ports = portals_from(_Geo(), None, None, [lp])
    assert len(ports.v0) == ROUND_SIDES
    assert ports.areas[0] == pytest.approx(math.pi * W * W, rel=0.01)
    assert ports.areas[0] < math.pi * W * W
    tips = np.vstack([ports.v0, ports.v0 + ports.e1, ports.v0 + ports.e2])
    assert np.allclose(tips[:, 2], H)
    assert (np.hypot(tips[:, 0], tips[:, 1]) <= W + 1e-12).all()
    o = np.array([[0.45, 0.45, H + 1.0], [0.0, 0.1, H + 1.0]])
    d = np.array([[0.0, 0.0, -1.0]] * 2)
    assert (ports.crossings(o, d)[:, 0] > 0).tolist() == [False, True]


def test_portal_tables_are_kept_between_prepares(monkeypatch):
    """A second prepare of the same scene (a re-render, a progressive pass) builds no
    portal table (portalmap.tables_built unchanged) and gets the same arrays; a moved
    portal or a changed map builds its table again."""
    img = _sun_map()
    ctx, li = _context(_room(env=img), True, monkeypatch)
    first = ctx.lights[li].portal_tables
    built = portalmap.tables_built
    ctx, li = _context(_room(env=img), True, monkeypatch)
    again = ctx.lights[li].portal_tables
    assert portalmap.tables_built == built
    assert again[0] is first[0]
    moved = _room(env=img)
    moved.portals[0].corners = moved.portals[0].corners + [0.0, 0.0, -0.01]
    ctx, li = _context(moved, True, monkeypatch)
    assert ctx.lights[li].portal_tables is not None
    assert portalmap.tables_built == built + 1
    img2 = img.copy()
    img2[3, 6] = 5.0
    ctx, li = _context(_room(env=img2), True, monkeypatch)
    assert not np.array_equal(ctx.lights[li].portal_tables[0], first[0])
    assert portalmap.tables_built == built + 2


def test_a_portal_smaller_than_its_opening_is_found_and_takes_the_leaky_share(monkeypatch):
    """lights.portal_leaks: a portal over the whole roof opening (or a round one over the
    round hole) is not leaky; one a fifth narrower than the opening is (the sky through
    the strips beside it comes only by the other strategies), named in a warning, and its share is capped at PORTAL_SHARE_LEAK_HI. Still unbiased."""
    import engine.lights.world as wl
    from engine.lights import portal_leaks
    ctx, li = _context(_room(), True, monkeypatch)
    assert ctx.lights[li].portal_leaks == []
    assert ctx.lights[li].portal_share_bounds == (wl.PORTAL_SHARE_LO, wl.PORTAL_SHARE_HI)
    ctx, li = _context(_round_room(), True, monkeypatch)
    assert ctx.lights[li].portal_leaks == []
    narrow = _room(portal=False)
    w = 0.8 * W
    narrow.portals.append(LightPortal("Narrow", [(-w, -W, H), (w, -W, H), (w, W, H),
                                                 (-w, W, H)], (0.0, 0.0, -1.0)))
    ctx, li = _context(narrow, True, monkeypatch)
    light = ctx.lights[li]
    assert light.portal_leaks == ["Narrow"]
    assert portal_leaks(ctx.geo, narrow.portals[0])
    assert light.portal_share_bounds == (wl.PORTAL_SHARE_LEAK_LO, wl.PORTAL_SHARE_LEAK_HI)
    assert any("light portal 'Narrow'" in w for w in ctx.plan.warnings)
    point = (0.9, 0.3)
    from test_light_portal_shadows import _opening_irradiance
    e = _samples(ctx, li, (*point, 0.0), 200_000, 6)
    assert_unbiased(e, _opening_irradiance(*point), point)


def test_the_effect_report_says_the_world_lights_through_the_portals():
    """With light portals the world line said "from the whole sky" (newuser36's round
    window): it names the portals' count and how the shadow rays aim."""
    from engine import RenderSettings
    from engine.render import prepare_context

    def world_line(scene):
        ctx = prepare_context(scene, RenderSettings(photons=2000, workers=1))
        ctx.accel.close()
        return next(r for r in ctx.plan.report() if r.startswith("world light"))
    with_portal = world_line(_round_room())
    assert "through 1 light portal:" in with_portal and "whole sky" not in with_portal, \
        with_portal
    without = world_line(_round_room(portal=False))
    assert "from the whole sky" in without and "portal" not in without, without
    # One portal is "it", not "them" (newuser46's window: "through 1 light portal
    # (shadow rays aimed through them, by the map seen through them)").
    assert "aimed through the portal where a surface sees the sky through it" in with_portal, \
        with_portal
    mapped = world_line(_round_room(env=_sun_map()))
    assert "through 1 light portal (shadow rays aimed through it, " in mapped, mapped
    assert "them" not in mapped, mapped
