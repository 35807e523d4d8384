"""Glossy noise against Cycles at equal samples (issue 14): a rough metal ball and a
Principled dielectric ball on a grey floor, lit by one light at a time (an area light, an
emissive mesh panel, a point light with a radius, a constant world) or by 20 small area
lights / 20 point lights with a radius sharing the same power (more than the light tree's
threshold: both renderers pick lights with their light trees). For each renderer two
renders at SPP samples with different seeds: the pixel noise of an object is the std of
their difference over its pixels / sqrt(2); the mean is over its pixels (Cycles' at
REF_SPP samples). Needs the bpy wheel.

    .venv/bin/python tools/glossy_noise.py              table: ours / Cycles noise, means
    .venv/bin/python tools/glossy_noise.py --references  writes Cycles' numbers to
                                                         tests/references/glossy_noise.json
    .venv/bin/python tools/glossy_noise.py --references --lights area20,point20
                                                         ... of these lights only (merged)
(tests/blender/test_glossy_noise_cycles.py compares ours with them.)
"""
from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)
import accuracy_scenes as acc  # noqa: E402
import json  # noqa: E402
import bpy  # noqa: E402

mb = acc.mb
W, H = 96, 72
OBJECTS = ("Metal", "Dielectric", "Floor")
LIGHTS = ("area", "mesh", "point", "world", "area20", "point20")
MANY = 20  # lights of the area20 / point20 scenes
SPP, REF_SPP = 16, 256
REF_PATH = os.path.join(ROOT, "tests", "references", "glossy_noise.json")


def build(light, metal_rough=0.3, diel_rough=0.2):
    mb.reset()
    mb.plane("Floor", 20, 20, acc.principled("FloorMat", base_color=(0.5, 0.5, 0.5),
                                              roughness=0.8))
    mb.sphere("Metal", 0.5, acc.principled("MetalMat", base_color=(0.9, 0.7, 0.5),
                                           metallic=1.0, roughness=metal_rough),
              (-0.6, 0.0, 0.5), segments=48, rings=24)
    mb.sphere("Dielectric", 0.5, acc.principled("DielMat", base_color=(0.2, 0.3, 0.6),
                                                roughness=diel_rough),
              (0.6, 0.0, 0.5), segments=48, rings=24)
    world = bpy.data.worlds.new("World")
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    if light == "area":
        mb.light("Lamp", "AREA", (-1.0, -2.0, 3.0), 200.0, look_at=(0, 0, 0.5),
                 shape="SQUARE", size=1.0)
    elif light == "point":
        mb.light("Lamp", "POINT", (-1.0, -2.0, 3.0), 200.0, shadow_soft_size=0.25)
    elif light == "mesh":
        m, nt, out = mb.empty_material("Panel")
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 20.0
        nt.links.new(em.outputs[0], out.inputs["Surface"])
        # A panel of a few quads (a subdivided plane), tilted towards the balls.
        me = bpy.data.meshes.new("Panel")
        n = 3
        verts = [(-0.5 + i / n, -0.5 + j / n, 0.0) for j in range(n + 1) for i in range(n + 1)]
        faces = [(j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1,
                  (j + 1) * (n + 1) + i) for j in range(n) for i in range(n)]
        me.from_pydata(verts, [], faces)
        me.update()
        from mathutils import Vector
        obj = mb.add_object("Panel", me, m, (-1.0, -2.0, 3.0))
        d = Vector((0, 0, 0.5)) - Vector((-1.0, -2.0, 3.0))
        obj.rotation_euler = (-d).to_track_quat("Z", "Y").to_euler()
    elif light in ("area20", "point20"):
        # A 5 x 4 grid of small lights round the single light's place, 200 W in all.
        for i in range(MANY):
            loc = (-1.0 + 0.35 * (i % 5 - 2), -2.0, 3.0 + 0.35 * (i // 5 - 1.5))
            if light == "area20":
                mb.light(f"Lamp{i}", "AREA", loc, 200.0 / MANY, look_at=(0, 0, 0.5),
                         shape="SQUARE", size=0.2)
            else:
                mb.light(f"Lamp{i}", "POINT", loc, 200.0 / MANY, shadow_soft_size=0.08)
    elif light == "world":
        bg.inputs["Color"].default_value = (0.6, 0.6, 0.6, 1.0)
    else:
        raise ValueError(light)
    bpy.context.scene.world = world
    mb.camera((0.0, -4.0, 1.6), (0.0, 0.0, 0.45), 40.0)
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.film_transparent = False
    return scene


def labels(scene):
    """(H, W) int: index into OBJECTS + 1 of the object each pixel's centre sees, eroded."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    o = cam.matrix_world.translation
    out = np.zeros((H, W), int)
    for y in range(H):
        for x in range(W):
            p = tl + (tr - tl) * ((x + 0.5) / W) + (bl - tl) * ((y + 0.5) / H)
            hit, _, _, _, ob, _ = scene.ray_cast(dg, o, (p - o).normalized())
            if hit and ob.name in OBJECTS:
                out[y, x] = OBJECTS.index(ob.name) + 1
    e = out.copy()
    e[1:] *= out[:-1] == out[1:]
    e[:-1] *= out[1:] == out[:-1]
    e[:, 1:] *= out[:, :-1] == out[:, 1:]
    e[:, :-1] *= out[:, 1:] == out[:, :-1]
    return e


def render(scene, engine, spp, seed, **overrides):
    if engine == "cycles":
        acc.set_cycles(scene, spp, seed)
    else:
        acc.set_photonmap_defaults(scene)
        pm = scene.photonmap
        pm.spp = spp
        pm.seed = seed
        for k, v in overrides.items():
            setattr(pm, k, v)
    return acc.render_rgb(scene)


def measure(light, engine, spp=SPP, seeds=(1, 2), **overrides):
    """{object: (pixel noise, mean)} of `engine` ("ours" | "cycles") on the scene lit by
    `light`: noise from two renders at spp with `seeds`, the mean over both."""
    lab = labels(build(light))
    imgs = [render(build(light), engine, spp, seed, **overrides)[0] for seed in seeds]
    out = {}
    for k, name in enumerate(OBJECTS):
        m = lab == k + 1
        if m.sum() < 5:
            continue
        noise = float(np.std((imgs[0] - imgs[1])[m]) / math.sqrt(2))
        out[name] = (noise, float(np.mean([im[m].mean() for im in imgs])))
    return out


def references(lights=LIGHTS):
    """Cycles' noise at SPP (seeds 1, 2) and mean at REF_SPP (seed 3) per light and object,
    for `lights` (the others' stored numbers are kept)."""
    ref = {"width": W, "height": H, "spp": SPP, "ref_spp": REF_SPP, "lights": {}}
    if os.path.exists(REF_PATH):
        with open(REF_PATH) as f:
            ref["lights"] = json.load(f)["lights"]
    for light in lights:
        noisy = measure(light, "cycles")
        conv = measure(light, "cycles", REF_SPP, seeds=(3, 4))
        ref["lights"][light] = {name: {"noise": noisy[name][0], "mean": conv[name][1]}
                                for name in noisy}
    with open(REF_PATH, "w") as f:
        json.dump(ref, f, indent=1)
    return ref


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--references", action="store_true")
    ap.add_argument("--lights", default=",".join(LIGHTS))
    ap.add_argument("--no-photons", action="store_true", help="ours with photon_mapping off")
    args = ap.parse_args(argv)
    if args.references:
        references(args.lights.split(","))
    with open(REF_PATH) as f:
        ref = json.load(f)
    over = {"photon_mapping": False} if args.no_photons else {}
    print(f"{SPP} spp, {W}x{H}; Cycles' numbers from {os.path.relpath(REF_PATH, ROOT)}")
    print("| light | object | noise ours | noise Cycles | ratio | mean ours / Cycles |")
    print("|---|---|---:|---:|---:|---:|")
    for light in args.lights.split(","):
        ours = measure(light, "ours", **over)
        for name, (noise, mean) in ours.items():
            c = ref["lights"][light][name]
            print(f"| {light} | {name} | {noise:.4f} | {c['noise']:.4f} | "
                  f"{noise / c['noise']:.2f} | {mean / c['mean']:.3f} |", flush=True)


if __name__ == "__main__":
    main()
