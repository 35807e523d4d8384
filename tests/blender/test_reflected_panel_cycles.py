"""A panel lit only by a rough floor's reflection of a shielded lamp, against Cycles
(issue 14, roughlobes31: every closure within 2 % of Cycles).

A white Diffuse panel (x = 1.5 m, facing the room), a 4 m Principled floor (base 0.9,
Metallic 1 or 0), a 100 W point lamp 0.3 m above the floor under a black 0.8 m shield:
the panel sees the lamp only by way of the floor (its metal or specular lobe, and for the
dielectric floor its diffuse base), black world. Cycles scales the floor's lobes by
Multiscatter GGX's energy compensation at its view direction, here the panel's side; the
photons took it at the lamp's side, where the light arrives: the metal floor's
compensation (Multiscatter over plain GGX, ours against Cycles') read +2.5 to +2.8 % at
roughness 1 (three seeds), and now -0.2 to 0.0 % (photonkernels.lobe_adjoint takes it
at the side the photon leaves to); the same floor under a rough coat (Coat Weight 1, Coat
Roughness 1) read 1.024 of Cycles, now 0.997 (three seeds). Ours with 2M global and caustic photons and 64 spp,
where the image mean's spread over seeds is about 1 % (at the defaults, 16 spp and
400k / 200k photons, 3-6 %: the dielectric floor's 0.965 of s30's bench at roughness 1
plain GGX was one such draw, 1.012 over three seeds here).
bench/bench_reflected_panel.py prints the same table.

Cycles' image means (1024 spp, seed 0: the same numbers every run) are stored in
tests/references/reflected_panel.json (this file run as a script writes them); the slow
test_stored_cycles_means_are_cycles_now renders them again live.
"""
import json
import math
import os

import pytest

pytestmark = pytest.mark.blender

REF_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                        "references", "reflected_panel.json")

CASES = ((0.5, "MULTI_GGX"), (1.0, "MULTI_GGX"), (1.0, "GGX"))


def _material(bpy, name, build):
    """A material whose Surface is build(nodes) (-> the output socket)."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    nt.links.new(build(nt.nodes), out.inputs["Surface"])
    return m


def scene_for(bpy, roughness, distribution, kind):
    """The scene: floor `kind` "metal" (Principled Metallic 1), "coated metal" (the same
    under Coat Weight 1 of Coat Roughness `roughness`) or "dielectric" (Principled,
    Metallic 0) of base colour 0.9 at `roughness` and `distribution`
    ("MULTI_GGX" or "GGX"); 48 x 36, the camera seeing the panel only."""
    from mathutils import Vector
    bpy.ops.wm.read_homefile(use_empty=True)
    from addon import engine
    engine._previous_frame_warnings.clear()
    sc = bpy.context.scene
    sc.render.engine = "PHOTONMAP"
    sc.render.resolution_x, sc.render.resolution_y = 48, 36
    sc.render.resolution_percentage = 100
    w = bpy.data.worlds.new("W")
    sc.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    next(n for n in w.node_tree.nodes if n.type == "BACKGROUND").inputs[
        "Strength"].default_value = 0.0

    def floor(nodes):
        n = nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (0.9, 0.9, 0.9, 1)
        n.inputs["Roughness"].default_value = roughness
        if kind in ("metal", "coated metal"):
            n.inputs["Metallic"].default_value = 1.0
        if kind == "coated metal":
            n.inputs["Coat Weight"].default_value = 1.0
            n.inputs["Coat Roughness"].default_value = roughness
        n.distribution = distribution
        return n.outputs[0]

    def diffuse(c):
        def build(nodes):
            n = nodes.new("ShaderNodeBsdfDiffuse")
            n.inputs["Color"].default_value = (c, c, c, 1)
            return n.outputs[0]
        return build

    bpy.ops.mesh.primitive_plane_add(size=4, location=(0, 0, 0))
    bpy.context.active_object.data.materials.append(_material(bpy, "Floor", floor))
    bpy.ops.mesh.primitive_plane_add(size=1, location=(1.5, 0, 1.25),
                                     rotation=(0, -math.pi / 2, 0))
    p = bpy.context.active_object
    p.scale = (1.5, 3, 1)
    p.data.materials.append(_material(bpy, "Panel", diffuse(0.8)))
    bpy.ops.mesh.primitive_plane_add(size=0.8, location=(-1.0, 0, 0.35))
    bpy.context.active_object.data.materials.append(_material(bpy, "Shield", diffuse(0.0)))
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.data.energy, lamp.data.shadow_soft_size = 100.0, 0.02
    lamp.location = (-1.0, 0, 0.3)
    sc.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (-0.5, 0, 1.3)
    cam.data.lens = 30
    cam.rotation_euler = (Vector((1.5, 0, 1.3)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    sc.collection.objects.link(cam)
    sc.camera = cam
    return sc


def image_mean(bpy, scene, path, engine, spp=64, photons=2_000_000, seed=0):
    """The image's mean linear radiance: ours at default settings but `spp` samples,
    `photons` global and caustic photons and `seed`, Cycles at 1024 spp, seed 0; the same
    Light Paths (12 / 4 diffuse / 4 glossy / 12 transmission)."""
    from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
    c = cycles_plain(scene, 1024, 12)  # the add-on reads the same Light Paths
    c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 4, 4, 12
    scene.render.engine = engine
    if engine == "PHOTONMAP":
        pm = default_photonmap(scene)
        pm.spp = spp
        pm.photons = pm.caustic_photons = photons
        pm.seed = seed
    return float(read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean())


def _key(kind, roughness, dist):
    return f"{kind} {roughness} {dist}"


def _cycles_means(bpy, tmp_path, kinds=("metal", "coated metal", "dielectric")):
    """Cycles' image mean per kind and CASES entry, rendered now: {_key: mean}."""
    return {_key(kind, roughness, dist): image_mean(
                bpy, scene_for(bpy, roughness, dist, kind),
                tmp_path / f"CYCLES_{kind}_{roughness}_{dist}.exr", "CYCLES")
            for kind in kinds for roughness, dist in CASES}


def _stored_means():
    with open(REF_PATH) as f:
        return json.load(f)["means"]


def _ratios(bpy, tmp_path, kind):
    """ours / Cycles (the stored means) per CASES entry."""
    cycles = _stored_means()
    ratio = {}
    for roughness, dist in CASES:
        scene = scene_for(bpy, roughness, dist, kind)
        ours = image_mean(bpy, scene, tmp_path / f"PHOTONMAP_{roughness}_{dist}.exr",
                          "PHOTONMAP")
        want = cycles[_key(kind, roughness, dist)]
        assert want > 0.01, cycles  # the panel is lit
        ratio[roughness, dist] = ours / want
    print(kind, "ours / Cycles:", {k: round(v, 4) for k, v in ratio.items()})
    return ratio


@pytest.mark.parametrize("kind", ["metal", "coated metal", "dielectric"])
def test_panel_lit_by_a_rough_floor_matches_cycles(bpy_addon, tmp_path, kind):
    ratio = _ratios(bpy_addon, tmp_path, kind)
    for k, v in ratio.items():
        assert abs(v - 1.0) < 0.02, (k, ratio)
    # The energy compensation's effect at roughness 1 (Multiscatter over plain GGX: the
    # same photon paths, so most of the noise cancels), ours against Cycles'.
    effect = ratio[1.0, "MULTI_GGX"] / ratio[1.0, "GGX"]
    assert abs(effect - 1.0) < 0.01, (effect, ratio)


@pytest.mark.slow
def test_stored_cycles_means_are_cycles_now(bpy_addon, tmp_path):
    """The stored means are what this Blender's Cycles renders (9 renders at 1024 spp,
    ~25 CPU s; seed 0, so the same numbers up to float summation order)."""
    stored, now = _stored_means(), _cycles_means(bpy_addon, tmp_path)
    assert set(now) == set(stored)
    for k, v in now.items():
        assert abs(v / stored[k] - 1.0) < 1e-3, (k, v, stored[k])


if __name__ == "__main__":  # write the stored means: .venv/bin/python <this file>
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=1024, seed=0)
