"""vase45: newuser45's brushed-metal vase reduced to one object and one light, rendered
by ours and by Cycles in one process; prints the mean luminance ratio ours / Cycles over
the vase's pixels (all, and those Cycles reads bright / dim).

    PYTHONPATH=. .venv/bin/python bench/vase45_metal.py LIGHT [--flat] [--rough R]
        [--aniso A] [--spp N] [--cycles-spp N] [--res W H] [--shape vase|sphere]
        [--cycles-seed S] [--set NAME=VALUE] [--keep DIR] [--room] [--lift M] [--wall-spec S]
        [--high | --top] [--spot-radius R] [--terminator T] [--scale K] [--metallic M]
        [--diffuse-bounces N] [--filter-glossy F] [--no-reflective-caustics]

LIGHT: point (60 W, radius 0.1 m) | point0 (radius 0) | spot (150 W, 50 deg, blend 0.3,
radius 0.05) | mesh (an emissive quad, strength 4) | world (a uniform World colour 0.5)
| sun. --room: a diffuse 8 x 8 x 4 m box round it (walls 0.8). The object: newuser45's lathed vase profile scaled x4 (6 rings, 32 steps,
Shade Smooth unless --flat), Principled Metallic 1, base (0.9, 0.88, 0.85), or a
UV sphere (16 x 8). World black unless LIGHT is world. Cycles: no denoise, no adaptive
sampling, clamp off (both engines), seed 0. The Light Paths options set scene.cycles,
which both engines read. Findings and commands: docs/accuracy.md "vase45".
"""
from __future__ import annotations

import argparse
import ast
import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import (assign, camera, cpu, empty_scene, new_material,  # noqa: E402
                              object_masks, principled, world_colour)
from newuser44_table import lathe  # noqa: E402
from newuser26_compare import read_exr  # noqa: E402
from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402

PROFILE = [(0.05, 0.0), (0.08, 0.05), (0.09, 0.12), (0.06, 0.22), (0.04, 0.28),
           (0.05, 0.32)]


def build(a):
    scene = empty_scene()
    metal = principled("Metal", (0.9, 0.88, 0.85), a.rough, metallic=a.metallic,
                       Anisotropic=a.aniso)
    if a.shape == "vase":
        obj = lathe("Vase", [(a.scale * r, a.scale * z) for r, z in PROFILE], metal,
                    (0, 0, -0.16 * a.scale + a.lift))
    else:
        primitive_uv_sphere_add(segments=16, ring_count=8, radius=0.5)
        obj = bpy.context.active_object
        obj.name = "Vase"
        bpy.ops.object.shade_smooth()
        assign(obj, metal)
    if a.terminator is not None:  # Object > Shading > Shadow Terminator > Geometry Offset
        obj.shadow_terminator_geometry_offset = a.terminator
    if a.flat:
        for p in obj.data.polygons:
            p.use_smooth = False
    world_colour(scene, (0.5, 0.5, 0.5) if a.light == "world" else (0, 0, 0), 1.0)
    if a.room:  # a diffuse room round it (floor at the vase's foot): reflections of walls
        bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 1.36), scale=(8, 8, 4))
        bpy.context.active_object.name = "Cube"
        assign(bpy.context.active_object, principled("Wall", (0.8, 0.78, 0.74), 0.8,
                                                              Specular_IOR_Level=a.wall_spec))
    if a.light in ("point", "point0"):
        bpy.ops.object.light_add(type="POINT", location=(-1.5, -1.2, 0.8))
        lt = bpy.context.active_object
        lt.data.energy = 60.0
        lt.data.shadow_soft_size = 0.1 if a.light == "point" else 0.0
    elif a.light == "spot":
        bpy.ops.object.light_add(type="SPOT", location=(-0.3, -0.4, 2.0) if a.high or a.top
                                 else (-0.8, -1.0, 2.0))
        lt = bpy.context.active_object
        lt.data.energy = 150.0
        lt.data.spot_size = math.radians(50)
        lt.data.spot_blend = 0.3
        lt.data.shadow_soft_size = 0.05 if a.spot_radius is None else a.spot_radius
        lt.rotation_euler = (Vector((0, 0, 0)) - lt.location).to_track_quat(
            "-Z", "Y").to_euler()
    elif a.light == "sun":
        bpy.ops.object.light_add(type="SUN", location=(0, 0, 3))
        lt = bpy.context.active_object
        lt.data.energy = 3.0
        lt.data.angle = math.radians(5)
        lt.rotation_euler = Vector((1.5, 1.2, -0.8)).to_track_quat("-Z", "Y").to_euler()
    elif a.light == "mesh":
        m = new_material("Glow")
        nt = m.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        e = nt.nodes.new("ShaderNodeEmission")
        e.inputs["Strength"].default_value = 4.0
        nt.links.new(e.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        bpy.ops.mesh.primitive_plane_add(size=0.6, location=(-1.5, -1.2, 0.8))
        q = bpy.context.active_object
        q.rotation_euler = (Vector((0, 0, 0)) - q.location).to_track_quat(
            "Z", "Y").to_euler()
        assign(q, m)
    if a.top:  # straight down onto the cap: no pixel views its leaning normals from below
        camera((0.0, -0.05, 3.5), (0.0, 0.0, 0.0), lens=50.0)
    elif a.high:  # from above, as newuser45's camera sees the vase's top (its cap, lip)
        camera((0.0, -2.6, 2.2), (0.0, 0.0, 0.1), lens=50.0)
    else:
        camera((0.0, -3.2, 0.3), (0.0, 0.0, 0.0), lens=50.0)
    c = scene.cycles
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    if a.filter_glossy is not None:  # Light Paths > Filter Glossy, read by both
        c.blur_glossy = a.filter_glossy
    if a.no_reflective_caustics:  # Light Paths > Caustics > Reflective, read by both
        c.caustics_reflective = False
    if a.diffuse_bounces is not None:  # Light Paths > Diffuse, read by both engines
        c.diffuse_bounces = a.diffuse_bounces
    return scene


def render(scene, engine, out, a):
    r = scene.render
    r.resolution_x, r.resolution_y = a.res
    r.resolution_percentage = 100
    r.engine = engine
    if engine == "CYCLES":
        c = scene.cycles
        c.device, c.samples, c.seed = "CPU", a.cycles_spp, getattr(a, "cycles_seed", 0)
        c.use_denoising = c.use_adaptive_sampling = False
    else:
        scene.photonmap.spp = a.spp
        for k, v in (s.split("=", 1) for s in a.set):
            setattr(scene.photonmap, k, ast.literal_eval(v))
    fmt = r.image_settings
    fmt.media_type = "IMAGE"
    fmt.file_format, fmt.color_depth = "OPEN_EXR", "32"
    r.filepath, r.use_file_extension = out, False
    t0 = cpu()
    bpy.ops.render.render(write_still=True)
    return read_exr(out)[..., :3], cpu() - t0


def lum(x):
    return x @ np.array([0.2126, 0.7152, 0.0722])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("light", choices=("point", "point0", "spot", "mesh", "world", "sun"))
    ap.add_argument("--flat", action="store_true")
    ap.add_argument("--rough", type=float, default=0.25)
    ap.add_argument("--aniso", type=float, default=0.0)
    ap.add_argument("--metallic", type=float, default=1.0)
    ap.add_argument("--diffuse-bounces", type=int)
    ap.add_argument("--no-reflective-caustics", action="store_true")
    ap.add_argument("--filter-glossy", type=float)
    ap.add_argument("--wall-spec", type=float, default=0.5,
                    help="the room's Principled Specular IOR Level (0: diffuse only)")
    ap.add_argument("--scale", type=float, default=4.0,
                    help="the vase's size over newuser45's (1: its 0.32 m, ~90 pixels)")
    ap.add_argument("--terminator", type=float,
                    help="the object's Shadow Terminator Geometry Offset (Blender's 0.1)")
    ap.add_argument("--spot-radius", type=float, help="the Spot's radius (0.05 m)")
    ap.add_argument("--top", action="store_true", help="camera straight above, spot as --high")
    ap.add_argument("--high", action="store_true",
                    help="camera and spot from above (the vase's top cap and lip in view)")
    ap.add_argument("--lift", type=float, default=0.0, help="the vase's foot above the floor (m)")
    ap.add_argument("--shape", default="vase", choices=("vase", "sphere"))
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--cycles-spp", type=int, default=512)
    ap.add_argument("--cycles-seed", type=int, default=0)
    ap.add_argument("--res", type=int, nargs=2, default=(64, 96))
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--keep")
    ap.add_argument("--room", action="store_true", help="a diffuse room round the object")
    a = ap.parse_args()
    import addon
    addon.register()
    scene = build(a)
    d = a.keep or tempfile.mkdtemp(prefix="vase45_")
    os.makedirs(d, exist_ok=True)
    ids, names = object_masks(scene, *a.res)
    mask = ids == names.index("Vase")
    ref, tc = render(scene, "CYCLES", os.path.join(d, "cycles.exr"), a)
    ours, to = render(scene, "PHOTONMAP", os.path.join(d, "ours.exr"), a)
    lr, lo = lum(ref)[mask], lum(ours)[mask]
    hi = lr > np.percentile(lr, 85)
    tag = (f"{a.shape}{' room' if a.room else ''} {a.light} {'flat' if a.flat else 'smooth'} rough={a.rough} "
           f"aniso={a.aniso}{' high' if a.high else ''}{' top' if a.top else ''} spot_radius={a.spot_radius} terminator={a.terminator} scale={a.scale} lift={a.lift} wall_spec={a.wall_spec} metallic={a.metallic} diffuse_bounces={a.diffuse_bounces}"
           f"{' no-reflective-caustics' if a.no_reflective_caustics else ''} {a.set}"
           f" filter_glossy={a.filter_glossy}")
    print(f"VASE45 {tag}: all {lo.sum() / lr.sum():.4f}  bright15% "
          f"{lo[hi].sum() / lr[hi].sum():.4f}  rest {lo[~hi].sum() / lr[~hi].sum():.4f}"
          f"  px={mask.sum()} cyc_mean={lr.mean():.4g} cpu cycles={tc:.0f}s ours={to:.0f}s",
          flush=True)
    rows = np.nonzero(mask.any(axis=1))[0]
    cut = np.zeros_like(mask)
    cut[rows[0] + 3 * len(rows) // 4:] = True  # the lowest quarter of the vase's rows
    top = np.zeros_like(mask)
    top[:rows[0] + len(rows) // 4] = True  # the highest quarter: the lip and the cap
    for name, m in (("foot quarter", mask & cut), ("upper 3/4", mask & ~cut),
                    ("top quarter", mask & top)):
        print(f"VASE45 {name}: {lum(ours)[m].sum() / lum(ref)[m].sum():.4f} px={m.sum()}",
              flush=True)
    if "Cube" in names:  # the room's walls seen directly
        w = ids == names.index("Cube")
        cols = np.nonzero(mask.any(axis=0))[0]
        near = np.zeros_like(mask)  # beside the foot: the floor at the foot's image rows
        near[rows[0] + 3 * len(rows) // 4:rows[-1] + 1,
             max(cols[0] - 8, 0):cols[-1] + 9] = True
        m = w & near
        print(f"VASE45 floor beside the foot: {lum(ours)[m].sum() / lum(ref)[m].sum():.4f}"
              f" px={m.sum()}", flush=True)
        print(f"VASE45 walls: {lum(ours)[w].sum() / lum(ref)[w].sum():.4f} px={w.sum()}",
              flush=True)


if __name__ == "__main__":
    main()
