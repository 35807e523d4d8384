"""Do the final gather's regathers pay at equal time? Renders of the Blender donut
(bench/newuser51_donut.py) and Figure 6 (tests/references' figure6_box) with the
regathers' depth (integrator.MAX_GATHER_LEVEL 2 / 1 / 0) or their criterion changed, and a
table of CPU s, relMSE, HDR-FLIP, mean ratio and region means against a Cycles reference
(docs/performance.md "regather52").

    PYTHONPATH=. .venv/bin/python bench/regather52_equal_time.py donut OUT.exr \\
        [--level L] [--criterion both|boundary|short] [--spp N] [--seed S]
    PYTHONPATH=. .venv/bin/python bench/regather52_equal_time.py figure6 OUT.npy [...]
    PYTHONPATH=. .venv/bin/python bench/regather52_equal_time.py figure6-masks MASKS.npy
    PYTHONPATH=. .venv/bin/python bench/regather52_equal_time.py table REF MASKS A [B ...]

donut / figure6: one render at the scene's default settings but those given, in this
process (the donut through the add-on, as newuser51_donut.py renders it; Figure 6 through
engine.render as bench/bench_accuracy_ab.py does, at the reference's 96 x 72); prints
`RESULT ... cpu_s=...` (the process' CPU seconds of the render). --level patches
integrator.MAX_GATHER_LEVEL (the levels that gather again; 0: no regather, the lookup
read where the ray ends). --criterion: which lookups of a regathering level gather again:
both (the default: the gathered point's estimate met another surface or none, or the ray
is shorter than the map's search radius), boundary (the flag alone: the short test off,
add_gathered's `short` 0), short (the short test and the chain counts' reroutes alone:
GatherMap.lookup's flag cleared). Diagnostics only: constants and a wrapper, no setting.
table: per image (EXR or .npy, `A+B` for the mean of two seeds) against REF (EXR or the
.npy reference): relMSE, mean HDR-FLIP, whole-image mean ratio, and per region of MASKS
(object masks .npy: the donut's, newuser51_donut.py --masks, or Figure 6's, figure6-masks;
also the pixels within 2 px of another object, where contacts and corners lie; or
'corners': the image's four 12 x 12 corner squares and its border) the mean luminance
ratio.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BENCH = os.path.dirname(os.path.abspath(__file__))
for p in (ROOT, BENCH, os.path.join(ROOT, "tools")):
    if p not in sys.path:
        sys.path.insert(0, p)


def patch(level, criterion):
    """Set the regathers' depth and criterion for this process."""
    from engine import integrator, photonmap
    if level is not None:
        integrator.MAX_GATHER_LEVEL = level
    if criterion == "boundary":
        kernel = integrator.add_gathered

        def boundary_only(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, regather, again):
            return kernel(E, idx, rows, tp, wd, Ey, G, boundary, lt, 0.0, regather, again)
        integrator.add_gathered = boundary_only
    elif criterion == "short":
        lookup = photonmap.GatherMap.lookup

        def no_flag(self, *args, **kwargs):
            got = list(lookup(self, *args, **kwargs))
            got[1] = np.zeros(len(got[1]), bool)
            return tuple(got)
        photonmap.GatherMap.lookup = no_flag


def render_donut(a):
    import newuser51_donut
    sets = []
    if a.spp:
        sets += ["--set", f"spp={a.spp}"]
    sets += ["--set", f"seed={a.seed}"]
    sys.argv = ["newuser51_donut.py", "ours", a.out] + sets
    newuser51_donut.main()


def render_figure6(a):
    import accuracy_scenes as A
    from bench_accuracy_ab import render_ours
    import engine
    engine.jit.ensure_compiled()
    pm_scene, base = A.export_ours("figure6_box")
    kw = dict(base, workers=1, seed=a.seed)
    if a.spp:
        kw["spp"] = a.spp
    img, cpu, wall, st = render_ours(pm_scene, kw, {})
    np.save(a.out, img)
    ends = sum(v for k, v in st.get("ray_stages", {}).items() if k.startswith("regathered"))
    print(f"spp {kw.get('spp')} regathered {ends} gather {st.get('gather_rays', 0)} "
          f"shadow {st.get('shadow_rays', 0)}")
    print(f"RESULT figure6 cpu_s={cpu:.1f} wall_s={wall:.1f}", flush=True)


def figure6_masks(out):
    """Figure 6's object masks at the reference's size (newuser26_scenes.object_masks)."""
    import json
    import accuracy_scenes as A
    from newuser26_scenes import object_masks
    scene = A.setup("figure6_box")
    ref = A.load_reference("figure6_box")
    ids, names = object_masks(scene, ref.shape[1], ref.shape[0])
    np.save(out, ids)
    with open(out + ".json", "w") as f:
        json.dump(names, f)
    print("masks:", names)


def load(path):
    if "+" in path:
        return np.mean([load(p) for p in path.split("+")], axis=0)
    if path.endswith(".npy"):
        return np.asarray(np.load(path), np.float64)[..., :3]
    from newuser26_compare import read_exr
    return np.asarray(read_exr(path), np.float64)[..., :3]


def lum(x):
    return x @ np.array([0.2126, 0.7152, 0.0722])


def regions(masks, shape):
    if masks == "corners":
        h, w = shape[:2]
        c = 12
        out = []
        for name, ys, xs in (("top-left", slice(0, c), slice(0, c)),
                             ("top-right", slice(0, c), slice(w - c, w)),
                             ("bottom-left", slice(h - c, h), slice(0, c)),
                             ("bottom-right", slice(h - c, h), slice(w - c, w))):
            m = np.zeros((h, w), bool)
            m[ys, xs] = True
            out.append((name, m))
        border = np.ones((h, w), bool)
        border[6:-6, 6:-6] = False
        return out + [("6 px border", border)]
    from newuser26_compare import read_masks
    from newuser51_plate import near
    ids, names = read_masks(masks)
    # Contacts and corners: pixels within 2 px of another object's (where a gather ray's
    # end is short or its gather point's estimate met another surface).
    contact = np.zeros(ids.shape, bool)
    for i in np.unique(ids):
        contact |= (ids == i) & near(ids != i, 2)
    return [(n, ids == i) for i, n in enumerate(names)] + [
        ("world", ids == -1), ("<= 2 px from another object", contact),
        ("the rest", ~contact)]


def table(ref_path, masks, paths):
    import flip_evaluator
    ref = load(ref_path)
    regs = [(n, m) for n, m in regions(masks, ref.shape) if m.any()]
    lr = lum(ref)
    print("| image | relMSE | HDR-FLIP | mean ratio | " +
          " | ".join(f"{n} ({int(m.sum())})" for n, m in regs) + " |")
    print("|---|---|---|---|" + "---|" * len(regs))
    for p in paths:
        x = load(p)
        rel = float(np.mean((x - ref) ** 2 / (ref * ref + 0.01)))
        f = flip_evaluator.evaluate(ref.astype(np.float32), x.astype(np.float32), "HDR",
                                    applyMagma=False)[1]
        lx = lum(x)
        cells = [f"{lx[m].mean() / lr[m].mean():.3f}" for _, m in regs]
        name = "+".join(os.path.basename(q) for q in p.split("+"))
        print(f"| {name} | {rel:.5f} | {float(f):.4f} | {lx.mean() / lr.mean():.4f} | "
              + " | ".join(cells) + " |")


def main():
    if sys.argv[1] == "table":
        return table(sys.argv[2], sys.argv[3], sys.argv[4:])
    if sys.argv[1] == "figure6-masks":
        return figure6_masks(sys.argv[2])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", choices=("donut", "figure6"))
    ap.add_argument("out")
    ap.add_argument("--level", type=int, default=None, help="MAX_GATHER_LEVEL (default 2)")
    ap.add_argument("--criterion", choices=("both", "boundary", "short"), default="both")
    ap.add_argument("--spp", type=int, default=0, help="samples (0: the default)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    patch(a.level, a.criterion)
    t0 = time.time()
    (render_donut if a.scene == "donut" else render_figure6)(a)
    print(f"level {a.level} criterion {a.criterion} wall {time.time() - t0:.0f} s "
          f"load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
