"""CPU seconds and peak memory of example blends rendered by engine.render, one per child
process (so each peak is the render's own), at a small size: the side-by-side cost check of
a change against another checkout (run it from each).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_blend_cost.py [--blends figure6_box,...]
        [--size 160x120] [--spp 16] [--workers 1] [--repeat 2]

Each blend is exported once through the add-on into $TMPDIR/film_hashes/
(bench/bench_kernels.exported, shared with tools/film_hashes.py). Prints a table: blend,
CPU s of the render (process_time, the export and the kernels' load not counted), peak
resident MB of the process (ru_maxrss) and the MB it held before the render.
"""
import argparse
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

CHILD = """
import pickle, resource, sys, time
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
ensure_compiled()
path, w, h, spp, workers = sys.argv[1], *map(int, sys.argv[2:6])
with open(path, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = w, h
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.process_time()
render(scene, RenderSettings(workers=workers, spp=spp))
cpu = time.process_time() - t
print(cpu, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, before / 1024)
"""


def main(argv=None):
    from bench_kernels import exported
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure6_box,figure7_blocker")
    ap.add_argument("--size", default="160x120", help="WIDTHxHEIGHT")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=2, help="renders per blend (a row each)")
    args = ap.parse_args(argv)
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        ap.error(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 160x120")
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=ROOT)
    print(f"{'blend':<18} {'CPU s':>7} {'peak MB':>8} {'before MB':>9}")
    for name in args.blends.split(","):
        path = exported(name, where)
        for _ in range(args.repeat):
            out = subprocess.run([sys.executable, "-c", CHILD, path, str(width), str(height),
                                  str(args.spp), str(args.workers)], env=env, check=True,
                                 capture_output=True, text=True).stdout.split()
            cpu, peak, before = (float(v) for v in out[-3:])
            print(f"{name:<18} {cpu:7.2f} {peak:8.0f} {before:9.0f}", flush=True)


if __name__ == "__main__":
    main()
