"""What a render's glow shot (engine/render.py GLOW_SHOT: the caustic-only shot of light
off rough specular layers first, beside a global shot aimed by visual importance) costs,
by part: photons emitted into the region and outside it (glow_emitters: at least the
light's natural count outside, split >= 1), those the region cull drops, photons stored,
and CPU seconds of emission (the world / lamp kernels, the region cull) and of tracing
(closest hits, scattering). One process, one worker, best of --repeat renders by the
glow shot's own CPU seconds (time.process_time around trace_photons); docs/performance.md
"perf47".

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glow_shot.py SCENE.pkl [...]
        [--size 160x120] [--spp 16] [--repeat 3]

SCENE.pkl: a pickled (scene, settings kwargs) pair, as bench_interior.export gives for
bench/bench_exterior.py's yards (e.g. its "world": a world colour over a 40 m yard).
"""
import argparse
import cProfile
import importlib
import os
import pickle
import pstats
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from engine.jit import ensure_compiled  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

R = importlib.import_module("engine.render")  # (engine.render is also a function)
vi = importlib.import_module("engine.visualimportance")

PARTS = {  # profile entries (file tail, function) -> part
    ("emission.py", "drop_meeting"): "region cull",
    ("world.py", "emit_world"): "emission kernels",
    ("emission.py", "emit_point"): "emission kernels",
    ("photonkernels.py", "_scatter"): "scattering",
    ("accel.py", "_intersect_packets"): "closest hits",
}


def one(path, width, height, spp, repeat):
    with open(path, "rb") as f:
        scene, kw = pickle.load(f)
    scene.width, scene.height = width, height
    trace, drop = R.trace_photons, vi.drop_meeting
    got = {}

    def counted_drop(*a):
        j0, j = a[5], a[6]
        end = drop(*a)
        if got.get("in_glow"):
            got["natural"] += j - j0
            got["culled"] += j - end
        return end

    def spy(ctx, emitters, counts, *a, **k):
        if k.get("stream") != R.GLOW_STREAM:
            return trace(ctx, emitters, counts, *a, **k)
        got.update(in_glow=True, natural=0, culled=0, emitted=int(np.sum(counts)),
                   aimed=int(sum(round(getattr(e, "share", 0.0) * c)
                                 for e, c in zip(emitters, counts))))
        prof = cProfile.Profile(time.process_time)
        t0 = time.process_time()
        prof.enable()
        try:
            out = trace(ctx, emitters, counts, *a, **k)
        finally:
            prof.disable()
            got["in_glow"] = False
        got["cpu"] = time.process_time() - t0
        got["stored"] = len(out)
        parts = dict.fromkeys(PARTS.values(), 0.0)
        for (file, _, name), row in pstats.Stats(prof).stats.items():
            part = PARTS.get((os.path.basename(file), name))
            if part is not None:
                parts[part] += row[2]  # (tottime: the compiled call itself)
        got["parts"] = parts
        return out

    R.trace_photons, vi.drop_meeting = spy, counted_drop
    best = None
    try:
        for _ in range(repeat):
            got.clear()
            film = R.render(scene, RenderSettings(**dict(kw, workers=1, spp=spp)))
            if "cpu" in got and (best is None or got["cpu"] < best[0]["cpu"]):
                best = (dict(got), film.stats)
    finally:
        R.trace_photons, vi.drop_meeting = trace, drop
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pickles", nargs="+")
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    width, height = (int(v) for v in a.size.lower().split("x"))
    ensure_compiled()
    print(f"{width} x {height}, {a.spp} spp, 1 worker; the glow shot, best of {a.repeat} "
          f"(load {os.getloadavg()[0]:.1f})")
    print("| scene | glow share / split | emitted: aimed + outside | outside culled | "
          "stored | CPU s | emission kernels / region cull / closest hits / scattering s | "
          "us a photon emitted |")
    print("|---|---|---:|---:|---:|---:|---|---:|")
    for path in a.pickles:
        got = one(path, width, height, a.spp, a.repeat)
        name = os.path.splitext(os.path.basename(path))[0]
        if got is None:
            print(f"| {name} | no glow shot | | | | | | |")
            continue
        g, st = got
        p = g["parts"]
        print(f"| {name} | {st.get('glow_share', float('nan')):.4f} / "
              f"{st.get('glow_split', float('nan')):.2f} | {g['emitted']:,}: {g['aimed']:,} + "
              f"{g['emitted'] - g['aimed']:,} | {g['culled']:,} | {g['stored']:,} | "
              f"{g['cpu']:.3f} | {p['emission kernels']:.3f} / {p['region cull']:.3f} / "
              f"{p['closest hits']:.3f} / {p['scattering']:.3f} | "
              f"{g['cpu'] / max(g['emitted'], 1) * 1e6:.2f} |", flush=True)


if __name__ == "__main__":
    main()
