"""A screen-mapped backplate: the world's Background colour from an Image Texture of the
Texture Coordinate node's Window output (a photo behind the scene). Cycles projects each
direction through the camera (svm_node_tex_coord NODE_TEXCO_WINDOW); camera rays see the
image on the pixels, and the scene's light is the image as that projection spreads it over
the sphere of directions (engine/worldgraph.py; addon/world.py export_worlds)."""
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cycles_plain, read_rgba, render_exr
from tools.canonical_mesh import primitive_uv_sphere_add

pytestmark = pytest.mark.blender

W, H = 64, 48


@pytest.fixture()
def plate_scene(bpy_addon, fresh_scene):
    """A white rough sphere before a backplate: a 32 x 24 float image (red across,
    green up, a blue checker) on the world by Window coordinates; a camera at (0, -4,
    0.5). Returns (bpy, scene, world node tree)."""
    bpy = bpy_addon
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    mb.reset()
    sc = bpy.context.scene
    img = bpy.data.images.new("Plate", 32, 24, float_buffer=True)
    yy, xx = np.mgrid[0:24, 0:32]
    px = np.zeros((24, 32, 4), np.float32)
    px[..., 0], px[..., 1] = xx / 31.0, yy / 23.0
    px[..., 2], px[..., 3] = ((xx // 4 + yy // 4) % 2) * 0.8, 1.0
    img.pixels.foreach_set(px.ravel())
    img.pack()
    world = bpy.data.worlds.new("Backplate")
    sc.world = world
    world.use_nodes = True
    nt = world.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = img, "Linear"
    coord = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coord.outputs["Window"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    primitive_uv_sphere_add(radius=0.6, location=(0, 0, 0))
    mat = bpy.data.materials.new("White")
    mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 1.0
    bpy.context.active_object.data.materials.append(mat)
    mb.camera((0, -4, 0.5), (0, 0, 0))
    sc.render.resolution_x, sc.render.resolution_y = W, H
    sc.render.resolution_percentage = 100
    return bpy, sc, nt


def _export(bpy):
    from addon import export
    from addon.core import load_engine
    return export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                               width=W, height=H)[0]


def test_a_backplate_lands_on_the_pixels_and_lights_as_in_cycles(plate_scene, tmp_path):
    """The background pixels equal Cycles' (a 1-pixel-wide filter in both: the image
    itself, to 0.002), and the sphere lit by the projected image reads as in Cycles
    (within 3 % per channel over its middle); no warning; the effect report says so."""
    bpy, sc, _ = plate_scene
    sc.render.engine = "CYCLES"
    cycles_plain(sc, 128, 12)
    sc.cycles.filter_width = 0.01
    cyc = read_rgba(bpy, render_exr(bpy, sc, tmp_path / "cycles.exr"))[..., :3]
    sc.render.engine = "PHOTONMAP"
    sc.photonmap.spp = 32
    sc.render.filter_size = 0.01
    ours = read_rgba(bpy, render_exr(bpy, sc, tmp_path / "ours.exr"))[..., :3]
    from addon import engine
    info = engine.last_render
    assert not [w for w in info.get("warnings", []) if "world" in w], info.get("warnings")
    effects = info["stats"].get("effects", [])
    assert any("backplate" in line for line in effects), effects
    for corner in (np.s_[:8, :8], np.s_[:8, -8:], np.s_[-8:, :8], np.s_[-8:, -8:]):
        assert np.abs(ours[corner] - cyc[corner]).max() < 2e-3
    middle = np.s_[18:30, 26:38]
    ratio = ours[middle].mean((0, 1)) / cyc[middle].mean((0, 1))
    assert np.all(np.abs(ratio - 1.0) < 0.03), ratio


def test_is_camera_ray_shows_the_plate_and_lights_with_the_colour(plate_scene):
    """Mix by Is Camera Ray (a colour lights the scene, the camera sees the plate): the
    light is the colour alone, the camera's world the plate's graph evaluated per ray:
    the direction through a pixel's centre reads that pixel's texel."""
    bpy, sc, nt = plate_scene
    out = next(n for n in nt.nodes if n.type == "OUTPUT_WORLD")
    plate = nt.nodes["Background"]
    plain = nt.nodes.new("ShaderNodeBackground")
    plain.inputs["Color"].default_value = (0.3, 0.3, 0.3, 1.0)
    mix = nt.nodes.new("ShaderNodeMixShader")
    path = nt.nodes.new("ShaderNodeLightPath")
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    nt.links.new(plain.outputs[0], mix.inputs[1])
    nt.links.new(plate.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    scene = _export(bpy)
    from engine import worldgraph, worldmedium
    assert scene.environment is None
    np.testing.assert_allclose(scene.background, (0.3, 0.3, 0.3), rtol=1e-6)
    assert isinstance(scene.camera_environment, worldgraph.WorldGraph)
    cam = scene.camera
    # The centre of texel (i, j) of the 32 x 24 plate seen through the full frame.
    i, j = 5, 20
    ndc = np.array([(i + 0.5) / 32, (j + 0.5) / 24])
    hw, hh = cam.half_extents(W, H)
    local = np.array([(2 * ndc[0] - 1) * hw, (2 * ndc[1] - 1) * hh, -1.0])
    d = np.asarray(cam.rotation, np.float64) @ local
    d /= np.linalg.norm(d)
    seen = worldmedium.background(scene, d[None], np.array([True]))[0]
    np.testing.assert_allclose(seen, (i / 31, j / 23, ((i // 4 + j // 4) % 2) * 0.8),
                               atol=1e-4)
    lit = worldmedium.background(scene, d[None], np.array([False]))[0]
    np.testing.assert_allclose(lit, (0.3, 0.3, 0.3), rtol=1e-6)


def test_an_orthographic_camera_behind_a_backplate_is_warned(plate_scene):
    """Cycles projects an orthographic camera ray's origin; ours has its direction: said
    once, naming the world."""
    bpy, sc, _ = plate_scene
    sc.camera.data.type = "ORTHO"
    hits = [w for w in _export(bpy).all_warnings() if "orthographic" in w]
    assert len(hits) == 1 and "'Backplate'" in hits[0]
