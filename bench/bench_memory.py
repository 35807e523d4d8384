"""Peak memory: the estimate engine/resources.py refuses renders with, beside the peak
resident memory measured for the same render (each in a fresh process, ru_maxrss after
the render minus before it). Prints a table; the estimate should stay above the
measurement without being far above it.

    .venv/bin/python bench/bench_memory.py [--quick]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (label, scene, width, height, settings, extra triangles)
CASES = [
    ("defaults 160x120, Figure 3", "figure3", 160, 120, {"spp": 4}, 0),
    ("2M photons", "figure3", 64, 48, {"photons": 2_000_000, "caustic_photons": 0, "spp": 1}, 0),
    ("4M photons", "figure3", 64, 48, {"photons": 4_000_000, "caustic_photons": 0, "spp": 1}, 0),
    ("2M photons, closed box", "box", 32, 24, {"photons": 2_000_000, "caustic_photons": 0,
                                               "spp": 1}, 0),
    ("4M caustic photons", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 4_000_000,
                                               "spp": 1}, 0),
    ("1024x1024, 1 spp", "figure3", 1024, 1024, {"photons": 1000, "caustic_photons": 0,
                                                 "spp": 1}, 0),
    ("256 spp, 64x48", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 0, "spp": 256}, 0),
    ("256 spp, 8 gather rays", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 0,
                                                   "spp": 256, "gather_rays": 8}, 0),
    ("1M triangles", "figure3", 64, 48, {"photons": 1000, "caustic_photons": 0, "spp": 1},
     1_000_000),
]
QUICK = {"defaults 160x120, Figure 3", "2M photons", "256 spp, 64x48"}

CHILD = r"""
import json, resource, sys
sys.path.insert(0, ROOT)
import numpy as np
from engine import RenderSettings, render
from engine.api import cornell_box
from engine.resources import estimate_memory
from engine.scene import Mesh
from engine.scenefile import load_scene
scene = cornell_box() if NAME == "box" else load_scene(ROOT + "/scenes/figure3.toml")[0]
scene.width, scene.height = W, H
if TRIS:
    n = int((TRIS / 2) ** 0.5)
    xs = np.linspace(-3, 3, n + 1)
    X, Y = np.meshgrid(xs, xs)
    V = np.stack([X.ravel(), Y.ravel() + 3, np.full(X.size, 0.01)], 1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    F = np.concatenate([np.stack([i, i + 1, i + n + 2], 1), np.stack([i, i + n + 2, i + n + 1], 1)])
    scene.add_mesh(Mesh("grid", V, F, materials=["white_plastic_dull"]))
    del V, F, X, Y, i
settings = RenderSettings(**SETTINGS)
est = estimate_memory(scene, settings)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
film = render(scene, settings)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"estimate": est.total, "parts": est.parts, "measured": peak - before}))
"""


def run(case):
    label, name, w, h, settings, tris = case
    code = (f"ROOT={ROOT!r}; NAME={name!r}; W={w}; H={h}; TRIS={tris}; "
            f"SETTINGS={settings!r}\n" + CHILD)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="three cases only")
    args = ap.parse_args()
    mb = 1 << 20
    print("| render | estimate (MB) | measured peak (MB) | estimate / measured | largest part |")
    print("|---|---|---|---|---|")
    for case in CASES:
        if args.quick and case[0] not in QUICK:
            continue
        r = run(case)
        largest = max(r["parts"], key=r["parts"].get)
        print(f"| {case[0]} | {r['estimate'] / mb:.0f} | {r['measured'] / mb:.0f} | "
              f"{r['estimate'] / max(r['measured'], 1):.2f} | {largest} |", flush=True)


if __name__ == "__main__":
    main()
