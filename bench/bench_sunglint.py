"""A sun reflected by a car-paint ball onto a shaded wall: the engine's wall irradiance
against a closed form and against Cycles (issue 14, s22 sunglint).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_sunglint.py [--caustic 50000,200000,1000000]
        [--seeds 1,2] [--cycles]

The scene of tests/test_sky_sun_glint.py: a ball (radius 0.5 m) 2 m in front of a
Lambert wall (albedo 0.8), a Single Scattering sky's sun disc (0.545 degrees, 50 degrees
up) behind the wall, which sees only the ball's reflection. Paints:
  coat   black under a clear coat (roughness 0): the mirror quadrature is exact
  car    the new-user trial's car paint: base (0.5, 0.02, 0.02), metallic 0.7,
         roughness 0.35, specular layer on, coat 1.0 of roughness 0.03
Each row: the wall's mean irradiance (W/m^2, green and red) from the Caustic pass
(indirect off; the aimed caustic shot) and the combined image (indirect auto, 200k
global photons; the ball's diffuse base adds its red), the quadrature's value (coat only) and, with --cycles, Cycles 5.0.1's
(1024 spp, a Sun lamp of the same irradiance and angle, Clamp Direct / Indirect off,
rendered through the bpy in .venv: seconds each). Blender's default Clamp Indirect of 10
cuts the coat's sun samples (F x L_sun, thousands) to nothing: a clamped Cycles misses
this caustic even at infinite samples. Cycles finds the coat's sun caustic only by a wall sample that hits the
glint and whose mirror direction meets the 0.545 degree disc: a handful of samples of
F x L_sun each (fireflies), so its coat row is noise around the quadrature.
"""
from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

from engine import RenderSettings  # noqa: E402
from engine.scene import Camera, Material  # noqa: E402
import test_sky_sun_glint as glint  # noqa: E402

PAINTS = {
    "coat": dict(base_color=(0.0, 0.0, 0.0), coat_weight=1.0, coat_roughness=0.0),
    "car": dict(base_color=(0.5, 0.02, 0.02), metallic=0.7, roughness=0.35, specular=1.0,
                coat_weight=1.0, coat_roughness=0.03),
}

CYCLES_SCRIPT = r'''
import math, sys, numpy as np, bpy
from mathutils import Vector
sys.path.insert(0, ROOT)
from tools.canonical_mesh import primitive_uv_sphere_add
paint, E, elev, out = sys.argv[-4], [float(x) for x in sys.argv[-3].split(",")], float(sys.argv[-2]), sys.argv[-1]
bpy.ops.wm.read_homefile(use_empty=True); sc = bpy.context.scene
sc.render.resolution_x = sc.render.resolution_y = 48; sc.render.resolution_percentage = 100
def mat(name):
    m = bpy.data.materials.new(name); m.use_nodes = True; return m, m.node_tree.nodes["Principled BSDF"]
wall, b = mat("wall"); b.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1)
b.inputs["Roughness"].default_value = 1.0; b.inputs["Specular IOR Level"].default_value = 0.0
ball, b = mat("paint")
if paint == "coat":
    b.inputs["Base Color"].default_value = (0, 0, 0, 1); b.inputs["Specular IOR Level"].default_value = 0.0
    b.inputs["Coat Weight"].default_value = 1.0; b.inputs["Coat Roughness"].default_value = 0.0
else:
    b.inputs["Base Color"].default_value = (0.5, 0.02, 0.02, 1); b.inputs["Metallic"].default_value = 0.7
    b.inputs["Roughness"].default_value = 0.35; b.inputs["Coat Weight"].default_value = 1.0
    b.inputs["Coat Roughness"].default_value = 0.03
bpy.ops.mesh.primitive_plane_add(size=1, location=(0, 0, -1.0)); w = bpy.context.active_object
w.rotation_euler = (math.pi / 2, 0, 0); w.scale = (8, 5, 1); w.data.materials.append(wall)
primitive_uv_sphere_add(segments=96, ring_count=48, radius=0.5, location=(0, -2.0, 0))
bpy.ops.object.shade_smooth(); bpy.context.active_object.data.materials.append(ball)
D = Vector((0, -math.cos(elev), -math.sin(elev)))
sun = bpy.data.lights.new("Sun", "SUN"); sun.energy = max(E); sun.color = [e / max(E) for e in E]
sun.angle = math.radians(0.545)
so = bpy.data.objects.new("Sun", sun); sc.collection.objects.link(so)
so.rotation_euler = D.to_track_quat("-Z", "Y").to_euler()
wd = bpy.data.worlds.new("W"); sc.world = wd; wd.use_nodes = True
wd.node_tree.nodes["Background"].inputs[1].default_value = 0
cam = bpy.data.cameras.new("C"); cam.type = "ORTHO"; cam.ortho_scale = 3.0
co = bpy.data.objects.new("C", cam); sc.collection.objects.link(co)
co.location = (0, -0.5, -0.25); co.rotation_euler = (math.pi / 2, 0, 0); sc.camera = co
sc.render.engine = "CYCLES"; cy = sc.cycles; cy.samples = 1024; cy.use_denoising = False
cy.use_adaptive_sampling = False; cy.caustics_reflective = True;
cy.sample_clamp_direct = 0.0; cy.sample_clamp_indirect = 0.0  # Blender clamps indirect at 10 by default
cy.blur_glossy = 0; cy.device = "CPU"
sc.render.threads_mode = "FIXED"; sc.render.threads = 2
sc.render.image_settings.file_format = "OPEN_EXR"; sc.render.image_settings.color_depth = "32"
sc.render.filepath = out; bpy.ops.render.render(write_still=True)
im = bpy.data.images.load(out); a = np.empty(48 * 48 * 4, np.float32); im.pixels.foreach_get(a)
np.save(out + ".npy", a.reshape(48, 48, 4)[::-1, :, :3])
'''


def ours(paint, caustic, seed, indirect):
    from engine.api import PaperScene
    from engine.scene import Light
    sky = glint._sky()
    s = PaperScene(width=glint.RES, height=glint.RES)
    s.add_material(Material("matte", (glint.RHO,) * 3))
    s.add_material(Material("paint", **PAINTS[paint]))
    s.add_sphere((0, glint.BALL_Y, 0), glint.A, "paint", name="ball", segments=96)
    s.add_light(Light(**sky.sun_light_params()))
    s.add_plane((0, 0, -1.0), (0, -1, 0), (8.0, 5.0), "matte", name="wall", up=(0, 0, 1))
    s.camera = Camera(position=(0, -0.5, glint.VIEW_Z), rotation=glint.LOOK_Y, kind="ORTHO",
                      ortho_scale=glint.VIEW)
    film = s.render(RenderSettings(spp=16, photons=200_000 if indirect == "auto" else 0,
                                   caustic_photons=caustic, indirect=indirect, seed=seed))
    k = math.pi / glint.RHO
    return (film.caustic[..., :3].astype(np.float64).mean(axis=(0, 1)) * k,
            film.combined[..., :3].astype(np.float64).mean(axis=(0, 1)) * k)


def cycles(paint):
    sky = glint._sky()
    light = sky.sun_light_params()
    with tempfile.TemporaryDirectory() as tmp:
        script, out = os.path.join(tmp, "c.py"), os.path.join(tmp, "c.exr")
        with open(script, "w") as f:
            f.write(f"ROOT = {ROOT!r}\n" + CYCLES_SCRIPT)
        subprocess.run([sys.executable, script, paint, ",".join(str(float(e)) for e in light["color"]),
                        str(glint.ELEVATION), out], check=True, capture_output=True)
        img = np.load(out + ".npy")
    return img.astype(np.float64).mean(axis=(0, 1)) * math.pi / glint.RHO


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--caustic", default="50000,200000,1000000")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--cycles", action="store_true")
    a = ap.parse_args()
    sky = glint._sky()
    light = sky.sun_light_params()
    quad = glint._wall_irradiance(np.asarray(light["direction"], np.float64), 1.0).mean()
    E = np.asarray(light["color"], np.float64)
    print(f"sun disc irradiance (RGB, W/m^2): {np.round(E, 3)}; coat quadrature: wall mean "
          f"E = {quad * E[1]:.5f} (green)")
    print("| paint | caustic photons | seed | Caustic pass E (G, R) | combined E (G, R), indirect auto | quadrature (G) |")
    print("|---|---|---|---|---|---|")
    for paint in PAINTS:
        for n in (int(x) for x in a.caustic.split(",")):
            for seed in (int(x) for x in a.seeds.split(",")):
                cau, _ = ours(paint, n, seed, "off")
                _, comb = ours(paint, n, seed, "auto")
                q = f"{quad * E[1]:.5f}" if paint == "coat" else "-"
                print(f"| {paint} | {n:,} | {seed} | {cau[1]:.5f}, {cau[0]:.5f} | "
                      f"{comb[1]:.5f}, {comb[0]:.5f} | {q} |", flush=True)
        if a.cycles:
            c = cycles(paint)
            print(f"| {paint} | Cycles 1024 spp, no clamp | 0 | - | {c[1]:.5f}, {c[0]:.5f} | - |", flush=True)
    print(f"load: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
