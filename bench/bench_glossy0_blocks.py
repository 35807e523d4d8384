"""Ours against Cycles per 4 x 4-pixel block on tests/blender/test_glass_of_water_cycles.py's
scene (16 x 16) at Light Paths Glossy G, with the glass's smooth-shaded sides chosen
(docs/accuracy.md, turnedcamera45: the Glossy-0 residual comes with the inner side).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glossy0_blocks.py G SIDES water|empty

SIDES: smooth (both sides), outer or inner (the glass's other side flat; the water, if
any, smooth). BLOCK_WALL=1 in the environment: a black card just outside the sun-side
wall, up to the rim (the sun reaches the cavity through the open top only). Ours 64 spp, 20k / 400k photons, seed 0; Cycles 2048 spp (cycles_plain:
no clamp, no glossy blur, 12 bounces, read by both). Saves both images as .npy in
/tmp/turnedcamera45 (made if missing).
"""
import math, os, sys
os.makedirs("/tmp/turnedcamera45", exist_ok=True)
ROOT = os.getcwd()
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import numpy as np
import bpy, addon
addon.register()
from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
from test_glass_of_water_cycles import _scene
glossy = int(sys.argv[1]); shading = sys.argv[2]; water = sys.argv[3] == "water"
out = {}
for eng in ("PHOTONMAP", "CYCLES"):
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    _scene(bpy, sc, "smooth", water=water)
    ob = bpy.data.objects["Glass"]
    for poly in ob.data.polygons:
        if abs(poly.normal.z) < 0.1:
            c = poly.center
            outer = poly.normal.x * c.x + poly.normal.y * c.y > 0
            poly.use_smooth = (outer and shading in ("outer", "smooth")) or (not outer and shading in ("inner", "smooth"))
    if os.environ.get("BLOCK_WALL"):
        # a black card just outside the sun-side wall, up to the rim: the sun reaches the
        # cavity through the open top only
        bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.0, -0.41, 0.5),
                                         rotation=(math.pi / 2, 0.0, 0.0), scale=(2.0, 1.0, 1.0))
        from blender_helpers import glass_or_diffuse_material
        bpy.context.object.data.materials.append(
            glass_or_diffuse_material(bpy, "Black", "diffuse", (0.0,) * 3))
    print("smooth faces", sum(p.use_smooth for p in ob.data.polygons), "of", len(ob.data.polygons))
    cycles_plain(sc, 2048, 12)
    sc.cycles.glossy_bounces = glossy
    cheap(sc, spp=64, photons=20_000, caustic_photons=400_000)
    sc.photonmap.seed = 0
    sc.render.engine = eng
    out[eng] = read_rgba(bpy, render_exr(bpy, sc, f"/tmp/turnedcamera45/g0_{eng}.exr"))[..., :3].mean(axis=2)
    np.save(f"/tmp/turnedcamera45/g0map_{glossy}_{shading}_{sys.argv[3]}_{eng}.npy", out[eng])
a, c = out["PHOTONMAP"], out["CYCLES"]
np.set_printoptions(precision=3, suppress=True, linewidth=200)
print("means", a.mean(), c.mean(), a.mean() / c.mean())
b = lambda x: x.reshape(4, 4, 4, 4).mean(axis=(1, 3))
print("ours 4x4 blocks\n", b(a)); print("cycles\n", b(c)); print("ratio\n", b(a) / b(c))
