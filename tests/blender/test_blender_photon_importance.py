"""The add-on's "Photons Where Seen" property (photon_importance, engine/visualimportance.py)
reaches the engine's settings and decides the global shot of a render (issue 14)."""
import os
import sys

import pytest

from blender_helpers import ROOT, cheap

pytestmark = pytest.mark.blender


@pytest.fixture()
def open_ground(fresh_scene):
    """A ball on a 30 m ground under a dim grey world and one area light, seen from close
    by: most of the world's light lands where no gather ray ends (visual importance aims)."""
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    grey = mb.material("grey", "principled", (0.5, 0.5, 0.5), roughness=1.0)
    mb.plane("Floor", 30, 30, grey)
    mb.sphere("Ball", 0.5, grey, (0, 0, 0.5), segments=24, rings=12)
    mb.set_world((0.05, 0.05, 0.05))
    mb.light("Area", "AREA", (1.0, -1.0, 3.0), 500.0, look_at=(0, 0, 0), size=1.0)
    mb.camera((0, -4, 1.5), (0, 0, 0.4))
    cheap(scene, width=32, height=24, spp=1, photons=20_000, caustic_photons=2_000)
    return scene


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
