"""The add-on's "Photons Where Seen" property (photon_importance, engine/visualimportance.py)
reaches the engine's settings and decides the global shot of a render (issue 14)."""
import pytest

pytestmark = pytest.mark.blender


def test_photon_importance_property_reaches_the_engine(bpy_addon, open_ground):
    from engine.settings import RenderSettings
    pm = open_ground.photonmap
    assert pm.photon_importance is True  # the engine's default
    assert RenderSettings(**pm.to_settings_kwargs()).photon_importance is True
    pm.photon_importance = False
    assert pm.to_settings_kwargs()["photon_importance"] is False
    assert RenderSettings(**pm.to_settings_kwargs()).photon_importance is False
    assert pm.to_viewport_settings_kwargs()["photon_importance"] is False


def test_photon_importance_property_decides_the_global_shot(bpy_addon, open_ground):
    bpy = bpy_addon
    from addon import engine
    pm = open_ground.photonmap
    pm.photon_importance = True
    bpy.ops.render.render()
    on = dict(engine.last_render["stats"])
    assert str(on.get("photon_importance", "")).startswith("visual importance:"), on.get(
        "photon_importance")
    pm.photon_importance = False
    bpy.ops.render.render()
    off = dict(engine.last_render["stats"])
    assert "photon_importance" not in off, off.get("photon_importance")
    assert not engine.last_render["cancelled"]
