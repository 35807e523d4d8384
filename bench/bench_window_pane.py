"""A new user's room lit by a sun (or the world: --world) through a single-plane Glass BSDF
window pane (issue 14, pane31 and paneworld32: engine/panelight.py), before / after
next-event estimation through the pane, against live Cycles.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_window_pane.py \
        [--res 160 120] [--cycles-spp 1024] [--spp 128] [--sun-angle 3] [--out DIR] \
        [--world none|color|hdri]

--world color: no sun, a white world of strength 1 (Background colour); hdri: no sun, a
small generated sky (example_blends/make_blends.sky_hdri's gradient, 64 x 32) with a
bright 3 x 3 texel patch (~17 degrees) outside the window, 30 degrees up, giving 2 W/m^2
face-on. Use a --out of its own per --world (the masks and the Cycles render are kept).

The room: 4 x 3 x 2.6 m of white plaster (Principled, roughness 0.8) built from boxes, a
1.2 x 1.0 m opening in the +Y wall closed by one plane of Glass BSDF (IOR 1.5, roughness
0), a sun outside at 40 degrees elevation with a small angle (Cycles finds a sun behind
glass only by path tracing through it: it needs an angle), a black world, a table box in the
sun patch and a grey cylinder in the shade; an 18 mm camera from the window's corner. Each render runs in
a child process of its own (its CPU seconds: all threads, getrusage; the scene build not
counted): Cycles (plain: no denoise, no adaptive, no clamp, seed 0, glossy blur 0, default
Light Paths, Blackman-Harris 1.5 px as ours), ours with panelight.ENABLED off ("before":
the pane's light from the caustic map) and on ("after"). The Cycles render is kept in
--out (default /tmp/bench_window_pane) and reused.

Prints per region (Blender's scene.ray_cast per pixel: floor in the sun patch / in shade,
walls, objects) ours / Cycles brightness, and the 10 x 10 pixel block ratios (blocks
where Cycles is above 5 % of its mean): median, 5th-95th percentiles and min-max.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402


def _cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime


def _hdri():
    """The --world hdri sky (64 x 32, top row first): make_blends' gradient without its
    one-texel sun, and a 3 x 3 texel bright patch (2 W/m^2 face-on in all) centred 30
    degrees above the horizon at azimuth 75 degrees (towards +Y: outside the window)."""
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends
    img = make_blends.sky_hdri(64, 32, sun_irradiance=0.0).astype(np.float64)
    H, W = img.shape[:2]
    i0 = int((90.0 - 30.0) / 180.0 * H) - 1
    j0 = int((0.5 - 75.0 / 360.0) % 1.0 * W) - 1
    th0, th1 = np.pi * i0 / H, np.pi * (i0 + 3) / H
    omega = (np.cos(th0) - np.cos(th1)) * 2 * np.pi / W * 3
    img[i0:i0 + 3, j0:j0 + 3] = 2.0 / omega * np.array([1.0, 0.93, 0.82])
    return img.astype(np.float32)


def build(sun_angle, world_kind="none"):
    import bpy
    from mathutils import Vector
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"

    def material(name, color, roughness=0.8, glass=False):
        m = bpy.data.materials.new(name)
        if bpy.app.version < (5, 0, 0):
            m.use_nodes = True
        nt = m.node_tree
        if glass:
            nt.nodes.remove(nt.nodes["Principled BSDF"])
            g = nt.nodes.new("ShaderNodeBsdfGlass")
            g.inputs["IOR"].default_value = 1.5
            g.inputs["Roughness"].default_value = 0.0
            g.inputs["Color"].default_value = (*color, 1.0)
            nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        else:
            p = nt.nodes["Principled BSDF"]
            p.inputs["Base Color"].default_value = (*color, 1.0)
            p.inputs["Roughness"].default_value = roughness
        return m

    def box(name, loc, scale, mat):
        bpy.ops.mesh.primitive_cube_add(size=1, location=loc, scale=scale)
        o = bpy.context.active_object
        o.name = name
        o.data.materials.append(mat)
        return o

    plaster = material("Plaster", (0.8, 0.8, 0.8))
    wood = material("Wood", (0.5, 0.35, 0.2), roughness=0.6)
    grey = material("Grey", (0.4, 0.45, 0.5), roughness=0.5)
    pane = material("WindowGlass", (1.0, 1.0, 1.0), glass=True)
    box("Floor", (0, 0, -0.05), (4.2, 3.2, 0.1), plaster)
    box("Ceiling", (0, 0, 2.65), (4.2, 3.2, 0.1), plaster)
    box("LeftWall", (-2.05, 0, 1.3), (0.1, 3.2, 2.6), plaster)
    box("RightWall", (2.05, 0, 1.3), (0.1, 3.2, 2.6), plaster)
    box("FrontWall", (0, -1.55, 1.3), (4.0, 0.1, 2.6), plaster)
    # +Y wall around the window (x -0.6..0.6, z 0.9..1.9).
    box("BackWall_low", (0, 1.55, 0.45), (4.0, 0.1, 0.9), plaster)
    box("BackWall_high", (0, 1.55, 2.25), (4.0, 0.1, 0.7), plaster)
    box("BackWall_left", (-1.3, 1.55, 1.4), (1.4, 0.1, 1.0), plaster)
    box("BackWall_right", (1.3, 1.55, 1.4), (1.4, 0.1, 1.0), plaster)
    # The plane's normal faces out (+Y): the sun's light enters the glass side (the room).
    # Turned the other way (rotation +90 degrees, normal into the room) the light would
    # leave glass into air at 44 degrees, past the critical angle: Cycles and ours both
    # reflect it all (a dark room).
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0.0, 1.55, 1.4),
                                     rotation=(-math.pi / 2, 0, 0))
    w = bpy.context.active_object
    w.name = "WindowPane"
    w.scale = (1.2, 1.0, 1)
    w.data.materials.append(pane)
    box("Table", (0.5, -1.0, 0.35), (0.8, 0.6, 0.7), wood)
    bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.2, depth=0.8,
                                        location=(-1.1, 0.1, 0.4))
    c = bpy.context.active_object
    c.name = "Cylinder"
    c.data.materials.append(grey)
    # Sun outside (+Y), 40 degrees above the horizon, a little from the side.
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 4.0
    sun.data.angle = math.radians(sun_angle)
    el, az = math.radians(40.0), math.radians(20.0)
    travel = Vector((-math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el),
                     -math.sin(el)))
    sun.rotation_euler = travel.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("World")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = 0.0
    if world_kind != "none":
        # World-lit: no sun; the world (colour or HDRI) through the window alone.
        bpy.data.objects.remove(sun)
        sys.path.insert(0, os.path.join(ROOT, "example_blends"))
        import make_blends
        if world_kind == "color":
            make_blends.set_world((1.0, 1.0, 1.0), 1.0)
        else:
            make_blends.set_world_hdri(_hdri(), 1.0)
    # From the window's corner, looking into the room: the sun patch on the floor and
    # the front wall, the table in it, the cylinder in the shade.
    bpy.ops.object.camera_add(location=(1.8, 1.3, 2.0))
    cam = bpy.context.active_object
    cam.data.lens = 18.0
    cam.rotation_euler = Vector((-2.0, -2.4, -1.3)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    return scene


def masks(scene, w, h):
    """(H, W) object names' ids per pixel centre (row 0 at the top), the names, and (H, W)
    bool: the point is in the sun patch (a ray from it back along the sun's central
    direction refracted by the pane meets the pane first)."""
    import bpy
    from mathutils import Vector
    dg = bpy.context.evaluated_depsgraph_get()
    sun = bpy.data.objects.get("Sun")
    travel = (sun.matrix_world.to_3x3() @ Vector((0, 0, -1))).normalized() if sun else \
        Vector((0.0, -0.6, -0.8))  # (no sun: its patch is not read)
    pane = bpy.data.objects["WindowPane"]
    n = (pane.matrix_world.to_3x3() @ Vector((0, 0, 1))).normalized()
    ci = -travel.dot(n)
    eta = 1.0 / 1.5 if ci > 0 else 1.5
    ns = n if ci > 0 else -n
    ci = abs(ci)
    ct = math.sqrt(max(1.0 - eta * eta * (1.0 - ci * ci), 0.0))
    back = -(eta * travel + (eta * ci - ct) * ns)  # towards the pane from the room
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    names, ids = [], -np.ones((h, w), np.int32)
    pts = np.zeros((h, w, 3))
    lit = np.zeros((h, w), bool)
    for j in range(h):
        for i in range(w):
            u, v = (i + 0.5) / w, (j + 0.5) / h
            p = tl.lerp(tr, u).lerp(bl.lerp(br, u), v)
            hit, loc, _, _, ob, _ = scene.ray_cast(dg, origin, (p - origin).normalized())
            if hit:
                if ob.name not in names:
                    names.append(ob.name)
                ids[j, i] = names.index(ob.name)
                pts[j, i] = tuple(loc)
                h2, _, _, _, ob2, _ = scene.ray_cast(dg, loc + 1e-4 * back, back)
                lit[j, i] = bool(h2) and ob2.name == "WindowPane"
    return ids, names, pts, lit


def child(a):
    import bpy
    import addon
    addon.register()
    scene = build(a.sun_angle, a.world)
    r = scene.render
    r.resolution_x, r.resolution_y = a.res
    r.resolution_percentage = 100
    if a.child == "masks":
        ids, names, pts, lit = masks(scene, *a.res)
        np.save(os.path.join(a.out, "masks.npy"), ids)
        np.save(os.path.join(a.out, "points.npy"), pts)
        np.save(os.path.join(a.out, "lit.npy"), lit)
        with open(os.path.join(a.out, "masks.json"), "w") as f:
            json.dump(names, f)
        return
    # Cycles' settings that change its image, for both engines (ours reads Light Paths
    # and Clamping from them): clamping off, no glossy blur, default bounces.
    c = scene.cycles
    c.device, c.samples, c.seed = "CPU", a.cycles_spp, 0
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    r.filter_size = 1.5
    if a.child.startswith("cycles"):
        r.engine = "CYCLES"
        c.samples = int(a.child[len("cycles"):])
    else:
        from engine import panelight
        panelight.ENABLED = a.child == "after"
        r.engine = "PHOTONMAP"
        scene.photonmap.spp = a.spp
    s = r.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_depth = "OPEN_EXR", "32"
    path = os.path.join(a.out, a.child + ".exr")
    r.filepath, r.use_file_extension = path, False
    t0 = _cpu()
    bpy.ops.render.render(write_still=True)
    t = _cpu() - t0
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], np.float32).reshape(img.size[1], img.size[0], 4)[::-1, :, :3]
    np.save(os.path.join(a.out, a.child + ".npy"), px)
    print(f"RESULT {a.child} cpu_s={t:.1f}", flush=True)


def run(a, what):
    cmd = [sys.executable, os.path.abspath(__file__), "--child", what, "--out", a.out,
           "--res", str(a.res[0]), str(a.res[1]), "--spp", str(a.spp),
           "--cycles-spp", str(a.cycles_spp), "--sun-angle", str(a.sun_angle),
           "--world", a.world]
    out = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
    line = [x for x in out.stdout.splitlines() if x.startswith("RESULT")]
    if what != "masks" and not line:
        sys.stderr.write(out.stdout[-3000:] + out.stderr[-3000:])
        raise SystemExit(f"{what} failed")
    return float(line[0].split("cpu_s=")[1]) if line else 0.0


def blocks(img, b=10):
    h, w = img.shape[:2]
    return img[:h // b * b, :w // b * b].reshape(h // b, b, w // b, b).mean(axis=(1, 3))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, nargs=2, default=(160, 120))
    ap.add_argument("--cycles-spp", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--sun-angle", type=float, default=3.0)
    ap.add_argument("--out", default="/tmp/bench_window_pane")
    ap.add_argument("--cycles-equal", type=int, default=256,
                    help="Cycles at about ours' CPU time: its block ratios against the "
                    "reference too (0: none)")
    ap.add_argument("--world", default="none", choices=("none", "color", "hdri"),
                    help="light the room by the world through the window instead of a sun")
    ap.add_argument("--child")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    if a.child:
        return child(a)
    ref_path = os.path.join(a.out, f"cycles{a.cycles_spp}.npy")
    cyc_name = f"cycles{a.cycles_spp}"
    times = {}
    if not os.path.exists(ref_path):
        times[cyc_name] = run(a, cyc_name)
    if not os.path.exists(os.path.join(a.out, "lit.npy")):
        run(a, "masks")
    runs = ["before", "after"]
    if a.cycles_equal:
        runs.append(f"cycles{a.cycles_equal}")
    for what in runs:
        times[what] = run(a, what)
    ref = np.load(ref_path).astype(np.float64).mean(axis=2)
    ids = np.load(os.path.join(a.out, "masks.npy"))
    lit = np.load(os.path.join(a.out, "lit.npy"))
    names = json.load(open(os.path.join(a.out, "masks.json")))
    nid = {n: i for i, n in enumerate(names)}
    floor = ids == nid.get("Floor", -9)
    if a.world == "none":
        print(f"sun patch: {int((floor & lit).sum())} floor pixels")
    walls = np.isin(ids, [i for n, i in nid.items() if "Wall" in n or n == "Ceiling"])
    objects = np.isin(ids, [nid.get("Table", -9), nid.get("Cylinder", -9)])
    regions = {"floor, sun patch": floor & lit, "floor, shade": floor & ~lit,
               "table top in sun": objects & lit, "objects in shade": objects & ~lit,
               "walls + ceiling": walls, "whole image": np.ones_like(floor)}
    if a.world != "none":
        lit = np.zeros_like(lit)  # no sun patch: the world through the window
        regions = {"floor": floor, "objects": objects, "walls + ceiling": walls,
                   "whole image": np.ones_like(floor)}
    light = (f"sun 40 deg elevation, angle {a.sun_angle} deg" if a.world == "none" else
             {"color": "white world of strength 1",
              "hdri": "64x32 sky, 17-degree bright patch 30 deg up"}[a.world])
    print(f"room {a.res[0]}x{a.res[1]}, {light}; "
          f"ours {a.spp} spp (add-on defaults otherwise), Cycles {a.cycles_spp} spp"
          + (f" ({times[cyc_name]:.0f} CPU s)" if cyc_name in times else " (kept)"))
    print(f"{'region':20s} {'pixels':>6s} " + " ".join(f"{w:>10s}" for w in runs)
          + "   (/ Cycles reference)")
    imgs = {w: np.load(os.path.join(a.out, w + ".npy")).astype(np.float64).mean(axis=2)
            for w in runs}
    for name, m in regions.items():
        if not m.any():
            continue
        row = [imgs[w][m].mean() / max(ref[m].mean(), 1e-12) for w in runs]
        print(f"{name:20s} {int(m.sum()):6d} " + " ".join(f"{x:10.3f}" for x in row))
    rb = blocks(ref)
    ok = rb > 0.05 * ref.mean()
    print(f"10x10 block ratios / Cycles reference ({int(ok.sum())} blocks): "
          "median, p5-p95, min-max; the sun patch's blocks (half or more of the block lit)")
    patch = blocks(lit.astype(np.float64)) >= 0.5
    for w in runs:
        q = blocks(imgs[w])[ok] / rb[ok]
        print(f"  {w:6s} {np.median(q):.3f}  {np.percentile(q, 5):.3f}-"
              f"{np.percentile(q, 95):.3f}  {q.min():.3f}-{q.max():.3f}   "
              f"CPU {times[w]:.0f} s")
        if patch.any():
            q = blocks(imgs[w])[patch] / rb[patch]
            # Cycles-free: the lit floor's 2x2-pixel block means' relative spread (the
            # patch is evenly lit: its variation is noise and blotches).
            # (pixels whose 8 neighbours are lit floor too: not the sun's penumbra)
            inner = floor & lit
            inner[1:-1, 1:-1] &= np.all([np.roll(np.roll(floor & lit, dy, 0), dx, 1)
                                         [1:-1, 1:-1] for dy in (-1, 0, 1)
                                         for dx in (-1, 0, 1)], axis=0)
            inner[[0, -1], :] = False
            inner[:, [0, -1]] = False
            fl = imgs[w][inner]
            spread = fl.std() / fl.mean() if inner.any() else float("nan")
            print(f"         patch ({int(patch.sum())} blocks): {q.min():.3f}-{q.max():.3f};"
                  f" lit floor's inner {int(inner.sum())} pixels: std / mean {spread:.3f}")


if __name__ == "__main__":
    main()
