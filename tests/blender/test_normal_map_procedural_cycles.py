"""Normal Map node fed by procedural colours, against Cycles (issue 14): a Checker Texture
whose two colours lean the tangent-space normal 35 degrees one way or the other, a value
(a Wave texture's Fac through Map Range: a grey, as Cycles converts a value into the
Color socket) and a constant RGB in world space. Before, anything but an Image Texture on
the Normal Map's Color was warned and the surface rendered flat. (A grey g tilts every
normal to (T + B + N) / sqrt 3 whatever g: the value and constant cases are checked
against the analytic radiance, Cycles' bump shadowing term included.)

A Diffuse floor (a grid of 4 x 4 quads, the render UV map's u along +x) under a sun 70
degrees from the zenith coming from +x, so normals leaning along x read bright (towards
the sun) or dark (away); pixel centres only (render_pixel_centres), 32 x 32 px over 2 m,
the camera moved a third of a pixel so no centre sits on a checker edge or a shared
triangle edge."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W = H = 32
LEAN = math.radians(35)


def _scene(bpy, scene, kind):
    from blender_helpers import black_world, looking_down_camera, node_material, sun_light
    m, nt, out = node_material(bpy, f"Procedural {kind}")
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    if kind == "checker":
        chk = nt.nodes.new("ShaderNodeTexChecker")
        chk.inputs["Scale"].default_value = 4.0  # 0.5 m squares on the 2 m grid
        for name, sign in (("Color1", 1.0), ("Color2", -1.0)):
            chk.inputs[name].default_value = (0.5 + 0.5 * sign * math.sin(LEAN), 0.5,
                                              0.5 + 0.5 * math.cos(LEAN), 1.0)
        nt.links.new(chk.outputs["Color"], nmap.inputs["Color"])
    elif kind == "value":
        wave = nt.nodes.new("ShaderNodeTexWave")
        wave.wave_type, wave.bands_direction = "BANDS", "X"
        wave.inputs["Scale"].default_value = 2.0
        rng = nt.nodes.new("ShaderNodeMapRange")
        rng.inputs["To Min"].default_value = 0.55
        rng.inputs["To Max"].default_value = 0.95
        nt.links.new(wave.outputs["Fac"], rng.inputs["Value"])
        nt.links.new(rng.outputs["Result"], nmap.inputs["Color"])
    else:  # a constant world-space normal leaning 35 degrees towards the sun
        nmap.space = "WORLD"
        rgb = nt.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (0.5 + 0.5 * math.sin(LEAN), 0.5,
                                        0.5 + 0.5 * math.cos(LEAN), 1.0)
        nt.links.new(rgb.outputs[0], nmap.inputs["Color"])
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(nmap.outputs["Normal"], d.inputs["Normal"])
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2.0)
    bpy.context.object.data.materials.append(m)
    sun_light(bpy, scene, (0.0, math.radians(70.0), 0.0))  # light travels to -x, down
    cam = looking_down_camera(bpy, scene, 3.0, ortho_scale=2.0)
    cam.location.x += 0.02
    cam.location.y += 0.02
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100


def _bump_shadowing(cos_d, cos_i):
    """Cycles' bump shadowing term on a diffuse closure: GGX G1 of the smooth normal with
    alpha^2 = tan^2(theta_d) / 8, theta_d the tilt, theta_i the light's angle to the
    smooth normal (Conty Estevez et al. 2019)."""
    alpha2 = min((1.0 / cos_d ** 2 - 1.0) / 8.0, 1.0)
    lam = 0.5 * (math.sqrt(1.0 + alpha2 * (1.0 / cos_i ** 2 - 1.0)) - 1.0)
    return 1.0 / (1.0 + lam)


@pytest.mark.parametrize("kind", ["checker", "value", "world_constant"])
def test_procedural_normal_map_matches_cycles(fresh_scene, bpy_addon, tmp_path, kind):
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, kind)
    from blender_helpers import export_warnings, render_pixel_centres
    warnings = export_warnings(bpy)
    assert not [w for w in warnings if "Normal Map" in w], warnings
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3]
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3]
    err = np.abs(ours - ref)
    print(f"{kind}: Cycles {ref.min():.4f} .. {ref.max():.4f}, "
          f"ours {ours.min():.4f} .. {ours.max():.4f}, max |ours - Cycles| {err.max():.5f}")
    sun = np.array([math.sin(math.radians(70.0)), 0.0, math.cos(math.radians(70.0))])
    if kind in ("world_constant", "value"):
        # Every normal tilted alike: world_constant 35 degrees towards the sun; value: a
        # grey g maps to (2g - 1)(1, 1, 1), whatever g the normal (T + B + N) / sqrt 3.
        n = (np.array([math.sin(LEAN), 0.0, math.cos(LEAN)]) if kind == "world_constant"
             else np.ones(3) / math.sqrt(3.0))
        want = 0.8 / math.pi * 3.0 * float(n @ sun) * _bump_shadowing(n[2], sun[2])
        assert np.median(ref) == pytest.approx(want, rel=0.005)
        assert np.median(ours) == pytest.approx(want, rel=0.005)
    else:
        assert np.ptp(ref[..., 0]) > 0.2  # the map shows: bright and dark across x
    # Every pixel, but where Cycles loses one sample of 16 (black): at pixel centres on
    # the quads' diagonals, where its camera rays meet the edge two triangles share (all
    # 12 such centres of a lit floor read 15/16 of ours there, to 0.1 %).
    off = (err > 0.005 + 0.01 * ref).any(axis=2)
    one_lost = np.abs(ref[..., 0] / np.maximum(ours[..., 0], 1e-9) - 15.0 / 16.0) < 0.01
    assert np.all(~off | one_lost)
    assert off.sum() <= 16
