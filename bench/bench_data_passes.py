"""CPU seconds of a whole render with and without Cycles' data passes (RenderSettings.data_passes:
by default Denoising Data + Diffuse / Glossy / Transmission Color, engine/datapasses.py; an
optional fourth argument names the kinds, comma-separated), interleaved runs on an exported
example blend (docs/performance.md, "passes", "blenderbits").

    PYTHONPATH=$PWD .venv/bin/python bench/bench_data_passes.py figure6_box 160x120 16 [KINDS]
"""
import os
import pickle
import sys
import tempfile
import time

sys.path.insert(0, os.getcwd()); sys.path.insert(0, os.path.join(os.getcwd(), "bench"))
import numpy as np  # noqa: E402
from bench_kernels import exported
from engine.render import render
from engine.settings import RenderSettings
from engine.jit import ensure_compiled
ensure_compiled()
where = os.path.join(tempfile.gettempdir(), "film_hashes")
name, size, spp = sys.argv[1], sys.argv[2], int(sys.argv[3])
w, h = (int(v) for v in size.split("x"))
scene = pickle.load(open(exported(name, where), "rb")); scene.width, scene.height = w, h
kinds = tuple(sys.argv[4].split(",")) if len(sys.argv) > 4 else ("color", "denoising")
res = {(): [], kinds: []}
render(scene, RenderSettings(workers=1, spp=2, data_passes=kinds))  # warm
for rep in range(3):
    for dp in res:
        t = time.process_time()
        film = render(scene, RenderSettings(workers=1, spp=spp, data_passes=dp))
        res[dp].append(time.process_time() - t)
for dp, ts in res.items():
    print(name, size, spp, dp or "none", "cpu s", [round(x, 2) for x in ts], "median",
          round(float(np.median(ts)), 2))
