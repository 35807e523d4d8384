"""World light from an HDRI: what accuracy costs in CPU time (issue 14, "HDRI light noise
per CPU second").

The new-user trial's case-3 scene built in the engine alone: metal and plastic balls at
roughness 0.2 / 0.4 on a rough grey Principled floor, lit only by an equirectangular map
(a sky gradient, a warm ground, a 4 x 4-texel sun at 35 degrees elevation), 160 x 120,
the add-on's default settings. The trial's script made the map with a sun of 400, but
Blender saved its float buffer through the sRGB transfer function and read the .hdr back
as linear: the map the trial rendered (ours and Cycles alike) has a sun of 12.75 and a
brighter sky. `--map trial` (default) is that map; `--map linear` the one the script
meant (a 30x brighter sun: harder); `--map sunsky` the later trial's hand-written
sunsky.hdr (512x256, a 2-degree sun of radiance 1200: 99 % of the floor's direct light
from a few dozen texels). For each spp it renders `--seeds`
seeds and prints the CPU time (time.process_time of the render, all threads), the
relMSE against a reference (ours at --ref-spp, another seed; saved to / loaded from
--ref), relMSE x CPU time (lower is better: promise 1) and the image mean over the
reference's.

    PYTHONPATH=$PWD python bench/bench_world_light.py [--spp 16 32 64 128] [--seeds 2]
        [--ref /tmp/world_ref.npy] [--ref-spp 512] [--workers 1] [--map trial|linear]

`--trial3c` (needs bpy, the wheel in the venv): the new-user trial's case 3c as it was
run, built in Blender (Principled ground of roughness 0.8, a red ball, a glossy ball, a box,
the sunsky map as an Environment Texture), exported by the add-on, rendered by us at the
add-on's defaults with `--spp` and by Cycles (denoising, clamps, glossy filter and
adaptive sampling off) at `--cycles-spp`; relMSE against Cycles at `--ref-spp` (saved to /
loaded from --ref), so ours and Cycles' rows compare directly (lower relMSE x CPU wins).

    PYTHONPATH=$PWD python bench/bench_world_light.py --trial3c [--spp 32 64 128]
        [--cycles-spp 16 32 64] [--ref /tmp/case3c_cycles1024.npy] [--ref-spp 1024]

`--sky hosek|ms` (needs bpy): a low-sun Sky Texture scene built in Blender (issue 14, s18
skynoise: build_sky), ours and Cycles (2 threads) against Cycles at --ref-spp, as --trial3c;
--elevation sets the sun (degrees, default 7), --save keeps the images and the exported scene.

    PYTHONPATH=$PWD python bench/bench_world_light.py --sky hosek --spp 16 32 64 128
        --cycles-spp 16 32 64 128 256 --seeds 1 --ref /tmp/hosek_ref2048.npy --ref-spp 2048

relMSE = mean over pixels of (x - ref)^2 / (ref^2 + 0.01) on luminance, as the trial's
scripts compute it. The reference's own noise adds about relMSE(ref-spp) to every row
(~0.0003 at 512 spp after issue 14): compare rows, not the absolute floor. Report the
load (uptime) with the numbers: the machine is shared.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material

# The add-on's defaults (addon/properties.py to_settings_kwargs on a new scene).
ADDON_DEFAULTS = dict(photons=400_000, caustic_photons=200_000, max_photon_depth=32,
                      estimator="knn_simpson", min_photons=8, k_nearest=64,
                      final_gather=True, gather_rays=2, gather_by_share=True, max_depth=8,
                      light_samples=1, transparent_max_bounces=8, photon_mapping=True,
                      aim_caustics=True, photon_importance=True,
                      pixel_filter="blackman_harris", filter_width=1.5)


def sky_sun_map(w=256, h=128):
    """The trial's HDRI (case3_hdri.py make_hdri): (h, w, 3) float32, top row first."""
    v = (np.arange(h) + 0.5) / h
    elev = (0.5 - v) * np.pi
    img = np.zeros((h, w, 3), np.float32)
    sky = np.array([0.25, 0.45, 0.9]) * (0.4 + 0.6 * np.clip(np.sin(elev), 0, 1))[:, None]
    ground = np.array([0.15, 0.12, 0.1])
    img[:] = np.where((elev > 0)[:, None, None], sky[:, None, :], ground)
    su, se = 0.62, np.radians(35)
    sv = 0.5 - se / np.pi
    cu, cv = int(su * w), int(sv * h)
    img[cv - 2:cv + 2, cu - 2:cu + 2] = (400.0, 380.0, 340.0)
    return img


def sunsky_map(w=512, h=256):
    """The later trial's sunsky.hdr (case3_hdri_build.make_hdr): a blue sky, a brown ground,
    a sun of radiance (1200, 1100, 1000) within 2 degrees of elevation 40, longitude 30
    degrees; (h, w, 3) float32, top row first (the RGBE rounding of the file left out)."""
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    T, P = np.meshgrid((0.5 - v) * np.pi, (u - 0.5) * 2 * np.pi, indexing="ij")
    sky = np.clip(np.sin(T), 0, 1)[..., None]
    img = np.where(T[..., None] > 0, np.array([0.35, 0.5, 0.9]) * (0.4 + 0.6 * sky) + 0.1,
                   np.array([0.25, 0.22, 0.2]))
    se, sp = np.radians(40), np.radians(30)
    d = np.stack([np.cos(T) * np.cos(P), np.cos(T) * np.sin(P), np.sin(T)], -1)
    s = np.array([np.cos(se) * np.cos(sp), np.cos(se) * np.sin(sp), np.sin(se)])
    img[np.arccos(np.clip(d @ s, -1, 1)) < np.radians(2.0)] = (1200.0, 1100.0, 1000.0)
    # Columns as the file's (Blender and the engine read column u at atan2(y, x) =
    # 2 pi (0.5 - u): the sun at -30 degrees), rows top first as the file's.
    return img.astype(np.float32)


def write_rgbe(path, img):
    """A Radiance .hdr of (h, w, 3) linear RGB, top row first, written by hand (bpy's
    save clamps a sun of 1200 to about 20)."""
    rgb = np.asarray(img, np.float64)
    h, w = rgb.shape[:2]
    m = rgb.max(-1)
    e = np.where(m > 1e-32, np.floor(np.log2(np.maximum(m, 1e-32))) + 1, 0)
    scale = np.where(m > 1e-32, 256.0 / np.exp2(e), 0)
    rgbe = np.zeros((h, w, 4), np.uint8)
    rgbe[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(m > 1e-32, e + 128, 0).astype(np.uint8)
    with open(path, "wb") as f:
        f.write(f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode())
        f.write(rgbe.tobytes())


def srgb_encode(x):
    """The sRGB transfer function (linear -> encoded), applied to values above 1 too."""
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0), 1 / 2.4)
                    - 0.055).astype(np.float32)


def principled(name, color, metallic=0.0, roughness=0.5):
    return Material(name, tuple(color), metallic=metallic, roughness=roughness, specular=1.0,
                    specular_ior_level=0.5, node="principled")


def build_scene(width=160, height=120, sky="trial") -> PaperScene:
    s = PaperScene(width, height)
    s.add_plane((0, 0, 0), (0, 0, 1), 14.0, principled("FloorMat", (0.35,) * 3, 0.0, 0.8),
                name="Floor")
    specs = [("MetalR02", (0.9, 0.6, 0.3), 1.0, 0.2), ("MetalR04", (0.9, 0.9, 0.9), 1.0, 0.4),
             ("PlasticR02", (0.7, 0.05, 0.05), 0.0, 0.2),
             ("PlasticR04", (0.05, 0.2, 0.7), 0.0, 0.4)]
    for x, (n, col, met, r) in zip([-2.1, -0.7, 0.7, 2.1], specs):
        s.add_sphere((x, 0, 0.6), 0.6, principled(n + "Mat", col, met, r), name=n)
    # Blender: 42 mm lens on the 36 mm sensor fitted to the width
    s.set_camera((0, -7.0, 2.2), (0, 0, 0.5), view_angle=float(np.degrees(
        2 * np.arctan(18.0 / 42.0))))
    if sky == "sunsky":
        s.set_environment(sunsky_map())
    else:
        s.set_environment(srgb_encode(sky_sun_map()) if sky == "trial" else sky_sun_map())
    return s


def lum(x):
    return 0.2126 * x[..., 0] + 0.7152 * x[..., 1] + 0.0722 * x[..., 2]


def rel_mse(img, ref):
    L, R = lum(img), lum(ref)
    return float(np.mean((L - R) ** 2 / (R ** 2 + 1e-2)))


def run(scene, spp, seed, workers):
    st = RenderSettings(**ADDON_DEFAULTS, spp=spp, seed=seed, workers=workers)
    c0 = time.process_time()
    film = render(scene, st)
    return film, time.process_time() - c0


def _blender_material(name, color=(0.8, 0.8, 0.8), **inputs):
    import bpy
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    n = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    n.inputs["Base Color"].default_value = (*color, 1.0)
    for k, v in inputs.items():
        n.inputs[k].default_value = v
    return m


def _blender_put(obj, name, mat):
    obj.name = name
    obj.data.materials.append(mat)


def _blender_camera(location, target, lens):
    import bpy
    from mathutils import Vector
    cd = bpy.data.cameras.new("Cam")
    cd.lens = lens
    cam = bpy.data.objects.new("Cam", cd)
    cam.location = location
    cam.rotation_euler = (Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam


def build_trial3c(tmp):
    """The new-user trial's case 3c in the current (empty) Blender scene."""
    import bpy
    from tools.canonical_mesh import primitive_uv_sphere_add
    hdr = os.path.join(tmp, "sunsky.hdr")
    write_rgbe(hdr, sunsky_map())
    material, put = _blender_material, _blender_put
    bpy.ops.mesh.primitive_plane_add(size=30, location=(0, 0, 0))
    put(bpy.context.object, "Ground", material("GroundMat", (0.6, 0.6, 0.6), Roughness=0.8))
    for name, r, loc, mat in (
            ("RedBall", 0.6, (-1.0, 0.3, 0.6), material("Red", (0.8, 0.15, 0.1))),
            ("Gloss", 0.5, (0.9, 0.5, 0.5), material("Gloss", (0.2, 0.3, 0.8), Roughness=0.2))):
        primitive_uv_sphere_add(radius=r, location=loc, segments=48, ring_count=24)
        bpy.ops.object.shade_smooth()
        put(bpy.context.object, name, mat)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.2, -0.9, 0.35), rotation=(0, 0, 0.5))
    bpy.context.object.scale = (0.7, 0.7, 0.7)
    put(bpy.context.object, "Box", material("BoxMat"))
    w = bpy.data.worlds.new("HDRI")
    bpy.context.scene.world = w
    env = w.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdr)
    w.node_tree.links.new(env.outputs["Color"], w.node_tree.nodes["Background"].inputs["Color"])
    _blender_camera((0.5, -6.0, 2.2), (0.0, 0.3, 0.5), 35)


def build_sky(sky_type, elevation_deg=7.0, azimuth_deg=60.0):
    """A scene a Blender user would make under a low sun (issue 14, s18 skynoise): a
    Principled ground of roughness 0.5, a Principled ball, a metal ball and a box, the
    camera at eye height; the world a Sky Texture of `sky_type` (HOSEK_WILKIE: the node's
    sun_direction at `elevation_deg`, turbidity 2.2, ground albedo 0.3; MULTIPLE_SCATTERING:
    sun_elevation, the sun disc on), the sun `azimuth_deg` from +Y towards +X; no lamps."""
    import bpy
    from tools.canonical_mesh import primitive_uv_sphere_add
    material, put = _blender_material, _blender_put
    bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 0, 0))
    put(bpy.context.object, "Ground", material("GroundMat", (0.5, 0.5, 0.5), Roughness=0.5))
    for name, r, loc, mat in (
            ("Ball", 0.6, (-1.1, 0.6, 0.6), material("BallMat", (0.7, 0.25, 0.15),
                                                     Roughness=0.4)),
            ("Metal", 0.5, (0.9, 0.9, 0.5), material("MetalMat", (0.9, 0.85, 0.8),
                                                     Metallic=1.0, Roughness=0.25))):
        primitive_uv_sphere_add(radius=r, location=loc, segments=48, ring_count=24)
        bpy.ops.object.shade_smooth()
        put(bpy.context.object, name, mat)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.1, -0.6, 0.4), rotation=(0, 0, 0.6))
    bpy.context.object.scale = (0.8, 0.8, 0.8)
    put(bpy.context.object, "Box", material("BoxMat", (0.8, 0.8, 0.8), Roughness=0.5))
    w = bpy.data.worlds.new("Sky")
    bpy.context.scene.world = w
    sky = w.node_tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = sky_type
    e, r = np.radians(elevation_deg), np.radians(azimuth_deg)
    if sky_type == "HOSEK_WILKIE":
        sky.sun_direction = (np.cos(e) * np.sin(r), np.cos(e) * np.cos(r), np.sin(e))
        sky.turbidity, sky.ground_albedo = 2.2, 0.3
    else:
        sky.sun_elevation, sky.sun_rotation = e, r
    w.node_tree.links.new(sky.outputs["Color"], w.node_tree.nodes["Background"].inputs["Color"])
    _blender_camera((0.4, -6.5, 1.6), (0.0, 0.4, 0.5), 35)


def blender_case(a):
    """A scene built in Blender (--trial3c or --sky): ours and Cycles against Cycles (see
    the module docstring)."""
    import tempfile

    import bpy

    import addon
    from addon import export
    from addon.core import load_engine
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="bench_world_light_")
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 160, 120, 100
    if a.sky:
        build_sky({"hosek": "HOSEK_WILKIE", "ms": "MULTIPLE_SCATTERING"}[a.sky], a.elevation)
    else:
        build_trial3c(tmp)

    def cycles(spp, seed):
        sc.render.engine = "CYCLES"
        c = sc.cycles
        c.device, c.samples, c.seed = "CPU", spp, seed
        c.use_denoising = c.use_adaptive_sampling = False
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        c.blur_glossy = 0.0
        sc.render.threads_mode, sc.render.threads = "FIXED", 2
        st = sc.render.image_settings
        if hasattr(st, "media_type"):
            st.media_type = "IMAGE"
        st.file_format, st.color_depth, st.color_mode = "OPEN_EXR", "32", "RGBA"
        path = os.path.join(tmp, f"cycles_{spp}_{seed}.exr")
        sc.render.filepath, sc.render.use_file_extension = path, False
        c0 = time.process_time()
        bpy.ops.render.render(write_still=True)
        cpu = time.process_time() - c0
        img = bpy.data.images.load(path, check_existing=False)
        buf = np.empty(160 * 120 * 4, np.float32)
        img.pixels.foreach_get(buf)
        bpy.data.images.remove(img)
        return buf.reshape(120, 160, 4)[::-1, :, :3].copy(), cpu

    if a.ref and os.path.exists(a.ref):
        ref = np.load(a.ref)
    else:
        ref, cpu = cycles(a.ref_spp, 7)
        print(f"reference: Cycles {a.ref_spp} spp, {cpu:.1f} s CPU")
        if a.ref:
            np.save(a.ref, ref)
    sc.render.engine = "PHOTONMAP"
    kw = sc.photonmap.to_settings_kwargs(sc.render.film_transparent)
    pm_scene, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                      width=160, height=120)
    kw.update(workers=a.workers)
    kw.pop("spp", None)
    kw.pop("seed", None)
    render(pm_scene, RenderSettings(**kw, spp=1, seed=0))  # kernels loaded outside timings
    print(f"load: {os.getloadavg()[0]:.2f} (1-min average)")
    print(f"{'engine':>7} {'spp':>5} {'CPU s':>7} {'relMSE':>9} {'relMSE x CPU':>13} "
          f"{'mean/ref':>9}")
    rows = [("ours", spp) for spp in a.spp] + [("cycles", spp) for spp in a.cycles_spp]
    saved = {"ref": ref}
    if a.save:  # the exported scene, for per-pass studies outside Blender
        import pickle
        with open(os.path.splitext(a.save)[0] + "_scene.pkl", "wb") as f:
            pickle.dump((pm_scene, kw), f)
    for who, spp in rows:
        cpus, errs, means = [], [], []
        for seed in range(a.seeds):
            if who == "ours":
                c0 = time.process_time()
                film = render(pm_scene, RenderSettings(**kw, spp=spp, seed=1 + seed))
                cpu = time.process_time() - c0
                img = np.asarray(film.combined)[..., :3]
                for name in ("direct", "indirect", "caustic", "specular", "emission"):
                    saved[f"ours_{spp}_{seed}_{name}"] = np.asarray(getattr(film, name))
            else:
                img, cpu = cycles(spp, 1 + seed)
            saved[f"{who}_{spp}_{seed}"] = img
            cpus.append(cpu)
            errs.append(rel_mse(img, ref))
            means.append(float(lum(img).mean() / lum(ref).mean()))
        cpu, err = min(cpus), float(np.mean(errs))
        print(f"{who:>7} {spp:>5} {cpu:>7.2f} {err:>9.5f} {err * cpu:>13.5f} "
              f"{np.mean(means):>9.4f}", flush=True)
        if a.save:
            np.savez_compressed(a.save, **saved)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, nargs="+", default=[16, 32, 64, 128])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--ref", default=None, help="reference .npy (made if missing)")
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--map", choices=("trial", "linear", "sunsky"), default="trial")
    ap.add_argument("--trial3c", action="store_true",
                    help="the trial's case 3c in Blender, ours against Cycles (needs bpy)")
    ap.add_argument("--cycles-spp", type=int, nargs="*", default=[16, 32, 64])
    ap.add_argument("--sky", choices=("hosek", "ms"), default=None,
                    help="a low-sun Sky Texture scene built in Blender (hosek: Hosek / Wilkie, "
                         "ms: Multiple Scattering), ours against Cycles (needs bpy)")
    ap.add_argument("--elevation", type=float, default=7.0, help="--sky: sun elevation, deg")
    ap.add_argument("--save", default=None, help="--sky / --trial3c: save the images to "
                    "this .npz (keys ours_SPP_SEED / cycles_SPP_SEED)")
    a = ap.parse_args()
    if a.trial3c or a.sky:
        return blender_case(a)
    scene = build_scene(sky=a.map)
    run(scene, 1, 0, a.workers)  # compile / load the kernels outside the timings
    if a.ref and os.path.exists(a.ref):
        ref = np.load(a.ref)
    else:
        film, cpu = run(scene, a.ref_spp, 12345, a.workers)
        ref = np.asarray(film.combined)
        print(f"reference: {a.ref_spp} spp, {cpu:.1f} s CPU")
        if a.ref:
            np.save(a.ref, ref)
    print(f"load: {os.getloadavg()[0]:.2f} (1-min average)")
    print(f"{'spp':>5} {'CPU s':>7} {'relMSE':>9} {'relMSE x CPU':>13} {'mean/ref':>9}")
    for spp in a.spp:
        cpus, errs, means = [], [], []
        for seed in range(a.seeds):
            film, cpu = run(scene, spp, 1 + seed, a.workers)
            cpus.append(cpu)
            errs.append(rel_mse(film.combined, ref))
            means.append(float(lum(film.combined).mean() / lum(ref).mean()))
        cpu, err = min(cpus), float(np.mean(errs))
        print(f"{spp:>5} {cpu:>7.2f} {err:>9.5f} {err * cpu:>13.5f} {np.mean(means):>9.4f}",
              flush=True)


if __name__ == "__main__":
    main()
