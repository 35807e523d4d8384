"""Cycles references for the refraction scenes (tests/refraction_scenes.py).

Renders each scene with Cycles from the bpy wheel (bench/cycles_scene.py: no denoising,
no clamping, box filter) and stores the floor's mean brightness in
tests/references/refraction.json (a few hundred bytes; tests/test_refraction.py reads it).

    .venv/bin/python tools/make_refraction_references.py [--samples 1024]
"""
import argparse
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests"), os.path.join(ROOT, "bench")]
OUT = os.path.join(ROOT, "tests", "references", "refraction.json")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1024)
    args = ap.parse_args(argv)
    import cycles_scene
    import refraction_scenes as R
    out = {"samples": args.samples, "width": R.WIDTH, "height": R.HEIGHT, "floor_mean": {}}
    for name, build in R.SCENES.items():
        img, secs = cycles_scene.render(build(), args.samples)
        out["floor_mean"][name] = round(R.floor_mean(img), 5)
        print(f"{name:12s} {out['floor_mean'][name]:.5f}  ({secs:.1f} s)", flush=True)
    with open(OUT, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
