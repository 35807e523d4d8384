"""The add-on's "Gather by Indirect Share" property (gather_by_share, engine/render.py
gather_count) reaches the engine's settings, and a render reports the gather count used."""
import os
import sys

import pytest

from blender_helpers import ROOT, cheap

pytestmark = pytest.mark.blender


@pytest.fixture()
def open_ground(fresh_scene):
    """A grey ball on a 30 m ground under a dim world and one area light: nearly all the
    light the camera sees on the ground is direct."""
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
