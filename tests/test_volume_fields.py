"""Textured media beyond the density (engine/volumefields.py): the emission of a medium
integrated along its density field, a textured emission, a textured albedo.

A volume-only slab z 0..0.5 (20 x 20 m) seen straight down by an orthographic camera, a
black world, no surface to light: the camera's radiance is the emission integral
int_0^H e(z) T(z) dz, T(z) the transmittance from height z up through the slab's top,
whose closed forms (or 1-D quadratures) the tests compare with. A constant texture must
render as the homogeneous medium; seeding as heterogeneous.py's."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import prepare_context, render
from engine.scene import Material, SceneError
from engine.shadernodes import Math, ObjectSpacePosition, SeparateChannel, VectorMath

H = 0.5  # the slab's thickness (m)
A = 4.0  # the ramps' slope: f(z) = A z, 0 at the bottom, 2 at the top
E0 = np.array([1.0, 0.6, 0.3])  # emission colour (W/m^2/sr per m at ramp value 1)
SIGMA_A = np.array([0.5, 1.0, 2.0])  # 1/m at density 1
LIGHT = np.array([0.4, 0.2, 1.5])
POWER = 200.0


def _z():
    """World z at the point (Object coordinates of an object at the origin)."""
    return SeparateChannel(ObjectSpacePosition(np.eye(4)), 2)


def _ramp(a=A):
    return Math("MULTIPLY", _z(), a)


def _slab(absorption=(0.0, 0.0, 0.0), scattering=(0.0, 0.0, 0.0), emission=(0, 0, 0),
          density=None, emission_texture=None, albedo=None, light=None, width=8):
    s = PaperScene(width, width)
    s.add_material(Material("fog", volume_only=True, absorption=absorption,
                            scattering=scattering, volume_emission=emission,
                            density_texture=density, volume_emission_texture=emission_texture,
                            albedo_texture=albedo))
    s.add_box((0, 0, H / 2), (20.0, 20.0, H), "fog", name="slab")
    if light is not None:
        s.add_point_light(tuple(light), power=POWER)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    return s


def _image(scene, **kw):
    kw = {"workers": 1, "spp": 64, "photon_mapping": False, "seed": 4, **kw}
    film = render(scene, RenderSettings(**kw))
    return np.asarray(film.combined, np.float64)[..., :3]


def _mean(img):
    return img.reshape(-1, 3).mean(axis=0)


def _quadrature(e_of_z, tau_of_z, n=4000):
    """int_0^H e(z) exp(-tau(z)) dz by the midpoint rule, per channel (e, tau (n,3))."""
    z = (np.arange(n) + 0.5) / n * H
    return (e_of_z(z) * np.exp(-tau_of_z(z))).sum(axis=0) * (H / n)


def test_material_rejects_a_texture_that_is_not_a_node():
    with pytest.raises(SceneError, match="volume_emission_texture"):
        Material("bad", volume_only=True, volume_emission_texture=1.0)
    with pytest.raises(SceneError, match="albedo_texture"):
        Material("bad", volume_only=True, albedo_texture=(0.5, 0.5, 0.5))


def test_a_linear_emission_ramp_in_a_clear_slab():
    """e(z) = E0 A z, no extinction: the camera sees int_0^H e dz = E0 A H^2 / 2
    (uniform distances, stratified along each segment; the ramp's linear part integrates to
    within noise). The stand-in (the mean E0 A H / 2 over the slab) is the same integral
    here; the ramp's own samples decide it: within 1 %."""
    tex = VectorMath("MULTIPLY", _ramp(), E0)
    img = _image(_slab(emission_texture=tex), spp=64)
    assert np.isfinite(img).all()
    np.testing.assert_allclose(_mean(img), E0 * A * H ** 2 / 2, rtol=0.01)
    ctx = prepare_context(_slab(emission_texture=tex), RenderSettings(workers=1))
    # the stand-in row: the texture's mean over the slab's bounds
    fog = ctx.table.names.index("fog")
    np.testing.assert_allclose(ctx.table.volume_emission[fog], E0 * A * H / 2, rtol=0.01)


def test_an_emission_ramp_in_an_absorbing_slab_matches_the_closed_form():
    """e(z) = E0 A z under a homogeneous sigma_a: the camera reads
    A E0 [H (1 - e^{-sH}) / s - (1 - e^{-sH} (1 + sH)) / s^2] (w = H - z the depth
    below the top: the bright top is nearer the camera); the homogeneous closed form at
    the mean emission would be E0 A H / 2 (1 - e^{-sH}) / s, 4-14 % darker. Within
    1.5 %."""
    tex = VectorMath("MULTIPLY", _ramp(), E0)
    img = _image(_slab(absorption=SIGMA_A, emission_texture=tex), spp=128)
    s = SIGMA_A
    expect = A * E0 * (H * -np.expm1(-s * H) / s - (1 - np.exp(-s * H) * (1 + s * H)) / s ** 2)
    stand_in = E0 * A * H / 2 * -np.expm1(-s * H) / s
    assert np.all(stand_in / expect < 0.97)  # the test tells the two apart
    np.testing.assert_allclose(_mean(img), expect, rtol=0.015)


def test_a_constant_emission_along_a_density_ramp():
    """Density A z (sigma_a at density 1), a constant emission E0: the camera reads
    int_0^H E0 exp(-sigma_a A (H^2 - z^2) / 2) dz (ratio-tracked transmittance from each
    sampled point up to the top); the stand-in (the mean density's homogeneous glow,
    what rendered before) is 2-9 % off. Within 1.5 %."""
    img = _image(_slab(absorption=SIGMA_A, emission=E0, density=_ramp()), spp=128)
    expect = _quadrature(lambda z: np.tile(E0, (len(z), 1)),
                         lambda z: SIGMA_A * A * (H ** 2 - z[:, None] ** 2) / 2)
    stand_in = E0 * -np.expm1(-SIGMA_A * A * H / 2 * H) / (SIGMA_A * A * H / 2)
    assert np.all(np.abs(stand_in / expect - 1) > 0.02)
    np.testing.assert_allclose(_mean(img), expect, rtol=0.015)


def test_fire_the_density_and_the_emission_from_one_ramp():
    """Density A z and emission E0 A z (a Principled Volume's density and Emission
    Strength from the same texture): int_0^H E0 A z exp(-sigma_a A (H^2 - z^2) / 2) dz,
    which has the closed form E0 (1 - exp(-sigma_a A H^2 / 2)) / sigma_a. Within 1.5 %."""
    img = _image(_slab(absorption=SIGMA_A, density=_ramp(),
                       emission_texture=VectorMath("MULTIPLY", _ramp(), E0)), spp=128)
    expect = E0 * -np.expm1(-SIGMA_A * A * H ** 2 / 2) / SIGMA_A
    np.testing.assert_allclose(_mean(img), expect, rtol=0.015)


def test_a_constant_texture_renders_as_the_homogeneous_medium():
    """A constant emission texture (and a constant albedo texture) against the same
    medium's constant sockets: the same image within noise (1 %): a scattering,
    absorbing, glowing slab under a point light."""
    sig_s = np.array([0.6, 0.5, 0.4])
    albedo = sig_s / (SIGMA_A + sig_s)
    tex = _image(_slab(absorption=SIGMA_A, scattering=sig_s, light=LIGHT,
                       emission_texture=VectorMath("MULTIPLY", Math("ADD", 0.5, 0.0), E0),
                       albedo=VectorMath("ADD", albedo, 0.0)), spp=128)
    hom = _image(_slab(absorption=SIGMA_A, scattering=sig_s, emission=0.5 * E0,
                       light=LIGHT), spp=128)
    np.testing.assert_allclose(_mean(tex), _mean(hom), rtol=0.01)


def _albedo_single_scattering(albedo_of_z, sig_t, light=LIGHT, n_xy=24, n_s=400):
    """The slab's single scattering of the point light (constant sigma_t, albedo a(z)) by
    quadrature over the film and along each vertical ray: int sigma_t a(z)
    e^{-sigma_t (H - z)} p I / r^2 e^{-sigma_t (H - z) r / (light_z - z)} ds."""
    I = POWER / (4 * math.pi)
    xs = (np.arange(n_xy) + 0.5) / n_xy - 0.5
    ds = H / n_s
    s = (np.arange(n_s) + 0.5) * ds
    X, Y, Sg = np.meshgrid(xs, xs, s, indexing="ij")
    Z = H - Sg
    v = np.stack([light[0] - X, light[1] - Y, light[2] - Z], axis=-1)
    r = np.linalg.norm(v, axis=-1)
    out = np.zeros(3)
    for c in range(3):
        f = (sig_t[c] * albedo_of_z(Z, c) * np.exp(-sig_t[c] * (H - Z) * (1.0 + r / (light[2] - Z)))
             / (4 * math.pi) * I / r ** 2)
        out[c] = f.sum(axis=-1).mean() * ds
    return out


def test_an_albedo_ramp_matches_quadrature():
    """A homogeneous extinction sigma_t = (1, 1.5, 2) whose albedo is the colour
    (0.9, 0.6, 0.3) x 2 z (0 at the bottom, the colour at the top): single scattering of
    a point light against the quadrature within 2 % (the stand-in's mean albedo would be
    the colour / 2 everywhere: the slab's upper part, nearer the camera, is brighter)."""
    sig_t = np.array([1.0, 1.5, 2.0])
    col = np.array([0.9, 0.6, 0.3])
    tex = VectorMath("MULTIPLY", Math("MULTIPLY", _z(), 2.0), col)
    img = _image(_slab(absorption=sig_t, light=LIGHT, albedo=tex), spp=256)
    expect = _albedo_single_scattering(lambda Z, c: col[c] * 2 * Z, sig_t)
    stand_in = _albedo_single_scattering(lambda Z, c: col[c] * 0.5 + 0 * Z, sig_t)
    assert np.all(stand_in / expect < 0.9)
    np.testing.assert_allclose(_mean(img), expect, rtol=0.02)
    ctx = prepare_context(_slab(absorption=sig_t, light=LIGHT, albedo=tex),
                          RenderSettings(workers=1))
    # the stand-in: sigma_s = sigma_t x the mean albedo, the extinction unchanged
    fog = ctx.table.names.index("fog")
    np.testing.assert_allclose(ctx.table.scattering[fog], sig_t * col * 0.5, rtol=0.01)
    np.testing.assert_allclose(ctx.table.scattering[fog] + ctx.table.absorption[fog], sig_t)


def test_the_same_image_for_any_worker_count_and_no_nan():
    def scene():
        return _slab(absorption=SIGMA_A, scattering=0.5 * SIGMA_A, density=_ramp(),
                     emission_texture=VectorMath("MULTIPLY", _ramp(), E0),
                     albedo=VectorMath("MULTIPLY", _z(), (1.0, 0.5, 2.5)), light=LIGHT)
    a = _image(scene(), spp=4, seed=9)
    b = _image(scene(), spp=4, seed=9, workers=2)
    np.testing.assert_array_equal(a, b)
    assert np.isfinite(a).all() and a.min() >= 0.0
    c = _image(scene(), spp=4, seed=10)
    assert not np.array_equal(a, c)
    # an albedo texture above 1 is warned (read as 1 there)
    film = render(scene(), RenderSettings(workers=1, spp=1, photon_mapping=False))
    assert any("exceeds 1" in w for w in film.stats.get("warnings", [])), film.stats


def test_volume_bounces_and_photons_through_textured_media():
    """Volume bounces 2 with photons (the walks' glow segments, the photons' free
    flights with the albedo's weight) over a floor: finite, non-negative, workers 1 and
    2 bitwise."""
    def scene():
        s = _slab(absorption=SIGMA_A, scattering=0.5 * SIGMA_A, density=_ramp(),
                  emission_texture=VectorMath("MULTIPLY", _ramp(), E0),
                  albedo=VectorMath("MULTIPLY", _z(), (1.0, 0.5, 1.5)), light=LIGHT)
        s.add_plane((0, 0, -0.3), (0, 0, 1), 30.0, "white_diffuse", name="floor")
        return s
    kw = dict(spp=2, seed=3, photon_mapping=True, photons=5000, volume_bounces=2)
    a = _image(scene(), **kw)
    b = _image(scene(), workers=2, **kw)
    assert np.isfinite(a).all() and a.min() >= 0.0 and a.max() > 0.0
    np.testing.assert_array_equal(a, b)


def test_a_texture_that_cannot_be_read_inside_a_volume_is_warned():
    """An emission texture reading the surface's normal (nothing inside a volume has
    one): warned naming the material, rendered without it; finite."""
    from engine.shadernodes import Coordinates, ObjectNormal
    film = render(_slab(absorption=SIGMA_A, emission=E0,
                        emission_texture=ObjectNormal(Coordinates("normal"))),
                  RenderSettings(workers=1, spp=1, photon_mapping=False))
    warnings = film.stats.get("warnings", [])
    assert any("'fog'" in w and "emission texture cannot be evaluated" in w
               for w in warnings), warnings
    assert np.isfinite(np.asarray(film.combined)).all()
