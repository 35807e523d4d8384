"""A large outdoor scene as a new user builds it (issues 13/14): its render's CPU time and
peak memory through the add-on's batch renderer, at the add-on's default settings.

    NUMBA_CACHE_DIR=... .venv/bin/python bench/bench_outdoor_scale.py \
        [--res 80x60 160x120] [--blend /tmp/x/outdoor.blend] [--out /tmp/x] [--label L]

The scene, built with bpy (saved to --blend, then rendered by `python -m addon.batch` in a
child process, one render at a time): a 200 m ground plane; a lake (a 30 m water plane,
Glass BSDF IOR 1.33, 0.3 m over a sand bottom); 300 linked duplicates (one ico sphere
mesh for the rocks, one cone mesh for the trees) with random rotation (seeded) and scale,
so that their triangles have many orientations; a Sun and a sky-coloured world.

Prints a table: resolution, CPU s of the render's process (user + system, its
resource.getrusage via os.wait4: Blender's load and the scene's export included), its
peak RSS (ru_maxrss) and a hash of the image's pixels (a change that must keep the film
keeps the hash).
"""
from __future__ import annotations

import argparse
import hashlib
import math
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def build(path: str, seed: int = 0, count: int = 300):
    """Build the scene with bpy and save it to path (.blend)."""
    import bpy
    from mathutils import Vector

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    rng = np.random.default_rng(seed)

    def principled(name, color, roughness=0.6):
        m = bpy.data.materials.new(name)
        if bpy.app.version < (5, 0, 0):
            m.use_nodes = True
        p = m.node_tree.nodes["Principled BSDF"]
        p.inputs["Base Color"].default_value = (*color, 1.0)
        p.inputs["Roughness"].default_value = roughness
        return m

    def water():
        m = bpy.data.materials.new("Water")
        if bpy.app.version < (5, 0, 0):
            m.use_nodes = True
        nt = m.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        g = nt.nodes.new("ShaderNodeBsdfGlass")
        g.inputs["IOR"].default_value = 1.33
        g.inputs["Roughness"].default_value = 0.0
        g.inputs["Color"].default_value = (0.8, 0.9, 0.95, 1.0)
        nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        return m

    def plane(name, size, loc, mat):
        bpy.ops.mesh.primitive_plane_add(size=size, location=loc)
        o = bpy.context.active_object
        o.name = name
        o.data.materials.append(mat)
        return o

    plane("Ground", 200, (0, 0, 0), principled("Grass", (0.15, 0.35, 0.1)))
    plane("LakeBottom", 30, (-20, 10, 0.02), principled("Sand", (0.5, 0.45, 0.3)))
    plane("Water", 30, (-20, 10, 0.3), water())

    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4, radius=1.0)
    rock = bpy.context.active_object
    rock.name = "Rock"
    rock.data.materials.append(principled("Stone", (0.4, 0.4, 0.38), 0.8))
    bpy.ops.mesh.primitive_cone_add(vertices=32, radius1=1.0, depth=3.0)
    tree = bpy.context.active_object
    tree.name = "Tree"
    tree.data.materials.append(principled("Leaves", (0.05, 0.25, 0.05)))
    for i in range(count):
        src = rock if i % 2 else tree
        o = bpy.data.objects.new(f"{src.name}.{i:03d}", src.data)  # a linked duplicate
        scene.collection.objects.link(o)
        while True:
            x, y = rng.uniform(-90, 90, 2)
            if not (-36 < x < -4 and -6 < y < 26):  # not in the lake
                break
        s = rng.uniform(0.4, 2.0)
        o.location = (x, y, (0.3 if src is rock else 1.5) * s)
        o.rotation_euler = tuple(rng.uniform(0, 2 * math.pi, 3))
        o.scale = (s * rng.uniform(0.7, 1.3), s * rng.uniform(0.7, 1.3), s)
    rock.location, tree.location = (5, -20, 0.5), (-5, -15, 1.5)

    bpy.ops.object.light_add(type="SUN", location=(0, 0, 50))
    sun = bpy.context.active_object
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40), 0, math.radians(30))
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.45, 0.6, 0.9, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0

    bpy.ops.object.camera_add(location=(0, -70, 12))
    cam = bpy.context.active_object
    cam.rotation_euler = Vector((0 - 0, 10 - -70, 0 - 12)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    bpy.ops.wm.save_as_mainfile(filepath=path)


def render(blend, out, w, h):
    """(CPU s, peak RSS bytes, pixel hash) of `python -m addon.batch` rendering blend."""
    cmd = [sys.executable, "-m", "addon.batch", blend, "-o", out, "--width", str(w),
           "--height", str(h), "--quiet"]
    t0 = time.time()
    proc = subprocess.Popen(cmd, cwd=ROOT)
    _, status, ru = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"render failed ({proc.returncode}): {' '.join(cmd)}")
    return ru.ru_utime + ru.ru_stime, ru.ru_maxrss * 1024, time.time() - t0, _pixels(out)


def _pixels(path):
    """A hash of the image's pixels (the OpenEXR's bytes after its header would do, but
    the file's header holds a date: hash the decoded float pixels)."""
    import bpy
    img = bpy.data.images.load(path)
    try:
        px = np.empty(img.size[0] * img.size[1] * img.channels, np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return hashlib.sha256(px.tobytes()).hexdigest()[:12]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", nargs="+", default=["80x60", "160x120"])
    ap.add_argument("--blend", default="/tmp/scale/outdoor.blend")
    ap.add_argument("--out", default="/tmp/scale")
    ap.add_argument("--label", default="")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    if not os.path.exists(a.blend):
        build(a.blend)
    rows = []
    for res in a.res:
        w, h = (int(v) for v in res.split("x"))
        out = os.path.join(a.out, f"outdoor{a.label}_{w}x{h}.exr")
        cpu, rss, wall, digest = render(a.blend, out, w, h)
        rows.append((res, cpu, rss, wall, digest))
        print(f"RESULT {a.label or '-'} {res} cpu_s={cpu:.1f} maxrss_MB={rss / 2**20:.0f} "
              f"wall_s={wall:.1f} pixels={digest}", flush=True)
    print(f"\n{'label':>10} {'res':>8} {'CPU s':>8} {'peak RSS MB':>12} {'wall s':>8} pixels")
    for res, cpu, rss, wall, digest in rows:
        print(f"{a.label or '-':>10} {res:>8} {cpu:8.1f} {rss / 2**20:12.0f} {wall:8.1f} "
              f"{digest}")


if __name__ == "__main__":
    main()
