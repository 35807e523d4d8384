"""Random-walk subsurface scattering (engine/subsurfacewalk.py, issue 14) against live
Cycles: light through a thin slab lit from behind (the stand-in shows it black), the
terminator of a sphere lit from the side (the light spread into the shadow side), and a
cube at Subsurface Scale 0.3 (a skin colour, radius comparable to the object). Black world,
a sun, an orthographic camera looking down; block means of the object's pixels."""
import math

import numpy as np
import pytest

from blender_helpers import (black_world, cheap, cycles_plain, looking_down_camera,
                             read_rgba, render_exr, sun_light)
from tools.canonical_mesh import primitive_uv_sphere_add

pytestmark = pytest.mark.blender


def _material(bpy, colour, scale, radius=(1.0, 0.2, 0.1)):
    m = bpy.data.materials.new("SSS")
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*colour, 1.0)
    p.inputs["Roughness"].default_value = 0.5
    p.inputs["Subsurface Weight"].default_value = 1.0
    p.inputs["Subsurface Scale"].default_value = scale
    p.inputs["Subsurface Radius"].default_value = radius
    return m


def _renders(bpy, scene, tmp_path, ours_spp=32, cycles_spp=256):
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"
    cycles_plain(scene, cycles_spp, 8)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=ours_spp, photons=20_000, caustic_photons=0)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    return ours.astype(np.float64), ref.astype(np.float64)


def _add(bpy, scene, ob, m):
    ob.data.materials.append(m)
    if ob.name not in scene.collection.objects:
        scene.collection.objects.link(ob)


def _slab_from_behind(bpy, scene, tmp_path, material):
    """(ours, Cycles) mean RGB (3,) of a 1 x 1 m slab 2 cm thick of `material` seen from
    above, the sun below it: its top face is lit only through the slab."""
    bpy.ops.mesh.primitive_cube_add(size=1.0)
    slab = bpy.context.object
    slab.scale = (1.0, 1.0, 0.02)
    _add(bpy, scene, slab, material)
    black_world(bpy, scene)
    sun_light(bpy, scene, (math.pi, 0.0, 0.0), energy=3.0)  # travelling up (+Z)
    looking_down_camera(bpy, scene, 2.0, ortho_scale=0.8)
    ours, ref = _renders(bpy, scene, tmp_path)
    return ours.mean(axis=(0, 1)), ref.mean(axis=(0, 1))


def test_thin_slab_glows_when_lit_from_behind(fresh_scene, bpy_addon, tmp_path):
    """A 1 x 1 m slab 2 cm thick, white subsurface of radius 5 cm, the sun below it: the
    top face the camera sees is lit only through the slab."""
    got, want = _slab_from_behind(bpy_addon, fresh_scene, tmp_path, _material(
        bpy_addon, (0.9, 0.9, 0.9), 0.05, (1.0, 1.0, 1.0)))
    print(f"thin slab from behind: ours {np.round(got, 4)} Cycles {np.round(want, 4)}")
    assert want.min() > 0.05  # Cycles: the slab glows through
    np.testing.assert_allclose(got, want, rtol=0.03)


def test_terminator_profile_of_a_side_lit_sphere(fresh_scene, bpy_addon, tmp_path):
    """A ball 1 m across (Radius x Scale = (1, 0.2, 0.1) m: red light spreads ~8 cm), the
    sun grazing from -X, seen from above: the luminance profile across the terminator
    (the image's middle rows, column by column) as Cycles', and the light spread past
    the terminator into the shadow side (the diffuse stand-in leaves it black)."""
    bpy, scene = bpy_addon, fresh_scene
    primitive_uv_sphere_add(radius=0.5, segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    _add(bpy, scene, bpy.context.object, _material(bpy, (0.8, 0.5, 0.4), 1.0))
    black_world(bpy, scene)
    sun_light(bpy, scene, (0.0, -math.pi / 2, 0.0), energy=3.0)  # travelling along +X
    looking_down_camera(bpy, scene, 2.0, ortho_scale=1.1)
    ours, ref = _renders(bpy, scene, tmp_path, ours_spp=64)
    rows = slice(8, 16)
    po, pr = ours[rows].mean(axis=(0, 2)), ref[rows].mean(axis=(0, 2))
    with np.printoptions(linewidth=200):
        print("profile ours  ", np.round(po, 4))
        print("profile Cycles", np.round(pr, 4))
    # Pairs of columns within 10 % of their own value or 3 % of the lit side's level.
    po2, pr2 = po.reshape(-1, 2).mean(axis=1), pr.reshape(-1, 2).mean(axis=1)
    assert np.all(np.abs(po2 - pr2) <= np.maximum(0.1 * pr2, 0.03 * pr2.max())), (po2, pr2)
    # Past the terminator (the ball's +X half, columns 13-17): light that walked there.
    # Rare long red walks carry it: ours / Cycles 1.00-1.44 over seeds 0-3 at 64 samples
    # (the walk's mean there agrees with the numpy steps' to 1 %, tests/test_subsurface_walk).
    past = slice(13, 18)
    assert pr[past].sum() > 0.005 * pr.max()
    assert 0.6 < po[past].sum() / pr[past].sum() < 1.6, (po[past], pr[past])


def test_cube_at_scale_three_tenths(fresh_scene, bpy_addon, tmp_path):
    """A 0.5 m cube of a skin colour at Subsurface Scale 0.3 (red mean free path as large
    as the cube), the sun from above at an angle: light leaves through the sides and the
    back; the mean within 3 % and per 4 x 4 block means of the cube's pixels within 8 % of
    Cycles'."""
    bpy, scene = bpy_addon, fresh_scene
    bpy.ops.mesh.primitive_cube_add(size=0.5)
    cube = bpy.context.object
    cube.rotation_euler = (0.3, 0.2, 0.5)
    _add(bpy, scene, cube, _material(bpy, (0.8, 0.55, 0.45), 0.3))
    black_world(bpy, scene)
    sun_light(bpy, scene, (0.4, 0.3, 0.0), energy=3.0)
    looking_down_camera(bpy, scene, 2.0, ortho_scale=1.0)
    ours, ref = _renders(bpy, scene, tmp_path)
    lum_o, lum_r = ours.mean(axis=2), ref.mean(axis=2)
    covered = lum_r > 1e-4
    got, want = ours[covered].mean(axis=0), ref[covered].mean(axis=0)
    print(f"cube Scale 0.3: ours / Cycles {np.round(got / want, 4)}")
    np.testing.assert_allclose(got, want, rtol=0.03)
    bo = lum_o.reshape(6, 4, 6, 4).mean(axis=(1, 3))
    br = lum_r.reshape(6, 4, 6, 4).mean(axis=(1, 3))
    full = covered.reshape(6, 4, 6, 4).all(axis=(1, 3))
    assert np.all(np.abs(bo[full] - br[full]) <= 0.08 * br[full] + 0.01 * br.max()), (bo, br)


@pytest.mark.parametrize("scale", [0.1, 0.3])
def test_suzanne_at_large_scales(fresh_scene, bpy_addon, tmp_path, scale):
    """Suzanne 0.7 m across (its eyes are shells of their own, as Cycles walks them: each
    walk stays in its object, here one mesh) of a skin colour at Subsurface Scale 0.1 and
    0.3, an area light in front and above: the diffuse stand-in read +3.3 % and +7.9 %
    with another light (docs/compatibility.md, mixpale); the walk's mean within 4 % of
    Cycles'."""
    bpy, scene = bpy_addon, fresh_scene
    bpy.ops.mesh.primitive_monkey_add(size=0.7)
    bpy.ops.object.shade_smooth()
    monkey = bpy.context.object
    monkey.rotation_euler = (math.pi / 2, 0.0, 0.0)
    _add(bpy, scene, monkey, _material(bpy, (0.8, 0.5, 0.4), scale))
    black_world(bpy, scene)
    light = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    light.data.energy, light.data.size = 150.0, 1.0
    light.location = (0.8, -1.5, 1.2)
    from mathutils import Vector
    light.rotation_euler = Vector((-0.8, 1.5, -1.2)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(light)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 0.9
    cam.location = (0.0, -3.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    # (64 samples: the red walk, its radius ten times blue's, is the noisy channel of the
    # three-channel MIS; at 32 its mean over ~300 pixels moves +-3 % between seeds.)
    ours, ref = _renders(bpy, scene, tmp_path, ours_spp=64)
    covered = ref.sum(axis=2) > 1e-4
    got, want = ours[covered].mean(axis=0), ref[covered].mean(axis=0)
    print(f"Suzanne Scale {scale}: ours / Cycles {np.round(got / want, 4)}")
    np.testing.assert_allclose(got, want, rtol=0.04)


@pytest.mark.parametrize("glossy_first", [False, True])
def test_a_subsurface_side_of_a_mix_walks(fresh_scene, bpy_addon, tmp_path, glossy_first):
    """The thin slab lit from behind, its material a Mix Shader (0.3) of the subsurface
    Principled and a Glossy BSDF (a skin with an extra sheen of oil): the hits that take
    the subsurface side walk (addon/materials.py _picked_walk), so the slab glows through
    at 0.7 of its own light. Before s42 the mix rendered the stand-in, black here."""
    bpy, scene = bpy_addon, fresh_scene
    m = _material(bpy, (0.9, 0.9, 0.9), 0.05, (1.0, 1.0, 1.0))
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    g = nt.nodes.new("ShaderNodeBsdfGlossy")
    g.inputs["Roughness"].default_value = 0.5
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.7 if glossy_first else 0.3
    first, second = (g, p) if glossy_first else (p, g)
    nt.links.new(first.outputs[0], mix.inputs[1])
    nt.links.new(second.outputs[0], mix.inputs[2])
    out = nt.nodes["Material Output"]
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    from blender_helpers import convert_material
    conv = convert_material(m)
    assert conv.subsurface is not None and conv.subsurface.weight_node is not None
    assert not any("subsurface" in w for w in conv.warnings), conv.warnings
    got, want = _slab_from_behind(bpy, scene, tmp_path, m)
    print(f"mixed slab from behind: ours {np.round(got, 4)} Cycles {np.round(want, 4)}")
    assert want.min() > 0.03  # Cycles: the slab glows through
    np.testing.assert_allclose(got, want, rtol=0.04)

