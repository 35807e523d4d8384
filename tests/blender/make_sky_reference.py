"""Write tests/references/sky_cycles.json: Cycles' Single / Multiple Scattering, Preetham and
Hosek / Wilkie skies (Blender 5.0.1's, through the bpy wheel) for tests/test_sky.py. Run by
hand from the repository root:

    python tests/blender/make_sky_reference.py [--all]

A case already in the file (the same settings) keeps its numbers unless --all is given: adding a
case renders only that one.

Per case (sky type, sun elevation / rotation in degrees, altitude m, air / aerosol / ozone density):
- a 256 x 128 equirectangular panorama of the world without the sun disc (a panoramic
  camera at the origin looking along +X, up +Z: the Environment's layout, +X at the
  centre column), 16 samples; stored as the upper hemisphere's row means and column
  means of the RGB mean, and its per-channel sums, and the lower hemisphere's row means;
  a 0.01 px Gaussian pixel filter, so the pixels are the sky at their centres (Cycles'
  filter is scene.cycles.filter_width; render.filter_size is not Cycles' setting, and a
  Box filter is 1 px wide whatever filter_width says; until s14 this script set only
  render.filter_size and its panoramas were Blackman-Harris 1.5 px averages);
- the sun disc's irradiance (RGB, W / m^2): a camera aimed at the sun, 2 sun diameters
  across, 96 x 96 pixels, radiance x pixel solid angle summed, disc on minus disc off
  (Cycles' default filter, Blackman-Harris 1.5 px: the disc's edge averaged over pixels;
  point samples at 96 pixels across alias it by 0.2 %).
"""
import json
import math
import os

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OUT = os.path.join(ROOT, "tests", "references", "sky_cycles.json")
CASES = [
    dict(type="SINGLE_SCATTERING", sun_elevation=30.0, sun_rotation=0.0, altitude=100.0, air=1.0, aerosol=1.0, ozone=1.0,
         sun_size=0.545),
    dict(type="SINGLE_SCATTERING", sun_elevation=6.0, sun_rotation=70.0, altitude=2000.0, air=1.5, aerosol=3.0, ozone=2.0,
         sun_size=1.5),
    dict(type="SINGLE_SCATTERING", sun_elevation=75.0, sun_rotation=200.0, altitude=30000.0,
         air=0.5, aerosol=0.0, ozone=0.0, sun_size=0.545),
    dict(type="MULTIPLE_SCATTERING", sun_elevation=30.0, sun_rotation=0.0, altitude=100.0,
         air=1.0, aerosol=1.0, ozone=1.0, sun_size=0.545),
    dict(type="MULTIPLE_SCATTERING", sun_elevation=4.0, sun_rotation=250.0, altitude=5000.0,
         air=2.0, aerosol=0.5, ozone=3.0, sun_size=2.0),
    # Preetham: no disc; its sun is the node's sun_direction (normalised by Blender)
    dict(type="PREETHAM", sun_vector=[0.3, 0.5, 0.6], turbidity=3.0),
    # Hosek / Wilkie: no disc either; its sun the node's sun_direction, turbidity and ground
    # albedo; the cases cover the blends between turbidities (and none at 10), between
    # the two albedo sets and a sun below the horizon (clamped to it)
    dict(type="HOSEK_WILKIE", sun_vector=[0.3, 0.5, 0.6], turbidity=3.0, ground_albedo=0.3),
    dict(type="HOSEK_WILKIE", sun_vector=[-0.8, 0.2, 0.1], turbidity=7.5, ground_albedo=0.8),
    dict(type="HOSEK_WILKIE", sun_vector=[0.05, -0.1, 1.0], turbidity=1.7, ground_albedo=0.0),
    dict(type="HOSEK_WILKIE", sun_vector=[0.2, -0.7, -0.1], turbidity=10.0, ground_albedo=1.0),
]
ANALYTIC = ("PREETHAM", "HOSEK_WILKIE")
W, H = 256, 128


def _scene(bpy, case, disc):
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device, c.seed = "CPU", 0
    c.use_denoising = c.use_adaptive_sampling = False
    sc.render.resolution_percentage = 100
    sc.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("World")
    sc.world = world
    nt = world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = case["type"]
    if case["type"] in ANALYTIC:
        sky.sun_direction, sky.turbidity = case["sun_vector"], case["turbidity"]
        if case["type"] == "HOSEK_WILKIE":
            sky.ground_albedo = case["ground_albedo"]
    else:
        sky.sun_elevation = math.radians(case["sun_elevation"])
        sky.sun_rotation = math.radians(case["sun_rotation"])
        sky.altitude = case["altitude"]
        sky.air_density, sky.aerosol_density, sky.ozone_density = (
            case["air"], case["aerosol"], case["ozone"])
        sky.sun_size = math.radians(case["sun_size"])
        sky.sun_disc = disc
    nt.links.new(sky.outputs[0], bg.inputs["Color"])
    return sc


def _render(bpy, sc, cam_data, rotation, w, h, spp):
    cam = bpy.data.objects.new("Camera", cam_data)
    sc.collection.objects.link(cam)
    sc.camera = cam
    cam.rotation_euler = rotation
    sc.render.resolution_x, sc.render.resolution_y = w, h
    sc.cycles.samples = spp
    s = sc.render.image_settings
    s.media_type, s.file_format, s.color_depth, s.color_mode = "IMAGE", "OPEN_EXR", "32", "RGB"
    path = os.path.join(os.environ.get("TMPDIR", "/tmp"), "sky_reference.exr")
    sc.render.filepath, sc.render.use_file_extension = path, False
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    buf = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(buf)
    bpy.data.images.remove(img)
    return buf.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)


def panorama(bpy, case):
    sc = _scene(bpy, case, False)
    sc.cycles.pixel_filter_type, sc.cycles.filter_width = "GAUSSIAN", 0.01
    cd = bpy.data.cameras.new("Pano")
    cd.type, cd.panorama_type = "PANO", "EQUIRECTANGULAR"
    img = _render(bpy, sc, cd, (math.pi / 2, 0.0, -math.pi / 2), W, H, 16)
    up = img[: H // 2]
    return dict(row_means=up.mean(axis=(1, 2)).tolist(), column_means=up.mean(axis=(0, 2)).tolist(),
                channel_sums=up.sum(axis=(0, 1)).tolist(),
                lower_row_means=img[H // 2:].mean(axis=(1, 2)).tolist())


def disc_irradiance(bpy, case):
    from mathutils import Vector
    size = math.radians(case["sun_size"])
    fov, n = 2.0 * size, 96
    sums = []
    for disc in (True, False):
        sc = _scene(bpy, case, disc)
        cd = bpy.data.cameras.new("Aim")
        cd.sensor_fit, cd.sensor_width = "HORIZONTAL", 36.0
        cd.lens = 18.0 / math.tan(fov / 2.0)
        e, r = math.radians(case["sun_elevation"]), math.radians(case["sun_rotation"])
        d = Vector((math.cos(e) * math.sin(r), math.cos(e) * math.cos(r), math.sin(e)))
        img = _render(bpy, sc, cd, d.to_track_quat("-Z", "Y").to_euler(), n, n, 4)
        t = math.tan(fov / 2.0)
        g = ((np.arange(n) + 0.5) / n * 2.0 - 1.0) * t
        gx, gy = np.meshgrid(g, g)
        omega = (2.0 * t / n) ** 2 / (1.0 + gx ** 2 + gy ** 2) ** 1.5
        sums.append((img * omega[:, :, None]).sum(axis=(0, 1)))
    return (sums[0] - sums[1]).tolist()


def main():
    import sys

    import bpy
    old = []
    if os.path.exists(OUT) and "--all" not in sys.argv:
        with open(OUT) as f:
            old = json.load(f)["cases"]
    out = dict(blender=bpy.app.version_string, width=W, height=H, cases=[])
    for case in CASES:
        kept = [e for e in old if {k: e.get(k) for k in case} == case]
        if kept:
            out["cases"].append(kept[0])
            continue
        entry = dict(case)
        entry.update(panorama(bpy, case))
        entry["disc_irradiance"] = (disc_irradiance(bpy, case) if case["type"] not in ANALYTIC
                                    else [0.0, 0.0, 0.0])
        out["cases"].append(entry)
        print(case, "disc", np.round(entry["disc_irradiance"], 3))
    with open(OUT, "w") as f:
        json.dump(out, f, indent=1)
    print("wrote", OUT)


if __name__ == "__main__":
    main()
