"""Sky Texture export (addon/world.py): the node's settings, a Mapping in front, the sun
disc as a light of the exported scene, and the warning for a sky type not simulated.
Brightness against Cycles: tests/blender/test_sky_cycles.py."""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT

pytestmark = pytest.mark.blender


@pytest.fixture()
def mb(fresh_scene):
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends
    make_blends.reset()
    make_blends.camera((0, -5, 1), (0, 0, 0))
    return make_blends


def _export(bpy):
    from addon import export
    from addon.core import load_engine
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene, _ = export.export_scene(load_engine(), depsgraph, width=16, height=12)
    return scene


def _sky_world(bpy, mb, strength=1.0, mapping_rotation=None):
    mb.set_world((0.3, 0.2, 0.1), strength)
    nt = bpy.context.scene.world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.name = "Day"
    sky.sky_type = "SINGLE_SCATTERING" if bpy.app.version >= (5, 0, 0) else "NISHITA"
    sky.sun_elevation, sky.sun_rotation = math.radians(25.0), math.radians(40.0)
    sky.altitude, sky.sun_intensity = 800.0, 0.7
    sky.air_density, sky.ozone_density = 1.2, 0.8
    if hasattr(sky, "aerosol_density"):
        sky.aerosol_density = 2.0
    else:
        sky.dust_density = 2.0
    nt.links.new(sky.outputs[0], bg.inputs["Color"])
    if mapping_rotation is not None:
        coord = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.inputs["Rotation"].default_value = mapping_rotation
        nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        # (inputs["Vector"] skips the socket while it is flagged unavailable)
        nt.links.new(mapping.outputs[0], next(s for s in sky.inputs if s.name == "Vector"))
    return sky


def test_single_scattering_sky_exports_map_and_sun(mb, bpy_addon):
    from engine.lights.sky import SkyTexture
    from engine.scene import euler_rotation
    bpy = bpy_addon
    rot = (0.0, 0.0, math.radians(30.0))
    _sky_world(bpy, mb, strength=1.5, mapping_rotation=rot)
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w]
    env = scene.environment
    R = euler_rotation(rot)
    np.testing.assert_allclose(env.rotation, R, atol=1e-6)
    want = SkyTexture(sun_elevation=math.radians(25.0), sun_rotation=math.radians(40.0),
                      altitude=800.0, sun_intensity=0.7, air_density=1.2, aerosol_density=2.0,
                      ozone_density=0.8, strength=1.5, rotation=R)
    assert env.sky.altitude == pytest.approx(800.0) and env.sky.aerosol_density == pytest.approx(2.0)
    np.testing.assert_allclose(env.pixels, want.bake(), rtol=1e-4, atol=1e-6)
    suns = [li for li in scene.lights if li.kind == "SUN"]
    assert len(suns) == 1 and suns[0].visible_camera
    np.testing.assert_allclose(suns[0].color * suns[0].power, want.sun_irradiance(), rtol=1e-4)
    np.testing.assert_allclose(suns[0].direction, -(R.T @ want.sun_direction()), atol=1e-6)
    np.testing.assert_allclose(scene.background, env.average())
    # The same sky again: the last bake, not a new one (1-4 s a bake in the viewport).
    assert _export(bpy).environment is env
    # Disc off: the map alone.
    bpy.context.scene.world.node_tree.nodes["Day"].sun_disc = False
    again = _export(bpy)
    assert not [li for li in again.lights if li.kind == "SUN"] and again.environment is not env


def test_preetham_sky_exports_its_sun_direction_and_turbidity(mb, bpy_addon):
    from engine.lights.sky import SkyTexture
    bpy = bpy_addon
    sky = _sky_world(bpy, mb, strength=2.0)
    sky.sky_type = "PREETHAM"
    sky.sun_direction, sky.turbidity = (0.3, 0.5, 0.6), 3.5
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w]
    want = SkyTexture(sky_type="PREETHAM", sun_vector=(0.3, 0.5, 0.6), turbidity=3.5,
                      strength=2.0)
    np.testing.assert_allclose(scene.environment.pixels, want.bake(), rtol=1e-4, atol=1e-6)
    assert not scene.lights  # no disc


def test_hosek_wilkie_sky_exports_its_sun_direction_turbidity_and_ground_albedo(mb, bpy_addon):
    from engine.lights.sky import SkyTexture
    bpy = bpy_addon
    sky = _sky_world(bpy, mb, strength=2.0)
    sky.sky_type = "HOSEK_WILKIE"
    sky.sun_direction, sky.turbidity, sky.ground_albedo = (-0.4, 0.6, 0.5), 6.3, 0.7
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w]
    want = SkyTexture(sky_type="HOSEK_WILKIE", sun_vector=(-0.4, 0.6, 0.5), turbidity=6.3,
                      ground_albedo=0.7, strength=2.0)
    assert scene.environment.sky.ground_albedo == pytest.approx(0.7)
    np.testing.assert_allclose(scene.environment.pixels, want.bake(), rtol=1e-4, atol=1e-6)
    assert not scene.lights  # no disc


def test_unknown_sky_types_warn_and_use_the_viewport_colour(mb, bpy_addon, monkeypatch):
    """Every Blender 5.0 sky type is simulated; a type the engine does not know (here
    Hosek / Wilkie, taken off the engine's list) warns and the viewport colour stands in."""
    from importlib import import_module

    from addon.core import load_engine
    bpy = bpy_addon
    sky_mod = import_module(load_engine().__name__ + ".lights.sky")
    monkeypatch.setattr(sky_mod, "SUPPORTED_SKY_TYPES",
                        tuple(t for t in sky_mod.SUPPORTED_SKY_TYPES if t != "HOSEK_WILKIE"))
    sky = _sky_world(bpy, mb, strength=2.0)
    sky.sky_type = "HOSEK_WILKIE"
    scene = _export(bpy)
    hits = [w for w in scene.all_warnings() if "'Day'" in w]
    assert len(hits) == 1 and "HOSEK_WILKIE" in hits[0] and "Sky Texture" in hits[0]
    assert scene.environment is None and not scene.lights
    np.testing.assert_allclose(scene.background, (0.6, 0.4, 0.2), rtol=1e-6)


def test_sun_lamp_disc_is_hidden_from_the_camera_the_sky_disc_is_not(mb, bpy_addon):
    """Cycles shows a Sky Texture's sun disc to camera rays (it is the background) but never
    a sun lamp's disc, whatever the lamp object's camera visibility (Cycles 5.0.1: a
    20-degree sun in view reads 0 at visible_camera on and off). The export says which."""
    bpy = bpy_addon
    _sky_world(bpy, mb)
    lamp = mb.light("Lamp", "SUN", (0, 0, 3), 2.0, look_at=(0, 0, 0))
    lamp.visible_camera = True
    suns = {li.name: li for li in _export(bpy).lights if li.kind == "SUN"}
    assert not suns["Lamp"].visible_camera
    (sky_sun,) = [li for n, li in suns.items() if n != "Lamp"]
    assert sky_sun.visible_camera
