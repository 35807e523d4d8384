"""Cycles' Light Paths > Clamping through the add-on (engine/sampleclamp.py): our
properties have Cycles' names and defaults, the render reads Cycles' own when the Cycles
add-on is there, else ours; the panel shows the ones the render reads."""
from types import SimpleNamespace

import pytest

pytestmark = pytest.mark.blender


def test_clamping_properties_default_to_cycles_and_export(fresh_scene, bpy_addon):
    from addon.export import clamp_settings, clamp_source
    from engine.settings import RenderSettings
    pm, c = fresh_scene.photonmap, fresh_scene.cycles
    for name in ("sample_clamp_direct", "sample_clamp_indirect"):
        pm.property_unset(name)
        c.property_unset(name)
    assert (pm.sample_clamp_direct, pm.sample_clamp_indirect) == (0.0, 10.0)
    assert (c.sample_clamp_direct, c.sample_clamp_indirect) == (0.0, 10.0)  # Cycles' own
    s = RenderSettings(**pm.to_settings_kwargs())
    assert (s.clamp_direct, s.clamp_indirect) == (0.0, 10.0)
    # Clamped for a Cycles render: ours follows Cycles', our own values unused.
    c.sample_clamp_direct, c.sample_clamp_indirect = 4.0, 0.0
    pm.sample_clamp_direct, pm.sample_clamp_indirect = 7.0, 3.0
    assert clamp_source(fresh_scene, pm) == c
    s = RenderSettings(**pm.to_settings_kwargs())
    assert (s.clamp_direct, s.clamp_indirect) == (4.0, 0.0)
    # Without the Cycles add-on (no scene.cycles): ours.
    bare = SimpleNamespace(render=fresh_scene.render)
    assert clamp_source(bare, pm) is pm
    assert clamp_settings(bare, pm) == dict(clamp_direct=7.0, clamp_indirect=3.0)
    for name in ("sample_clamp_direct", "sample_clamp_indirect"):
        pm.property_unset(name)
        c.property_unset(name)
    assert hasattr(bpy_addon.types, "PHOTONMAP_PT_light_paths_clamping")


def test_clamping_panel_draws_the_properties_the_render_reads(fresh_scene):
    from addon.ui import PHOTONMAP_PT_light_paths_clamping as panel
    from test_blender_bounces import _Layout
    layout = _Layout()
    panel.draw(SimpleNamespace(layout=layout), SimpleNamespace(scene=fresh_scene))
    props = [(owner, name) for kind, owner, name in layout.log if kind == "prop"]
    c = fresh_scene.cycles
    assert props == [(c, "sample_clamp_direct"), (c, "sample_clamp_indirect")]
    assert ("label", None, "Shared with Cycles' Light Paths") in layout.log
