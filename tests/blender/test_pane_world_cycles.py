"""World light through a single-plane Glass BSDF pane against live Cycles (issue 14, the
room lit by its sky through a window; engine/panelight.py, paneworld32).

A grey floor in a shallow box (1 m walls) closed by one horizontal plane of Glass BSDF
(IOR 1.5, roughness 0) at its top, a world outside: a white Background of strength 1, or a
small generated sky map with a bright 17-degree patch 50 degrees off the zenith; an
orthographic camera inside looking down. All of the floor's direct light comes through
the glass. Ours takes it by shadow rays refracted through the pane; before, from the
caustic photon map alone (Direct pass 0). Brightness within 3 % of Cycles (2048 spp),
and ours' 8 x 8 blocks more even than with the world's pane light off (as on main).
Measured: white 1.0014 (off 0.9768), blocks max / min 1.024 (off 1.249, Cycles 1.014),
14 s; sky map 0.9968 (off 0.9786), 1.033 (off 1.230, Cycles 1.012), 28 s (slow).

Both renderers at Filter Glossy 0 (ours: the scene's Light Paths > Caustics > Filter
Glossy set to 0 before its render, so engine/glossysplit.py's split is off): the test is
of the pane's shadow rays, which refract the world's light unblurred. At Filter Glossy 1
Cycles blurs the pane after the floor's bounce and its light spreads over the floor and
the walls otherwise (white world 0.2246, sky map 0.1470 against 0.2532 / 0.1511 at 0);
ours keeps the pane's light unblurred and blurs the rest: 1.030 / 0.938 of Cycles at 1
(docs/compatibility.md, "splitpane47").
"""
import math

import numpy as np
import pytest
from blender_helpers import glass_or_diffuse_material

pytestmark = pytest.mark.blender


def _sky(H=32, W=64):
    """(H, W, 3) top row first: 0.5 above the horizon, 0.1 below, and a 3 x 3 texel
    patch of 8 (about 17 degrees wide) centred 50 degrees off the zenith."""
    img = np.full((H, W, 3), 0.5, np.float32)
    img[H // 2:] = 0.1
    i = int(50.0 / 180.0 * H)
    img[i - 1:i + 2, W // 2 - 1:W // 2 + 2] = (8.0, 7.5, 6.5)
    return img


def _scene(bpy, scene, world):
    import sys
    from blender_helpers import ROOT
    sys.path.insert(0, f"{ROOT}/example_blends")
    import make_blends
    bpy.ops.mesh.primitive_plane_add(size=6)
    floor = glass_or_diffuse_material(bpy, "Floor", "diffuse", (0.5,) * 3)
    bpy.context.object.data.materials.append(floor)
    for k in range(4):
        # 6 x 1 m walls from the floor to the pane, facing in
        a = k * math.pi / 2
        bpy.ops.mesh.primitive_plane_add(
            size=1, location=(3.0 * math.cos(a), 3.0 * math.sin(a), 0.5),
            rotation=(0.0, math.pi / 2, a))
        bpy.context.object.scale = (1.0, 6.0, 1.0)
        bpy.context.object.data.materials.append(floor)
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0.0, 0.0, 1.0))
    bpy.context.object.name = "Pane"
    bpy.context.object.data.materials.append(
        glass_or_diffuse_material(bpy, "Glass", "glass", (1.0,) * 3))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 2.0
    cam.location = (0.0, 0.0, 0.8)
    scene.collection.objects.link(cam)
    scene.camera = cam
    world_ = bpy.data.worlds.new("World")
    scene.world = world_
    if world == "white":
        make_blends.set_world((1.0, 1.0, 1.0), 1.0)
    else:
        make_blends.set_world_hdri(_sky(), 1.0)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100


def _blocks(img, b=8):
    h, w = img.shape[:2]
    return img[:h // b * b, :w // b * b].reshape(h // b, b, w // b, b).mean(axis=(1, 3))


@pytest.mark.parametrize("world", ["white", pytest.param("sky map", marks=pytest.mark.slow)])
def test_floor_under_a_pane_lit_by_the_world_matches_cycles(fresh_scene, bpy_addon,
                                                             tmp_path, world):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    from engine import panelight
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, world)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=16, photons=100_000, caustic_photons=100_000)
    scene.cycles.blur_glossy = 0.0  # (ours reads the scene's; cycles_plain sets Cycles')
    films = {}
    old = panelight.WORLD_ENABLED
    try:
        for on in (True, False):
            panelight.WORLD_ENABLED = on
            films[on] = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"ours{on}.exr"))
    finally:
        panelight.WORLD_ENABLED = old
    ours, before = films[True][..., :3], films[False][..., :3]
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 2048, 12)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    got, want = float(ours.mean()), float(ref.mean())

    def spread(img):
        b = _blocks(img.mean(axis=2))
        return float(b.max() / b.min())
    print(f"floor under a single-plane pane, {world} world, Filter Glossy 0: ours / "
          f"Cycles {got / want:.4f} "
          f"(world's pane light off, as on main: {float(before.mean()) / want:.4f}); 8x8 "
          f"block max / min: ours {spread(ours):.4f}, off {spread(before):.4f}, Cycles "
          f"{spread(ref):.4f}")
    assert want > 0.05
    assert got == pytest.approx(want, rel=0.03)
    assert spread(ours) < spread(before)
    assert spread(ours) < 1.06
