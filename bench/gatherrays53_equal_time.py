"""Gather rays per camera sample, light samples and photon counts at equal CPU time
(issues 13 / 14, docs/performance.md "gatherrays53").

    PYTHONPATH=. .venv/bin/python bench/gatherrays53_equal_time.py render SCENE OUTDIR \\
        [--seeds 0,1] [--variant NAME:key=value,...] [--calib-spp N] [--spps NAME=N,...]
        [--only NAME,...] [--spp N]
    PYTHONPATH=. .venv/bin/python bench/gatherrays53_equal_time.py table OUTDIR SCENE [...]

SCENE: donut (bench/newuser51_donut.py, 160 x 120; reference Cycles 2048 spp, REF
/tmp/newuser51/c2048.exr by default), jewellery (bench/newuser52_jewellery.py, 160 x 120;
Cycles 2048 spp pooled, /tmp/newuser52/c2048.exr), candles (bench/newuser53_candles.py,
160 x 120; Cycles 2048 spp pooled, /tmp/lightpick53/c2048.exr: docs/accuracy.md
"newuser53" renders it), figure6_box and principled_spheres
(tools/accuracy_scenes.py, their stored Cycles references in tests/references). --ref
overrides the reference (EXR or .npy).

render: the scene is built with bpy and exported once through the add-on (the donut and
the jewellery at the add-on's defaults, as their benches render them; the accuracy scenes
by accuracy_scenes.export_ours), then rendered by engine.render on one worker in this
process for the default settings and each variant, timing the process' CPU seconds.
Equal time: first every configuration renders once at --calib-spp samples (seed 99);
its CPU seconds split by the stages' wall clock into a fixed part (photons, maps: all
but stats' time_camera) and a per-sample part; a variant's spp is then the default's
budget (fixed + spp x per-sample at the default) less its own fixed part, over its own
per-sample part. A variant is NAME:key=value,... of engine.settings.RenderSettings fields;
photon_scale=F multiplies both photon counts; sample_all_up_to=N sets
engine.lights.selection.SAMPLE_ALL_UP_TO for that render (read at call time: scenes with
more lights than N pick one light per shadow ray through the light tree; 0 = always the
tree). --spp N sets the default's samples (the budget; else the add-on's). Default variants: g1 (gather_rays=1), g4
(gather_rays=4), p0.5 and p2 (photon_scale 0.5 / 2). Writes OUTDIR/SCENE_NAME_sSEED.npy
(the (H, W, 3) float32 image) and a line of JSON per render to OUTDIR/SCENE.jsonl (spp,
CPU s, rays; camera_rays and shadow_rays from the render's stats). --spps NAME=N,... skips the calibration and renders those configurations at
those samples (another process' printed budget: seeds split over processes); --only
renders only those configurations after the calibration.

table: per scene and configuration, per seed the CPU s, the gather rays per camera sample
(all levels; render.gather_count may give fewer level-0 rays than gather_rays, by the
indirect light's share), shadow rays per camera ray, relMSE (newuser26_compare's: (x - ref)^2 / (ref^2 + 0.01)), relMSE
x CPU s / the default's mean CPU s (relMSE at the default's time, where the error is noise:
corrects a render's miss of the budget) and mean HDR-FLIP against the reference, their means over
the seeds and each metric's ratio to the default's mean; a configuration "wins" a metric
when its mean is below the default's by more than the larger of the two seed spreads
(|seed 0 - seed 1|).
"""
from __future__ import annotations

import argparse
import ast
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BENCH = os.path.dirname(os.path.abspath(__file__))
for p in (ROOT, BENCH, os.path.join(ROOT, "tools")):
    if p not in sys.path:
        sys.path.insert(0, p)

REFS = {"donut": "/tmp/newuser51/c2048.exr", "jewellery": "/tmp/newuser52/c2048.exr",
        "candles": "/tmp/lightpick53/c2048.exr"}
DEFAULT_VARIANTS = ("g1:gather_rays=1", "g4:gather_rays=4", "p0.5:photon_scale=0.5",
                    "p2:photon_scale=2")


def parse_variant(text):
    name, _, rest = text.partition(":")
    out = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        out[key] = ast.literal_eval(value)
    return name, out


def export_addon_scene(scene):
    """(engine Scene, RenderSettings kwargs) of a bpy scene as the add-on exports it for a
    final render (addon/engine.py: export_scene, then the properties' settings)."""
    import bpy
    import engine
    from addon import export as ex
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(scene.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h)
    return pm_scene, scene.photonmap.to_settings_kwargs(scene.render.film_transparent)


def build(name):
    """(engine Scene, default RenderSettings kwargs) of SCENE."""
    import addon
    os.makedirs("/tmp/gatherrays53", exist_ok=True)
    if name == "donut":
        import newuser51_donut as D
        from studio48_stilllife import write_hdr
        hdr = "/tmp/gatherrays53/kitchen.hdr"
        write_hdr(hdr, D.kitchen_pixels())
        addon.register()
        scene = D.donut_scene(hdr)
    elif name == "jewellery":
        import newuser52_jewellery as J
        from studio48_stilllife import write_hdr
        hdr = "/tmp/gatherrays53/display.hdr"
        write_hdr(hdr, J.display_pixels())
        addon.register()
        scene = J.jewellery_scene(hdr)
    elif name == "candles":
        import newuser53_candles as C
        addon.register()
        scene = C.candles_scene()
    else:
        import accuracy_scenes as A
        return A.export_ours(name)
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 160, 120, 100
    r.engine = "PHOTONMAP"
    return export_addon_scene(scene)


def settings_of(base, over, spp, seed):
    kw = dict(base, workers=1, seed=seed, spp=spp)
    for k, v in over.items():
        if k == "sample_all_up_to":
            continue  # not a RenderSettings field: render_once sets the module's constant
        if k == "photon_scale":
            kw["photons"] = int(round(base["photons"] * v))
            kw["caustic_photons"] = int(round(base["caustic_photons"] * v))
        else:
            kw[k] = v
    return kw


def render_once(pm_scene, kw, over=None):
    """(image (H, W, 3) float32, CPU s, stats) of one engine render in this process;
    over["sample_all_up_to"], if given, is selection.SAMPLE_ALL_UP_TO for this render."""
    from engine.lights import selection
    from engine.render import render
    from engine.settings import RenderSettings
    settings = RenderSettings(**kw)
    saved = selection.SAMPLE_ALL_UP_TO
    selection.SAMPLE_ALL_UP_TO = int((over or {}).get("sample_all_up_to", saved))
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        film = render(pm_scene, settings)
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    finally:
        selection.SAMPLE_ALL_UP_TO = saved
    st = dict(film.stats)
    st["wall"] = wall
    return np.asarray(film.combined, np.float32), cpu, st


def render_main(a):
    import engine
    engine.jit.ensure_compiled()
    os.makedirs(a.outdir, exist_ok=True)
    pm_scene, base = build(a.scene)
    if a.spp:
        base = dict(base, spp=a.spp)
    default_spp = base["spp"]
    configs = [("default", {})] + [parse_variant(v) for v in (a.variant or DEFAULT_VARIANTS)]
    log = open(os.path.join(a.outdir, a.scene + ".jsonl"), "a")

    def record(name, kw, cpu, st, kind, over=None):
        row = dict(scene=a.scene, config=name, kind=kind, spp=kw["spp"], seed=kw["seed"],
                   cpu=round(cpu, 2), wall=round(st["wall"], 2),
                   time_camera=round(st.get("time_camera", 0.0), 2),
                   gather_rays=int(st.get("gather_rays", 0)),
                   shadow_rays=int(st.get("shadow_rays", 0)),
                   camera_rays=int(st.get("camera_rays", 0)),
                   sample_all_up_to=int((over or {}).get("sample_all_up_to", -1)),
                   photons=kw["photons"], caustic_photons=kw["caustic_photons"],
                   gather_per_sample=kw["gather_rays"], light_samples=kw["light_samples"],
                   load=round(os.getloadavg()[0], 1))
        log.write(json.dumps(row) + "\n")
        log.flush()
        print(json.dumps(row), flush=True)

    if a.spps:  # another process' calibration (its printed spp), e.g. for another seed
        spps = {k: int(v) for k, v in (x.split("=") for x in a.spps.split(","))}
        configs = [(n, o) for n, o in configs if n in spps]
        return render_seeds(a, pm_scene, base, configs, spps, record)
    # Calibration: each configuration's fixed and per-sample CPU s.
    cost = {}
    for name, over in configs:
        kw = settings_of(base, over, a.calib_spp, 99)
        _, cpu, st = render_once(pm_scene, kw, over)
        record(name, kw, cpu, st, "calibration", over)
        share = min(st.get("time_camera", 0.0) / max(st["wall"], 1e-9), 1.0)
        cost[name] = (cpu * (1.0 - share), cpu * share / a.calib_spp)
    fixed0, per0 = cost["default"]
    budget = fixed0 + default_spp * per0
    spps = {name: default_spp if name == "default" else
            max(1, int(round((budget - cost[name][0]) / cost[name][1]))) for name, _ in configs}
    print(f"budget {budget:.1f} CPU s; spp {spps}; cost (fixed, per spp) "
          f"{ {k: (round(f, 2), round(p, 4)) for k, (f, p) in cost.items()} }", flush=True)
    if a.only:
        configs = [(n, o) for n, o in configs if n in a.only.split(",")]
    render_seeds(a, pm_scene, base, configs, spps, record)


def render_seeds(a, pm_scene, base, configs, spps, record):
    for seed in a.seeds:
        for name, over in configs:
            kw = settings_of(base, over, spps[name], seed)
            img, cpu, st = render_once(pm_scene, kw, over)
            np.save(os.path.join(a.outdir, f"{a.scene}_{name}_s{seed}.npy"), img)
            record(name, kw, cpu, st, "render", over)


def load_image(path):
    if path.endswith(".npy"):
        return np.asarray(np.load(path), np.float64)[..., :3]
    from newuser26_compare import read_exr
    return np.asarray(read_exr(path), np.float64)[..., :3]


def reference(scene, override=None):
    if override:
        return load_image(override)
    if scene in REFS:
        return load_image(REFS[scene])
    import accuracy_scenes as A
    return np.asarray(A.load_reference(scene), np.float64)[..., :3]


def metrics(x, ref):
    import flip_evaluator
    rel = float(np.mean((x - ref) ** 2 / (ref * ref + 0.01)))
    f = flip_evaluator.evaluate(ref.astype(np.float32), x.astype(np.float32), "HDR",
                                applyMagma=False)[1]
    return rel, float(f)


def table(outdir, scenes, ref_override=None):
    for scene in scenes:
        ref = reference(scene, ref_override)
        rows = [json.loads(s) for s in open(os.path.join(outdir, scene + ".jsonl"))]
        runs = {}
        for r in rows:
            if r["kind"] != "render":
                continue
            path = os.path.join(outdir, f"{scene}_{r['config']}_s{r['seed']}.npy")
            if os.path.isfile(path):
                runs.setdefault(r["config"], {})[r["seed"]] = (r, metrics(load_image(path),
                                                                          ref))
        if "default" not in runs:
            continue
        seeds = sorted(runs["default"])

        def summary(cfg):
            got = [runs[cfg][s] for s in seeds if s in runs[cfg]]
            rel = [m[0] for _, m in got]
            fl = [m[1] for _, m in got]
            return (np.mean(rel), np.ptp(rel) if len(rel) > 1 else 0.0,
                    np.mean(fl), np.ptp(fl) if len(fl) > 1 else 0.0, got)

        d_rel, d_rels, d_fl, d_fls, d_got = summary("default")
        d_cpu = np.mean([r["cpu"] for r, _ in d_got])
        pixels = ref.shape[0] * ref.shape[1]
        print(f"\n**{scene}** (reference {ref_override or REFS.get(scene, 'tests/references')})"
              "\n")
        print("| config | spp | gather / sample | shadow / camera ray | seed | CPU s | relMSE | relMSE x CPU / default's "
              "| HDR-FLIP | mean relMSE (/ default) | mean FLIP (/ default) | wins |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for cfg in runs:
            rel, rels, fl, fls, got = summary(cfg)
            wins = []
            if cfg != "default":
                if d_rel - rel > max(rels, d_rels):
                    wins.append("relMSE")
                if d_fl - fl > max(fls, d_fls):
                    wins.append("FLIP")
                if rel - d_rel > max(rels, d_rels):
                    wins.append("loses relMSE")
                if fl - d_fl > max(fls, d_fls):
                    wins.append("loses FLIP")
            for i, (r, (m_rel, m_fl)) in enumerate(got):
                tail = (f"{rel:.5f} ({rel / d_rel:.3f}) | {fl:.4f} ({fl / d_fl:.3f}) | "
                        f"{', '.join(wins) or '-'}" if i == 0 else " | | ")
                print(f"| {cfg if i == 0 else ''} | {r['spp']} | "
                      f"{r['gather_rays'] / (pixels * r['spp']):.2f} | "
                      f"{r.get('shadow_rays', 0) / max(r.get('camera_rays', 0), 1):.2f} | "
                      f"{r['seed']} | "
                      f"{r['cpu']:.1f} | {m_rel:.5f} | {m_rel * r['cpu'] / d_cpu:.5f} | "
                      f"{m_fl:.4f} | {tail} |")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "table":
        ap = argparse.ArgumentParser()
        ap.add_argument("mode")
        ap.add_argument("outdir")
        ap.add_argument("scenes", nargs="+")
        ap.add_argument("--ref")
        a = ap.parse_args()
        return table(a.outdir, a.scenes, a.ref)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("render",))
    ap.add_argument("scene", choices=("donut", "jewellery", "candles", "figure6_box",
                                      "principled_spheres"))
    ap.add_argument("outdir")
    ap.add_argument("--seeds", type=lambda s: [int(x) for x in s.split(",")], default=[0, 1])
    ap.add_argument("--variant", action="append")
    ap.add_argument("--calib-spp", type=int, default=32)
    ap.add_argument("--spps", help="NAME=SPP,...: skip the calibration, render these")
    ap.add_argument("--only", help="NAME,...: after the calibration render only these")
    ap.add_argument("--spp", type=int, help="the default's samples (the budget)")
    a = ap.parse_args()
    t0 = time.time()
    render_main(a)
    print(f"wall {time.time() - t0:.0f} s load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
