"""Single scattering in homogeneous media (engine/volumescatter.py): the light a fog slab
scatters towards the camera from a point light, against the single-scattering integral
by quadrature; the extinction sigma_a + sigma_s dimming what is behind; the
Henyey-Greenstein phase function's normalisation and mean cosine; seeding."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.geometry import MaterialTable
from engine.media import absorption_table
from engine.render import render
from engine.scene import Material, SceneError
from engine.volumescatter import hg_phase, scattering_tables

SIGMA_S = np.array([0.6, 1.0, 1.6])  # 1/m per channel
SIGMA_A = np.array([0.3, 0.1, 0.0])
SLAB = (0.0, 0.5)  # z range of the slab
LIGHT = np.array([0.4, 0.2, 1.5])  # above the slab
INSIDE = np.array([0.8, -0.2, 0.3])  # a lamp inside the fog, beside the film (1/r^2)
POWER = 200.0


def test_material_fields_and_tables():
    m = Material("fog", volume_only=True, absorption=SIGMA_A, scattering=SIGMA_S,
                 anisotropy=0.3)
    table = MaterialTable.build([Material("a"), m])
    np.testing.assert_allclose(absorption_table(table)[1], SIGMA_A + SIGMA_S)
    sig_t, sig_s, g = scattering_tables(table)
    np.testing.assert_allclose(sig_s[1], SIGMA_S)
    assert g[1] == pytest.approx(0.3) and g[0] == 0.0
    assert scattering_tables(MaterialTable.build([Material("a")])) is None
    with pytest.raises(SceneError, match="scattering"):
        Material("bad", scattering=(-1.0, 0.0, 0.0))
    with pytest.raises(SceneError, match="anisotropy"):
        Material("bad", anisotropy=1.0)


def _trapezoid(y, x):
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


@pytest.mark.parametrize("g", [0.0, 0.5, -0.7, 0.9])
def test_phase_function_is_normalised_with_mean_cosine_g(g):
    """2 pi int p dmu = 1 (a probability density over the sphere) and the mean cosine
    2 pi int mu p dmu = g (Henyey-Greenstein's defining property)."""
    mu = np.linspace(-1.0, 1.0, 8001)
    p = np.array([hg_phase(x, g) for x in mu])
    assert 2 * math.pi * _trapezoid(p, mu) == pytest.approx(1.0, rel=2e-3)
    assert 2 * math.pi * _trapezoid(mu * p, mu) == pytest.approx(g, abs=3e-3)


def _slab_scene(g, width=8, behind=False, light=LIGHT):
    """Looking straight down (orthographic, 1 m wide) through a 20 x 20 m volume-only
    slab z 0..0.5 (sigma_a, sigma_s per channel, HG g), a point light of 200 W at LIGHT
    above it, black world; behind=True puts an emissive floor (radiance 1) at z = -0.2."""
    s = PaperScene(width, width)
    s.add_material(Material("fog", volume_only=True, absorption=SIGMA_A, scattering=SIGMA_S,
                            anisotropy=g))
    s.add_box((0, 0, 0.25), (20.0, 20.0, 0.5), "fog", name="slab")
    if behind:
        s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
        s.add_plane((0, 0, -0.2), (0, 0, 1), 30.0, "glow", name="floor")
    s.add_point_light(tuple(light), power=POWER)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    return s


def _single_scattering(g, light=LIGHT, n_xy=24, n_s=400):
    """The image's mean by quadrature: over the film square (pixel centres of an n_xy
    grid) and along each vertical ray through the slab (midpoint rule),
    int_0^S e^{-sigma_t s} sigma_s p(cos) I e^{-sigma_t l} / r^2 ds with I = P / 4 pi,
    l the shadow ray's length inside the slab (all of it for a lamp inside),
    cos = (0,0,-1) . w_to_light."""
    sig_t = SIGMA_A + SIGMA_S
    I = POWER / (4 * math.pi)
    xs = (np.arange(n_xy) + 0.5) / n_xy - 0.5
    S = SLAB[1] - SLAB[0]
    ds = S / n_s
    s = (np.arange(n_s) + 0.5) * ds
    X, Y, Sg = np.meshgrid(xs, xs, s, indexing="ij")
    Z = SLAB[1] - Sg
    v = np.stack([light[0] - X, light[1] - Y, light[2] - Z], axis=-1)
    r = np.linalg.norm(v, axis=-1)
    cos = -v[..., 2] / r
    l_in = r if light[2] < SLAB[1] else (SLAB[1] - Z) * r / (light[2] - Z)
    t = 1 + g * g - 2 * g * cos
    phase = (1 - g * g) / (4 * math.pi * t ** 1.5)
    out = np.zeros(3)
    for c in range(3):
        f = np.exp(-sig_t[c] * (Sg + l_in)) * SIGMA_S[c] * phase * I / r ** 2
        out[c] = f.sum(axis=-1).mean() * ds
    return out


@pytest.mark.parametrize("g, light", [(0.0, LIGHT), (0.6, LIGHT), (-0.4, INSIDE)],
                         ids=["isotropic", "forward", "lamp-inside"])
def test_single_scattering_of_a_point_light_matches_quadrature(g, light):
    """The camera's segments through the slab: one distance each (exponential sampling),
    the point light's shadow ray through the slab's top (exp(-sigma_t l); a lamp inside
    the slab: its whole length) and the phase function. 8x8 pixels x 256 spp: the mean
    within 1.5 % per channel."""
    film = render(_slab_scene(g, light=light),
                  RenderSettings(workers=1, spp=256, photon_mapping=False, seed=4))
    img = np.asarray(film.combined, np.float64)[..., :3]
    expect = _single_scattering(g, light)
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), expect, rtol=0.015)


def _floor_in_scattering(n_s=4000):
    """The emissive floor's (radiance 1, under the slab: an infinite plane seen from
    inside the slab) light scattered towards the camera, isotropic phase:
    int_0^S e^{-sigma_t s} sigma_s L_in(h) ds with L_in(h) = (1 / 4 pi) 2 pi
    int_0^1 e^{-sigma_t h / mu} dmu = E_2(sigma_t h) / 2 (the exponential integral),
    h = the point's height above the slab's bottom."""
    from scipy.special import expn
    sig_t = SIGMA_A + SIGMA_S
    S = SLAB[1] - SLAB[0]
    ds = S / n_s
    s = (np.arange(n_s) + 0.5) * ds
    h = S - s
    return np.array([np.sum(np.exp(-sig_t[c] * s) * SIGMA_S[c] * 0.5 * expn(2, sig_t[c] * h))
                     * ds for c in range(3)])


def test_extinction_dims_the_surface_behind_and_scattering_adds_to_it():
    """An emissive floor under the slab is seen through exp(-sigma_t 0.5), and the fog
    scatters both the point light's light and the floor's own (a mesh light, sampled by
    its triangles) towards the camera: the three terms by quadrature (the floor's adds
    0.068 / 0.098 / 0.111; measured: the sum within 0.05 %)."""
    film = render(_slab_scene(0.0, behind=True),
                  RenderSettings(workers=1, spp=256, photon_mapping=False, seed=4))
    img = np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    expect = (np.exp(-(SIGMA_A + SIGMA_S) * 0.5) + _single_scattering(0.0)
              + _floor_in_scattering())
    np.testing.assert_allclose(img, expect, rtol=0.01)


def test_the_same_image_for_any_worker_count():
    a = render(_slab_scene(0.3), RenderSettings(workers=1, spp=4, photon_mapping=False,
                                                seed=9))
    b = render(_slab_scene(0.3), RenderSettings(workers=2, spp=4, photon_mapping=False,
                                                seed=9))
    np.testing.assert_array_equal(np.asarray(a.combined), np.asarray(b.combined))
    c = render(_slab_scene(0.3), RenderSettings(workers=1, spp=4, photon_mapping=False,
                                                seed=10))
    assert not np.array_equal(np.asarray(a.combined), np.asarray(c.combined))


def _furnace_single_scattering(sig, H, n_s=4000):
    """A non-absorbing isotropic slab of thickness H in a uniform radiance-1 enclosure
    (the world above, an emissive floor below), seen from above: T + single scattering,
    e^{-sig H} + int_0^H e^{-sig s} sig L_in(z) ds with L_in(z) = (E_2(sig (H - z)) +
    E_2(sig z)) / 2 (each hemisphere's radiance 1 through the slab above / below z)."""
    from scipy.special import expn
    ds = H / n_s
    s = (np.arange(n_s) + 0.5) * ds
    z = H - s
    lin = 0.5 * expn(2, sig * (H - z)) + 0.5 * expn(2, sig * z)
    return math.exp(-sig * H) + float(np.sum(np.exp(-sig * s) * sig * lin) * ds)


def _furnace_slab(sig, H):
    """An albedo-1 isotropic slab (sigma_s sig, H thick, 40 m wide) over an emissive floor
    of radiance 1 under a white world of radiance 1, seen from above by an orthographic
    camera: a uniform enclosure of radiance 1."""
    s = PaperScene(8, 8, background=(1.0, 1.0, 1.0))
    s.add_material(Material("fog", volume_only=True, scattering=(sig, sig, sig)))
    s.add_box((0, 0, H / 2 + 0.1), (40.0, 40.0, H), "fog", name="slab")
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 400.0, "glow", name="floor")
    s.set_camera((0, 0, H + 1.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    return s


@pytest.mark.parametrize("sig, H", [(0.2, 0.5), (1.0, 1.0), (2.0, 1.0)])
def test_furnace_albedo_one_keeps_the_energy_single_scattering_carries(sig, H):
    """Albedo 1, isotropic phase, a 40 x 40 m slab between a uniform white world
    (radiance 1, sampled by the world light) and an emissive floor (radiance 1, a mesh
    light): the full answer is 1 everywhere (nothing absorbs); the light the slab takes
    out of the camera ray (1 - T) comes back by single scattering up to the higher
    orders, which are not simulated (docs/compatibility.md, Volume scattering). The
    image against the quadrature of T + single scattering within 1 % (measured
    0.9986-1.0022 at 64-256 spp); the energy kept: 0.9845 at optical depth 0.1 (1 - T
    alone: 0.905), 0.616 at 1, 0.349 at 2."""
    s = _furnace_slab(sig, H)
    film = render(s, RenderSettings(workers=1, spp=128, photon_mapping=False, seed=1))
    img = np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    expect = _furnace_single_scattering(sig, H)
    np.testing.assert_allclose(img, expect, rtol=0.01)
    # Energy: never more than the enclosure's 1, and more than the unscattered e^{-tau}.
    assert math.exp(-sig * H) < expect < 1.0
    assert img.max() < 1.0


def _camera_in_fog(scattering):
    """A perspective camera at z 2 inside a 6 x 6 x 4 m volume-only box (z -1..3) looking
    straight down (view angle 4 degrees) at an emissive floor (radiance 1) at z 0 inside
    it; the medium sigma_a (0.5, 0.3, 0.1) /m, and scattering (0.4 /m, isotropic) or none."""
    s = PaperScene(8, 8)
    s.add_material(Material("fog", volume_only=True, absorption=(0.5, 0.3, 0.1),
                            scattering=(0.4, 0.4, 0.4) if scattering else (0.0, 0.0, 0.0)))
    s.add_box((0, 0, 1.0), (6.0, 6.0, 4.0), "fog", name="fog")
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "glow", name="floor")
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), view_angle=4.0)
    film = render(s, RenderSettings(workers=1, spp=16, photon_mapping=False, seed=3))
    return np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)


def test_a_camera_inside_the_fog_starts_its_paths_in_it():
    """engine/mediumstart.py: the camera's first segments, to a floor inside the fog (a
    front face of no medium, which media.py's back-face rule would not see), keep
    exp(-sigma_t 2) (the rays' slant at 2 degrees off the axis: < 0.1 %), and with
    scattering the fog's glow adds on top."""
    absorbing = _camera_in_fog(False)
    np.testing.assert_allclose(absorbing, np.exp(-np.array([0.5, 0.3, 0.1]) * 2.0),
                               rtol=2e-3)
    foggy = _camera_in_fog(True)
    dimmed = np.exp(-(np.array([0.5, 0.3, 0.1]) + 0.4) * 2.0)
    assert np.all(foggy > dimmed * 1.05)  # the floor's light scattered back up the ray


def _fog_cube(sigma_a, view_angle=2.0):
    """A fog cube around the whole scene (a 6 x 6 x 4 m volume-only box, z -1..3, absorbing
    sigma_a per channel): a white floor at z 0 inside it, a 100 W point light at z 1 and
    a perspective camera at z 2 inside it, looking straight down (view angle 2 degrees)."""
    s = PaperScene(8, 8)
    s.add_material(Material("fog", volume_only=True, absorption=sigma_a))
    s.add_box((0, 0, 1.0), (6.0, 6.0, 4.0), "fog", name="fog")
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white_diffuse", name="floor")
    s.add_point_light((0.0, 0.0, 1.0), power=100.0)
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), view_angle=view_angle)
    return s


def test_a_floor_inside_a_fog_cube_is_lit_and_seen_through_the_fog():
    """Everything inside the fog: the floor under the lamp takes I / 1 m^2 x exp(-sigma 1)
    (its shadow rays meet no surface: wholly in the hit's medium, directlight.direct_light
    medium_sigma) and the camera sees it through exp(-sigma 2): 0.8 / pi x 100 / 4 pi x
    exp(-3 sigma) within 0.3 % (the 1-degree half view: cos^3 > 0.9995)."""
    sigma = np.array([0.4, 0.2, 0.05])
    film = render(_fog_cube(sigma), RenderSettings(workers=1, spp=4, photon_mapping=False,
                                                   seed=2))
    img = np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    expect = 0.8 / math.pi * 100.0 / (4 * math.pi) * np.exp(-3.0 * sigma)
    np.testing.assert_allclose(img, expect, rtol=3e-3)


def test_photons_of_a_lamp_inside_the_fog_start_in_it():
    """engine/photons.py _light_medium: the point light's photons start in the fog cube's
    medium, so their first segment to the floor (a front face of no medium) is
    attenuated: the floor's first-hit power under the lamp over the same scene with a
    clear medium (the same seed: the same paths) is exp(-sigma r) for r ~ 1 m."""
    from engine.photons import DIRECT, trace_photons
    from engine.render import prepare_context
    sigma = np.array([0.4, 0.2, 0.05])

    def floor_power(sig):
        ctx = prepare_context(_fog_cube(sig), RenderSettings(workers=1))
        ph = trace_photons(ctx, ctx.lights, [40_000], caustic_only=False, stream=3)
        pos = ph.position.astype(np.float64) + ctx.geo.offset
        under = ((np.abs(pos[:, 2]) < 1e-3) & (np.hypot(pos[:, 0], pos[:, 1]) < 0.1)
                 & (ph.kind == DIRECT))
        return ph.power[under].astype(np.float64).sum(axis=0), pos[under]
    fog, where = floor_power(sigma)
    clear, _ = floor_power(np.full(3, 1e-9))
    r = np.sqrt(1.0 + (where[:, 0] ** 2 + where[:, 1] ** 2))
    expect = np.exp(-sigma[None, :] * r[:, None]).mean(axis=0)
    np.testing.assert_allclose(fog / clear, expect, rtol=2e-3)


def test_a_lamp_inside_a_fog_box_lights_the_floor_outside_through_it():
    """A point light at the centre of an absorbing volume-only box (z 0.5..1.5) over a
    white floor, seen from above (orthographic, 0.5 m, through the box: exp(-sigma 1)):
    the floor's shadow rays enter the box through its bottom (a front face) and end at
    the lamp inside, which no back face closes (shadowtransmittance: the medium entered
    and not left dims the way from the entry to the end, exp(-sigma 0.5 r)). Expected
    by quadrature over the film: 0.8 / pi x I cos / r^2 x exp(-sigma 0.5 r) x exp(-sigma)."""
    sigma = np.array([0.8, 0.4, 0.1])
    s = PaperScene(8, 8)
    s.add_material(Material("fog", volume_only=True, absorption=sigma))
    s.add_box((0, 0, 1.0), (3.0, 3.0, 1.0), "fog", name="fog")
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white_diffuse", name="floor")
    s.add_point_light((0.0, 0.0, 1.0), power=100.0)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=0.5)
    film = render(s, RenderSettings(workers=1, spp=16, photon_mapping=False, seed=2))
    img = np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    xs = (np.arange(64) + 0.5) / 64 * 0.5 - 0.25
    X, Y = np.meshgrid(xs, xs)
    r = np.sqrt(X ** 2 + Y ** 2 + 1.0)
    E = (100.0 / (4 * math.pi) / r ** 3)[..., None] * np.exp(-sigma * 0.5 * r[..., None])
    expect = (0.8 / math.pi * E * np.exp(-sigma)).reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(img, expect, rtol=5e-3)


@pytest.mark.parametrize("sig, H", [(1.0, 1.0), (2.0, 1.0)])
def test_furnace_with_volume_bounces_keeps_all_the_energy(sig, H):
    """The furnace slab (albedo 1, isotropic, radiance 1 all round) with Volume bounces
    64 (engine/volumescatter.py CameraScattering.walk: the path scatters on inside the
    medium, the lamps' light at every point): no energy is lost along a path, so the
    image reads 1 (the enclosure's radiance), where single scattering kept 0.616 / 0.349.
    Measured, mean of 6 seeds at 128 spp: Volume bounces 0 / 1 / 4 / 64: 0.616 / 0.764 /
    0.945 / 1.0004 at optical depth 1, 0.349 / 0.498 / 0.763 / 1.0006 at 2 (sd per seed
    0.006 / 0.010 at 64): within 2.5 % at 256 spp (> 3.5 sd)."""
    s = _furnace_slab(sig, H)
    film = render(s, RenderSettings(workers=1, spp=256, photon_mapping=False, seed=1,
                                    volume_bounces=64))
    img = np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(img, 1.0, rtol=0.025)


@pytest.mark.parametrize("g", [0.0, 0.6, -0.3])
def test_phase_sampling_follows_the_phase_function(g):
    """sample_hg's directions about d: the mean cosine is g and the histogram of cos
    follows 2 pi hg_phase (its density in cos), within the sampling noise."""
    from engine.volumescatter import sample_hg
    rng = np.random.default_rng(5)
    n = 200_000
    d = np.tile(np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81]), (n, 1))
    w = sample_hg(d, np.full(n, g), *rng.random((2, n)))
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, rtol=1e-12)
    cos = (w * d).sum(axis=1)
    assert cos.mean() == pytest.approx(g, abs=0.01)
    hist, edges = np.histogram(cos, bins=20, range=(-1.0, 1.0), density=True)
    mid = 0.5 * (edges[1:] + edges[:-1])
    expect = np.array([2 * math.pi * hg_phase(c, g) for c in mid])
    np.testing.assert_allclose(hist, expect, rtol=0.05, atol=0.01)


def _spot_row(pos, axis, cos_bound, pullback=0.0):
    from engine.volumescatter import EQ_COLUMNS
    row = np.zeros((1, EQ_COLUMNS))
    row[0, 0:3], row[0, 3:6], row[0, 6], row[0, 7] = pos, axis, cos_bound, pullback
    return row


def test_lit_interval_is_the_part_of_the_segment_inside_the_spots_cone():
    """Cycles clips a segment to the spot's cone before equiangular sampling
    (spot_light_valid_ray_segment): a ray 2 m under a spot pointing down meets the cone
    of half-angle acos 0.9 over |x| <= 2 tan; a ray above the apex, none; along the
    axis, from the apex on; a point light (cosine -1), all of it."""
    from engine.volumescatter import lit_interval
    spot = _spot_row((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), 0.9)
    half = 2.0 * math.tan(math.acos(0.9))
    a, b = lit_interval(-5.0, 0.0, -2.0, 1.0, 0.0, 0.0, 10.0, spot, 0)
    assert a == pytest.approx(5.0 - half, abs=1e-9) and b == pytest.approx(5.0 + half, abs=1e-9)
    a, b = lit_interval(-5.0, 0.0, 1.0, 1.0, 0.0, 0.0, 10.0, spot, 0)
    assert not b > a
    a, b = lit_interval(0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 4.0, spot, 0)
    assert a == pytest.approx(1.0, abs=1e-9) and b == pytest.approx(4.0, abs=1e-9)
    a, b = lit_interval(-5.0, 0.0, -2.0, 1.0, 0.0, 0.0, 3.0, spot, 0)  # ends before the cone
    assert not b > a
    point = _spot_row((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), -1.0)
    assert lit_interval(-5.0, 0.0, -2.0, 1.0, 0.0, 0.0, 10.0, point, 0) == (0.0, 10.0)


def test_distances_clipped_to_a_spots_cone_stay_unbiased():
    """sample_segments with a spot: the weights T(s) sigma_s / pdf(s) integrate both the
    whole segment (1 - e^-tau) and its lit part (e^-sigma a - e^-sigma b), the pdf being
    the mixture of the exponential and the cone-clipped equiangular strategy."""
    from engine.volumescatter import sample_segments
    n = 200_000
    sigma = 0.1
    spot = _spot_row((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), 0.9)
    rng = np.random.default_rng(5)
    u, up = rng.random(n), rng.random(n)
    src, p, w, m = (np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)),
                    np.empty(n, np.int64))
    e = np.array([[1.0, 0.0, 0.0]])
    k = sample_segments(np.zeros(n, np.int64), np.zeros(1, np.int32), e,
                        np.array([[0.0, 1.0, 0.0]]), np.full((1, 3), sigma),
                        np.full((1, 3), sigma), np.zeros(n, np.int64),
                        np.tile([-5.0, 0.0, -2.0], (n, 1)), np.tile([1.0, 0.0, 0.0], (n, 1)),
                        np.full(n, 10.0), u, up, spot, src, p, w, m)
    assert k == n
    s = p[:, 0] + 5.0
    half = 2.0 * math.tan(math.acos(0.9))
    a, b = 5.0 - half, 5.0 + half
    inside = (s >= a) & (s <= b)
    assert w[:, 0].mean() == pytest.approx(1.0 - math.exp(-1.0), rel=0.01)
    assert (w[:, 0] * inside).mean() == pytest.approx(math.exp(-sigma * a)
                                                     - math.exp(-sigma * b), rel=0.01)
    assert inside.mean() > 0.55  # 0.5 + 0.5 x 0.19 aim at the cone (unclipped: ~0.29)
