"""Photon portals (engine/portal.py, portal34) against live Cycles: a 4 x 4 x 2 m closed
grey room (zero-thickness walls, as users model them) lit by a white world through one
1 x 1 m plane of Glass BSDF (IOR 1.5) in its roof; an orthographic camera inside looking
up at the ceiling round the pane (the pane's pixels left out), lit by the room's indirect
light only (the final gather reads the photon map). With portals the world's photons start on the pane; without (as on
main) visual importance aims them at the room and most meet the roof from outside.
Brightness within 3 % of Cycles (4096 spp; two seeds' mean), and less block noise between
two seeds than without portals. Measured (16 spp, 50k photons): ours / Cycles 0.9937
(off 0.9869), 8x8-block noise 0.0139 (off 0.0200), 15 s.

Cycles' mean of the ceiling (4096 spp, seed 0: the same number every run) is stored in
tests/references/portal_cycles.json (this file run as a script writes it); the slow
test_stored_ceiling_mean_is_cycles_now renders it again live.
"""
import math
import os

import numpy as np
import pytest
from blender_helpers import (ROOT, assert_stored_means_are_now, black_world,
                             glass_or_diffuse_material, light_portal, looking_down_camera,
                             renders_by_switch, roof_window_room, stored_cycles_means)

pytestmark = pytest.mark.blender
REF_PATH = os.path.join(ROOT, "tests", "references", "portal_cycles.json")


def _plane(bpy, size, loc, rot, scale, mat, name=None):
    bpy.ops.mesh.primitive_plane_add(size=size, location=loc, rotation=rot)
    ob = bpy.context.object
    ob.scale = scale
    ob.data.materials.append(mat)
    if name:
        ob.name = name
    return ob


def _scene(bpy, scene):
    roof_window_room(bpy, scene)
    _plane(bpy, 1, (0, 0, 2.0), (0, 0, 0), (1, 1, 1),
           glass_or_diffuse_material(bpy, "Glass", "glass", (1.0,) * 3), "Pane")
    # looking up at the ceiling (lit by the room's indirect light only) round the pane
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 3.6
    cam.location = (0.0, 0.0, 0.5)
    cam.rotation_euler = (math.pi, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam


def _ceiling():
    """(32, 32) bool: the ceiling only, the pane (the sky through it) in the middle
    10 x 10 pixels left out."""
    keep = np.ones((32, 32), bool)
    keep[11:21, 11:21] = False
    return keep


def _cycles_means(bpy, tmp_path):
    """Cycles' mean of the image with the pane's pixels zeroed (4096 spp), rendered now."""
    from blender_helpers import cycles_plain, read_rgba, render_exr
    bpy.ops.wm.read_homefile(use_empty=True)  # as the fresh_scene fixture
    scene = bpy.context.scene
    _scene(bpy, scene)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 4096, 12)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    return {"ceiling": float((ref * _ceiling()[..., None]).mean())}


@pytest.mark.slow
def test_stored_ceiling_mean_is_cycles_now(bpy_addon, tmp_path):
    """The stored mean is what this Blender's Cycles renders (4096 spp)."""
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_means(bpy_addon, tmp_path))


def test_room_lit_through_a_roof_window_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    from blender_helpers import cheap
    from engine import portal
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=16, photons=50_000, caustic_photons=20_000)
    films = renders_by_switch(bpy, scene, tmp_path, portal, "ENABLED")
    keep = _ceiling()
    for k in films:
        films[k] = films[k] * keep[..., None]

    def noise(on):
        """The two seeds' difference: per 8 x 8 block, std / mean."""
        d = (films[on, 0] - films[on, 1]).mean(axis=2) / math.sqrt(2.0)
        b = d.reshape(4, 8, 4, 8).mean(axis=(1, 3))
        return float(b.std() / films[on, 0].mean())
    want = stored_cycles_means(REF_PATH)["ceiling"]
    got = 0.5 * float(films[True, 0].mean() + films[True, 1].mean())
    off = 0.5 * float(films[False, 0].mean() + films[False, 1].mean())
    print(f"room under a roof window, its ceiling (Cycles {want:.5f}): ours / Cycles "
          f"{got / want:.4f} (portals off, as on main: {off / want:.4f}), two seeds' mean; "
          f"8x8-block noise (two seeds) on {noise(True):.4f} off {noise(False):.4f}")
    assert want > 0.005
    assert got == pytest.approx(want, rel=0.03)
    assert noise(True) < noise(False)


def test_a_light_portal_emits_nothing_as_in_cycles(fresh_scene, bpy_addon, tmp_path):
    """An Area light of 1000 W with Portal on over a grey floor under a black world:
    Cycles renders black (a portal only guides its background sampling), and so do we
    (before portal34 it lit the floor as an area light)."""
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    grey = glass_or_diffuse_material(bpy, "Grey", "diffuse", (0.6,) * 3)
    _plane(bpy, 4, (0, 0, 0), (0, 0, 0), (1, 1, 1), grey, "Floor")
    light_portal(bpy, scene, (0.0, 0.0, 1.0), energy=1000.0)
    looking_down_camera(bpy, scene, 2.0, ortho_scale=3.0)
    black_world(bpy, scene)
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=2, photons=2_000, caustic_photons=1_000)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3]
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 16, 12)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3]
    print(f"a 1000 W portal light: Cycles mean {float(ref.mean()):.6f}, ours "
          f"{float(ours.mean()):.6f}")
    assert float(ref.max()) == 0.0
    assert float(ours.max()) == 0.0


if __name__ == "__main__":  # write the stored mean: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=4096, seed=0)
