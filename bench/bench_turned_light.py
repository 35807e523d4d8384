"""The sunlight final-gather chains find through Cycles' turned-normal glass reflections
(engine/turnedlight.py, turnednormal44), on tests/blender/test_glass_of_water_cycles.py's
scene: ours with engine/turnedlight.py off (as before), each of its two parts alone and
both (on), against Cycles.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_turned_light.py [--spp 4]
        [--photons 20000] [--caustic-photons 100000] [--seed 0] [--cycles-spp 1024]
        [--glossy 4] [--angle 30] [--shadings smooth,flat] [--contents water,empty]

Ours at the test's settings by default (4 spp, 20k / 100k photons, one thread), the
image mean and CPU seconds of each render in one process; Cycles: the stored 4096-spp
mean where the test stores one (the glass of water, Glossy 4: tests/references/
glass_of_water.json; a 30-degree sun), else rendered here at --cycles-spp (no clamp, no
glossy blur, 12 bounces, Glossy --glossy); --angle: the sun's disc (degrees). "share of
the gap" = (on - off) / (Cycles - off). Prints a Markdown table; docs/accuracy.md,
turnednormal44, gives the numbers measured.
"""
import argparse
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy  # noqa: E402
import addon  # noqa: E402
addon.register()
from engine import turnedlight  # noqa: E402
from blender_helpers import cheap, cycles_plain  # noqa: E402
from test_glass_of_water_cycles import _mean, _scene, _stored_means  # noqa: E402


# turnedlight's switches (ENABLED, UNGUARD, ESCAPES) by column: off (as before), the
# turned normal at the bent glass alone (escapes add nothing), the escapes alone (the
# guard kept), both (the default).
MODES = {"off": (False, True, True), "unguarded only": (True, True, False),
         "escapes only": (True, False, True), "on": (True, True, True)}


def _render(engine, shading, water, args, tmp, name):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    _scene(bpy, scene, shading, sun_angle=args.angle, water=water)
    if engine == "CYCLES":
        cycles_plain(scene, args.cycles_spp, 12)
    else:
        cheap(scene, spp=args.spp, photons=args.photons,
              caustic_photons=args.caustic_photons)
        scene.photonmap.seed = args.seed
        scene.photonmap.threads = 1
    scene.cycles.glossy_bounces = args.glossy
    c0 = time.process_time()
    m = _mean(bpy, scene, os.path.join(tmp, name + ".exr"), engine)
    return m, time.process_time() - c0


def glass_arguments(spp):
    """The arguments of the glass-of-water benches (this one, bench_turned_camera.py):
    ours' samples (spp: the default), photons and seed, Cycles' samples, Light Paths
    Glossy, the shadings and contents to render."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=spp)
    ap.add_argument("--photons", type=int, default=20_000)
    ap.add_argument("--caustic-photons", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cycles-spp", type=int, default=1024)
    ap.add_argument("--glossy", type=int, default=4)
    ap.add_argument("--shadings", default="smooth,flat")
    ap.add_argument("--contents", default="water,empty")
    return ap


def glass_cases(args):
    """[(content, water, shading)]: the glass-of-water cases args (glass_arguments') ask
    for, contents outer."""
    return [(content, content == "water", shading) for content in args.contents.split(",")
            for shading in args.shadings.split(",")]


def main():
    ap = glass_arguments(4)
    ap.add_argument("--angle", type=float, default=30.0)
    args = ap.parse_args()
    stored = _stored_means()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        _render("PHOTONMAP", "flat", True, args, tmp, "warm")  # loads the kernels
        for content, water, shading in glass_cases(args):
            got = {}
            for mode, (on, unguard, escapes) in MODES.items():
                turnedlight.ENABLED = on
                turnedlight.UNGUARD, turnedlight.ESCAPES = unguard, escapes
                try:
                    got[mode] = _render("PHOTONMAP", shading, water, args, tmp,
                                        f"{content}_{shading}_{mode}")
                finally:
                    turnedlight.ENABLED = turnedlight.UNGUARD = True
                    turnedlight.ESCAPES = True
            if water and args.glossy == 4 and args.angle == 30.0:
                cyc = stored[shading]
            else:
                cyc = _render("CYCLES", shading, water, args, tmp,
                              f"cycles_{content}_{shading}")[0]
            rows.append((content, shading, got, cyc))
    print(f"\nours {args.spp} spp, {args.photons} / {args.caustic_photons} photons, seed "
          f"{args.seed}, one thread; Cycles {args.cycles_spp} spp (stored 4096 for the "
          f"glass of water), Glossy {args.glossy}; load {os.getloadavg()[0]:.1f}\n")
    print("| content | shading | Cycles | " + " | ".join(f"{m} / Cycles" for m in MODES)
          + " | share of the gap (on) | CPU s off / on |")
    print("|---|---|---:|" + "---:|" * (len(MODES) + 2))
    for content, shading, got, cyc in rows:
        off, on = got["off"], got["on"]
        gap = cyc - off[0]
        share = (on[0] - off[0]) / gap if abs(gap) > 1e-9 else float("nan")
        print(f"| {'glass of water' if content == 'water' else 'empty glass'} | {shading} | "
              f"{cyc:.4f} | " + " | ".join(f"{got[m][0] / cyc:.4f}" for m in MODES)
              + f" | {share:.2f} | {off[1]:.1f} / {on[1]:.1f} |")


if __name__ == "__main__":
    main()
