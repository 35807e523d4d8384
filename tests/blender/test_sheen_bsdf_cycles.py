"""The Sheen BSDF node against Cycles (it fell back to a Diffuse BSDF of its Color, warned:
a velvet cushion rendered as flat paint).

Cycles' Sheen BSDF (Microfiber, the node's default) is bsdf_sheen, the lobe the
Principled BSDF's sheen layer adds, here alone. A sun-lit sheet seen from the normal to
grazing (a sheen's weight grows towards grazing), at three roughnesses: direct light
only, every pixel one BSDF evaluation in both engines (a Mix with a Diffuse BSDF: one
closure picked per hit in both), so image means within 2 % of the brightest view. Main
read a Diffuse BSDF of the node's Color.
"""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender


def _sheen_sheet(bpy, roughness, diffuse_mix=0.0):
    """A 40 m plane of Sheen BSDF, or of a Mix Shader of a Diffuse BSDF and it (factor
    1 - diffuse_mix towards the sheen): a velvet's usual set-up."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, "Velvet")
    n = nt.nodes.new("ShaderNodeBsdfSheen")
    n.inputs["Color"].default_value = (0.9, 0.4, 0.2, 1.0)
    n.inputs["Roughness"].default_value = roughness
    surface = n.outputs[0]
    if diffuse_mix > 0.0:
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = (0.2, 0.3, 0.6, 1.0)
        mix = nt.nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 1.0 - diffuse_mix
        nt.links.new(d.outputs[0], mix.inputs[1])
        nt.links.new(surface, mix.inputs[2])
        surface = mix.outputs[0]
    nt.links.new(surface, out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(m)


def _sun_and_camera(bpy, scene, view_deg):
    from mathutils import Vector
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 20.0, 0.0
    sun.rotation_euler = (0.0, math.radians(60.0), 0.0)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    t = math.radians(view_deg)
    cam.location = (-6.0 * math.sin(t), 0.3, 6.0 * math.cos(t))
    cam.data.lens = 200.0  # a narrow view: one direction over the patch
    cam.rotation_euler = (Vector((0, 0, 0)) - Vector(cam.location)).to_track_quat(
        "-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    from blender_helpers import black_world
    black_world(bpy, scene)


@pytest.mark.parametrize("roughness, diffuse_mix", [(0.2, 0.0), (0.5, 0.0), (1.0, 0.0),
                                                     (0.5, 0.5)])
def test_sunlit_sheen_bsdf_matches_cycles(fresh_scene, bpy_addon, tmp_path, roughness,
                                          diffuse_mix):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100
    _sheen_sheet(bpy, roughness, diffuse_mix)
    report, pairs = [], []
    for view in (0.0, 45.0, 75.0, 85.0):
        for o in [o for o in scene.objects if o.type in ("LIGHT", "CAMERA")]:
            bpy.data.objects.remove(o)
        _sun_and_camera(bpy, scene, view)
        scene.render.engine = "PHOTONMAP"
        # (A mix picks one side per hit: 64 spp keeps the pick's noise inside the 2 %.)
        cheap(scene, spp=64 if diffuse_mix else 16, photons=20_000, caustic_photons=0)
        scene.photonmap.photon_mapping = False
        ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"o{view}.exr"))[..., :3]
        scene.render.engine = "CYCLES"
        cycles_plain(scene, 64, 0)
        ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"c{view}.exr"))[..., :3]
        got, want = ours.reshape(-1, 3).mean(0), ref.reshape(-1, 3).mean(0)
        report.append((view, np.round(got, 4), np.round(want, 4)))
        pairs.append((got, want))
    print(f"roughness {roughness}, diffuse {diffuse_mix}: ours, Cycles by view angle", report)
    # A sheen is dark head-on and bright at grazing: 2 % of the brightest view.
    top = max(want.max() for _, want in pairs)
    assert top > 0.01
    for got, want in pairs:
        assert np.all(np.abs(got - want) <= 0.02 * top), report
