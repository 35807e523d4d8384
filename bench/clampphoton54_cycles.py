"""Cycles' Clamp Indirect per photon (clampphoton54, engine/photonclamp.py): ours against
Cycles at the same Clamp Indirect, per region, on bench/clampray53_cycles.py's scenes,
before (engine.photonclamp.PER_PHOTON False: the estimates clamped as a whole, main's
clamp) and after (each photon weighed as the Cycles path it ends).

    PYTHONPATH=$PWD .venv/bin/python bench/clampphoton54_cycles.py SCENE [--out DIR]
        [--cycles-spp N] [--seeds 0] [--clamps 10,1]

SCENE: ball, room, jewel1, jewel0 (bench/clampray53_cycles.py's docstring: the scenes,
their regions, the settings). Cycles at --cycles-spp, seed 0, and ours' renders are
cached in --out (.npy; clampray53_cycles.py's names: its "o0" files are the before
renders, integrator.CLAMP_PER_GATHER_RAY False; the after renders are "p1"), so that
script's caches serve as both Cycles' and the before images. Prints a table per scene:
each region's mean luminance, Cycles' own, and ours' before / after over Cycles' at the
same clamp.
"""
from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (ROOT, os.path.join(ROOT, "bench"), os.path.join(ROOT, "tools")):
    if p not in sys.path:
        sys.path.insert(0, p)

import clampray53_cycles as R  # noqa: E402


def main():
    a = R.parse("/tmp/clampphoton54", "0", "10,1", __doc__)
    import engine.integrator as I
    import engine.photonclamp as P
    I.CLAMP_PER_GATHER_RAY = False

    def switch(per_photon):
        P.PER_PHOTON = per_photon

    R.clamp_table(a, switch, lambda on, seed, clamp:
                  f"{a.scene}_{'p1' if on else 'o0'}_s{seed}_clamp{clamp:g}.npy",
                  show_cpu=True)


if __name__ == "__main__":
    main()
