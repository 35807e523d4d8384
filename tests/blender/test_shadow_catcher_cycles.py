"""Shadow Catcher objects against Cycles 5.0 (engine/shadowcatcher.py, docs/accuracy.md
"catcher37"): a red cube on a grey catcher floor under a sun and a blue world.

Cycles' approximate shadow catcher (the Shadow Catcher pass off) with Film > Transparent
makes the floor invisible (alpha 0, colour 0) where it is lit as without the cube and
alpha = 1 - shadow where the cube shades it; without Transparent it darkens the world
behind the floor by the shadow; the cube renders as usual. With the pass on, Combined
leaves the floor out (alpha 0) and the pass holds the shadow (with / without, 1 where
lit). The bounds are measured (ours 16 spp against Cycles 256 spp) with room for noise.
"""
import math

import numpy as np
import pytest

from blender_helpers import cheap, cycles_plain, read_layers, render_exr, sun_light, world_color

WORLD = (0.2, 0.3, 0.5)


def _scene(bpy):
    """64 x 48: the floor (6 m, Diffuse 0.5, catcher) with a red cube on it, a sun from
    the side (a long shadow), the camera looking down at an angle."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    world_color(bpy, scene, WORLD)
    bpy.ops.mesh.primitive_plane_add(size=6.0)
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(_diffuse(bpy, "grey", (0.5, 0.5, 0.5)))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.5))
    cube = bpy.context.object
    cube.name = "Cube"
    cube.data.materials.append(_diffuse(bpy, "red", (0.8, 0.1, 0.1)))
    sun_light(bpy, scene, (math.radians(62), 0.0, math.radians(35)), 3.0)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, -5.0, 4.5)
    cam.rotation_euler = (math.radians(48), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    scene.render.resolution_percentage = 100
    floor.is_shadow_catcher = True
    return scene, floor, cube


def _diffuse(bpy, name, rgb):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*rgb, 1.0)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    return m


def _render(bpy, scene, path, engine, transparent, with_pass):
    scene.render.engine = engine
    scene.render.film_transparent = transparent
    scene.view_layers[0].cycles.use_pass_shadow_catcher = with_pass
    scene.render.filter_size = 0.01  # pixel means, no filter spreading edges
    if engine == "CYCLES":
        cycles_plain(scene, 256, 4)
    else:
        cheap(scene, spp=16, photons=50_000, caustic_photons=0)
    return read_layers(render_exr(bpy, scene, path, multilayer=True))


@pytest.fixture(scope="module")
def renders(bpy_addon, tmp_path_factory):
    bpy = bpy_addon
    tmp = tmp_path_factory.mktemp("catcher")
    scene, _, _ = _scene(bpy)
    out = {}
    for engine in ("CYCLES", "PHOTONMAP"):
        for transparent, with_pass in ((True, False), (False, False), (True, True)):
            out[engine, transparent, with_pass] = _render(
                bpy, scene, tmp / f"{engine}{int(transparent)}{int(with_pass)}.exr",
                engine, transparent, with_pass)
    return out


def _inside(m):
    """Pixels of mask m whose 4 neighbours are in it too."""
    out = m.copy()
    out[1:] &= m[:-1]
    out[:-1] &= m[1:]
    out[:, 1:] &= m[:, :-1]
    out[:, :-1] &= m[:, 1:]
    return out


def _regions(renders):
    """Masks from Cycles' renders: the cube (alpha 1 in both Combined), the floor's shadow
    core (only floor: Combined's alpha 0 with the pass on; pass < 0.5) and the lit floor
    (pass > 0.9), each shrunk by a pixel."""
    both = renders["CYCLES", True, True]
    a_matte = both["Combined"][..., 3]
    shade = both["Shadow Catcher"].mean(axis=2)
    cube = _inside((renders["CYCLES", True, False]["Combined"][..., 3] > 0.999)
                   & (a_matte > 0.999))
    floor = a_matte < 1e-6
    shadow = _inside(floor & (shade < 0.5))
    lit = _inside(floor & (shade > 0.9))
    assert cube.sum() >= 20 and shadow.sum() >= 10 and lit.sum() >= 300, (
        cube.sum(), shadow.sum(), lit.sum())
    return cube, shadow, lit


def _mean(img, mask):
    return img[mask].mean(axis=0)


def test_transparent_film_shows_only_the_shadow(renders):
    """Film Transparent: the lit floor is invisible (alpha 0, no colour), the shadow is
    alpha 1 - shadow over black, the cube renders as without a catcher. Measured: cube
    RGB within 0.3 % of Cycles, shadow alpha 0.607 (Cycles 0.611), lit floor alpha 0.008
    (0.003: ours is the ratio of two 16-spp estimates)."""
    cube, shadow, lit = _regions(renders)
    cyc = renders["CYCLES", True, False]["Combined"]
    ours = renders["PHOTONMAP", True, False]["Combined"]
    assert np.allclose(_mean(ours, cube)[:3], _mean(cyc, cube)[:3], rtol=0.03), (
        _mean(ours, cube), _mean(cyc, cube))
    assert np.all(ours[cube][:, 3] > 0.999)
    assert np.abs(ours[lit][:, :3]).max() < 1e-5          # colour 0: premultiplied matte
    assert _mean(ours, lit)[3] < 0.02, _mean(ours, lit)
    assert abs(_mean(ours, shadow)[3] - _mean(cyc, shadow)[3]) < 0.03, (
        _mean(ours, shadow), _mean(cyc, shadow))
    assert np.abs(ours[shadow][:, :3]).max() < 1e-5
    # Beyond the floor (the image's top rows see the world): nothing at all.
    assert np.abs(ours[:2]).max() < 1e-6 and np.abs(cyc[:2]).max() < 1e-6


def test_opaque_film_darkens_the_world_behind_the_floor(renders):
    """Without Film Transparent Cycles composites the shadow onto the world seen through
    the floor: the lit floor shows the world's colour, the shadow the world times
    (1 - shadow), alpha 1 everywhere. Measured: lit within 0.5 % of the world colour,
    shadow within 1 % of Cycles."""
    cube, shadow, lit = _regions(renders)
    cyc = renders["CYCLES", False, False]["Combined"]
    ours = renders["PHOTONMAP", False, False]["Combined"]
    assert np.allclose(ours[..., 3], 1.0)
    assert np.allclose(_mean(ours, lit)[:3], WORLD, rtol=0.02), _mean(ours, lit)
    assert np.allclose(_mean(cyc, lit)[:3], WORLD, rtol=0.02), _mean(cyc, lit)
    assert np.allclose(_mean(ours, shadow)[:3], _mean(cyc, shadow)[:3], rtol=0.05), (
        _mean(ours, shadow), _mean(cyc, shadow))
    assert np.all(_mean(ours, shadow)[:3] < 0.5 * np.array(WORLD))
    assert np.allclose(_mean(ours, cube)[:3], _mean(cyc, cube)[:3], rtol=0.03)


def test_shadow_catcher_pass(renders):
    """View Layer > Passes > Shadow Catcher on: Combined leaves the floor out (alpha 0
    and no colour, shadow included) and the pass holds with / without the cube: 1 on the
    cube and the lit floor, Cycles' value in the shadow (measured (0.308, 0.377, 0.495)
    against Cycles' (0.305, 0.373, 0.491)); the lit floor's red from the cube's bounce
    (1.023 in red) is Cycles' too."""
    cube, shadow, lit = _regions(renders)
    cyc = renders["CYCLES", True, True]
    ours = renders["PHOTONMAP", True, True]
    floor = shadow | lit
    assert np.abs(ours["Combined"][floor]).max() < 1e-5
    assert np.allclose(ours["Shadow Catcher"][cube], 1.0)
    assert abs(_mean(ours["Shadow Catcher"], lit).mean() - 1.0) < 0.02, (
        _mean(ours["Shadow Catcher"], lit))
    assert np.allclose(_mean(ours["Shadow Catcher"], shadow),
                       _mean(cyc["Shadow Catcher"], shadow), rtol=0.05), (
        _mean(ours["Shadow Catcher"], shadow), _mean(cyc["Shadow Catcher"], shadow))


class _Layout:
    """A stand-in for a panel's layout: records the properties drawn."""

    def __init__(self, log=None):
        self.log = [] if log is None else log
        self.use_property_split = self.use_property_decorate = False

    def column(self, **kw):
        return _Layout(self.log)

    def prop(self, owner, name, **kw):
        assert hasattr(owner, name), name  # a real property of this Blender
        self.log.append(name)


def test_panels_show_the_catcher_switches(bpy_addon):
    """With our engine the object's Visibility panel offers Shadow Catcher and Holdout
    and the ray visibility the add-on reads (Blender's own panel shows them for Cycles
    and EEVEE only); View Layer > Passes offers the Shadow Catcher pass."""
    from types import SimpleNamespace

    from addon.ui import PHOTONMAP_PT_object_visibility, PHOTONMAP_PT_passes
    bpy = bpy_addon
    scene, floor, _ = _scene(bpy)
    scene.render.engine = "PHOTONMAP"
    ctx = SimpleNamespace(engine="PHOTONMAP", object=floor, scene=scene,
                          view_layer=scene.view_layers[0])
    assert PHOTONMAP_PT_object_visibility.poll(ctx)
    layout = _Layout()
    PHOTONMAP_PT_object_visibility.draw(SimpleNamespace(layout=layout), ctx)
    assert {"is_shadow_catcher", "is_holdout", "visible_camera", "visible_shadow"} <= set(
        layout.log)
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    layout = _Layout()
    PHOTONMAP_PT_object_visibility.draw(SimpleNamespace(layout=layout),
                                        SimpleNamespace(object=sun))
    assert "is_shadow_catcher" not in layout.log and "visible_diffuse" in layout.log
    layout = _Layout()
    PHOTONMAP_PT_passes.draw(SimpleNamespace(layout=layout), ctx)
    assert "use_pass_shadow_catcher" in layout.log
    assert bpy.types.PHOTONMAP_PT_object_visibility.bl_parent_id == "OBJECT_PT_visibility"
