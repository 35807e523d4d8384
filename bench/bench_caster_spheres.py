"""Where aimed caustic photons go, with one bounding sphere per caster ("before") and with
the clustered spheres of engine/casterspheres.py ("after"): spheres, the share of aimed
photons whose first hit is a caster, the share stored in the caustic map, and the CPU
seconds of the caustic shot (best of --repeat, one thread).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_caster_spheres.py [--photons 200000]
        [--pickles ring=/tmp/x/ring.pkl,figure8_caustic=/tmp/x/figure8_caustic.pkl]
    PYTHONPATH=$PWD .venv/bin/python bench/bench_caster_spheres.py --map-noise /tmp/x/ring.pkl
    PYTHONPATH=$PWD .venv/bin/python bench/bench_caster_spheres.py --sphere-cost --repeat 3
    PYTHONPATH=$PWD .venv/bin/python bench/bench_caster_spheres.py --noise /tmp/x/ring.pkl
        [--seeds 8] [--width 96]

Pickles: engine Scenes exported from blends (bench_kernels.exported, or addon.export);
without them only the built-in scenes of tests/caster_scenes.py run (a half ring, a
torus, a curved glass sheet, a glass ball). --noise renders the caustic pass of one
pickle (indirect off, 4 spp, Fixed Radius estimator of --radius m) over --seeds seeds before and after, and against our own
reference (after, 20x the photons, 16 spp): the relative variance over seeds and the
relMSE in the caustic's region (where the reference's caustic is above 10 % of its 99th
percentile), with each shot's CPU seconds."""
import argparse
import os
import pickle
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import numpy as np  # noqa: E402

from engine import RenderSettings, casterspheres  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.photons import CAUSTIC, trace_photons  # noqa: E402
from engine.render import _allocate_aimed, close_context, prepare_context  # noqa: E402


def first_hits_on_casters(ctx, targets, n, seed):
    """Share of n aimed photons (per light, by _allocate_aimed's split) that carry power
    and whose first hit belongs to a caster."""
    rng = np.random.default_rng(seed)
    counts = _allocate_aimed(ctx, targets, n)
    hit = total = 0
    casters = set(int(i) for i in ctx.plan.caster_ids)
    for light, count in zip(ctx.lights, counts):
        if not count:
            continue
        o, d, power = light.emit_towards(count, rng, *targets)
        live = power.max(axis=1) > 0
        _, prim, _, _ = ctx.accel.intersect(o[live], d[live])
        ok = prim >= 0
        hit += int(np.isin(ctx.geo.object_id[prim[ok]], list(casters)).sum())
        total += count
    return hit / max(total, 1)


def measure(scene, photons, repeat, seed=1):
    ctx = prepare_context(scene, RenderSettings(workers=1, seed=seed))
    try:
        targets = ctx.plan.caster_spheres
        if not len(targets[1]):
            return None
        hits = first_hits_on_casters(ctx, targets, photons, seed)
        # As the render's aimed shot (render._photon_pass): with rough specular surfaces
        # (the table's coat) it keeps only paths whose first hit is a caster; the rest
        # come from unaimed photons.
        first_hit = None
        if ctx.plan.rough_specular:
            split = np.zeros(len(ctx.geo.object_names), bool)
            split[ctx.plan.caster_ids] = True
            first_hit = (split, True)
        best = np.inf
        for _ in range(repeat):
            counts = _allocate_aimed(ctx, targets, photons)
            t = time.process_time()
            shot = trace_photons(ctx, ctx.lights, counts, caustic_only=True, stream=2,
                                 targets=targets, first_hit=first_hit)
            best = min(best, time.process_time() - t)
        stored = int(np.count_nonzero(shot.kind == CAUSTIC))
        power = float(shot.power[shot.kind == CAUSTIC].sum())
        return dict(spheres=len(targets[1]), hits=hits, stored=stored,
                    share=stored / photons, cpu=best, power=power)
    finally:
        close_context(ctx)


def noise(path, seeds, width, photons, radius):
    from engine.render import render

    def caustic(on, seed, n, spp):
        casterspheres.CLUSTER_CASTERS = on
        with open(path, "rb") as f:
            scene = pickle.load(f)
        scene.height = round(scene.height * width / scene.width)
        scene.width = width
        # A fixed radius (Fixed Radius estimator): a k-NN estimate takes k photons
        # whatever their number (its noise stays, its blur shrinks), so only a fixed
        # disc shows the photons' noise.
        film = render(scene, RenderSettings(workers=1, spp=spp, seed=seed, indirect="off",
                                            caustic_photons=n, estimator="radius",
                                            radius=radius))
        return film.caustic.mean(axis=2), film.stats["time_photons"]
    ref, _ = caustic(True, 1000, 20 * photons, 16)
    mask = ref > 0.1 * np.percentile(ref, 99)
    print(f"caustic region: {int(mask.sum())} of {mask.size} pixels; reference "
          f"{20 * photons:,} photons, 16 spp; Fixed Radius estimator, {radius} m\n")
    print("| aiming | caustic photons | photon pass CPU s (mean) | relative variance over "
          "seeds | relMSE vs reference | region mean / reference |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, on, n in (("one sphere (before)", False, photons),
                         ("one sphere, 2x photons", False, 2 * photons),
                         ("clustered (after)", True, photons)):
        images, cpu = [], []
        for seed in range(1, seeds + 1):
            img, t = caustic(on, seed, n, 4)
            images.append(img[mask])
            cpu.append(t)
        x = np.array(images)
        var = float(np.mean(x.var(axis=0, ddof=1) / ref[mask] ** 2))
        rel = float(np.mean((x - ref[mask]) ** 2 / (ref[mask] ** 2 + 0.01)))
        print(f"| {label} | {n:,} | {np.mean(cpu):.2f} | {var:.4f} | {rel:.4f} | "
              f"{x.mean() / ref[mask].mean():.4f} |", flush=True)
    casterspheres.CLUSTER_CASTERS = True


def map_noise(path, seeds, photons, cell, repeat_cpu=2):
    """The aimed shot's caustic irradiance on the table, in square cells of side `cell`
    (a fixed-area estimate: its noise is the photons' alone, no camera sampling), over
    `seeds` seeds: before (one sphere) at 1x, 2x, 4x the photons and after (clustered)
    at 1x; reference: after at 20x. Cells of the caustic: reference above 10 % of its
    99th percentile."""
    with open(path, "rb") as f:
        scene = pickle.load(f)

    def table_irradiance(on, seed, n):
        casterspheres.CLUSTER_CASTERS = on
        ctx = prepare_context(scene, RenderSettings(workers=1, seed=seed))
        try:
            targets = ctx.plan.caster_spheres
            first_hit = None
            if ctx.plan.rough_specular:
                split = np.zeros(len(ctx.geo.object_names), bool)
                split[ctx.plan.caster_ids] = True
                first_hit = (split, True)
            counts = _allocate_aimed(ctx, targets, n)
            t = time.process_time()
            shot = trace_photons(ctx, ctx.lights, counts, caustic_only=True, stream=2,
                                 targets=targets, first_hit=first_hit)
            cpu = time.process_time() - t
            up = (shot.kind == CAUSTIC) & (shot.normal[:, 2] > 0.99)
            pos, power = shot.position[up], shot.power[up].sum(axis=1)
            edges = np.arange(-3.0, 3.0 + cell / 2, cell)
            h, _, _ = np.histogram2d(pos[:, 0], pos[:, 1], bins=[edges, edges],
                                     weights=power)
            return h / (cell * cell), cpu
        finally:
            close_context(ctx)
            casterspheres.CLUSTER_CASTERS = True

    ref, _ = table_irradiance(True, 1000, 20 * photons)
    mask = ref > 0.1 * np.percentile(ref[ref > 0], 99)
    print(f"{int(mask.sum())} cells of {cell} m in the caustic; reference {20 * photons:,} "
          f"photons (clustered)\n")
    print("| aiming | caustic photons | caustic shot CPU s (mean) | relative variance "
          "over seeds | relMSE vs reference | caustic mean / reference |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, on, k in (("one sphere (before)", False, 1), ("one sphere", False, 2),
                         ("one sphere", False, 4), ("clustered (after)", True, 1)):
        maps, cpu = [], []
        for seed in range(1, seeds + 1):
            m, t = table_irradiance(on, seed, k * photons)
            maps.append(m[mask])
            cpu.append(t)
        x, r = np.array(maps), ref[mask]
        var = float(np.mean(x.var(axis=0, ddof=1) / r ** 2))
        rel = float(np.mean((x - r) ** 2 / (r ** 2 + 0.01)))
        print(f"| {label} | {k * photons:,} | {np.mean(cpu):.3f} | {var:.4f} | {rel:.4f} | "
              f"{x.sum(axis=1).mean() / r.sum():.4f} |", flush=True)


def sphere_cost(photons, repeat):
    """CPU seconds of the aimed caustic shot of the glass ball (tests/test_scenes.py) with
    its sphere given 1, 8, 16, 64 times (the same pdf: only the kernels' per-sphere loop
    grows), best of `repeat`."""
    from test_scenes import caustic_scene
    ctx = prepare_context(caustic_scene(16), RenderSettings(workers=1, seed=1))
    try:
        c, r = ctx.plan.caster_spheres
        print("| spheres | caustic shot CPU s | / one sphere |\n|---:|---:|---:|")
        base = None
        for k in (1, 8, 16, 64):
            targets = (np.repeat(c, k, axis=0), np.repeat(r, k))
            best = np.inf
            for _ in range(repeat):
                t = time.process_time()
                trace_photons(ctx, ctx.lights, [photons], caustic_only=True, stream=2,
                              targets=targets)
                best = min(best, time.process_time() - t)
            base = base or best
            print(f"| {k} | {best:.3f} | {best / base:.2f} |", flush=True)
    finally:
        close_context(ctx)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--photons", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--pickles", default="")
    ap.add_argument("--noise", default="")
    ap.add_argument("--map-noise", default="")
    ap.add_argument("--sphere-cost", action="store_true")
    ap.add_argument("--cell", type=float, default=0.05)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--width", type=int, default=96)
    ap.add_argument("--radius", type=float, default=0.05)
    args = ap.parse_args()
    ensure_compiled()
    if args.sphere_cost:
        sphere_cost(args.photons, args.repeat)
        return
    if args.map_noise:
        map_noise(args.map_noise, args.seeds, args.photons, args.cell)
        return
    if args.noise:
        noise(args.noise, args.seeds, args.width, args.photons, args.radius)
        return
    from caster_scenes import ring_scene, sheet_scene, torus_scene
    from test_scenes import caustic_scene
    scenes = [("half ring (tests)", ring_scene), ("torus (tests)", torus_scene),
              ("curved glass sheet (tests)", sheet_scene),
              ("glass ball (tests)", lambda: caustic_scene(16))]
    for item in filter(None, args.pickles.split(",")):
        name, path = item.split("=")

        def load(path=path):
            with open(path, "rb") as f:
                return pickle.load(f)
        scenes.append((name, load))
    print(f"{args.photons:,} caustic photons, 1 thread, CPU s best of {args.repeat}\n")
    print("| scene | spheres before / after | first hit on a caster before / after | "
          "stored before / after | stored share gain | caustic power after / before | "
          "CPU s before / after | stored per CPU s gain |")
    print("|---|---|---|---|---|---|---|---|")
    for name, make in scenes:
        res = {}
        for label, on in (("before", False), ("after", True)):
            casterspheres.CLUSTER_CASTERS = on
            res[label] = measure(make(), args.photons, args.repeat)
        casterspheres.CLUSTER_CASTERS = True
        b, a = res["before"], res["after"]
        if b is None:
            print(f"| {name} | no caster |")
            continue
        print(f"| {name} | {b['spheres']} / {a['spheres']} | {b['hits']:.1%} / {a['hits']:.1%} "
              f"| {b['stored']:,} ({b['share']:.1%}) / {a['stored']:,} ({a['share']:.1%}) "
              f"| {a['stored'] / max(b['stored'], 1):.2f}x | {a['power'] / b['power']:.4f} "
              f"| {b['cpu']:.2f} / {a['cpu']:.2f} "
              f"| {(a['stored'] / a['cpu']) / (b['stored'] / b['cpu']):.2f}x |", flush=True)


if __name__ == "__main__":
    main()
