"""CPU seconds of a default render through the add-on, stage by stage (slow52,
docs/performance.md "slow52"): the export, prepare_context less its effect analysis (BVH,
lights), the effect analysis (engine/effects.py: its probes), the photon pass, the maps'
build, the camera pass (engine.render's own stage timers, film.stats time_photons /
time_photon_map / time_camera, made to read CPU) and engine.render's total. CPU is time.process_time(): every thread of the render's process, so
the numbers hold on a machine other jobs share (wall time does not).

    PYTHONPATH=$PWD .venv/bin/python bench/slow52_stages.py [--root BASE ...]
        [--blends figure6_box,figure7_blocker,figure8_caustic] [--repeat 2]
        [--percent 100] [--threads 0] [--profile OUT.prof] [--set module.NAME=value]

Each render is a fresh child process that opens example_blends/NAME.blend (or NAME itself
where it ends in .blend: e.g. the donut bench/newuser51_donut.py --save writes) with `bpy`,
registers the add-on of ROOT (the checkout named by --root, several allowed: this
checkout by default) and renders with engine 'PHOTONMAP' at the blend's saved settings,
as `python -m addon.batch NAME.blend -o X.png` does (the image is not written). Kernels
are loaded before the clock starts (a checkout compiles its own once). Prints one table
row a render (stages in CPU s, then the ray counts in millions, then the first 8 hex digits
of the film's hash: tools/film_hashes.py's SHA-1 of its passes, for a bitwise check), then
each root's per-stage minimum over the repeats. --profile writes a cProfile of the (one)
render's engine.render call, run with one thread.
"""
import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = r"""
import json, os, sys, time
ROOT, BLEND, PERCENT, THREADS, PROFILE, SETS = sys.argv[1:7]
import importlib
import bpy
bpy.ops.wm.open_mainfile(filepath=BLEND if BLEND.endswith(".blend")
                         else os.path.join(ROOT, "example_blends", BLEND + ".blend"))
sys.path.insert(0, ROOT)
import addon
import addon.export as export
import engine
import engine.jit as jit
jit.ensure_compiled()
for item in filter(None, SETS.split(";")):  # --set module.NAME=value (a Python literal)
    name, value = item.split("=", 1)
    module, attr = name.rsplit(".", 1)
    setattr(importlib.import_module(module), attr, eval(value))
er = sys.modules["engine.render"]
cpu = time.process_time


class _CpuClock:
    # engine.render's own stage timers (film.stats time_photons, time_photon_map,
    # time_camera) read perf_counter: here they read the process's CPU instead.
    perf_counter = staticmethod(cpu)

    def __getattr__(self, name):
        return getattr(time, name)


er.time = _CpuClock()
marks = {}

def timed(name, fn):
    def wrapped(*a, **k):
        t = cpu()
        try:
            return fn(*a, **k)
        finally:
            marks[name] = marks.get(name, 0.0) + cpu() - t
    return wrapped

export.export_scene = timed("export", export.export_scene)
er.prepare_context = timed("prepare", er.prepare_context)
er.analyse = timed("effects", er.analyse)
render = engine.render
film_stats = {}

def rendered(scene, settings=None, progress=None, **k):
    t = cpu()
    if PROFILE:
        import cProfile
        # (no should_cancel, one thread: the chunks run inline, on the profiled thread,
        # engine.parallel.ordered_map)
        k.pop("should_cancel", None)
        prof = cProfile.Profile(time.process_time)  # (CPU, not the shared machine's wall)
        film = prof.runcall(render, scene, settings, progress=progress, **k)
        prof.dump_stats(PROFILE)
    else:
        film = render(scene, settings, progress=progress, **k)
    end = cpu()
    marks["render_total"] = end - t
    for a, b in (("photons", "time_photons"), ("photon_map", "time_photon_map"),
                 ("camera", "time_camera")):
        marks[a] = float(film.stats.get(b, 0.0))
    film_stats.update({k: v for k, v in film.stats.items()
                       if isinstance(v, (int, float)) and not isinstance(v, bool)})
    # (tools/film_hashes.py's hash: the passes' bytes, so a row says whether a change
    # kept this blend's image bitwise)
    import hashlib
    import numpy as np
    h = hashlib.sha1()
    for name in ("direct", "indirect", "caustic", "specular", "emission"):
        h.update(np.ascontiguousarray(getattr(film, name)).tobytes())
    marks["film"] = h.hexdigest()[:8]
    return film
engine.render = rendered
addon.register()
sc = bpy.context.scene
sc.render.engine = "PHOTONMAP"
sc.render.resolution_percentage = int(sc.render.resolution_percentage * int(PERCENT) / 100)
if int(THREADS) or PROFILE:
    sc.photonmap.threads = 1 if PROFILE else int(THREADS)
load = os.getloadavg()[0]
t = cpu()
bpy.ops.render.render(write_still=False)
marks["process_render"] = cpu() - t
print("RESULT " + json.dumps(dict(marks=marks, load=load, spp=sc.photonmap.spp,
                                  stats=film_stats)), flush=True)
"""

STAGES = ("export", "prepare_rest", "effects", "photons", "photon_map", "camera",
          "render_total")

RAYS = ("camera_rays", "shadow_rays", "gather_rays", "specular_rays")


def run(root, blend, percent, threads, profile="", sets=""):
    """The child's stage marks for one render: {stage: CPU s}, the load average at its
    start and the film's numeric stats."""
    env = dict(os.environ, PYTHONPATH=root)
    out = subprocess.run([sys.executable, "-c", CHILD, root, blend, str(percent),
                          str(threads), profile, sets], env=env, capture_output=True, text=True,
                         cwd=root)
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            got = json.loads(line[7:])
            m = got["marks"]
            m["prepare_rest"] = m.get("prepare", 0.0) - m.get("effects", 0.0)
            return got
    raise RuntimeError(f"{root} {blend}: no result\n{out.stdout[-2000:]}\n{out.stderr[-3000:]}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", action="append", help="checkout(s) to time (default: this one)")
    ap.add_argument("--blends", default="figure6_box,figure7_blocker,figure8_caustic")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--percent", type=int, default=100, help="of the blend's resolution %%")
    ap.add_argument("--threads", type=int, default=0, help="0: the blend's (all cores)")
    ap.add_argument("--profile", default="", help="cProfile output (one render, 1 thread)")
    ap.add_argument("--set", action="append", default=[],
                    help="module.NAME=value set in the child before the render, e.g. "
                         "engine.photonlayout.COMPACT=False")
    args = ap.parse_args()
    roots = [os.path.abspath(r) for r in (args.root or [HERE])]
    sets = ";".join(args.set)
    if args.profile:
        got = run(roots[0], args.blends.split(",")[0], args.percent, 1, args.profile, sets)
        print(json.dumps(got["marks"]))
        return
    print("| root | blend | load | " + " | ".join(STAGES) + " | " + " | ".join(RAYS)
          + " | film |")
    print("|---|---|---:|" + "---:|" * (len(STAGES) + len(RAYS)) + "---|")
    best = {}
    for blend in args.blends.split(","):
        for _ in range(args.repeat):
            for root in roots:  # interleaved: a load change hits every root alike
                got = run(root, blend, args.percent, args.threads, sets=sets)
                m = got["marks"]
                name = os.path.basename(root)
                print(f"| {name} | {os.path.basename(blend)} | {got['load']:.1f} | "
                      + " | ".join(f"{m.get(s, 0.0):.2f}" for s in STAGES) + " | "
                      + " | ".join(f"{got['stats'].get(r, 0) / 1e6:.2f}M" for r in RAYS)
                      + f" | {m.get('film', '')} |",
                      flush=True)
                b = best.setdefault((name, blend), {})
                for s in STAGES:
                    b[s] = min(b.get(s, 1e9), m.get(s, 0.0))
    print("\nminimum over the repeats, CPU s")
    print("| root | blend | " + " | ".join(STAGES) + " |")
    print("|---|---|" + "---:|" * len(STAGES))
    for (name, blend), b in best.items():
        print(f"| {name} | {os.path.basename(blend)} | " + " | ".join(f"{b[s]:.2f}" for s in STAGES) + " |")


if __name__ == "__main__":
    main()
