"""Quality presets: settings bundles whose labels carry measured cost and error.

The numbers come from `bench/bench_accuracy.py`, which renders its reference scene (the
paper's Figure 6 box with a glass ball, 160x120) with every preset, measures wall time,
relMSE and HDR-FLIP against a converged Cycles reference, and writes them to
presets_measured.json next to this file. Labels are never typed in by hand.
"""
from __future__ import annotations

import json
import os
import re

PRESETS = {
    "preview": dict(photons=50_000, caustic_photons=25_000, spp=8, gather_rays=1, k_nearest=48),
    "medium": dict(photons=200_000, caustic_photons=100_000, spp=32, gather_rays=1,
                   k_nearest=64),
    # The defaults (engine/settings.py): HDR-FLIP of Cycles at 256 spp on simple scenes.
    "high": dict(photons=400_000, caustic_photons=200_000, spp=128, gather_rays=2, k_nearest=64),
    "reference": dict(photons=1_000_000, caustic_photons=500_000, spp=512, gather_rays=2,
                      k_nearest=96),
}
MEASURED_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "presets_measured.json")


def measured() -> dict:
    """{preset: {"seconds": s, "relmse": e, "flip": f, "scene": text}} or {} if not measured."""
    try:
        with open(MEASURED_FILE) as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def measured_size(m: dict) -> tuple[int, int]:
    """The image size a measurement was made at (its 'width' / 'height', else read from
    its scene text '... 160x120 ...'; 160x120 if neither says)."""
    if "width" in m and "height" in m:
        return int(m["width"]), int(m["height"])
    found = re.search(r"(\d+)\s*x\s*(\d+)", str(m.get("scene", "")))
    return (int(found.group(1)), int(found.group(2))) if found else (160, 120)


def label(name: str, width: int | None = None, height: int | None = None) -> str:
    """'High (~10 s, FLIP 0.049)' from the measurements; the bare name if unmeasured.
    With width and height (the file's own resolution) the time is scaled to that many
    pixels and the size is named: 'High (~45 s at 320x240, FLIP 0.033)'. Time per pixel
    is assumed constant (the camera pass dominates; photon tracing does not grow with
    pixels, so small images come out slightly underestimated)."""
    m = measured().get(name)
    title = name.capitalize()
    if not m:
        return title
    if width is None or height is None:
        return f"{title} (~{m['seconds']:.0f} s, FLIP {m['flip']:.3f})"
    w0, h0 = measured_size(m)
    secs = m["seconds"] * (int(width) * int(height)) / float(w0 * h0)
    when = f"{secs:.0f} s" if secs >= 1 else f"{secs:.1f} s"
    return f"{title} (~{when} at {int(width)}x{int(height)}, FLIP {m['flip']:.3f})"


def apply(name: str, overrides: dict | None = None) -> dict:
    if name not in PRESETS:
        raise ValueError(f"unknown quality preset '{name}' (choose {', '.join(PRESETS)})")
    out = dict(PRESETS[name])
    out.update(overrides or {})
    return out
