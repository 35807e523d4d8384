"""Film > Transparent seen through transparent surfaces, against Cycles 5.0: camera rays
continued through an alpha card keep Cycles' transparent background
(PATH_RAY_TRANSPARENT_BACKGROUND): no world behind the card, alpha = the card's alpha
where nothing is behind it (film_write_transparent: average(throughput)); a holdout
behind the card holds out the throughput that reaches it, with or without a transparent
film. Before (s37): alpha 1 over nothing and the world drawn through the card.

An orthographic camera looks down on: an alpha-0.4 red card at 1 m over the image's left
half; a grey floor under the top half; a holdout square at 0.5 m under the card's lower
part; a blue world and a sun. 32 x 32, 8 px a metre; ours 8 spp against Cycles 64.
"""
import numpy as np
import pytest

from blender_helpers import (cheap, cycles_plain, looking_down_camera, read_layers,
                             render_exr, sun_light, world_color)

pytestmark = pytest.mark.blender

WORLD = (0.2, 0.3, 0.5)


def _plane(bpy, name, location, scale, material=None):
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=location)
    ob = bpy.context.object
    ob.name = name
    ob.scale = scale
    if material is not None:
        ob.data.materials.append(material)
    return ob


def _principled(bpy, name, rgb, alpha=1.0):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*rgb, 1.0)
    p.inputs["Roughness"].default_value = 1.0
    p.inputs["Alpha"].default_value = alpha
    return m


@pytest.fixture(scope="module")
def renders(bpy_addon, tmp_path_factory):
    bpy = bpy_addon
    tmp = tmp_path_factory.mktemp("film")
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    world_color(bpy, scene, WORLD)
    _plane(bpy, "Card", (-1.0, 0.0, 1.0), (2.0, 4.0, 1.0),
           _principled(bpy, "card", (0.8, 0.1, 0.1), alpha=0.4))
    _plane(bpy, "Floor", (0.0, 1.0, 0.0), (4.0, 2.0, 1.0),
           _principled(bpy, "grey", (0.5, 0.5, 0.5)))
    _plane(bpy, "Hole", (-1.0, -1.0, 0.5), (1.0, 1.0, 1.0),
           _principled(bpy, "grey2", (0.5, 0.5, 0.5))).is_holdout = True
    sun_light(bpy, scene, (0.3, 0.2, 0.0), 3.0)
    looking_down_camera(bpy, scene, 5.0, ortho_scale=4.0)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100
    scene.render.filter_size = 0.01
    out = {}
    for engine in ("CYCLES", "PHOTONMAP"):
        scene.render.engine = engine
        cycles_plain(scene, 64, 4)
        cheap(scene, spp=8, photons=20_000, caustic_photons=0)
        for transparent in (True, False):
            scene.render.film_transparent = transparent
            path = tmp / f"{engine}{int(transparent)}.exr"
            out[engine, transparent] = read_layers(render_exr(bpy, scene, path,
                                                              multilayer=True))["Combined"]
    return out


def _box(cols, rows):
    m = np.zeros((32, 32), bool)
    m[rows[0]:rows[1], cols[0]:cols[1]] = True
    return m


# Regions (rows from the top: y = 2 - row / 8, x = col / 8 - 2), a pixel inside each edge.
OVER_NOTHING = _box((1, 3), (18, 30))      # the card, nothing under it
OVER_FLOOR = _box((2, 14), (2, 14))        # the card over the floor
OVER_HOLE = _box((5, 11), (21, 27))        # the card over the holdout
FLOOR = _box((18, 30), (2, 14))            # the floor, no card
NOTHING = _box((18, 30), (18, 30))         # the world only


def test_alpha_card_over_a_transparent_film(renders):
    """Measured: alpha 0.398 over nothing and over the holdout (Cycles 0.398), RGB within
    0.1 % of Cycles' (no world through the card)."""
    cyc, ours = renders["CYCLES", True], renders["PHOTONMAP", True]
    for mask, alpha in ((OVER_NOTHING, 0.4), (OVER_HOLE, 0.4), (OVER_FLOOR, 1.0),
                        (FLOOR, 1.0), (NOTHING, 0.0)):
        assert abs(cyc[mask][:, 3].mean() - alpha) < 0.01, (alpha, cyc[mask][:, 3].mean())
        assert abs(ours[mask][:, 3].mean() - alpha) < 0.01, (alpha, ours[mask][:, 3].mean())
    for mask in (OVER_NOTHING, OVER_HOLE):
        assert np.allclose(ours[mask][:, :3].mean(0), cyc[mask][:, :3].mean(0), rtol=0.03), (
            ours[mask][:, :3].mean(0), cyc[mask][:, :3].mean(0))
    assert np.abs(ours[NOTHING]).max() < 1e-6


def test_alpha_card_over_an_opaque_film(renders):
    """Without a transparent film the world shows through the card (alpha 1) and the
    holdout behind it still cuts 0.6 of it (alpha 0.4, as Cycles)."""
    cyc, ours = renders["CYCLES", False], renders["PHOTONMAP", False]
    for mask, alpha in ((OVER_NOTHING, 1.0), (OVER_HOLE, 0.4), (NOTHING, 1.0)):
        assert abs(cyc[mask][:, 3].mean() - alpha) < 0.01, (alpha, cyc[mask][:, 3].mean())
        assert abs(ours[mask][:, 3].mean() - alpha) < 0.01, (alpha, ours[mask][:, 3].mean())
    for mask in (OVER_NOTHING, OVER_HOLE, NOTHING):
        assert np.allclose(ours[mask][:, :3].mean(0), cyc[mask][:, :3].mean(0), rtol=0.03), (
            ours[mask][:, :3].mean(0), cyc[mask][:, :3].mean(0))
