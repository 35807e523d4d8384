"""The Caustic pass under a rough single-plane pane lit by a sun, seed by seed, against
rho / pi E_sun T (roughphoton47, docs/accuracy.md "roughphoton47").

tests/blender/test_pane_sun_cycles.py's scene as a PaperScene (a 20 m floor, albedo 0.5;
an 8 m pane at 1 m, Glass BSDF GGX, IOR 1.5; a 3 W/m^2 sun 30 degrees off the zenith, a
15 degree disc; an orthographic 2 x 2 m view from under the pane), at
bench/bench_split_rough_glass.py's settings (16 spp, 100,000 photons, 100,000 caustic
photons), seeds 0-7. T: the closure's valid-pairs transmittance at 30 degrees
(tests/test_rough_pane_photons.py). Rough glass focuses nothing, so the pass reads the
global shot's caustic-kind photons (a few thousand; a few hundred in the view), not the
caustic shot. Prints one line per roughness: each seed's Caustic pass / rho / pi E_sun T,
their mean and its standard error.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_rough_pane_seeds.py
    PYTHONPATH=$PWD .venv/bin/python bench/bench_rough_pane_seeds.py blender
        the Blender test's own scene (bench/bench_split_rough_glass.py's pane, GGX, FG 0,
        clamps off; ours only), roughness 1 and 0.3, seeds 0-5
"""
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))


def blender():
    import tempfile
    import bpy
    import addon
    import blender_helpers as bh
    import test_pane_sun_cycles as ps
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="roughpane_")
    # rho / pi E_sun T (T at a point sun's 30 degrees, tests/test_rough_pane_photons.py)
    for rough, want in ((1.0, 0.1544), (0.3, 0.1759)):
        vals = []
        for seed in range(6):
            bpy.ops.wm.read_homefile(use_empty=True)
            s = bpy.context.scene
            ps._scene(bpy, s)
            s.cycles.pixel_filter_type, s.cycles.filter_width = "BOX", 1.0
            g = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
            g.inputs["Roughness"].default_value = rough
            g.distribution = "GGX"
            s.cycles.blur_glossy = 0.0
            s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
            bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
            s.photonmap.seed = seed
            s.render.engine = "PHOTONMAP"
            path = bh.render_exr(bpy, s, os.path.join(tmp, f"o{rough}_{seed}.exr"),
                                 multilayer=True)
            vals.append(float(bh.read_layers(path)["Caustic"][..., :3].mean()))
        print(f"Blender scene, roughness {rough}: Caustic pass "
              + " ".join(f"{v:.4f}" for v in vals) + "; / rho / pi E_sun T "
              + " ".join(f"{v / want:.3f}" for v in vals)
              + f"; mean {sum(vals) / len(vals) / want:.4f}", flush=True)


def main():
    if sys.argv[1:] == ["blender"]:
        sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
        return blender()
    from engine import RenderSettings
    import test_rough_pane_photons as t
    seeds = range(8)
    for r in (0.3, 0.6, 1.0):
        want = t.ALBEDO / math.pi * t.SUN_E * t._transmittance(r)
        vals, stored = [], []
        for seed in seeds:
            film = t._scene(r, 15.0).render(RenderSettings(
                spp=16, photons=100_000, caustic_photons=100_000, seed=seed))
            vals.append(float(film.caustic.astype(np.float64).mean()) / want)
            stored.append(int(film.stats.get("caustic_photons", 0)))
        v = np.array(vals)
        print(f"roughness {r}: rho / pi E_sun T {want:.4f}; caustic photons stored "
              f"{min(stored)}-{max(stored)}; seeds {seeds.start}-{seeds.stop - 1}: "
              + " ".join(f"{x:.3f}" for x in v)
              + f"; mean {v.mean():.4f} +- {v.std(ddof=1) / math.sqrt(len(v)):.4f}",
              flush=True)


if __name__ == "__main__":
    main()
