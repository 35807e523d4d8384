"""A white panel lit only by a rough floor's reflection of a shielded point lamp: ours /
Cycles, for a metal floor (Principled Metallic 1) and a dielectric one (Principled, white
base), roughness 0.5 and 1, Multiscatter GGX and plain GGX (issue 14: does a photon take
the reflective lobes' energy compensation at the right side? photonkernels.lobe_adjoint,
as glass_adjoint for rough glass). The scene and settings are
tests/blender/test_reflected_panel_cycles.py's.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_reflected_panel.py [--seeds 0,1,2]
        [--spp 64] [--photons 2000000] [metal|dielectric ...]

48x36; ours at default settings but --spp samples and --photons global and caustic
photons, per seed (Photon Mapping > Seed); Cycles 1024 spp, seed 0; the same Light Paths
(12 / 4 diffuse / 4 glossy / 12 transmission). Prints a Markdown table of the image
means, ours as the mean over the seeds, and the spread of ours / Cycles over them.
Measured 2026-12-04 (2 shared cores), seeds 0,1,2, 64 spp, 2M photons, roughness 0.5
Multiscatter / 1 Multiscatter / 1 GGX:
  before lobe_adjoint (75e287d): metal 1.001 / 1.025 / 0.999, dielectric 1.000 / 1.012 / 1.012
  after (roughlobes31):          metal 1.003 / 0.998 / 0.999, dielectric 1.000 / 1.012 / 1.012
At the old settings (16 spp, 400k / 200k photons, seed 0) 75e287d read metal 0.992 /
1.037 / 1.010, dielectric 0.984 / 0.984 / 0.965: one draw of an image mean whose spread
over seeds is 3-6 % there (the dielectric floor's final gathering at 16 spp).
"""
import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy  # noqa: E402
import addon  # noqa: E402
addon.register()
from test_reflected_panel_cycles import CASES, image_mean, scene_for  # noqa: E402


def main():
    import tempfile
    ap = argparse.ArgumentParser()
    ap.add_argument("kinds", nargs="*", default=["metal", "dielectric"])
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--photons", type=int, default=2_000_000)
    a = ap.parse_args()
    seeds = [int(s) for s in a.seeds.split(",")]
    print(f"seeds {seeds}, ours {a.spp} spp, {a.photons} photons")
    print("| floor | roughness | distribution | ours | Cycles | ours / Cycles "
          "| min-max over seeds |")
    print("|---|---:|---|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in a.kinds:
            for rough, dist in CASES:
                cyc = image_mean(bpy, scene_for(bpy, rough, dist, kind),
                                 os.path.join(tmp, "c.exr"), "CYCLES")
                ours = []
                for seed in seeds:
                    ours.append(image_mean(bpy, scene_for(bpy, rough, dist, kind),
                                           os.path.join(tmp, "o.exr"), "PHOTONMAP",
                                           spp=a.spp, photons=a.photons, seed=seed))
                m = sum(ours) / len(ours)
                print(f"| {kind} | {rough} | {dist} | {m:.5f} | {cyc:.5f} | {m / cyc:.4f} "
                      f"| {min(ours) / cyc:.4f}-{max(ours) / cyc:.4f} |", flush=True)


if __name__ == "__main__":
    main()
