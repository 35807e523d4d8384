"""An 8-bit image with alpha in an Image Texture node, as Cycles reads it (newuser54's leaf
cards; addon/materials.py cycles_associates_alpha, engine/textures.py associate /
unassociate): Cycles premultiplies its RGB by alpha at load, so the Color output alone is
dark where the image is see-through (a PNG decal's transparent surround renders black),
and divides by the filtered alpha where the node's Alpha output is linked (a cut-out's
edge keeps the leaf's colour). The add-on read the stored straight RGB: a colour-only
lookup of alpha 0.5 white read 1.0 where Cycles reads 0.216 (measured below)."""
import numpy as np
import pytest
from blender_helpers import convert_material
from blender_helpers import node_material as _material

pytestmark = pytest.mark.blender


def _image(bpy, name, alpha=0.5):
    img = bpy.data.images.new(name, 4, 4, alpha=True)
    px = np.ones((4, 4, 4), np.float32)
    px[..., 1] = 0.6
    px[..., 3] = alpha
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def test_the_rule_follows_how_cycles_loads_the_image(fresh_scene, bpy_addon):
    from addon.materials import cycles_associates_alpha
    bpy = bpy_addon
    img = _image(bpy, "byte")
    assert cycles_associates_alpha(img)                 # 8-bit, straight, sRGB
    img.colorspace_settings.name = "Non-Color"
    assert not cycles_associates_alpha(img)             # data: never associated
    img.colorspace_settings.name = "sRGB"
    img.alpha_mode = "CHANNEL_PACKED"
    assert not cycles_associates_alpha(img)
    img.alpha_mode = "NONE"
    assert not cycles_associates_alpha(img)
    flt = bpy.data.images.new("float", 4, 4, alpha=True, float_buffer=True)
    assert not cycles_associates_alpha(flt)             # left as Blender gives it


@pytest.mark.parametrize("link_alpha", [False, True])
def test_a_leaf_material_unassociates_only_with_alpha_linked(fresh_scene, bpy_addon,
                                                             link_alpha):
    bpy = bpy_addon
    m, nt, out = _material(bpy, "Leaf")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "leaf")
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    if link_alpha:
        nt.links.new(tex.outputs["Alpha"], p.inputs["Alpha"])
    nt.links.new(p.outputs[0], out.inputs["Surface"])
    mat = convert_material(m)
    assert mat.texture.associated and mat.texture.unassociate == link_alpha
    rgb = mat.texture.sample(np.array([[0.5, 0.5]]))[0]
    from engine.imageio import srgb_decode
    want = np.array([1.0, 0.6, 1.0]) * (1.0 if link_alpha else 0.5)
    assert np.allclose(rgb, srgb_decode(want), atol=2e-3)


def test_colour_only_lookup_of_a_half_transparent_image_matches_cycles(fresh_scene,
                                                                       bpy_addon, tmp_path):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    m, nt, out = _material(bpy, "Decal")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "decal")
    tex.interpolation = "Closest"
    em = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(tex.outputs["Color"], em.inputs["Color"])
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    bpy.context.object.data.materials.append(m)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 0.0, 3.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.cycles.pixel_filter_type = "BOX"
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=1, photons=1000, caustic_photons=0)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[3:5, 3:5, :3]
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 1, 0)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[3:5, 3:5, :3]
    print("colour-only, alpha 0.5: ours", ours.mean((0, 1)), "Cycles", ref.mean((0, 1)))
    assert ref[..., 0].mean() < 0.3                   # Cycles: premultiplied (0.216)
    assert np.allclose(ours, ref, rtol=0.03)          # 8-bit rounding of Cycles' (c a)/255


# --- float images (alpha55) -------------------------------------------------------------
# Cycles holds a float image's RGB premultiplied and divides by alpha where the node's
# Alpha output is linked (not Non-Color / Channel Packed / None). Read through Blender
# (generated, packed) it copies Blender's float buffer; read from its file it takes the
# file's values, premultiplying them itself only for a format with straight alpha (PNG),
# whatever Image > Alpha says (addon/materials.py _float_texels).
STRAIGHT = (1.0, 0.6, 0.2, 0.5)                    # a texel's straight colour and alpha
ASSOCIATED = (0.5, 0.3, 0.1, 0.5)


def _float_image(bpy, name, rgba, space=None):
    img = bpy.data.images.new(name, 4, 4, alpha=True, float_buffer=True)
    if space is not None:  # before the pixels: a generated image refills on a change
        img.colorspace_settings.name = space
    img.pixels.foreach_set(np.tile(np.float32(rgba), 16))
    return img


def _png16(path, rgba):
    """A 4 x 4 16-bit RGBA PNG of one straight colour (PNG holds straight alpha)."""
    import struct
    import zlib
    v = np.round(np.clip(np.array(rgba), 0.0, 1.0) * 65535).astype(">u2")
    row = b"\x00" + np.tile(v, 4).tobytes()

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data)))
    with open(path, "wb") as f:
        head = struct.pack(">IIBBBBB", 4, 4, 16, 6, 0, 0, 0)  # 16-bit RGBA
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", head)
                + chunk(b"IDAT", zlib.compress(row * 4)) + chunk(b"IEND", b""))
    return str(path)


def _saved(bpy, scene, img, path, fmt, depth):
    s = scene.render.image_settings
    s.file_format, s.color_mode, s.color_depth = fmt, "RGBA", depth
    img.save_render(str(path), scene=scene)
    return str(path)


def _loaded(bpy, path, alpha_mode, pack=False):
    img = bpy.data.images.load(path, check_existing=False)
    img.alpha_mode = alpha_mode
    img.reload()
    if pack:
        img.pack()
    return img


def _float_cases(bpy, scene, tmp_path):
    """[(label, image)]: the float images the probe reads, each a 4 x 4 of one texel."""
    gen = _float_image(bpy, "generated", ASSOCIATED)
    exr = _saved(bpy, scene, _float_image(bpy, "w_exr", ASSOCIATED), tmp_path / "a.exr",
                 "OPEN_EXR", "32")
    tif = _saved(bpy, scene, _float_image(bpy, "w_tif", ASSOCIATED), tmp_path / "a.tif",
                 "TIFF", "16")
    png = _png16(tmp_path / "a.png", STRAIGHT)
    packed = _float_image(bpy, "packed_channels", ASSOCIATED)
    packed.alpha_mode = "CHANNEL_PACKED"
    none = _float_image(bpy, "alpha_none", ASSOCIATED)
    none.alpha_mode = "NONE"
    return [("generated", gen),
            ("generated Non-Color", _float_image(bpy, "data", ASSOCIATED, "Non-Color")),
            ("generated Channel Packed", packed),
            ("generated alpha None", none),
            ("EXR file Straight", _loaded(bpy, exr, "STRAIGHT")),
            ("EXR file Premultiplied", _loaded(bpy, exr, "PREMUL")),
            ("EXR packed Straight", _loaded(bpy, exr, "STRAIGHT", pack=True)),
            ("16-bit PNG file sRGB", _loaded(bpy, png, "STRAIGHT")),
            ("16-bit PNG file Premultiplied", _loaded(bpy, png, "PREMUL")),
            ("16-bit PNG packed", _loaded(bpy, png, "STRAIGHT", pack=True)),
            ("16-bit TIFF file (Blender's)", _loaded(bpy, tif, "STRAIGHT"))]


def test_float_images_read_as_cycles_reads_them(fresh_scene, bpy_addon, tmp_path):
    """One column per float image, in two rows: the Color output alone into an Emission
    (top), and Color times Alpha into an Emission (bottom: the Alpha output linked).
    Closest, so each 8 x 8 block reads one texel."""
    from blender_helpers import cheap, cycles_plain, looking_down_camera, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    cases = _float_cases(bpy, scene, tmp_path)
    n = len(cases)
    for i, (label, img) in enumerate(cases):
        for row, link_alpha in enumerate((False, True)):
            m, nt, out = _material(bpy, f"{label} {link_alpha}")
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image, tex.interpolation = img, "Closest"
            em = nt.nodes.new("ShaderNodeEmission")
            colour = tex.outputs["Color"]
            if link_alpha:  # Color x Alpha: a Mix from black by the Alpha output
                mix = nt.nodes.new("ShaderNodeMix")
                mix.data_type = "RGBA"
                mix.inputs["A"].default_value = (0.0, 0.0, 0.0, 1.0)
                nt.links.new(tex.outputs["Alpha"], mix.inputs["Factor"])
                nt.links.new(colour, mix.inputs["B"])
                colour = mix.outputs["Result"]
            nt.links.new(colour, em.inputs["Color"])
            nt.links.new(em.outputs[0], out.inputs["Surface"])
            bpy.ops.mesh.primitive_plane_add(size=1.0, location=(i - (n - 1) / 2,
                                                                 0.5 - row, 0.0))
            bpy.context.object.data.materials.append(m)
    looking_down_camera(bpy, scene, 3.0, ortho_scale=n)
    scene.render.resolution_x, scene.render.resolution_y = 8 * n, 16
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.cycles.pixel_filter_type = "BOX"
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=1, photons=1000, caustic_photons=0)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 1, 0)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]

    def block(img, i, row):  # the 4 x 4 pixels at the block's centre
        return img[8 * row + 2:8 * row + 6, 8 * i + 2:8 * i + 6].mean((0, 1))
    bad = []
    for i, (label, _) in enumerate(cases):
        for row, what in ((0, "colour only"), (1, "colour x alpha (Alpha linked)")):
            o, c = block(ours, i, row), block(ref, i, row)
            print(f"{label:32s} {what:30s} ours {np.round(o, 4)} Cycles {np.round(c, 4)}")
            if not np.allclose(o, c, rtol=0.01, atol=1e-3):
                bad.append((label, what, o, c))
    assert not bad


def test_float_rules_follow_the_loader_and_the_file(fresh_scene, bpy_addon, tmp_path):
    from addon.materials import (cycles_unassociates_alpha, file_alpha_unassociated,
                                 tiff_extra_sample)
    bpy = bpy_addon
    flt = _float_image(bpy, "f", ASSOCIATED)
    assert cycles_unassociates_alpha(flt)               # associated in Cycles' texture
    for mode in ("CHANNEL_PACKED", "NONE"):
        flt.alpha_mode = mode
        assert not cycles_unassociates_alpha(flt)
    assert not cycles_unassociates_alpha(_float_image(bpy, "d", ASSOCIATED, "Non-Color"))
    tif = _saved(bpy, fresh_scene, _float_image(bpy, "t", ASSOCIATED), tmp_path / "a.tif",
                 "TIFF", "16")
    assert tiff_extra_sample(tif) == 1                  # Blender writes associated alpha
    assert not file_alpha_unassociated(bpy.data.images.load(tif))
    png = bpy.data.images.load(_png16(tmp_path / "a.png", STRAIGHT))
    assert png.is_float and file_alpha_unassociated(png)
    exr = _saved(bpy, fresh_scene, _float_image(bpy, "e", ASSOCIATED), tmp_path / "a.exr",
                 "OPEN_EXR", "32")
    assert not file_alpha_unassociated(bpy.data.images.load(exr))
    assert tiff_extra_sample(png.filepath) == 0         # not a TIFF


def test_a_udim_tiffs_alpha_is_read_from_each_tiles_file(fresh_scene, bpy_addon, tmp_path):
    """A UDIM image's path holds a <UDIM> token, not a file: each tile's TIFF is asked
    for its own ExtraSamples (Blender writes associated alpha; Pillow unassociated)."""
    from PIL import Image
    from addon.materials import file_alpha_unassociated, image_file_path
    bpy = bpy_addon
    _saved(bpy, fresh_scene, _float_image(bpy, "u", ASSOCIATED), tmp_path / "t.1001.tif",
           "TIFF", "16")
    Image.new("RGBA", (4, 4), (10, 20, 30, 128)).save(tmp_path / "t.1002.tif")
    img = bpy.data.images.load(str(tmp_path / "t.1001.tif"))
    img.source = "TILED"                                # Blender finds tile 1002 itself
    assert [t.number for t in img.tiles] == [1001, 1002]
    assert "<UDIM>" in img.filepath
    assert image_file_path(img) == str(tmp_path / "t.1001.tif")
    assert image_file_path(img, 1002) == str(tmp_path / "t.1002.tif")
    assert not file_alpha_unassociated(img)             # the first tile's file
    assert not file_alpha_unassociated(img, 1001)
    assert file_alpha_unassociated(img, 1002)
