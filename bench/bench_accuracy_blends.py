"""Accuracy vs time on the example blends, through the add-on.

The same ladder as bench_accuracy.py (the paper's Figure 6 ladder, the quality presets,
progressive passes, Cycles at 16..1024 samples) for each example .blend, rendered through
the Blender add-on at the stored references' resolution (96x72) and scored against the
stored Cycles references (tests/references/, `make references`). Writes, per blend,
docs/accuracy_time_<blend>.md / .csv / .png.

    .venv/bin/python bench/bench_accuracy_blends.py [--only figure6_box,figure3_sphere]
"""
from __future__ import annotations

import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import accuracy_scenes as A  # noqa: E402  (needs the bpy wheel)
from bench_accuracy import PAPER_LADDER, PAPER_SCALE, score, write_plot, write_report  # noqa: E402
from engine.presets import PRESETS  # noqa: E402

BLENDS = ("figure3_sphere", "figure6_box", "figure7_blocker", "figure8_caustic")


def run(name, quick=False):
    ref = A.load_reference(name)
    meta = A.load_meta().get(name, {})
    rows = []

    def measure(kind, label, img, secs, note=""):
        rows.append(score(ref, kind, label, img, secs, note, prefix=f"{name:16s} "))

    for spp in ([16, 64] if quick else [16, 64, 256, 1024]):
        img, secs = A.render_cycles(name, spp, seed=1)
        measure("cycles", f"{spp} spp", img, secs)
    for photons, r in (PAPER_LADDER[:2] if quick else PAPER_LADDER):
        img, secs = A.render_ours(name, photons=photons, caustic_photons=photons // 2,
                                  use_auto_radius=False, radius=r * PAPER_SCALE,
                                  estimator="classic", final_gather=False, spp=16)
        measure("paper", f"{photons:,} photons, r={r * PAPER_SCALE:.2f} m", img, secs,
                "classic estimator, no final gather")
    for preset, overrides in PRESETS.items():
        if quick and preset == "reference":
            continue
        img, secs = A.render_ours(name, **overrides)
        measure("preset", preset, img, secs)
    for passes in ([1, 2] if quick else [1, 2, 4, 8]):
        img, secs = A.render_ours(name, progressive=True, max_passes=passes, spp=8,
                                  photons=100_000, caustic_photons=50_000)
        measure("progressive", f"{passes} passes of 8 spp", img, secs)
    args = argparse.Namespace(width=A.WIDTH, height=A.HEIGHT,
                              ref_samples=meta.get("cycles_samples", "?"))
    suffix = f"_{name}"
    write_report(rows, meta.get("cycles_time_s", float("nan")), args, suffix=suffix,
                 title=f"{name}.blend")
    write_plot(rows, args, suffix=suffix, title=f"{name}.blend")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="comma-separated blend names")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    for name in (args.only.split(",") if args.only else BLENDS):
        run(name, args.quick)


if __name__ == "__main__":
    main()
