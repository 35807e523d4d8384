"""How much light Cycles' Principled subsurface scattering (random walk, Blender's
defaults: Radius (1, 0.2, 0.1), IOR 1.4) keeps compared with the same material without it
(Subsurface Weight 0: a diffuse base), per Subsurface Scale, on a UV sphere and a Suzanne
under an area light in a black world. Photon Mapping renders Subsurface Weight > 0 as the
diffuse base of the albedo Cycles' random walk gives a thick object (engine/subsurface.py).

    NUMBA_CACHE_DIR=... PYTHONPATH=. .venv/bin/python bench/bench_subsurface_cycles.py \
        [--spp 128] [--res 64] [--scales 0.01 0.05 0.1 0.3]

Prints a table: shape, size (m), scale, mean free path of the red channel over the object
size, per channel the mean of the object's pixels with SSS / without (Cycles both, seed
0, same samples), and ours (Photon Mapping, --ours-spp, the add-on's other defaults:
engine/subsurface.py's albedo) / Cycles with SSS, per channel and for the mean.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402

from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402


def build(shape: str, size: float, weight: float, scale: float):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    m = bpy.data.materials.new("Skin")
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (0.9, 0.6, 0.5, 1.0)
    p.inputs["Roughness"].default_value = 0.4
    p.inputs["Subsurface Weight"].default_value = weight
    p.inputs["Subsurface Scale"].default_value = scale
    if shape == "sphere":
        primitive_uv_sphere_add(radius=size / 2, segments=48, ring_count=24)
    else:
        bpy.ops.mesh.primitive_monkey_add(size=size)
        bpy.ops.object.modifier_add(type="SUBSURF")
    o = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    o.data.materials.append(m)
    bpy.ops.object.light_add(type="AREA", location=(1.5 * size, -1.5 * size, 2.0 * size))
    light = bpy.context.active_object
    light.data.energy = 200.0 * size * size
    light.data.size = size
    from mathutils import Vector
    light.rotation_euler = Vector((-1.5, 1.5, -2.0)).to_track_quat("-Z", "Y").to_euler()
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    bpy.ops.object.camera_add(location=(0, -3.0 * size, 0.4 * size))
    cam = bpy.context.active_object
    cam.rotation_euler = Vector((0, 3.0, -0.4)).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = 50
    scene.camera = cam
    return scene


def render(scene, res, spp, engine="CYCLES"):
    r = scene.render
    r.resolution_x = r.resolution_y = res
    r.resolution_percentage = 100
    r.engine = engine
    if engine == "PHOTONMAP":
        scene.photonmap.spp = spp
    c = scene.cycles
    c.device, c.samples, c.seed = "CPU", spp, 0
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    s = r.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    out = os.path.join(tempfile.mkdtemp(), "sss.exr")
    r.filepath = out
    r.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(out)
    return np.array(img.pixels[:], np.float64).reshape(-1, 4)[:, :3]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--scales", type=float, nargs="+", default=[0.01, 0.05, 0.1, 0.3])
    ap.add_argument("--shapes", nargs="+", default=["sphere:1.0", "monkey:0.7"])
    ap.add_argument("--ours-spp", type=int, default=16)
    a = ap.parse_args()
    import addon
    addon.register()
    print("| shape | size m | scale | red mfp / size | Cycles SSS / diffuse R G B | "
          "ours / Cycles SSS R G B | ours / Cycles mean |")
    print("|---|---|---|---|---|---|---|")
    for spec in a.shapes:
        shape, size = spec.split(":")
        size = float(size)
        base = render(build(shape, size, 0.0, 0.05), a.res, a.spp)
        obj = base.sum(axis=1) > 0
        ref = base[obj].mean(axis=0)
        for scale in a.scales:
            sss = render(build(shape, size, 1.0, scale), a.res, a.spp)
            got = sss[obj].mean(axis=0)
            ratio = got / ref
            ours = render(build(shape, size, 1.0, scale), a.res, a.ours_spp,
                          "PHOTONMAP")[obj].mean(axis=0)
            q = ours / got
            print(f"| {shape} | {size:g} | {scale:g} | {scale / size:.3f} | "
                  f"{ratio[0]:.3f} {ratio[1]:.3f} {ratio[2]:.3f} | "
                  f"{q[0]:.3f} {q[1]:.3f} {q[2]:.3f} | {ours.mean() / got.mean():.3f} |",
                  flush=True)


if __name__ == "__main__":
    main()
