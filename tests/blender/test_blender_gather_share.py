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
    kwargs["gather_rays"] = 8
    film = render(scene, RenderSettings(**kwargs))
    # The ground's light is direct, from the area light: the share over seeds 0-5 reads
    # 0.035-0.053 at 20k photons (0.039-0.049 at 200k), so 2 to 5 of 8 rays.
    share = film.stats["indirect_share"]
    assert 0 < share < 0.08, share
    used = film.stats["gather_rays_used"]
    assert used == gather_count(8, share) < 8, (used, share)
    assert any(f"final gathering with {used} of 8 ray(s)" in line
               for line in film.stats["effects"])
