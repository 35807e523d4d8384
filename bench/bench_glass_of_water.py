"""The glass of water of tests/blender/test_glass_of_water_cycles.py (issue 14, water43):
ours / Cycles by shading (flat, smooth sides), content (glass of water, empty glass) and
the sun's disc (degrees), for the table seen straight down through the water.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glass_of_water.py [--angles 1,30]
        [--cycles-spp 4096] [--spp 16] [--photons 100000] [--caustic-photons 1000000]
        [--seed 0]

16 x 16 pixels, the test's scene; ours at --spp samples and the given photon counts;
Cycles at --cycles-spp, seed 0, no clamping or glossy blur, 12 bounces. Prints a
Markdown table of the image means and ours / Cycles. At a 1-degree sun Cycles' mean is
its fireflies' (its diffuse rays meet the sun through the water 1 time in ~14,000): not
converged at any sample count here. Measured numbers: docs/accuracy.md, water43.
"""
import argparse
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy  # noqa: E402
import addon  # noqa: E402
addon.register()
from blender_helpers import cheap, cycles_plain  # noqa: E402
from test_glass_of_water_cycles import SHADINGS, _mean, _scene  # noqa: E402


def _render(engine, shading, water, angle, args, tmp):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    _scene(bpy, scene, shading, angle, water)
    if engine == "CYCLES":
        cycles_plain(scene, args.cycles_spp, 12)
    else:
        cheap(scene, spp=args.spp, photons=args.photons,
              caustic_photons=args.caustic_photons)
        scene.photonmap.seed = args.seed
    name = f"{engine}_{shading}_{int(water)}_{angle:g}.exr"
    return _mean(bpy, scene, os.path.join(tmp, name), engine)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--angles", default="1,30")
    ap.add_argument("--cycles-spp", type=int, default=4096)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--photons", type=int, default=100_000)
    ap.add_argument("--caustic-photons", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for angle in (float(a) for a in args.angles.split(",")):
            for shading in SHADINGS:
                for water in (True, False):
                    ours = _render("PHOTONMAP", shading, water, angle, args, tmp)
                    cyc = _render("CYCLES", shading, water, angle, args, tmp)
                    rows.append((angle, shading, "glass of water" if water else "empty glass",
                                 ours, cyc))
    print(f"\nours {args.spp} spp, {args.photons} global / {args.caustic_photons} caustic "
          f"photons, seed {args.seed}; Cycles {args.cycles_spp} spp\n")
    print("| sun (deg) | shading | content | ours | Cycles | ours / Cycles |")
    print("|---:|---|---|---:|---:|---:|")
    for angle, shading, content, ours, cyc in rows:
        print(f"| {angle:g} | {shading} | {content} | {ours:.4f} | {cyc:.4f} | "
              f"{ours / cyc:.3f} |")


if __name__ == "__main__":
    main()
