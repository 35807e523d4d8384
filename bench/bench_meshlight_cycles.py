"""Emissive meshes' direct light, live Cycles against ours (docs/performance.md,
"meshlight"): a neon tube (a 16-sided Emission cylinder) and a small tilted Emission quad
over a diffuse floor, a glossy Principled back wall and a glossy Principled ball, no other
light, Light Paths max bounces 0 (direct light and its MIS with the BSDF rays only),
80 x 60. Per seed: the image's relMSE (luminance, (x - r)^2 / (r^2 + 0.01), as the
new-user trials) against a Cycles reference of CSPP samples, the image mean over the
reference's, and the process CPU seconds of the render (Cycles' and our threads
included), for Cycles and ours at the same spp.

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_meshlight_cycles.py \\
        REF.npy [SPP [SEEDS]]

REF.npy: the reference image, rendered (CSPP, default 1024) and saved when missing.
Run from another checkout (a copy of this file in its bench/) for a before / after.
"""
import math, os, resource, sys, tempfile
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
sys.path.insert(0, os.path.join(ROOT, "example_blends"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cycles_plain, read_rgba, render_exr
import make_blends as mb

ref_path = sys.argv[1]
SPP = int(sys.argv[2]) if len(sys.argv) > 2 else 16
SEEDS = int(sys.argv[3]) if len(sys.argv) > 3 else 3


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def lum(img):
    return img[..., 0] * 0.2126 + img[..., 1] * 0.7152 + img[..., 2] * 0.0722


def rel_mse(img, ref):
    a, b = lum(img), lum(ref)
    return float(np.mean((a - b) ** 2 / (b * b + 1e-2)))


scene = mb.reset()
mb.plane("Floor", 6, 6, mb.material("floor", "diffuse", (0.8, 0.8, 0.8)))
mb.plane("Wall", 6, 3, mb.material("wall", "principled", (0.6, 0.6, 0.6), roughness=0.3),
         location=(0, 1.0, 1.5), rotation=(math.pi / 2, 0, 0))
mb.sphere("Ball", 0.3, mb.material("ball", "principled", (0.8, 0.5, 0.2), roughness=0.25),
          (0.5, 0.1, 0.3))


def emission(name, strength, color):
    m, nt, out = mb.empty_material(name)
    n = nt.nodes.new("ShaderNodeEmission")
    n.inputs["Color"].default_value = (*color, 1.0)
    n.inputs["Strength"].default_value = strength
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    return m


bpy.ops.mesh.primitive_cylinder_add(vertices=16, radius=0.03, depth=1.4,
                                    location=(0, 0.8, 0.7), rotation=(0, math.pi / 2, 0))
tube = bpy.context.active_object
tube.name = "Tube"
tube.data.materials.append(emission("neon", 20.0, (1.0, 0.3, 0.6)))
bpy.ops.mesh.primitive_plane_add(size=0.3, location=(-0.9, -0.2, 0.9),
                                 rotation=(0.6, 0.4, 0))
quad = bpy.context.active_object
quad.name = "Quad"
quad.data.materials.append(emission("panel", 10.0, (0.6, 0.8, 1.0)))
mb.camera((0, -3.0, 1.3), (0, 0.3, 0.4), fov_deg=50)
mb.set_world((0, 0, 0))
scene.render.resolution_x, scene.render.resolution_y = 80, 60
scene.render.resolution_percentage = 100
tmp = tempfile.mkdtemp()


def cycles(spp, seed):
    c = cycles_plain(scene, spp, 0)
    c.seed = seed
    scene.render.threads_mode, scene.render.threads = "FIXED", 2
    scene.render.engine = "CYCLES"
    c0 = cpu()
    img = read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/c.exr"))[..., :3]
    return img, cpu() - c0


if os.path.exists(ref_path):
    ref = np.load(ref_path)
else:
    ref, t = cycles(int(os.environ.get("CSPP", 1024)), 0)
    np.save(ref_path, ref)
    print(f"reference: Cycles {os.environ.get('CSPP', 1024)} spp, cpu {t:.1f} s", flush=True)

for seed in range(1, SEEDS + 1):
    img, t = cycles(SPP, seed)
    print(f"cycles {SPP} spp seed {seed}: relMSE {rel_mse(img, ref):.5f} "
          f"mean/ref {img.mean() / ref.mean():.4f} cpu {t:.1f} s", flush=True)
for seed in range(1, SEEDS + 1):
    scene.render.engine = "PHOTONMAP"
    pm = scene.photonmap
    pm.spp, pm.seed, pm.photon_mapping = SPP, seed, False
    c0 = cpu()
    img = read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/o.exr"))[..., :3]
    t = cpu() - c0
    print(f"ours {SPP} spp seed {seed}: relMSE {rel_mse(img, ref):.5f} "
          f"mean/ref {img.mean() / ref.mean():.4f} cpu {t:.1f} s", flush=True)
