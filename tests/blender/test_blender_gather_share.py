"""The add-on's "Gather by Indirect Share" property (gather_by_share, engine/render.py
gather_count) reaches the engine's settings, and a render reports the gather count used."""
import pytest

pytestmark = pytest.mark.blender


def test_gather_by_share_property_reaches_the_engine(bpy_addon, open_ground):
    from engine.settings import RenderSettings
    pm = open_ground.photonmap
    assert pm.gather_by_share is True  # the engine's default
    assert RenderSettings(**pm.to_settings_kwargs()).gather_by_share is True
    pm.gather_by_share = False
    assert pm.to_settings_kwargs()["gather_by_share"] is False
    assert RenderSettings(**pm.to_settings_kwargs()).gather_by_share is False
    assert pm.to_viewport_settings_kwargs()["gather_by_share"] is False


def test_render_reports_the_gather_count(bpy_addon, open_ground):
    from addon import export
    import engine
    from engine.render import gather_count, render
    from engine.settings import RenderSettings
    dg = bpy_addon.context.evaluated_depsgraph_get()
    scene, _ = export.export_scene(engine, dg, width=32, height=24)
    kwargs = open_ground.photonmap.to_settings_kwargs()
    film = render(scene, RenderSettings(**kwargs))
    share = film.stats["indirect_share"]
    assert 0 < share < 0.05, share  # the ground's light: direct, from the area light
    assert film.stats["gather_rays_used"] == gather_count(kwargs["gather_rays"], share) == 1
    assert any("final gathering with 1 of 2 ray(s)" in line for line in film.stats["effects"])
