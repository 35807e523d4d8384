"""Cycles' light passes in the engine (engine/lightpasses.py, RenderSettings.data_passes
"light"): analytic values (a Lambert floor under a sun: Diffuse Direct = E / pi as
Blender shows it; a mirror metal ball and the world: Glossy Direct = the world's
radiance; Emission and Environment exactly what the camera sees), light bounced off a
wall in Diffuse Indirect only, glass into Transmission, the recombination
(Dir + Ind) x Col + Emission + Environment = Combined, the image's bits untouched, the
same passes for any worker count and from the adaptive path. The comparison against
live Cycles is tests/blender/test_blender_light_passes.py."""
import numpy as np
import pytest

from engine import RenderSettings
from engine import lightpasses as lp
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material

W, H = 16, 12
EFFECTS = ("direct", "indirect", "caustic", "specular", "emission")
SUN = 2.0
ALBEDO = (0.6, 0.4, 0.2)
WORLD = (0.2, 0.3, 0.5)


def _settings(**kw):
    base = dict(workers=1, spp=4, seed=5, photons=5_000, caustic_photons=2_000,
                data_passes=("light",))
    base.update(kw)
    return RenderSettings(**base)


def _floor_scene(wall=False, background=(0.0, 0.0, 0.0)):
    """A Lambert floor (ALBEDO) seen from 5 m straight above under a sun (strength SUN,
    straight down); with wall, a white wall beside the view lit by a second sun from
    the side (its light reaches the floor only by the wall's bounce)."""
    s = PaperScene(W, H, background=background)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, Material("floor", ALBEDO), name="floor")
    s.add_sun((0.0, 0.0, -1.0), strength=SUN)
    if wall:
        s.add_plane((1.5, 0, 1.0), (-1, 0, 0), 6.0, Material("wall", (0.9, 0.9, 0.9)),
                    name="wall")
    s.set_camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=20.0)
    return s


def _ball_scene(material, emitter=False):
    """A ball of `material` 4 m in front of the camera in a uniform world WORLD (its
    edge and the world around it in view); with emitter, an emitting ball beside it."""
    s = PaperScene(W, H, background=WORLD)
    s.add_sphere((0, 0, 0), 1.0, material, name="ball", segments=64)
    if emitter:
        s.add_sphere((1.6, 0, 0), 0.5, Material("lamp", (0, 0, 0), emission=(2.0, 1.0, 0.5)),
                     name="lamp")
    s.set_camera((0, -4.0, 0), (0, 0, 0), up=(0, 0, 1), view_angle=45.0)
    return s


def _shown(film):
    return lp.shown(film.data)


def _recombined(film):
    d, sh = film.data, _shown(film)
    out = sh["emission"] + sh["environment"] + sh["volume"]
    for k in ("diffuse", "glossy", "transmission"):
        out = out + (sh[f"{k}_direct"] + sh[f"{k}_indirect"]) * d[f"{k}_color"]
    return out


def test_lambert_floor_under_sun():
    """Diffuse Direct as Blender shows it is the irradiance over pi whatever the albedo
    (Cycles divides the albedo out); no indirect light, no other pass."""
    film = render(_floor_scene(), _settings())
    sh = _shown(film)
    np.testing.assert_allclose(sh["diffuse_direct"], SUN / np.pi, rtol=1e-5)
    np.testing.assert_allclose(film.data["diffuse_color"], np.broadcast_to(ALBEDO, (H, W, 3)),
                               rtol=1e-6)
    for key in lp.KEYS:
        if key != "diffuse_direct":
            assert not film.data[key].any(), key


def test_wall_bounce_is_diffuse_indirect():
    """The wall's bounced light on the floor is Diffuse Indirect; Diffuse Direct stays
    the sun's E / pi."""
    film = render(_floor_scene(wall=True), _settings(spp=8))
    sh = _shown(film)
    on_floor = np.abs(film.data["diffuse_color"][..., 0] - ALBEDO[0]) < 1e-6
    assert on_floor.sum() > W * H // 3
    direct = sh["diffuse_direct"][on_floor]
    lit = direct[:, 0] > 0.5 * SUN / np.pi  # (the wall's shadow side aside)
    np.testing.assert_allclose(direct[lit], SUN / np.pi, rtol=1e-5)
    assert sh["diffuse_indirect"][on_floor].mean() > 1e-3
    assert not film.data["glossy_indirect"].any() and not film.data["transmission_indirect"].any()
    np.testing.assert_allclose(_recombined(film), film.combined, rtol=1e-5, atol=1e-7)


def test_mirror_ball_glossy_direct():
    """A mirror metal ball in a uniform world: the world it reflects is Glossy Direct
    (one bounce) and, divided by Glossy Color, the world's radiance (to 1.5 %: the Color
    pass takes principled.setup's albedo estimate, the path the sampled Fresnel); the
    world around it Environment, exactly."""
    film = render(_ball_scene(Material("metal", (0.9, 0.6, 0.3), metallic=1.0,
                                       roughness=0.0)), _settings())
    d, sh = film.data, _shown(film)
    ball = d["glossy_color"][..., 0] > 0.0
    sky = (d["glossy_color"] + d["diffuse_color"]).sum(axis=2) == 0.0
    assert ball.sum() > 20 and sky.sum() > 20
    inner = ball & (d["glossy_color"][..., 0] > 0.5)  # (whole pixels on the ball)
    np.testing.assert_allclose(sh["glossy_direct"][inner], np.broadcast_to(WORLD, (inner.sum(), 3)),
                               rtol=0.015)
    np.testing.assert_allclose(sh["environment"][sky], np.broadcast_to(WORLD, (sky.sum(), 3)),
                               rtol=1e-6)
    for key in ("diffuse_direct", "diffuse_indirect", "transmission_direct",
                "transmission_indirect", "emission", "glossy_indirect"):
        assert not d[key].any(), key


def test_glass_ball_transmission_and_emission():
    """A clear glass ball: the world through it (two refractions) is Transmission
    Indirect, its reflection Glossy Direct; an emitting ball seen directly is Emission,
    exactly its radiance; the passes recombine to Combined."""
    film = render(_ball_scene(Material("glass", (1, 1, 1), transmission=1.0, ior=1.45),
                              emitter=True), _settings(spp=16))
    d, sh = film.data, _shown(film)
    glass = d["transmission_color"][..., 0] > 0.5
    assert glass.sum() > 20
    assert not d["transmission_direct"].any()  # (smooth glass samples no light)
    assert (sh["transmission_indirect"][glass] > 0).all()
    assert sh["glossy_direct"][glass].mean() > 0
    lamp = np.all(np.abs(d["emission"] - (2.0, 1.0, 0.5)) < 1e-6, axis=2)
    assert lamp.sum() > 3
    np.testing.assert_allclose(_recombined(film), film.combined, rtol=1e-5, atol=1e-7)


def test_identity_bits_and_workers():
    """Asking for the light passes leaves the image's bits as they were; the passes sum
    to the effect passes (before the colour divide: float64 sums, float32 film) and are
    the same bits for 1 and 2 workers."""
    s = _floor_scene(wall=True, background=WORLD)
    s.add_sphere((-0.6, 0.3, 0.5), 0.5, Material("metal", (0.9, 0.7, 0.4), metallic=1.0,
                                                 roughness=0.3), name="metal")
    s.add_sphere((0.4, -0.4, 0.4), 0.4, Material("glass", (1, 1, 1), transmission=1.0,
                                                 roughness=0.2), name="glass")
    plain = render(s, _settings(data_passes=()))
    one = render(s, _settings())
    two = render(s, _settings(workers=2))
    for name in EFFECTS:
        assert np.array_equal(getattr(plain, name), getattr(one, name)), name
        assert np.array_equal(getattr(one, name), getattr(two, name)), name
    for key in lp.KEYS:
        assert np.array_equal(one.data[key], two.data[key]), key
    raw = sum(one.data[k].astype(np.float64) for k in lp.KEYS)
    comb = sum(getattr(one, n).astype(np.float64) for n in EFFECTS)
    np.testing.assert_allclose(raw, comb, rtol=1e-6, atol=1e-7)
    assert one.data["glossy_direct"].any() and one.data["transmission_indirect"].any()
    np.testing.assert_allclose(_recombined(one), one.combined, rtol=1e-5, atol=1e-6)


def test_adaptive_carries_light_passes():
    s = _floor_scene(wall=True)
    film = render(s, _settings(adaptive_threshold=0.05, adaptive_min_samples=4, spp=8))
    plain = render(s, _settings(adaptive_threshold=0.05, adaptive_min_samples=4, spp=8,
                                data_passes=()))
    for name in EFFECTS:
        assert np.array_equal(getattr(plain, name), getattr(film, name)), name
    np.testing.assert_allclose(_recombined(film), film.combined, rtol=1e-5, atol=1e-7)


def test_divide_even_color():
    """Cycles' safe_divide_even_color: a zero channel of the divisor takes the others'
    ratio (their mean), all zero gives zero."""
    a = np.array([[2.0, 4.0, 6.0], [2.0, 4.0, 6.0], [2.0, 4.0, 6.0], [1.0, 1.0, 1.0]])
    b = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 3.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(lp.divide_even_color(a, b),
                               [[2.0, 2.0, 2.0], [2.0, 2.0, 2.0], [2.0, 4.0, 6.0],
                                [0.0, 0.0, 0.0]])


def test_settings_bring_color():
    assert RenderSettings(data_passes=("light",)).data_passes == ("color", "light")


def test_progressive_averages_raw_passes():
    """Progressive passes average the raw sums (Film.data), so the recombination of the
    averaged passes is still the averaged Combined."""
    from engine import Budget, render_progressive
    film = render_progressive(_floor_scene(wall=True), _settings(spp=2), Budget(passes=2))
    assert "diffuse_indirect" in film.data
    np.testing.assert_allclose(_recombined(film), film.combined, rtol=1e-5, atol=1e-6)


def test_sheen_is_diffuse_and_specular_layer_glossy():
    """Cycles counts sheen as diffuse: a sheen floor under the sun puts its light in
    Diffuse Direct only; a Principled specular layer's highlight goes to Glossy Direct,
    the base below it to Diffuse Direct."""
    s = _floor_scene()
    s.materials["floor"].sheen_weight = 1.0
    s.materials["floor"].sheen_roughness = 0.5
    film = render(s, _settings())
    assert film.data["diffuse_direct"].any()
    assert not film.data["glossy_direct"].any()
    s = _floor_scene()
    s.add_sun((0.3, 0.0, -1.0), strength=1.0)
    s.materials["floor"].specular = 1.0
    s.materials["floor"].roughness = 0.3
    film = render(s, _settings())
    assert film.data["glossy_direct"].any() and film.data["diffuse_direct"].any()
    raw = sum(film.data[k].astype(np.float64) for k in lp.KEYS)
    comb = sum(getattr(film, n).astype(np.float64) for n in EFFECTS)
    np.testing.assert_allclose(raw, comb, rtol=1e-6, atol=1e-7)


def test_light_linking_keeps_the_identity():
    """With Light Linking (receiver sets split the shaded hits) the glossy part comes
    from a second direct stage: the passes still sum to the image, which keeps its bits."""
    s = PaperScene(W, H, background=(0.0, 0.0, 0.0))
    s.add_material(Material("gloss", ALBEDO, specular=1.0, roughness=0.4))
    s.add_plane((-1.0, 0, 0), (0, 0, 1), (2.0, 4.0), "gloss", name="left", up=(0, 1, 0))
    s.add_plane((1.0, 0, 0), (0, 0, 1), (2.0, 4.0), "gloss", name="right", up=(0, 1, 0))
    key = s.add_point_light((0.5, -1.0, 2.0), power=500.0, radius=0.3, name="key")
    key.receivers = ["left"]
    s.add_sun((0.2, 0.1, -1.0), strength=1.0)
    s.set_camera((0.0, -3.0, 3.0), (0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), view_angle=50.0)
    plain = render(s, _settings(data_passes=()))
    film = render(s, _settings())
    for name in EFFECTS:
        assert np.array_equal(getattr(plain, name), getattr(film, name)), name
    assert film.data["glossy_direct"].any() and film.data["diffuse_direct"].any()
    raw = sum(film.data[k].astype(np.float64) for k in lp.KEYS)
    comb = sum(getattr(film, n).astype(np.float64) for n in EFFECTS)
    np.testing.assert_allclose(raw, comb, rtol=1e-6, atol=1e-7)


def test_fog_light_is_kept_apart():
    """Light scattered in a fog slab towards the camera goes to the volume sum (Volume
    Direct at Volume bounces 0), the emissive floor seen through it to Emission; the
    passes still sum to the image."""
    s = PaperScene(8, 8)
    s.add_material(Material("fog", volume_only=True, absorption=(0.3, 0.1, 0.0),
                            scattering=(0.6, 1.0, 1.6)))
    s.add_box((0, 0, 0.25), (20.0, 20.0, 0.5), "fog", name="slab")
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, -0.2), (0, 0, 1), 30.0, "glow", name="floor")
    s.add_point_light((0.4, 0.2, 1.5), power=200.0)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    film = render(s, _settings())
    d = film.data
    assert d["volume"].min() > 0 and d["emission"].min() > 0
    # At Volume bounces 0 (the settings' default) Blender's Volume Direct is all of it.
    sh = lp.shown(d, volume_bounces=0)
    assert np.array_equal(sh["volume_direct"], d["volume"]) and not sh["volume_indirect"].any()
    assert "volume_direct" not in lp.shown(d, volume_bounces=2)
    raw = sum(d[k].astype(np.float64) for k in lp.KEYS)
    comb = sum(getattr(film, n).astype(np.float64) for n in EFFECTS)
    np.testing.assert_allclose(raw, comb, rtol=1e-6, atol=1e-7)


def test_translucent_light_from_behind_is_diffuse_direct():
    """A Translucent BSDF sheet lit by a sun from behind: Cycles counts the translucent
    closure among its diffuse ones, so the light it lets through is Diffuse Direct
    (measured against Cycles 5.0: 1.2219 / 1.2211 on a sheet of colour 0.8, Transmission
    Direct 0 in both); before s40 it reached no pass and the passes did not sum to the
    image. The sheet's light is E x colour / pi, which Blender shows divided by the
    colour: E / pi."""
    s = PaperScene(W, H, background=(0.0, 0.0, 0.0))
    sheet = Material("sheet", (0.8, 0.8, 0.8), translucent=1.0, roughness=1.0)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, sheet, name="sheet")
    s.add_sun((0.0, 0.0, 1.0), strength=SUN)  # travelling up: it lights the sheet's back
    s.set_camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=20.0)
    film = render(s, _settings(photons=2_000, caustic_photons=0))
    sh = _shown(film)
    assert film.combined.mean() > 0.1
    np.testing.assert_allclose(sh["diffuse_direct"], SUN / np.pi, rtol=2e-3)
    assert not film.data["transmission_direct"].any()
    np.testing.assert_allclose(_recombined(film), film.combined, rtol=1e-4, atol=1e-6)


def test_translucent_light_through_a_bounce_is_diffuse_indirect():
    """A Translucent BSDF sheet over a sunlit floor, seen from above: the light it lets
    through comes from the floor's bounce, and its bounce through the sheet is diffuse to
    the passes (Cycles 5.0 measured: Diffuse Indirect 1.329, ours 1.319, Transmission 0
    in both); the passes sum to the image."""
    s = PaperScene(W, H, background=(0.0, 0.0, 0.0))
    sheet = Material("sheet", (0.8, 0.8, 0.8), translucent=1.0, roughness=1.0)
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, sheet, name="sheet")
    s.add_plane((0, 0, -1.0), (0, 0, 1), 40.0, Material("floor", (0.8, 0.8, 0.8)),
                name="floor")
    s.add_sun((0.6, 0.0, -0.8), strength=SUN)
    s.set_camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=20.0)
    film = render(s, _settings(photons=5_000, caustic_photons=0))
    sh = _shown(film)
    assert sh["diffuse_indirect"].mean() > 0.05
    assert not film.data["transmission_indirect"].any()
    assert not film.data["transmission_direct"].any()
    np.testing.assert_allclose(_recombined(film), film.combined, rtol=1e-4, atol=1e-6)
