"""Heterogeneous media (engine/heterogeneous.py): a density texture on a volume-only slab.
A density linear in z, f(z) = A z over the slab z 0..0.5, has the optical depth
sigma_unit x A (0.5^2 - z^2) / 2 from z up to the top, so the transmittance through the
slab, the sun's light under a ramped box and the single scattering of a point light
(camera ray and shadow ray both ratio-tracked, the point's density in the weight) have
closed forms or 1-D quadratures; a constant texture renders as the homogeneous medium of
the same density; seeding; zero-density regions."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.bsdf import surface_hit
from engine.heterogeneous import HeterogeneousMedia, ray_keys, uniforms
from engine.integrator import Counters, direct_irradiance
from engine.render import prepare_context, render
from engine.scene import Material, SceneError
from engine.shadernodes import Math, ObjectSpacePosition, SeparateChannel

A = 4.0  # the ramp: f(z) = A z (density 0 at the slab's bottom, 2 at its top)
SIGMA_A = np.array([0.5, 1.0, 2.0])  # 1/m at density 1
SIGMA_S = np.array([0.6, 1.0, 1.6])
LIGHT = np.array([0.4, 0.2, 1.5])
POWER = 200.0


def _z():
    """World z at the point (Object coordinates of an object at the origin)."""
    return SeparateChannel(ObjectSpacePosition(np.eye(4)), 2)


def _ramp(a=A, shift=0.0):
    """f(z) = a (z - shift)."""
    return Math("MULTIPLY", Math("SUBTRACT", _z(), shift), a)


def _slab(density, absorption=SIGMA_A, scattering=(0.0, 0.0, 0.0), floor=-0.2,
          light=None, width=8):
    """Looking straight down (orthographic, 1 m wide) through a 20 x 20 m volume-only slab
    z 0..0.5 whose density is the node `density` (None: homogeneous at density 1), an
    emissive floor of radiance 1 at z = floor (None: none; inside the slab, the camera
    sees it through the slab's upper part only: a ray through all of the slab reads the
    mean density alone), a point light of 200 W at `light` (None: none), black world."""
    s = PaperScene(width, width)
    s.add_material(Material("fog", volume_only=True, absorption=absorption,
                            scattering=scattering, density_texture=density))
    s.add_box((0, 0, 0.25), (20.0, 20.0, 0.5), "fog", name="slab")
    if floor is not None:
        s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
        s.add_plane((0, 0, floor), (0, 0, 1), 30.0, "glow", name="floor")
    if light is not None:
        s.add_point_light(tuple(light), power=POWER)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    return s


def _image(scene, **kw):
    kw = {"workers": 1, "spp": 64, "photon_mapping": False, "seed": 4, **kw}
    film = render(scene, RenderSettings(**kw))
    return np.asarray(film.combined, np.float64)[..., :3]


def test_material_field_and_the_stand_in():
    with pytest.raises(SceneError, match="density_texture"):
        Material("bad", volume_only=True, absorption=SIGMA_A, density_texture=1.0)
    ctx = prepare_context(_slab(_ramp()), RenderSettings(workers=1))
    het = ctx.hetero
    assert isinstance(het, HeterogeneousMedia) and len(het.fields) == 1
    (m, f), = het.fields.items()
    # the ramp's mean over the slab is A x 0.25 = 1, its largest value A x 0.5 = 2
    assert f.f_mean == pytest.approx(1.0, rel=0.02)
    assert f.f_max == pytest.approx(2.0, rel=0.02)
    np.testing.assert_allclose(ctx.table.absorption[m], f.f_mean * SIGMA_A)
    # a material without a density texture: no heterogeneous media
    assert prepare_context(_slab(None), RenderSettings(workers=1)).hetero is None


def test_counter_based_numbers_are_uniform_and_depend_on_the_ray():
    o = np.random.default_rng(0).random((20000, 3))
    d = np.tile([0.0, 0.0, 1.0], (20000, 1))
    k = ray_keys(5, o, d)
    u = uniforms(k, 0)
    assert 0.0 <= u.min() and u.max() < 1.0
    assert u.mean() == pytest.approx(0.5, abs=0.01) and u.var() == pytest.approx(1 / 12, rel=0.03)
    assert abs(np.corrcoef(u, uniforms(k, 1))[0, 1]) < 0.03
    np.testing.assert_array_equal(k, ray_keys(5, o.copy(), d))
    assert not np.array_equal(k, ray_keys(6, o, d))


def test_camera_transmittance_of_a_linear_ramp():
    """An absorbing slab, density A z, an emissive floor inside it at z = 0.25: seen
    through the upper half it keeps exp(-sigma_a A (0.5^2 - 0.25^2) / 2) per channel
    (the mean density's stand-in would give exp(-sigma_a 0.25), 1.1-1.6x as bright;
    residual ratio tracking on the camera segment; 8 x 8 px x 256 spp, within 1.5 %)."""
    img = _image(_slab(_ramp(), floor=0.25), spp=256)
    expect = np.exp(-SIGMA_A * A * (0.25 - 0.0625) / 2)
    assert np.isfinite(img).all()
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), expect, rtol=0.015)


def test_shadow_rays_through_a_ramped_box():
    """A straight-down sun of 2 W/m^2 over a 2 x 2 x 0.8 m box (z 0.6..1.4) whose density
    is z, a floor at z = 1 through its middle: the floor inside the box gets
    2 exp(-sigma_a (1.4^2 - 1) / 2) per channel (its shadow rays leave through the box's
    top: the stand-in would give 2 exp(-sigma_a 0.4)), the one under it (z = 0, the
    middle floor cut away there) 2 exp(-sigma_a (1.4^2 - 0.6^2) / 2); the mean of 3000
    ratio-tracked shadow rays within 4 standard errors (and 3 %)."""
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_plane((-2.5, 0, 1.0), (0, 0, 1), 5.0, "white_diffuse", name="middle")
    s.add_material(Material("ramp", volume_only=True, absorption=SIGMA_A,
                            density_texture=_ramp(1.0)))
    s.add_box((0, 0, 1.0), (2.0, 2.0, 0.8), "ramp", name="box")
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    ctx = prepare_context(s, RenderSettings(workers=1))
    for x0, z, expect in ((-0.5, 1.0, 2.0 * np.exp(-SIGMA_A * (1.4 ** 2 - 1.0) / 2)),
                          (0.5, 0.0, 2.0 * np.exp(-SIGMA_A * (1.4 ** 2 - 0.6 ** 2) / 2))):
        hit = _hits_at(ctx, 3000, x0, z)
        E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
        mean, se = E.mean(axis=0), E.std(axis=0) / math.sqrt(len(E))
        assert np.all(np.abs(mean - expect) < 4 * se + 1e-9), (z, mean, expect, se)
        np.testing.assert_allclose(mean, expect, rtol=0.03)
        assert E.min() >= 0.0  # the residual's bound holds: no negative weights


def _hits_at(ctx, n, x0, z, half=0.4):
    """Hits on the horizontal surface at height z of n rays straight down around (x0, 0)."""
    rng = np.random.default_rng(0)
    o = np.column_stack([x0 + rng.uniform(-half, half, n), rng.uniform(-half, half, n),
                         np.full(n, z + 0.05)]) - ctx.geo.offset
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, d)
    keep = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])


def _ramp_single_scattering(light=LIGHT, n_xy=24, n_s=400):
    """The slab's single scattering of the point light at density A z, by quadrature over
    the film and along each vertical ray: int sigma_s(z) e^{-tau_cam(z)} p I / r^2
    e^{-tau_shadow(z)} ds, isotropic phase, tau_cam(z) = sigma_t A (0.25 - z^2) / 2, the
    shadow ray's tau that x r / (light_z - z) (it leaves through the top)."""
    sig_t = SIGMA_A + SIGMA_S
    I = POWER / (4 * math.pi)
    xs = (np.arange(n_xy) + 0.5) / n_xy - 0.5
    ds = 0.5 / n_s
    s = (np.arange(n_s) + 0.5) * ds
    X, Y, Sg = np.meshgrid(xs, xs, s, indexing="ij")
    Z = 0.5 - Sg
    v = np.stack([light[0] - X, light[1] - Y, light[2] - Z], axis=-1)
    r = np.linalg.norm(v, axis=-1)
    F = A * (0.25 - Z ** 2) / 2
    out = np.zeros(3)
    for c in range(3):
        f = (SIGMA_S[c] * A * Z * np.exp(-sig_t[c] * F * (1.0 + r / (light[2] - Z)))
             / (4 * math.pi) * I / r ** 2)
        out[c] = f.sum(axis=-1).mean() * ds
    return out


def test_single_scattering_of_a_ramp_matches_quadrature():
    """A scattering slab of density A z under a point light, no floor: the camera
    segment's scatter point weighted by its ratio-tracked T(s) and density, its shadow
    ray ratio-tracked to the slab's top. 8 x 8 px x 256 spp: within 2 % per channel."""
    img = _image(_slab(_ramp(), scattering=SIGMA_S, floor=None, light=LIGHT), spp=256)
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), _ramp_single_scattering(),
                               rtol=0.02)


def test_a_constant_texture_renders_as_the_homogeneous_medium():
    """Density 0.7 from a node against the homogeneous slab with 0.7 x the coefficients.
    Seen through (absorption only): the stand-in is the mean density itself and the
    majorant grid's control is 0.7 everywhere with nothing to track (its bound is 0), so
    the images agree to rounding. With a point light's scattering the textured slab
    draws its distances along the grid's majorant (here the stand-in's exponential,
    without the equiangular share): another unbiased estimate, the images' means within
    1.5 % at 64 spp."""
    het = _image(_slab(Math("ADD", 0.7, 0.0)), spp=16)
    hom = _image(_slab(None, absorption=0.7 * SIGMA_A), spp=16)
    np.testing.assert_allclose(het, hom, rtol=1e-9, atol=1e-12)
    het = _image(_slab(Math("ADD", 0.7, 0.0), scattering=SIGMA_S, light=LIGHT), spp=64)
    hom = _image(_slab(None, absorption=0.7 * SIGMA_A, scattering=0.7 * SIGMA_S,
                       light=LIGHT), spp=64)
    np.testing.assert_allclose(het.reshape(-1, 3).mean(axis=0),
                               hom.reshape(-1, 3).mean(axis=0), rtol=0.015)


def _cloud_field():
    """A cloud's density: 4 x a Color Ramp (black below 0.45, white above 0.62) of a
    Noise Texture (Scale 2.5, Detail 2) of the Object coordinates (the feature matrix's
    volume_cloud, reading Generated there)."""
    from engine.shadernodes import ColorRamp, Noise
    noise = Noise(ObjectSpacePosition(np.eye(4)), {"Scale": 2.5, "Detail": 2.0})
    ramp = ColorRamp(noise, [0.45, 0.62], [(0, 0, 0), (1, 1, 1)])
    return Math("MULTIPLY", ramp, 4.0)


@pytest.mark.parametrize("field", ["ramp", "cloud"])
def test_the_majorant_grid_bounds_the_field(field):
    """At 20,000 random points of the object (a 1.6 x 1.6 x 1.2 m box; the ramp A z on
    the slab): the field lies within the cell's residual bound about its control
    (ctrl +- rad, engine/majorant.py) and below the cell's sampling majorant sup; the
    cloud's grid tracks at a mean rate well below one bound for the whole box (the
    largest |f - f_mean| x 1.25: hetvol39's), and its clear air takes no steps."""
    if field == "ramp":
        ctx = prepare_context(_slab(_ramp()), RenderSettings(workers=1))
        lo, hi = np.array([-10.0, -10.0, 0.0]), np.array([10.0, 10.0, 0.5])
    else:
        s = PaperScene(8, 6)
        s.add_material(Material("cloud", volume_only=True, absorption=(0.2, 0.2, 0.2),
                                scattering=(0.8, 0.8, 0.8), density_texture=_cloud_field()))
        s.add_box((0.0, 0.0, 0.0), (1.6, 1.6, 1.2), "cloud", name="cloud")
        s.add_sun((0, 0, -1), 2.0)
        s.set_camera((0, -6, 3), (0, 0, 0))
        ctx = prepare_context(s, RenderSettings(workers=1))
        lo, hi = np.array([-0.8, -0.8, -0.6]), np.array([0.8, 0.8, 0.6])
    het = ctx.hetero
    (m, _), = het.fields.items()
    g = het.grid
    k = int(het.object[0])
    slot = int(g.slot_of[k, m])
    p = lo + (hi - lo) * np.random.default_rng(7).random((20000, 3))
    f = het.density(m, p - ctx.geo.offset, np.full(len(p), k))
    n = g.dims[slot]
    i = np.clip(np.floor((p - ctx.geo.offset - g.origin[slot]) / g.cell[slot]).astype(int),
                0, n - 1)
    flat = g.offset[slot] + (i[:, 0] * n[1] + i[:, 1]) * n[2] + i[:, 2]
    assert np.all(np.abs(f - g.ctrl[flat]) <= g.rad[flat] + 1e-9)
    assert np.all(f <= g.sup[flat] + 1e-9)
    if field == "cloud":
        assert 0.0 < f.mean() and (f == 0).mean() > 0.3 and f.max() > 3.9
        f_mean = het.fields[m].f_mean
        assert g.rad.mean() < 0.5 * (f.max() - f_mean) * 1.25
        assert np.all(g.rad[g.sup == 0] == 0) and (g.sup == 0).mean() > 0.1


def test_single_scattering_drawn_along_the_majorant_of_a_linear_ramp():
    """Distances drawn along the majorant grid (HeterogeneousMedia.scatter) on rays
    straight down through the slab of density A z: the weights T(s) sigma_s(s) / pdf(s)
    average to the closed form int_0^0.5 sigma_s(s) T(s) ds = sigma_s / sigma_t (1 -
    exp(-sigma_t A 0.5^2 / 2)) per channel (T ratio-tracked against the grid's control;
    20,000 rays, stratified numbers, within 1 %), and every point lies in the slab with
    density above 0 (the pdf follows the field)."""
    sigma_a = np.array([0.5, 1.0, 2.0])
    ctx = prepare_context(_slab(_ramp(), absorption=sigma_a, scattering=SIGMA_S, floor=None),
                          RenderSettings(workers=1))
    het = ctx.hetero
    (m, _), = het.fields.items()
    K = 20000
    rng = np.random.default_rng(3)
    off = ctx.geo.offset
    o = np.column_stack([rng.uniform(-5, 5, K), rng.uniform(-5, 5, K), np.full(K, 0.5)]) - off
    d = np.tile([0.0, 0.0, -1.0], (K, 1))
    t = np.full(K, 0.5)
    u = (np.arange(K) + rng.random(K)) / K
    pts = np.zeros((K, 3))
    w = np.ones((K, 3))
    pts, w = het.scatter(o, d, t, pts, np.full(K, m), w, u)
    z = (pts + off)[:, 2]
    assert np.all((z > 0.0) & (z < 0.5))
    sigma_t = sigma_a + SIGMA_S
    expect = SIGMA_S / sigma_t * -np.expm1(-sigma_t * A * 0.25 / 2)
    np.testing.assert_allclose(w.mean(axis=0), expect, rtol=0.01)


def test_the_same_image_for_any_worker_count():
    scene = _slab(_ramp(), scattering=SIGMA_S, light=LIGHT)
    a = _image(scene, spp=4, seed=9)
    b = _image(_slab(_ramp(), scattering=SIGMA_S, light=LIGHT), spp=4, seed=9, workers=2)
    np.testing.assert_array_equal(a, b)
    c = _image(_slab(_ramp(), scattering=SIGMA_S, light=LIGHT), spp=4, seed=10)
    assert not np.array_equal(a, c)


def test_zero_density_regions_and_an_empty_field():
    """Density A (z - 0.25), negative (read as 0) in the slab's lower half, an emissive
    floor inside the slab at z = 0.1: finite, and the floor keeps exp(-sigma_a A / 32)
    (the stand-in: exp(-sigma_a A / 40)); a field 0 everywhere shows the floor as it is."""
    img = _image(_slab(_ramp(shift=0.25), floor=0.1), spp=256)
    assert np.isfinite(img).all()
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0),
                               np.exp(-SIGMA_A * A * 0.25 ** 2 / 2), rtol=0.015)
    empty = _image(_slab(Math("MULTIPLY", _z(), 0.0), scattering=SIGMA_S, light=LIGHT),
                   spp=4)
    assert np.isfinite(empty).all()
    np.testing.assert_allclose(empty, 1.0, rtol=1e-9)


def test_a_lamp_and_a_floor_inside_a_ramped_box():
    """A 50 W point light at z = 1.3 inside the box of density z (z 0.6..1.4) and a white
    floor through the box at z = 1, seen from above through the box's top: each pixel
    T_cam 0.8 / pi I cos / r^2 T_shadow with T_cam = exp(-sigma_a (1.4^2 - 1) / 2) and the
    shadow ray, which meets no surface (directlight's in-medium rays), T_shadow =
    exp(-sigma_a (1.3^2 - 1) / 2 x r / 0.3): the image's mean against a quadrature over
    the film within 2 % (the stand-in would be 1.07-1.23x as bright)."""
    s = PaperScene(8, 8)
    s.add_material(Material("ramp", volume_only=True, absorption=SIGMA_A,
                            density_texture=_ramp(1.0)))
    s.add_box((0, 0, 1.0), (2.0, 2.0, 0.8), "ramp", name="box")
    s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, "white_diffuse", name="middle")
    power = 50.0
    s.add_point_light((0.0, 0.0, 1.3), power=power)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=0.2)
    img = _image(s, spp=256)
    xs = ((np.arange(48) + 0.5) / 48 - 0.5) * 0.2
    X, Y = np.meshgrid(xs, xs)
    r = np.sqrt(X ** 2 + Y ** 2 + 0.09)
    E = power / (4 * math.pi) * (0.3 / r) / r ** 2
    expect = np.array([np.mean(0.8 / math.pi * E * np.exp(-sa * (1.4 ** 2 - 1) / 2)
                               * np.exp(-sa * (1.3 ** 2 - 1) / 2 * r / 0.3))
                       for sa in SIGMA_A])
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), expect, rtol=0.02)


def _ramped_box_under_sun(absorption, density):
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_plane((-2.5, 0, 1.0), (0, 0, 1), 5.0, "white_diffuse", name="middle")
    s.add_material(Material("ramp", volume_only=True, absorption=absorption,
                            density_texture=density))
    s.add_box((0, 0, 1.0), (2.0, 2.0, 0.8), "ramp", name="box")
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    return prepare_context(s, RenderSettings(workers=1))


def test_photons_through_a_ramped_box():
    """The sun's photons landing on the floor through the box's middle (z = 1, density z
    above it up to 1.4) against the same scene with a clear box (the same seed: the same
    paths): exp(-sigma_a (1.4^2 - 1) / 2) per channel, the stand-in's exp(-sigma_a 0.4)
    8-16 % off; within 3 % (about 1000 photons, each ratio-tracked)."""
    from engine.photons import DIRECT, trace_photons

    def power(ctx):
        ph = trace_photons(ctx, ctx.lights, [100_000], caustic_only=False, stream=3)
        pos = ph.position.astype(np.float64) + ctx.geo.offset
        on = ((np.abs(pos[:, 2] - 1.0) < 1e-3) & (pos[:, 0] > -0.8) & (pos[:, 0] < -0.1)
              & (np.abs(pos[:, 1]) < 0.8) & (ph.kind == DIRECT))
        return ph.power[on].astype(np.float64).sum(axis=0), int(on.sum())

    a, n = power(_ramped_box_under_sun(SIGMA_A, _ramp(1.0)))
    b, _ = power(_ramped_box_under_sun((0.0, 0.0, 0.0), None))
    assert n > 500 and b.min() > 0
    np.testing.assert_allclose(a / b, np.exp(-SIGMA_A * (1.4 ** 2 - 1.0) / 2), rtol=0.03)


def test_volume_bounces_and_photons_are_seeded_and_finite():
    """Volume bounces 2 with photon mapping (the camera walks and the photons' free
    flights through the ramped slab, a white floor under it): the same image for 1 and 2
    workers, finite, and brighter than single scattering alone."""
    def scene():
        s = _slab(_ramp(), scattering=SIGMA_S, floor=None, light=LIGHT)
        s.add_plane((0, 0, -0.2), (0, 0, 1), 30.0, "white_diffuse", name="ground")
        return s
    kw = dict(spp=4, seed=3, photon_mapping=True, photons=20_000, volume_bounces=2)
    a = _image(scene(), **kw)
    b = _image(scene(), workers=2, **kw)
    np.testing.assert_array_equal(a, b)
    assert np.isfinite(a).all()
    single = _image(scene(), **{**kw, "volume_bounces": 0})
    assert a.mean() > single.mean()


def test_a_tree_that_cannot_be_read_inside_a_volume_is_warned():
    """A density tree reading a surface's normal (ObjectNormal: a PointGeometry has no
    normals): warned, naming the material, and rendered homogeneous at density 1."""
    from engine.shadernodes import Coordinates, ObjectNormal
    node = SeparateChannel(ObjectNormal(Coordinates("normal")), 2)
    scene = _slab(node, floor=0.25)
    ctx = prepare_context(scene, RenderSettings(workers=1))
    assert not ctx.hetero.fields
    assert any("'fog'" in w and "density texture" in w for w in ctx.hetero.limits())
    film = render(_slab(node, floor=0.25), RenderSettings(workers=1, spp=1,
                                                          photon_mapping=False))
    img = np.asarray(film.combined, np.float64)[..., :3]
    np.testing.assert_allclose(img, np.broadcast_to(np.exp(-SIGMA_A * 0.25), img.shape),
                               rtol=1e-6)
    assert any("density texture" in w for w in film.stats["warnings"])
