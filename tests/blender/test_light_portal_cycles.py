"""The world's shadow rays through a Cycles light portal (engine/lights/world.py,
lightportal34) against live Cycles: a 4 x 4 x 2 m closed grey room (zero-thickness
walls) with an open 1 x 1 m hole in its roof (no glass) and an Area light with Portal on
over it, under a white world; an orthographic camera inside looking down at the floor.
Brightness within 3 % of Cycles (1024 spp, with the portal; two seeds' mean), and the
pixel noise between two seeds well under that of the shadow rays without the portal
(engine.lights.SHADOW_PORTALS off: trial34's cosine sampling).

Cycles' image means (seed 0: the same numbers every run) are stored in
tests/references/light_portal_cycles.json (this file run as a script writes them); the
slow test_stored_light_portal_means_are_cycles_now renders them again live.
"""
import math
import os

import pytest
from blender_helpers import (ROOT, assert_stored_means_are_now, light_portal,
                             looking_down_camera, renders_by_switch, roof_window_room,
                             stored_cycles_means)

pytestmark = pytest.mark.blender
REF_PATH = os.path.join(ROOT, "tests", "references", "light_portal_cycles.json")
CYCLES_SPP = {"open roof window": 1024, "HDRI sun": 512, "round roof window": 1024}


def _scene(bpy, scene):
    roof_window_room(bpy, scene)
    light_portal(bpy, scene, (0.0, 0.0, 2.0))  # over the hole, its -Z into the room
    looking_down_camera(bpy, scene, 1.5, ortho_scale=3.6)


def _switch_against_cycles(bpy, scene, tmp_path, module, switch, key):
    """Ours with engine switch module.switch on and off (two seeds each,
    renders_by_switch) and Cycles (its stored mean of case `key`): (ours on / Cycles,
    ours off / Cycles, Cycles' mean, {on: the two seeds' pixel noise std / mean}),
    printed by the caller."""
    from blender_helpers import cheap
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=16, photons=50_000, caustic_photons=20_000)
    films = renders_by_switch(bpy, scene, tmp_path, module, switch)
    noise = {}
    for on in (True, False):
        d = (films[on, 0] - films[on, 1]).mean(axis=2) / math.sqrt(2.0)
        noise[on] = float(d.std() / films[on, 0].mean())
    want = stored_cycles_means(REF_PATH)[key]
    ours = {on: 0.5 * float(films[on, 0].mean() + films[on, 1].mean()) / want
            for on in (True, False)}
    return ours[True], ours[False], want, noise


def test_room_lit_through_an_open_roof_window_with_a_portal_matches_cycles(
        fresh_scene, bpy_addon, tmp_path):
    import engine.lights as el
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene)
    got, off, want, noise = _switch_against_cycles(bpy, scene, tmp_path, el,
                                                   "SHADOW_PORTALS", "open roof window")
    print(f"floor under an open roof window with a portal (Cycles {want:.5f}): ours / "
          f"Cycles {got:.4f} (shadow rays without the portal {off:.4f}); "
          f"pixel noise (two seeds) on {noise[True]:.4f} off {noise[False]:.4f}")
    assert want > 0.01
    assert got == pytest.approx(1.0, rel=0.03)
    assert noise[True] < 0.5 * noise[False]


def test_hdri_room_with_a_sun_through_the_portal_matches_cycles(fresh_scene, bpy_addon,
                                                                tmp_path):
    """The same room under an HDRI (example_blends/make_blends.sky_hdri, 128 x 64: a sky
    gradient and a one-texel sun of 3 W/m^2 80 degrees high, which shines through the hole
    onto the floor) with the portal sampled by the map seen through it (portalenv35,
    engine/lights/portalmap.py): brightness within 3 % of Cycles (512 spp, with the
    portal; two seeds' mean), and the two seeds' pixel noise under 0.7 x that of the
    portal sampled uniformly in solid angle (engine.lights.world.PORTAL_MAP_SAMPLING
    off, lightportal34)."""
    import engine.lights.world as wl
    bpy = bpy_addon
    scene = fresh_scene
    _hdri_scene(bpy, scene)
    got, solid, want, noise = _switch_against_cycles(bpy, scene, tmp_path, wl,
                                                     "PORTAL_MAP_SAMPLING", "HDRI sun")
    print(f"HDRI room with a sun through an open roof window and a portal (Cycles "
          f"{want:.5f}): ours / Cycles {got:.4f} (portal by solid angle {solid:.4f}); "
          f"pixel noise (two seeds) by the map {noise[True]:.4f}, by solid angle "
          f"{noise[False]:.4f}")
    assert want > 0.01
    assert got == pytest.approx(1.0, rel=0.03)
    assert noise[True] < 0.7 * noise[False]


def _hdri_scene(bpy, scene):
    """_scene under make_blends.sky_hdri's sky with a sun 80 degrees high."""
    _scene(bpy, scene)
    import make_blends  # (on the path: roof_window_room)
    make_blends.set_world_hdri(make_blends.sky_hdri(128, 64, sun_elevation=80.0,
                                                    sun_azimuth=0.0, sun_irradiance=3.0))


def _round_roof_room(bpy, scene, sides=64, radius=0.5):
    """roof_window_room with its roof's square hole closed and a round one (a
    `sides`-gon of `radius`, centred) cut instead: the ring of quads between the hole
    and the roof's square edge (sides a multiple of 8: the square's corners among the
    edge's points)."""
    grey = roof_window_room(bpy, scene)
    for ob in list(scene.objects):
        if ob.type == "MESH" and abs(ob.location.z - 2.0) < 1e-6:
            bpy.data.objects.remove(ob)
    a = [2 * math.pi * k / sides for k in range(sides)]
    inner = [(radius * math.cos(t), radius * math.sin(t), 2.0) for t in a]
    outer = []
    for t in a:
        c, s = math.cos(t), math.sin(t)
        m = 2.0 / max(abs(c), abs(s))
        outer.append((m * c, m * s, 2.0))
    faces = [(k, sides + k, sides + (k + 1) % sides, (k + 1) % sides) for k in range(sides)]
    me = bpy.data.meshes.new("Roof")
    me.from_pydata(inner + outer, [], faces)
    me.materials.append(grey)
    ob = bpy.data.objects.new("Roof", me)
    scene.collection.objects.link(ob)


def _round_scene(bpy, scene):
    """The round hole in the roof under a Disk light portal."""
    _round_roof_room(bpy, scene)
    portal = light_portal(bpy, scene, (0.0, 0.0, 2.0))
    portal.data.shape = "DISK"
    looking_down_camera(bpy, scene, 1.5, ortho_scale=3.6)


@pytest.mark.slow  # (49 s on the shared machine: Cycles 1024 spp and four renders of ours)
def test_round_roof_window_with_a_disk_portal_matches_cycles(fresh_scene, bpy_addon,
                                                             tmp_path):
    """A round hole (radius 0.5 m) in the roof with a Disk light portal over it (Cycles'
    is_round portal; portals36: sampled by its ellipse's area, photons from its
    inscribed polygon): brightness within 3 % of Cycles (1024 spp, with the portal; two
    seeds' mean) and the two seeds' pixel noise under half that of the shadow rays
    without the portal. Measured: 1.0012 (0.9742 without the portal's shadow rays),
    noise 0.033 against 0.636."""
    import engine.lights as el
    bpy = bpy_addon
    scene = fresh_scene
    _round_scene(bpy, scene)
    got, off, want, noise = _switch_against_cycles(bpy, scene, tmp_path, el,
                                                   "SHADOW_PORTALS", "round roof window")
    print(f"floor under an open round roof window with a Disk portal (Cycles {want:.5f}): "
          f"ours / Cycles {got:.4f} (shadow rays without the portal {off:.4f}); "
          f"pixel noise (two seeds) on {noise[True]:.4f} off {noise[False]:.4f}")
    assert want > 0.01
    assert got == pytest.approx(1.0, rel=0.03)
    assert noise[True] < 0.5 * noise[False]


def _cycles_means(bpy, tmp_path):
    """Cycles' image mean of each case (CYCLES_SPP), rendered now: {key: mean}."""
    from blender_helpers import cycles_plain, read_rgba, render_exr
    builds = {"open roof window": _scene, "HDRI sun": _hdri_scene,
              "round roof window": _round_scene}
    out = {}
    for key, build in builds.items():
        bpy.ops.wm.read_homefile(use_empty=True)  # as the fresh_scene fixture
        scene = bpy.context.scene
        build(bpy, scene)
        scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
        scene.render.engine = "CYCLES"
        cycles_plain(scene, CYCLES_SPP[key], 12)
        out[key] = float(read_rgba(bpy, render_exr(
            bpy, scene, tmp_path / "cycles.exr"))[..., :3].mean())
    return out


@pytest.mark.slow
def test_stored_light_portal_means_are_cycles_now(bpy_addon, tmp_path):
    """The stored means are what this Blender's Cycles renders (3 renders)."""
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_means(bpy_addon, tmp_path))


if __name__ == "__main__":  # write the stored means: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=CYCLES_SPP, seed=0)
