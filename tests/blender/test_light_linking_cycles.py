"""Light Linking (Object > Shading > Light Linking, Blender 4.0+) against live Cycles: three
grey cubes in a row on a grey floor, a key lamp whose Light Linking collection holds the
middle cube only (or excludes it), and a fill light that lights everything. Each region
(the cubes' tops, the floor round them) reads Cycles' brightness within 3 % with direct
light only, and within 5 % with the bounces (the photons of the key end at their first
hit on anything but the middle cube: the floor round it is lit by what its sides throw).
Shadow Linking: the key's shadows cast only by its blockers, region by region within 3 %.
Before linking38 the key lit every object and every object shadowed it (a warning said
so)."""
import numpy as np
import pytest

from blender_helpers import (black_world, cheap, cycles_plain, export_warnings,
                             glass_or_diffuse_material, looking_down_camera, read_rgba,
                             render_exr)

pytestmark = pytest.mark.blender

RES, VIEW = 48, 8.0
CUBES = {"CubeA": -2.5, "CubeB": 0.0, "CubeC": 2.5}


def _scene(bpy):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = RES
    scene.render.resolution_percentage = 100
    grey = glass_or_diffuse_material(bpy, "Grey", "diffuse", (0.6, 0.6, 0.6))
    bpy.ops.mesh.primitive_plane_add(size=12.0)
    floor = bpy.context.active_object
    floor.name = "Floor"
    floor.data.materials.append(grey)
    for name, x in CUBES.items():
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(x, 0.0, 0.5))
        cube = bpy.context.active_object
        cube.name = name
        cube.data.materials.append(grey)
    black_world(bpy, scene)
    looking_down_camera(bpy, scene, 10.0, ortho_scale=VIEW)
    key = bpy.data.objects.new("Key", bpy.data.lights.new("Key", "POINT"))
    key.data.energy, key.data.shadow_soft_size = 400.0, 0.0
    key.location = (1.0, -1.0, 2.5)  # lights the middle cube's top and two of its sides
    scene.collection.objects.link(key)
    fill = bpy.data.objects.new("Fill", bpy.data.lights.new("Fill", "AREA"))
    fill.data.energy, fill.data.size = 150.0, 3.0
    fill.location = (0.0, 0.0, 5.0)
    scene.collection.objects.link(fill)
    return scene, key


def _link(bpy, key, state):
    """The key's Light Linking collection: the middle cube with link state `state`."""
    coll = bpy.data.collections.new("KeyLinks")
    coll.objects.link(bpy.data.objects["CubeB"])
    coll.collection_objects[0].light_linking.link_state = state
    key.light_linking.receiver_collection = coll


def _regions():
    """Pixel masks: each cube's top, and the floor strips beside the cubes (above and
    below them in the image)."""
    c = (np.arange(RES) + 0.5) / RES * VIEW - VIEW / 2
    x = np.tile(c, (RES, 1))
    y = np.tile(-c[:, None], (1, RES))
    out = {f"{name} top": (np.abs(x - cx) < 0.35) & (np.abs(y) < 0.35)
           for name, cx in CUBES.items()}
    for name, cx in CUBES.items():
        out[f"floor by {name}"] = (np.abs(x - cx) < 1.0) & (np.abs(y) > 0.7) & (np.abs(y) < 1.6)
    return out


def _render(bpy, scene, tmp_path, engine, tag, bounces, spp=None):
    scene.render.engine = engine
    if engine == "CYCLES":
        cycles_plain(scene, spp or (512 if bounces else 256), bounces)
    else:
        cheap(scene, spp=spp or (64 if bounces else 32), photons=400_000, caustic_photons=0)
        scene.photonmap.photon_mapping = bool(bounces)
    img = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"{tag}_{engine}.exr"))
    return img[..., :3].mean(axis=2)


@pytest.mark.parametrize("state,bounces", [("INCLUDE", 0), ("EXCLUDE", 0),
                                           pytest.param("INCLUDE", 4,
                                                        marks=pytest.mark.slow)])
def test_key_linked_to_one_cube_lights_as_in_cycles(bpy_addon, tmp_path, state, bounces):
    bpy = bpy_addon
    scene, key = _scene(bpy)
    _link(bpy, key, state)
    assert not [w for w in export_warnings(bpy) if "Light Linking" in w]
    c = _render(bpy, scene, tmp_path, "CYCLES", state, bounces)
    o = _render(bpy, scene, tmp_path, "PHOTONMAP", state, bounces)
    regions = _regions()
    cm = {k: float(c[m].mean()) for k, m in regions.items()}
    om = {k: float(o[m].mean()) for k, m in regions.items()}
    print(state, bounces, {k: (round(cm[k], 4), round(om[k] / cm[k], 4)) for k in cm})
    # The link is real in Cycles: the middle cube's top is far brighter (INCLUDE) or
    # darker (EXCLUDE) than the others'.
    ratio = cm["CubeB top"] / cm["CubeC top"]  # (the cube nearest the key beside B)
    assert (ratio > 1.5) if state == "INCLUDE" else (ratio < 0.8), cm
    tol = 0.05 if bounces else 0.03
    for k in regions:
        assert om[k] == pytest.approx(cm[k], rel=tol), (k, om[k], cm[k])


def _shadow_regions():
    """The floor behind each cube as the key sees it (its shadow: the key is at (1, -1),
    shadows fall towards -x, +y) and the cubes' tops."""
    c = (np.arange(RES) + 0.5) / RES * VIEW - VIEW / 2
    x = np.tile(c, (RES, 1))
    y = np.tile(-c[:, None], (1, RES))
    out = {f"{name} top": (np.abs(x - cx) < 0.35) & (np.abs(y) < 0.35)
           for name, cx in CUBES.items()}
    for name, cx in CUBES.items():
        out[f"behind {name}"] = ((x > cx - 1.3) & (x < cx - 0.6) & (y > 0.6) & (y < 1.3))
    return out


@pytest.mark.parametrize("state,bounces", [("EXCLUDE", 0), ("INCLUDE", 0),
                                           pytest.param("EXCLUDE", 4,
                                                        marks=pytest.mark.slow)])
def test_shadow_linking_as_in_cycles(bpy_addon, tmp_path, state, bounces):
    """Shadow Linking: EXCLUDE the middle cube from the key's blockers (its key shadow
    goes), or INCLUDE it alone (it keeps its key shadow; the floor and the other cubes
    block nothing of the key); the fill's shadows stay. Direct light, within 3 % of
    Cycles; with 4 bounces too (the key's photons pass the cube: the floor behind it
    0.992, 0.987 while they stopped there)."""
    bpy = bpy_addon
    scene, key = _scene(bpy)
    blockers = bpy.data.collections.new("KeyBlockers")
    blockers.objects.link(bpy.data.objects["CubeB"])
    blockers.collection_objects[0].light_linking.link_state = state
    key.light_linking.blocker_collection = blockers
    assert not [w for w in export_warnings(bpy) if "Linking" in w]
    c = _render(bpy, scene, tmp_path, "CYCLES", "shadow" + state, bounces)
    o = _render(bpy, scene, tmp_path, "PHOTONMAP", "shadow" + state, bounces)
    regions = _shadow_regions()
    cm = {k: float(c[m].mean()) for k, m in regions.items()}
    om = {k: float(o[m].mean()) for k, m in regions.items()}
    print(state, bounces, {k: (round(cm[k], 4), round(om[k] / cm[k], 4)) for k in cm})
    # Cycles: the middle cube's key shadow is gone (EXCLUDE: behind it nearly as bright
    # as behind the right cube, in no key shadow) or kept (INCLUDE).
    ratio = cm["behind CubeB"] / cm["behind CubeC"]
    assert (ratio > 0.7) if state == "EXCLUDE" else (ratio < 0.5), cm
    for k in regions:
        assert om[k] == pytest.approx(cm[k], rel=0.03), (k, om[k], cm[k])


def test_an_emitting_objects_light_linking_as_in_cycles(bpy_addon, tmp_path):
    """An emitting object's Light Linking: a glowing bar beside the middle cube whose
    collection holds the middle cube only; the key lamp off. Direct light, each region
    within 3 % of Cycles (the floor round the bar takes none of its light, the cube
    does). Its Shadow Linking is not rendered: warned, naming object and collection."""
    bpy = bpy_addon
    scene, bar = glowing_bar_scene(bpy)
    assert not [w for w in export_warnings(bpy) if "Linking" in w]
    c = _render(bpy, scene, tmp_path, "CYCLES", "bar", 0)
    # Ours at 256 spp: the floor by cube B (the bar's own bright pixels in it) read 1.006-
    # 1.044 of Cycles at 4096 spp over seeds 0-7 at 32 spp (mean 1.021, sd 0.0125: a low-
    # spp bias besides the noise), 0.995-1.005 at 256 (mean 0.999, sd 0.0032; 1.3 CPU s);
    # Cycles' 256 spp within 0.4 % (`pytest -s tests/blender/seed_sweeps.py -k
    # linking_bar`; docs/accuracy.md, flaky50).
    o = _render(bpy, scene, tmp_path, "PHOTONMAP", "bar", 0, spp=256)
    regions = _regions()
    cm = {k: float(c[m].mean()) for k, m in regions.items()}
    om = {k: float(o[m].mean()) for k, m in regions.items()}
    print("bar", {k: (round(cm[k], 4), round(om[k] / cm[k], 4)) for k in cm})
    for k in regions:
        assert om[k] == pytest.approx(cm[k], rel=0.03), (k, om[k], cm[k])
    bar.light_linking.blocker_collection = bpy.data.collections.new("BarBlockers")
    warnings = [w for w in export_warnings(bpy) if "Linking" in w]
    assert warnings == ["object 'Bar': Shadow Linking (collection 'BarBlockers') is not "
                        "supported; every object casts its shadows"], warnings


def glowing_bar_scene(bpy):
    """(scene, bar): _scene with the key lamp off and a glowing bar (Emission 20) beside
    the middle cube, its Light Linking receivers a collection of that cube alone."""
    scene, key = _scene(bpy)
    key.data.energy = 0.0
    glow = glass_or_diffuse_material(bpy, "GlowMat", "diffuse", (0.0, 0.0, 0.0))
    nt = glow.node_tree
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 20.0
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(1.0, -1.2, 0.2),
                                    scale=(0.8, 0.2, 0.2))
    bar = bpy.context.active_object
    bar.name = "Bar"
    bar.data.materials.append(glow)
    coll = bpy.data.collections.new("BarLinks")
    coll.objects.link(bpy.data.objects["CubeB"])
    bar.light_linking.receiver_collection = coll
    return scene, bar


def test_collections_resolve_to_engine_receivers(bpy_addon):
    """Blender's resolution (depsgraph_light_linking.cc): objects of child collections
    take the child entry's link state; with any INCLUDE the light lights the included
    objects only, with only EXCLUDE entries every object but those."""
    bpy = bpy_addon
    from addon import export
    from addon.core import load_engine
    _, key = _scene(bpy)
    coll = bpy.data.collections.new("KeyLinks")
    child = bpy.data.collections.new("Sub")
    coll.children.link(child)
    child.objects.link(bpy.data.objects["CubeA"])
    coll.objects.link(bpy.data.objects["CubeB"])
    key.light_linking.receiver_collection = coll
    assert export.light_link_objects(coll) == (["CubeA", "CubeB"], [])

    def exported():
        out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                     width=8, height=8)
        light = next(li for li in out.lights if li.name == "Key")
        return light.receivers, light.non_receivers

    assert exported() == (["CubeA", "CubeB"], [])
    coll.collection_children[0].light_linking.link_state = "EXCLUDE"
    assert exported() == (["CubeB"], [])
    coll.collection_objects[0].light_linking.link_state = "EXCLUDE"
    assert exported() == (None, ["CubeA", "CubeB"])
    key.light_linking.receiver_collection = None
    key.light_linking.blocker_collection = coll
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=8)
    light = next(li for li in out.lights if li.name == "Key")
    assert (light.receivers, light.non_receivers) == (None, [])
    assert (light.blockers, light.non_blockers) == (None, ["CubeA", "CubeB"])


@pytest.mark.parametrize("linked", [False, True])
def test_world_fog_and_a_linked_lamp_as_in_cycles(bpy_addon, tmp_path, linked):
    """The world volume is in no object (Cycles' receiver set 0): a lamp whose Light
    Linking collection includes the floor lights the floor and none of the fog; unlinked
    it lights both. Image mean and the floor / fog regions within 3 % of Cycles (direct
    light, Volume bounces 0)."""
    bpy = bpy_addon
    scene, key = _scene(bpy)
    bpy.data.objects["Fill"].data.energy = 0.0
    world = scene.world
    nt = world.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_WORLD")
    fog = nt.nodes.new("ShaderNodeVolumePrincipled")
    fog.inputs["Density"].default_value = 0.15
    nt.links.new(fog.outputs[0], out.inputs["Volume"])
    if linked:
        _link(bpy, key, "INCLUDE")
        key.light_linking.receiver_collection.objects.link(bpy.data.objects["Floor"])
    scene.cycles.volume_bounces = 0
    # Cycles 1024 spp, ours 256: unlinked, the floor by cube B read 0.990-1.067 of Cycles
    # at 4096 spp over seeds 0-7 with ours at 32 spp (sd 0.025; seed 3 out of 3 %), at 256
    # 0.995-1.014 (sd 0.0067; 1.3 CPU s), and Cycles' 256 spp spread 0.6 % there itself
    # (`pytest -s tests/blender/seed_sweeps.py -k linking_fog`; docs/accuracy.md, flaky50).
    c = _render(bpy, scene, tmp_path, "CYCLES", f"fog{linked}", 0, spp=1024)
    o = _render(bpy, scene, tmp_path, "PHOTONMAP", f"fog{linked}", 0, spp=256)
    regions = _regions()
    cm = {k: float(c[m].mean()) for k, m in regions.items()}
    om = {k: float(o[m].mean()) for k, m in regions.items()}
    print("fog", linked, float(c.mean()), float(o.mean() / c.mean()),
          {k: (round(cm[k], 4), round(om[k] / max(cm[k], 1e-9), 4)) for k in cm})
    assert float(o.mean()) == pytest.approx(float(c.mean()), rel=0.03)
    for k in regions:
        assert om[k] == pytest.approx(cm[k], rel=0.03, abs=2e-3), (k, om[k], cm[k])
