"""Accuracy vs time: what each setting costs and what it buys, against Cycles.

Renders the paper's Figure 6 box (glass ball, 160x120, engine API) at a ladder of settings
— the defaults, the paper's Figure 6 ladder, the quality presets, and one progressive run —
measures wall time, relMSE and mean HDR-FLIP against a converged Cycles reference, renders
Cycles itself at 4..1024 samples for its curve on the same axes; then does the same for
every scene of bench/bench_accuracy_blends.py through the add-on (the example blends, the
Figure 7 mirror-floor room, issue 14's Principled spheres) and writes:

    docs/accuracy_time.md     summary per scene (our default render against Cycles' curve:
                              Cycles' FLIP at our time, Cycles' time at our FLIP / ours),
                              then the Figure 6 box table (also .csv)
    docs/accuracy_time.png    error vs time, log-log, one panel per metric
    docs/accuracy_time_<scene>.md/.csv/.png   per scene (bench_accuracy_blends.py)
    docs/figure6_ladder.png   image strip like the paper's Figure 6
    engine/presets_measured.json   the numbers behind the preset labels

    .venv/bin/python bench/bench_accuracy.py [--quick] [--ref-samples 4096]
                                             [--scenes figure7_mirror,...] [--no-scenes]
                                             [--presets-only]
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


def _loglog(x, xs, ys):
    """y at x on the piecewise-linear log-log curve through (xs, ys), extended past its
    ends by the end segments' slopes; (y, extrapolated)."""
    lx, lxs, lys = np.log(x), np.log(xs), np.log(ys)
    order = np.argsort(lxs)
    lxs, lys = lxs[order], lys[order]
    if lxs[0] <= lx <= lxs[-1]:
        return float(np.exp(np.interp(lx, lxs, lys))), False
    i = 0 if lx < lxs[0] else len(lxs) - 2
    slope = (lys[i + 1] - lys[i]) / (lxs[i + 1] - lxs[i])
    return float(np.exp(lys[i] + slope * (lx - lxs[i]))), True


def equal_error(rows, ours):
    """Ours against Cycles' own curve (the 'cycles' rows, time vs FLIP, log-log):
    Cycles' FLIP at our time, and the time Cycles needs to reach our FLIP divided by ours
    (> 1: we get there faster). Values from beyond Cycles' measured range are extrapolated
    along its end segment and flagged. FLIP falls slower than 1/sqrt(time) once the
    reference's own noise shows, so Cycles' time for a FLIP below its last rung is a
    rough estimate."""
    cyc = [r for r in rows if r["kind"] == "cycles"]
    ts = np.array([r["seconds"] for r in cyc], float)
    fs = np.array([r["flip"] for r in cyc], float)
    flip_at_our_time, ext_f = _loglog(ours["seconds"], ts, fs)
    # time as a function of FLIP along the curve (FLIP falls as time grows)
    order = np.argsort(ts)
    keep = fs[order] <= np.minimum.accumulate(fs[order])  # the monotone part of the curve
    t_needed, ext_t = _loglog(ours["flip"], fs[order][keep], ts[order][keep])
    return dict(cycles_flip_at_our_time=flip_at_our_time, flip_extrapolated=ext_f,
                cycles_time_at_our_flip=t_needed, time_extrapolated=ext_t,
                time_ratio=t_needed / ours["seconds"])


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
    ap.add_argument("--scenes", help="comma-separated scenes of bench_accuracy_blends.py "
                                     "to re-render (default: all; the others are "
                                     "read from their docs/accuracy_time_<scene>.csv)")
    ap.add_argument("--no-scenes", action="store_true",
                    help="only the Figure 6 box (no Blender scenes)")
    ap.add_argument("--fast", action="store_true",
                    help="scenes: only Cycles' curve and our default render (the summary)")
    ap.add_argument("--no-figure6", action="store_true",
                    help="keep the Figure 6 box rows of docs/accuracy_time.csv (no re-render)")
    ap.add_argument("--ladder-only", action="store_true",
                    help="only docs/figure6_ladder.png (the paper's ladder on the Figure 6 "
                         "box: photon hits over renders), no docs tables")
    ap.add_argument("--presets-only", action="store_true",
                    help="only the presets on the Figure 6 box: rewrite "
                         "engine/presets_measured.json, no docs (after a preset changes)")
    args = ap.parse_args(argv)
    if args.ladder_only:
        scene = cornell_box(args.width, args.height)
        write_strip([paper_rung(scene, photons, r)[1:] for photons, r in PAPER_LADDER], None)
        return
    if args.presets_only:
        scene = cornell_box(args.width, args.height)
        ref, _ = reference(scene, args.ref_samples)
        rows = []
        measure_presets(scene, ref, args, rows)
        return rows
    if args.no_figure6:
        rows, ref_secs = read_rows(os.path.join(DOCS, "accuracy_time.csv")), None
        with open(os.path.join(DOCS, "accuracy_time.md")) as f:
            import re
            m = re.search(r"Reference: Cycles \d+ spp \((\d+) s\)", f.read())
            ref_secs = float(m.group(1)) if m else float("nan")
    else:
        rows, ref_secs = figure6(args)
    summary = []
    if any(r["kind"] == "default" for r in rows):
        summary.append(summarize("figure6_box (engine API, 160x120)", rows,
                                 f"{args.ref_samples} spp"))
    import bench_accuracy_blends as B
    rerun = set() if args.no_scenes else set(args.scenes.split(",") if args.scenes
                                             else B.SCENES)
    for name in B.SCENES:
        csv_path = os.path.join(DOCS, f"accuracy_time_{name}.csv")
        if name in rerun:
            scene_rows = B.run(name, args.quick, args.fast)
        elif os.path.isfile(csv_path):
            scene_rows = read_rows(csv_path)  # as last measured
        else:
            continue
        if not any(r["kind"] == "default" for r in scene_rows):
            continue  # measured before the default row existed
        judge = B.JUDGE.get(name, name)  # the scene both renderers were scored on
        meta = B.A.load_scene_meta(judge)
        w, h = B.A.SIZES.get(judge, (B.A.WIDTH, B.A.HEIGHT))
        label = name if judge == name else f"{name}, judged on {judge}"
        summary.append(summarize(f"[{label}](accuracy_time_{name}.md) ({w}x{h})",
                                 scene_rows, reference_text(meta)))
    print_summary(summary)
    write_report(rows, ref_secs, args, summary=summary)
    write_plot(rows, args)
    return rows


def read_rows(path):
    """Rows of a table written by write_report (its .csv), numbers as numbers."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for key in ("seconds", "relmse", "flip", "brightness"):
            r[key] = float(r[key])
    return rows


def paper_rung(scene, photons, r):
    """One rung of the paper's ladder (fixed radius r in paper units, classic estimator, no
    final gather, 16 spp): (seconds, label, photon-hit view, render)."""
    st = RenderSettings(photons=photons, caustic_photons=photons // 2, radius=r * PAPER_SCALE,
                        paper_mode=True, spp=16)
    t0 = time.perf_counter()
    film = render(scene, st)
    return (time.perf_counter() - t0, f"{photons:,} / r={r * PAPER_SCALE:.2f}",
            film.photon_hits, film.combined)


def figure6(args):
    """The Figure 6 box (engine API) ladder; writes its strip and the presets' measured
    numbers; returns (rows, reference seconds)."""
    scene = cornell_box(args.width, args.height)
    ref, ref_secs = reference(scene, args.ref_samples)
    rows, strip = [], []

    def measure(kind, label, img, secs, note=""):
        rows.append(score(ref, kind, label, img, secs, note))

    # Cycles curve on the same scene.
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import cycles_scene
    for spp in ([4, 16, 64] if args.quick else [4, 16, 64, 256, 1024]):
        img, secs = cycles_scene.render(scene, spp, seed=1)
        measure("cycles", f"{spp} spp", img, secs)

    t0 = time.perf_counter()
    film = render(scene, RenderSettings())
    measure("default", "default settings", film.combined, time.perf_counter() - t0)

    # The paper's ladder: fixed radius, paper estimator, no final gather (Fig. 6).
    for photons, r in (PAPER_LADDER[:2] if args.quick else PAPER_LADDER):
        secs, label, hits, img = paper_rung(scene, photons, r)
        measure("paper", f"{photons:,} photons, r={r * PAPER_SCALE:.2f} m", img, secs,
                "classic estimator, no final gather")
        strip.append((label, hits, img))

    measured = measure_presets(scene, ref, args, rows, write=False)

    # Progressive: error after each pass of one run.
    def on_pass(film, info):
        if info["passes"] in (1, 2, 4, 8, 16, 32):
            measure("progressive", f"{info['passes']} passes ({info['photons']:,} photons)",
                    film.combined, info["elapsed"],
                    f"estimated relMSE {info['error_estimate']:.4f}")
    render_progressive(scene, RenderSettings(spp=8, photons=100_000, caustic_photons=50_000),
                       Budget(passes=4 if args.quick else 16), on_pass=on_pass)

    write_strip(strip, ref)
    if not args.quick:
        with open(MEASURED_FILE, "w") as f:
            json.dump(measured, f, indent=1)
    return rows, ref_secs


def measure_presets(scene, ref, args, rows, write=True):
    """Render the Figure 6 box with every preset (wall seconds, 2 workers), append their
    rows; {preset: numbers} for engine/presets_measured.json (written if `write` and the
    run is not --quick)."""
    measured = {}
    for name, overrides in PRESETS.items():
        if args.quick and name == "reference":
            continue
        t0 = time.perf_counter()
        film = render(scene, RenderSettings(**overrides))
        secs = time.perf_counter() - t0
        rows.append(score(ref, "preset", name, film.combined, secs))
        measured[name] = dict(seconds=secs, relmse=rows[-1]["relmse"], flip=rows[-1]["flip"],
                              scene=f"Figure 6 box {args.width}x{args.height}, 2 cores",
                              width=args.width, height=args.height)
    if write and not args.quick:
        with open(MEASURED_FILE, "w") as f:
            json.dump(measured, f, indent=1)
    return measured


def reference_text(meta):
    """'N spp, relMSE floor x': the reference's samples and its own relMSE, estimated from
    a render at n spp (another seed) scored against it: relMSE_n ~ v (1/n + 1/N), so the
    reference's own is relMSE_n q / (1 + q), q = n / N."""
    n, big = meta.get("cycles_low_samples"), meta.get("cycles_samples")
    if not n or not big or "cycles_low_relmse" not in meta:
        return f"{big or '?'} spp"
    q = n / big
    return f"{big} spp, own relMSE ~{meta['cycles_low_relmse'] * q / (1 + q):.4f}"


def summarize(scene, rows, ref_text):
    """One summary row: our default render and our best row against Cycles' curve."""
    default = next(r for r in rows if r["kind"] == "default")
    ours = [r for r in rows if r["kind"] != "cycles"]
    best = max(ours, key=lambda r: equal_error(rows, r)["time_ratio"])
    return dict(scene=scene, reference=ref_text, default=default,
                default_eq=equal_error(rows, default), best=best,
                best_eq=equal_error(rows, best))


def _flag(value, extrapolated, fmt):
    return ("~" if extrapolated else "") + format(value, fmt)


SUMMARY_HEADER = [
    "| scene | reference | ours default: s / FLIP | Cycles FLIP at that time | Cycles s at "
    "our FLIP | equal-FLIP time ratio | best of our settings: ratio |",
    "|---|---|---:|---:|---:|---:|---|",
]


def summary_lines(summary):
    lines = list(SUMMARY_HEADER)
    for s in summary:
        d, e, b = s["default"], s["default_eq"], s["best_eq"]
        lines.append(
            f"| {s['scene']} | {s['reference']} | {d['seconds']:.1f} / {d['flip']:.4f} | "
            f"{_flag(e['cycles_flip_at_our_time'], e['flip_extrapolated'], '.4f')} | "
            f"{_flag(e['cycles_time_at_our_flip'], e['time_extrapolated'], '.1f')} | "
            f"**{_flag(e['time_ratio'], e['time_extrapolated'], '.2f')}** | "
            f"{s['best']['kind']}: {s['best']['setting']}, "
            f"{_flag(b['time_ratio'], b['time_extrapolated'], '.2f')} |")
    return lines


def print_summary(summary):
    print("\n".join(summary_lines(summary)), flush=True)


def write_report(rows, ref_secs, args, suffix="", title=None, summary=None, extra=()):
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
    ]
    if summary:
        lines = [
            "# Accuracy vs time against Cycles",
            "",
            f"Made by `.venv/bin/python bench/bench_accuracy.py` ({time.strftime('%Y-%m-%d')},"
            f" {os.cpu_count()} cores, load average {os.getloadavg()[1]:.1f} over the last 5 "
            "minutes of the run; times are wall-clock, ours and Cycles' measured in turn "
            "in one process, so a busy machine slows both alike). Each scene: our render at "
            "default settings placed on Cycles' own error-vs-time curve (Cycles at 4..1024 "
            "spp, log-log interpolation; ~ marks a value extrapolated beyond the curve's "
            "ends). *Cycles FLIP at that time*: Cycles' mean HDR-FLIP after our render time "
            "(ours is better when our FLIP is lower). *Equal-FLIP time ratio*: the time "
            "Cycles needs to reach our FLIP divided by ours (> 1: we are faster). The "
            "reference column gives its samples and its own relMSE (its noise floor: the "
            "FLIP of a render much closer to it than that is not meaningful). Per-scene "
            "tables and plots are linked."
            + (" The Figure 6 box table below was kept from an earlier run (--no-figure6)."
               if getattr(args, "no_figure6", False) else ""),
            "",
        ] + summary_lines(summary) + ["", ""] + ["#" + lines[0]] + lines[1:]
    lines += [
        "| renderer | setting | seconds | relMSE | FLIP | brightness | note |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        lines.append(f"| {r['kind']} | {r['setting']} | {r['seconds']:.1f} | {r['relmse']:.4f} | "
                     f"{r['flip']:.4f} | {r['brightness']:.3f} | {r['note']} |")
    lines += ["", f"![error vs time](accuracy_time{suffix}.png)", ""] + list(extra)
    if not suffix:
        lines += ["![Figure 6 ladder](figure6_ladder.png)", ""]
    with open(os.path.join(DOCS, f"accuracy_time{suffix}.md"), "w") as f:
        f.write("\n".join(lines))


def write_plot(rows, args, suffix="", title=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    styles = {"cycles": "o-", "default": "*", "paper": "s--", "preset": "D-",
              "progressive": "^-"}
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
