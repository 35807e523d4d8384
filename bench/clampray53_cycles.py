"""Cycles' Clamp Indirect per gather ray (clampray53): ours against Cycles at Clamp
Indirect 10, 1 and 0 (off), per region, on three scenes, before (the clamp on the mean of
a camera sample's gather rays: engine.integrator.CLAMP_PER_GATHER_RAY False) and after.

    PYTHONPATH=$PWD .venv/bin/python bench/clampray53_cycles.py SCENE [--out DIR]
        [--cycles-spp N] [--seeds 0,1] [--clamps 10,1,0]

SCENE:
  ball    a clear glass ball (r 0.3 m, Principled Transmission 1, IOR 1.45, roughness 0)
          on a white floor (0.8) under a 0.1 m square area light (40 W, 1.6 m up), a dim
          grey World (0.02); 64 x 48. Regions: "caustic" (floor pixels whose ray to the
          light's centre meets the ball), "floor" (the other floor pixels), "ball", "image".
  room    a closed 4 x 4 x 2.5 m white room (0.7) with a 1 x 1 m window in one wall, a Sun
          (strength 40) shining through it 40 degrees down, a black World; 64 x 48 from a
          corner. Regions: "sunlit" (the floor and walls the sun reaches), "shade" (the
          other floor pixels), "walls" (the rest), "image".
  jewel   bench/newuser52_jewellery.py's display on its Render Region round the pendant
          (--border 0.094 0.375 0.333 0.583 of 160 x 120). Regions: newuser52's
          "Plinth:PendantShadow" (where the pendant's caustic falls), "Pendant",
          "Plinth" (the region's other plinth pixels), "region". At Filter Glossy 1 and 0
          (scene names jewel1, jewel0). Needs newuser52's masks at 160 x 120 in
          /tmp/newuser52/masks.npy (`bench/newuser52_jewellery.py x OUT.exr --masks
          /tmp/newuser52/masks.npy`, docs/accuracy.md "newuser52").

Both engines at Blender's Light Paths defaults otherwise (Filter Glossy 1 for ball and room,
caustics on), Cycles' Clamp Direct 0; ours through the add-on at its defaults (128 spp),
its seed --seeds. Cycles at --cycles-spp, seed 0, cached in --out (.npy) and loaded from
there. Prints one table per scene: each region's mean luminance, Cycles' own, and ours'
before / after over Cycles' at the same clamp.
"""
from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (ROOT, os.path.join(ROOT, "bench"), os.path.join(ROOT, "tools")):
    if p not in sys.path:
        sys.path.insert(0, p)

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

import accuracy_scenes as A  # noqa: E402

BORDER = (0.094, 0.375, 0.333, 0.583)


def _principled(name, colour, **inputs):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*colour, 1.0)
    for k, v in inputs.items():
        b.inputs[k].default_value = v
    return m


def _plane(loc, rot, scale, mat, name):
    bpy.ops.mesh.primitive_plane_add(size=1, location=loc, rotation=rot)
    ob = bpy.context.object
    ob.scale, ob.name = scale, name
    ob.data.materials.append(mat)
    return ob


def _camera(scene, loc, target, lens=35.0):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = loc
    cam.rotation_euler = (Vector(target) - Vector(loc)).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = lens
    scene.camera = cam


def _world(scene, value):
    w = bpy.data.worlds.new("World")
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (value, value, value, 1)
    scene.world = w


def _empty():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    A.ensure_addon()
    return bpy.context.scene


def ball_scene():
    scene = _empty()
    _plane((0, 0, 0), (0, 0, 0), (4, 4, 1), _principled("Floor", (0.8, 0.8, 0.8),
                                                         Roughness=1.0), "Floor")
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(0, 0, 0.3), segments=64,
                                         ring_count=32)
    ball = bpy.context.object
    ball.name = "Ball"
    bpy.ops.object.shade_smooth()
    ball.data.materials.append(_principled("Glass", (1, 1, 1), Roughness=0.0, IOR=1.45,
                                           **{"Transmission Weight": 1.0}))
    light = bpy.data.lights.new("Area", "AREA")
    light.energy, light.size = 40.0, 0.1
    ob = bpy.data.objects.new("Area", light)
    scene.collection.objects.link(ob)
    ob.location = (0.25, -0.15, 1.6)
    _world(scene, 0.02)
    _camera(scene, (1.6, -1.6, 1.5), (-0.1, 0.1, 0.1), lens=40.0)
    return scene, 64, 48


def room_scene():
    scene = _empty()
    white = _principled("White", (0.7, 0.7, 0.7), Roughness=1.0)
    _plane((0, 0, 0), (0, 0, 0), (4, 4, 1), white, "Floor")
    _plane((0, 0, 2.5), (0, 0, 0), (4, 4, 1), white, "Ceiling")
    for k in (1, 2, 3):  # three whole walls
        a = k * math.pi / 2
        _plane((2.0 * math.cos(a), 2.0 * math.sin(a), 1.25), (0.0, math.pi / 2, a),
               (2.5, 4.0, 1.0), white, f"Wall{k}")
    # the window wall (x = 2) round a 1 x 1 m hole 0.9-1.9 m up, centred
    rot = (0.0, math.pi / 2, 0.0)
    _plane((2.0, 0, 0.45), rot, (0.9, 4.0, 1.0), white, "WallBelow")
    _plane((2.0, 0, 2.2), rot, (0.6, 4.0, 1.0), white, "WallAbove")
    for y in (1.25, -1.25):
        _plane((2.0, y, 1.4), rot, (1.0, 1.5, 1.0), white, "WallSide")
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy, sun.angle = 40.0, math.radians(0.526)
    ob = bpy.data.objects.new("Sun", sun)
    scene.collection.objects.link(ob)
    # shining in through the window (towards -x), 40 degrees down, a little sideways
    d = Vector((-math.cos(math.radians(40)), 0.25, -math.sin(math.radians(40)))).normalized()
    ob.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    _world(scene, 0.0)
    _camera(scene, (-1.7, -1.7, 1.6), (1.0, 0.6, 0.4), lens=18.0)
    return scene, 64, 48


def jewel_scene():
    import newuser52_jewellery as J
    from studio48_stilllife import write_hdr
    hdr = "/tmp/newuser52/display.hdr"
    os.makedirs(os.path.dirname(hdr), exist_ok=True)
    write_hdr(hdr, J.display_pixels())
    A.ensure_addon()
    scene = J.jewellery_scene(hdr)
    r = scene.render
    r.use_border, r.use_crop_to_border = True, False
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = BORDER
    return scene, 160, 120


def masks(scene, name, w, h):
    """{region: (H, W) bool}, row 0 at the top."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    out = {}
    hits = np.full((h, w), "", object)
    lit = np.zeros((h, w), bool)
    for j in range(h):
        for i in range(w):
            p = tl.lerp(tr, (i + 0.5) / w).lerp(bl.lerp(br, (i + 0.5) / w), (j + 0.5) / h)
            ok, x, n, _, ob, _ = scene.ray_cast(dg, origin, (p - origin).normalized())
            if not ok:
                continue
            hits[j, i] = ob.name
            x1 = x + n * 1e-4
            if name == "ball" and ob.name == "Floor":
                d = Vector((0.25, -0.15, 1.6)) - x1
                ok2, _, _, _, ob2, _ = scene.ray_cast(dg, x1, d.normalized(),
                                                      distance=d.length)
                lit[j, i] = not (ok2 and ob2.name == "Ball")
            elif name == "room":
                sun = scene.objects["Sun"]
                d = (sun.matrix_world.to_quaternion() @ Vector((0, 0, 1))).normalized()
                ok2 = scene.ray_cast(dg, x1, d)[0]
                lit[j, i] = not ok2
    if name == "ball":
        floor = hits == "Floor"
        out = {"caustic": floor & ~lit, "floor": floor & lit, "ball": hits == "Ball"}
    else:
        out = {"sunlit": lit & (hits != ""), "shade": (hits == "Floor") & ~lit,
               "walls": (hits != "Floor") & ~lit}
    out["image"] = np.ones((h, w), bool)
    return out


def jewel_masks(w, h):
    x0, x1, y0, y1 = BORDER
    ids = np.load("/tmp/newuser52/masks.npy")
    import json
    names = json.load(open("/tmp/newuser52/masks.npy.json"))
    region = np.zeros((h, w), bool)
    # (Blender's border rounding: engine region rows counted from the top)
    region[h - int(y1 * h):h - int(y0 * h), int(x0 * w):int(x1 * w)] = True
    out = {}
    for key in ("Plinth:PendantShadow", "Pendant", "Plinth"):
        out[key] = region & (ids == names.index(key))
    out["region"] = region
    return out, region


def lum(img):
    return np.asarray(img, np.float64)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def scene_regions(name):
    """(scene, regions) of one of main()'s scene choices, at its resolution."""
    if name.startswith("jewel"):
        scene, w, h = jewel_scene()
        scene.cycles.blur_glossy = float(name[-1])
        regions, _ = jewel_masks(w, h)
    else:
        scene, w, h = (ball_scene if name == "ball" else room_scene)()
        r = scene.render
        r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
        regions = masks(scene, name, w, h)
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    return scene, regions


def clamp_table(a, switch, cache_name, show_cpu=False):
    """Print the table: per Clamp Indirect in a.clamps, Cycles at a.cycles_spp (cached),
    then per seed ours with switch(False) and switch(True), as ratios to Cycles per
    region. cache_name(on, seed, clamp) names ours' cached render (the same name twice:
    one render)."""
    scene, regions = scene_regions(a.scene)
    seeds = [int(s) for s in a.seeds.split(",")]
    clamps = [float(c) for c in a.clamps.split(",")]
    r = scene.render
    print("pixels:", {k: int(v.sum()) for k, v in regions.items()}, flush=True)
    c = scene.cycles
    fg = c.blur_glossy
    c.sample_clamp_direct = 0.0
    names = list(regions)
    print(f"\n| {a.scene} | clamp | seed | " + " | ".join(names) + " |")
    print("|---|---:|---:|" + "---:|" * len(names))
    for clamp in clamps:
        c.sample_clamp_indirect = clamp
        r.engine = "CYCLES"
        c.device, c.samples, c.seed = "CPU", a.cycles_spp, 0
        c.use_denoising = c.use_adaptive_sampling = False
        ref, cpu = A.render_rgb_cached(
            scene, os.path.join(a.out, f"{a.scene}_c{a.cycles_spp}_clamp{clamp:g}.npy"))
        ref_m = [lum(ref)[m].mean() for m in regions.values()]
        print(f"| Cycles {a.cycles_spp} spp ({cpu:.0f} CPU s) | {clamp:g} | 0 | "
              + " | ".join(f"{v:.4f}" for v in ref_m) + " |", flush=True)
        r.engine = "PHOTONMAP"
        for seed in seeds:
            scene.photonmap.seed = seed
            row, cpus = [], []
            for on in (False, True):
                switch(on)
                img, cpu = A.render_rgb_cached(
                    scene, os.path.join(a.out, cache_name(on, seed, clamp)))
                row.append([lum(img)[m].mean() for m in regions.values()])
                cpus.append(cpu)
            label = f"ours before / after ({cpus[1]:.0f} CPU s)" if show_cpu \
                else "ours before / after"
            print(f"| {label} | {clamp:g} | {seed} | "
                  + " | ".join(f"{b / x:.3f} / {p / x:.3f}"
                               for b, p, x in zip(*row, ref_m)) + " |", flush=True)
    assert fg == c.blur_glossy


def parse(out, seeds, clamps, doc=__doc__):
    """main()'s arguments (doc: the calling script's docstring, for --help)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("scene", choices=("ball", "room", "jewel1", "jewel0"))
    ap.add_argument("--out", default=out)
    ap.add_argument("--cycles-spp", type=int, default=1024)
    ap.add_argument("--seeds", default=seeds)
    ap.add_argument("--clamps", default=clamps)
    a = ap.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
    os.makedirs(a.out, exist_ok=True)
    return a


def main():
    a = parse("/tmp/clampray53", "0,1", "10,1,0")
    import engine.integrator as I

    def switch(per_ray):
        I.CLAMP_PER_GATHER_RAY = per_ray

    # (unclamped, the switch changes nothing: one render)
    clamp_table(a, switch, lambda on, seed, clamp:
                f"{a.scene}_o{int(on or not clamp)}_s{seed}_clamp{clamp:g}.npy")


if __name__ == "__main__":
    main()
