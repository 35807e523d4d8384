"""Sky Texture against Cycles (issue 14: "World light ... Sky Texture if feasible").

A grey diffuse ground (40 m) and a grey ball under a Single Scattering sky (sun 30 degrees
up, behind the camera's right shoulder; a Multiple Scattering one, 5.0's default; and a
Hosek / Wilkie one, its sun the same direction as a vector),
rendered by our engine and by Cycles from the bpy wheel: the mean of the ground pixels (lit by the sun disc, as a sun light here, and
the sky, as the baked environment) and of the sky pixels the camera sees (the baked map
seen directly) agree with Cycles, with the sun disc on and off. Pixels are told apart
by their camera ray (sky: pointing above the horizon; ground: meeting the plane away
from the ball and its shadow).

Tolerances from the noise, measured over seeds 1-3 (48 x 36, Cycles 256 spp, ours 16 spp,
photon mapping on): Cycles' means move by 0.03 %; ours by 0.2 % (ground, sun on) and
0.9 % (ground lit by the sky alone, the map's importance sampling); the sky pixels are
the map itself (no noise), 0.999-1.000 of Cycles' table lookups. Measured ratios ours /
Cycles: sky 0.9999, ground 1.0006-1.0017 with the disc, 0.998-1.007 without (Multiple
Scattering, seed 0: sky 1.0000, ground 1.0004; Hosek / Wilkie, the same sun as a vector, no
disc: sky 1.0000, ground 0.9984). Bounds: sky 1 %, ground 2 % (twice our
seed spread, well under a visible difference).
"""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W, H = 48, 36
CAM, TARGET, FOV = np.array([0.0, -6.0, 1.0]), np.array([0.0, 0.0, 0.6]), 60.0
BALL, RADIUS = np.array([0.0, 0.0, 0.5]), 0.5


def _scene(bpy, sun_disc, sky_type="SINGLE_SCATTERING"):
    import make_blends as mb
    scene = mb.reset()
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    grey = mb.material("grey", "diffuse", (0.5, 0.5, 0.5))
    mb.plane("Ground", 40, 40, grey)
    mb.sphere("Ball", RADIUS, grey, tuple(BALL), segments=32, rings=16)
    mb.camera(tuple(CAM), tuple(TARGET), fov_deg=FOV)
    mb.set_world((0.0, 0.0, 0.0), 1.0)
    nt = scene.world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    sky = nt.nodes.new("ShaderNodeTexSky")
    if sky_type == "SINGLE_SCATTERING" and bpy.app.version < (5, 0, 0):
        sky_type = "NISHITA"
    sky.sky_type = sky_type
    sky.sun_elevation = math.radians(30.0)
    sky.sun_rotation = math.radians(150.0)  # towards (+x, -y): behind the camera
    sky.sun_disc = sun_disc
    if sky_type == "HOSEK_WILKIE":  # the same sun as a vector; turbidity 2.2, albedo 0.3
        e, r = math.radians(30.0), math.radians(150.0)
        sky.sun_direction = (math.cos(e) * math.sin(r), math.cos(e) * math.cos(r), math.sin(e))
    nt.links.new(sky.outputs[0], bg.inputs["Color"])
    return scene


def _rays():
    """(H, W, 3) unit camera ray directions through the pixel centres (rows top first)."""
    fwd = TARGET - CAM
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    t = math.tan(math.radians(FOV) / 2.0)
    x = ((np.arange(W) + 0.5) / W * 2.0 - 1.0) * t
    y = (1.0 - (np.arange(H) + 0.5) / H * 2.0) * t * H / W
    d = fwd + x[None, :, None] * right + y[:, None, None] * up
    return d / np.linalg.norm(d, axis=2, keepdims=True)


def _masks():
    d = _rays()
    sky = d[..., 2] > 0.03
    t = -CAM[2] / np.where(d[..., 2] < 0, d[..., 2], -1e-9)
    p = CAM + t[..., None] * d
    # the ground away from the ball, its shadow (cast towards +y, -x) and its bounce light
    ground = (d[..., 2] < -0.03) & (np.abs(p[..., 0]) < 15) & (np.abs(p[..., 1]) < 15)
    ground &= np.linalg.norm(p[..., :2] - BALL[:2], axis=-1) > 2.5
    return sky, ground


def _render(bpy, scene, path, engine):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    if engine == "CYCLES":
        cycles_plain(scene, 256, 4)
    else:
        cheap(scene, spp=16, photons=50_000, caustic_photons=0)
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].astype(np.float64)


@pytest.mark.parametrize("sky_type, sun_disc", [("SINGLE_SCATTERING", True),
                                                ("SINGLE_SCATTERING", False),
                                                ("MULTIPLE_SCATTERING", True),
                                                ("HOSEK_WILKIE", False)])
def test_sky_matches_cycles(fresh_scene, bpy_addon, tmp_path, sky_type, sun_disc):
    import os
    import sys
    from blender_helpers import ROOT, luminance
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    bpy = bpy_addon
    if sky_type == "MULTIPLE_SCATTERING" and bpy.app.version < (5, 0, 0):
        pytest.skip("Multiple Scattering is Blender 5.0's")
    scene = _scene(bpy, sun_disc, sky_type)
    ours = _render(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")
    ref = _render(bpy, scene, tmp_path / "cycles.exr", "CYCLES")
    sky, ground = _masks()
    assert sky.sum() > 200 and ground.sum() > 200
    assert np.all(np.isfinite(ours))
    for name, m in (("sky", sky), ("ground", ground)):
        got, want = luminance(ours[m]).mean(), luminance(ref[m]).mean()
        print(f"{sky_type} sun disc {sun_disc}: {name} ours {got:.4f} Cycles {want:.4f} "
              f"ratio {got / want:.4f}")
        assert abs(got / want - 1.0) <= (0.01 if name == "sky" else 0.02), (
            f"{sky_type} sun disc {sun_disc}: {name} ours {got:.4f} Cycles {want:.4f}")
    # The disc's light is there: Cycles' ground reads 10.67 with it, 1.30 without
    # (Hosek / Wilkie has no disc).
    assert (luminance(ref[ground]).mean() > 5.0) == sun_disc
