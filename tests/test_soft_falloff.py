"""Point and spot lights with a radius, with and without Blender's "Soft Falloff"
(issue 14; engine/lights/point.py). Cycles (kernel/light/point.h, spot.h) makes such a
light a disk of radius r facing the shaded point when Soft Falloff is on (Blender's
default) and a sphere of radius r when it is off (is_sphere), both of radiance
I / (pi r^2), I = P / (4 pi). Face-on at distance d the disk gives I / (d^2 + r^2), the
sphere I / d^2 exactly (a uniformly bright sphere lights a point as a point source of its
intensity). Measured in the bpy wheel's Cycles (5.0.1): switching Soft Falloff off
brightens a floor under a light at 0.9 m of radius 0.6 by 1.19x (point) and 1.28x (a
90-degree spot); tools/feature_matrix.py's light_point_sphere compares a whole image."""
import math

import numpy as np
import pytest

import engine.integrator as integrator
from engine.api import PaperScene
from engine.scene import Light, Material
from engine.settings import RenderSettings

H, R, POWER = 0.9, 0.6, 100.0
ALBEDO = 0.5


def _floor_scene(soft, kind="point"):
    """A diffuse floor (albedo 0.5) under a light of radius R at height H, seen straight
    down by a narrow camera: every pixel sees the floor within ~1.5 % of the light's foot."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("grey", (ALBEDO,) * 3, specular=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 20.0, "grey", name="floor")
    if kind == "point":
        s.add_point_light((0, 0, H), POWER, radius=R, soft_falloff=soft)
    else:
        s.add_spot_light((0, 0, H), (0, 0, 0), POWER, spot_size_degrees=120.0, blend=0.0,
                         radius=R, soft_falloff=soft)
    s.set_camera((0, 0, 6.0), (0, 0, 0), up=(0, 1, 0), view_angle=0.3)
    return s


def _floor_radiance(soft, kind="point", spp=64):
    film = _floor_scene(soft, kind).render(
        RenderSettings(spp=spp, photon_mapping=False, seed=2, workers=1))
    return float(film.combined.mean())


@pytest.mark.parametrize("kind", ["point", "spot"])
def test_floor_under_the_light_as_cycles_computes_it(kind):
    """Radiance rho / pi x E at the light's foot: E = I / (H^2 + R^2) with Soft Falloff,
    I / H^2 without (a sphere), for a point and a spot (whose cone holds the floor's
    patch). The sphere's uniform cone sampling has no noise here (every direction meets
    the light and the floor sees the whole cap), the disk's very little."""
    intensity = POWER / (4.0 * math.pi)
    want_disk = ALBEDO / math.pi * intensity / (H * H + R * R)
    want_sphere = ALBEDO / math.pi * intensity / (H * H)
    disk, sphere = _floor_radiance(True, kind), _floor_radiance(False, kind)
    assert disk == pytest.approx(want_disk, rel=0.01)
    assert sphere == pytest.approx(want_sphere, rel=0.01)
    assert sphere / disk == pytest.approx(1.0 + R * R / (H * H), rel=0.015)


def test_every_ray_that_meets_a_sphere_light_has_the_pdf_of_its_shadow_rays():
    """The sphere's shadow rays (directlight's _sphere_light_sample) and the continuation
    that meets it (PointLight.intersect, integrator.mis_light_pdf) must agree for multiple
    importance sampling: every shadow-ray direction meets the sphere at the ray's end, and
    its pdf is the one mis_light_pdf gives there."""
    from engine.render import prepare_context
    s = _floor_scene(False)
    ctx = prepare_context(s, RenderSettings(workers=1, photon_mapping=False))
    li = next(i for i, x in enumerate(ctx.lights) if x.kind == "POINT")
    light = ctx.lights[li]
    assert light.is_sphere
    # Shading points on the floor around the light's foot.
    from engine.integrator import light_shadow_rays
    hit = _floor_hits(ctx, 400)
    rows, irr, o32, d32, t32 = light_shadow_rays(ctx, hit, li, np.random.default_rng(3))
    assert len(rows) > 300
    o, d = o32.astype(np.float64), d32.astype(np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    mask, t, L = light.intersect(o, d, np.full(len(o), np.inf))
    assert mask.all()
    np.testing.assert_allclose(t, t32, rtol=1e-4)  # the shadow ray ends on the sphere
    pdf = integrator.mis_light_pdf(light, o, d, t)
    rel = hit.p[rows] - light.pos
    sin2 = light.radius ** 2 / np.einsum("ij,ij->i", rel, rel)
    np.testing.assert_allclose(pdf, 1.0 / (2 * np.pi * (1 - np.sqrt(1 - sin2))), rtol=1e-6)
    np.testing.assert_allclose(L, np.broadcast_to(light.intensity / (np.pi * light.radius ** 2),
                                                  L.shape))


def _floor_hits(ctx, n):
    """n floor hits (engine.bsdf.surface_hit) within 2 m of the light's foot, seen from
    above."""
    from engine.bsdf import surface_hit
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), np.zeros(n)])
    o = pts - ctx.geo.offset + [0.0, 0.0, -1.0]
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, up)
    assert (prim >= 0).all()
    return surface_hit(ctx.geo, ctx.table, prim, u, v, -up)


def test_soft_falloff_from_the_scene_file(tmp_path):
    """Scene files say `soft_falloff = false` for a sphere (default true); other values
    are refused naming the key."""
    from engine.scenefile import SceneFileError, load_scene
    text = """
[camera]
position = [0, -4, 1]
look_at = [0, 0, 0]
[[lights]]
type = "point"
position = [0, 0, 1]
radius = 0.3
soft_falloff = %s
"""
    (tmp_path / "a.toml").write_text(text % "false")
    scene = load_scene(str(tmp_path / "a.toml"))[0]
    assert scene.lights[0].soft_falloff is False
    (tmp_path / "b.toml").write_text((text % "true").replace("soft_falloff = true\n", ""))
    assert load_scene(str(tmp_path / "b.toml"))[0].lights[0].soft_falloff is True
    (tmp_path / "c.toml").write_text(text % '"no"')
    with pytest.raises(SceneFileError, match="soft_falloff"):
        load_scene(str(tmp_path / "c.toml"))
    assert Light("x", "POINT", radius=0.3, soft_falloff=0).soft_falloff is False


def _disk_numpy(o, d, tmax, pos, radius):
    """PointLight.intersect's disk (Soft Falloff on) as the numpy stage computed it (mask,
    t): the oracle of the compiled intersect_disk."""
    from engine.sampling import dot
    rel = o - pos
    dist = np.linalg.norm(rel, axis=1)
    axis = rel / np.maximum(dist, 1e-300)[:, None]
    toward = -dot(d, axis)
    front = toward > 1e-12
    t = dist / np.where(front, toward, 1.0)
    on_disk = t[:, None] * d + rel
    mask = (front & (dist > 0) & (t < tmax)
            & (np.einsum("ij,ij->i", on_disk, on_disk) <= radius ** 2))
    return mask, np.where(front, t, np.inf)


@pytest.mark.parametrize("kind", ["point", "spot"])
def test_disk_light_met_by_rays_as_the_numpy_stage_bit_for_bit(kind):
    """PointLight.intersect with Soft Falloff (the compiled intersect_disk) gives the
    mask, distances and radiance of the numpy stage it replaced, bit for bit: rays aimed
    at the disk (hits, near misses at its rim), random rays, rays from the centre itself
    (distance 0), away from it, stopped short by tmax (an array, and a scalar), on a point
    and a spot light (its cone mask read along the ray)."""
    from engine.render import prepare_context
    ctx = prepare_context(_floor_scene(True, kind), RenderSettings(workers=1,
                                                                   photon_mapping=False))
    light = next(x for x in ctx.lights if x.kind in ("POINT", "SPOT"))
    assert not light.is_sphere and light.radius > 0
    rng = np.random.default_rng(8)
    m = 20_000
    o = light.pos + rng.normal(size=(m, 3)) * rng.uniform(0.1, 4.0, (m, 1))
    aim = light.pos + rng.normal(size=(m, 3)) * light.radius * 0.7
    d = aim - o
    d[::3] = rng.normal(size=d[::3].shape)  # anywhere
    d /= np.linalg.norm(d, axis=1)[:, None]
    o[::97] = light.pos  # from the centre
    tmax = rng.uniform(0.0, 6.0, m)
    tmax[::5] = np.inf
    for tm in (tmax, np.inf, 1.5):
        mask, t, L = light.intersect(o, d, tm)
        want_mask, want_t = _disk_numpy(o, d, tm, light.pos, light.radius)
        np.testing.assert_array_equal(mask, want_mask)
        np.testing.assert_array_equal(t.view(np.uint64), want_t.view(np.uint64))
        assert 0.05 * m < mask.sum() < 0.95 * m
        f = light._falloff_plain(-d)
        want_L = np.broadcast_to(light.intensity / (math.pi * light.radius ** 2), (m, 3))
        if f is not None:
            want_L = want_L * np.where(np.zeros(m, bool), 1.0, f)[:, None]
        np.testing.assert_array_equal(np.asarray(L), want_L)


@pytest.mark.parametrize("soft", [True, False])
def test_photons_give_the_floor_the_camera_sides_irradiance(soft):
    """The photons' irradiance at the light's foot (their power within 0.15 m over the
    disc's area) equals the camera side's: I / (H^2 + R^2) with Soft Falloff, I / H^2
    without. Photons leave the sphere of radius R either way; with Soft Falloff their
    power at the first hit takes d^2 / (d^2 + R^2) (photons.soft_falloff_sources: a
    lamp shade read 1.19x Cycles without it, newuser31)."""
    from engine.accel import Accel
    from engine.geometry import prepare
    from engine.lights import allocate_photons, prepare_lights
    from engine.photons import DIRECT, trace_photons
    from engine.render import Context
    s = _floor_scene(soft)
    s.validate()
    settings = RenderSettings(photons=400_000, seed=3)
    geo, table = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(s, geo, table)
    ctx = Context(s, settings, geo, table, accel, lights)
    ph = trace_photons(ctx, lights, allocate_photons(lights, 400_000), False, 1)
    xy = ph.position[:, :2].astype(np.float64) + geo.offset[:2]
    rho = 0.15
    near = (ph.kind == DIRECT) & (np.hypot(xy[:, 0], xy[:, 1]) < rho)
    got = float(ph.power[near].astype(np.float64).sum(axis=0).mean()) / (math.pi * rho ** 2)
    intensity = POWER / (4.0 * math.pi)
    # The disc's mean of I cos^3 / (H^2 + r^2)-like falloff is ~1.5 % below the foot's.
    want = intensity / (H * H + (R * R if soft else 0.0))
    print(f"soft {soft}: photons / camera side {got / want:.4f}")
    assert got == pytest.approx(want, rel=0.03)


def _disk_spot_irradiance(x, spot_half, r, n=600):
    """Irradiance (W/m^2) at the floor point (x, 0, 0) under a spot of radius r at (0, 0, H)
    aimed straight down, Soft Falloff on, blend 0, as Cycles' spot_light_sample takes it:
    the disk of radius r through the centre facing the point, radiance I / (pi r^2), each
    of its points masked by the cone along the ray from that point to the floor
    (spot_light_attenuation(-ls->D)). A midpoint rule over n x n polar cells."""
    p = np.array([x, 0.0, 0.0])
    c = np.array([0.0, 0.0, H])
    a = (p - c) / np.linalg.norm(p - c)
    e1 = np.cross(a, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    rho = (np.arange(n) + 0.5) / n * r
    phi = (np.arange(n) + 0.5) / n * 2 * math.pi
    R_, P_ = np.meshgrid(rho, phi, indexing="ij")
    y = c + (R_ * np.cos(P_))[..., None] * e1 + (R_ * np.sin(P_))[..., None] * e2
    v = p - y  # from the light's point to the floor
    d = np.linalg.norm(v, axis=-1)
    w = v / d[..., None]
    inside = -w[..., 2] > math.cos(spot_half)  # the cone's axis is -z
    cos_floor = np.maximum(-w[..., 2], 0.0)
    cos_disk = np.maximum(w @ a, 0.0)
    dA = R_ * (r / n) * (2 * math.pi / n)
    L = POWER / (4.0 * math.pi) / (math.pi * r * r)
    return float((L * inside * cos_floor * cos_disk / d ** 2 * dA).sum())


def test_spot_cone_edge_softened_by_the_disk_as_in_cycles():
    """A spot with a radius (Soft Falloff on) masks each shadow-ray sample by the cone
    along the ray from the sampled point on its disk (Cycles' spot_light_sample:
    spot_light_attenuation(-ls->D)), so the light's size softens the cone's edge: at a
    hard-edged (blend 0) 60-degree spot of radius 0.3 m 0.9 m up, floor points 26, 30 and
    34 degrees off its axis take the disk's masked irradiance (_disk_spot_irradiance);
    the mask taken from the light's centre gave the unmasked disk inside and 0 outside,
    the penumbra's 34-degree point 0 where Cycles lights it (newuser52's jewellery
    display: the velvet at a 1 cm spot's edge read 0.84 and 1.05 of Cycles)."""
    from engine.bsdf import surface_hit
    from engine.integrator import light_shadow_rays
    from engine.render import prepare_context
    r, half = 0.3, math.radians(30.0)
    s = PaperScene(width=8, height=8)
    s.add_material(Material("grey", (ALBEDO,) * 3, specular=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 20.0, "grey", name="floor")
    s.add_spot_light((0, 0, H), (0, 0, 0), POWER, spot_size_degrees=60.0, blend=0.0,
                     radius=r, soft_falloff=True)
    s.set_camera((0, 0, 6.0), (0, 0, 0), up=(0, 1, 0), view_angle=10.0)
    ctx = prepare_context(s, RenderSettings(workers=1, photon_mapping=False))
    li = next(i for i, x in enumerate(ctx.lights) if x.kind == "SPOT")
    assert not ctx.lights[li].is_sphere
    n = 40_000
    for deg in (26.0, 30.0, 34.0):
        x = H * math.tan(math.radians(deg))
        pts = np.tile([x, 0.0, 0.0], (n, 1))
        up = np.tile([0.0, 0.0, 1.0], (n, 1))
        _, prim, u, v = ctx.accel.intersect(pts - ctx.geo.offset + [0.0, 0.0, -1.0], up)
        assert (prim >= 0).all()
        hit = surface_hit(ctx.geo, ctx.table, prim, u, v, -up)
        rows, irr, *_ = light_shadow_rays(ctx, hit, li, np.random.default_rng(int(deg)))
        got = float(irr[:, 0].sum()) / n
        want = _disk_spot_irradiance(x, half, r)
        print(f"{deg} degrees: {got:.5f} against {want:.5f}")
        assert want > 0.5  # each point sees part of the disk inside the cone
        assert got == pytest.approx(want, rel=0.02)


def test_soft_falloff_at_first_hit_by_each_lights_rows():
    """photons._soft_falloff_at_first_hit scales each photon that hit by d^2 / (d^2 +
    r^2), d its first hit's distance from its own light's centre and r that light's
    radius, for a group of lights (soft_falloff_sources: one row per light, each owning
    its slots in order; a light without Soft Falloff leaves its photons as they are),
    and leaves the photons that missed alone."""
    from types import SimpleNamespace
    from engine.photons import _soft_falloff_at_first_hit, soft_falloff_sources
    from engine.scene import POINT, SPOT

    def lamp(kind, radius, pos):
        return SimpleNamespace(kind=kind, radius=radius, is_sphere=False,
                               pos=np.array(pos, float))

    lamps = [lamp(POINT, 0.5, (0, 1, 2)), lamp(SPOT, 0.0, (1, 1, 1)),
             lamp(SPOT, 0.2, (3, 0, 1))]
    counts = [300, 200, 500]
    group = SimpleNamespace(lights=lamps, counts=counts)
    m = sum(counts)
    rng = np.random.default_rng(4)
    o32 = rng.normal(size=(m, 3)).astype(np.float32)
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    t32 = rng.uniform(0.01, 5.0, m).astype(np.float32)
    geom = np.where(rng.uniform(size=m) < 0.3, -1, 0).astype(np.int32)
    slot = np.arange(m)
    power = rng.uniform(size=(m, 3)).astype(np.float32)
    got = power.copy()
    _soft_falloff_at_first_hit(soft_falloff_sources(group, m), o32, d, t32, geom, slot, got)
    owner = np.repeat(np.arange(3), counts)
    centre = np.array([lp.pos for lp in lamps])[owner]
    r2 = np.array([lp.radius ** 2 for lp in lamps])[owner]
    p = o32.astype(np.float64) + t32.astype(np.float64)[:, None] * d
    dist2 = ((p - centre) ** 2).sum(axis=1)
    want = np.where(((geom >= 0) & (r2 > 0))[:, None],
                    power * (dist2 / (dist2 + r2))[:, None], power)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    assert np.array_equal(got[geom < 0], power[geom < 0])
    assert np.array_equal(got[owner == 1], power[owner == 1])
    # one soft light alone: every photon of the chunk by that light's row
    one = power.copy()
    _soft_falloff_at_first_hit(soft_falloff_sources(lamps[0], m), o32, d, t32, geom, slot, one)
    dist2 = ((p - lamps[0].pos) ** 2).sum(axis=1)
    want = np.where((geom >= 0)[:, None], power * (dist2 / (dist2 + 0.25))[:, None], power)
    np.testing.assert_allclose(one, want, rtol=1e-6)
