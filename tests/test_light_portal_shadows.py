"""The world's shadow rays through Cycles light portals (engine/lights/world.py,
lightportal34, issue 14): a 4 x 4 x 2 m closed room with a 1 x 1 m open hole in its roof
and a light portal over it, under a uniform world of radiance L (or an environment map).

Analytic: a floor point at depth h under the opening receives E = L x the opening's
projected solid angle = pi L F, F the form factor of a differential area to a parallel
rectangle (Howell's catalogue, C-11: a corner of an a x b rectangle over the point at
distance h, F = 1/(2 pi) [A / sqrt(1+A^2) atan(B / sqrt(1+A^2)) + B / sqrt(1+B^2)
atan(A / sqrt(1+B^2))], A = a/h, B = b/h; any rectangle in the plane by adding and
subtracting corner rectangles)."""
import math

import numpy as np
import pytest

import engine.lights as el
from engine import RenderSettings
from engine.bsdf import surface_hit
from engine.directlight import DirectLightBuffers, sample_lights
from engine.geometry import SHADOW
from engine.integrator import NO_HROWS, NO_ROWS3, _hit_arrays, light_shadow_rays
from engine.lights.packing import pack_lights
from engine.lights.selection import empty_tree
from engine.render import prepare_context
from engine.api import PaperScene
from engine.scene import Camera, LightPortal, Material
from helpers import assert_unbiased

L = 0.8
HALF, H, W = 2.0, 2.0, 0.5   # room half width, height, the opening's half width (m)


def _floor_and_walls():
    """The room's floor and four walls (grey 0.5) under a world of radiance L, no roof."""
    s = PaperScene(width=16, height=16, background=(L, L, L))
    s.add_material(Material("wall", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 2 * HALF, "wall", name="floor")
    h = HALF
    for k, (a, b) in enumerate((((-h, -h), (h, -h)), ((h, -h), (h, h)),
                                ((h, h), (-h, h)), ((-h, h), (-h, -h)))):
        v = np.array([[a[0], a[1], 0.0], [b[0], b[1], 0.0], [b[0], b[1], H],
                      [a[0], a[1], H]])
        s.add_triangles(v, np.array([[0, 1, 2], [0, 2, 3]]), "wall", name=f"wall{k}")
    return s


def _room(portal=True, env=None):
    """The room (module docstring); env: an equirectangular map (H,W,3) for the world."""
    s = _floor_and_walls()
    h = HALF
    v = np.array([[-h, -h, H], [h, -h, H], [h, h, H], [-h, h, H],
                  [-W, -W, H], [W, -W, H], [W, W, H], [-W, W, H]])
    f = np.array([[0, 4, 1], [1, 4, 5], [1, 5, 2], [2, 5, 6], [2, 6, 3], [3, 6, 7],
                  [3, 7, 0], [0, 7, 4]])
    s.add_triangles(v, f, "wall", name="roof")
    if portal:
        s.portals.append(LightPortal("Portal", [(-W, -W, H), (W, -W, H), (W, W, H),
                                                (-W, W, H)], (0.0, 0.0, -1.0)))
    if env is not None:
        from engine.lights.environment import Environment
        s.environment = Environment(env)
    s.camera = Camera(position=(0, 0, 1.5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=2 * HALF - 0.2)
    return s


def _context(scene, shadow_portals=True, monkeypatch=None):
    if monkeypatch is not None:
        monkeypatch.setattr(el, "SHADOW_PORTALS", shadow_portals, raising=False)
    ctx = prepare_context(scene, RenderSettings(workers=1, photon_mapping=False))
    li = next(i for i, x in enumerate(ctx.lights) if x.kind == "WORLD")
    return ctx, li


def _floor_hits(ctx, pts):
    """Floor hits (engine.bsdf.surface_hit) at points pts (N,3), seen from above."""
    o = np.asarray(pts, np.float64) - ctx.geo.offset + [0.0, 0.0, 0.5]
    down = np.tile([0.0, 0.0, -1.0], (len(o), 1))
    _, prim, u, v = ctx.accel.intersect(o, down)
    assert (prim >= 0).all()
    return surface_hit(ctx.geo, ctx.table, prim, u, v, down)


def _samples(ctx, li, point, n, seed):
    """n one-sample irradiance estimates (n,) (green) of the world's shadow rays at a
    floor point: contribution x visibility."""
    hit = _floor_hits(ctx, np.tile(point, (n, 1)))
    rows, irr, o32, d32, t32 = light_shadow_rays(ctx, hit, li, np.random.default_rng(seed))
    assert len(rows) == len(o32)  # every entry traced, rays in entry order
    blocked = np.empty(len(rows), np.bool_)
    ctx.accel.occluded_into(o32, d32, t32.copy(), blocked, cls=SHADOW)
    e = np.zeros(n)
    e[rows] = irr[:, 1] * ~blocked
    return e


def _corner(x, y, h):
    """Signed form factor of the rectangle [0, x] x [0, y] at height h over the origin
    (Howell C-11, module docstring)."""
    a, b = abs(x) / h, abs(y) / h
    ra, rb = math.sqrt(1 + a * a), math.sqrt(1 + b * b)
    f = (a / ra * math.atan(b / ra) + b / rb * math.atan(a / rb)) / (2 * math.pi)
    return math.copysign(1.0, x) * math.copysign(1.0, y) * f


def _opening_irradiance(px, py):
    """E = pi L F of the roof's opening [-W, W]^2 at height H over floor point (px, py)."""
    x0, x1, y0, y1 = -W - px, W - px, -W - py, W - py
    F = (_corner(x1, y1, H) - _corner(x0, y1, H) - _corner(x1, y0, H)
         + _corner(x0, y0, H))
    return math.pi * L * F


@pytest.mark.parametrize("point", [(0.0, 0.0), (1.2, -0.7), (-1.8, 1.5)])
def test_floor_under_the_opening_gets_L_times_its_projected_solid_angle(point, monkeypatch):
    """The portal strategy mixed with the cosine one stays unbiased: the floor's
    irradiance by the world's shadow rays is pi L F within 4 standard errors (and 1 %)."""
    ctx, li = _context(_room(), True, monkeypatch)
    assert len(ctx.lights[li].portal_rects) == 1
    e = _samples(ctx, li, (*point, 0.0), 200_000, 5)
    want = _opening_irradiance(*point)
    assert_unbiased(e, want, point)


def test_portal_sampling_cuts_the_floor_noise(monkeypatch):
    """At the floor under a 1 x 1 m opening 2 m up, cosine sampling alone (trial34) sends
    ~6 % of its shadow rays through the opening: per-sample std/mean 3.9. With the portal
    the samples are nearly all lit and MIS-weighted to about the mean: std/mean < 0.5, and
    far from the window (projected solid angle 0.6 %) < 1."""
    for point, limit in (((0.0, 0.0), 0.5), ((-1.8, 1.5), 1.0)):
        ctx, li = _context(_room(), True, monkeypatch)
        on = _samples(ctx, li, (*point, 0.0), 100_000, 7)
        ctx, li = _context(_room(), False, monkeypatch)
        off = _samples(ctx, li, (*point, 0.0), 100_000, 7)
        r_on, r_off = on.std() / on.mean(), off.std() / off.mean()
        print(point, f"std/mean on {r_on:.3f} off {r_off:.3f}")
        assert r_on < limit
        assert r_on < 0.25 * r_off


def _sample_with_pdfs(ctx, li, hit, rng):
    """light_shadow_rays' sample with the kernel's direction and pdf per entry:
    (rows, directions (M,3), pdfs (M,))."""
    n = len(hit.p)
    u1, u2, sel = rng.random((3, n))
    buf = DirectLightBuffers().ensure(n)
    codes, params, mesh = pack_lights(ctx.lights)
    m_all, _ = sample_lights(*_hit_arrays(ctx.geo, hit), codes, params, *mesh,
                             *empty_tree(), np.ones(len(codes), np.bool_),
                             np.array([li], np.int64), np.ones(1, np.bool_), u1[None],
                             u2[None], sel[None], buf.contrib, buf.row, buf.kidx, buf.ray,
                             buf.o32, buf.d32, buf.t32, buf.wdir, buf.lpdf, buf.bump,
                             NO_HROWS, NO_ROWS3)
    return buf.row[:m_all].copy(), buf.wdir[:m_all].copy(), buf.lpdf[:m_all].copy()


def _sun_map():
    """A 16 x 32 map: sky 0.4, ground 0.1, one bright texel in the sky."""
    img = np.full((16, 32, 3), 0.4, np.float32)
    img[8:] = 0.1
    img[3, 5] = (60.0, 50.0, 40.0)
    return img


def _floor_pdfs_agree(ctx, li):
    """World shadow samples at 4000 random floor points: asserts nearly all sample and
    their kernel pdf equals WorldLight.pdf (the continuation's MIS weight) at the same
    point, normal and direction; returns (light, hit, rows, wdir)."""
    rng = np.random.default_rng(2)
    n = 4000
    pts = np.column_stack([rng.uniform(-1.9, 1.9, n), rng.uniform(-1.9, 1.9, n), np.zeros(n)])
    hit = _floor_hits(ctx, pts)
    rows, wdir, lpdf = _sample_with_pdfs(ctx, li, hit, rng)
    assert len(rows) > 0.9 * n
    light = ctx.lights[li]
    np.testing.assert_allclose(lpdf, light.pdf(wdir, hit.ns[rows], hit.p[rows]), rtol=1e-9)
    return light, hit, rows, wdir


@pytest.mark.parametrize("env", [False, True])
def test_shadow_ray_pdf_is_the_continuations(env, monkeypatch):
    """The pdf the kernel's world sample carries (for the glossy lobes' MIS) equals
    WorldLight.pdf at the same direction, point and shading normal (the continuation's
    MIS weight, integrator.mis_light_pdf): the portal mixture on both sides."""
    ctx, li = _context(_room(env=_sun_map() if env else None), True, monkeypatch)
    light, hit, rows, wdir = _floor_pdfs_agree(ctx, li)
    with pytest.raises(ValueError):  # (with portals the points are required)
        light.pdf(wdir, hit.ns[rows])
    up = wdir[:, 2] > 0
    pw = hit.p[rows] + ctx.geo.offset  # (world space)
    t = (H - pw[:, 2]) / np.where(up, wdir[:, 2], 1.0)
    x = pw + t[:, None] * wdir
    through = up & (np.abs(x[:, 0]) < W) & (np.abs(x[:, 1]) < W)
    assert through.mean() > 0.5  # most samples aim at the opening


@pytest.mark.parametrize("row", [1, 4])
def test_environment_map_through_the_portal_is_unbiased(row, monkeypatch):
    """With an environment map (a 0.4 sky over a 0.1 ground and one texel of 60, row 1:
    17 degrees from the zenith, seen through the opening from the floor point; row 4:
    out of view), the floor's mean irradiance is the same with and without the portal
    strategy (within 4 standard errors). Noise: with the bright texel out of view the
    flat sky through the opening is all there is, 1/4 of the noise at most (measured
    5.10 -> 0.64 sampling the portal uniformly in solid angle, lightportal34; 0.33 by the
    map, portalenv35); in view the portal's samples follow the map seen through it
    (lights/portalmap.py), half at most (measured 1.88 -> 0.64; uniformly in solid
    angle with the map's share kept, PORTAL_SHARE_ENV_*: 2.25)."""
    img = np.full((16, 32, 3), 0.4, np.float32)
    img[8:] = 0.1
    img[row, 5] = (60.0, 50.0, 40.0)
    point = (0.3, -0.2, 0.0)
    out = {}
    for on in (True, False):
        ctx, li = _context(_room(env=img), on, monkeypatch)
        out[on] = _samples(ctx, li, point, 200_000, 9)
    a, b = out[True], out[False]
    se = math.hypot(a.std(), b.std()) / math.sqrt(len(a))
    r_on, r_off = a.std() / a.mean(), b.std() / b.mean()
    print(f"on {a.mean():.5f} off {b.mean():.5f} se {se:.5f} std/mean on {r_on:.3f} "
          f"off {r_off:.3f}")
    assert abs(a.mean() - b.mean()) < 4 * se
    assert r_on < (0.5 * r_off if row == 1 else 0.25 * r_off)


def test_points_outside_the_room_and_scenes_without_portals_sample_as_before(monkeypatch):
    """A point on the portal's outer side (above the roof) or one that sees it only below
    its horizon gets the portal share 0 (the strategies before lightportal34 alone);
    under the opening the share lies within its bounds and the portal's pdf is 1 / its
    solid angle; without portals the world takes no third number (as before)."""
    ctx, li = _context(_room(portal=False), True, monkeypatch)
    assert not ctx.lights[li].needs_choice
    ctx, li = _context(_room(), True, monkeypatch)
    assert ctx.lights[li].needs_choice
    from engine.lights.world import portal_pdfs
    row = np.zeros(pack_lights(ctx.lights)[1].shape[1])
    ctx.lights[li].pack(row)
    p = np.array([[0.0, 0.0, H + 0.5], [0.0, 0.0, 1.0], [1.9, 0.0, 1.9]]) - ctx.geo.offset
    ns = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    w = np.array([[0.0, 0.0, 1.0]] * 3)
    share, pdf = np.empty(3), np.empty(3)
    portal_pdfs(row, np.zeros((1, 1, 1)), np.zeros((1, 2, 2)), p, ns, w, share, pdf)
    # above the roof: not on the room side; the floor-facing ceiling point: all corners
    # below its horizon
    assert share[0] == 0.0 and share[2] == 0.0 and pdf[0] == 0.0
    # 1 m under the opening: its solid angle and a share within the bounds
    assert 0.1 <= share[1] <= 0.9
    omega = 4 * math.asin(W * W / (W * W + 1.0))  # a square of side 2W at distance 1
    assert pdf[1] == pytest.approx(1.0 / omega, rel=1e-9)


def test_a_portal_over_a_glass_pane_is_left_to_the_pane(monkeypatch):
    """A light portal over a single-plane glass pane (the pane's light comes by
    engine/panelight.py; the world's ordinary shadow rays stop at the glass) takes no
    shadow rays: the portal's samples would all be lost, and with another way in (a
    4 x 1 m opening in a wall) the floor's world samples were 3.3x noisier (std/mean
    4.37 -> 14.5). Over the open hole the portal is kept."""
    from engine.lights import portal_covered
    s = _room()
    s.add_plane((0, 0, H), (0, 0, 1), 2 * W, "wall", name="pane")  # (any surface)
    ctx, li = _context(s, True, monkeypatch)
    assert len(ctx.lights[li].portal_rects) == 0
    assert portal_covered(ctx.geo, s.portals[0])
    ctx, li = _context(_room(), True, monkeypatch)
    assert len(ctx.lights[li].portal_rects) == 1
    assert not portal_covered(ctx.geo, _room().portals[0])


def test_the_light_tree_picks_the_world_with_its_portal_unbiased(monkeypatch):
    """With more lights than SAMPLE_ALL_UP_TO the light tree picks one per shadow ray
    (its number, remapped, then picks the world's strategy): 20 point lights under the
    floor (they light nothing on it) and the world with its portal; the floor's
    irradiance is still pi L F (within 4 standard errors and 1 %)."""
    from engine.lights.selection import SAMPLE_ALL_UP_TO, selector_for
    from engine.scene import Light
    s = _room()
    for k in range(SAMPLE_ALL_UP_TO + 4):
        s.add_light(Light(f"lamp{k}", "POINT", power=1.0,
                          position=(-1.5 + 0.15 * k, 0.3, -1.0)))
    ctx, _ = _context(s, True, monkeypatch)
    chosen = selector_for(ctx)
    assert chosen is not None
    n = 200_000
    point = (0.4, -0.3, 0.0)
    hit = _floor_hits(ctx, np.tile(point, (n, 1)))
    rng = np.random.default_rng(4)
    u1, u2, sel = rng.random((3, n))
    buf = DirectLightBuffers().ensure(n)
    codes, params, mesh = pack_lights(ctx.lights)
    m_all, m_rays = sample_lights(*_hit_arrays(ctx.geo, hit), codes, params, *mesh,
                                  *chosen[1], np.array([-1], np.int64),
                                  np.ones(1, np.bool_), u1[None], u2[None], sel[None],
                                  buf.contrib, buf.row, buf.kidx, buf.ray, buf.o32, buf.d32,
                                  buf.t32, buf.wdir, buf.lpdf, buf.bump, NO_HROWS, NO_ROWS3)
    ray = buf.ray[:m_all]
    traced = ray >= 0
    blocked = np.empty(m_rays, np.bool_)
    ctx.accel.occluded_into(buf.o32[:m_rays].copy(), buf.d32[:m_rays].copy(),
                            buf.t32[:m_rays].copy(), blocked, cls=SHADOW)
    lit = np.ones(m_all, bool)
    lit[traced] = ~blocked[ray[traced]]
    e = np.zeros(n)
    np.add.at(e, buf.row[:m_all], buf.contrib[:m_all, 1] * lit)
    want = _opening_irradiance(*point[:2])
    se = e.std() / math.sqrt(n)
    print(f"mean/want {e.mean() / want:.4f} se/want {se / want:.4f}")
    assert abs(e.mean() - want) < 4 * se
    assert e.mean() == pytest.approx(want, rel=0.01)
