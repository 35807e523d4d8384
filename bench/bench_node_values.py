"""Per-hit cost of the value nodes Map Range, Blackbody and the Wave Texture, beside the
Noise Texture, in CPU nanoseconds per hit (best of 3, process time).

    .venv/bin/python bench/bench_node_values.py [--hits 200000]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import shadernodes as sn  # noqa: E402


class _Points:
    """Fixed coordinates per hit (a stand-in for Generated / UV coordinates)."""

    def __init__(self, pts):
        self.pts = pts

    def evaluate(self, geo, prim, u, v):
        return self.pts[prim]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--hits", type=int, default=200_000)
    n = p.parse_args(argv).hits
    pts = np.random.default_rng(0).uniform(-1, 1, (n, 3))
    value = _Points(np.repeat(pts[:, :1], 3, axis=1))  # read as its luminance: x
    nodes = {
        "Map Range Linear": sn.MapRange({"Value": value}),
        "Map Range Smoother Step": sn.MapRange({"Value": value}, kind="SMOOTHERSTEP"),
        "Blackbody (800-12000 K)": sn.Blackbody(sn.MapRange(
            {"Value": value, "From Min": -1.0, "To Min": 800.0, "To Max": 12000.0})),
        "Wave (no distortion)": sn.Wave(_Points(pts)),
        "Wave (distortion 4, detail 2.5)": sn.Wave(_Points(pts), {"Distortion": 4.0,
                                                                  "Detail": 2.5}),
        "Noise (default, Fac)": sn.Noise(_Points(pts)),
    }
    prim, zero = np.arange(n), np.zeros(n)
    for name, node in nodes.items():
        node.evaluate(None, prim[:8], zero[:8], zero[:8])  # compile / load kernels
        best = float("inf")
        for _ in range(3):
            t0 = time.process_time()
            node.evaluate(None, prim, zero, zero)
            best = min(best, time.process_time() - t0)
        print(f"{name:34s} {best / n * 1e9:8.1f} ns CPU per hit")


if __name__ == "__main__":
    main()
