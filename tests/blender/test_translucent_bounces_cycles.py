"""Light Paths count a Translucent BSDF bounce as Cycles does: a transmission bounce.

Cycles' bsdf_translucent_sample labels its rays LABEL_TRANSMIT | LABEL_DIFFUSE, and
path_state_next counts a diffuse bounce only for a reflection (LABEL_REFLECT |
LABEL_DIFFUSE: Diffuse, Sheen); every transmission, the translucent one included, is a
transmission bounce (intern/cycles/kernel/integrator/path_state.h). The photons counted it
as a diffuse bounce (s33): at Transmission 0 they kept the light a lamp sends through a
Translucent panel after a bounce on a reflector (Cycles drops it: 1.63 against 1.15), and
at Diffuse 1 they dropped it (Cycles keeps it: 1.15 against 1.63).

Scene: a 100 W point lamp between a white reflector (above) and a Translucent panel
(below); the camera between the panel and a white floor looks down at the floor, whose
light comes through the panel: the lamp's own (a light sample at the panel, counted at
any Transmission) and the reflector's (a bounce at the panel that continues).

Cycles' image means (seed 0: the same numbers every run) are stored in
tests/references/translucent_bounces_cycles.json (this file run as a script writes
them); the slow test_stored_bounce_means_are_cycles_now renders them again live.
"""
import math
import os

import pytest

pytestmark = pytest.mark.blender
REF_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                        "references", "translucent_bounces_cycles.json")
TRANSLUCENT_LIMITS = {(d, t): dict(diffuse_bounces=d, transmission_bounces=t)
                      for d, t in ((4, 12), (4, 0), (1, 12))}
SHEEN_LIMITS = {(d, g): dict(diffuse_bounces=d, glossy_bounces=g)
                for d, g in ((4, 4), (4, 0), (1, 4))}
VISIBILITY = {"diffuse off": (False, True), "transmission off": (True, False)}


def _material(bpy, name, kind, rgb):
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    n = nt.nodes.new(kind)
    n.inputs["Color"].default_value = (*rgb, 1.0)
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    return m


def _scene(bpy, scene):
    white = _material(bpy, "White", "ShaderNodeBsdfDiffuse", (0.8, 0.8, 0.8))
    panel = _material(bpy, "Panel", "ShaderNodeBsdfTranslucent", (0.9, 0.9, 0.9))
    for z, size, mat in ((0.0, 4.0, panel), (1.0, 4.0, white), (-1.0, 6.0, white)):
        bpy.ops.mesh.primitive_plane_add(size=size, location=(0.0, 0.0, z))
        bpy.context.object.data.materials.append(mat)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.data.energy, lamp.data.shadow_soft_size = 100.0, 0.0
    lamp.location = (0.0, 0.0, 0.5)
    scene.collection.objects.link(lamp)
    from blender_helpers import black_world, looking_down_camera
    looking_down_camera(bpy, scene, -0.3, lens=20.0)
    black_world(bpy, scene)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100


def _engine_means(bpy, scene, tmp_path, spp, limits, engine):
    """{name: image mean} of `engine` for each Light Paths setting in limits
    ({name: {property: value}} on scene.cycles, which the add-on reads too)."""
    from blender_helpers import cycles_plain, read_rgba, render_exr
    got = {}
    for name, values in limits.items():
        c = cycles_plain(scene, spp, 12)
        for k, val in values.items():
            setattr(c, k, val)
        scene.render.engine = engine
        path = tmp_path / f"{engine}_{name}.exr"
        got[name] = float(read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean())
    return got


def _key(case, name):
    return f"{case} {'/'.join(map(str, name)) if isinstance(name, tuple) else name}"


def _means(bpy, scene, tmp_path, spp, limits, case):
    """{name: (ours, Cycles)} image means for each Light Paths setting in limits: ours
    rendered, Cycles' stored under _key(case, name)."""
    from blender_helpers import stored_cycles_means
    stored = stored_cycles_means(REF_PATH)
    ours = _engine_means(bpy, scene, tmp_path, spp, limits, "PHOTONMAP")
    got = {name: (o, stored[_key(case, name)]) for name, o in ours.items()}
    print({k: (round(o, 4), round(r, 4), round(o / r, 4) if r else None)
           for k, (o, r) in got.items()})
    return got


def test_translucent_bounce_is_a_transmission_bounce(fresh_scene, bpy_addon, tmp_path):
    from blender_helpers import default_photonmap
    bpy = bpy_addon
    scene = fresh_scene
    default_photonmap(scene).spp = 16
    _scene(bpy, scene)
    got = _means(bpy, scene, tmp_path, 256, TRANSLUCENT_LIMITS, "translucent")
    for (d, t), (ours, ref) in got.items():
        assert ref > 0.5 and math.isfinite(ours)
        assert abs(ours / ref - 1.0) < 0.03, ((d, t), ours, ref)
    # Transmission 0 drops the reflector's light through the panel, Diffuse 1 keeps it
    # (Cycles: 0.65 and 0.92 of the full light): the panel's bounce is no diffuse one.
    (full, full_ref), (t0, t0_ref), (d1, d1_ref) = got[4, 12], got[4, 0], got[1, 12]
    assert t0 / full < 0.75 and t0_ref / full_ref < 0.75
    assert d1 / full > 0.88 and d1_ref / full_ref > 0.88


def test_translucent_light_sample_follows_the_lamps_diffuse_visibility(fresh_scene, bpy_addon,
                                                                       tmp_path):
    """The lamp's light through the panel is Cycles' light sample at a diffuse closure
    (_surface_shader_exclude: CLOSURE_IS_BSDF_DIFFUSE spans DIFFUSE..TRANSLUCENT): the
    lamp's Diffuse visibility off leaves the floor black, its Transmission visibility off
    changes nothing (review33: the photons read 1.24 and 0.94 of those)."""
    from blender_helpers import default_photonmap
    bpy = bpy_addon
    scene = fresh_scene
    default_photonmap(scene).spp = 16
    _scene(bpy, scene)
    lamp = bpy.data.objects["Lamp"]
    got = {}
    for name, (diffuse, transmission) in VISIBILITY.items():
        lamp.visible_diffuse, lamp.visible_transmission = diffuse, transmission
        got.update(_means(bpy, scene, tmp_path, 256, {name: {}}, "lamp visibility"))
    assert got["diffuse off"][1] == 0.0 and got["diffuse off"][0] < 1e-3, got
    ours, ref = got["transmission off"]
    assert ref > 0.5 and abs(ours / ref - 1.0) < 0.03, got


def _sheen_room(bpy, scene):
    """A lamp between two black discs lights two white side walls only; their light
    reaches the floor directly and by a bounce on a Sheen-only ceiling (Principled: black
    base, Sheen Weight 1, Specular IOR Level 0)."""
    from blender_helpers import node_material
    white = _material(bpy, "White", "ShaderNodeBsdfDiffuse", (0.8, 0.8, 0.8))
    black = _material(bpy, "Black", "ShaderNodeBsdfDiffuse", (0.0, 0.0, 0.0))
    sheen, nt, out = node_material(bpy, "Sheen")
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    p.inputs["Specular IOR Level"].default_value = 0.0
    p.inputs["Sheen Weight"].default_value = 1.0
    p.inputs["Sheen Roughness"].default_value = 0.5
    p.inputs["Sheen Tint"].default_value = (1.0, 1.0, 1.0, 1.0)
    nt.links.new(p.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.data.materials.append(white)
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, 2.0))
    bpy.context.object.data.materials.append(sheen)
    for x in (-2.0, 2.0):
        bpy.ops.mesh.primitive_plane_add(size=4.0, location=(x, 0.0, 1.0),
                                         rotation=(0.0, math.pi / 2, 0.0))
        bpy.context.object.data.materials.append(white)
    for z in (0.9, 1.1):
        bpy.ops.mesh.primitive_circle_add(radius=0.6, location=(0.0, 0.0, z),
                                          fill_type="NGON", vertices=32)
        bpy.context.object.data.materials.append(black)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.data.energy, lamp.data.shadow_soft_size = 300.0, 0.0
    lamp.location = (0.0, 0.0, 1.0)
    scene.collection.objects.link(lamp)
    from blender_helpers import black_world, looking_down_camera
    looking_down_camera(bpy, scene, 0.6, lens=20.0)
    black_world(bpy, scene)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100


def test_sheen_bounce_is_a_diffuse_bounce(fresh_scene, bpy_addon, tmp_path):
    """Cycles' bsdf_sheen_sample labels LABEL_REFLECT | LABEL_DIFFUSE: a diffuse bounce.
    The camera side counted it so; the photons counted a glossy one, so Glossy 0 dropped
    the walls' light the Sheen ceiling sends down."""
    from blender_helpers import default_photonmap
    bpy = bpy_addon
    scene = fresh_scene
    default_photonmap(scene).spp = 16
    _sheen_room(bpy, scene)
    got = _means(bpy, scene, tmp_path, 512, SHEEN_LIMITS, "sheen")
    for (d, g), (ours, ref) in got.items():
        assert ref > 0.01 and math.isfinite(ours)
        assert abs(ours / ref - 1.0) < 0.04, ((d, g), ours, ref)
    # Glossy 0 keeps the Sheen bounce's light in both (Cycles 1.000 of Glossy 4; the
    # photons' glossy count read 0.988: the same photons, some dropped).
    full, g0 = got[4, 4], got[4, 0]
    assert abs(g0[0] / full[0] - g0[1] / full[1]) < 0.004, got


def _cycles_means(bpy, tmp_path):
    """Cycles' image means of the three tests, rendered now: {_key: mean}."""
    def fresh(build):
        bpy.ops.wm.read_homefile(use_empty=True)  # as the fresh_scene fixture
        scene = bpy.context.scene
        build(bpy, scene)
        return scene

    out = {}
    scene = fresh(_scene)
    for name, mean in _engine_means(bpy, scene, tmp_path, 256, TRANSLUCENT_LIMITS,
                                    "CYCLES").items():
        out[_key("translucent", name)] = mean
    scene = fresh(_scene)
    lamp = bpy.data.objects["Lamp"]
    for name, (diffuse, transmission) in VISIBILITY.items():
        lamp.visible_diffuse, lamp.visible_transmission = diffuse, transmission
        out[_key("lamp visibility", name)] = _engine_means(
            bpy, scene, tmp_path, 256, {name: {}}, "CYCLES")[name]
    scene = fresh(_sheen_room)
    for name, mean in _engine_means(bpy, scene, tmp_path, 512, SHEEN_LIMITS,
                                    "CYCLES").items():
        out[_key("sheen", name)] = mean
    return out


@pytest.mark.slow
def test_stored_bounce_means_are_cycles_now(bpy_addon, tmp_path):
    """The stored means are what this Blender's Cycles renders (8 renders at 256-512
    spp)."""
    from blender_helpers import assert_stored_means_are_now, stored_cycles_means
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_means(bpy_addon, tmp_path))


if __name__ == "__main__":  # write the stored means: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples={
        "translucent": 256, "lamp visibility": 256, "sheen": 512}, seed=0)
