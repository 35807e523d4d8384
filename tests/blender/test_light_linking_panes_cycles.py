"""Light Linking through a window pane and a lamp shade against Cycles (issue 14;
engine/panelight.py, engine/shadelight.py; docs/compatibility.md linking38, fogfloor39).

Cycles counts a lamp met through a glass pane only if it lights the object the path last
bounced from (light_link_receiver_forward: mis_ray_object), and the refraction at the
pane is that bounce; the light a Translucent shade passes on is the shade's next-event
estimate (its own light set), indirect for what lies beyond. So a sun linked to a cube
behind a glass pane lights nothing through the pane, and one linked to the pane lights
every cube behind it; through a Transparent BSDF pane (not a bounce: shadow rays pass it)
the cube's own link decides. Ours takes these lights by next-event estimation through
the pane or the shade, with the same rule.
"""
import math
import os
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.blender

RES, VIEW = 32, 4.0
CUBES = {"CubeA": -1.0, "CubeB": 1.0}


def _pane_scene(bpy, kind):
    """Two grey cubes on a grey floor under a 10 m single-plane pane at z = 2 (a smooth
    Glass BSDF, or a Transparent BSDF), a sun 20 degrees off the zenith with a 15 degree
    disc (Cycles finds a sun through glass only by path tracing), black world, an
    orthographic camera under the pane looking down."""
    from blender_helpers import (black_world, glass_or_diffuse_material, looking_down_camera,
                                 node_material)
    bpy.ops.wm.read_homefile(use_empty=True)
    from addon import engine
    engine._previous_frame_warnings.clear()
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = RES
    scene.render.resolution_percentage = 100
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    grey = glass_or_diffuse_material(bpy, "Grey", "diffuse", (0.6,) * 3)
    bpy.ops.mesh.primitive_plane_add(size=12.0)
    bpy.context.active_object.name = "Floor"
    bpy.context.active_object.data.materials.append(grey)
    for name, x in CUBES.items():
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(x, 0.0, 0.5))
        bpy.context.active_object.name = name
        bpy.context.active_object.data.materials.append(grey)
    bpy.ops.mesh.primitive_plane_add(size=10.0, location=(0.0, 0.0, 2.0))
    pane = bpy.context.active_object
    pane.name = "Pane"
    if kind == "glass":
        pane.data.materials.append(glass_or_diffuse_material(bpy, "Glass", "glass", (1.0,) * 3))
    else:
        m, nt, out = node_material(bpy, "Clear")
        t = nt.nodes.new("ShaderNodeBsdfTransparent")
        nt.links.new(t.outputs[0], out.inputs["Surface"])
        pane.data.materials.append(m)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 3.0, math.radians(15.0)
    sun.rotation_euler = (0.0, math.radians(20.0), 0.0)
    scene.collection.objects.link(sun)
    black_world(bpy, scene)
    looking_down_camera(bpy, scene, 1.8, ortho_scale=VIEW)
    return scene, sun


def _link(bpy, emitter, names):
    coll = bpy.data.collections.new(emitter.name + "Links")
    for n in names:
        coll.objects.link(bpy.data.objects[n])
    emitter.light_linking.receiver_collection = coll


def _tops(img):
    """The cubes' tops' mean grey values."""
    c = (np.arange(RES) + 0.5) / RES * VIEW - VIEW / 2
    x = np.tile(c, (RES, 1))
    y = np.tile(-c[:, None], (1, RES))
    return {name: float(img[(np.abs(x - cx) < 0.35) & (np.abs(y) < 0.35)].mean())
            for name, cx in CUBES.items()}


def _render(bpy, scene, path, engine, spp):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    if engine == "CYCLES":
        cycles_plain(scene, spp, 12)
    else:
        cheap(scene, spp=spp, photons=100_000, caustic_photons=100_000)
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean(axis=2)


@pytest.mark.slow
@pytest.mark.parametrize("kind,linked", [("glass", ("CubeA",)), ("glass", ("CubeA", "Pane")),
                                         ("transparent", ("CubeA",))])
def test_sun_linked_through_a_pane_as_in_cycles(bpy_addon, tmp_path, kind, linked):
    """Ours 32 spp, Cycles 512 spp. Measured: glass, sun linked to cube A: both 0 in both
    (ours before: 0.229 on both tops); linked to cube A and the pane: A 1.006, B 0.984;
    transparent pane, linked to cube A: A 0.996, B 0 in both. ~40 s each."""
    bpy = bpy_addon
    scene, sun = _pane_scene(bpy, kind)
    _link(bpy, sun, linked)
    ref = _tops(_render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 512))
    ours = _tops(_render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 32))
    print(kind, linked, ref, ours)
    for name in CUBES:
        # Through glass the pane's link decides, through a transparent pass the cube's.
        lit = ("Pane" in linked) if kind == "glass" else (name in linked)
        if lit:
            assert ref[name] > 0.1, ref  # the link is real in Cycles
            assert ours[name] == pytest.approx(ref[name], rel=0.03), (name, ours, ref)
        else:
            assert ref[name] < 1e-3 and ours[name] < 1e-3, (name, ours, ref)


def _translucent(nodes):
    n = nodes.new("ShaderNodeBsdfTranslucent")
    n.inputs["Color"].default_value = (0.95, 0.85, 0.7, 1.0)
    return n.outputs[0]


@pytest.mark.slow
@pytest.mark.parametrize("linked", [("Panel",), ("Shade",)])
def test_lamp_linked_through_a_translucent_shade_as_in_cycles(bpy_addon, tmp_path, linked):
    """tests/blender/test_translucent_shade_cycles.py's scene (a point lamp in an open
    Translucent cylinder, a panel beside it lit only through the shade). The lamp linked
    to the panel only: Cycles 0 (the shade, unlinked, passes nothing on), ours 0 (before:
    1.048, the light through the shade taken for the panel's); linked to the shade only:
    the panel lit in full (indirect light is not linked), ours / Cycles 1.000. Ours 16
    spp, Cycles 256 spp. ~30 s each."""
    bpy = bpy_addon
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
    from test_rough_glass_shade_cycles import _shade_scene
    scene = _shade_scene(bpy, 0.0, "GGX", shade=_translucent)
    names = {"Panel": next(o.name for o in bpy.data.objects if o.name.startswith("Plane")),
             "Shade": next(o.name for o in bpy.data.objects if o.name.startswith("Cylinder"))}
    _link(bpy, bpy.data.objects["Lamp"], [names[n] for n in linked])
    means = {}
    for engine, spp in (("CYCLES", 256), ("PHOTONMAP", 16)):
        c = cycles_plain(scene, spp, 12)
        c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 4, 4, 12
        scene.render.engine = engine
        if engine == "PHOTONMAP":
            default_photonmap(scene).spp = spp
        img = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"{engine}.exr"))[..., :3]
        means[engine] = float(img.mean())
    print(linked, means)
    if "Shade" in linked:
        assert means["CYCLES"] > 0.05
        assert means["PHOTONMAP"] == pytest.approx(means["CYCLES"], rel=0.02)
    else:
        assert means["CYCLES"] < 1e-3 and means["PHOTONMAP"] < 1e-3, means
