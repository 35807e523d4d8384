"""Float images tagged sRGB, as Blender 5's Image.save() writes an EXR of a float image
(sRGB-encoded values, colour space "sRGB"), against live Cycles (issue 14, newuser32's
day room: walls +3.3 %, a horizon band 1.105 of Cycles). Cycles reads such a file as
stored and decodes after interpolating (scene/image.cpp detect_colorspace:
compress_as_srgb; svm/image.h: color_srgb_to_linear_v4 after the lookup); Blender decodes
it per texel at load, which the add-on read as linear (decoded first: brighter wherever
neighbouring texels differ). addon/materials.py cycles_stores_srgb is the rule; the
engine's lookups engine/lights/environment.py and engine/textures.py.

Scenes: (1) a world of a 32 x 16 sky map with a gradient and a sharp 2 x 1 texel sun low
in front of the camera, seen directly (8 x 8 pixel blocks of the sky) and lighting a
diffuse floor; (2) an 8 x 8 float texture with a checker, a gradient and a bright block
(encoded above 1) on two planes seen from above: the left one's Diffuse BSDF colour under
a white world, the right one's Emission colour.
Measured (ours 64 / 16 spp, Cycles 1024 / 64 spp, 10 s for the file): sky blocks
0.9995-1.0002 of Cycles, floor 1.0004 (main, decoding first: 1.0007-1.6178, 1.1059);
texture blocks 0.9971-1.0024 diffuse, 0.9962-1.0023 emission (main: up to 1.4291, 1.4266).
"""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender


def _save_float_srgb(bpy, linear, path, name):
    """Save an (H, W, 3) top-first float image with Image.save() as Blender 5 does (EXR of
    sRGB-encoded values tagged sRGB) and load it back from the file (not packed)."""
    h, w = linear.shape[:2]
    img = bpy.data.images.new(name + "_gen", w, h, alpha=False, float_buffer=True)
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = linear[::-1]
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = str(path)
    img.file_format = "OPEN_EXR"
    img.save()
    bpy.data.images.remove(img)
    out = bpy.data.images.load(str(path), check_existing=False)
    out.name = name
    assert out.is_float and out.packed_file is None and out.source == "FILE"
    assert out.colorspace_settings.name == "sRGB"
    return out


def _sky(H=16, W=32):
    """(H, W, 3) linear, top row first: a sky from 0.9 at the horizon to 0.25 at the
    zenith over a 0.2 ground, and a 2 x 1 texel sun of 30 at 11-22 degrees elevation
    straight ahead (+X, the image's centre)."""
    el = 90.0 - (np.arange(H) + 0.5) / H * 180.0
    t = np.clip(np.sin(np.radians(el)), 0.0, 1.0)[:, None]
    sky = (1 - t) * np.array([0.9, 0.85, 0.8]) + t * np.array([0.25, 0.35, 0.6])
    img = np.where((el > 0)[:, None], sky, np.array([0.2, 0.18, 0.15]))
    img = np.repeat(img[:, None, :], W, axis=1)
    img[6, W // 2 - 1:W // 2 + 1] = (30.0, 28.0, 24.0)
    return img.astype(np.float32)


def _texture():
    """(8, 8, 3) linear, top row first: a 0.02 / 0.6 checker (rows 0-3, columns 0-3), a
    gradient (rows 4-7), and (columns 4-7 of rows 0-3) a 2 x 2 block of 6 in 0.1."""
    img = np.empty((8, 8, 3), np.float32)
    ii, jj = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
    img[:4, :4] = np.where(((ii + jj) % 2 == 0)[..., None], 0.6, 0.02)
    img[4:] = np.linspace(0.01, 0.9, 8)[None, :, None]
    img[:4, 4:] = 0.1
    img[1:3, 5:7] = 6.0
    return img


def _blocks(img, b=8):
    h, w = img.shape[:2]
    return img[:h // b * b, :w // b * b].reshape(h // b, b, w // b, b, -1).mean(axis=(1, 3))


def _render_pair(bpy, scene, tmp_path, spp_ours, spp_cycles):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=spp_ours, photons=20_000, caustic_photons=0)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    scene.render.engine = "CYCLES"
    cycles_plain(scene, spp_cycles, 4)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    return ours.astype(np.float64), ref.astype(np.float64)


def test_the_rule_follows_how_cycles_reads_the_image(fresh_scene, bpy_addon, tmp_path):
    from addon.materials import cycles_stores_srgb
    bpy = bpy_addon
    img = _save_float_srgb(bpy, _texture(), tmp_path / "tex.exr", "tex")
    assert cycles_stores_srgb(img)            # a file tagged sRGB: stored, decoded after
    img.colorspace_settings.name = "Linear Rec.709"
    assert not cycles_stores_srgb(img)        # raw
    img.colorspace_settings.name = "ACEScg"
    assert not cycles_stores_srgb(img)        # converted to linear at load
    img.colorspace_settings.name = "sRGB"
    img.pack()
    assert not cycles_stores_srgb(img)        # BlenderImageLoader: linear float buffer
    gen = bpy.data.images.new("gen", 4, 4, float_buffer=True)
    gen.colorspace_settings.name = "sRGB"
    assert not cycles_stores_srgb(gen)
    byte = bpy.data.images.new("byte", 4, 4)
    assert byte.colorspace_settings.name == "sRGB" and cycles_stores_srgb(byte)


def test_float_srgb_world_seen_and_lighting_a_floor_matches_cycles(fresh_scene, bpy_addon,
                                                                   tmp_path):
    bpy = bpy_addon
    scene = fresh_scene
    img = _save_float_srgb(bpy, _sky(), tmp_path / "sky.exr", "sky")
    world = bpy.data.worlds.new("World")
    scene.world = world
    nt = world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = img
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bpy.ops.mesh.primitive_plane_add(size=60.0)
    from blender_helpers import glass_or_diffuse_material
    bpy.context.object.data.materials.append(
        glass_or_diffuse_material(bpy, "Floor", "diffuse", (0.5,) * 3))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.lens, cam.data.sensor_width = 18.0, 36.0
    cam.location = (0.0, 0.0, 1.0)
    cam.rotation_euler = (math.radians(80.0), 0.0, math.radians(-90.0))  # +X, 10 deg down
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    scene.render.resolution_percentage = 100
    ours, ref = _render_pair(bpy, scene, tmp_path, 64, 1024)
    # The horizon sits 10 degrees above the image's centre: rows 0-15 are sky, the
    # floor from row 18 down.
    sky_o, sky_r = _blocks(ours[:16]), _blocks(ref[:16])
    ratio = sky_o.mean(-1) / sky_r.mean(-1)
    floor = float(ours[18:].mean() / ref[18:].mean())
    print(f"float sRGB world: sky 8x8 blocks ours / Cycles {ratio.min():.4f}-"
          f"{ratio.max():.4f}; floor {floor:.4f}")
    assert sky_r.max() > 5.0        # the sun's texels are in view
    assert np.all(np.abs(ratio - 1.0) < 0.02)
    assert floor == pytest.approx(1.0, abs=0.02)


def test_float_srgb_image_texture_on_planes_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    from blender_helpers import node_material
    bpy = bpy_addon
    scene = fresh_scene
    img = _save_float_srgb(bpy, _texture(), tmp_path / "tex.exr", "tex")
    world = bpy.data.worlds.new("World")
    scene.world = world
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    for x, kind in ((-1.0, "ShaderNodeBsdfDiffuse"), (1.0, "ShaderNodeEmission")):
        m, nt, out = node_material(bpy, kind)
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image, tex.interpolation, tex.extension = img, "Linear", "EXTEND"
        shader = nt.nodes.new(kind)
        if kind == "ShaderNodeBsdfDiffuse":
            # albedo <= 1: the texture x 0.15 (its bright block is 6)
            mul = nt.nodes.new("ShaderNodeMix")
            mul.data_type, mul.blend_type = "RGBA", "MULTIPLY"
            mul.inputs["Factor"].default_value = 1.0
            mul.inputs[7].default_value = (0.15, 0.15, 0.15, 1.0)
            nt.links.new(tex.outputs["Color"], mul.inputs[6])
            nt.links.new(mul.outputs[2], shader.inputs["Color"])
        else:
            nt.links.new(tex.outputs["Color"], shader.inputs["Color"])
        nt.links.new(shader.outputs[0], out.inputs["Surface"])
        bpy.ops.mesh.primitive_plane_add(size=2.0, location=(x, 0.0, 0.0))
        bpy.context.object.data.materials.append(m)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 4.0
    cam.location = (0.0, 0.0, 3.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 64, 32
    scene.render.resolution_percentage = 100
    ours, ref = _render_pair(bpy, scene, tmp_path, 16, 64)
    # 4 pixels a texel; 8 x 8 blocks of 2 x 2 texels, each plane 4 x 4 blocks
    bo, br = _blocks(ours).mean(-1), _blocks(ref).mean(-1)
    ratio = bo / br
    print("float sRGB texture: 8x8 blocks ours / Cycles, diffuse "
          f"{ratio[:, :4].min():.4f}-{ratio[:, :4].max():.4f}, emission "
          f"{ratio[:, 4:].min():.4f}-{ratio[:, 4:].max():.4f}")
    assert ref[:, 32:].max() > 3.0    # the block above 1 (encoded) is read
    assert np.all(np.abs(ratio - 1.0) < 0.015)
