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
