"""World export (addon/world.py): Background colour and strength, Environment Texture
(packed image, Mapping rotation, interpolation), warnings naming what is not simulated;
the HDRI example blend. Brightness against Cycles: tests/blender/test_feature_matrix.py
(world_color, world_hdri, world_hdri_rotated)."""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cheap, open_blend, read_layers, render_exr

pytestmark = pytest.mark.blender


@pytest.fixture()
def mb(fresh_scene):
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends
    make_blends.reset()
    return make_blends


def _export(bpy):
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    mb_camera = bpy.context.scene.camera
    if mb_camera is None:
        sys.modules["make_blends"].camera((0, -5, 1), (0, 0, 0))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene, _ = export.export_scene(pm, depsgraph, width=16, height=12)
    return scene


def test_background_colour_times_strength(mb, bpy_addon):
    mb.set_world((0.2, 0.4, 0.6), 2.5)
    scene = _export(bpy_addon)
    assert scene.environment is None
    np.testing.assert_allclose(scene.background, (0.5, 1.0, 1.5), rtol=1e-6)


def test_environment_texture_with_mapping_rotation(mb, bpy_addon):
    sky = mb.sky_hdri(32, 16)
    mb.set_world_hdri(sky, 1.7, rotation=(0.0, 0.0, math.radians(60.0)))
    scene = _export(bpy_addon)
    env = scene.environment
    assert env is not None and env.interpolation == "Linear"
    np.testing.assert_allclose(env.pixels, sky * 1.7, rtol=1e-5)
    from engine.scene import euler_rotation
    np.testing.assert_allclose(env.rotation, euler_rotation((0, 0, math.radians(60))),
                               atol=1e-6)
    np.testing.assert_allclose(scene.background, env.average())
    assert not [w for w in scene.all_warnings() if "world" in w]


def test_unsupported_world_nodes_warn_once_naming_the_node(mb, bpy_addon):
    bpy = bpy_addon
    mb.set_world_hdri(mb.sky_hdri(16, 8), 1.0)
    nt = bpy.context.scene.world.node_tree
    env = next(n for n in nt.nodes if n.type == "TEX_ENVIRONMENT")
    env.projection = "MIRROR_BALL"
    env.name = "Ball Env"
    scene = _export(bpy)
    hits = [w for w in scene.all_warnings() if "Ball Env" in w and "MIRROR_BALL" in w]
    assert len(hits) == 1 and scene.environment is None
    # (Every Sky Texture type is simulated; an unknown one's warning: test_blender_sky.)
    # A node the converter does not know in the colour: named, and the socket's colour
    # is used. (A texture of the direction is baked: test_direction_textures_...)
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    ao = nt.nodes.new("ShaderNodeAmbientOcclusion")
    ao.name = "Occluded"
    nt.links.new(ao.outputs["Color"], bg.inputs["Color"])
    scene = _export(bpy)
    assert len([w for w in scene.all_warnings() if "Occluded" in w]) == 1


def pm_environment(pixels):
    """The engine Environment of a linear map as set_world_hdri packs it (strength 1)."""
    from addon.core import load_engine
    return load_engine().Environment(pixels, 1.0)


def _mix(bpy, fac=None, rgb=(0.1, 0.2, 0.7), strength=1.0, output="Is Camera Ray",
         swap=False):
    """Mix the world's Background (the HDRI) with a colour Background by a Mix Shader:
    factor a constant or a Light Path output; swap puts the colour first."""
    nt = bpy.context.scene.world.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_WORLD")
    hdri = next(n for n in nt.nodes if n.type == "BACKGROUND")
    plain = nt.nodes.new("ShaderNodeBackground")
    plain.inputs["Color"].default_value = (*rgb, 1.0)
    plain.inputs["Strength"].default_value = strength
    mix = nt.nodes.new("ShaderNodeMixShader")
    if fac is None:
        path = nt.nodes.new("ShaderNodeLightPath")
        nt.links.new(path.outputs[output], mix.inputs["Fac"])
    else:
        mix.inputs["Fac"].default_value = fac
    first, second = (plain, hdri) if swap else (hdri, plain)
    nt.links.new(first.outputs[0], mix.inputs[1])
    nt.links.new(second.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return nt, mix


def test_is_camera_ray_splits_the_camera_world_from_the_light(mb, bpy_addon):
    """Mix by Light Path's Is Camera Ray: the HDRI lights the scene, the camera sees the
    colour (and the other way round with the shaders swapped); no warning."""
    bpy = bpy_addon
    sky = mb.sky_hdri(32, 16)
    mb.set_world_hdri(sky, 1.5)
    _mix(bpy, strength=2.0)
    scene = _export(bpy)
    np.testing.assert_allclose(scene.environment.pixels, sky * 1.5, rtol=1e-5)
    assert scene.camera_environment is None
    np.testing.assert_allclose(scene.camera_background, (0.2, 0.4, 1.4), rtol=1e-6)
    assert not [w for w in scene.all_warnings() if "world" in w]
    from engine import worldmedium
    d = np.array([[0.0, 0.3, 1.0], [1.0, 0.0, 0.2]])
    seen = worldmedium.background(scene, d, np.array([True, False]))
    np.testing.assert_allclose(seen[0], (0.2, 0.4, 1.4), rtol=1e-6)
    np.testing.assert_allclose(seen[1], scene.environment.radiance(d[1:])[0])
    mb.set_world_hdri(sky, 1.5)
    _mix(bpy, strength=2.0, swap=True)
    scene = _export(bpy)
    assert scene.environment is None and scene.camera_background is not None
    np.testing.assert_allclose(scene.background, (0.2, 0.4, 1.4), rtol=1e-6)
    np.testing.assert_allclose(scene.camera_environment.pixels, sky * 1.5, rtol=1e-5)


def test_constant_mixes_and_adds_are_summed_into_one_world(mb, bpy_addon):
    """A constant Mix of the HDRI and a colour bakes one map (0.6 x HDRI + 0.4 x colour);
    an Add Shader of two colours sums them; the camera sees the same (no camera world)."""
    bpy = bpy_addon
    sky = mb.sky_hdri(32, 16)
    mb.set_world_hdri(sky, 1.0)
    _mix(bpy, fac=0.4, rgb=(0.5, 0.25, 0.1), strength=2.0)
    scene = _export(bpy)
    # (baked on the map's grid refined 4x: each baked texel the map's own lookup there)
    from addon.world import bake_grid
    plain = pm_environment(sky)
    h, w, dirs = bake_grid(plain)
    assert (h, w) == (64, 128)
    np.testing.assert_allclose(scene.environment.pixels.reshape(-1, 3),
                               0.6 * plain.radiance(dirs) + 0.4 * np.array([1.0, 0.5, 0.2]),
                               rtol=1e-5, atol=1e-6)
    assert scene.camera_environment is None and scene.camera_background is None
    nt = bpy.context.scene.world.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputWorld")
    first = nt.nodes.new("ShaderNodeBackground")
    first.inputs["Color"].default_value = (0.2, 0.2, 0.2, 1.0)
    second = nt.nodes.new("ShaderNodeBackground")
    second.inputs["Color"].default_value = (0.1, 0.3, 0.0, 1.0)
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(first.outputs[0], add.inputs[0])
    nt.links.new(second.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], out.inputs["Surface"])
    scene = _export(bpy)
    np.testing.assert_allclose(scene.background, (0.3, 0.5, 0.2), rtol=1e-6)
    assert scene.environment is None and not [w for w in scene.all_warnings()
                                              if "world" in w]


def test_other_light_path_outputs_and_shaders_in_the_world_are_warned(mb, bpy_addon):
    """Is Glossy Ray (reflections differ from the light: not split) reads 0 for every ray
    but the camera's, with one warning naming the node; a Diffuse BSDF in the world tree
    is not a world shader: warned, the viewport colour as before."""
    bpy = bpy_addon
    sky = mb.sky_hdri(16, 8)
    mb.set_world_hdri(sky, 1.0)
    _nt, mix = _mix(bpy, output="Is Glossy Ray")
    scene = _export(bpy)
    hits = [w for w in scene.all_warnings() if "Is Glossy Ray" in w]
    assert len(hits) == 1, scene.all_warnings()
    np.testing.assert_allclose(scene.environment.pixels, sky, rtol=1e-5)
    assert scene.camera_environment is None  # (0 for the camera too: the same world)
    nt = bpy.context.scene.world.node_tree
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(diffuse.outputs[0], mix.inputs[2])
    scene = _export(bpy)
    hits = [w for w in scene.all_warnings() if "not supported" in w and "surface" in w]
    assert len(hits) == 1 and scene.environment is None


def test_colour_nodes_over_the_hdri_are_baked_into_the_map(mb, bpy_addon):
    """Gamma and Multiply (a Mix node) between the Environment Texture and the Background
    are evaluated on the map's texels (engine/shadernodes: the material nodes' own code);
    a Strength from Light Path's Is Camera Ray (Math) gives the camera its own strength."""
    bpy = bpy_addon
    sky = mb.sky_hdri(32, 16)
    mb.set_world_hdri(sky, 1.0)
    nt = bpy.context.scene.world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    env = next(n for n in nt.nodes if n.type == "TEX_ENVIRONMENT")
    gamma = nt.nodes.new("ShaderNodeGamma")
    gamma.inputs["Gamma"].default_value = 2.0
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    mix.inputs[7].default_value = (1.0, 0.5, 0.25, 1.0)
    nt.links.new(env.outputs["Color"], gamma.inputs["Color"])
    nt.links.new(gamma.outputs[0], mix.inputs[6])
    nt.links.new(mix.outputs[2], bg.inputs["Color"])
    path = nt.nodes.new("ShaderNodeLightPath")
    strength = nt.nodes.new("ShaderNodeMath")
    strength.operation = "ADD"
    strength.inputs[1].default_value = 2.0
    nt.links.new(path.outputs["Is Camera Ray"], strength.inputs[0])
    nt.links.new(strength.outputs[0], bg.inputs["Strength"])
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w], scene.all_warnings()
    from addon.world import bake_grid
    plain = pm_environment(sky)
    want = plain.radiance(bake_grid(plain)[2]) ** 2 * np.array([1.0, 0.5, 0.25])
    np.testing.assert_allclose(scene.environment.pixels.reshape(-1, 3), 2.0 * want,
                               rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(scene.camera_environment.pixels.reshape(-1, 3), 3.0 * want,
                               rtol=1e-4,
                               atol=1e-6)


def test_ray_visibility_camera_off_shows_black_and_lights_as_before(mb, bpy_addon):
    """World > Settings > Ray Visibility > Camera off: camera rays see black (Cycles
    evaluates no background for them), the HDRI still lights; Glossy off is warned."""
    bpy = bpy_addon
    sky = mb.sky_hdri(16, 8)
    mb.set_world_hdri(sky, 1.0)
    vis = bpy.context.scene.world.cycles_visibility
    vis.camera = False
    scene = _export(bpy)
    np.testing.assert_allclose(scene.environment.pixels, sky, rtol=1e-5)
    assert scene.camera_environment is None
    np.testing.assert_array_equal(scene.camera_background, np.zeros(3))
    assert not [w for w in scene.all_warnings() if "Ray Visibility" in w]
    vis.camera, vis.glossy = True, False
    scene = _export(bpy)
    assert scene.camera_background is None
    hits = [w for w in scene.all_warnings() if "Ray Visibility" in w]
    assert len(hits) == 1 and "Glossy" in hits[0]


def test_texture_coordinates_other_than_the_direction_warn(mb, bpy_addon):
    bpy = bpy_addon
    mb.set_world_hdri(mb.sky_hdri(16, 8), 1.0, rotation=(0.0, 0.0, 0.5))
    nt = bpy.context.scene.world.node_tree
    coord = next(n for n in nt.nodes if n.type == "TEX_COORD")
    mapping = next(n for n in nt.nodes if n.type == "MAPPING")
    assert not [w for w in _export(bpy).all_warnings() if "world" in w]
    nt.links.new(coord.outputs["Window"], mapping.inputs["Vector"])
    hits = [w for w in _export(bpy).all_warnings() if "'Window'" in w]
    assert len(hits) == 1 and coord.name in hits[0]


def test_a_world_volume_is_exported_and_its_dropped_parts_warned(mb, bpy_addon):
    """The World Output's Volume becomes Scene.world_medium (worldfog37; before: a
    warning, before s37 dropped without a word); the background stays exported (the
    engine switches it off); its emission glows, a texture on it is warned naming the world
    and node."""
    bpy = bpy_addon
    mb.set_world((0.2, 0.2, 0.2), 1.0)
    nt = bpy.context.scene.world.node_tree
    scene = _export(bpy)
    assert scene.world_medium is None
    assert not [w for w in scene.all_warnings() if "Volume" in w]
    out = next(n for n in nt.nodes if n.type == "OUTPUT_WORLD")
    fog = nt.nodes.new("ShaderNodeVolumePrincipled")
    fog.name = "Haze"
    fog.inputs["Density"].default_value = 0.2
    fog.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    nt.links.new(fog.outputs["Volume"], out.inputs["Volume"])
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "Volume" in w]
    np.testing.assert_allclose(scene.world_medium.scattering, 0.1, rtol=1e-6)
    np.testing.assert_allclose(scene.world_medium.absorption, 0.1, rtol=1e-6)
    np.testing.assert_allclose(scene.background, (0.2, 0.2, 0.2), rtol=1e-6)
    # Its emission glows (volemit38: before, warned naming the world and the node).
    fog.inputs["Emission Strength"].default_value = 1.0
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "emission" in w]
    assert np.all(scene.world_medium.emission > 0)
    # A texture on it is still warned, naming the world and the node.
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], fog.inputs["Emission Strength"])
    hits = [w for w in _export(bpy).all_warnings() if "'Haze'" in w]
    world = bpy.context.scene.world.name
    assert len(hits) == 1 and f"world '{world}'" in hits[0], hits


@pytest.mark.slow
def test_hdri_example_blend_renders(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = open_blend(bpy, "hdri_sphere.blend")
    cheap(scene, pct=25, spp=4)
    layers = read_layers(render_exr(bpy, scene, tmp_path / "hdri.exr", multilayer=True))
    img = layers["Combined"]
    assert np.all(np.isfinite(img)) and img[..., :3].mean() > 0.05
    # The sky shows at the top of the frame (bluer than it is red); the lit floor below.
    top = img[:3, :, :3].mean(axis=(0, 1))
    assert top[2] > top[0], top
    from addon import engine
    assert not [w for w in engine.last_render["warnings"] if "world" in w]


def _direction_world(bpy):
    """A world of one Background fed by nodes of the direction: (node tree, Background,
    Texture Coordinate)."""
    world = bpy.data.worlds.new("Directions")
    bpy.context.scene.world = world
    nt = world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    return nt, bg, nt.nodes.new("ShaderNodeTexCoord")


# Directions away from the poles (where the bake grid's top row lies 0.7 degrees off the
# pole, and a factor of x reads 0.012 there instead of 0).
_UNIT = np.array([[0.28, 0.0, 0.96], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8], [0.8, 0.0, 0.6],
                  [-0.6, 0.0, 0.8], [0.0, -1.0, 0.0], [0.36, 0.48, -0.8]])


def test_direction_textures_bake_the_world(mb, bpy_addon):
    """A Background colour made of nodes of the direction (Generated -> Separate XYZ ->
    Color Ramp: a gradient sky) is baked into a map (Cycles' background: Generated = the
    ray direction); looked up along directions it is the ramp at the direction's z; no
    warning; the camera sees the same world."""
    bpy = bpy_addon
    nt, bg, coord = _direction_world(bpy)
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    stops = ramp.color_ramp.elements
    stops[0].position, stops[0].color = 0.0, (1.0, 0.8, 0.6, 1.0)
    stops[1].position, stops[1].color = 1.0, (0.2, 0.4, 1.0, 1.0)
    nt.links.new(coord.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["Z"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 2.0
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w]
    assert scene.environment is not None and scene.camera_environment is None
    t = np.clip(_UNIT[:, 2], 0.0, 1.0)[:, None]
    want = 2.0 * ((1.0 - t) * np.array([1.0, 0.8, 0.6]) + t * np.array([0.2, 0.4, 1.0]))
    # (bilinear over 0.35-degree texels: within 0.4 % of the ramp)
    np.testing.assert_allclose(scene.environment.radiance(_UNIT), want, rtol=4e-3)
    # The Normal output is the opposite direction (Cycles: N = -D).
    nt.links.new(coord.outputs["Normal"], sep.inputs[0])
    scene = _export(bpy)
    t = np.clip(-_UNIT[:, 2], 0.0, 1.0)[:, None]
    want = 2.0 * ((1.0 - t) * np.array([1.0, 0.8, 0.6]) + t * np.array([0.2, 0.4, 1.0]))
    np.testing.assert_allclose(scene.environment.radiance(_UNIT), want, rtol=4e-3)


def test_textured_mix_factor_and_strength_vary_with_direction(mb, bpy_addon):
    """A Mix Shader's factor from a Gradient Texture (Linear: clamp(x, 0, 1) of the
    direction) weighs an HDRI against a colour per direction; a Strength from Math of the
    direction's x scales a colour; a negative one reads 0 and is warned."""
    bpy = bpy_addon
    sky = mb.sky_hdri(32, 16)
    mb.set_world_hdri(sky, 1.0)
    nt, mix = _mix(bpy, fac=0.0, rgb=(1.0, 0.5, 0.25), strength=2.0)
    coord = nt.nodes.new("ShaderNodeTexCoord")
    grad = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(coord.outputs["Generated"], grad.inputs["Vector"])
    nt.links.new(grad.outputs["Fac"], mix.inputs["Fac"])
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w]
    hdri = pm_environment(sky)
    f = np.clip(_UNIT[:, 0], 0.0, 1.0)[:, None]
    want = (1.0 - f) * hdri.radiance(_UNIT) + f * np.array([2.0, 1.0, 0.5])
    # (the factor's kink at x = 0 spread over a texel of the fine bake grid: 0.002)
    np.testing.assert_allclose(scene.environment.radiance(_UNIT), want, rtol=2e-2,
                               atol=5e-3)
    # Strength = 0.8 x + 1 on a plain colour.
    nt, bg, coord = _direction_world(bpy)
    bg.inputs["Color"].default_value = (0.5, 0.6, 0.7, 1.0)
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    math_node = nt.nodes.new("ShaderNodeMath")
    math_node.operation = "MULTIPLY_ADD"
    math_node.inputs[1].default_value, math_node.inputs[2].default_value = 0.8, 1.0
    nt.links.new(coord.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["X"], math_node.inputs[0])
    nt.links.new(math_node.outputs[0], bg.inputs["Strength"])
    scene = _export(bpy)
    assert not [w for w in scene.all_warnings() if "world" in w]
    want = (0.8 * _UNIT[:, :1] + 1.0) * np.array([0.5, 0.6, 0.7])
    np.testing.assert_allclose(scene.environment.radiance(_UNIT), want, rtol=4e-3)
    # 2 x + 0.3 is negative toward -x: those directions read 0, warned once.
    math_node.inputs[1].default_value, math_node.inputs[2].default_value = 2.0, 0.3
    scene = _export(bpy)
    hits = [w for w in scene.all_warnings() if "negative" in w]
    assert len(hits) == 1 and "Directions" in hits[0]
    got = scene.environment.radiance(_UNIT)
    want = np.maximum(2.0 * _UNIT[:, :1] + 0.3, 0.0) * np.array([0.5, 0.6, 0.7])
    np.testing.assert_allclose(got, want, rtol=4e-3, atol=3e-3)


def test_world_nodes_that_need_a_surface_or_the_screen_warn(mb, bpy_addon):
    """Texture Coordinate's UV output (a world has no UV map) is read as the direction
    and warned naming the node (its Window output is the camera's projection:
    tests/blender/test_world_backplate_cycles.py); a Light Path output inside a colour
    graph warned, its socket's value used."""
    bpy = bpy_addon
    nt, bg, coord = _direction_world(bpy)
    coord.name = "Screen"
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(coord.outputs["UV"], noise.inputs["Vector"])
    nt.links.new(noise.outputs["Color"], bg.inputs["Color"])
    scene = _export(bpy)
    hits = [w for w in scene.all_warnings() if "'UV'" in w]
    assert len(hits) == 1 and "Screen" in hits[0] and scene.environment is not None
    path = nt.nodes.new("ShaderNodeLightPath")
    path.name = "Path"
    nt.links.new(path.outputs["Is Camera Ray"], noise.inputs["Scale"])
    hits = [w for w in _export(bpy).all_warnings() if "'Path'" in w]
    assert len(hits) == 1


def test_viewport_updates_reuse_the_baked_world_until_it_changes(mb, bpy_addon):
    """The viewport's export bakes a direction world once: an update that leaves the
    world alone (an object moved) reuses the map and its warnings; a world update bakes
    it again."""
    bpy = bpy_addon
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    nt, bg, coord = _direction_world(bpy)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(coord.outputs["Window"], noise.inputs["Vector"])  # (warned)
    nt.links.new(noise.outputs["Color"], bg.inputs["Color"])
    mb.camera((0, -5, 1), (0, 0, 0))
    cache = export.ViewportExport(pm)
    camera = pm.Camera.look_at((0, -10, 3), (0, 0, 0))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    first, _ = export.export_viewport(cache, depsgraph, camera, 16, 12)
    again, info = export.export_viewport(cache, depsgraph, camera, 16, 12,
                                         export.ViewportUpdates())
    assert again.environment is first.environment and not info["world_changed"]
    assert [w for w in again.warnings if "'Window'" in w]
    bg.inputs["Strength"].default_value = 3.0
    updates = export.ViewportUpdates()
    updates.world = True
    third, info = export.export_viewport(cache, bpy.context.evaluated_depsgraph_get(),
                                         camera, 16, 12, updates)
    assert third.environment is not first.environment and info["world_changed"]
    np.testing.assert_allclose(third.environment.average(), 3.0 * first.environment.average(),
                               rtol=1e-5)


@pytest.mark.parametrize("case", ["missing file", "no image"])
def test_an_environment_image_that_cannot_load_is_a_magenta_world(mb, bpy_addon, case):
    """An Environment Texture whose file is missing, or that has no image, shows and
    lights magenta (1, 0, 1) as in Cycles (measured: sky and floor (1, 0, 1) in both),
    with one warning saying so (it was the Background's own colour)."""
    bpy = bpy_addon
    nt, bg, _coord = _direction_world(bpy)
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    if case == "missing file":
        img = bpy.data.images.new("gone", 4, 4)
        img.source, img.filepath = "FILE", "//nowhere/sky.exr"
        env.image = img
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 2.0
    scene = _export(bpy)
    np.testing.assert_allclose(scene.environment.radiance(_UNIT), np.tile([2.0, 0.0, 2.0],
                                                                          (len(_UNIT), 1)))
    assert len([w for w in scene.all_warnings() if "magenta" in w]) == 1
