"""World light from an HDRI: what accuracy costs in CPU time (issue 14, "HDRI light noise
per CPU second").

The new-user trial's case-3 scene built in the engine alone: metal and plastic balls at
roughness 0.2 / 0.4 on a rough grey Principled floor, lit only by an equirectangular map
(a sky gradient, a warm ground, a 4 x 4-texel sun at 35 degrees elevation), 160 x 120,
the add-on's default settings. The trial's script made the map with a sun of 400, but
Blender saved its float buffer through the sRGB transfer function and read the .hdr back
as linear: the map the trial rendered (ours and Cycles alike) has a sun of 12.75 and a
brighter sky. `--map trial` (default) is that map; `--map linear` the one the script
meant (a 30x brighter sun: harder). For each spp it renders `--seeds`
seeds and prints the CPU time (time.process_time of the render, all threads), the
relMSE against a reference (ours at --ref-spp, another seed; saved to / loaded from
--ref), relMSE x CPU time (lower is better: promise 1) and the image mean over the
reference's.

    PYTHONPATH=$PWD python bench/bench_world_light.py [--spp 16 32 64 128] [--seeds 2]
        [--ref /tmp/world_ref.npy] [--ref-spp 512] [--workers 1] [--map trial|linear]

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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, nargs="+", default=[16, 32, 64, 128])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--ref", default=None, help="reference .npy (made if missing)")
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--map", choices=("trial", "linear"), default="trial")
    a = ap.parse_args()
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
