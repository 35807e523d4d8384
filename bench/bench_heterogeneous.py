"""Heterogeneous media (a textured volume Density): time, tracking steps and noise of
ours at several sample counts, against a high-sample reference of ours and against
Cycles 5.0 (hetspeed40, docs/performance.md).

The scene: tests/blender/test_heterogeneous_cycles.py's cloud cube (Principled Volume,
Density = 4 x Color Ramp (0.45 .. 0.62) of a Noise Texture, Scale 2.5, Detail 2,
Generated) over a white floor under a 600 W spot, direct light (Max Bounces 0, Volume
bounces 0), box filter; "cloud" at 64 x 48, "large" the same cube 1.75x larger (object
scale; its puffs scale with it) at 128 x 96.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_heterogeneous.py [--label after]
        [--engine-root DIR] [--cases cloud,large] [--spp 16,64,256] [--ref-spp 2048]
        [--cycles] [--stand-in-distances]

--engine-root: the checkout whose engine renders (default: this one; another commit's
checkout measures "before" with the same script: its kernel cache must be warm). Each
run adds its rows to /tmp/bench_heterogeneous.json (keyed by label) and prints every
label's rows; the references (Cycles at --ref-spp, and ours at --ref-spp from the first
label that renders one) are kept in /tmp/bench_heterogeneous_refs.npz.

Columns: seconds (the render call, one process, threads = the add-on's default),
tracking draws per part (the tracking loop's random numbers / the media parts it
tracked: tentative collisions + 1), relMSE (mean over pixels and channels of
(x - ref)^2 / (ref^2 + 0.01)) against ours and against Cycles; Cycles' rows at the same
sample counts give the equal-time comparison.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
REFS = "/tmp/bench_heterogeneous_refs.npz"
ROWS = "/tmp/bench_heterogeneous.json"


def rel_mse(img, ref):
    return float(np.mean((img - ref) ** 2 / (ref ** 2 + 0.01)))


def build(bpy, case):
    sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
    import test_heterogeneous_cycles as T
    scene = T._scene(bpy, "Generated")
    if case == "large":
        cloud = bpy.data.objects["Cloud"]
        cloud.scale = (1.75, 1.75, 1.75)
        cloud.location = (0.0, 0.0, 1.35)
        scene.render.resolution_x, scene.render.resolution_y = 128, 96
    return scene


def render(bpy, scene, engine, spp, path):
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    scene.render.engine = engine
    c = cycles_plain(scene, spp, 0)
    c.volume_bounces = 0
    if engine != "CYCLES":
        cheap(scene, spp=spp)
        scene.photonmap.photon_mapping = False
    t = time.perf_counter()
    img = read_rgba(bpy, render_exr(bpy, scene, path))[..., :3]
    return np.asarray(img, np.float64), time.perf_counter() - t


class Draws:
    """Counts the tracking loop's random numbers and the parts it tracked (wraps
    heterogeneous.uniforms and HeterogeneousMedia.intervals)."""

    def __init__(self):
        import engine.heterogeneous as H
        self.H = H
        self.draws = 0
        self.parts = 0
        self._uniforms, self._intervals = H.uniforms, H.HeterogeneousMedia.intervals
        me = self

        def uniforms(keys, step):
            me.draws += len(keys)
            return me._uniforms(keys, step)

        def intervals(het, o, u, length):
            out = me._intervals(het, o, u, length)
            me.parts += len(out[0])
            return out

        H.uniforms = uniforms
        H.HeterogeneousMedia.intervals = intervals

    def take(self):
        d, p = self.draws, self.parts
        self.draws = self.parts = 0
        return d / max(p, 1), p


def _save(rows):
    with open(ROWS, "w") as f:
        json.dump(rows, f, indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--label", default="after")
    ap.add_argument("--engine-root", default=ROOT)
    ap.add_argument("--cases", default="cloud,large")
    ap.add_argument("--spp", default="16,64,256")
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--cycles", action="store_true", help="also Cycles at --spp")
    ap.add_argument("--stand-in-distances", action="store_true",
                    help="the camera segments' scatter distances drawn for the mean "
                         "density's stand-in (scatter_weights), not along the majorant "
                         "grid: how much of the noise the distances make")
    args = ap.parse_args()
    sys.path.insert(0, os.path.abspath(args.engine_root))
    sys.path.insert(1, os.path.join(ROOT, "tests", "blender"))
    import bpy
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    draws = Draws()
    if args.stand_in_distances:
        import engine.heterogeneous as H
        H.HeterogeneousMedia.scatter = (
            lambda het, o, d, t, pts, m, w, u: (pts, het.scatter_weights(o, d, pts, m, w)))
    refs = dict(np.load(REFS)) if os.path.exists(REFS) else {}
    rows = json.load(open(ROWS)) if os.path.exists(ROWS) else {}
    out = rows.setdefault(args.label, [])
    out[:] = [r for r in out if r["case"] not in args.cases.split(",")]
    tmp = "/tmp/bench_heterogeneous.exr"
    for case in args.cases.split(","):
        scene = build(bpy, case)
        if f"cycles_{case}" not in refs:
            refs[f"cycles_{case}"], sec = render(bpy, scene, "CYCLES", args.ref_spp, tmp)
            print(f"{case}: Cycles {args.ref_spp} spp reference {sec:.1f} s", flush=True)
            np.savez(REFS, **refs)
        if f"ours_{case}" not in refs:
            refs[f"ours_{case}"], sec = render(bpy, scene, "PHOTONMAP", args.ref_spp, tmp)
            draws.take()
            print(f"{case}: ours ({args.label}) {args.ref_spp} spp reference {sec:.1f} s",
                  flush=True)
            np.savez(REFS, **refs)
        for spp in [int(s) for s in args.spp.split(",")]:
            img, sec = render(bpy, scene, "PHOTONMAP", spp, tmp)
            per_part, parts = draws.take()
            out.append(dict(case=case, who="ours", spp=spp, seconds=sec, draws=per_part,
                            parts=parts, ours=rel_mse(img, refs[f"ours_{case}"]),
                            cycles=rel_mse(img, refs[f"cycles_{case}"])))
            print(out[-1], flush=True)
            _save(rows)
            if args.cycles:
                img, sec = render(bpy, scene, "CYCLES", spp, tmp)
                rows.setdefault("cycles", [])
                rows["cycles"] = [r for r in rows["cycles"]
                                  if not (r["case"] == case and r["spp"] == spp)]
                rows["cycles"].append(dict(case=case, who="cycles", spp=spp, seconds=sec,
                                           draws=0, parts=0,
                                           ours=rel_mse(img, refs[f"ours_{case}"]),
                                           cycles=rel_mse(img, refs[f"cycles_{case}"])))
                print(rows["cycles"][-1], flush=True)
                _save(rows)
    print()
    print("| label | case | spp | seconds | draws / part | parts | relMSE vs ours ref "
          "| relMSE vs Cycles ref |")
    print("|---|---|---|---|---|---|---|---|")
    for label, rs in rows.items():
        for r in sorted(rs, key=lambda r: (r["case"], r["spp"])):
            print(f"| {label} | {r['case']} | {r['spp']} | {r['seconds']:.2f} | "
                  f"{r['draws']:.2f} | {r['parts']} | {r['ours']:.4f} | {r['cycles']:.4f} |")


if __name__ == "__main__":
    main()
