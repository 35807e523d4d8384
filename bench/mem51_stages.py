"""Resident memory of one render through the add-on, stage by stage (mem51,
docs/performance.md "mem51"): VmRSS sampled every 50 ms on a thread of the render's own
process, marked at each stage (numpy, `import bpy`, the add-on, the engine's import
(numba, llvmlite, scipy, embreex), the scene's build in Blender, the kernels' load, the
export, prepare_context (BVH, lights, effect analysis), the photon pass, the maps' build,
the camera pass), with the peak within each. Prints one line a mark (the process's
VmRSS / VmHWM there, MB) and each stage's sampled peak; --json writes the samples.

    PYTHONPATH=$PWD .venv/bin/python bench/mem51_stages.py [--json OUT] \
        bench/newuser51_donut.py ours OUT.exr [its options]
    PYTHONPATH=$PWD .venv/bin/python bench/mem51_stages.py [--json OUT] \
        --blend example_blends/figure6_box.blend W H OUT.exr [SPP [THREADS]]

A script runs as its own __main__ (as the bench scripts do); --blend opens the blend and
renders it with engine 'PHOTONMAP' at its saved settings (SPP, THREADS: the add-on's
spp and threads instead). The "photon_map" stage runs until the camera pass' first
chunk is merged, so it holds the first chunks' arrays as well ("render" from then on).
"""
import json
import os
import runpy
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
T0 = time.time()
STAGE = ["start"]
MARKS, PEAKS, SAMPLES = [], {}, []


def status() -> dict:
    """VmRSS, VmHWM, RssAnon, RssFile of this process, MB."""
    out = {}
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(("VmRSS", "VmHWM", "RssAnon", "RssFile")):
                k, v = line.split(":")
                out[k] = int(v.split()[0]) // 1024
    return out


def mark(name: str) -> None:
    s = status()
    MARKS.append({"t": round(time.time() - T0, 2), "stage": name, **s})
    STAGE[0] = name
    print(f"MEM {time.time() - T0:7.2f} s  {name:34s} RSS {s['VmRSS']:5d} MB  "
          f"HWM {s['VmHWM']:5d} MB  anon {s['RssAnon']:5d} MB", flush=True)


def sample() -> None:
    while True:
        s = status()
        SAMPLES.append((round(time.time() - T0, 2), STAGE[0], s["VmRSS"]))
        PEAKS[STAGE[0]] = max(PEAKS.get(STAGE[0], 0), s["VmRSS"])
        time.sleep(0.05)


def render_blend(path, w, h, out, spp=None, threads=None):
    import bpy
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))
    import addon
    addon.register()
    sc = bpy.context.scene
    r = sc.render
    r.engine = "PHOTONMAP"
    if spp is not None:
        sc.photonmap.spp = int(spp)
    if threads is not None:
        sc.photonmap.threads = int(threads)
    r.resolution_x, r.resolution_y, r.resolution_percentage = int(w), int(h), 100
    r.image_settings.file_format, r.image_settings.color_depth = "OPEN_EXR", "32"
    r.filepath, r.use_file_extension = os.path.abspath(out), False
    t = time.process_time()
    bpy.ops.render.render(write_still=True)
    print(f"RESULT cpu_s={time.process_time() - t:.1f} spp={sc.photonmap.spp}", flush=True)


def main():
    args = sys.argv[1:]
    out = None
    if args[:1] == ["--json"]:
        out, args = args[1], args[2:]
    threading.Thread(target=sample, daemon=True).start()
    mark("python")
    import numpy  # noqa: F401
    mark("numpy")
    import bpy  # noqa: F401
    mark("import bpy")
    sys.path.insert(0, ROOT)
    import addon
    import addon.export as export
    mark("import addon")
    import engine
    import engine.jit as jit
    mark("import engine")
    er = sys.modules["engine.render"]
    register = addon.register

    def registered():
        register()
        mark("addon.register")
    addon.register = registered
    load = jit.ensure_compiled

    def ensure_compiled(*a, **k):  # the add-on's call, before its export
        mark("scene built, render called")
        got = load(*a, **k)
        mark("kernels loaded")
        return got
    jit.ensure_compiled = ensure_compiled
    export_scene = export.export_scene

    def exported(*a, **k):
        got = export_scene(*a, **k)
        mark("exported")
        return got
    export.export_scene = exported
    prepare = er.prepare_context

    def prepared(*a, **k):
        mark("engine.render started")
        got = prepare(*a, **k)
        mark("prepared (BVH, lights, effects)")
        return got
    er.prepare_context = prepared
    render = engine.render

    def rendered(scene, settings=None, progress=None, **k):
        last = [None]

        def told(stage, fraction, text):
            if stage != last[0]:
                last[0] = stage
                mark("stage " + stage)
            if progress is not None:
                progress(stage, fraction, text)
        film = render(scene, settings, progress=told, **k)
        mark("engine.render returned")
        return film
    engine.render = rendered
    try:
        if args[0] == "--blend":
            render_blend(*args[1:])
        else:
            sys.argv = args
            runpy.run_path(args[0], run_name="__main__")
    finally:
        mark("end")
        for name, peak in PEAKS.items():
            print(f"PEAK from {name:34s} to the next mark {peak:5d} MB")
        if out:
            with open(out, "w") as f:
                json.dump({"marks": MARKS, "peaks": PEAKS, "samples": SAMPLES}, f)


if __name__ == "__main__":
    main()
