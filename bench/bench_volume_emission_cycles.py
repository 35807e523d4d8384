"""Volume emission (volemit38, issue 14): ours against live Cycles 5.0, and what the
photons would add. A glowing volume-only box (Principled Volume, Emission Strength 2,
Emission Color (1, 0.5, 0.2), Density 0 or 0.8 with Color 0.7), no lamp, black world,
64 x 48, box filter, Max Bounces 4, Volume bounces 0. Scenes:
  floor   the box over a white floor (0.8): the floor sees the glow directly
  corner  the same box in a corner (floor and two white walls): the walls and the floor
          also light each other, light the glow reaches only after a diffuse bounce
Per scene and density: the 5 x 5 block means of the box, the floor in front of it, the
wall (corner) and the image sum, ours over Cycles (Cycles at REF_SPP), and seconds a
render. Ours brings the glow to surfaces through its final-gather rays alone (no photons
from media, engine/volumeemission.py): the corner's walls miss the glow's second bounce.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_volume_emission_cycles.py [SPP [REF_SPP]]
"""
import os, sys, time
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
sys.path.insert(0, os.path.join(ROOT, "example_blends"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import (black_world, cheap, cycles_plain, default_photonmap, project,
                             read_rgba, render_exr)
import make_blends as mb

SPP = int(sys.argv[1]) if len(sys.argv) > 1 else 256
REF_SPP = int(sys.argv[2]) if len(sys.argv) > 2 else 1024
TMP = "/tmp/volemit38-bench"
os.makedirs(TMP, exist_ok=True)


def glow(density):
    m, nt, out = mb.empty_material(f"glow{density}")
    v = nt.nodes.new("ShaderNodeVolumePrincipled")
    v.inputs["Density"].default_value = density
    v.inputs["Color"].default_value = (0.7, 0.7, 0.7, 1.0)
    v.inputs["Emission Strength"].default_value = 2.0
    v.inputs["Emission Color"].default_value = (1.0, 0.5, 0.2, 1.0)
    nt.links.new(v.outputs[0], out.inputs["Volume"])
    return m


def build(kind, density):
    scene = mb.reset()
    default_photonmap(scene)
    white = mb.material("white", "diffuse", (0.8, 0.8, 0.8))
    mb.plane("Floor", 8, 8, white)
    if kind == "corner":
        mb.box("WallBack", 8, 0.1, 4, white, location=(0, 1.5, 2))
        mb.box("WallSide", 0.1, 8, 4, white, location=(1.5, 0, 2))
    mb.box("Glow", 1.2, 1.2, 0.8, glow(density), location=(0.0, 0.0, 0.8))
    mb.camera((-1.5, -5.0, 1.8), (0.3, 0.3, 0.6), fov_deg=50.0)
    black_world(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    scene.render.resolution_percentage = 100
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    return scene


def render(scene, engine, spp):
    scene.render.engine = engine
    c = cycles_plain(scene, spp, 4)
    c.volume_bounces = 0
    if engine != "CYCLES":
        cheap(scene, spp=spp)
    t = time.perf_counter()
    img = read_rgba(bpy, render_exr(bpy, scene, os.path.join(TMP, "bench.exr")))[..., :3]
    return img.astype(np.float64), time.perf_counter() - t


def block(img, rc, r=2):
    y, x = rc
    return img[y - r:y + r + 1, x - r:x + r + 1].reshape(-1, 3).mean(axis=0)


print("| scene | density | box | floor in front | wall | image sum | ours s | Cycles s |")
print("|---|---|---|---|---|---|---|---|")
for kind in ("floor", "corner"):
    for density in (0.0, 0.8):
        scene = build(kind, density)
        ours, t_ours = render(scene, "PHOTONMAP", SPP)
        ref, t_ref = render(scene, "CYCLES", REF_SPP)
        points = {"box": (0.0, 0.0, 0.8), "floor": (-0.3, -1.1, 0.0),
                  "wall": (1.45, 0.3, 1.2)}
        cells = []
        for where, p in points.items():
            if where == "wall" and kind != "corner":
                cells.append("-")
                continue
            rc = project(bpy, scene, p)
            cells.append(f"{(block(ours, rc) / block(ref, rc)).mean():.3f}")
        total = ours.sum() / ref.sum()
        print(f"| {kind} | {density} | " + " | ".join(cells)
              + f" | {total:.3f} | {t_ours:.1f} | {t_ref:.1f} |", flush=True)
