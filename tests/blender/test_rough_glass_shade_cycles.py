"""A lamp shade of rough glass against Cycles (issue 14, lamp30: the night living room's
walls read 1.05-1.06 of Cycles with a thin rough-glass Principled shade around the lamp).

A point lamp inside an open tall cylinder of Principled glass (Transmission 1, thin:
single-sided), a white Diffuse panel beside it, black world. The panel sees the lamp only
through the glass (the shade's openings light it nowhere): every bit of its light is a
caustic photon refracted out of the shade. Cycles' Multiscatter GGX scales the glass lobe
by its energy compensation at its view direction (microfacet_ggx_glass_albedo_scaling at
sd->I), here the panel's side of the shade; the photons took it on the lamp's side, where
the shade is seen from inside (eta < 1: a much larger factor), so the panel read +6 %
(roughness 0.5) and +59 % (roughness 1) of Cycles. photonkernels.glass_adjoint takes the
factor at the side the photon leaves to.

- roughness 0.5, Multiscatter GGX: the panel within 3 % of 0.954 x Cycles. Cycles 5.0
  evaluates refraction pairs no microfacet makes ("TODO: check if the refraction
  configuration is valid", bsdf_microfacet.h), which its light samples see: a rough sheet
  with a radius-0 lamp behind it reads 0.954 of Cycles at roughness 0.5, exactly what the
  two evaluation functions predict (bench/bench_rough_sheet_eval.py; docs/compatibility.md
  "roughlobes31": we keep the valid-pair evaluation). Before s31 the photons ignored the
  lamp's Soft Falloff (photons.soft_falloff_sources), +5 % here, which hid that gap: the
  panel read 1.008 (and 1.063 before glass_adjoint); a Translucent BSDF shade, which has
  no such gap, read 1.037 and reads 0.998 since (newuser31).
- roughness 1: the compensation's effect (Multiscatter GGX over plain GGX) within 3 % of
  Cycles' (was 1.80x Cycles'). Plain GGX alone reads 0.88 of Cycles at roughness 1 (0.96
  at 0.75): a deficit of the single-scattering photon transport through very rough glass,
  not this test's (docs/accuracy.md, lamp30).
- Since roughshade33 the panel's light through the shade is the next-event estimate of
  engine/shadelight.py (the camera side's f_t at the shade, the view towards the panel),
  not caustic photons: the same brightness (0.963 / 0.834 / 0.842 of Cycles; main 0.961 /
  0.831 / 0.840: the roughness-1 deficit is the lobe's evaluation's, not the photons'),
  smoother 8 x 8 blocks than main's (MAIN_SPREAD).
"""
import math

import numpy as np
import pytest

pytestmark = [pytest.mark.blender, pytest.mark.slow]

# Ours / Cycles where Cycles' light samples count its invalid refraction pairs: a rough
# sheet (roughness 0.5) with a radius-0 lamp behind it, predicted from the two evaluation
# functions and measured (bench/bench_rough_sheet_eval.py, docs/accuracy.md roughlobes31).
CYCLES_UNCHECKED_PAIRS = 0.954
# Main's (9cde680: the light through the glass as caustic photons) max / min of ours /
# Cycles over the panel's lit 8 x 8 blocks, 16 spp against Cycles 1024 spp.
MAIN_SPREAD = {(0.5, "MULTI_GGX"): 1.230, (1.0, "MULTI_GGX"): 1.181, (1.0, "GGX"): 1.194}


def _material(bpy, name, build):
    """A material whose Surface is build(nodes) (-> the output socket)."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    nt.links.new(build(nt.nodes), out.inputs["Surface"])
    return m


def _glass(roughness, distribution):
    def build(nodes):
        n = nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (0.95, 0.85, 0.7, 1.0)
        n.inputs["Roughness"].default_value = roughness
        n.inputs["Transmission Weight"].default_value = 1.0
        n.distribution = distribution
        return n.outputs[0]
    return build


def _diffuse(nodes):
    n = nodes.new("ShaderNodeBsdfDiffuse")
    n.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    return n.outputs[0]


def _glossy(nodes):
    n = nodes.new("ShaderNodeBsdfGlossy")
    n.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    n.inputs["Roughness"].default_value = 0.5
    return n.outputs[0]


def _shade_scene(bpy, roughness, distribution, shade=None, panel_build=_diffuse):
    """The panel (x = 1 m, facing the lamp), the 1 m tall shade of radius 0.22 m around a
    100 W point lamp of radius 0.05 m at the origin, the camera seeing the panel only.
    shade: the shade's surface, build(nodes) -> output socket (None: the glass of
    `roughness` and `distribution`)."""
    from mathutils import Vector
    bpy.ops.wm.read_homefile(use_empty=True)
    from addon import engine
    engine._previous_frame_warnings.clear()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 48, 36
    scene.render.resolution_percentage = 100
    world = bpy.data.worlds.new("World")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    next(n for n in world.node_tree.nodes if n.type == "BACKGROUND").inputs[
        "Strength"].default_value = 0.0
    bpy.ops.mesh.primitive_plane_add(size=1, location=(1.0, 0.0, 0.0),
                                     rotation=(0.0, -math.pi / 2, 0.0))
    panel = bpy.context.active_object
    panel.scale = (3.0, 3.0, 1.0)
    panel.data.materials.append(_material(bpy, "Panel", panel_build))
    shade_build = shade
    bpy.ops.mesh.primitive_cylinder_add(radius=0.22, depth=1.0, location=(0.0, 0.0, 0.0),
                                        vertices=32, end_fill_type="NOTHING")
    shade = bpy.context.active_object
    shade.data.materials.append(_material(bpy, "Shade", shade_build or _glass(roughness,
                                                                             distribution)))
    bpy.ops.object.shade_smooth()
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.data.energy, lamp.data.shadow_soft_size = 100.0, 0.05
    scene.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, -1.2, 0.0)
    cam.data.lens = 35.0
    cam.rotation_euler = (Vector((1.0, 0.0, 0.0)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def _image(bpy, scene, path, engine, spp=16):
    """The render's (H, W) grey image (ours at spp samples)."""
    from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
    c = cycles_plain(scene, 1024, 12)  # the add-on reads the same Light Paths
    c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 4, 4, 12
    scene.render.engine = engine
    if engine == "PHOTONMAP":
        default_photonmap(scene).spp = spp
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean(axis=2)


def _block_spread(ours, cycles):
    """max / min of ours / Cycles over the panel's lit 8 x 8 pixel blocks (brighter than
    a quarter of Cycles' brightest; bench/bench_shade_panel.py's measure)."""
    def blocks(img):
        h, w = (img.shape[0] // 8) * 8, (img.shape[1] // 8) * 8
        return img[:h, :w].reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3))
    bc = blocks(cycles)
    r = (blocks(ours) / np.maximum(bc, 1e-12))[bc > 0.25 * bc.max()]
    return float(r.max() / r.min())


def test_panel_lit_through_a_rough_glass_shade_matches_cycles(bpy_addon, tmp_path):
    bpy = bpy_addon
    got, img = {}, {}
    for roughness, dist in ((0.5, "MULTI_GGX"), (1.0, "MULTI_GGX"), (1.0, "GGX")):
        for engine in ("PHOTONMAP", "CYCLES"):
            scene = _shade_scene(bpy, roughness, dist)
            img[roughness, dist, engine] = _image(
                bpy, scene, tmp_path / f"{engine}_{roughness}_{dist}.exr", engine)
            got[roughness, dist, engine] = float(img[roughness, dist, engine].mean())
    ratio = {k[:2]: got[k[:2] + ("PHOTONMAP",)] / got[k[:2] + ("CYCLES",)] for k in got}
    effect = ratio[1.0, "MULTI_GGX"] / ratio[1.0, "GGX"]
    spread = {k: _block_spread(img[k + ("PHOTONMAP",)], img[k + ("CYCLES",)]) for k in ratio}
    print("ours / Cycles:", {k: round(v, 4) for k, v in ratio.items()},
          "compensation's effect, ours / Cycles':", round(effect, 4),
          "lit blocks' spread:", {k: round(v, 4) for k, v in spread.items()})
    assert all(v > 0.05 for v in got.values()), got  # the panel is lit in every case
    assert abs(ratio[0.5, "MULTI_GGX"] / CYCLES_UNCHECKED_PAIRS - 1.0) < 0.03, ratio
    assert abs(effect - 1.0) < 0.03, (effect, ratio)
    # The panel's light through the shade by shadow rays (engine/shadelight.py,
    # roughshade33), not caustic photons: its blocks smoother than main's (measured
    # 1.180 / 1.093 / 1.105; Cycles' own 1024 spp read 1.20 against 16384 spp,
    # bench/bench_shade_panel.py --shade glass: most of what is left is the reference's).
    for k, most in MAIN_SPREAD.items():
        assert spread[k] - 1.0 < 0.85 * (most - 1.0), (k, spread, MAIN_SPREAD)


# Main's path (the glossy panel's light through the shade from its reflected rays alone:
# this branch with shadelight.SERVE_GLOSSY off) max / min of ours / Cycles over the glossy
# panel's lit 8 x 8 blocks, 64 spp (its brightness: 0.927 of Cycles).
MAIN_GLOSSY_SPREAD = 1.498


def test_glossy_panel_lit_through_a_rough_glass_shade_matches_cycles(bpy_addon, tmp_path):
    """A Glossy BSDF panel (roughness 0.5) beside the roughness-0.5 shade: its highlight
    of the lamp through the glass takes the shade samples, MIS'd with its reflected rays
    (engine/shadelight.py, glossshade34). Ours at 64 spp against Cycles 1024 spp: the
    brightness within 4 % of the diffuse panel's 0.954 x Cycles (Cycles' light samples at
    the glass count its invalid refraction pairs, CYCLES_UNCHECKED_PAIRS), the lit blocks
    smoother than main's. Measured: 0.9689, spread 1.076 (main's path 0.927, 1.498)."""
    bpy = bpy_addon
    img = {}
    for engine in ("PHOTONMAP", "CYCLES"):
        scene = _shade_scene(bpy, 0.5, "MULTI_GGX", panel_build=_glossy)
        img[engine] = _image(bpy, scene, tmp_path / f"{engine}_glossy.exr", engine, spp=64)
    ratio = float(img["PHOTONMAP"].mean() / img["CYCLES"].mean())
    spread = _block_spread(img["PHOTONMAP"], img["CYCLES"])
    print("glossy panel: ours / Cycles", round(ratio, 4), "lit blocks' spread",
          round(spread, 4))
    assert img["CYCLES"].mean() > 0.01
    assert abs(ratio / CYCLES_UNCHECKED_PAIRS - 1.0) < 0.04, ratio
    assert spread - 1.0 < 0.5 * (MAIN_GLOSSY_SPREAD - 1.0), (spread, MAIN_GLOSSY_SPREAD)
