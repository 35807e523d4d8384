"""Light by way of one smooth surface at low Light Paths limits, live Cycles against ours
(docs/performance.md, "limits"): a floor lit only through a mirror, a flat glass pane or a
glass ball, image means at 40 x 30 (Cycles CSPP=128 spp, ours 16).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD .venv/bin/python bench/bench_limits_cycles.py mirror|pane|ball
"""
import math, os, sys, tempfile
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
sys.path.insert(0, os.path.join(ROOT, "example_blends"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import cycles_plain, read_rgba, render_exr
import make_blends as mb
which = sys.argv[1]
scene = mb.reset()
floor = mb.material("floor", "diffuse", (0.8, 0.8, 0.8))
mb.plane("Floor", 6, 6, floor)
if which == "mirror":
    m, nt, out = mb.empty_material("mirror")
    n = nt.nodes.new("ShaderNodeBsdfGlossy"); n.inputs["Roughness"].default_value = 0.0
    n.inputs["Color"].default_value = (1, 1, 1, 1)
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    mb.plane("Mirror", 3, 3, m, location=(0, 0, 3.0), rotation=(math.pi, 0, 0))
    mb.light("Lamp", "AREA", (0, 0, 2.0), 200.0, look_at=(0, 0, 3.0), size=0.5)
    cases = [(12, 1, 0, 12), (1, 1, 0, 12), (0, 1, 0, 12)]
else:
    glass = mb.material("glass", "glass", (1, 1, 1), roughness=0.0, ior=1.5)
    if which == "pane":
        mb.box("Pane", 2.0, 2.0, 0.02, glass, location=(0, 0, 1.5))
    else:
        mb.sphere("Ball", 0.6, glass, (0, 0, 1.5))
    # a blocker ring so the floor sees the light only through the glass: an opaque plane
    # with the glass in its hole is costly; instead the light is small and close above
    mb.light("Lamp", "AREA", (0, 0, 2.3), 200.0, look_at=(0, 0, 0), size=0.3)
    cases = [(12, 1, 0, 0), (12, 1, 0, 1), (12, 1, 0, 2), (12, 4, 4, 12)]
mb.camera((0, -2.5, 1.2), (0, 0.3, 0), fov_deg=50)
mb.set_world((0, 0, 0))
scene.render.resolution_x, scene.render.resolution_y = 40, 30
scene.render.resolution_percentage = 100
tmp = tempfile.mkdtemp()
for lim in cases:
    c = cycles_plain(scene, int(os.environ.get("CSPP", 128)), lim[0])
    c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = lim[1:]
    scene.render.engine = "CYCLES"
    cyc = read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/c.exr"))[..., :3]
    scene.render.engine = "PHOTONMAP"
    pm = scene.photonmap
    pm.spp, pm.seed = 16, 0
    ours = read_rgba(bpy, render_exr(bpy, scene, f"{tmp}/o.exr"))[..., :3]
    print(f"{which} limits {lim}: cycles {cyc.mean():.5f} ours {ours.mean():.5f}", flush=True)
