"""Add Shader and Refraction BSDF against Cycles (issue 14: "Diffuse, Glossy, Glass,
Refraction; Mix and Add. Every closure matches Cycles within 2 %").

- Add Shader sums its two closures (Cycles); it was exported as their even mix (exactly
  0.500 of Cycles on a sun-lit plane). A plane lit by a delta sun in a black world, seen
  at 45 degrees, direct light only: every pixel is one BSDF evaluation in both engines,
  so the image means agree to well within the 2 % the issue asks.
- Mix Shader of two surfaces whose parameters do not blend linearly (a blue dielectric and
  a gold metal, by a constant or a Noise Texture): each hit takes one of the two closures
  as Cycles' closure sampling does; the parameters' blend was R +76 % on such a plane.
- Refraction BSDF transmits only (colour x refraction, no Fresnel reflection); it was
  exported as a Glass BSDF (1.086 of Cycles on a ball). A smooth slab of it over an
  emissive floor, seen from straight above through a black world: each pixel sees the
  floor through two parallel interfaces, colour^2 x the floor's radiance (the n^2 of the
  two crossings cancel), where a Glass BSDF's Fresnel would take ~8 % away.
"""
import math

import numpy as np
import pytest
from tools.canonical_mesh import primitive_uv_sphere_add

pytestmark = pytest.mark.blender


def _material(bpy, name, build):
    """A material whose Surface is build(nodes, links) (-> the output socket)."""
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(build(nt.nodes, nt.links), out.inputs["Surface"])
    return m


def _diffuse(nodes, rgb):
    n = nodes.new("ShaderNodeBsdfDiffuse")
    n.inputs["Color"].default_value = (*rgb, 1.0)
    return n.outputs[0]


def _glossy(nodes, rgb, roughness):
    n = nodes.new("ShaderNodeBsdfGlossy")  # Multiscatter GGX, the node's default
    n.inputs["Color"].default_value = (*rgb, 1.0)
    n.inputs["Roughness"].default_value = roughness
    return n.outputs[0]


def _add(nodes, links, a, b):
    n = nodes.new("ShaderNodeAddShader")
    links.new(a, n.inputs[0])
    links.new(b, n.inputs[1])
    return n.outputs[0]


def _mix(nodes, links, fac, a, b):
    n = nodes.new("ShaderNodeMixShader")
    n.inputs[0].default_value = fac
    links.new(a, n.inputs[1])
    links.new(b, n.inputs[2])
    return n.outputs[0]


ADD_CASES = {
    "diffuse+diffuse": lambda nd, ln: _add(nd, ln, _diffuse(nd, (0.4, 0.4, 0.4)),
                                          _diffuse(nd, (0.4, 0.4, 0.4))),
    "red+blue diffuse": lambda nd, ln: _add(nd, ln, _diffuse(nd, (0.5, 0.1, 0.05)),
                                           _diffuse(nd, (0.05, 0.2, 0.6))),
    "diffuse+glossy": lambda nd, ln: _add(nd, ln, _diffuse(nd, (0.5, 0.5, 0.5)),
                                         _glossy(nd, (0.5, 0.5, 0.5), 0.4)),
    "tinted diffuse+glossy": lambda nd, ln: _add(nd, ln, _diffuse(nd, (0.6, 0.3, 0.1)),
                                                _glossy(nd, (0.3, 0.5, 0.8), 0.3)),
    # An Add inside a Mix: (1 - f) x (diffuse + glossy) + f x diffuse.
    "mix(add, diffuse)": lambda nd, ln: _mix(
        nd, ln, 0.3, _add(nd, ln, _diffuse(nd, (0.5, 0.5, 0.5)),
                          _glossy(nd, (0.5, 0.5, 0.5), 0.4)),
        _diffuse(nd, (0.2, 0.6, 0.3))),
}

# Unlike surfaces, which a blend of parameters at weight 2 misrendered (s42: Diffuse +
# Glass 4.8 / 1.6 / 0.85 x Cycles, dielectric + metal 0.85 / 0.63 / 0.66 x, Glossy +
# dielectric 0.8 x, Diffuse + metal 0.64 / 0.82 / 1.37 x): each hit takes one side whole
# at weight 2, Cycles' sum in expectation (test_add_shader_of_unlike_surfaces_...).
ADD_UNLIKE_CASES = {
    "blue diffuse+yellow glass": lambda nd, ln: _add(nd, ln, _diffuse(nd, (0.1, 0.4, 0.8)),
                                                    _glass_node(nd)),
    "red dielectric+gold metal": lambda nd, ln: _add(
        nd, ln, _principled(nd, (0.8, 0.2, 0.1), 0.5), _gold_metal(nd)),
    "gold glossy+red dielectric": lambda nd, ln: _add(
        nd, ln, _glossy(nd, (0.9, 0.8, 0.3), 0.25), _principled(nd, (0.8, 0.2, 0.1), 0.5)),
    "blue diffuse+gold metal": lambda nd, ln: _add(nd, ln, _diffuse(nd, (0.1, 0.4, 0.8)),
                                                  _gold_metal(nd)),
    # A glowing see-through card (a hologram): the emission adds light, not coverage (an
    # opaque grey card before s42: 7.3 / 2.4 / 5.2 x Cycles on the sunlit plane).
    "orange transparent+green emission": lambda nd, ln: _add(
        nd, ln, _transparent(nd, (0.9, 0.7, 0.4)), _emission(nd, (0.2, 0.9, 0.3))),
}



def _principled(nodes, rgb, roughness, metallic=0.0, ior=1.5, coat=None):
    """coat: (Coat Weight, Coat Tint RGB, Coat IOR, Coat Roughness) or None (no coat)."""
    n = nodes.new("ShaderNodeBsdfPrincipled")
    n.inputs["Base Color"].default_value = (*rgb, 1.0)
    n.inputs["Roughness"].default_value = roughness
    n.inputs["Metallic"].default_value = metallic
    n.inputs["IOR"].default_value = ior
    if coat is not None:
        n.inputs["Coat Weight"].default_value = coat[0]
        n.inputs["Coat Tint"].default_value = (*coat[1], 1.0)
        n.inputs["Coat IOR"].default_value = coat[2]
        n.inputs["Coat Roughness"].default_value = coat[3]
    return n.outputs[0]


def _noise_mix(nodes, links, a, b):
    """Mix Shader by a Noise Texture's Fac (scale 6, Blender's defaults otherwise)."""
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 6.0
    n = nodes.new("ShaderNodeMixShader")
    links.new(noise.outputs["Fac"], n.inputs[0])
    links.new(a, n.inputs[1])
    links.new(b, n.inputs[2])
    return n.outputs[0]


def _emission(nd, rgb, strength=0.5):
    n = nd.new("ShaderNodeEmission")
    n.inputs["Color"].default_value = (*rgb, 1.0)
    n.inputs["Strength"].default_value = strength
    return n.outputs[0]


def _glass_node(nd, roughness=0.0, rgb=(0.9, 0.9, 0.6)):
    n = nd.new("ShaderNodeBsdfGlass")
    n.inputs["Roughness"].default_value = roughness
    n.inputs["Color"].default_value = (*rgb, 1.0)
    return n.outputs[0]


def _transparent(nd, rgb):
    n = nd.new("ShaderNodeBsdfTransparent")
    n.inputs["Color"].default_value = (*rgb, 1.0)
    return n.outputs[0]


def _sheen(nd, rgb):
    n = nd.new("ShaderNodeBsdfSheen")
    n.inputs["Color"].default_value = (*rgb, 1.0)
    return n.outputs[0]


def _refraction(nd, roughness=0.2, rgb=(0.6, 0.9, 0.6)):
    n = nd.new("ShaderNodeBsdfRefraction")
    n.inputs["Roughness"].default_value = roughness
    n.inputs["Color"].default_value = (*rgb, 1.0)
    return n.outputs[0]


def _blue_dielectric(nd):
    return _principled(nd, (0.1, 0.4, 0.8), 0.6)


def _gold_metal(nd):
    return _principled(nd, (0.95, 0.8, 0.4), 0.25, metallic=1.0)


# Mix Shader of two surfaces whose parameters do not blend linearly (issue 14, newuser24
# finding 3): Cycles mixes the two BSDFs, a blend of the parameters is a teal half-metal
# (R +76 % on a sun-lit plane before mixpale).
MIX_CASES = {
    "dielectric+metal 0.5": lambda nd, ln: _mix(nd, ln, 0.5, _blue_dielectric(nd),
                                                _gold_metal(nd)),
    "dielectric+metal noise": lambda nd, ln: _noise_mix(nd, ln, _blue_dielectric(nd),
                                                        _gold_metal(nd)),
    "red diffuse+rough white metal 0.3": lambda nd, ln: _mix(
        nd, ln, 0.3, _diffuse(nd, (0.7, 0.1, 0.1)), _principled(nd, (0.9, 0.9, 0.9), 0.5,
                                                                  metallic=1.0)),
    # The picked side's IOR, not the blend's (mixsides: one IOR 2.75 per material made
    # the red side's specular layer 5 x too strong and the white side's too weak).
    "red IOR 1.5+white IOR 4 noise": lambda nd, ln: _noise_mix(
        nd, ln, _principled(nd, (0.8, 0.1, 0.1), 0.3, ior=1.5),
        _principled(nd, (0.8, 0.8, 0.8), 0.3, ior=4.0)),
    # The picked side's coat tint and IOR (a green-tinted coat on red, no coat on blue:
    # the blend's tint was halfway to white). A rough coat: no sharp highlight of the sun
    # in view, whose few pixels would decide the mean.
    # A Glossy BSDF and a Principled dielectric of another roughness, in either order:
    # with the Glossy BSDF first they were blended to one roughness (s42: highlight
    # blocks 0.91-1.41 of Cycles on a ball); now picked per hit under the Glossy BSDF's
    # colour model, exact for a side without a metal lobe.
    "gold glossy+blue dielectric 0.4": lambda nd, ln: _mix(
        nd, ln, 0.4, _glossy(nd, (0.9, 0.8, 0.3), 0.25), _blue_dielectric(nd)),
    "blue dielectric+gold glossy 0.6": lambda nd, ln: _mix(
        nd, ln, 0.6, _blue_dielectric(nd), _glossy(nd, (0.9, 0.8, 0.3), 0.25)),
    # A Glass BSDF beside a Principled dielectric: blended, 4.6 / 2.3 / 1.4 x Cycles per
    # channel on this plane (s42); picked per hit, within 1 %.
    "yellow glass+blue dielectric 0.5": lambda nd, ln: _mix(
        nd, ln, 0.5, _glass_node(nd), _blue_dielectric(nd)),
    # A Glass BSDF's colour tints its own lobes: a blend with a blue Diffuse averaged the
    # colours (4.8 / 1.6 / 0.85 x Cycles); two Glossy BSDFs of two colours and roughnesses
    # were blended to one (0.84 / 1.04 / 1.33 x). Both picked per hit since s42.
    "yellow glass+blue diffuse 0.5": lambda nd, ln: _mix(
        nd, ln, 0.5, _glass_node(nd), _diffuse(nd, (0.1, 0.4, 0.8))),
    "gold glossy 0.25+cyan glossy 0.6": lambda nd, ln: _mix(
        nd, ln, 0.5, _glossy(nd, (0.9, 0.8, 0.3), 0.25), _glossy(nd, (0.3, 0.8, 0.9), 0.6)),
    # An Emission side is black as a surface: the other side's lobes scale by their
    # share. The colour was scaled instead, which left a Glossy BSDF (1.65 x Cycles), a
    # dielectric's specular layer (1.11-1.29 x) and a sheen (1.18 x) whole (s42).
    "gold glossy+green emission 0.4": lambda nd, ln: _mix(
        nd, ln, 0.4, _glossy(nd, (0.9, 0.8, 0.3), 0.25), _emission(nd, (0.2, 0.9, 0.3))),
    "red dielectric+green emission 0.4": lambda nd, ln: _mix(
        nd, ln, 0.4, _principled(nd, (0.8, 0.2, 0.1), 0.5), _emission(nd, (0.2, 0.9, 0.3))),
    # The picked side's closure model: a Refraction BSDF (no reflection) beside a Glass
    # BSDF or a metal rendered under the other's model: 1.6-1.9 x / 1.03-1.08 x (s42).
    "rough glass+green refraction 0.4": lambda nd, ln: _mix(
        nd, ln, 0.4, _glass_node(nd, 0.3, (0.9, 0.9, 0.9)), _refraction(nd)),
    "gold metal+green refraction 0.4": lambda nd, ln: _mix(
        nd, ln, 0.4, _gold_metal(nd), _refraction(nd)),
    # A Sheen BSDF beside a Glossy BSDF became a sheen layer over the glossy lobe,
    # dimming it by the sheen's albedo (0.975-0.98 x Cycles, s42); picked since.
    "gold glossy+pink sheen 0.4": lambda nd, ln: _mix(
        nd, ln, 0.4, _glossy(nd, (0.9, 0.8, 0.3), 0.25), _sheen(nd, (0.9, 0.3, 0.5))),
    "green-coated red+blue 0.5": lambda nd, ln: _mix(
        nd, ln, 0.5, _principled(nd, (0.8, 0.2, 0.1), 0.4,
                                 coat=(1.0, (0.3, 0.9, 0.2), 2.0, 0.3)),
        _principled(nd, (0.1, 0.3, 0.8), 0.4)),
}

def _render(bpy, scene, path, engine, spp, bounces):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    if engine == "CYCLES":
        c = cycles_plain(scene, spp, bounces)
        c.transmission_bounces = bounces
        c.caustics_reflective = c.caustics_refractive = True
    else:
        cheap(scene, spp=spp, photons=20_000, caustic_photons=0)
        scene.photonmap.photon_mapping = False
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3]


def _black_world(bpy, scene):
    world = bpy.data.worlds.new("Black")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = 0.0


def _camera(bpy, scene, location, rotation, ortho=None):
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = location, rotation
    if ortho is not None:
        cam.data.type, cam.data.ortho_scale = "ORTHO", ortho
    scene.collection.objects.link(cam)
    scene.camera = cam


def _check(ours, ref, what):
    """Image means within 2 % per channel (of the brightest channel for a faint one)."""
    got, want = ours.reshape(-1, 3).mean(axis=0), ref.reshape(-1, 3).mean(axis=0)
    print(f"{what}: ours / Cycles {np.round(got / np.maximum(want, 1e-9), 4)}")
    tol = np.maximum(0.02 * want, 0.02 * want.max())
    assert np.all(np.abs(got - want) <= tol), (
        f"{what}: ours {np.round(got, 4)} Cycles {np.round(want, 4)} "
        f"(ratio {np.round(got / np.maximum(want, 1e-9), 4)})")


@pytest.mark.parametrize("case", sorted(ADD_CASES))
def test_add_shader_on_sunlit_plane_matches_cycles(fresh_scene, bpy_addon, tmp_path, case):
    bpy = bpy_addon
    scene = fresh_scene
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(_material(bpy, "Add", ADD_CASES[case]))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = (0.0, math.radians(35.0), 0.0)  # light from +x, 35 deg off zenith
    scene.collection.objects.link(sun)
    # From -x at 45 degrees: the glossy lobe's highlight lies in the field of view.
    _camera(bpy, scene, (-6.0, 0.0, 6.0), (math.radians(45.0), 0.0, math.radians(-90.0)))
    _black_world(bpy, scene)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 4, 0)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 16, 0)
    assert ref.mean() > 0.05
    _check(ours, ref, case)


def _picks_on_sunlit_plane(bpy, scene, tmp_path, build, case):
    """The sunlit plane of material build, ours at 64 spp against Cycles at 256: a pick's
    noise (each hit takes one of two closures, engine.shadernodes.ClosurePick; a sun's
    highlight on a metal side) stays inside _check's 2 % (at 16 / 64 spp two cases sat at
    1.1-1.3 % with one set of picks and 2.1-2.3 % with another)."""
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(_material(bpy, "Picked", build))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = (0.0, math.radians(35.0), 0.0)
    scene.collection.objects.link(sun)
    _camera(bpy, scene, (-6.0, 0.0, 6.0), (math.radians(45.0), 0.0, math.radians(-90.0)))
    _black_world(bpy, scene)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 64, 0)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 256, 0)
    assert ref.mean() > 0.05
    _check(ours, ref, case)


@pytest.mark.parametrize("case", sorted(ADD_UNLIKE_CASES))
def test_add_shader_of_unlike_surfaces_matches_cycles(fresh_scene, bpy_addon, tmp_path, case):
    """Each hit takes one of the two closures at weight 2 (an Add Shader sums them)."""
    _picks_on_sunlit_plane(bpy_addon, fresh_scene, tmp_path, ADD_UNLIKE_CASES[case], case)


@pytest.mark.parametrize("case", sorted(MIX_CASES))
def test_mix_shader_of_unlike_surfaces_matches_cycles(fresh_scene, bpy_addon, tmp_path,
                                                      case):
    """Each hit takes one of the two closures, or a blend where it is exact."""
    _picks_on_sunlit_plane(bpy_addon, fresh_scene, tmp_path, MIX_CASES[case], case)


@pytest.mark.parametrize("color", [(1.0, 1.0, 1.0), (0.9, 0.6, 0.3)])
def test_refraction_slab_over_emissive_floor_matches_cycles(fresh_scene, bpy_addon, tmp_path,
                                                            color):
    bpy = bpy_addon
    scene = fresh_scene
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100

    def emission(nodes, links):
        n = nodes.new("ShaderNodeEmission")
        n.inputs["Strength"].default_value = 1.0
        return n.outputs[0]

    def refraction(nodes, links):
        n = nodes.new("ShaderNodeBsdfRefraction")
        n.inputs["Color"].default_value = (*color, 1.0)
        n.inputs["Roughness"].default_value = 0.0
        n.inputs["IOR"].default_value = 1.45
        return n.outputs[0]

    bpy.ops.mesh.primitive_plane_add(size=20)
    bpy.context.object.data.materials.append(_material(bpy, "Floor", emission))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 1.0))
    slab = bpy.context.object
    slab.scale = (6.0, 6.0, 0.3)
    slab.data.materials.append(_material(bpy, "Refraction", refraction))
    # Straight down, orthographic, 2 m across: every pixel looks through the slab.
    _camera(bpy, scene, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0), ortho=2.0)
    _black_world(bpy, scene)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 4, 8)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 64, 8)
    # Cycles at 4 spp drops one sample in a few pixels (0.984 of colour^2); at 64 spp 0.999.
    np.testing.assert_allclose(ref.reshape(-1, 3).mean(axis=0), np.square(color), rtol=0.01)
    _check(ours, ref, f"refraction {color}")


def _nodes_of(node, seen=None):
    """Every engine node reachable from node through its attributes."""
    seen = [] if seen is None else seen
    if hasattr(node, "evaluate") and all(n is not node for n in seen):
        seen.append(node)
        for v in vars(node).values():
            _nodes_of(v, seen)
    return seen


def test_only_unlike_surfaces_pick_a_closure_per_hit(fresh_scene, bpy_addon):
    """A parameter blend stays where it is exact (no noise added): two Diffuse colours by
    a texture, a Diffuse and a Glossy; a dielectric and a metal take one side per hit."""
    from blender_helpers import convert_material
    from engine.shadernodes import ClosurePick
    bpy = bpy_addon

    def picks(build):
        t = convert_material(_material(bpy, "M", build))
        roots = [t.texture, *(t.scalar_textures or {}).values()]
        return any(isinstance(n, ClosurePick) for r in roots for n in _nodes_of(r))
    assert not picks(lambda nd, ln: _noise_mix(nd, ln, _diffuse(nd, (0.7, 0.1, 0.1)),
                                               _diffuse(nd, (0.1, 0.1, 0.7))))
    assert not picks(lambda nd, ln: _noise_mix(nd, ln, _diffuse(nd, (0.7, 0.1, 0.1)),
                                               _glossy(nd, (0.9, 0.9, 0.9), 0.2)))
    assert picks(lambda nd, ln: _noise_mix(nd, ln, _blue_dielectric(nd), _gold_metal(nd)))
    assert picks(MIX_CASES["dielectric+metal 0.5"])
    # mixsides: one colour, one set of lobe weights, but a parameter the blend holds at
    # one value per material differs (the IOR, a coat's tint): pick. A Diffuse side's IOR
    # has no say (the blend takes the glossy side's): no pick.
    white = (0.8, 0.8, 0.8)
    assert picks(lambda nd, ln: _noise_mix(nd, ln, _principled(nd, white, 0.3, ior=1.5),
                                           _principled(nd, white, 0.3, ior=2.4)))
    assert picks(lambda nd, ln: _noise_mix(
        nd, ln, _principled(nd, white, 0.3, coat=(1.0, (0.3, 0.9, 0.2), 1.5, 0.1)),
        _principled(nd, white, 0.3)))
    assert not picks(lambda nd, ln: _noise_mix(
        nd, ln, _principled(nd, white, 0.3, coat=(1.0, (1.0, 1.0, 1.0), 1.5, 0.1)),
        _principled(nd, white, 0.3)))
    assert not picks(lambda nd, ln: _noise_mix(nd, ln, _diffuse(nd, white),
                                               _principled(nd, white, 0.3, ior=2.4)))

    def textured_rough(nd, ln):
        # A side with a texture-driven Roughness: deciding the pick built the sides' blend
        # without engine nodes and raised AttributeError (before mixsides).
        side = _blue_dielectric(nd)
        tex = nd.new("ShaderNodeTexNoise")
        ln.new(tex.outputs["Fac"], side.node.inputs["Roughness"])
        return _noise_mix(nd, ln, side, _gold_metal(nd))
    assert picks(textured_rough)

    def nested(nd, ln):
        # A picked mix (IOR 1.5 / 2.4, one colour) inside an even mix with a Diffuse of
        # that colour: the outer blend keeps the picked IOR per hit (the Diffuse has no
        # IOR to dilute it with) and takes the tints as colours.
        inner = _noise_mix(nd, ln, _principled(nd, white, 0.3, ior=1.5),
                           _principled(nd, white, 0.3, ior=2.4))
        return _mix(nd, ln, 0.5, inner, _diffuse(nd, white))
    t = convert_material(_material(bpy, "N", nested))
    assert any(isinstance(n, ClosurePick) for n in _nodes_of(t.scalar_textures["ior"]))


def test_a_picked_mix_takes_each_sides_own_parameters(fresh_scene, bpy_addon):
    """mixsides: the IOR, coat IOR and tints, distribution and anisotropy of a picked mix
    come from the side each hit takes (they were one blended value per material)."""
    from blender_helpers import convert_material
    from engine.geometry import MaterialTable
    from engine.textures import scalar_params
    from engine.closures import principled as pr
    bpy = bpy_addon

    def build(nd, ln):
        a = _principled(nd, (0.8, 0.1, 0.1), 0.3, ior=1.5,
                        coat=(1.0, (0.3, 0.9, 0.2), 1.8, 0.1))
        b = _principled(nd, (0.1, 0.1, 0.8), 0.3, ior=2.4)
        nb = b.node
        nb.inputs["Anisotropic"].default_value = 0.7
        nb.inputs["Anisotropic Rotation"].default_value = 0.25
        nb.inputs["Specular Tint"].default_value = (0.2, 0.4, 0.9, 1.0)
        nb.distribution = "GGX"
        return _mix(nd, ln, 0.5, a, b)
    m = convert_material(_material(bpy, "M", build))
    table = MaterialTable.build([m])
    rng = np.random.default_rng(5)
    n = 4000
    prim = rng.integers(0, 2, n)
    u, v = rng.random(n) * 0.5, rng.random(n) * 0.5
    rows = scalar_params(table, None, np.zeros(n, np.int64), prim, u, v)
    b = rows[:, pr.M_COAT_W] == 0  # the hits that took the second (uncoated) side
    a = ~b
    assert 0.4 < b.mean() < 0.6
    expect = {pr.M_IOR: (1.5, 2.4), pr.M_COAT_IOR: (1.8, None), pr.M_MULTI: (1.0, 0.0),
              pr.M_ANISO: (0.0, 0.7), pr.M_AROT: (None, 0.25)}
    for col, (xa, xb) in expect.items():
        if xa is not None:
            np.testing.assert_allclose(rows[a, col], xa, err_msg=str(col))
        if xb is not None:
            np.testing.assert_allclose(rows[b, col], xb, err_msg=str(col))
    np.testing.assert_allclose(rows[a, pr.M_CTINT:pr.M_CTINT + 3], [[0.3, 0.9, 0.2]] * a.sum())
    np.testing.assert_allclose(rows[b, pr.M_STINT:pr.M_STINT + 3], [[0.2, 0.4, 0.9]] * b.sum())
    np.testing.assert_allclose(rows[a, pr.M_STINT:pr.M_STINT + 3], 1.0)


@pytest.mark.parametrize("fac", [0.0, 0.5])
def test_ceiling_lit_by_a_mix_shader_floor_matches_cycles(fresh_scene, bpy_addon, tmp_path,
                                                          fac):
    """A white ceiling lit only by what a floor reflects: the floor is a white dielectric
    or (probability fac) a white metal per hit, under an area light facing down. The
    ceiling's indirect light is the floor's photon density read by gather rays through
    the floor's own pick. Issue 14 (review of mixpale): photons were stored only where
    their own hit took the dielectric side, so the gather read (1 - f)^2 of the floor's
    diffuse light."""
    bpy = bpy_addon
    scene = fresh_scene
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.context.object.data.materials.append(_material(
        bpy, "MixFloor", lambda nd, ln: _mix(nd, ln, fac,
                                             _principled(nd, (0.8, 0.8, 0.8), 0.5),
                                             _principled(nd, (0.9, 0.9, 0.9), 0.3,
                                                         metallic=1.0))))
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, 2.0),
                                     rotation=(math.pi, 0.0, 0.0))
    bpy.context.object.data.materials.append(_material(
        bpy, "Ceiling", lambda nd, ln: _diffuse(nd, (0.8, 0.8, 0.8))))
    # Facing down (an area light emits along its local -Z): it lights the floor only.
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "AREA"))
    lamp.data.energy, lamp.data.size = 200.0, 0.5
    lamp.location = (-1.0, 0.0, 1.0)
    scene.collection.objects.link(lamp)
    # Looking up at the ceiling, away from the lamp.
    _camera(bpy, scene, (0.8, 0.0, 0.5), (math.pi, 0.0, 0.0), ortho=1.2)
    _black_world(bpy, scene)
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    cycles_plain(scene, 1024, 4)
    c = scene.cycles
    c.caustics_reflective = c.caustics_refractive = True
    scene.render.engine = "CYCLES"
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=16, photons=200_000, caustic_photons=200_000)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    assert ref.mean() > 0.005
    got, want = ours.reshape(-1, 3).mean(axis=0), ref.reshape(-1, 3).mean(axis=0)
    print(f"ceiling over mix {fac}: ours / Cycles {np.round(got / want, 4)} "
          f"Cycles {np.round(want, 4)}")
    np.testing.assert_allclose(got, want, rtol=0.03)


def test_picked_mix_warns_what_stays_one_per_material(fresh_scene, bpy_addon):
    """mixsides: sides with different Normal inputs share one shading normal: warned,
    naming the material and the node. The closure model is picked per hit since s42 (a
    Principled metal beside a Glossy BSDF, a Glass beside a Refraction BSDF): each hit's
    row takes its side's model, and nothing of it is warned."""
    from blender_helpers import convert_material
    from engine.geometry import MaterialTable, node_code
    from engine.textures import scalar_params
    from engine.closures import principled as pr
    bpy = bpy_addon

    def models(nd, ln):
        return _mix(nd, ln, 0.5, _gold_metal(nd), _glossy(nd, (0.9, 0.7, 0.3), 0.2))

    def dielectric_glossy(nd, ln):
        return _noise_mix(nd, ln, _blue_dielectric(nd), _glossy(nd, (0.9, 0.7, 0.3), 0.2))

    def normals(nd, ln):
        side = _blue_dielectric(nd)
        bump = nd.new("ShaderNodeBump")
        tex = nd.new("ShaderNodeTexNoise")
        ln.new(tex.outputs["Fac"], bump.inputs["Height"])
        ln.new(bump.outputs["Normal"], side.node.inputs["Normal"])
        return _noise_mix(nd, ln, side, _gold_metal(nd))
    m = convert_material(_material(bpy, "Models", models))
    rng = np.random.default_rng(3)
    n = 4000
    rows = scalar_params(MaterialTable.build([m]), None, np.zeros(n, np.int64),
                         rng.integers(0, 2, n), rng.random(n) * 0.5, rng.random(n) * 0.5)
    gold = rows[:, pr.M_NODE] == node_code("principled")
    glossy = rows[:, pr.M_NODE] == node_code("glossy")
    assert np.all(gold | glossy) and 0.2 < gold.mean() < 0.8
    np.testing.assert_allclose(rows[gold, pr.M_ROUGH], 0.25, rtol=1e-6)
    np.testing.assert_allclose(rows[glossy, pr.M_ROUGH], 0.2, rtol=1e-6)
    w = convert_material(_material(bpy, "Normals", normals)).warnings
    assert any("'Normals'" in x and "'Normal' inputs differ" in x for x in w), w
    w = convert_material(_material(bpy, "Plain", MIX_CASES["dielectric+metal noise"])).warnings
    assert not any("inputs differ" in x for x in w), w
    m = convert_material(_material(bpy, "DG", dielectric_glossy))
    assert m.node == "glossy", m.node


@pytest.mark.parametrize("first", ["glossy", "principled"])
def test_a_glossy_bsdf_mixed_with_a_principled_is_picked_and_named_glossy(
        fresh_scene, bpy_addon, first):
    """Mix of a Glossy BSDF (roughness 0.1) and a Principled dielectric (0.6) at a constant
    factor, in either order: each hit takes one side whole (a blend held one roughness,
    0.25, with the Glossy BSDF first), under the Glossy BSDF's colour model, without a
    warning; the effect report names a glossy object, not 'polished metal (metallic 1)'
    (newuser41b)."""
    from blender_helpers import convert_material, export_warnings
    from engine.shadernodes import ClosurePick
    bpy = bpy_addon

    def build(nd, ln):
        g, p = _glossy(nd, (0.9, 0.8, 0.3), 0.1), _principled(nd, (0.7, 0.1, 0.1), 0.6)
        return _mix(nd, ln, 0.3, g, p) if first == "glossy" else _mix(nd, ln, 0.7, p, g)
    mat = _material(bpy, "GP", build)
    m = convert_material(mat)
    assert m.node == "glossy", m.node
    roots = list((m.scalar_textures or {}).values())
    assert any(isinstance(n, ClosurePick) for r in roots for n in _nodes_of(r)), roots
    assert not any("Mix Shader" in x for x in m.warnings), m.warnings
    primitive_uv_sphere_add(radius=0.5, location=(0, 0, 0.5))
    bpy.context.object.data.materials.append(mat)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.location = (1.0, -1.0, 3.0)
    fresh_scene.collection.objects.link(lamp)
    _camera(bpy, fresh_scene, (0.0, -3.0, 0.5), (math.radians(90.0), 0.0, 0.0))
    from addon.core import load_engine
    from addon import export
    from engine import RenderSettings
    from engine.render import prepare_context
    scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                   width=16, height=12)
    ctx = prepare_context(scene, RenderSettings(photons=2000, caustic_photons=2000,
                                                workers=1))
    ctx.accel.close()
    line = next(x for x in ctx.plan.report() if x.startswith("specular reflection"))
    assert "glossy 'Sphere' (Glossy BSDF, roughness 0.1)" in line, line
    assert "metal" not in line, line


def _glass_cylinder(bpy, scene, roughness):
    """The smooth-shaded glass cylinder scene of the two tests below, Principled glass
    (IOR 1.5) of the given roughness."""
    scene.render.resolution_x, scene.render.resolution_y = 48, 48
    scene.render.resolution_percentage = 100

    def emission(nodes, links):
        n = nodes.new("ShaderNodeEmission")
        n.inputs["Color"].default_value = (0.9, 0.8, 0.6, 1.0)
        n.inputs["Strength"].default_value = 1.0
        return n.outputs[0]

    def glass(nodes, links):
        n = nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        n.inputs["Roughness"].default_value = roughness
        n.inputs["Transmission Weight"].default_value = 1.0
        n.inputs["IOR"].default_value = 1.5
        return n.outputs[0]

    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(_material(bpy, "Floor", emission))
    # 0.1 mm above the floor: at exact contact Cycles' image is a rounding discontinuity
    # (rays inside the glass meet the cap and the floor at one distance; docs/accuracy.md,
    # contact30), and these tests are about the rims' raised normals.
    bpy.ops.mesh.primitive_cylinder_add(vertices=16, radius=0.5, depth=1.2,
                                        location=(0.0, 0.0, 0.6001))
    cyl = bpy.context.object
    bpy.ops.object.shade_smooth()
    cyl.data.materials.append(_material(bpy, "Glass", glass))
    # From the side, 30 degrees down: the bottom rim's normals face away from the camera.
    _camera(bpy, scene, (0.0, -3.2, 2.4), (math.radians(60.0), 0.0, 0.0))
    scene.camera.data.lens = 50.0
    _black_world(bpy, scene)


def test_smooth_shaded_glass_cylinder_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """A smooth-shaded glass cylinder with caps (a bottle as artists model it: s26's
    new-user trial, its bottom band 0.67 of Cycles): at the rims the interpolated normal
    tilts ~45 degrees and faces away from the camera, where Cycles refracts about its
    raised normal (maybe_ensure_valid_specular_reflection, for its glass closures too);
    without the raise our camera paths died there. Over an emissive floor in a black
    world, specular chains only (photon mapping off): every pixel is the floor's emission
    through the glass in both engines. The lower half of the cylinder, where its bottom
    rim is, within 3 %, the image within 2 %."""
    bpy = bpy_addon
    scene = fresh_scene
    _glass_cylinder(bpy, scene, 0.0)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 16, 12)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 64, 12)
    _check(ours, ref, "smooth glass cylinder (image)")
    lower = slice(24, 40)  # the rows below the image centre, over the bottom rim
    _check(ours[lower], ref[lower], "smooth glass cylinder (lower rows)")


@pytest.mark.parametrize("roughness", [0.1, 0.3, 0.6])
def test_smooth_shaded_rough_glass_cylinder_matches_cycles(fresh_scene, bpy_addon, tmp_path,
                                                           roughness):
    """The same cylinder of rough glass: Cycles raises its rough glass closure's normal
    too (bsdf_microfacet.h takes valid_reflection_N as its N), and so do we
    (principled.raised_rough_glass): at the bottom rim, where the interpolated normal
    faces away from the camera, the lobe's sampling, eval and pdf are about the raised
    normal. Before, rough glass kept the shading normal and the lower rows read 0.953,
    0.968 and 0.973 of Cycles at roughness 0.1, 0.3 and 0.6; now 0.997, 0.994 and 0.979
    (bench/bench_rough_glass_rim.py). The lower rows within 3 %, the image within 2 %."""
    bpy = bpy_addon
    scene = fresh_scene
    _glass_cylinder(bpy, scene, roughness)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 64, 12)
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 512, 12)
    _check(ours, ref, f"rough glass cylinder {roughness} (image)")
    lower = slice(24, 40)  # the rows below the image centre, over the bottom rim
    got, want = ours[lower].mean(), ref[lower].mean()
    print(f"rough glass cylinder {roughness} (lower rows): ours / Cycles {got / want:.4f}")
    assert abs(got / want - 1.0) <= 0.03, (got, want)


def test_refraction_out_onto_a_touching_floor_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """A smooth-shaded glass cylinder standing on the floor, its bottom cap in the floor's
    plane (a bottle as a user places it; issue 14's product shot, product29). Camera rays
    refracted out through the cap meet the floor right there in Cycles (it skips only the
    primitive a ray leaves); ours started them a rounding offset past the cap, below the
    floor's plane too, and they saw the world under it (engine/coincident.py). Red
    emissive floor, green world, photon mapping off: in the cylinder's upper rows, which
    look down through it to where it stands, the floor's and the world's shares of the
    light (red, green) as Cycles' within 0.03 (before: red 0.845, green 0.127 against
    Cycles' 0.910, 0.062; after 0.911, 0.062)."""
    from blender_helpers import project
    bpy = bpy_addon
    scene = fresh_scene
    scene.render.resolution_x, scene.render.resolution_y = 48, 48
    scene.render.resolution_percentage = 100

    def emission(nodes, links):
        n = nodes.new("ShaderNodeEmission")
        n.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
        n.inputs["Strength"].default_value = 1.0
        return n.outputs[0]

    def glass(nodes, links):
        n = nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        n.inputs["Roughness"].default_value = 0.0
        n.inputs["Transmission Weight"].default_value = 1.0
        n.inputs["IOR"].default_value = 1.45
        return n.outputs[0]

    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(_material(bpy, "Floor", emission))
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=0.22, depth=0.9,
                                        location=(0.0, 0.0, 0.45))
    cyl = bpy.context.object
    bpy.ops.object.shade_smooth()
    cyl.data.materials.append(_material(bpy, "Glass", glass))
    # From 10 degrees above the cylinder's top, aimed at its middle: its upper rows look
    # down through it.
    height = 0.9 + 3.0 * math.tan(math.radians(10.0))
    _camera(bpy, scene, (0.0, -3.0, height),
            (math.pi / 2 - math.atan2(height - 0.45, 3.0), 0.0, 0.0))
    scene.camera.data.lens = 85.0
    world = bpy.data.worlds.new("Green")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (0.0, 1.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    # The cylinder's upper third, inside its outline (rows top to bottom).
    bpy.context.view_layer.update()
    top = project(bpy, scene, (0.0, -0.22, 0.9))
    mid = project(bpy, scene, (0.0, -0.22, 0.6))
    left = project(bpy, scene, (-0.15, -0.22, 0.75))
    right = project(bpy, scene, (0.15, -0.22, 0.75))
    rows = slice(top[0] + 1, mid[0])
    cols = slice(left[1] + 1, right[1])
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", 32, 12)[rows, cols]
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES", 256, 12)[rows, cols]
    got, want = ours.reshape(-1, 3).mean(axis=0), ref.reshape(-1, 3).mean(axis=0)
    print(f"cylinder's upper rows {rows} cols {cols}: ours {np.round(got, 4)} "
          f"Cycles {np.round(want, 4)}")
    assert ours.size and np.all(np.abs(got - want)[:2] <= 0.03), (got, want)


def test_nested_picks_convert_and_choose_independently(fresh_scene, bpy_addon):
    """review42: a pick inside an Add or another Mix failed to convert once the closure
    model was picked per hit ('node' blended as a number), and a nested pick read the
    outer pick's random number (Mix 0.5 of Mix 0.5 of blue and gold, and green: 50 / 0 /
    50 % instead of 25 / 25 / 50 %)."""
    from blender_helpers import convert_material
    from engine.geometry import MaterialTable, node_code
    from engine.textures import scalar_params
    from engine.closures import principled as pr
    bpy = bpy_addon
    rng = np.random.default_rng(11)
    n = 20000

    def rows_of(build, name):
        m = convert_material(_material(bpy, name, build))
        assert not any("could not be read" in w for w in m.warnings), m.warnings
        return scalar_params(MaterialTable.build([m]), None, np.zeros(n, np.int64),
                             rng.integers(0, 4, n), rng.random(n) * 0.5, rng.random(n) * 0.5)

    def in_add(nd, ln):
        return _add(nd, ln, _mix(nd, ln, 0.5, _gold_metal(nd),
                                 _glossy(nd, (0.9, 0.7, 0.3), 0.2)),
                    _diffuse(nd, (0.1, 0.4, 0.8)))
    rows = rows_of(in_add, "InAdd")
    codes = rows[:, pr.M_NODE]
    assert set(np.unique(codes)) == {node_code("principled"), node_code("glossy")}
    glossy = codes == node_code("glossy")
    assert abs(glossy.mean() - 0.25) < 0.02, glossy.mean()  # half of the Add's half

    def in_mix(nd, ln):
        return _mix(nd, ln, 0.5, _mix(nd, ln, 0.5, _blue_dielectric(nd), _gold_metal(nd)),
                    _diffuse(nd, (0.1, 0.8, 0.2)))
    rows = rows_of(in_mix, "InMix")
    gold = rows[:, pr.M_METALLIC] > 0.5
    blue = (~gold) & (rows[:, pr.M_SPEC] > 0.5)
    green = (~gold) & ~blue
    for part, want in ((gold, 0.25), (blue, 0.25), (green, 0.5)):
        assert abs(part.mean() - want) < 0.02, (gold.mean(), blue.mean(), green.mean())
    rows_of(lambda nd, ln: _mix(nd, ln, 0.5, _mix(nd, ln, 0.5, _glass_node(nd),
                                                  _refraction(nd)),
                                _diffuse(nd, (0.1, 0.4, 0.8))), "GlassRefrDiffuse")


def test_translucent_share_and_equal_roughness_glass_stay_right(fresh_scene, bpy_addon):
    """review42: a subsurface side beside a Translucent BSDF was picked with a fixed 0.5
    translucent share (the factor's share since); a Glass BSDF and a Principled
    dielectric of the same roughness but two colours were blended (the Glass BSDF's model
    tints its lobes by the one blended colour): picked."""
    from blender_helpers import convert_material
    from engine.shadernodes import ClosurePick
    bpy = bpy_addon

    def sss_translucent(fac):
        def build(nd, ln):
            s = nd.new("ShaderNodeSubsurfaceScattering")
            t = nd.new("ShaderNodeBsdfTranslucent")
            return _mix(nd, ln, fac, s.outputs[0], t.outputs[0])
        return build
    for fac in (0.2, 0.8):
        m = convert_material(_material(bpy, f"ST{fac}", sss_translucent(fac)))
        assert abs(m.translucent - fac) < 1e-6, (fac, m.translucent)
    m = convert_material(_material(bpy, "GP", lambda nd, ln: _mix(
        nd, ln, 0.5, _glass_node(nd, 0.6, (1.0, 1.0, 1.0)),
        _principled(nd, (0.1, 0.4, 0.8), 0.6))))
    roots = list((m.scalar_textures or {}).values())
    assert any(isinstance(x, ClosurePick) for r in roots for x in _nodes_of(r)), roots
