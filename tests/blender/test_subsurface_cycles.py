"""Principled Subsurface against Cycles (s24 new user: the monkey rendered 4.9 % bright;
Subsurface rendered as a diffuse base of its Base Color). A ball 1 m across under an area
light in a black world, Subsurface Scale 0.01 (mean free paths of 1 cm and less: thick
for its light): Cycles' random walk reflects A(c) < c of the light on Base Color c, which
engine/subsurface.py gives the diffuse base; the ball's mean agrees with Cycles' within
the 2 % the issue asks (its pixels see the surface at every view angle, as the
hemispherical A averages them). Thin objects and a larger scale lose more in Cycles
(docs/accuracy.md, 'mixpale')."""
import math

import numpy as np
import pytest
from tools.canonical_mesh import primitive_uv_sphere_add

pytestmark = pytest.mark.blender


def _ball(bpy, scene, color, weight):
    m = bpy.data.materials.new("Skin")
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Roughness"].default_value = 0.4
    p.inputs["Subsurface Weight"].default_value = weight
    p.inputs["Subsurface Scale"].default_value = 0.01
    primitive_uv_sphere_add(radius=0.5, segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(m)
    light = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    light.data.energy, light.data.size = 200.0, 1.0
    light.location = (1.5, -1.5, 2.0)
    from mathutils import Vector
    light.rotation_euler = Vector((-1.5, 1.5, -2.0)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(light)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, -3.0, 0.4)
    cam.rotation_euler = Vector((0.0, 3.0, -0.4)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("Black")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    next(n for n in world.node_tree.nodes
         if n.type == "BACKGROUND").inputs["Strength"].default_value = 0.0


def _render(bpy, scene, path, engine, spp):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    if engine == "CYCLES":
        cycles_plain(scene, spp, 8)
    else:
        cheap(scene, spp=spp, photons=20_000, caustic_photons=0)
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].reshape(-1, 3)


# Ours' spp and the bound per case, from the spread over seeds 0-7 against Cycles at 4096
# spp (docs/accuracy.md, "flaky50"): the stand-in (16 spp) reads R, G, B 0.997 / 1.012 /
# 1.019 at weight 1 and 1.000 / 1.006 / 1.009 at 0.5 (its A(c) table against this ball,
# a bias), sd 0.3-0.4 % a channel; the walk at 64 spp 1.004 / 1.001 / 1.000, sd 1.5-2.0 %
# (0.974-1.034: its 3 % bound was 1.5 sd). Cycles at 128 spp moved 0.4-0.8 % a channel
# between seeds 0-2; at 1024 about 0.15 %.
CYCLES_SPP = 1024


@pytest.mark.parametrize("weight, walk, tol, spp", [(1.0, False, 0.035, 64),
                                                    (0.5, False, 0.025, 64),
                                                    (1.0, True, 0.03, 1024)])
def test_thick_subsurface_ball_matches_cycles(fresh_scene, bpy_addon, tmp_path, weight, walk,
                                              tol, spp):
    """The diffuse stand-in (walk off) and the random walk (engine/subsurfacewalk.py,
    docs/accuracy.md 'sss41'), per channel against Cycles at CYCLES_SPP.

    Bounds at 4-6 standard deviations of the seed spread beyond the measured bias (the
    stand-in at 64 spp: sd ~0.2 % a channel; the walk at 1024: ~0.5 %). They still catch
    what they are for: the stand-in's diffuse base of Base Color instead of A(c) reads this
    ball's c / A(c) = 1.009 / 1.047 / 1.100 bright at weight 1 (1.005 / 1.023 / 1.048 at
    0.5). Measured by `pytest -s tests/blender/seed_sweeps.py -k sss` (docs/accuracy.md,
    "flaky50")."""
    bpy = bpy_addon
    scene = fresh_scene
    scene.photonmap.subsurface_walk = walk
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100
    _ball(bpy, scene, (0.9, 0.6, 0.3), weight)
    # (the walk's three-channel MIS spreads a channel's samples: +-4 % at 16 spp, +-2 %
    # at 64, hence its 1024)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", spp)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", CYCLES_SPP)
    ball = ref.sum(axis=1) > 0
    got, want = ours[ball].mean(axis=0), ref[ball].mean(axis=0)
    print(f"subsurface weight {weight} walk {walk}: ours / Cycles {np.round(got / want, 4)}")
    np.testing.assert_allclose(got, want, rtol=tol)
