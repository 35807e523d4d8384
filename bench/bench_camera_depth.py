"""Camera chains capped at max_depth 8 (the old default) against the Light Paths limits
alone (the default since s15, max_depth 1024): CPU time (time.process_time, one worker),
specular rays and mean brightness per scene, interleaved, best of `repeat`. Scenes: the
API's Cornell box with its glass sphere, tests/test_effects.py's five glass slabs (chains
past 8 bounces), and pickled engine scenes given on the command line (e.g. /tmp/pk/*.pkl).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_camera_depth.py [--repeat 2] [scene.pkl ...]
"""
import argparse
import os
import pickle
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "tests"))

from engine import RenderSettings, jit  # noqa: E402
from engine.api import cornell_box  # noqa: E402
from engine.render import render  # noqa: E402
from test_effects import _glass_slabs  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("pickles", nargs="*")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--spp", type=int, default=16)
    a = ap.parse_args()
    jit.ensure_compiled()
    scenes = {"cornell_box": cornell_box(80, 60), "glass_slabs": _glass_slabs()}
    for path in a.pickles:
        sc = pickle.load(open(path, "rb"))
        sc.width, sc.height = 80, 60
        scenes[os.path.basename(path)] = sc
    print(f"load {os.getloadavg()[0]:.1f}; {a.spp} spp, 1 worker, best of {a.repeat}")
    print("| scene | max_depth | CPU s | specular rays | mean |")
    print("|---|---:|---:|---:|---:|")
    for name, sc in scenes.items():
        res = {8: [], 1024: []}
        for _ in range(a.repeat):
            for d in res:
                t = time.process_time()
                f = render(sc, RenderSettings(spp=a.spp, workers=1, max_depth=d))
                res[d].append((time.process_time() - t, f.stats["specular_rays"],
                               float(f.combined.mean())))
        for d, runs in res.items():
            print(f"| {name} | {d} | {min(r[0] for r in runs):.2f} | {runs[0][1]:,} | "
                  f"{runs[0][2]:.5f} |")


if __name__ == "__main__":
    main()
