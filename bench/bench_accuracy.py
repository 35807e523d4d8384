"""Accuracy vs time: what each setting costs and what it buys.

Renders the paper's Figure 6 box (glass ball, 160x120) at a ladder of settings — the
paper's Figure 6 ladder, the quality presets, and one progressive run — measures wall
time, relMSE and mean HDR-FLIP against a converged Cycles reference, renders Cycles
itself at 16..1024 samples for its curve on the same axes, and writes:

    docs/accuracy_time.md     table (also .csv)
    docs/accuracy_time.png    error vs time, log-log, one panel per metric
    docs/figure6_ladder.png   image strip like the paper's Figure 6
    engine/presets_measured.json   the numbers behind the preset labels

    .venv/bin/python bench/bench_accuracy.py [--quick] [--ref-samples 4096]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from engine import RenderSettings, render  # noqa: E402
from engine.api import PAPER_FIGURE6_LADDER, PAPER_FIGURE6_RADIUS_SCALE, cornell_box  # noqa: E402
from engine.imageio import replacing, to_8bit  # noqa: E402
from engine.presets import MEASURED_FILE, PRESETS  # noqa: E402
from engine.progressive import Budget, relmse, render_progressive  # noqa: E402

DOCS = os.path.join(ROOT, "docs")
CACHE = os.path.join(ROOT, "out", "bench_cache")
# The paper's Figure 6 ladder (photons, radius in the paper's units) and the scale from
# its units to our 4 m box (engine/api.py, docs/paper_mode.md).
PAPER_LADDER = list(PAPER_FIGURE6_LADDER)
PAPER_SCALE = PAPER_FIGURE6_RADIUS_SCALE


def flip(ref, x):
    import flip_evaluator
    return float(flip_evaluator.evaluate(ref.astype(np.float32), x.astype(np.float32), "HDR")[1])


def score(ref, kind, label, img, secs, note="", prefix=""):
    """One table row: time and errors of `img` against `ref` (printed as it is measured)."""
    row = dict(kind=kind, setting=label, seconds=round(secs, 2),
               relmse=round(relmse(img, ref), 5), flip=round(flip(ref, img), 4),
               brightness=round(float(img.mean() / ref.mean()), 4), note=note)
    print(f"{prefix}{kind:12s} {label:34s} {secs:7.1f} s  relMSE {row['relmse']:.4f}  "
          f"FLIP {row['flip']:.4f}  brightness {row['brightness']:.3f}", flush=True)
    return row


def reference(scene, samples):
    os.makedirs(CACHE, exist_ok=True)
    path = os.path.join(CACHE, f"figure6_{scene.width}x{scene.height}_{samples}.npy")
    if os.path.exists(path):
        meta = json.load(open(path + ".json"))
        return np.load(path).astype(np.float32), meta["seconds"]
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import cycles_scene
    img, secs = cycles_scene.render(scene, samples)
    with open(path + ".json", "w") as f:  # first: the .npy marks a complete cache entry
        json.dump({"seconds": secs, "samples": samples}, f)
    with replacing(path) as tmp:  # an interrupted run must not leave a truncated reference
        np.save(tmp, img.astype(np.float32))
    return img, secs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--ref-samples", type=int, default=4096)
    ap.add_argument("--quick", action="store_true", help="fewer rungs (a smoke run)")
    args = ap.parse_args(argv)
    scene = cornell_box(args.width, args.height)
    ref, ref_secs = reference(scene, args.ref_samples)
    rows, strip = [], []

    def measure(kind, label, img, secs, note=""):
        rows.append(score(ref, kind, label, img, secs, note))

    # Cycles curve on the same scene.
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import cycles_scene
    for spp in ([16, 64] if args.quick else [16, 64, 256, 1024]):
        img, secs = cycles_scene.render(scene, spp, seed=1)
        measure("cycles", f"{spp} spp", img, secs)

    # The paper's ladder: fixed radius, paper estimator, no final gather (Fig. 6).
    for photons, r in (PAPER_LADDER[:2] if args.quick else PAPER_LADDER):
        st = RenderSettings(photons=photons, caustic_photons=photons // 2, radius=r * PAPER_SCALE,
                            paper_mode=True, spp=16)
        t0 = time.perf_counter()
        film = render(scene, st)
        secs = time.perf_counter() - t0
        measure("paper", f"{photons:,} photons, r={r * PAPER_SCALE:.2f} m", film.combined, secs,
                "classic estimator, no final gather")
        strip.append((f"{photons:,} / r={r * PAPER_SCALE:.2f}", film.photon_hits, film.combined))

    # Presets.
    measured = {}
    for name, overrides in PRESETS.items():
        if args.quick and name == "reference":
            continue
        t0 = time.perf_counter()
        film = render(scene, RenderSettings(**overrides))
        secs = time.perf_counter() - t0
        measure("preset", name, film.combined, secs)
        measured[name] = dict(seconds=secs, relmse=rows[-1]["relmse"], flip=rows[-1]["flip"],
                              scene=f"Figure 6 box {args.width}x{args.height}, 2 cores",
                              width=args.width, height=args.height)

    # Progressive: error after each pass of one run.
    def on_pass(film, info):
        if info["passes"] in (1, 2, 4, 8, 16, 32):
            measure("progressive", f"{info['passes']} passes ({info['photons']:,} photons)",
                    film.combined, info["elapsed"],
                    f"estimated relMSE {info['error_estimate']:.4f}")
    render_progressive(scene, RenderSettings(spp=8, photons=100_000, caustic_photons=50_000),
                       Budget(passes=4 if args.quick else 16), on_pass=on_pass)

    write_report(rows, ref_secs, args)
    write_plot(rows, args)
    write_strip(strip, ref)
    if not args.quick:
        with open(MEASURED_FILE, "w") as f:
            json.dump(measured, f, indent=1)
    return rows


def write_report(rows, ref_secs, args, suffix="", title=None):
    os.makedirs(DOCS, exist_ok=True)
    with open(os.path.join(DOCS, f"accuracy_time{suffix}.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    scene_text = title or "the paper's Figure 6 box with a glass ball (engine.api.cornell_box)"
    command = ("bench/bench_accuracy_blends.py" if suffix else "bench/bench_accuracy.py")
    lines = [
        f"# Accuracy vs time: {title or 'Figure 6 box'}",
        "",
        f"Scene: {scene_text}, {args.width}x{args.height}, 2 cores. "
        f"Reference: Cycles {args.ref_samples} spp ({ref_secs:.0f} s), box filter, no "
        "denoising or clamping. relMSE and mean HDR-FLIP (docs/design.md, Measuring "
        "accuracy); lower is better. "
        "Cycles rows are Cycles itself at fewer samples, timed on the same machine.",
        "",
        f"Regenerate: `.venv/bin/python {command}`.",
        "",
        "| renderer | setting | seconds | relMSE | FLIP | brightness | note |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        lines.append(f"| {r['kind']} | {r['setting']} | {r['seconds']:.1f} | {r['relmse']:.4f} | "
                     f"{r['flip']:.4f} | {r['brightness']:.3f} | {r['note']} |")
    lines += ["", f"![error vs time](accuracy_time{suffix}.png)", ""]
    if not suffix:
        lines += ["![Figure 6 ladder](figure6_ladder.png)", ""]
    with open(os.path.join(DOCS, f"accuracy_time{suffix}.md"), "w") as f:
        f.write("\n".join(lines))


def write_plot(rows, args, suffix="", title=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    styles = {"cycles": "o-", "paper": "s--", "preset": "D-", "progressive": "^-"}
    for ax, metric in zip(axes, ("relmse", "flip")):
        for kind, style in styles.items():
            pts = [(r["seconds"], r[metric]) for r in rows if r["kind"] == kind]
            if pts:
                x, y = zip(*pts)
                ax.plot(x, y, style, label=kind)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("relMSE" if metric == "relmse" else "mean HDR-FLIP")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(f"{title or 'Figure 6 box'} {args.width}x{args.height}: error vs time (2 cores)")
    fig.tight_layout()
    with replacing(os.path.join(DOCS, f"accuracy_time{suffix}.png")) as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)


def write_strip(strip, ref):
    """Paper Fig. 6: photon hits (top) and the render (bottom) for each ladder rung."""
    if not strip:
        return
    top = np.concatenate([to_8bit(hits) for _, hits, _ in strip], axis=1)
    bottom = np.concatenate([to_8bit(img) for _, _, img in strip], axis=1)
    from PIL import Image
    with replacing(os.path.join(DOCS, "figure6_ladder.png")) as tmp:
        Image.fromarray(np.concatenate([top, bottom], axis=0)).save(tmp)


if __name__ == "__main__":
    main()
