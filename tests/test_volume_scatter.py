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
    above it (None: no light), black world; behind=True puts an emissive floor (radiance 1) at z = -0.2."""
    s = PaperScene(width, width)
    s.add_material(Material("fog", volume_only=True, absorption=SIGMA_A, scattering=SIGMA_S,
                            anisotropy=g))
    s.add_box((0, 0, 0.25), (20.0, 20.0, 0.5), "fog", name="slab")
    if behind:
        s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
        s.add_plane((0, 0, -0.2), (0, 0, 1), 30.0, "glow", name="floor")
    if light is not None:
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
    ratio, expect = floor_photon_dimming(_fog_cube, np.array([0.4, 0.2, 0.05]))
    np.testing.assert_allclose(ratio, expect, rtol=2e-3)


def floor_photon_dimming(scene_of, sigma):
    """The direct photons' power on the floor within 0.1 m under a lamp 1 m above it, in
    scene_of(sigma) over scene_of(clear) (the same seed: the same paths), and the
    exp(-sigma r) it should be (r from the lamp to each photon): ((3,), (3,))."""
    from engine.photons import DIRECT, trace_photons
    from engine.render import prepare_context

    def floor_power(sig):
        ctx = prepare_context(scene_of(sig), RenderSettings(workers=1))
        ph = trace_photons(ctx, ctx.lights, [40_000], caustic_only=False, stream=3)
        pos = ph.position.astype(np.float64) + ctx.geo.offset
        under = ((np.abs(pos[:, 2]) < 1e-3) & (np.hypot(pos[:, 0], pos[:, 1]) < 0.1)
                 & (ph.kind == DIRECT))
        return ph.power[under].astype(np.float64).sum(axis=0), pos[under]
    fog, where = floor_power(sigma)
    clear, _ = floor_power(np.full(3, 1e-9))
    r = np.sqrt(1.0 + (where[:, 0] ** 2 + where[:, 1] ** 2))
    return fog / clear, np.exp(-sigma[None, :] * r[:, None]).mean(axis=0)


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
                        np.full(n, 10.0), u, up, spot, 0.5, 0.5, src, p, w, m)
    assert k == n
    s = p[:, 0] + 5.0
    half = 2.0 * math.tan(math.acos(0.9))
    a, b = 5.0 - half, 5.0 + half
    inside = (s >= a) & (s <= b)
    assert w[:, 0].mean() == pytest.approx(1.0 - math.exp(-1.0), rel=0.01)
    assert (w[:, 0] * inside).mean() == pytest.approx(math.exp(-sigma * a)
                                                     - math.exp(-sigma * b), rel=0.01)
    assert inside.mean() > 0.55  # 0.5 + 0.5 x 0.19 aim at the cone (unclipped: ~0.29)


# ---------------------------------------------------------------- fog37: area lights
def _area_row(pos, axis, u, v, size=(1.0, 1.0), disk=False, spread=math.pi):
    """equiangular_rows' row of an area light (a stand-in Light with the packed slots)."""
    from engine.lights import packing as pk
    from engine.volumescatter import equiangular_rows
    q = np.zeros((1, pk.P))
    q[0, pk.POS:pk.POS + 3], q[0, pk.DIR:pk.DIR + 3] = pos, axis
    q[0, pk.U:pk.U + 3], q[0, pk.V:pk.V + 3] = u, v
    q[0, pk.SIZE_X], q[0, pk.SIZE_Y], q[0, pk.IS_DISK] = size[0], size[1], disk
    q[0, pk.AREA_] = size[0] * size[1] * (math.pi / 4 if disk else 1.0)

    class L:
        pass
    light = L()
    light.spread = spread
    return equiangular_rows([light], np.array([pk.CODE_AREA]), q, [0])


def test_lit_interval_of_an_area_light_is_its_front_side_and_spread():
    """Cycles' area_light_valid_ray_segment: the part of a segment in front of the light's
    plane; with a spread below 180 degrees, also inside the cone of half the spread whose
    apex lies behind the light by its extent / tan(spread / 2)."""
    from engine.volumescatter import lit_interval
    down = ((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    row = _area_row(*down)
    # A vertical ray from z = 2 down to z = -3: lit below the plane z = 0.
    a, b = lit_interval(0.3, 0.0, 2.0, 0.0, 0.0, -1.0, 5.0, row, 0)
    assert a == pytest.approx(2.0, abs=1e-12) and b == pytest.approx(5.0, abs=1e-12)
    # Upwards from below: lit until it crosses the plane.
    a, b = lit_interval(5.0, 0.0, -1.0, 0.0, 0.0, 1.0, 4.0, row, 0)
    assert a == pytest.approx(0.0) and b == pytest.approx(1.0, abs=1e-12)
    # Parallel to the plane: all of it under, none of it above.
    assert lit_interval(-5.0, 0.0, -1.0, 1.0, 0.0, 0.0, 10.0, row, 0) == (0.0, 10.0)
    a, b = lit_interval(-5.0, 0.0, 1.0, 1.0, 0.0, 0.0, 10.0, row, 0)
    assert not b > a
    # Spread 60 degrees, a 1 x 1 square: apex at z = extent / tan(30.06 deg) above it.
    row = _area_row(*down, spread=math.radians(60.0))
    half = math.radians(30.0) + 1e-3
    apex = 0.5 * math.sqrt(2.0) / math.tan(half)
    assert row[0, 6] == pytest.approx(math.cos(half)) and row[0, 7] == pytest.approx(apex)
    assert row[0, 16] == pytest.approx(math.sqrt(1.0 / math.pi))  # the widened peak
    # A horizontal ray 2 m under the light: inside the cone over |x| <= (2 + apex) tan.
    r = (2.0 + apex) * math.tan(half)
    a, b = lit_interval(-5.0, 0.0, -2.0, 1.0, 0.0, 0.0, 10.0, row, 0)
    assert a == pytest.approx(5.0 - r, abs=1e-9) and b == pytest.approx(5.0 + r, abs=1e-9)
    # Every ray leaving the light within the spread stays inside the cone.
    rng = np.random.default_rng(3)
    for _ in range(200):
        x0, y0 = rng.random(2) - 0.5
        ang, phi = rng.random() * math.radians(30.0), rng.random() * 2 * math.pi
        w = np.array([math.sin(ang) * math.cos(phi), math.sin(ang) * math.sin(phi),
                      -math.cos(ang)])
        a, b = lit_interval(x0, y0, 0.0, *w, 20.0, row, 0)
        assert a < 1e-9 and b == pytest.approx(20.0)


@pytest.mark.parametrize("thin", [0.5, 0.2])
def test_distances_aimed_at_an_area_light_stay_unbiased(thin):
    """sample_segments with an area light (a 1 x 1 square at z = 0 facing down, the
    segment crossing its plane, aimed at its centre) and the exponential share in
    [thin, 0.5] (adaptive_share of the segment's optical depth against the light's
    equiangular_gain): the weights T(s) sigma_s / pdf(s) integrate the whole segment
    (1 - e^-tau) and its part in front of the light (the pdf: the mixture)."""
    from engine.volumescatter import (adaptive_share, equiangular_gain, lit_interval,
                                      sample_segments)
    n = 200_000
    sigma = 0.1
    row = _area_row((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    rng = np.random.default_rng(7)
    u, up = rng.random(n), rng.random(n)
    src, p, w, m = (np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)),
                    np.empty(n, np.int64))
    d = np.array([0.6, 0.0, -0.8])  # from (-3, 0, 4): crosses z = 0 at s = 5
    k = sample_segments(np.zeros(n, np.int64), np.zeros(1, np.int32),
                        np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]),
                        np.full((1, 3), sigma), np.full((1, 3), sigma), np.zeros(n, np.int64),
                        np.tile([-3.0, 0.0, 4.0], (n, 1)), np.tile(d, (n, 1)),
                        np.full(n, 10.0), u, up, row, thin, 0.5, src, p, w, m)
    assert k == n
    s = (4.0 - p[:, 2]) / 0.8
    front = s >= 5.0
    assert w[:, 0].mean() == pytest.approx(1.0 - math.exp(-1.0), rel=0.01)
    assert (w[:, 0] * front).mean() == pytest.approx(math.exp(-0.5) - math.exp(-1.0), rel=0.01)
    tau = 1.0
    a, b = lit_interval(-3.0, 0.0, 4.0, *d, 10.0, row, 0)
    assert a == pytest.approx(5.0) and b == pytest.approx(10.0)
    rho = equiangular_gain(-3.0, 0.0, 4.0, *d, 10.0, a, b, 0.0, 0.0, 0.0, row[0, 16])
    share = adaptive_share(tau, rho, 1, thin, 0.5)
    # the equiangular share all lands in front: (1 - share) + share x the exponential's
    expect = (1 - share) + share * (math.exp(-0.5) - math.exp(-1.0)) / (1.0 - math.exp(-1.0))
    assert front.mean() == pytest.approx(expect, abs=0.005)


AREA = dict(center=(0.3, 0.1, 1.2), size=0.8, power=200.0)


def _area_slab_scene(spread=math.pi, width=8):
    s = _slab_scene(0.3, width=width, light=None)
    light = s.add_rect_area_light(AREA["center"], AREA["size"], AREA["power"],
                                  direction=(0.2, 0.0, -1.0))
    light.spread = spread
    return s


def _area_single_scattering(g, spread=math.pi, n_xy=16, n_s=160, n_l=14):
    """The image's mean by quadrature for _area_slab_scene: over the film (n_xy^2 pixel
    centres), along each vertical ray through the slab (n_s midpoints) and over the light
    (n_l^2 midpoints of its square, radiance P / (pi A) x spread_attenuation):
    int int e^{-sigma_t (s + l)} sigma_s p(cos) L cos_l / r^2 dA ds."""
    from engine.api import _frame
    from engine.scene import spread_attenuation
    axis = np.array([0.2, 0.0, -1.0])
    axis /= np.linalg.norm(axis)
    u, v, _ = _frame(axis)
    size = AREA["size"]
    L = AREA["power"] / (math.pi * size * size)
    g1 = (np.arange(n_l) + 0.5) / n_l - 0.5
    ly = (np.asarray(AREA["center"]) + size * g1[:, None, None] * u
          + size * g1[None, :, None] * v).reshape(-1, 3)
    dA = size * size / len(ly)
    xs = (np.arange(n_xy) + 0.5) / n_xy - 0.5
    S = SLAB[1] - SLAB[0]
    ds = S / n_s
    sg = (np.arange(n_s) + 0.5) * ds
    sig_t = SIGMA_A + SIGMA_S
    out = np.zeros(3)
    for x in xs:
        X, Y, Sg = np.meshgrid([x], xs, sg, indexing="ij")
        P = np.stack([X, Y, SLAB[1] - Sg], axis=-1).reshape(-1, 1, 3)
        vec = ly[None, :, :] - P
        r = np.linalg.norm(vec, axis=-1)
        wi = vec / r[..., None]
        cos_l = -(wi @ axis)
        att = np.where(cos_l > 0, spread_attenuation(cos_l, spread), 0.0)
        cos = -wi[..., 2]
        t = 1 + g * g - 2 * g * cos
        phase = (1 - g * g) / (4 * math.pi * t ** 1.5)
        l_in = (SLAB[1] - P[..., 2]) / wi[..., 2]  # the shadow ray's length in the slab
        geo = phase * L * np.maximum(cos_l, 0) * att / r ** 2 * dA
        Sv = Sg.reshape(-1, 1)
        for c in range(3):
            f = np.exp(-sig_t[c] * (Sv + l_in)) * SIGMA_S[c] * geo
            out[c] += f.sum() * ds
    return out / n_xy ** 2


@pytest.mark.parametrize("spread", [180.0, 60.0], ids=["lambertian", "spread60"])
def test_single_scattering_of_an_area_light_matches_quadrature(spread):
    """A tilted 0.8 m square area light over the fog slab (its light aimed at by
    equiangular sampling: its centre, the segment's part in front of it and inside its
    spread): the image's mean within 2 % of the quadrature (8 x 8, 256 spp)."""
    film = render(_area_slab_scene(math.radians(spread)),
                  RenderSettings(workers=1, spp=256, photon_mapping=False, seed=4))
    img = np.asarray(film.combined, np.float64)[..., :3]
    expect = _area_single_scattering(0.3, math.radians(spread))
    print(img.reshape(-1, 3).mean(axis=0) / expect)
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), expect, rtol=0.02)


def _segments_towards(row, o, d, S, sigma, n, seed, lo=0.5, hi=0.5):
    """sample_segments on n copies of one segment: (s (n,), weights (n,)); the
    exponential's share adaptive_share's in [lo, hi]."""
    from engine.volumescatter import sample_segments
    rng = np.random.default_rng(seed)
    u, up = rng.random(n), rng.random(n)
    src, p, w, m = (np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)),
                    np.empty(n, np.int64))
    k = sample_segments(np.zeros(n, np.int64), np.zeros(1, np.int32),
                        np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]),
                        np.full((1, 3), sigma), np.full((1, 3), sigma), np.zeros(n, np.int64),
                        np.tile(o, (n, 1)), np.tile(d, (n, 1)), np.full(n, S), u, up, row,
                        lo, hi, src, p, w, m)
    assert k == n
    return ((p - o) @ d), w[:, 0]


@pytest.mark.parametrize("radius", [0.0, 0.05])
def test_a_ray_grazing_a_lamp_with_a_radius_is_sampled_where_its_light_is(radius):
    """A ray passing 5 mm from a soft-falloff lamp of radius 5 cm, whose light along it
    is I / (x^2 + D^2 + r^2) (engine/lights/point.py): equiangular sampling widened by the
    radius (_equiangular) draws distances in proportion to it, so the estimate of
    int T sigma_s / (x^2 + D^2 + r^2) ds is unbiased (either way) and, widened, its
    samples' spread is a fraction of the mean (aimed at the centre alone, a peak 5 mm
    wide: several times the mean; fog37, the god ray's rare bright samples)."""
    from engine.volumescatter import EQ_COLUMNS
    row = np.zeros((1, EQ_COLUMNS))
    row[0, 6], row[0, 16] = -1.0, radius
    D, r, sigma, S = 0.005, 0.05, 0.05, 4.0
    o, d = np.array([-2.0, D, 0.0]), np.array([1.0, 0.0, 0.0])
    s, w = _segments_towards(row, o, d, S, sigma, 400_000, 11, 0.1, 0.9)
    est = w * 1.0 / ((s - 2.0) ** 2 + D * D + r * r)
    x = (np.arange(400_000) + 0.5) / 400_000 * S
    exact = np.mean(np.exp(-sigma * x) * sigma / ((x - 2.0) ** 2 + D * D + r * r)) * S
    assert est.mean() == pytest.approx(exact, rel=0.01)
    spread = est.std() / est.mean()
    print(radius, spread)
    assert (spread < 0.5) if radius > 0 else (spread > 1.2)


def test_adaptive_share_sets_the_optical_depth_against_the_lamps_peak():
    """adaptive_share: tau / (tau + rho) in [lo, hi], 1/2 when both strategies are all
    but uniform, 1 without lit lights; equiangular_gain: 0 for a far lamp over its whole
    segment, log(S / (b - a)) for a far lamp's clipped part, log(1 + L^2 / D^2)-like
    near a lamp."""
    from engine.volumescatter import adaptive_share, equiangular_gain
    assert adaptive_share(0.3, 0.0, 0, 0.1, 0.9) == 1.0
    assert adaptive_share(0.0, 0.0, 1, 0.1, 0.9) == 0.5
    assert adaptive_share(1.0, 3.0, 1, 0.1, 0.9) == pytest.approx(0.25)
    assert adaptive_share(1.0, 0.0, 1, 0.1, 0.9) == pytest.approx(0.9)
    assert adaptive_share(0.01, 5.0, 2, 0.1, 0.9) == pytest.approx(0.1)
    far = equiangular_gain(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.5, 1e6, 0.0, 0.0)
    assert far == pytest.approx(0.0, abs=1e-9)
    clipped = equiangular_gain(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 10.0, 2.0, 4.0, 3.0, 1e6, 0.0,
                               0.0)
    assert clipped == pytest.approx(math.log(5.0), abs=1e-9)
    near = equiangular_gain(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 2.0, 1.0, 0.1, 0.0, 0.0)
    assert near == pytest.approx(math.log(1.01 / 0.01), rel=1e-9)


def test_the_same_image_for_any_worker_count_with_an_area_light():
    """The area light's equiangular sampling and the camera segments' stratified numbers
    (the ("volume",) dimension by each path's pixel and sample index): the same image on
    1 and 2 workers (64 x 64 x 16 samples: 4 chunks), another for another seed."""
    a, b, c = (render(_area_slab_scene(width=64),
                      RenderSettings(workers=w, spp=16, seed=seed, photon_mapping=False))
               for w, seed in ((1, 9), (2, 9), (1, 10)))
    np.testing.assert_array_equal(np.asarray(a.combined), np.asarray(b.combined))
    assert not np.array_equal(np.asarray(a.combined), np.asarray(c.combined))


def _fog_ceiling_scene():
    """A grey floor seen directly (orthographic, from 1 m above it), a fog slab z 1.5..2
    above the camera and a point light above the slab: the floor's final-gather rays
    cross the fog (its glow on the floor)."""
    s = PaperScene(48, 48)
    s.add_material(Material("fog", volume_only=True, absorption=SIGMA_A, scattering=SIGMA_S,
                            anisotropy=0.3))
    s.add_box((0, 0, 1.75), (20.0, 20.0, 0.5), "fog", name="slab")
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "grey", name="floor")
    s.add_point_light((0.4, 0.2, 3.0), power=POWER)
    s.set_camera((0, 0, 1.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    return s


def test_the_same_image_for_any_worker_count_with_gather_rays_through_the_fog():
    """The floor's final-gather rays take stratified distance numbers through the fog
    above it (("gather-volume", g)): the same image on 1 and 2 workers (3 chunks), and
    another with those numbers random (integrator.GATHER_VOLUME_STRATIFIED: the path is
    taken)."""
    from engine import integrator
    settings = dict(spp=16, seed=3, photons=20_000)
    a, b = (render(_fog_ceiling_scene(), RenderSettings(workers=w, **settings))
            for w in (1, 2))
    np.testing.assert_array_equal(np.asarray(a.combined), np.asarray(b.combined))
    integrator.GATHER_VOLUME_STRATIFIED = False
    try:
        c = render(_fog_ceiling_scene(), RenderSettings(workers=1, **settings))
    finally:
        integrator.GATHER_VOLUME_STRATIFIED = True
    assert not np.array_equal(np.asarray(a.combined), np.asarray(c.combined))
