"""Window-lit interiors at equal time against Cycles (interior41; issues 13 / 14).

For each interior .blend (a room lit by sky + sun through a window, a lamp or two), with
Light Paths > Clamping > Indirect 0 and Filter Glossy 0 for both renderers (else at
Cycles' defaults the comparison is one of clamps) and every other setting as the file
has it (Cycles' defaults: 12 bounces, 4 diffuse, Blackman-Harris 1.5 px):

- the reference: Cycles at --ref-spp samples (seed 7777), cached as an .npy beside
  --ref-dir (its own relMSE is printed: two halves' spread is not available from one
  render, so its noise floor is estimated from the ladder's trend);
- Cycles' ladder (--cycles, seed 1) and ours (--spp, seeds --seeds) at default settings,
  each render timed in the process's CPU seconds (the machine's 2 cores are shared: wall
  seconds mean little), ours by engine.render on one worker from one export;
- per render: relMSE (x - ref)^2 / (ref^2 + 0.01) and mean HDR-FLIP against the
  reference, and relMSE by region (the first hit of a pinhole ray through each pixel
  centre, from bpy's ray_cast: floor (normal z > 0.7), ceiling (z < -0.7), walls, within
  --near m of the window object's box ("window": also walls / floor / ceiling there),
  and 'other' (lamp, pane, sky));
- with two or more seeds: the seeds' pixel variance split by our effect passes (direct,
  indirect, caustic, specular, emission: Film), as each pass's share of the summed
  per-pixel relative variance, and the stage seconds (photons, photon map, camera);
- equal time: Cycles' relMSE and FLIP at our CPU seconds (log-log on its ladder) and the
  ratio of Cycles' seconds to reach our error to ours (> 1: we are faster).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_interior.py \\
        /tmp/newuser40/scenes/a_solid.blend --spp 8,16,32,64 --cycles 16,64,256,1024 \\
        --seeds 0,1 [--variant NAME:key=value,...]

A variant is NAME:key=value,... of engine.settings.RenderSettings fields, or
@module.CONST=value to patch a module constant read by Python (as bench_accuracy_ab.py),
measured over the same spp ladder.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402
import accuracy_scenes as A  # noqa: E402
from bench_accuracy import _loglog  # noqa: E402
from bench_accuracy_ab import parse_variant, render_ours  # noqa: E402

EFFECTS = ("direct", "indirect", "caustic", "specular", "emission")


def open_scene(path, width=None):
    """Open `path` in bpy, Clamp Indirect 0 and Filter Glossy 0 (Cycles' properties, which
    the add-on reads too); returns the scene."""
    A.ensure_addon()
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    sc = bpy.context.scene
    r = sc.render
    if width:
        r.resolution_y = round(r.resolution_y * width / r.resolution_x)
        r.resolution_x = width
    r.resolution_percentage = 100
    r.use_border = False
    c = sc.cycles
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    pm = sc.photonmap
    for prop in pm.bl_rna.properties:
        if prop.identifier != "rna_type":
            pm.property_unset(prop.identifier)
    for owner in (pm,):
        if hasattr(owner, "sample_clamp_indirect"):
            owner.sample_clamp_indirect = 0.0
    return sc


def cycles(path, spp, seed, width):
    sc = open_scene(path, width)
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = seed
    c0 = time.process_time()
    img, wall = A.render_rgb(sc)
    return img, time.process_time() - c0, wall


def regions(path, width, window, near):
    """{name: (H,W) bool} from pinhole rays through the pixel centres (bpy ray_cast)."""
    from mathutils import Vector
    sc = open_scene(path, width)
    dg = bpy.context.evaluated_depsgraph_get()
    cam = sc.camera
    W, H = sc.render.resolution_x, sc.render.resolution_y
    frame = [cam.matrix_world @ v for v in cam.data.view_frame(scene=sc)]
    # view_frame: top-right, bottom-right, bottom-left, top-left
    tr, br, bl, tl = frame
    eye = cam.matrix_world.translation
    box = None
    ob = bpy.data.objects.get(window)
    if ob is not None:
        pts = np.array([ob.matrix_world @ Vector(c) for c in ob.bound_box])
        box = pts.min(0), pts.max(0)
    out = {k: np.zeros((H, W), bool) for k in ("floor", "ceiling", "walls", "window",
                                                 "other")}
    for y in range(H):
        fy = (y + 0.5) / H
        for x in range(W):
            fx = (x + 0.5) / W
            top = tl + (tr - tl) * fx
            bot = bl + (br - bl) * fx
            target = top + (bot - top) * fy
            d = (target - eye).normalized()
            ok, loc, nrm, _, obj, _ = sc.ray_cast(dg, eye, d)
            mats = [s.material for s in obj.material_slots] if ok else []
            plain = ok and not any(
                m is not None and m.node_tree is not None and any(
                    n.type in ("EMISSION", "BSDF_GLASS") or (
                        n.type == "BSDF_PRINCIPLED" and (
                            n.inputs["Transmission Weight"].default_value > 0.5
                            or n.inputs["Emission Strength"].default_value > 0))
                    for n in m.node_tree.nodes) for m in mats)
            if not plain:
                out["other"][y, x] = True
                continue
            if box is not None:
                q = np.clip(np.array(loc), box[0], box[1])
                if np.linalg.norm(q - np.array(loc)) < near:
                    out["window"][y, x] = True
                    continue
            key = "floor" if nrm.z > 0.7 else "ceiling" if nrm.z < -0.7 else "walls"
            out[key][y, x] = True
    return out


def region_relmse(img, ref, regs):
    e = (np.asarray(img, np.float64) - ref) ** 2 / (ref * ref + 0.01)
    return {k: float(e[m].mean()) for k, m in regs.items() if m.any()}


def fmt_regions(d):
    return " ".join(f"{k} {v:.4f}" for k, v in d.items())


def export(path, width):
    from addon import export as ex
    import engine
    sc = open_scene(path, width)
    sc.render.engine = "PHOTONMAP"
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(sc.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h, render_visibility=True)
    return pm_scene, sc.photonmap.to_settings_kwargs(sc.render.film_transparent)


def render_film(pm_scene, kwargs, patches=None):
    """(Film, CPU s, wall s) of one engine render; patches {(module, CONST): value}:
    module constants of engine/ set for its duration (a diagnostic, bench_accuracy_ab)."""
    import importlib
    from engine.render import render
    from engine.settings import RenderSettings
    saved = {}
    for (module, const), value in (patches or {}).items():
        mod = importlib.import_module("engine." + module)
        saved[(mod, const)] = getattr(mod, const)
        setattr(mod, const, value)
    try:
        c0, t0 = time.process_time(), time.perf_counter()
        film = render(pm_scene, RenderSettings(**kwargs))
        return film, time.process_time() - c0, time.perf_counter() - t0
    finally:
        for (mod, const), value in saved.items():
            setattr(mod, const, value)


def build_two_windows(path, width=160, height=120):
    """Save a third interior to `path` (the new user's rooms' recipe): a 6 x 5 x 3 m room,
    Solidify walls 0.2 (outward), two open windows cut by Boolean (WindowCutter in the +y
    wall, WindowCutter2 in the -x wall), Principled walls 0.8 grey (roughness 0.8), a 1 kW
    point lamp under the ceiling (radius 0.1 m), Sun 3 W/m^2 (1 deg) and a Nishita Sky
    Texture at 40 deg; camera in a corner, 20 mm."""
    import math
    from mathutils import Vector
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = width, height
    sc.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 1.5))
    room = bpy.context.active_object
    room.name = "Room"
    room.scale = (6, 5, 3)
    bpy.ops.object.transform_apply(scale=True)
    sol = room.modifiers.new("Solidify", "SOLIDIFY")
    sol.thickness, sol.offset = 0.2, 1.0
    for name, loc, scale in (("WindowCutter", (0, 2.6, 1.6), (2.0, 1.0, 1.2)),
                             ("WindowCutter2", (-3.1, -0.8, 1.5), (1.0, 1.4, 1.1))):
        bpy.ops.mesh.primitive_cube_add(size=1, location=loc)
        cut = bpy.context.active_object
        cut.name, cut.scale = name, scale
        cut.hide_render, cut.display_type = True, "WIRE"
        boo = room.modifiers.new(name, "BOOLEAN")
        boo.object, boo.operation = cut, "DIFFERENCE"
    m = bpy.data.materials.new("Walls")
    m.use_nodes = True
    pr = m.node_tree.nodes["Principled BSDF"]
    pr.inputs["Base Color"].default_value = (0.8, 0.8, 0.75, 1)
    pr.inputs["Roughness"].default_value = 0.8
    room.data.materials.append(m)
    lamp = bpy.data.lights.new("CeilingLamp", "POINT")
    lamp.energy, lamp.shadow_soft_size = 1000.0, 0.1
    lo = bpy.data.objects.new("CeilingLamp", lamp)
    lo.location = (0.5, 0.0, 2.7)
    sc.collection.objects.link(lo)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy, sun.angle = 3.0, math.radians(1)
    so = bpy.data.objects.new("Sun", sun)
    so.rotation_euler = (math.radians(-50), 0, math.radians(10))
    sc.collection.objects.link(so)
    w = bpy.data.worlds.new("Sky")
    sc.world = w
    w.use_nodes = True
    sky = w.node_tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "NISHITA" if "NISHITA" in [
        i.identifier for i in sky.bl_rna.properties["sky_type"].enum_items] else sky.sky_type
    sky.sun_elevation = math.radians(40)
    w.node_tree.links.new(sky.outputs[0], w.node_tree.nodes["Background"].inputs[0])
    cam = bpy.data.cameras.new("Camera")
    cam.lens = 20
    co = bpy.data.objects.new("Camera", cam)
    co.location = (2.5, -2.0, 1.5)
    co.rotation_euler = (Vector((-1.0, 2.5, 1.3)) - co.location).to_track_quat(
        "-Z", "Y").to_euler()
    sc.collection.objects.link(co)
    sc.camera = co
    bpy.ops.wm.save_as_mainfile(filepath=path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("blend", nargs="+")
    ap.add_argument("--width", type=int, default=0, help="render width (0: the file's)")
    ap.add_argument("--spp", default="8,16,32,64,128")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--cycles", default="16,64,256,1024")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--ref-dir", default="/tmp/interior41-refs")
    ap.add_argument("--window", default="WindowCutter", help="the window's object (its box)")
    ap.add_argument("--near", type=float, default=0.75)
    ap.add_argument("--variant", action="append", default=[])
    ap.add_argument("--build-two-windows", action="store_true",
                    help="first save build_two_windows() to the (one) blend path given")
    args = ap.parse_args(argv)
    if args.build_two_windows:
        build_two_windows(args.blend[0])
    import engine
    engine.jit.ensure_compiled()
    os.makedirs(args.ref_dir, exist_ok=True)
    for path in args.blend:
        name = os.path.splitext(os.path.basename(path))[0]
        ref_path = os.path.join(args.ref_dir, f"{name}-{args.width}-{args.ref_spp}.npy")
        if not os.path.isfile(ref_path):
            img, cpu, wall = cycles(path, args.ref_spp, 7777, args.width or None)
            np.save(ref_path, img)
            print(f"{name}: reference Cycles {args.ref_spp} spp cpu {cpu:.0f} s wall "
                  f"{wall:.0f} s", flush=True)
        ref = np.load(ref_path).astype(np.float64)
        regs = regions(path, args.width or None, args.window, args.near)
        print(f"== {name} {ref.shape[1]}x{ref.shape[0]}  reference {ref_path}  pixels: "
              + " ".join(f"{k} {int(m.sum())}" for k, m in regs.items()), flush=True)
        curve = []
        for spp in [int(s) for s in args.cycles.split(",") if s]:
            img, cpu, wall = cycles(path, spp, 1, args.width or None)
            rm, f = A.relmse(img, ref), A.flip(img, ref)
            curve.append((cpu, rm, f))
            print(f"cycles {spp:5d} spp  cpu {cpu:7.1f} s  relMSE {rm:.4f}  FLIP {f:.4f}  "
                  f"mean {img.mean() / ref.mean():.3f}  | "
                  + fmt_regions(region_relmse(img, ref, regs)), flush=True)
        pm_scene, base = export(path, args.width or None)
        base = dict(base, workers=1)
        seeds = [int(s) for s in args.seeds.split(",")]
        print(f"load average {os.getloadavg()[0]:.1f}", flush=True)
        for text in ["default:"] + args.variant:
            vname, overrides, patches = parse_variant(text)
            for spp in [int(s) for s in args.spp.split(",")]:
                films, cpus, rms, fls = [], [], [], []
                for seed in seeds:
                    film, cpu, wall = render_film(
                        pm_scene, dict(base, seed=seed, spp=spp, **overrides), patches)
                    img = film.combined
                    films.append(film)
                    cpus.append(cpu)
                    rms.append(A.relmse(img, ref))
                    fls.append(A.flip(img, ref))
                st = films[0].stats
                line = (f"{vname:10s} {spp:4d} spp  cpu {np.mean(cpus):7.1f} s  relMSE "
                        f"{np.mean(rms):.4f}  FLIP {np.mean(fls):.4f}  mean "
                        f"{films[0].combined.mean() / ref.mean():.3f}  gather rays/spp "
                        f"{st.get('gather_rays_used', '-')}  stages photons "
                        f"{st.get('time_photons', 0):.1f} map {st.get('time_photon_map', 0):.1f}"
                        f" camera {st.get('time_camera', 0):.1f} s wall")
                if len(curve) >= 2:
                    c_rm = np.exp(np.interp(np.log(np.mean(cpus)),
                                            np.log([c for c, _, _ in curve]),
                                            np.log([r for _, r, _ in curve])))
                    t_rm, ex_rm = _loglog(np.mean(rms), [r for _, r, _ in curve],
                                          [c for c, _, _ in curve])
                    t_f, ex_f = _loglog(np.mean(fls), [f for _, _, f in curve],
                                        [c for c, _, _ in curve])
                    line += (f"\n           Cycles at that time relMSE {c_rm:.4f};"
                             f" Cycles s at our relMSE {'~' if ex_rm else ''}{t_rm:.1f}"
                             f" (ratio {t_rm / np.mean(cpus):.2f}), at our FLIP "
                             f"{'~' if ex_f else ''}{t_f:.1f} (ratio {t_f / np.mean(cpus):.2f})")
                rs = st.get("ray_stages", {})
                line += ("\n           rays (M): " + " ".join(
                    f"{k} {v / 1e6:.2f}" for k, v in rs.items() if v > 1e4))
                line += "\n           regions relMSE: " + fmt_regions(
                    region_relmse(films[0].combined, ref, regs))
                if len(films) >= 2:
                    # The seeds' variance per pixel, relative, by effect pass: each
                    # pass's share of the summed variance (the passes' covariances left
                    # out: they are independent estimators of disjoint paths).
                    denom = ref * ref + 0.01
                    var = {e: float((np.var(np.stack([getattr(f, e) for f in films]),
                                            axis=0, ddof=1) / denom).mean()) for e in EFFECTS}
                    tot = np.var(np.stack([f.combined for f in films]), axis=0, ddof=1)
                    tot = float((tot / denom).mean())
                    line += (f"\n           seeds' relative variance {tot:.4f}: " + " ".join(
                        f"{e} {v / max(sum(var.values()), 1e-30):.0%}" for e, v in var.items()))
                    for rk, m in regs.items():
                        if rk == "other" or not m.any():
                            continue
                        vv = {e: float((np.var(np.stack([getattr(f, e)[m] for f in films]),
                                               axis=0, ddof=1) / denom[m]).mean())
                              for e in ("direct", "indirect", "caustic")}
                        s = max(sum(vv.values()), 1e-30)
                        line += f"\n             {rk:8s} " + " ".join(
                            f"{e} {v / s:.0%}" for e, v in vv.items())
                print(line, f"(load {os.getloadavg()[0]:.1f})", flush=True)


if __name__ == "__main__":
    main()
