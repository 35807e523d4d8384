"""Materials per ray class (engine/raymaterials.py: Cycles' Light Path node inside a
material): a card over a floor that the camera sees as one material, shadow rays as
another and every other ray as a third; an emitter the camera looks through."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.geometry import CAMERA, SHADOW, MaterialTable
from engine.integrator import Counters, direct_irradiance
from engine.raymaterials import expand, path_materials
from engine.render import prepare_context, render
from engine.scene import Material, SceneError

from helpers import top_down_plane
from test_transparent_shadows import _floor_hits

SUN = 2.0  # W/m^2, straight down


def _card_scene(card: Material, res=24):
    """A 0.5-albedo floor seen straight down (orthographic, 4 m wide) under a straight-down
    sun, with a 2 x 2 m horizontal card of material `card` 1 m above its middle."""
    s = top_down_plane(albedo=0.5, res=res, view=4.0)
    s.add_material(card)
    s.add_plane((0, 0, 1.0), (0, 0, 1), 2.0, card.name, name="card")
    s.add_sun((0, 0, -1), SUN)
    return s


def _three_way_card():
    """Grey diffuse for diffuse rays, red diffuse for the camera, a tinted Transparent BSDF
    for shadow rays."""
    return Material("card", (0.5, 0.5, 0.5), ray_variants={
        "camera": Material("card [camera]", (0.8, 0.0, 0.0)),
        "shadow": Material("card [shadow]", (0.8, 0.8, 0.8), alpha=0.0,
                           transparent_tint=(0.2, 0.6, 1.0))})


def test_table_appends_variants_and_remaps_only_their_classes():
    card = _three_way_card()
    rows, remap = expand([Material("floor"), card])
    assert [m.name for m in rows] == ["floor", "card", "card [camera]", "card [shadow]"]
    assert set(remap) == {CAMERA, SHADOW}
    assert remap[CAMERA].tolist() == [0, 2, 2, 3] and remap[SHADOW].tolist() == [0, 3, 2, 3]
    table = MaterialTable.build([Material("floor"), Material("plain")])
    assert table.ray_remap == {}
    with pytest.raises(SceneError):
        Material("bad", ray_variants={"volume": Material("x")})


def test_shadow_rays_meet_the_shadow_material():
    """The floor under the card gets the sun through the shadow rays' Transparent BSDF,
    tinted, although every other ray meets an opaque diffuse card."""
    ctx = prepare_context(_card_scene(_three_way_card()), RenderSettings(workers=1))
    assert ctx.shadow is not None
    hit = _floor_hits(ctx, 300, half=0.9)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    assert np.allclose(E, SUN * np.array([0.2, 0.6, 1.0]), rtol=1e-12)
    # Without the variant the card shadows the floor.
    plain = prepare_context(_card_scene(Material("card", (0.5, 0.5, 0.5))),
                            RenderSettings(workers=1))
    E0 = direct_irradiance(plain, _floor_hits(plain, 300, half=0.9),
                           np.random.default_rng(1), Counters())
    assert np.all(E0 == 0.0)


def test_camera_sees_its_material_and_the_floor_is_lit_through_the_card():
    """Seen from above with direct light only: the card reads as its camera material (red,
    0.8 E / pi), the floor beside it as 0.5 E / pi; the photons and shadows the other
    classes make do not change that."""
    film = render(_card_scene(_three_way_card()),
                  RenderSettings(spp=1, photon_mapping=False, workers=1, seed=3))
    img = film.combined
    h = img.shape[0]
    c = slice(h // 2 - 3, h // 2 + 3)
    assert np.allclose(img[c, c], SUN / np.pi * np.array([0.8, 0.0, 0.0]), rtol=1e-6,
                       atol=1e-9)
    assert np.allclose(img[1:3, 1:3], SUN / np.pi * 0.5, rtol=1e-6)


def test_emitter_the_camera_looks_through_lights_the_floor():
    """Mix Shader(Is Camera Ray, Emission, Transparent): the card lights the floor as a
    mesh light (diffuse rays meet its emission), and the camera sees the floor through it."""
    lamp = Material("lamp", (0.0, 0.0, 0.0), emission=(5.0, 5.0, 5.0), ray_variants={
        "camera": Material("lamp [camera]", (0.0, 0.0, 0.0), alpha=0.0)})
    s = _card_scene(lamp)
    s.lights.clear()  # the lamp alone
    film = render(s, RenderSettings(spp=4, photon_mapping=False, workers=1, seed=3))
    img = film.combined
    h = img.shape[0]
    c = slice(h // 2 - 2, h // 2 + 2)
    # Under the middle of a 2 x 2 m Lambertian emitter 1 m up: E = L pi F, F the four
    # corner factors of 1 x 1 m quarters (docs: helpers.rect_corner_factor).
    from helpers import rect_corner_factor
    E = 5.0 * 4.0 * rect_corner_factor(1.0, 1.0, 1.0)
    seen = img[c, c].mean()
    assert abs(seen - 0.5 * E / np.pi) < 0.05 * 0.5 * E / np.pi
    # The camera's material is a plain pass: the emitter itself is not seen.
    assert seen < 5.0 * 0.5


def test_no_variant_change_keeps_the_image_bitwise():
    """A camera variant equal to the material renders the same bits (its rows take the
    per-hit table path, engine/raymaterials.hit_tables); a table without variants never
    gives per-hit rows."""
    def card(variants):
        return Material("card", (0.3, 0.6, 0.2), roughness=0.4, specular=1.0,
                        ray_variants=variants)
    same = card({"camera": Material("card [camera]", (0.3, 0.6, 0.2), roughness=0.4,
                                    specular=1.0)})
    settings = RenderSettings(spp=2, photons=5000, caustic_photons=0, workers=1, seed=5)
    a = render(_card_scene(card(None), res=16), settings).combined
    b = render(_card_scene(same, res=16), settings).combined
    assert np.array_equal(a, b)
    ctx = prepare_context(_card_scene(card(None)), RenderSettings(workers=1))
    assert path_materials(ctx.geo, ctx.table, np.arange(ctx.geo.count), CAMERA) is None


def test_each_hit_reads_its_ray_class_row():
    """path_materials picks, per hit, the row of the class that met it (camera, glossy,
    transmission rows mixed in one batch, as a camera chain's bounce has them), and
    hit_tables hands the compiled readers those rows with the hits' own geometry rows."""
    from engine.geometry import DIFFUSE, GLOSSY, TRANSMISSION
    from engine.raymaterials import hit_tables
    card = Material("card", (0.5, 0.5, 0.5), ray_variants={
        "camera": Material("card [camera]", (0.8, 0.0, 0.0)),
        "glossy": Material("card [glossy]", (0.0, 0.8, 0.0))})
    ctx = prepare_context(_card_scene(card), RenderSettings(workers=1))
    geo, table = ctx.geo, ctx.table
    names = table.names
    card_tri = int(np.flatnonzero(np.asarray(geo.material) == names.index("card"))[0])
    floor_tri = int(np.flatnonzero(np.asarray(geo.material) == names.index("matte"))[0])
    prim = np.array([card_tri, card_tri, card_tri, card_tri, floor_tri])
    cls = np.array([CAMERA, GLOSSY, TRANSMISSION, DIFFUSE, CAMERA])
    rows = path_materials(geo, table, prim, cls)
    assert [names[i] for i in rows] == ["card [camera]", "card [glossy]", "card", "card",
                                        "matte"]
    assert rows.dtype == geo.material.dtype
    idx, tabs = hit_tables(geo, prim, rows, "v0", "e1", "corner_normals", "material")
    assert idx.tolist() == [0, 1, 2, 3, 4]
    assert np.array_equal(tabs[0], geo.v0[prim]) and np.array_equal(tabs[1], geo.e1[prim])
    assert tabs[2] is geo.corner_normals or np.array_equal(tabs[2], geo.corner_normals[prim])
    assert np.array_equal(tabs[3], rows)


def test_holdout_for_the_camera_lamp_for_the_rest():
    """Mix Shader(Is Camera Ray, Emission, Holdout): camera rays meeting the lamp see a
    hole (no colour, holdout 1), while it lights the floor around it."""
    lamp = Material("lamp", (0.0, 0.0, 0.0), emission=(5.0, 5.0, 5.0), ray_variants={
        "camera": Material("lamp [camera]", (0.0, 0.0, 0.0), holdout=True)})
    s = _card_scene(lamp)
    s.lights.clear()
    film = render(s, RenderSettings(spp=4, photon_mapping=False, workers=1, seed=3))
    h = film.combined.shape[0]
    c = slice(h // 2 - 2, h // 2 + 2)
    assert np.all(film.combined[c, c] == 0.0) and np.all(film.holdout[c, c] == 1.0)
    assert film.combined[1:3, 1:3].min() > 0.0 and np.all(film.holdout[1:3, 1:3] == 0.0)


def test_effects_call_shadow_transparent_glass_window_glass():
    """Glass that shadow rays see as a Transparent BSDF needs no caustic photons for its
    direct light: the effect analysis lists it as window glass, not a caster, and says why."""
    glass = Material("glass", (1.0, 1.0, 1.0), transmission=1.0, specular=1.0,
                     roughness=0.0, node="glass", ray_variants={
                         "shadow": Material("glass [shadow]", alpha=0.0)})
    ctx = prepare_context(_card_scene(glass), RenderSettings(workers=1))
    assert "card" in ctx.plan.window_glass and "card" not in ctx.plan.casters
    line = next(x for x in ctx.plan.report() if x.startswith("Light Path in materials"))
    assert "shadow rays see another surface on 'card'" in line
    assert "no caustic photons aimed at it" in line
    plain = prepare_context(_card_scene(Material("glass", (1.0, 1.0, 1.0), transmission=1.0,
                                                 specular=1.0, roughness=0.0, node="glass")),
                            RenderSettings(workers=1))
    assert "card" not in plain.plan.window_glass
    assert not any(x.startswith("Light Path") for x in plain.plan.report())


def test_scene_file_reads_ray_class_materials(tmp_path):
    """[materials.NAME.shadow_rays] (camera_rays, glossy_rays, transmission_rays) in a
    scene file: the surface those rays meet; an unknown key inside it is an error naming
    it."""
    from engine.scenefile import load_scene
    text = """
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
up = [0, 1, 0]
[materials.window]
transmission = 1.0
specular = 1.0
roughness = 0.0
node = "glass"
[materials.window.shadow_rays]
alpha = 0.0
transparent_tint = [0.5, 0.5, 0.5]
[materials.window.camera_rays]
holdout = true
[[objects]]
type = "plane"
center = [0, 0, 1]
size = 2
material = "window"
"""
    path = tmp_path / "s.toml"
    path.write_text(text.replace("transparent_tint = [0.5, 0.5, 0.5]\n", ""))
    scene, _ = load_scene(str(path))
    m = scene.materials["window"]
    assert set(m.ray_variants) == {"shadow", "camera"}
    assert m.ray_variants["shadow"].alpha == 0.0 and m.ray_variants["camera"].holdout
    path.write_text(text)
    with pytest.raises(Exception, match="transparent_tint"):
        load_scene(str(path))
