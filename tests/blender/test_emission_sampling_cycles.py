"""Material > Settings > Emission Sampling against Cycles (issue 14, s25 emissamp): a
4 m white box (Cornell-style, open front) lit only by an emissive 1 m panel 0.6 m under
its ceiling, its front facing the floor; its back lights the ceiling above it. Cycles'
Emission Sampling changes only its noise, so one Cycles render (Front and Back) is the
reference for every mode; ours samples one side (Front: the ceiling's light arrives by
gather rays alone) or none (None: the whole room's direct light by gather rays), and
must stay as bright: the mean of the pixels that do not see the panel directly, in all
and in the top quarter (the ceiling), within 2 % of Cycles."""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cycles_plain, default_photonmap, read_rgba, render_exr

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def _room(bpy):
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    white = mb.material("white", "diffuse", (0.8, 0.8, 0.8))
    mb.cornell_box(white, white, white)
    lamp, nt, out = mb.empty_material("lamp")
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Strength"].default_value = 10.0
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    # Rotated half a turn about x: the face normal (the front) points down.
    mb.plane("Panel", 1.0, 1.0, lamp, (0, 0.5, 3.4), (math.pi, 0, 0))
    mb.set_world((0.0, 0.0, 0.0))
    mb.camera((0, -6.5, 2.0), (0, 0, 2.0), fov_deg=45.0)
    scene.render.resolution_x, scene.render.resolution_y = 40, 30
    scene.render.resolution_percentage = 100
    scene.render.filter_size = 1.0
    return scene, lamp


def test_none_and_front_are_as_bright_as_cycles(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene, lamp = _room(bpy)
    lamp.cycles.emission_sampling = "FRONT_BACK"
    cycles_plain(scene, 256, 12)
    scene.render.engine = "CYCLES"
    cyc = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "c.exr"))[..., :3]
    scene.render.engine = "PHOTONMAP"
    pm = default_photonmap(scene)
    pm.spp, pm.seed = 32, 0
    # Pixels that do not see the panel (radiance 10) directly, in all and in the top
    # quarter (the ceiling): the light it sends to the room.
    room = cyc.max(axis=2) < 2.0
    top = room.copy()
    top[cyc.shape[0] // 4:] = False
    ratios = {}
    for mode in ("NONE", "FRONT", "FRONT_BACK"):
        lamp.cycles.emission_sampling = mode
        ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"o_{mode}.exr"))[..., :3]
        ratios[mode] = (float(ours[room].mean() / cyc[room].mean()),
                        float(ours[top].mean() / cyc[top].mean()))
    print(" ".join(f"{m}: image {w:.4f} top quarter {c:.4f}" for m, (w, c) in ratios.items()))
    for mode, (whole, ceiling) in ratios.items():
        assert abs(whole - 1.0) < 0.02 and abs(ceiling - 1.0) < 0.02, ratios


def test_export_reads_emission_sampling(bpy_addon):
    bpy = bpy_addon
    import engine
    from addon import export
    scene, lamp = _room(bpy)
    for mode in ("NONE", "AUTO", "FRONT", "BACK", "FRONT_BACK"):
        lamp.cycles.emission_sampling = mode
        bpy.context.view_layer.update()
        pm_scene, _ = export.export_scene(engine, bpy.context.evaluated_depsgraph_get())
        got = {m.name: m.emission_sampling for m in pm_scene.materials.values()}
        assert got["lamp"] == mode, got


def test_material_panel_offers_emission_sampling(bpy_addon):
    """Our material Settings panel shows Emission Sampling (Cycles' panel is drawn for
    Cycles alone) and the Pass Index, and is registered."""
    from types import SimpleNamespace

    from addon.ui import PHOTONMAP_PT_material_settings
    bpy = bpy_addon
    assert hasattr(bpy.types, "PHOTONMAP_PT_material_settings")
    log = []

    class Layout:
        use_property_split = use_property_decorate = False

        def column(self, **kw):
            return self

        def prop(self, owner, name, **kw):
            log.append(name)

    mat = bpy.data.materials.new("panel_probe")
    PHOTONMAP_PT_material_settings.draw(SimpleNamespace(layout=Layout()),
                                        SimpleNamespace(material=mat))
    assert log == ["emission_sampling", "pass_index"], log
