"""The Light Path node inside materials against live Cycles (lightpath40: addon/lightpath.py,
engine/raymaterials.py).

1. A window of Mix Shader(Is Shadow Ray, Glass, Transparent): a 2 cm glass slab 1.5 m
   over a grey floor, a 1 m area light above to one side, seen straight down
   (orthographic). Shadow rays see the Transparent BSDF: the patch of floor the light
   reaches through the window is lit as if the window were not there, and the floor seen
   through the glass is dimmed by the glass's two refractions only. Cycles with Light
   Paths > Caustics > Refractive off: with it on (its default) Cycles adds the refractive
   caustic through the glass on top of the shadow rays' light (x1.9 on the lit patch,
   docs/compatibility.md, lightpath40), light this trick is used to replace. The same
   window as a single plane matches Cycles with it on (our photons' caustic through it).
2. A lamp the camera looks through: Mix Shader(Is Camera Ray, Emission, Transparent) on a
   1 m plane 1 m over the floor, the only light: the camera sees the floor under it, lit;
   with a Holdout for the Transparent, a hole (no colour, alpha 0) where the lamp is.
3. A screen that glows only for the camera: Emission Strength = 7 x Is Camera Ray, beside
   an area light: the camera sees it glow, the floor gets none of its light (and the
   screen, black to every other ray, shadows the area light's).
"""
import numpy as np
import pytest
from blender_helpers import (black_world, cycles_plain, glass_or_diffuse_material,
                             looking_down_camera, node_material, read_rgba, render_exr)

pytestmark = pytest.mark.blender

RES = 40  # px over 4 m: 10 px per metre, pixel i at x = (i + 0.5) / 10 - 2


def _px(x):
    return int(round((x + 2.0) * 10.0 - 0.5))


def _region(img, x0, x1, y0=-0.3, y1=0.3):
    """Mean of an (H,W) image over world x in [x0, x1], y in [y0, y1] (row 0 at +y)."""
    return float(img[_px(-y1):_px(-y0) + 1, _px(x0):_px(x1) + 1].mean())


def _light_path_material(bpy, name, fac_output, a, b):
    """Mix Shader(Fac = Light Path's fac_output, a, b): a and b callables making the two
    shader nodes in the tree."""
    m, nt, out = node_material(bpy, name)
    mix = nt.nodes.new("ShaderNodeMixShader")
    path = nt.nodes.new("ShaderNodeLightPath")
    nt.links.new(path.outputs[fac_output], mix.inputs[0])
    nt.links.new(a(nt).outputs[0], mix.inputs[1])
    nt.links.new(b(nt).outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def _glass(nt):
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Roughness"].default_value = 0.0
    return g


def _emission(nt, strength=4.0):
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Strength"].default_value = strength
    return e


def _base(bpy):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    black_world(bpy, scene)
    bpy.ops.mesh.primitive_plane_add(size=6)
    bpy.context.object.data.materials.append(
        glass_or_diffuse_material(bpy, "Floor", "diffuse", (0.8,) * 3))
    looking_down_camera(bpy, scene, 6.0, ortho_scale=4.0)
    scene.render.resolution_x = scene.render.resolution_y = RES
    return scene


def _area(bpy, scene, x, power=300.0):
    light = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    light.data.energy, light.data.size = power, 1.0
    light.location = (x, 0.0, 3.0)
    scene.collection.objects.link(light)


def _both(bpy, scene, tmp_path, cycles_spp=512, spp=16, caustics_refractive=True,
          alpha=False):
    """(ours, Cycles) mean of RGB (H,W) of scene; alpha: (H,W,2) mean of RGB and alpha."""
    def read(path):
        rgba = read_rgba(bpy, render_exr(bpy, scene, str(path)))
        grey = rgba[..., :3].mean(-1)
        return np.stack([grey, rgba[..., 3]], axis=-1) if alpha else grey
    scene.render.engine = "CYCLES"
    cycles_plain(scene, cycles_spp, 8)
    scene.cycles.caustics_refractive = caustics_refractive
    ref = read(tmp_path / "c.exr")
    scene.render.engine = "PHOTONMAP"
    scene.photonmap.spp = spp
    return read(tmp_path / "o.exr"), ref


@pytest.mark.parametrize("shape, caustics, fac", [("slab", False, "Is Shadow Ray"),
                                                 ("plane", True, "Is Shadow Ray"),
                                                 ("slab", False, "shadow + diffuse")])
def test_window_transparent_to_shadow_rays_lights_the_floor_as_cycles(bpy_addon, tmp_path,
                                                                      shape, caustics, fac):
    """A slab: ours is Cycles with Caustics > Refractive off (the photons crossing thin
    flat glass keep their path's kind: shadow rays carry the light). A single plane: ours
    is Cycles with it on (the photons refracted into the plane's far side are caustic
    photons, on top of the shadow rays' light). "shadow + diffuse": the factor Is Shadow
    Ray + Is Diffuse Ray (Math Add), transparent to bounces and photons too."""
    bpy = bpy_addon
    scene = _base(bpy)
    window = _light_path_material(bpy, "Window", "Is Shadow Ray", _glass,
                                  lambda nt: nt.nodes.new("ShaderNodeBsdfTransparent"))
    if fac == "shadow + diffuse":
        nt = window.node_tree
        mix = next(n for n in nt.nodes if n.type == "MIX_SHADER")
        path = next(n for n in nt.nodes if n.type == "LIGHT_PATH")
        add = nt.nodes.new("ShaderNodeMath")
        add.operation = "ADD"
        nt.links.new(path.outputs["Is Shadow Ray"], add.inputs[0])
        nt.links.new(path.outputs["Is Diffuse Ray"], add.inputs[1])
        nt.links.new(add.outputs[0], mix.inputs[0])
    if shape == "slab":
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.5))
        bpy.context.object.scale = (1.2, 1.2, 0.02)
    else:
        bpy.ops.mesh.primitive_plane_add(size=1.2, location=(0.0, 0.0, 1.5))
    bpy.context.object.name = "Window"
    bpy.context.object.data.materials.append(window)
    _area(bpy, scene, 0.8)
    scene.render.engine = "PHOTONMAP"
    from blender_helpers import export_warnings
    assert not [w for w in export_warnings(bpy) if "Window" in w]
    ours, ref = _both(bpy, scene, tmp_path, caustics_refractive=caustics)
    for x0, x1 in ((-1.4, -0.8), (-0.3, 0.3), (1.2, 1.8)):  # lit patch, glass, open floor
        a, b = _region(ours, x0, x1), _region(ref, x0, x1)
        assert abs(a / b - 1.0) < 0.04, ((x0, x1), a, b)


@pytest.mark.parametrize("other", ["ShaderNodeBsdfTransparent", "ShaderNodeHoldout"])
def test_lamp_the_camera_does_not_see_lights_the_floor_as_cycles(bpy_addon, tmp_path, other):
    """Mix Shader(Is Camera Ray, Emission, Transparent or Holdout): the camera sees the
    floor under the lamp (Transparent) or a hole there (Holdout: no colour, alpha 0)."""
    bpy = bpy_addon
    scene = _base(bpy)
    lamp = _light_path_material(bpy, "Lamp", "Is Camera Ray", _emission,
                                lambda nt: nt.nodes.new(other))
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.0, 0.0, 1.0))
    bpy.context.object.data.materials.append(lamp)
    scene.render.engine = "PHOTONMAP"
    from blender_helpers import export_warnings
    assert not [w for w in export_warnings(bpy) if "Lamp" in w]
    ours, ref = _both(bpy, scene, tmp_path, alpha=True)
    beside = _region(ref[..., 0], 1.2, 1.8)
    assert beside > 0.02
    if other == "ShaderNodeHoldout":
        for img in (ours, ref):
            assert _region(img[..., 0], -0.3, 0.3) < 1e-6  # no colour
            assert _region(img[..., 1], -0.3, 0.3) < 1e-6  # alpha 0
        regions = ((1.2, 1.8),)
    else:
        assert _region(ref[..., 0], -0.3, 0.3) > 0.3  # lit: no glowing plane seen
        regions = ((-0.3, 0.3), (1.2, 1.8))
    for x0, x1 in regions:
        a, b = _region(ours[..., 0], x0, x1), _region(ref[..., 0], x0, x1)
        assert abs(a / b - 1.0) < 0.04, ((x0, x1), a, b)


def test_screen_glowing_only_for_the_camera_lights_nothing(bpy_addon, tmp_path):
    bpy = bpy_addon
    scene = _base(bpy)
    m, nt, out = node_material(bpy, "Screen")
    e = _emission(nt)
    mul = nt.nodes.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    mul.inputs[1].default_value = 7.0
    path = nt.nodes.new("ShaderNodeLightPath")
    nt.links.new(path.outputs["Is Camera Ray"], mul.inputs[0])
    nt.links.new(mul.outputs[0], e.inputs["Strength"])
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-1.0, 0.0, 1.0))
    bpy.context.object.data.materials.append(m)
    _area(bpy, scene, 1.0, power=100.0)
    ours, ref = _both(bpy, scene, tmp_path, cycles_spp=64, spp=4)
    # The camera sees the screen's 7 W/m^2/sr (white emission); the floor beside it only
    # the area light's light.
    assert abs(_region(ours, -1.3, -0.7) - 7.0) < 0.01 and abs(_region(ref, -1.3, -0.7)
                                                              - 7.0) < 0.01
    # The floor under the light, lit alike; the floor the screen hides from the light
    # black in both (the screen is an opaque black surface to every other ray).
    a, b = _region(ours, 0.7, 1.3), _region(ref, 0.7, 1.3)
    assert abs(a / b - 1.0) < 0.05, (a, b)
    assert _region(ours, -1.9, -1.6) < 1e-3 and _region(ref, -1.9, -1.6) < 1e-3


def test_wall_red_to_the_camera_white_to_bounces_bleeds_white_as_cycles(bpy_addon, tmp_path):
    """4. Colour bleeding control: a Diffuse wall whose Color is Mix(Factor = Is Camera
    Ray, white, red): the camera sees it red, the light it bounces onto the floor is
    white (Cycles and ours: the floor's red / green ratio near the wall within 5 %)."""
    bpy = bpy_addon
    scene = _base(bpy)
    m, nt, out = node_material(bpy, "Wall")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["A"].default_value = (0.9, 0.9, 0.9, 1.0)
    mix.inputs["B"].default_value = (0.9, 0.05, 0.05, 1.0)
    path = nt.nodes.new("ShaderNodeLightPath")
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Factor"])
    nt.links.new(mix.outputs["Result"], d.inputs["Color"])
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.6, 0.0, 1.0),
                                     rotation=(0.0, np.pi / 2, 0.0))
    bpy.context.object.data.materials.append(m)
    _area(bpy, scene, -0.4, power=400.0)
    cam = scene.camera
    cam.data.type = "PERSP"
    cam.location, cam.rotation_euler = (-3.0, 0.0, 1.6), (np.radians(70.0), 0.0,
                                                          np.radians(-90.0))
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 512, 8)
    ref = read_rgba(bpy, render_exr(bpy, scene, str(tmp_path / "c.exr")))[..., :3]
    scene.render.engine = "PHOTONMAP"
    scene.photonmap.spp = 16
    ours = read_rgba(bpy, render_exr(bpy, scene, str(tmp_path / "o.exr")))[..., :3]
    from blender_helpers import project

    def patch(img, point, r=2):
        row, col = project(bpy, scene, point)
        return img[row - r:row + r + 1, col - r:col + r + 1].reshape(-1, 3).mean(axis=0)

    wall_o, wall_c = patch(ours, (0.6, 0.0, 1.2)), patch(ref, (0.6, 0.0, 1.2))
    assert wall_c[0] > 5 * wall_c[1] and wall_o[0] > 5 * wall_o[1]  # red to the camera
    assert abs(wall_o[0] / wall_c[0] - 1.0) < 0.04
    floor_o, floor_c = patch(ours, (0.0, 0.0, 0.0), 1), patch(ref, (0.0, 0.0, 0.0), 1)
    assert abs(floor_o.mean() / floor_c.mean() - 1.0) < 0.05
    assert abs((floor_o[0] / floor_o[1]) / (floor_c[0] / floor_c[1]) - 1.0) < 0.05


def test_conversion_keeps_the_classes_that_differ_and_warns_per_hit_outputs(bpy_addon):
    """The converter's variants (addon/lightpath.py): a shadow-ray window has a shadow
    variant only; Is Glossy Ray splits glossy and transmission rays (Cycles' glass
    refraction carries PATH_RAY_GLOSSY); a material without Light Path has none; Ray Length
    is warned by material and node name and reads 0."""
    from blender_helpers import convert_material
    bpy = bpy_addon
    bpy.ops.wm.read_homefile(use_empty=True)
    transparent = lambda nt: nt.nodes.new("ShaderNodeBsdfTransparent")  # noqa: E731
    window = convert_material(_light_path_material(bpy, "W", "Is Shadow Ray", _glass,
                                                   transparent))
    assert set(window.ray_variants) == {"shadow"} and window.transmission == 1.0
    assert window.ray_variants["shadow"].alpha == 0.0 and not window.warnings
    glossy = convert_material(_light_path_material(bpy, "G", "Is Glossy Ray", _glass,
                                                   transparent))
    assert set(glossy.ray_variants) == {"glossy", "transmission"}
    plain = convert_material(glass_or_diffuse_material(bpy, "P", "glass", (1.0,) * 3))
    assert plain.ray_variants is None
    m, nt, out = node_material(bpy, "Fade")
    e = _emission(nt)
    path = nt.nodes.new("ShaderNodeLightPath")
    path.name = "Path"
    nt.links.new(path.outputs["Ray Length"], e.inputs["Strength"])
    nt.links.new(e.outputs[0], out.inputs["Surface"])
    fade = convert_material(m)
    assert fade.emission.max() == 0.0 and fade.ray_variants is None
    assert any("'Fade'" in w and "'Path'" in w and "Ray Length" in w for w in fade.warnings)


def test_floor_blue_to_transmission_rays_as_cycles(bpy_addon, tmp_path):
    """5. The camera chain's own classes: a floor of Mix Shader(Is Transmission Ray, white
    Diffuse, blue Diffuse) under a clear glass slab (Glass BSDF alone) seen straight down:
    through the glass (transmission rays) it is blue, beside it (camera rays) white, in
    Cycles and ours; the blue patch's channels within 5 % of Cycles'."""
    bpy = bpy_addon
    scene = _base(bpy)

    def diffuse(rgb):
        def make(nt):
            n = nt.nodes.new("ShaderNodeBsdfDiffuse")
            n.inputs["Color"].default_value = (*rgb, 1.0)
            return n
        return make

    floor = _light_path_material(bpy, "TFloor", "Is Transmission Ray", diffuse((0.8,) * 3),
                                 diffuse((0.1, 0.2, 0.8)))
    bpy.data.objects["Plane"].data.materials[0] = floor
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.5))
    bpy.context.object.scale = (1.2, 1.2, 0.02)
    bpy.context.object.data.materials.append(
        glass_or_diffuse_material(bpy, "Clear", "glass", (1.0,) * 3))
    _area(bpy, scene, 1.5)
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 256, 8)
    ref = read_rgba(bpy, render_exr(bpy, scene, str(tmp_path / "c.exr")))[..., :3]
    scene.render.engine = "PHOTONMAP"
    scene.photonmap.spp = 16
    ours = read_rgba(bpy, render_exr(bpy, scene, str(tmp_path / "o.exr")))[..., :3]

    def rgb(img, x0, x1):
        return np.array([_region(img[..., c], x0, x1) for c in range(3)])

    for img in (ours, ref):
        through, beside = rgb(img, -0.3, 0.3), rgb(img, 1.2, 1.8)
        assert through[2] > 2.0 * through[0]  # blue through the glass
        assert abs(beside[2] / beside[0] - 1.0) < 0.05  # white beside it
    for x0, x1 in ((-0.3, 0.3), (1.2, 1.8)):
        a, b = rgb(ours, x0, x1), rgb(ref, x0, x1)
        assert np.all(np.abs(a / b - 1.0) < 0.05), ((x0, x1), a, b)
