"""Rough glass on Cycles' raised normal (issue 14): a smooth-shaded rough glass cylinder
over an emissive floor, ours against Cycles, by band, at several roughnesses.

    NUMBA_CACHE_DIR=... .venv/bin/python bench/bench_rough_glass_rim.py \\
        [--rough 0.1,0.3,0.6] [--spp 64] [--ref 512] [--root REPO]

The scene is tests/blender/test_add_refraction_cycles.py's smooth-shaded glass cylinder
(16 sides with caps, shade smooth, Principled transmission 1, IOR 1.5) at the given
roughness, seen from the side 30 degrees down (its bottom rim's interpolated normals face
away from the camera, where Cycles raises its glass closure's normal), over an emissive
floor in a black world, photon mapping off: every pixel is the floor's emission through
the glass in both engines (--emission-sampling NONE: found by the paths alone, no light
sampling). --root: the repository whose engine and add-on render ours
(default: this one; another worktree gives the 'before' column). Cycles' images are
cached in $TMPDIR. Prints ours / Cycles (mean of the three channels) for the image, the
lower rows (24..39, the bottom rim's band, as the smooth-glass test checks it) and the
rim rows alone (30..37).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile

import numpy as np

BANDS = (("image", slice(0, 48)), ("lower rows 24-39", slice(24, 40)),
         ("rim rows 30-37", slice(30, 38)))


def build(bpy, rough, sampling="AUTO"):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 48
    scene.render.resolution_percentage = 100

    def material(name, build_fn):
        m = bpy.data.materials.new(name)
        nt = m.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(build_fn(nt.nodes), out.inputs["Surface"])
        return m

    def emission(nodes):
        n = nodes.new("ShaderNodeEmission")
        n.inputs["Color"].default_value = (0.9, 0.8, 0.6, 1.0)
        n.inputs["Strength"].default_value = 1.0
        return n.outputs[0]

    def glass(nodes):
        n = nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        n.inputs["Roughness"].default_value = rough
        n.inputs["Transmission Weight"].default_value = 1.0
        n.inputs["IOR"].default_value = 1.5
        return n.outputs[0]

    bpy.ops.mesh.primitive_plane_add(size=40)
    floor = material("Floor", emission)
    floor.cycles.emission_sampling = sampling
    bpy.context.object.data.materials.append(floor)
    bpy.ops.mesh.primitive_cylinder_add(vertices=16, radius=0.5, depth=1.2,
                                        location=(0.0, 0.0, 0.6))
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(material("Glass", glass))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = (0.0, -3.2, 2.4), (math.radians(60.0), 0.0, 0.0)
    cam.data.lens = 50.0
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("Black")
    scene.world = world
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = 0.0
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    return scene


def render(bpy, H, scene, engine, spp, bounces=12):
    scene.render.engine = engine
    if engine == "CYCLES":
        c = H.cycles_plain(scene, spp, bounces)
        c.transmission_bounces = bounces
        c.caustics_reflective = c.caustics_refractive = True
    else:
        H.cheap(scene, spp=spp, photons=20_000, caustic_photons=0)
        scene.photonmap.photon_mapping = False
    path = os.path.join(tempfile.gettempdir(), f"roughglass_{engine}.exr")
    return H.read_rgba(bpy, H.render_exr(bpy, scene, path))[..., :3]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rough", default="0.1,0.3,0.6")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--ref", type=int, default=512)
    ap.add_argument("--emission-sampling", default="AUTO",
                    help="the floor's Emission Sampling (NONE: found by the paths alone)")
    ap.add_argument("--root", default=os.path.dirname(os.path.dirname(
        os.path.abspath(__file__))))
    a = ap.parse_args()
    root = os.path.abspath(a.root)
    sys.path.insert(0, root)
    sys.path.insert(0, os.path.join(root, "tests", "blender"))
    import bpy
    import addon
    import engine
    import blender_helpers as H
    addon.register()
    print(f"engine from {os.path.dirname(engine.__file__)}; ours {a.spp} spp, "
          f"Cycles {a.ref} spp; floor's emission sampling {a.emission_sampling}")
    print(f"{'rough':>6} " + " ".join(f"{name:>17}" for name, _ in BANDS))
    for rough in (float(x) for x in a.rough.split(",")):
        cache = os.path.join(tempfile.gettempdir(),
                             f"roughglass_cyl_cycles_{rough:g}_{a.ref}_{a.emission_sampling}.npy")
        if os.path.isfile(cache):
            ref = np.load(cache)
        else:
            ref = render(bpy, H, build(bpy, rough, a.emission_sampling), "CYCLES", a.ref)
            np.save(cache, ref)
        ours = render(bpy, H, build(bpy, rough, a.emission_sampling), "PHOTONMAP", a.spp)
        ratios = [ours[b].mean() / ref[b].mean() for _, b in BANDS]
        print(f"{rough:6.2f} " + " ".join(f"{r:17.4f}" for r in ratios))


if __name__ == "__main__":
    main()
