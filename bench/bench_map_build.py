"""Photon map build (render._build_maps: kd-trees, gather map, radii) of a default render,
CPU and wall seconds, one checkout per run.

    .venv/bin/python bench/bench_map_build.py [CHECKOUT] [--blends figure6_box,...]
        [--workers 1,2] [--repeat 3]

CHECKOUT (default: this one) is put first on sys.path, so an older checkout's engine can
be measured by the same script. Each example blend is exported once through the add-on
(the bpy wheel; bench_kernels.exported) and its photon pass run at default
settings (320x240); the map build is then replayed `repeat` times on the same photons
(best CPU time of the process, time.process_time: all threads) and its result hashed:
the SHA-1 of every map's photon arrays, the gather map's points and irradiance, and the
radii (the same hash before and after = the same maps).
"""
import argparse
import hashlib
import importlib
import os
import pickle
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def maps_hash(out: dict) -> str:
    import numpy as np
    h = hashlib.sha1()
    for key in sorted(out):
        value = out[key]
        if hasattr(value, "photons"):  # PhotonMap
            ph = value.photons
            for a in (ph.position, ph.power, ph.direction, ph.normal, ph.kind):
                h.update(np.ascontiguousarray(a).tobytes())
        elif hasattr(value, "E"):  # GatherMap
            for a in (value.E, value.boundary, value.position, value.normal):
                h.update(np.ascontiguousarray(a).tobytes())
        else:
            h.update(repr(value).encode())
    return h.hexdigest()[:16]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkout", nargs="?", default=os.path.dirname(HERE))
    ap.add_argument("--blends", default="figure6_box,figure7_blocker")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    args = ap.parse_args(argv)
    root = os.path.abspath(args.checkout)
    sys.path.insert(0, HERE)
    from bench_kernels import exported  # exports with this checkout's add-on
    os.makedirs(args.work, exist_ok=True)
    pickles = {name: exported(name, args.work) for name in args.blends.split(",")}
    sys.path.insert(0, root)
    from engine.jit import ensure_compiled
    from engine.settings import RenderSettings
    ensure_compiled()
    render = importlib.import_module("engine.render")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; engine "
          f"{os.path.dirname(render.__file__)}")
    print("| blend | workers | global / caustic photons | build CPU s | build wall s | maps SHA-1 |")
    print("|---|---:|---|---:|---:|---|")
    for name, path in pickles.items():
        with open(path, "rb") as f:
            scene = pickle.load(f)
        scene.width, scene.height = 320, 240
        for workers in (int(w) for w in args.workers.split(",")):
            ctx = render.prepare_context(scene, RenderSettings(workers=workers))
            captured = {}
            build = render._build_maps

            def capture(ctx_, shot, caustic, use, stop):
                captured.update(shot=shot, caustic=caustic, use=use)
                return build(ctx_, shot, caustic, use, stop)
            render._build_maps = capture
            try:
                render._photon_pass(ctx, {}, None, None)
            finally:
                render._build_maps = build
            cpu = wall = float("inf")
            for _ in range(args.repeat):
                t0, c0 = time.perf_counter(), time.process_time()
                out = build(ctx, captured["shot"], captured["caustic"], captured["use"],
                            lambda: False)
                wall = min(wall, time.perf_counter() - t0)
                cpu = min(cpu, time.process_time() - c0)
            print(f"| {name} | {workers} | {len(captured['shot']):,} / "
                  f"{len(captured['caustic']):,} | {cpu:.2f} | {wall:.2f} | "
                  f"{maps_hash(out)} |", flush=True)
            ctx.accel.close()


if __name__ == "__main__":
    main()
