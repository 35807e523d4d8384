"""The stats line's count of what lights the scene (engine.lights.light_census): the
lamps, the World and the emissive meshes' triangles, as the effect report lists them.
The line said "2 lights" for two lamps under an HDRI beside a glowing lamp shade
(newuser45 / newuser46: a user reads the shade or the HDRI as missing; docs/accuracy.md,
report47)."""
from types import SimpleNamespace

from engine.api import Material, PaperScene
from engine.lights import light_census
from engine.render import prepare_context
from engine.settings import RenderSettings


def _census(scene) -> str:
    ctx = prepare_context(scene, RenderSettings(photons=2000, workers=1))
    ctx.accel.close()
    return light_census(ctx.lights, ctx.scene)


def _room(background=(0.0, 0.0, 0.0)):
    s = PaperScene(width=16, height=12, background=background)
    s.add_material(Material("white", (0.8, 0.8, 0.8)))
    s.add_plane((0, 0, 0), (0, 0, 1), 6, "white", name="Floor")
    s.set_camera((0, -5, 2.5), (0, 0.5, 0.5), view_angle=50)
    return s


def test_lamps_world_and_emitting_triangles_are_each_counted():
    s = _room()
    assert _census(s) == "none"
    s.add_rect_area_light((0, -0.5, 3), (1, 1), power=400, name="Area")
    assert _census(s) == "1 lamp"
    s.add_point_light((1, 0, 2), power=60, name="Point")
    assert _census(s) == "2 lamps"
    s.add_material(Material("glow", (0, 0, 0), emission=(4.0, 3.0, 1.8)))
    s.add_box((1.2, 1.0, 1.2), (0.3, 0.3, 0.3), "glow", name="LampShade")
    assert _census(s) == "2 lamps + 12 emitting triangles"
    s.background = (0.02, 0.03, 0.06)  # a dim World colour lights the scene too
    assert _census(s) == "2 lamps + world + 12 emitting triangles"


def test_a_world_alone_one_emitting_triangle_and_a_sky_sun():
    s = _room(background=(0.5, 0.5, 0.5))
    assert _census(s) == "world"
    s.add_material(Material("glow", (0, 0, 0), emission=(1.0, 1.0, 1.0)))
    s.add_triangles([(0, 0, 1), (1, 0, 1), (0, 1, 1)], [(0, 1, 2)], "glow", name="Tri")
    assert _census(s) == "world + 1 emitting triangle"
    # A Sky Texture's sun disc is a SUN light the export adds for the world
    # (addon/world.py sky_sun_lights, named as environment.sun_light says): the world's.
    s = _room()
    s.add_sun((0.3, 0.2, -1.0), strength=3.0, name="Sky sun")
    ctx = prepare_context(s, RenderSettings(photons=2000, workers=1))
    ctx.accel.close()
    assert light_census(ctx.lights, ctx.scene) == "1 lamp"
    sky = SimpleNamespace(environment=SimpleNamespace(sun_light={"name": "Sky sun"}))
    assert light_census(ctx.lights, sky) == "world"


def test_a_render_and_a_progressive_render_carry_it_in_their_stats():
    """The add-on's Done line reads film.stats["light_census"] from either render."""
    from engine.progressive import Budget, render_progressive
    from engine.render import render
    s = _room(background=(0.2, 0.3, 0.4))
    s.add_point_light((1, 0, 2), power=60, name="Point")
    settings = RenderSettings(photons=500, spp=1, workers=1)
    assert render(s, settings).stats["light_census"] == "1 lamp + world"
    film = render_progressive(s, settings, Budget(passes=1))
    assert film.stats["light_census"] == "1 lamp + world"
