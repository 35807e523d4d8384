"""Hair speed against Cycles: a groom's render time, rays and brightness, before / after
(docs/performance.md, hair39).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_hair.py [--base OTHER_CHECKOUT]
        [--spp 128] [--cycles-spp 256] [--workers 2] [--strands 3000] [--repeat 1]

The scene is newuser38's (session 38's new-user trial): a Curves object of `--strands`
strands (4 keys, radius 8 -> 3 mm, a Principled BSDF of brown base colour, roughness
0.4) sprouting from a 0.8 m skin-coloured sphere over a grey floor, a sun of strength 3,
a world of 0.05 grey, 160 x 120, the add-on's default settings but `--spp`. One child
Blender (bpy) process builds it, renders it with Cycles at `--cycles-spp` (no denoising,
no adaptive sampling: the time Cycles takes on this machine) and exports the engine's
scene through the add-on into $TMPDIR/bench_hair/ (kept: delete the folder after
changing the export). Each checkout then renders the exported scene in a child process
of its own (its own kernel cache), counting the rays it hands Embree (engine/accel.py's
Accel calls) by kind.

Columns: wall and CPU seconds of the render (engine.render.render, kernels cached),
rays per camera sample, rays per CPU second (all rays over the render's CPU time: the
engine's rate against Embree's ~2.3-2.7 M/s on 1M triangles, docs/design.md, Embree
(embreex) facts), our wall time over Cycles', whole-image luminance over Cycles', the
10 x 10-pixel blocks' mean |ours / Cycles - 1| (block error), and the film's SHA-1 (same
for the same image).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

BUILD = r"""
import json, math, pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
import bpy
import addon
addon.register()
from addon import export
from addon.core import load_engine
from tools.canonical_mesh import primitive_uv_sphere_add

bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene
sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 160, 120, 100
world = bpy.data.worlds.new("World"); sc.world = world
bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1)

def mat(name, col, rough):
    m = bpy.data.materials.new(name)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*col, 1); p.inputs["Roughness"].default_value = rough
    return m

def mesh(name, kind, loc, size, m):
    if kind == "plane":
        bpy.ops.mesh.primitive_plane_add(size=size, location=loc)
    else:
        primitive_uv_sphere_add(radius=size, location=loc, segments=32, ring_count=16)
    o = bpy.context.active_object; o.name = name
    if kind == "sphere":
        bpy.ops.object.shade_smooth()
    o.data.materials.append(m)

cam = bpy.data.cameras.new("Camera"); cam.lens = 18 / math.tan(math.radians(40) / 2)
co = bpy.data.objects.new("Camera", cam)
sc.collection.objects.link(co); sc.camera = co
from mathutils import Vector
co.location = (0, -4.5, 1.6)
co.rotation_euler = (Vector((0, 0, 1.0)) - co.location).to_track_quat("-Z", "Y").to_euler()
mesh("Floor", "plane", (0, 0, 0), 12, mat("Grey", (0.6, 0.6, 0.6), 0.6))
mesh("Head", "sphere", (0, 0, 1.0), 0.8, mat("Skin", (0.7, 0.5, 0.4), 0.5))
rng = np.random.default_rng(1); n, keys = STRANDS, 4
d = rng.normal(size=(n, 3)); d /= np.linalg.norm(d, axis=1, keepdims=True)
s = np.linspace(0, 1, keys)
pos = (np.array([0, 0, 1.0]) + d[:, None] * (0.8 + 0.35 * s[None, :, None])
       + np.array([0, 0, -0.15]) * (s * s)[None, :, None])
c = bpy.data.hair_curves.new("Hair"); c.add_curves([keys] * n)
c.position_data.foreach_set("vector", pos.reshape(-1).astype(np.float32))
r = c.attributes.new("radius", "FLOAT", "POINT")
r.data.foreach_set("value", np.tile(np.linspace(0.008, 0.003, keys), n).astype(np.float32))
c.materials.append(mat("HairMat", (0.5, 0.3, 0.1), 0.4))
o = bpy.data.objects.new("Hair", c); sc.collection.objects.link(o)
sun = bpy.data.lights.new("Sun", "SUN"); sun.energy = 3.0
so = bpy.data.objects.new("Sun", sun); so.location = (0, 0, 5)
so.rotation_euler = (math.radians(40), 0, math.radians(30)); sc.collection.objects.link(so)

sc.render.engine = "CYCLES"
cy = sc.cycles; cy.device = "CPU"; cy.samples = CYCLES_SPP
cy.use_denoising = False; cy.use_adaptive_sampling = False
im = sc.render.image_settings
if hasattr(im, "media_type"):
    im.media_type = "IMAGE"
im.file_format = "OPEN_EXR"; im.color_depth = "32"
sc.render.filepath = OUT + "/cycles.exr"; sc.render.use_file_extension = False
t = time.time(); bpy.ops.render.render(write_still=True); cycles_s = time.time() - t
sc.render.engine = "PHOTONMAP"
dg = bpy.context.evaluated_depsgraph_get()
scene, _ = export.export_scene(load_engine(), dg, width=160, height=120)
kw = sc.photonmap.to_settings_kwargs(sc.render.film_transparent)
with open(OUT + "/hair.pkl", "wb") as f:
    pickle.dump((scene, kw), f)
from engine.imageio import read_image
np.save(OUT + "/cycles.npy", read_image(OUT + "/cycles.exr")[..., :3].astype(np.float64))
print(json.dumps({"cycles_s": cycles_s, "triangles": int(len(scene.faces))
                  if hasattr(scene, "faces") else 0}))
"""

RENDER = r"""
import collections, hashlib, json, os, pickle, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine import accel
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
ensure_compiled()
scene, kw = pickle.load(open(OUT + "/hair.pkl", "rb"))
rays = collections.Counter()

def counted(name):
    f = getattr(accel.Accel, name)
    def call(self, origins, *a, **k):
        rays[name] += len(origins)
        return f(self, origins, *a, **k)
    setattr(accel.Accel, name, call)

for name in ("intersect", "intersect_hits", "occluded", "occluded_into"):
    if hasattr(accel.Accel, name):
        counted(name)
settings = RenderSettings(**dict(kw, spp=SPP, workers=WORKERS))
c0, t0 = os.times(), time.perf_counter()
film = render(scene, settings)
wall, c1 = time.perf_counter() - t0, os.times()
h = hashlib.sha1()
for k in ("direct", "indirect", "caustic", "specular", "emission"):
    h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
np.save(IMAGE, np.asarray(film.combined)[..., :3].astype(np.float64))
print(json.dumps(dict(wall=wall, cpu=(c1.user + c1.system) - (c0.user + c0.system),
                      rays=dict(rays), hash=h.hexdigest()[:12],
                      camera=film.stats.get("time_camera", 0.0),
                      photons=film.stats.get("time_photons", 0.0))))
"""

LUMINANCE = (0.2126, 0.7152, 0.0722)


def child(code, python, cwd, **values):
    """Run code in a child `python` with the upper-case names bound to values; its last
    stdout line is JSON."""
    head = "".join(f"{k} = {v!r}\n" for k, v in values.items())
    run = subprocess.run([python, "-c", head + code], cwd=cwd, capture_output=True,
                         text=True, env=dict(os.environ, PYTHONPATH=cwd))
    if run.returncode:
        sys.exit(f"child failed in {cwd}:\n{run.stderr[-3000:]}")
    return json.loads(run.stdout.strip().splitlines()[-1])


def compare(image, cycles):
    import numpy as np
    lum = np.array(LUMINANCE)
    a, b = image @ lum, cycles @ lum
    h, w = (a.shape[0] // 10) * 10, (a.shape[1] // 10) * 10
    ba = a[:h, :w].reshape(h // 10, 10, w // 10, 10).mean(axis=(1, 3))
    bb = b[:h, :w].reshape(h // 10, 10, w // 10, 10).mean(axis=(1, 3))
    return a.mean() / b.mean(), float(np.abs(ba / np.maximum(bb, 1e-9) - 1).mean())


def main():
    import numpy as np
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", help="a checkout to compare with (before)")
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--cycles-spp", type=int, default=256)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--strands", type=int, default=3000)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    python = sys.executable
    out = os.path.join(tempfile.gettempdir(), "bench_hair", f"s{args.strands}_c{args.cycles_spp}")
    os.makedirs(out, exist_ok=True)
    meta = os.path.join(out, "meta.json")
    if not os.path.exists(meta):
        got = child(BUILD, python, ROOT, ROOT=ROOT, OUT=out, STRANDS=args.strands,
                    CYCLES_SPP=args.cycles_spp)
        with open(meta, "w") as f:
            json.dump(got, f)
    with open(meta) as f:
        cycles_s = json.load(f)["cycles_s"]
    cycles = np.load(os.path.join(out, "cycles.npy"))
    npx = 160 * 120 * args.spp
    print(f"\n{args.strands} strands, 160 x 120, ours {args.spp} spp ({args.workers} workers), "
          f"Cycles {args.cycles_spp} spp: {cycles_s:.1f} s\n")
    print("| checkout | wall s | CPU s | rays / sample | M rays / CPU s | ours / Cycles "
          "time | brightness vs Cycles | block error | film |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    roots = ([("before", os.path.abspath(args.base))] if args.base else []) + [("after", ROOT)]
    for _ in range(args.repeat):
        for label, root in roots:
            image = os.path.join(out, f"{label}.npy")
            r = child(RENDER, python, root, ROOT=root, OUT=out, SPP=args.spp,
                      WORKERS=args.workers, IMAGE=image)
            total = sum(r["rays"].values())
            bright, block = compare(np.load(image), cycles)
            print(f"| {label} ({os.path.basename(root)}) | {r['wall']:.1f} | {r['cpu']:.1f} | "
                  f"{total / npx:.1f} | {total / r['cpu'] / 1e6:.2f} | "
                  f"{r['wall'] / cycles_s:.1f}x | {bright:.3f} | {block:.3f} | {r['hash']} |",
                  flush=True)


if __name__ == "__main__":
    main()
