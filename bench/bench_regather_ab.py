"""The regathered ends' secondary caustic off / on (integrator.SECONDARY_FROM_GATHER_POINTS,
regather29) in one process: a warm-up render, then N pairs of 1-worker renders at default
settings, the order alternating (off, on / on, off), process CPU s each, the camera pass's
seconds and the load; min and median ratios. Steadier than fresh processes on a loaded
machine (the same heap, caches and compiled kernels for both).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_regather_ab.py figure7_blocker 3

The blend is one bench_kernels.py exported (its --work directory, default /tmp/bench_kernels)."""
import os, pickle, sys, tempfile, time
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from engine.jit import ensure_compiled
ensure_compiled()
import engine.integrator as I
from engine.render import render
from engine.settings import RenderSettings
scene = pickle.load(open(os.path.join(tempfile.gettempdir(), "bench_kernels", f"{sys.argv[1]}.pkl"), "rb"))
scene.width, scene.height = 320, 240
render(scene, RenderSettings(workers=1, spp=1))  # warm
out = {False: [], True: []}
for rep in range(int(sys.argv[2])):
    for flag in ((False, True) if rep % 2 == 0 else (True, False)):
        I.SECONDARY_FROM_GATHER_POINTS = flag
        t0 = time.process_time()
        film = render(scene, RenderSettings(workers=1))
        out[flag].append(round(time.process_time() - t0, 2))
        print(flag, out[flag][-1], round(film.stats.get("time_camera", 0), 2), os.getloadavg()[0], flush=True)
print("before", out[False], "after", out[True], "min ratio", min(out[False]) / min(out[True]),
      "median ratio", sorted(out[False])[len(out[False]) // 2] / sorted(out[True])[len(out[True]) // 2])
