"""CPU cost of the s20 limits changes against the behaviour before them in one process
(before: the gather map read whole, GatherCounts.partial all False - s20's last-level
scale, GatherCounts.last_level_scale, is now gatherlevel44's subsets -, and
chaincounts.flat_passages never binding),
interleaved, best of REPS, getrusage user+sys, one worker, 16 spp. Figure 6 is exported
from its blend once by a child Blender process (bench_kernels.exported).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_limits.py REPS
"""
import os, pickle, resource, sys, tempfile
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_kernels import exported
import numpy as np
from engine import chaincounts, RenderSettings
from engine.jit import ensure_compiled
from engine.render import render
from engine.api import PaperScene
from engine.scene import Material
ensure_compiled()
o_scale, o_pass = chaincounts.GatherCounts.partial, chaincounts.flat_passages
def set_main(on):
    chaincounts.GatherCounts.partial = (lambda self, level, c: np.zeros(len(c), bool)) if on else o_scale
    chaincounts.flat_passages = (lambda c, l: np.full(len(np.asarray(c).reshape(-1, 4)), 1 << 20)) if on else o_pass
def pane():
    s = PaperScene(width=80, height=60)
    s.add_material(Material("floor", (0.8, 0.8, 0.8)))
    s.add_plane((0, 0, 0), normal=(0, 0, 1), size=6.0, material="floor", name="floor")
    s.add_material(Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=1.5))
    s.add_box((0, 0, 1.0), (3.0, 3.0, 0.02), "glass", name="pane")
    s.add_point_light((0, 0, 1.6), power=100.0)
    s.set_camera((0, -0.4, 0.8), (0, 0, 0), view_angle=40)
    return s
def fig6():
    where = os.path.join(tempfile.gettempdir(), "bench_limits")
    os.makedirs(where, exist_ok=True)
    with open(exported("figure6_box", where), "rb") as f:
        s = pickle.load(f)
    s.width, s.height = 160, 120
    return s
def mirror_glass_room(a=0.8):
    """A Lambertian room 4 x 5 x 3 m with a point light, a mirror ball and a glass ball."""
    s = PaperScene(width=48, height=36)
    s.add_material(Material("wall", (a,) * 3))
    s.add_box((0, 0, 1.5), (4, 5, 3), "wall", name="room")
    s.add_point_light((0, 0.5, 2.6), power=300.0)
    s.add_material(Material("mirror", (0.95,) * 3, metallic=1.0, roughness=0.0))
    s.add_sphere((1.0, 1.0, 0.6), 0.6, "mirror", name="mball")
    s.add_material(Material("glass", (1, 1, 1), transmission=1.0, roughness=0.0, ior=1.5))
    s.add_sphere((-1.0, 0.8, 0.6), 0.6, "glass", name="gball")
    s.set_camera((0.5, -2.2, 1.4), (-0.3, 2.0, 1.0), view_angle=70)
    return s
def room():
    s = mirror_glass_room(); s.width, s.height = 96, 72
    return s
cases = [("figure6 defaults", fig6, {}), ("pane Transmission 1", pane, dict(transmission_bounces=1)),
         ("room Total 5", room, dict(max_bounces=5))]
reps = int(sys.argv[1])
for label, make, lim in cases:
    best = {"main": 1e9, "branch": 1e9}
    for _ in range(reps):
        for k in best:
            set_main(k == "main")
            scene = make()
            r0 = resource.getrusage(resource.RUSAGE_SELF)
            render(scene, RenderSettings(workers=1, spp=16, seed=0, **lim))
            r1 = resource.getrusage(resource.RUSAGE_SELF)
            best[k] = min(best[k], r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    print(f"{label}: main {best['main']:.2f} s, branch {best['branch']:.2f} s", flush=True)
