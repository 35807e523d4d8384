"""Cycles' Light Group passes through the add-on (issue 14, passes41; engine/lightgroups.py)
against live Cycles 5.0: a grey box on a floor lit by an area light (group "key"), a sun
(group "sun"), an emissive panel the camera sees (group "glow") and a grey world (group
"sky"), 64 x 48, Cycles 256 spp, ours 32 spp.

Each group's pass "Combined_<group>": its image mean within 3 % of Cycles' and its 16 x 16
pixel blocks within 8 % (the noise of both); the four groups sum to our Combined within
1.5 % (each group renders apart: the sum agrees in expectation, not sample by sample) and
Cycles' to its own to float precision. An emitter in no group of the view layer (the sun,
once its group is left out) is in no pass: the groups then miss the sun's light.
"""
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cheap, cycles_plain, read_layers, render_exr

pytestmark = pytest.mark.blender

W, H = 64, 48
GROUPS = ("key", "sun", "glow", "sky")


def _scene(bpy):
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    grey = mb.material("grey", "principled", (0.6, 0.6, 0.6), roughness=1.0)
    mb.plane("Floor", 8, 8, grey)
    mb.box("Box", 1.0, 1.0, 1.0, grey, (0.0, 0.0, 0.5), (0, 0, 0))
    panel = mb.box("Panel", 0.6, 0.1, 0.6, grey, (1.4, 0.6, 0.5), (0, 0, 0))
    m, nt, out = mb.empty_material("glow")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 0.5, 0.2, 1.0)
    em.inputs["Strength"].default_value = 4.0
    nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
    panel.data.materials.clear()
    panel.data.materials.append(m)
    mb.set_world((0.2, 0.2, 0.2))
    sun = mb.light("Sun", "SUN", (0, 0, 5), 2.0, look_at=(0.3, 0.2, 0))
    area = mb.light("Area", "AREA", (-1.5, -1.5, 3.0), 300.0, look_at=(0, 0, 0), size=1.0)
    mb.camera((0, -5.5, 2.6), (0, 0.6, 0.2))
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.use_compositing = False
    vl = scene.view_layers[0]
    for g in GROUPS:
        vl.lightgroups.add(name=g)
    area.lightgroup, sun.lightgroup, panel.lightgroup = "key", "sun", "glow"
    scene.world.lightgroup = "sky"
    return scene


@pytest.fixture(scope="module")
def renders(bpy_addon, tmp_path_factory):
    bpy = bpy_addon
    tmp = tmp_path_factory.mktemp("light_groups")
    scene = _scene(bpy)
    out = {}
    for engine in ("CYCLES", "PHOTONMAP"):
        scene.render.engine = engine
        if engine == "CYCLES":
            cycles_plain(scene, 256, 4)
        else:
            cheap(scene, spp=32, photons=50_000, caustic_photons=5_000)
        out[engine] = read_layers(render_exr(bpy, scene, tmp / f"{engine}.exr",
                                             multilayer=True))
    return out


def _blocks(a, s=16):
    h, w = a.shape[:2]
    return a[:h // s * s, :w // s * s].reshape(h // s, s, w // s, s, -1).mean(axis=(1, 3))


@pytest.mark.slow
@pytest.mark.parametrize("group", GROUPS)
def test_group_pass_matches_cycles(renders, group):
    cyc = renders["CYCLES"][f"Combined_{group}"][..., :3]
    ours = renders["PHOTONMAP"][f"Combined_{group}"][..., :3]
    assert ours.shape == cyc.shape == (H, W, 3)
    assert cyc.mean() > 0.01
    assert abs(ours.mean() / cyc.mean() - 1.0) < 0.03, (group, ours.mean(), cyc.mean())
    bc, bo = _blocks(cyc), _blocks(ours)
    lit = bc > 0.05 * bc.max()
    assert np.all(np.abs(bo[lit] / bc[lit] - 1.0) < 0.08), (group, (bo / bc)[..., 0])


@pytest.mark.slow
def test_groups_sum_to_combined(renders):
    for engine, tol in (("CYCLES", 1e-4), ("PHOTONMAP", 0.015)):
        passes = renders[engine]
        total = sum(passes[f"Combined_{g}"][..., :3] for g in GROUPS)
        combined = passes["Combined"][..., :3]
        assert abs(total.mean() / combined.mean() - 1.0) < tol, (engine, total.mean(),
                                                                  combined.mean())


def test_panels_draw_the_light_groups_and_passes(bpy_addon):
    """The View Layer's Passes panel offers Vector and Ambient Occlusion, its Light Groups
    sub-panel the groups' list; Object and World panels their Light Group field (Cycles'
    own panels show for Cycles alone)."""
    from types import SimpleNamespace

    from addon import ui

    log = []

    class Layout:
        use_property_split = use_property_decorate = False
        enabled = True

        def column(self, **kw):
            return self

        row = column

        def prop(self, owner, name, **kw):
            log.append(name)

        def prop_search(self, owner, name, *args, **kw):
            log.append(("search", name))

        def template_list(self, *args, **kw):
            log.append(("list", args[3]))

        def operator(self, name, **kw):
            log.append(name)
            return SimpleNamespace(name="")

        def separator(self):
            pass

        def menu(self, *args, **kw):
            pass

    scene = bpy_addon.context.scene
    ctx = SimpleNamespace(view_layer=scene.view_layers[0], object=scene.objects[0],
                          world=scene.world or bpy_addon.data.worlds.new("w"))
    ui.PHOTONMAP_PT_passes.draw(SimpleNamespace(layout=Layout()), ctx)
    assert "use_pass_vector" in log and "use_pass_ambient_occlusion" in log
    ui.PHOTONMAP_PT_passes_lightgroups.draw(SimpleNamespace(layout=Layout()), ctx)
    assert ("list", "lightgroups") in log
    for panel in (ui.PHOTONMAP_PT_object_lightgroup, ui.PHOTONMAP_PT_world_lightgroup):
        log.clear()
        panel.draw(SimpleNamespace(layout=Layout()), ctx)
        assert ("search", "lightgroup") in log
