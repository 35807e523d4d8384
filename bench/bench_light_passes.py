"""The light passes' cost and checks (engine/lightpasses.py, data_passes "light") on the
paper's example blends: the render's CPU time without and with them (process time, one
worker: steadier than wall time on a shared machine; the photon pass is the same in both), whether the image keeps
its bits, and how far the recombination (Dir + Ind) x Col + Emission + Environment (+
the volume light) is from Combined. Prints a markdown table.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_light_passes.py [--size 160x120]
        [--spp 16] [--workers 1] [--repeat 3] [--blends figure6_box,figure7_blocker,figure8_caustic]

Each blend is exported once through the add-on by a child Blender (bpy) process into
$TMPDIR/film_hashes/ (bench_kernels.exported, shared with tools/film_hashes.py).
"""
import argparse
import os
import pickle
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import numpy as np  # noqa: E402

from bench_kernels import exported  # noqa: E402
from engine import lightpasses  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

EFFECTS = ("direct", "indirect", "caustic", "specular", "emission")


def recombined(film):
    d, sh = film.data, lightpasses.shown(film.data)
    out = sh["emission"] + sh["environment"] + sh["volume"]
    for k in ("diffuse", "glossy", "transmission"):
        out = out + (sh[f"{k}_direct"] + sh[f"{k}_indirect"]) * d[f"{k}_color"]
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--size", default="160x120", help="WIDTHxHEIGHT")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3, help="renders of each; the fastest counts")
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    where = os.path.join(tempfile.gettempdir(), "film_hashes")
    ensure_compiled()
    print(f"| blend | CPU s off | CPU s light | ratio | image bits | max abs "
          f"recombination error / max Combined | Diffuse / Glossy / Transmission "
          f"Direct + Indirect, Emission, Environment: share of Combined |")
    print("|---|---:|---:|---:|---|---|---|")
    for name in args.blends.split(","):
        with open(exported(name, where), "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = width, height
        films, secs = {}, {}
        for _ in range(args.repeat):
            for label, passes in (("off", ()), ("light", ("light",))):
                t = time.process_time()
                films[label] = render(scene, RenderSettings(workers=args.workers,
                                                            spp=args.spp, data_passes=passes))
                took = time.process_time() - t
                secs[label] = min(secs.get(label, took), took)
        off, on = films["off"], films["light"]
        same = all(np.array_equal(getattr(off, n), getattr(on, n)) for n in EFFECTS)
        err = np.abs(recombined(on) - on.combined).max() / max(float(on.combined.max()), 1e-30)
        total = float(on.combined.astype(np.float64).sum())
        d = on.data
        share = [float(sum(d[k].astype(np.float64).sum() for k in keys)) / total
                 for keys in (("diffuse_direct", "diffuse_indirect"),
                              ("glossy_direct", "glossy_indirect"),
                              ("transmission_direct", "transmission_indirect"),
                              ("emission",), ("environment",))]
        print(f"| {name} | {secs['off']:.2f} | {secs['light']:.2f} | "
              f"{secs['light'] / secs['off']:.2f} | {'same' if same else 'DIFFER'} | "
              f"{err:.1e} | {' / '.join(f'{s:.3f}' for s in share)} |", flush=True)


if __name__ == "__main__":
    main()
