"""A Mix Shader of two Principled BSDFs (blue dielectric, gold metal) on a plane under a
sun and a uniform world, mixed by a constant factor or by a Noise Texture, rendered with
Photon Mapping and with Cycles through the bpy wheel (issue 14, session s25 mixpale).

    NUMBA_CACHE_DIR=... PYTHONPATH=. .venv/bin/python bench/bench_mix_closures.py \
        FACTOR MODE [--res W H] [--spp 16] [--threads N]

FACTOR: const (0.5) | noise (Noise Texture, scale 6, Blender's defaults otherwise)
MODE:   ours | cycles:SPP  (Cycles plain: no denoise, no adaptive, no clamp, seed 0)

Prints `RESULT factor mode R G B cpu_s sha1`: the mean linear RGB of the image (the plane
fills the frame), CPU s of this process (getrusage, the build not counted) and the
image's SHA-1 (ours: the same for any --threads).
"""
from __future__ import annotations

import argparse
import math
import os
import resource
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def build(factor: str):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    mat = bpy.data.materials.new("Mix")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nt = mat.node_tree
    p1 = nt.nodes["Principled BSDF"]
    p1.inputs["Base Color"].default_value = (0.1, 0.4, 0.8, 1)
    p1.inputs["Roughness"].default_value = 0.6
    p2 = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p2.inputs["Base Color"].default_value = (0.95, 0.8, 0.4, 1)
    p2.inputs["Metallic"].default_value = 1.0
    p2.inputs["Roughness"].default_value = 0.25
    ms = nt.nodes.new("ShaderNodeMixShader")
    if factor == "noise":
        noise = nt.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 6.0
        nt.links.new(noise.outputs["Fac"], ms.inputs[0])
    else:
        ms.inputs[0].default_value = 0.5
    nt.links.new(p1.outputs[0], ms.inputs[1])
    nt.links.new(p2.outputs[0], ms.inputs[2])
    nt.links.new(ms.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=4)
    plane = bpy.context.active_object
    plane.data.materials.append(mat)
    bpy.ops.object.light_add(type="SUN", location=(0, 0, 5))
    sun = bpy.context.active_object
    sun.data.energy = 3.0
    sun.data.angle = math.radians(5)
    sun.rotation_euler = (math.radians(35), 0, math.radians(30))
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1)
    bpy.ops.object.camera_add(location=(0, -1.2, 2.2), rotation=(math.radians(28), 0, 0))
    cam = bpy.context.active_object
    cam.data.lens = 50
    scene.camera = cam
    return scene


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("factor", choices=("const", "noise"))
    ap.add_argument("mode")
    ap.add_argument("--res", type=int, nargs=2, default=(80, 60))
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--threads", type=int, default=0, help="ours: worker processes (0: auto)")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = build(a.factor)
    r = scene.render
    r.resolution_x, r.resolution_y = a.res
    r.resolution_percentage = 100
    if a.mode == "ours":
        r.engine = "PHOTONMAP"
        scene.photonmap.spp = a.spp
        scene.photonmap.threads = a.threads
    else:
        r.engine = "CYCLES"
        c = scene.cycles
        c.device, c.samples, c.seed = "CPU", int(a.mode.split(":")[1]), 0
        c.use_denoising = c.use_adaptive_sampling = False
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        c.blur_glossy = 0.0
        r.filter_size = 1.5
    s = r.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    out = os.path.join(tempfile.mkdtemp(), "mix.exr")
    r.filepath = out
    r.use_file_extension = False
    t0 = cpu()
    bpy.ops.render.render(write_still=True)
    t = cpu() - t0
    img = bpy.data.images.load(out)
    px = np.array(img.pixels[:], np.float64).reshape(-1, 4)[:, :3]
    m = px.mean(axis=0)
    import hashlib
    sha = hashlib.sha1(np.ascontiguousarray(px, np.float32).tobytes()).hexdigest()[:12]
    print(f"RESULT {a.factor} {a.mode} {m[0]:.4f} {m[1]:.4f} {m[2]:.4f} cpu_s={t:.1f} "
          f"sha1={sha}", flush=True)


if __name__ == "__main__":
    main()
