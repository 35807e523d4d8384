"""Jensen's compact photon layout, measured before it is built: what storing each photon's
direction as 2 bytes (theta, phi; Jensen, "Realistic Image Synthesis Using Photon
Mapping", 2001, sec. 5.2), its power as 4 (Ward's RGBE, Graphics Gems II) and its normal as
an octahedral 2 x int16 (Cigolle et al. 2014, "A Survey of Efficient Representations for
Independent Unit Vectors") would save and change. The engine keeps float32 (12 B each);
this layout keeps 2 + 4 + 4 = 10 B of those 36, 26 B less per photon in each map that
holds a copy (the global / caustic / glow maps', the gather map's estimating photons).

Simulated, not built: each shot's direction, power and normal are quantized to that
layout and decoded back to float32 before the maps are made (render._build_maps), so
every map and estimate reads the decoded values, as kernels reading the compact layout
would (the gather map's estimating photons' power is then scaled by its float32 share
factors, where a stored layout would round the scaled power: the same error size).
The photon paths are main's: only what is stored changes.

Per scene: the bytes the layout would save per stored photon (26 B x the photons the
maps hold over the stored photons, each Photons once), and the image change against the
float32 layout at the same seed: the combined pass' mean |a - b| / mean a, the largest
per-pixel |a - b| / a over pixels above 1 % of the mean, and, for the scenes with a
Cycles reference (tests/references, tools/accuracy_scenes.py; needs the bpy wheel), the
mean HDR-FLIP of each against it over --seeds at the add-on's defaults.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_photon_layout.py \\
        --pickles $TMPDIR/film_hashes/figure6_box.pkl ... [--flip figure6_box,...] \\
        [--seeds 0,1] [--shipped]

--shipped (compact49): the layout the engine ships (engine/photonlayout.py: octahedral
direction and normal, RGBE power, 12 B of the 36; decoded in the kernels) against the
float32 maps, by its switch photonlayout.COMPACT (on / off), instead of the simulation.
"""
from __future__ import annotations

import argparse
import os
import pickle
import sys
import time

import numpy as np

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
sys.path.insert(0, ROOT)

SAVED_BYTES = (12 - 2) + (12 - 4) + (12 - 4)  # direction, power, normal: float32 -> compact


def quantize_direction(d: np.ndarray) -> np.ndarray:
    """(N,3) float32 unit directions through Jensen's 2 bytes: theta = acos(z) and phi =
    atan2(y, x) each in 256 steps, decoded at the step's centre."""
    d = np.asarray(d, np.float64)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2.0 * np.pi)
    ti = np.minimum((theta * (256.0 / np.pi)).astype(np.int64), 255)
    pj = np.minimum((phi * (256.0 / (2.0 * np.pi))).astype(np.int64), 255)
    t = (ti + 0.5) * (np.pi / 256.0)
    p = (pj + 0.5) * (2.0 * np.pi / 256.0)
    st = np.sin(t)
    return np.stack([st * np.cos(p), st * np.sin(p), np.cos(t)], axis=1).astype(np.float32)


def quantize_power(c: np.ndarray) -> np.ndarray:
    """(N,3) float32 RGB power through Ward's RGBE (a shared exponent, 8-bit mantissas),
    decoded as (m + 0.5) 2^(e - 8) as Ward's reader does; rows whose largest channel is
    below 1e-32 (or <= 0) decode to 0."""
    c = np.asarray(c, np.float64)
    v = c.max(axis=1)
    _, e = np.frexp(v)
    m = np.floor(c * np.ldexp(256.0, -e)[:, None])
    m = np.clip(m, 0.0, 255.0)
    out = (m + 0.5) * np.ldexp(1.0, e - 8)[:, None]
    out[v < 1e-32] = 0.0
    return out.astype(np.float32)


def quantize_normal(n: np.ndarray) -> np.ndarray:
    """(N,3) float32 unit normals through the octahedral map in 2 x int16 (snorm)."""
    n = np.asarray(n, np.float64)
    n = n / np.maximum(np.abs(n).sum(axis=1), 1e-300)[:, None]
    x, y, z = n[:, 0].copy(), n[:, 1].copy(), n[:, 2]
    sx, sy = np.where(x >= 0.0, 1.0, -1.0), np.where(y >= 0.0, 1.0, -1.0)
    low = z < 0.0
    x[low], y[low] = ((1.0 - np.abs(n[low, 1])) * sx[low], (1.0 - np.abs(n[low, 0])) * sy[low])
    qx = np.round(np.clip(x, -1.0, 1.0) * 32767.0).astype(np.int16) / 32767.0
    qy = np.round(np.clip(y, -1.0, 1.0) * 32767.0).astype(np.int16) / 32767.0
    qz = 1.0 - np.abs(qx) - np.abs(qy)
    sx, sy = np.where(qx >= 0.0, 1.0, -1.0), np.where(qy >= 0.0, 1.0, -1.0)
    low = qz < 0.0
    qx, qy = qx.copy(), qy.copy()
    qx[low], qy[low] = (1.0 - np.abs(qy[low])) * sx[low], (1.0 - np.abs(qx[low])) * sy[low]
    out = np.stack([qx, qy, qz], axis=1)
    return (out / np.linalg.norm(out, axis=1)[:, None]).astype(np.float32)


def quantize(photons) -> None:
    """The Photons' direction, power and normal in place, through the compact layout."""
    if photons is None or not len(photons):
        return
    photons.direction = quantize_direction(photons.direction)
    photons.power = quantize_power(photons.power)
    photons.normal = quantize_normal(photons.normal)


def held_photons(ctx) -> int:
    """Photons the Context's maps hold (each Photons object once, by its power array)."""
    from engine.render import MAP_FIELDS
    seen, total, stack = set(), 0, [getattr(ctx, f, None) for f in MAP_FIELDS]
    while stack:
        obj = stack.pop()
        if obj is None or isinstance(obj, (int, float, str, bool, np.ndarray)) \
                or id(obj) in seen:
            continue
        seen.add(id(obj))
        if type(obj).__name__ == "Photons":
            key = ("p", obj.power.__array_interface__["data"][0])
            if key not in seen:
                seen.add(key)
                total += len(obj)
            continue
        if isinstance(obj, (list, tuple)):
            stack.extend(obj)
        elif isinstance(obj, dict):
            stack.extend(obj.values())
        elif type(obj).__module__.startswith("engine.") and hasattr(obj, "__dict__"):
            stack.extend(v for k, v in vars(obj).items() if k != "accel")
    return total


SHIPPED = False  # --shipped: photonlayout.COMPACT on / off instead of the simulation


def render(scene, kwargs, compact: bool):
    """(film, photons held by the maps) of one render, the shots quantized if compact
    (SHIPPED: the maps in the engine's compact layout, else its float32 layout)."""
    import importlib
    R = importlib.import_module("engine.render")  # (engine.render is also a function)
    from engine import photonlayout
    from engine.settings import RenderSettings
    build, camera, got = R._build_maps, R.render_camera, {}
    if SHIPPED:
        photonlayout.COMPACT = compact

    def build_spy(ctx, shot, caustic, use_caustic_shot, stop, pre_radius=None, glow=None,
                  camera_map_radius=None):
        if compact and not SHIPPED:
            for ph in {id(p): p for p in (shot, caustic, glow) if p is not None}.values():
                quantize(ph)
        return build(ctx, shot, caustic, use_caustic_shot, stop, pre_radius, glow,
                     camera_map_radius)

    def camera_spy(ctx, *a, **kw):
        got["held"] = held_photons(ctx)
        return camera(ctx, *a, **kw)

    R._build_maps, R.render_camera = build_spy, camera_spy
    try:
        film = R.render(scene, RenderSettings(**kwargs))
    finally:
        R._build_maps, R.render_camera = build, camera
    return film, got.get("held", 0)


def change(a, b):
    """(mean |a - b| / mean a, max |a - b| / a over pixels above 1 % of a's mean)."""
    a, b = np.asarray(a, np.float64).sum(axis=-1), np.asarray(b, np.float64).sum(axis=-1)
    mean = max(float(np.abs(a).mean()), 1e-300)
    lit = a > 0.01 * mean
    rel = np.abs(a - b)[lit] / a[lit]
    return float(np.abs(a - b).mean()) / mean, float(rel.max()) if rel.size else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pickles", nargs="*", default=[],
                    help="pickled scenes (tools/film_hashes.py's exports): bytes, change")
    ap.add_argument("--flip", default="",
                    help="accuracy scenes (tools/accuracy_scenes.py) for HDR-FLIP vs Cycles")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--shipped", action="store_true",
                    help="the engine's compact layout (photonlayout.COMPACT on / off)")
    args = ap.parse_args()
    global SHIPPED, SAVED_BYTES
    SHIPPED = args.shipped
    if SHIPPED:
        SAVED_BYTES = 3 * (12 - 4)  # direction, power, normal: 4 B each
    from engine.jit import ensure_compiled
    ensure_compiled()
    print(f"160 x 120, 16 spp, 1 worker, seed 0; {SAVED_BYTES} B saved a photon held")
    print("| scene | stored | held by the maps | B saved a stored photon | "
          "mean abs change | max rel change | CPU s float32 / compact |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for path in args.pickles:
        with open(path, "rb") as f:
            obj = pickle.load(f)
        scene, kw = obj if isinstance(obj, tuple) else (obj, {})
        scene.width, scene.height = 160, 120
        kw = dict(kw, workers=1, spp=16, seed=0)
        out = []
        for compact in (False, True):
            c0 = time.process_time()
            film, held = render(scene, kw, compact)
            out.append((film, held, time.process_time() - c0))
        st = out[0][0].stats
        stored = st.get("global_photons", 0) + st.get("caustic_photons", 0) \
            + st.get("glow_photons", 0)
        mean_abs, max_rel = change(out[0][0].combined, out[1][0].combined)
        name = os.path.splitext(os.path.basename(path))[0]
        print(f"| {name} | {stored:,} | {out[0][1]:,} | "
              f"{SAVED_BYTES * out[0][1] / max(stored, 1):.1f} | {mean_abs:.4f} | "
              f"{max_rel:.3f} | {out[0][2]:.1f} / {out[1][2]:.1f} |", flush=True)
    if args.flip:
        sys.path.insert(0, os.path.join(ROOT, "tools"))
        import accuracy_scenes as A
        seeds = [int(s) for s in args.seeds.split(",")]
        print(f"\nHDR-FLIP against the Cycles reference, add-on defaults, seeds {seeds}")
        print("| scene | FLIP float32 | FLIP compact | mean abs change (seed 0) |")
        print("|---|---:|---:|---:|")
        for name in args.flip.split(","):
            scene, kw = A.export_ours(name)
            ref = A.load_reference(name)
            flips, first = {False: [], True: []}, {}
            for seed in seeds:
                for compact in (False, True):
                    film, _ = render(scene, dict(kw, seed=seed), compact)
                    img = np.asarray(film.combined, np.float32)[..., :3]
                    flips[compact].append(A.flip(img, ref))
                    if seed == seeds[0]:
                        first[compact] = img
            print(f"| {name} | {np.mean(flips[False]):.4f} | {np.mean(flips[True]):.4f} | "
                  f"{change(first[False], first[True])[0]:.4f} |", flush=True)


if __name__ == "__main__":
    main()
