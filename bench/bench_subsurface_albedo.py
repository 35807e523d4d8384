"""Cycles' random-walk subsurface scattering on a thick flat slab (a half-space for its
mean free path): the diffuse reflectance it yields per Base Color value, against the
diffuse base it replaces (Subsurface Weight 0). engine/subsurface.py's table came from
this script (session s25, mixpale).

    NUMBA_CACHE_DIR=... PYTHONPATH=. .venv/bin/python bench/bench_subsurface_albedo.py \
        [--spp 256] [--res 24] [--sun 30 60] [--view 0]

A 40 m x 40 m x 2 m slab, Subsurface Scale 0.01 and Radius (1, 1, 1) (mean free path
1 cm: nothing leaves through the sides or the bottom), Roughness 0.5, a sun at each
zenith angle, a black world, an orthographic camera at view zenith angle --view. Per
colour value c (three per render, one per channel): spec = the image with Base Color 0
(the specular layer alone), dif = Subsurface Weight 0, sss = Subsurface Weight 1;
printed: c, a(c, view) = c (sss - spec) / (dif - spec) (the Lambertian albedo that would
give Cycles' radiance at that view) and a / c. engine/subsurface.py's A(c) is
2 int a mu dmu over runs at --view 0 30 45 60 75 80 85 (--sun 30; trapezoids in
mu = cos(view), a at 90 degrees taken as at 85).
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

COLOURS = [(0.02, 0.05, 0.1), (0.15, 0.2, 0.3), (0.4, 0.5, 0.6), (0.7, 0.8, 0.85),
           (0.88, 0.9, 0.92), (0.94, 0.97, 1.0)]


def render(color, weight, sun_deg, res, spp, view_deg=0.0):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    m = bpy.data.materials.new("Slab")
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Roughness"].default_value = 0.5
    p.inputs["Subsurface Weight"].default_value = weight
    p.inputs["Subsurface Scale"].default_value = 0.01
    p.inputs["Subsurface Radius"].default_value = (1.0, 1.0, 1.0)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, -1.0), scale=(40, 40, 2))
    bpy.context.active_object.data.materials.append(m)
    bpy.ops.object.light_add(type="SUN")
    sun = bpy.context.active_object
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = (0.0, math.radians(sun_deg), 0.0)
    w = bpy.data.worlds.new("World")
    scene.world = w
    if bpy.app.version < (5, 0, 0):
        w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    t = math.radians(view_deg)  # the view's zenith angle, tilted towards -y
    cam.location = (0, -5 * math.sin(t), 5 * math.cos(t))
    cam.rotation_euler = (t, 0.0, 0.0)
    cam.data.type, cam.data.ortho_scale = "ORTHO", 2.0
    scene.collection.objects.link(cam)
    scene.camera = cam
    r = scene.render
    r.resolution_x = r.resolution_y = res
    r.resolution_percentage = 100
    r.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.seed = "CPU", spp, 0
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    s = r.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    out = os.path.join(tempfile.mkdtemp(), "slab.exr")
    r.filepath = out
    r.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(out)
    return np.array(img.pixels[:], np.float64).reshape(-1, 4)[:, :3].mean(axis=0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--res", type=int, default=24)
    ap.add_argument("--sun", type=float, nargs="+", default=[30.0, 60.0])
    ap.add_argument("--view", type=float, default=0.0, help="view zenith angle, degrees")
    a = ap.parse_args()
    print("| sun zenith deg | c | a(c) | a(c) / c |")
    print("|---|---|---|---|")
    for sun in a.sun:
        spec = render((0.0, 0.0, 0.0), 0.0, sun, a.res, a.spp, a.view)
        for col in COLOURS:
            dif = render(col, 0.0, sun, a.res, a.spp, a.view)
            sss = render(col, 1.0, sun, a.res, a.spp, a.view)
            alb = np.asarray(col) * (sss - spec) / (dif - spec)
            for c, x in zip(col, alb):
                print(f"| {sun:g} | {c:g} | {x:.4f} | {x / c:.4f} |", flush=True)


if __name__ == "__main__":
    main()
