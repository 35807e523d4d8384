"""Particle hair (a Particle System of type Hair, Render As Path) renders as Cycles renders
it: its strands read by co_hair as Cycles' blender/curves.cpp reads them
(addon/particlehair.py), made tubes as a Curves object's (engine/hair.py).

Measured (s39, 96 x 72, Cycles 256 spp, ours 32 spp, default photons): 300 parent strands
0.5 m long (Diameter Root 1, Tip 0.2, Radius Scale 0.02, Strand Shape -0.5, material slot
2) on a small emitter plane over a grey floor under a sun: whole image 0.995 of Cycles,
8 x 6 blocks 0.952-1.004 (the tuft's 0.95-0.98, as a Curves tuft's with the photons'
indirect light: test_hair_cycles.py); with Interpolated children (200 parents x 10):
whole 1.002, blocks 0.978-1.054. The strands coloured by a Checker on the emitter's UV
map: 400 parents whole 0.995, blocks 0.91-1.012 (before the roots' UVs: 0.879, blocks
0.24); 100 parents x 10 children 0.997, blocks 0.953-1.013.

Cycles' 12 x 12 block means (256 spp, seed 0: the same numbers every run) are stored in
tests/references/particle_hair_cycles.json (this file run as a script writes them); the
slow test_stored_particle_hair_blocks_are_cycles_now renders them again live."""
import math
import os

import numpy as np
import pytest

from blender_helpers import (ROOT, assert_stored_means_are_now, block_means,
                             cycles_block_means, ours_luminance, principled_material,
                             stored_block_means, stored_cycles_means, sun_light,
                             world_color)

pytestmark = pytest.mark.blender
REF_PATH = os.path.join(ROOT, "tests", "references", "particle_hair_cycles.json")


def _scene(bpy, count=300, children="NONE"):
    """A grey floor, a small emitter plane (slot 1 'Skin', slot 2 'Hair') growing `count`
    strands of hair (Render > Material: slot 2), a sun, a dim world, 96 x 72."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world_color(bpy, sc, (0.05, 0.05, 0.05))
    bpy.ops.mesh.primitive_plane_add(size=4)
    bpy.context.object.name = "Floor"
    bpy.context.object.data.materials.append(principled_material(bpy, "Grey", (0.5, 0.5, 0.5), 0.5))
    bpy.ops.mesh.primitive_plane_add(size=1.2, location=(0, 0, 0.001))
    emitter = bpy.context.object
    emitter.name = "Emitter"
    emitter.data.materials.append(principled_material(bpy, "Skin", (0.2, 0.6, 0.2), 0.5))
    emitter.data.materials.append(principled_material(bpy, "Hair", (0.8, 0.3, 0.1), 0.6))
    mod = emitter.modifiers.new("Fur", "PARTICLE_SYSTEM")
    part = mod.particle_system.settings
    part.type = "HAIR"
    part.count = count
    part.hair_length = 0.5
    part.material = 2
    part.root_radius, part.tip_radius, part.radius_scale = 1.0, 0.2, 0.02
    part.shape = -0.5
    part.use_close_tip = False
    part.use_advanced_hair = True
    part.brownian_factor = 0.1  # the strands bend: keys off the straight line
    part.child_type = children
    part.rendered_child_count = part.child_percent = 10
    sun_light(bpy, sc, (math.radians(40), 0, math.radians(30)), energy=3.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -3.2, 1.6), (math.radians(65), 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 96, 72, 100
    return sc, emitter, mod


def _export(bpy, viewport=False):
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    if viewport:
        cache = export.ViewportExport(pm)
        camera = pm.Camera.look_at((0, -4, 2), (0, 0, 0))
        return export.export_viewport(cache, depsgraph, camera, 16, 12)[0]
    return export.export_scene(pm, depsgraph, width=16, height=12)[0]


def test_particle_strands_are_read_as_cycles_reads_them(bpy_addon):
    """The strands' keys (2^Steps + 1 per strand, rooted on the emitter, as long as Hair
    Length), radii (Hair Shape: Diameter Root / Tip x Radius Scale / 2 blended by Strand
    Shape along the key polyline; Close Tip: 0 at the last key), the material slot, and
    the children in place of the parents, in the emitter's object space."""
    bpy = bpy_addon
    sc, emitter, mod = _scene(bpy, count=40)
    emitter.location = (0.3, 0.0, 0.5)
    emitter.rotation_euler = (0.0, 0.0, 0.7)
    part = mod.particle_system.settings
    part.display_step = 3
    part.brownian_factor = 0.0  # straight strands: their length is Hair Length
    from addon.particlehair import particle_strands, shape_radius
    ob = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get())
    strands = particle_strands(ob, background=False)
    assert strands.systems == ["Fur"]
    offsets = strands.offsets
    assert len(offsets) == 41 and np.all(np.diff(offsets) == 2 ** 3 + 1)
    assert np.all(strands.slot == 1)
    roots, tips = strands.points[offsets[:-1]], strands.points[offsets[1:] - 1]
    # object space: roots on the emitter plane (z = 0 there), inside its 1.2 m square
    assert np.abs(roots[:, 2]).max() < 1e-5 and np.abs(roots[:, :2]).max() <= 0.6 + 1e-5
    pts = strands.points.reshape(40, 9, 3)
    length = np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(axis=1)
    np.testing.assert_allclose(length, 0.5, rtol=1e-4)
    assert np.all(tips[:, 2] > 0.3)
    r = strands.radius.reshape(40, 9)
    assert np.allclose(r[:, 0], 0.01) and np.allclose(r[:, -1], 0.002)
    run = np.concatenate([np.zeros((40, 1)), np.cumsum(
        np.linalg.norm(np.diff(pts, axis=1), axis=2), axis=1)], axis=1)
    np.testing.assert_allclose(r, shape_radius(-0.5, 0.01, 0.002, run / run[:, -1:]),
                               rtol=1e-6)
    assert shape_radius(0.5, 1.0, 0.0, np.array([0.5]))[0] == pytest.approx(0.25)
    part.use_close_tip = True
    ob = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert np.all(particle_strands(ob, False).radius.reshape(40, 9)[:, -1] == 0.0)
    # Children (viewport: Display Amount of them) replace the parents, as in Cycles.
    part.child_type = "INTERPOLATED"
    part.child_percent = 3
    ob = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert len(particle_strands(ob, False).offsets) - 1 == 40 * 3
    mod.show_viewport = False
    ob = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert particle_strands(ob, False) is None


def test_particle_hair_exports_with_its_emitter(bpy_addon):
    """Both export paths give '<emitter>/particle hair' with the emitter's material slots
    (the strands in Render > Material's), in world space, no warning; a hidden emitter
    (Show Instancer off) keeps its hair; an Object-type particle system adds nothing."""
    bpy = bpy_addon
    sc, emitter, mod = _scene(bpy, count=30)
    emitter.location.x = 1.0
    for view in (False, True):
        out = _export(bpy, view)
        hair = [m for m in out.meshes if m.name == "Emitter/particle hair"]
        assert len(hair) == 1, [m.name for m in out.meshes]
        assert hair[0].materials == ["Skin", "Hair"]
        assert np.all(np.asarray(hair[0].material_ids) == 1)
        v = np.asarray(hair[0].vertices)
        assert abs(v[:, 0].mean() - 1.0) < 0.15 and v[:, 2].max() > 0.3
        assert "Emitter" in [m.name for m in out.meshes]
        assert not [w for w in out.all_warnings() if "particle" in w or "hair" in w], \
            out.all_warnings()
    from addon import export
    from addon.core import load_engine
    ob = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get())
    with pytest.raises(export.ExportCancelled):  # Esc while the keys are read
        export.extract_particle_hair(load_engine(), ob, False, should_cancel=lambda: True)
    emitter.show_instancer_for_viewport = False
    names = [m.name for m in _export(bpy).meshes]
    assert "Emitter/particle hair" in names and "Emitter" not in names
    emitter.show_instancer_for_viewport = True
    mod.particle_system.settings.render_type = "OBJECT"  # instances, not strands
    assert "Emitter/particle hair" not in [m.name for m in _export(bpy).meshes]


def _checker_scene(bpy, children):
    """_scene's tuft (400 parents, or 100 with 10 children each) coloured by a Checker
    Texture on the emitter's UV map."""
    sc, _emitter, _mod = _scene(bpy, count=400 if children == "NONE" else 100,
                                children=children)
    nt = bpy.data.materials["Hair"].node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 3.0
    checker.inputs["Color1"].default_value = (0.9, 0.9, 0.1, 1.0)
    checker.inputs["Color2"].default_value = (0.05, 0.1, 0.8, 1.0)
    uv_map = nt.nodes.new("ShaderNodeUVMap")
    nt.links.new(uv_map.outputs["UV"], checker.inputs["Vector"])
    nt.links.new(checker.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return sc


@pytest.mark.parametrize("children", ["NONE", pytest.param("INTERPOLATED",
                                                           marks=pytest.mark.slow)])
def test_particle_hair_matches_cycles(bpy_addon, tmp_path, children):
    """The tuft against Cycles, its strands coloured by a Checker Texture on the emitter's
    UV map (each strand takes the map at its root, as Cycles' curve_uv)."""
    ours = ours_luminance(bpy_addon, _checker_scene(bpy_addon, children), tmp_path)
    ref = _stored_blocks(f"checker {children}")
    from addon import engine
    assert not [w for w in engine.last_render["warnings"] if "hair" in w.lower()]
    assert np.isfinite(ours).all()
    whole = ours.mean() / ref.mean()  # 96 x 72: the blocks' mean is the image's
    ratio = block_means(ours) / ref
    assert 0.985 < whole < 1.015, whole
    assert 0.88 < ratio.min() and ratio.max() < 1.07, np.round(ratio, 3)
    # The hair is there: the tuft's blocks (pixels [24:48, 24:72]) differ from the bare
    # floor's (pixels [60:, :12]).
    tuft, floor = ref[2:4, 2:6].mean(), ref[5, 0]
    assert tuft < 0.8 * floor or tuft > 1.25 * floor, (tuft, floor)


def _generated_ramp_scene(bpy):
    """_scene's tuft (200 strands) coloured by a Color Ramp of Generated's x."""
    sc, emitter, mod = _scene(bpy, count=200)
    nt = bpy.data.materials["Hair"].node_tree
    coord = nt.nodes.new("ShaderNodeTexCoord")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.9, 0.8, 0.1, 1.0)
    ramp.color_ramp.elements[1].color = (0.05, 0.1, 0.9, 1.0)
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["X"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return sc, emitter


def test_generated_coordinates_are_the_roots_in_the_emitters_texture_space(bpy_addon):
    """Each strand's Generated coordinate is its root key in the emitter mesh's texture
    space, the same along the whole strand (Cycles' blender/curves.cpp: co * size - loc
    of the first key; before: the tubes' own bounds)."""
    bpy = bpy_addon
    sc, emitter = _generated_ramp_scene(bpy)
    from addon import export
    from addon.core import load_engine
    from addon.particlehair import particle_strands
    ob = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get())
    geo = export.extract_particle_hair(load_engine(), ob, background=True)
    gen = export.texture_coordinates(geo, False)["generated"]
    strands = particle_strands(ob, background=True)
    roots = strands.points[strands.offsets[:-1]]
    # The emitter is a 1.2 m plane: its texture space spans x, y in [-0.6, 0.6].
    want = (roots[:, :2] + 0.6) / 1.2
    first = gen[:, 0, :2]  # every corner of a strand's tubes carries its root's value
    assert np.ptp(gen[:, :, 0], axis=1).max() < 1e-12
    np.testing.assert_allclose(np.unique(first[:, 0]), np.unique(want[:, 0]), atol=1e-6)
    assert 0.0 <= first.min() and first.max() <= 1.0


@pytest.mark.slow
def test_generated_coordinates_colour_the_tuft_as_cycles(bpy_addon, tmp_path):
    """A Color Ramp of Generated's x colours the tuft as in Cycles (s40: whole 1.00x,
    blocks within 0.88-1.08)."""
    ours = ours_luminance(bpy_addon, _generated_ramp_scene(bpy_addon)[0], tmp_path)
    ref = _stored_blocks("generated ramp")
    whole = ours.mean() / ref.mean()
    ratio = block_means(ours) / ref
    assert 0.985 < whole < 1.015, whole
    assert 0.88 < ratio.min() and ratio.max() < 1.08, np.round(ratio, 3)


def _cycles_blocks(bpy, tmp_path):
    """Cycles' block means of each scene, rendered now: {key: [48 means]}."""
    return cycles_block_means(
        bpy, {"checker NONE": lambda: _checker_scene(bpy, "NONE"),
              "checker INTERPOLATED": lambda: _checker_scene(bpy, "INTERPOLATED"),
              "generated ramp": lambda: _generated_ramp_scene(bpy)[0]}, tmp_path)


def _stored_blocks(key):
    return stored_block_means(REF_PATH, key)


@pytest.mark.slow
def test_stored_particle_hair_blocks_are_cycles_now(bpy_addon, tmp_path):
    """The stored block means are what this Blender's Cycles renders (3 renders at
    256 spp)."""
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_blocks(bpy_addon, tmp_path))


if __name__ == "__main__":  # write the stored block means: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_blocks, cycles_samples=256, seed=0)
