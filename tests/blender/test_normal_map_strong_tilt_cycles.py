"""A Normal Map fed by a Noise Texture's Color at Strength 1 (issue 14, the new-user trial
of s36): the colour's blue channel swings round 0.5, so many normals lean far from the
surface, some past it (below the geometric surface) or away from the viewer. Cycles then
gives a Principled BSDF's glossy lobes (the dielectric specular layer, metal) a normal
raised just enough that the view's mirror direction clears the surface
(maybe_ensure_valid_specular_reflection, valid_reflection_N), while the diffuse lobe keeps
the bent normal; each lobe takes light above its own normal. Ours took light for every lobe
above the bent normal only: the patches turned away from the sun read 0.86 of Cycles on a
rough dielectric and metal 0.90 (docs/accuracy.md, nmap37).

A 2 m plane under a sun 45 degrees from the zenith (angle 0: no penumbra), seen from above
(orthographic) and obliquely (perspective, 58 degrees from the zenith); direct light only,
every sample at the pixel's centre (render_pixel_centres): both engines' pixels are the
closure's exact value there, so they compare pixel by pixel."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W = H = 32


def _scene(bpy, scene, material, view):
    from blender_helpers import black_world, looking_down_camera, node_material, sun_light
    m, nt, out = node_material(bpy, f"Noise normals {material}")
    b = nt.nodes.new("ShaderNodeBsdfPrincipled")
    if material == "metal":
        b.inputs["Base Color"].default_value = (0.9, 0.7, 0.4, 1.0)
        b.inputs["Metallic"].default_value = 1.0
        b.inputs["Roughness"].default_value = 0.25
    else:
        b.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
        b.inputs["Roughness"].default_value = 0.9
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 8.0
    nmap = nt.nodes.new("ShaderNodeNormalMap")  # tangent space, Strength 1
    nt.links.new(noise.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], b.inputs["Normal"])
    nt.links.new(b.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    bpy.context.object.data.materials.append(m)
    sun = sun_light(bpy, scene, (0.0, math.radians(45.0), 0.0))  # from +x, down
    sun.data.angle = 0.0
    if view == "top":
        looking_down_camera(bpy, scene, 3.0, ortho_scale=1.6)
    else:
        cam = looking_down_camera(bpy, scene, 1.6, lens=50.0)
        cam.location = (0.0, -2.6, 1.6)
        cam.rotation_euler = (math.atan2(2.6, 1.6), 0.0, 0.0)  # looking at the origin
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100


@pytest.mark.parametrize("material,view", [("dielectric", "top"), ("dielectric", "oblique"),
                                           ("metal", "top"), ("metal", "oblique")])
def test_strongly_tilted_noise_normals_match_cycles(fresh_scene, bpy_addon, tmp_path,
                                                    material, view):
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene, material, view)
    from blender_helpers import render_pixel_centres
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP")[..., :3]
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES")[..., :3]
    lo, lc = ours.mean(axis=2), ref.mean(axis=2)
    lit = lc > 0.0
    # Cycles' darkest third of the lit pixels: the patches turned from the sun, where the
    # glossy lobes' raised normal still sees it (before: 0.86 of Cycles on the dielectric).
    dark = lit & (lc <= np.quantile(lc[lit], 1.0 / 3.0))
    err = np.abs(lo - lc)
    print(f"{material} {view}: mean ours / Cycles {lo.mean() / lc.mean():.4f}, darkest "
          f"third {lo[dark].mean() / lc[dark].mean():.4f}, max |d| {err.max():.5f}, "
          f"pixels off {(err > 0.002 + 0.02 * lc).sum()}")
    assert lo.mean() == pytest.approx(lc.mean(), rel=0.01)
    assert lo[dark].mean() == pytest.approx(lc[dark].mean(), rel=0.02)
    # Pixel by pixel, but for a few where the two engines' normals (float32 noise) part
    # on a steep highlight's flank.
    assert (err > 0.002 + 0.02 * lc).mean() <= 0.02
