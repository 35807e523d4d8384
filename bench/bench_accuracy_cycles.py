"""Accuracy against Cycles: one command writes docs/accuracy.md and docs/accuracy/*.png.

    .venv/bin/python bench/bench_accuracy_cycles.py [--only NAME[,NAME]] [--rerender-cycles]

For every scene with a stored reference (tests/references/, made by
tools/make_references.py) renders our engine through the add-on at its default settings and
the reference's resolution, and scores it against the Cycles reference: brightness ratio
(mean ours / mean Cycles), relMSE, mean HDR-FLIP (docs/design.md, Measuring accuracy). Cycles at 256 spp is
scored the same way (from references.json, or re-rendered with --rerender-cycles) for the
"no worse than Cycles at 256 samples" comparison. Strips: ours | Cycles | FLIP error map.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import accuracy_scenes as acc  # noqa: E402

DOCS = os.path.join(ROOT, "docs")
STRIPS = os.path.join(DOCS, "accuracy")
TARGET_BRIGHT = {"diffuse": 0.02, "specular": 0.05}
TARGET_RELMSE = {"diffuse": 0.02, "specular": None}


def to_srgb8(x, exposure=1.0):
    x = np.clip(np.asarray(x, np.float64) * exposure, 0, 1)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (s * 255 + 0.5).astype(np.uint8)


def write_strip(path, ours, ref, flip_map, scale=2):
    from matplotlib import cm
    # exposure: the reference's 99th percentile maps to 1 (bright lights may clip)
    p99 = float(np.percentile(ref, 99)) or 1.0
    fm = np.asarray(flip_map, np.float64)
    if fm.ndim == 3 and np.allclose(fm, fm[..., :1]):
        fm = fm[..., 0]  # grey error values: colour them
    if fm.ndim == 2:
        fm = cm.magma(np.clip(fm, 0, 1))[..., :3]
    fm = (np.clip(fm, 0, 1) * 255 + 0.5).astype(np.uint8)  # else: FLIP's own colour map
    gap = np.full((ref.shape[0], 2, 3), 255, np.uint8)
    strip = np.concatenate([to_srgb8(ours, 1 / p99), gap, to_srgb8(ref, 1 / p99), gap, fm],
                           axis=1)
    strip = strip.repeat(scale, 0).repeat(scale, 1)
    import matplotlib.pyplot as plt
    plt.imsave(path, strip)


def settings_text():
    from engine.settings import RenderSettings
    d = RenderSettings()
    return (f"defaults: {d.photons // 1000}k+{d.caustic_photons // 1000}k photons, "
            f"{d.spp} spp, {d.estimator} k={d.k_nearest}, final gather {d.gather_rays}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", help="comma-separated scene names")
    p.add_argument("--rerender-cycles", action="store_true",
                   help="render Cycles at 256 spp again instead of using references.json")
    args = p.parse_args(argv)
    meta = acc.load_meta()
    names = [n for n in acc.SCENES if n in meta and
             os.path.isfile(os.path.join(acc.REF_DIR, n + ".npy"))]
    if args.only:
        names = [n for n in args.only.split(",") if n in names]
    if not names:
        raise SystemExit("no references: run .venv/bin/python tools/make_references.py")
    os.makedirs(STRIPS, exist_ok=True)
    rows = []
    for name in names:
        m = meta[name]
        ref = acc.load_reference(name)
        ours, t_ours = acc.render_ours(name)
        assert ours.shape == ref.shape, (ours.shape, ref.shape)
        f_ours, fmap = acc.flip(ours, ref, return_map=True)
        row = dict(name=name, kind=m["kind"], res=f"{m['width']}x{m['height']}",
                   cyc_spp=m["cycles_samples"], cyc_t=m["cycles_time_s"], t=t_ours,
                   bright=acc.brightness(ours, ref), relmse=acc.relmse(ours, ref),
                   flip=f_ours, low_spp=m["cycles_low_samples"], low_t=m["cycles_low_time_s"],
                   low_flip=m["cycles_low_flip"], low_relmse=m["cycles_low_relmse"])
        if args.rerender_cycles:
            low, row["low_t"] = acc.render_cycles(name, 256, seed=1)
            row.update(low_spp=256, low_flip=acc.flip(low, ref),
                       low_relmse=acc.relmse(low, ref))
        tb, tr = TARGET_BRIGHT[row["kind"]], TARGET_RELMSE[row["kind"]]
        ok = abs(row["bright"] - 1) <= tb and (tr is None or row["relmse"] <= tr)
        row["ok"] = ("yes" if ok else "**no**") + (
            "" if row["flip"] <= row["low_flip"] else " (FLIP > C256)")
        write_strip(os.path.join(STRIPS, name + ".png"), ours, ref, fmap)
        rows.append(row)
        print(f"{name:18s} ours {t_ours:5.1f} s  bright {row['bright']:.4f}  relMSE "
              f"{row['relmse']:.4f}  FLIP {row['flip']:.4f} | Cycles-{row['low_spp']} FLIP "
              f"{row['low_flip']:.4f} relMSE {row['low_relmse']:.4f}", flush=True)
    write_md(rows)
    return 0


NOTES = [
    "- **figure8_caustic**: Cycles cannot render this scene right. Its spot has radius 0 (a "
    "delta light) and shines through a smooth glass ball, so no Cycles path connects floor -> "
    "glass -> light: it loses the caustic and the light the caustic bounces. The row is kept "
    "as a record, not as a target (the test marks it xfail). **caustic_soft_spot** is the "
    "same scene with a 0.15 m spot, which Cycles can hit through the glass; its reference "
    "needs 65,536 spp. That is the caustic comparison.",
    "- **sun_point** is the one scene where our FLIP is above Cycles-256. The excess sits "
    "where the cube and the ball meet the floor (indirect light 3-4 % dark after two levels "
    "of recursive gathering) and on the sun's hard shadow edges (128 vs 256 samples of pixel "
    "coverage). At 1M photons and 512 spp it is 0.0068, in 7.2 s.",
    "- **Time**: on these small scenes Cycles at 256 spp is 1.5-3x faster than our default "
    "render, whose photon pass and map build are a fixed cost of about 1 s. Our error per "
    "unit of time is set out in [accuracy_time.md](accuracy_time.md).",
    "- **figure7_mirror** (the Figure 7 room with a perfect mirror floor and a 0.1 m point "
    "light, scenes/figure7_mirror.toml): the room's right half is lit only through the "
    "mirror, light Cycles finds slowly. Its reference has 8192 spp (21 min on the shared "
    "2-core machine); Cycles-256 scores relMSE 0.77 against it, so the reference's own "
    "relMSE is about 0.77 x 256/8192 / (1 + 256/8192) = 0.023: errors near that are its "
    "noise floor, not ours.",
    "- **principled_spheres** (issue 14: a row of Principled balls on a rough Principled "
    "floor, area light, dim grey world, 160x120) is scored per object, not here: "
    "tests/test_principled_cycles.py and "
    "[accuracy_time_principled_spheres.md](accuracy_time_principled_spheres.md).",
    "- What was fixed at the estimator to get here (own-photon bias, sparse-cell "
    "correlation, corners and contacts, crowded neighbours, emissive meshes hitting "
    "themselves), with the measurements: [estimator_bias.md](estimator_bias.md).",
]


def write_md(rows):
    lines = [
        "# Accuracy against Cycles",
        "",
        "Made by `.venv/bin/python bench/bench_accuracy_cycles.py` "
        f"({time.strftime('%Y-%m-%d')}, {os.cpu_count()} cores). References: Cycles 5.0.1 "
        "from the bpy wheel, CPU, no denoising, no clamping, filter glossy 0, 32 bounces, "
        "box pixel filter 1 px, no adaptive sampling (`tools/make_references.py`, stored in "
        "`tests/references/`). Ours: through the add-on at its default settings "
        f"({settings_text()}). Times are wall-clock `bpy.ops.render.render` on this "
        "machine.",
        "",
        "Targets (issue 4): brightness within 2 % and relMSE <= 0.02 on diffuse scenes, within "
        "5 % on scenes with glass, mirrors or glossy surfaces; mean HDR-FLIP no worse than "
        "Cycles at 256 spp (C256, another seed, scored against the same reference).",
        "",
        "| scene | kind | res | Cycles spp / time | ours time | brightness | relMSE | FLIP "
        "| C256 FLIP / relMSE / time | target met |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['name']} | {r['kind']} | {r['res']} | {r['cyc_spp']} / {r['cyc_t']:.0f} s "
            f"| {r['t']:.1f} s | {r['bright']:.4f} | {r['relmse']:.4f} | {r['flip']:.4f} "
            f"| {r['low_flip']:.4f} / {r['low_relmse']:.4f} / {r['low_t']:.1f} s | {r['ok']} |")
    lines += ["", "## Notes", ""] + NOTES
    lines += ["", "Strips (`docs/accuracy/NAME.png`): ours | Cycles reference | HDR-FLIP error "
              "map (magma, 0 = black .. 1 = white); both images with the same exposure "
              "(reference 99th percentile = 1), sRGB.", ""]
    for r in rows:
        lines.append(f"![{r['name']}](accuracy/{r['name']}.png)")
    with open(os.path.join(DOCS, "accuracy.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("wrote docs/accuracy.md and docs/accuracy/*.png")


if __name__ == "__main__":
    sys.exit(main())
