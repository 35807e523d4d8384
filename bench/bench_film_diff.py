"""Where two checkouts' films differ: each blend (the film_hashes exports) rendered as
tools/film_hashes.py renders it (80x60, 16 spp, default settings) by a child process per
checkout and worker count, then per blend the SHA-1 of each (tools/film_hashes.film_hash),
the pixels whose image (the passes' sum) differs, the summed image of each and the mean and
largest change of the changed pixels. Prints a table.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_film_diff.py --base ROOT \
        [--base-cache DIR] [--blends figure3_sphere,figure7_blocker] [--workers 1]

--base ROOT: the other checkout (e.g. `git archive ca876ee | tar -x -C ROOT`), its numba
cache --base-cache (NUMBA_CACHE_DIR of this process otherwise).
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, os.path.join(ROOT, "tools"))

from bench_kernels import exported  # noqa: E402

CHILD = r"""
import pickle, sys, numpy as np
sys.path.insert(0, "{root}/tools")
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
from film_hashes import PASSES, film_hash
ensure_compiled()
with open("{pkl}", "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = {w}, {h}
film = render(scene, RenderSettings(workers={workers}, spp={spp}))
np.savez("{out}", hash=film_hash(film), **{{p: getattr(film, p) for p in PASSES}})
"""


def run(root, cache, pkl, out, w, h, workers, spp):
    env = dict(os.environ, PYTHONPATH=root)
    if cache:
        env["NUMBA_CACHE_DIR"] = cache
    code = CHILD.format(root=root, pkl=pkl, out=out, w=w, h=h, workers=workers, spp=spp)
    subprocess.run([sys.executable, "-c", code], env=env, cwd=root, check=True)
    got = np.load(out)
    image = sum(got[p] for p in got.files if p != "hash")
    return str(got["hash"]), image


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True)
    ap.add_argument("--base-cache", default=None)
    ap.add_argument("--blends", default="figure3_sphere,figure7_blocker")
    ap.add_argument("--workers", type=int, nargs="+", default=[1])
    ap.add_argument("--size", default="80x60")
    ap.add_argument("--spp", type=int, default=16)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    os.makedirs(where, exist_ok=True)
    work = tempfile.mkdtemp(prefix="film_diff")
    print("| blend | workers | base SHA-1 | this SHA-1 | pixels changed | base image sum | "
          "this image sum | mean change (changed pixels) | largest change |")
    print("|---|---:|---|---|---:|---:|---:|---:|---:|")
    for name in args.blends.split(","):
        pkl = exported(name, where)
        for workers in args.workers:
            hb, ib = run(os.path.abspath(args.base), args.base_cache, pkl,
                         os.path.join(work, f"{name}_{workers}_base.npz"), w, h, workers,
                         args.spp)
            ha, ia = run(ROOT, None, pkl, os.path.join(work, f"{name}_{workers}_this.npz"),
                         w, h, workers, args.spp)
            d = (ia - ib).reshape(h * w, -1).sum(axis=1)
            changed = np.flatnonzero(np.any((ia != ib).reshape(h * w, -1), axis=1))
            mean = d[changed].mean() if len(changed) else 0.0
            big = np.abs(d).max() if len(changed) else 0.0
            print(f"| {name} | {workers} | {hb[:8]} | {ha[:8]} | {len(changed)} | "
                  f"{ib.sum():.4f} | {ia.sum():.4f} | {mean:+.5f} | {big:.5f} |", flush=True)


if __name__ == "__main__":
    main()
