"""Caustic Photons against the noise of the floor under a rough single-plane pane lit by a
sun (roughcaustic48, docs/accuracy.md "roughcaustic48").

tests/test_rough_pane_photons.py's scene (a 20 m floor of albedo 0.5 under an 8 m GGX
Glass BSDF pane at 1 m, IOR 1.5; a 3 W/m^2 sun 30 degrees off the zenith, a 15 degree
disc) seen from under the pane by an orthographic 2 x 2 m view at RES x RES pixels, 16 spp,
100,000 global photons, Filter Glossy 0. The floor's light through the pane is the Caustic
pass; far from the pane's edges it is even (rho / pi E_sun T), so its spread over the
pixels is noise. For each roughness, Caustic Photons and the aim at rough refractors off
("before": effects.AIM_ROUGH_REFRACTORS = False, the global shot's caustic-kind photons)
and on ("after"): the caustic photons stored, the Caustic pass's mean (and / rho / pi
E_sun T at a point sun's 30 degrees; each seed's too), its pixel std / mean, the std /
mean of its 8 x 8 pixel block means (the blotches), the image's mean; means over seeds
0 .. SEEDS-1.

    PYTHONPATH=$PWD .venv/bin/python bench/roughcaustic48_pane_noise.py [RES] [SEEDS] [ROUGH ...]
        (defaults: 64, 2, roughness 1.0 and 0.5)
    PYTHONPATH=$PWD .venv/bin/python bench/roughcaustic48_pane_noise.py blender [SPP] [ROUGH ...]
        the Blender test's own scene (tests/blender/test_pane_sun_cycles.py, 32 x 32, GGX,
        Filter Glossy 0, clamps off): Cycles' image mean (SPP samples, default 512) and
        ours' (16 spp, 100,000 photons, 200,000 caustic photons, seeds 0-3) before and
        after, roughness 0.3 and 1.0 by default
"""
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

COUNTS = (50_000, 200_000, 800_000)


def blender(args):
    import tempfile
    import bpy
    import addon
    import blender_helpers as bh
    import test_pane_sun_cycles as ps
    from engine import effects
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="roughcaustic48_")
    spp = int(args[0]) if args else 512
    roughs = [float(a) for a in args[1:]] or [0.3, 1.0]

    def build(rough):
        bpy.ops.wm.read_homefile(use_empty=True)
        s = bpy.context.scene
        ps._scene(bpy, s)
        s.cycles.pixel_filter_type, s.cycles.filter_width = "BOX", 1.0
        g = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
        g.inputs["Roughness"].default_value = rough
        g.distribution = "GGX"
        return s
    for rough in roughs:
        s = build(rough)
        bh.cycles_plain(s, spp, 12)
        s.render.engine = "CYCLES"
        cyc = float(bh.read_rgba(bpy, bh.render_exr(bpy, s, os.path.join(
            tmp, f"c{rough}.exr")))[..., :3].mean())
        for aim in (False, True):
            effects.AIM_ROUGH_REFRACTORS = aim
            vals = []
            for seed in range(4):
                s = build(rough)
                s.cycles.blur_glossy = 0.0
                s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
                bh.cheap(s, spp=16, photons=100_000, caustic_photons=200_000)
                s.photonmap.seed = seed
                s.render.engine = "PHOTONMAP"
                vals.append(float(bh.read_rgba(bpy, bh.render_exr(bpy, s, os.path.join(
                    tmp, f"o{rough}{aim}{seed}.exr")))[..., :3].mean()))
            v = np.array(vals) / cyc
            print(f"roughness {rough}, {'aimed' if aim else 'global (before)'}: Cycles "
                  f"{cyc:.4f} ({spp} spp); ours / Cycles seeds 0-3 "
                  + " ".join(f"{x:.3f}" for x in v)
                  + f"; mean {v.mean():.4f} +- {v.std(ddof=1) / math.sqrt(len(v)):.4f}",
                  flush=True)


def main():
    if sys.argv[1:2] == ["blender"]:
        sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
        return blender(sys.argv[2:])
    from engine import RenderSettings, effects
    import test_rough_pane_photons as t
    args = sys.argv[1:]
    res = int(args[0]) if args else 64
    seeds = range(int(args[1]) if len(args) > 1 else 2)
    roughs = [float(a) for a in args[2:]] or [1.0, 0.5]
    print("| roughness | shot | Caustic Photons | stored | Caustic pass (/ rho/pi E T) | "
          "pixel std / mean | 8x8 block std / mean | image mean |")
    print("|---|---|---:|---:|---|---:|---:|---:|")
    for r in roughs:
        want = t.ALBEDO / math.pi * t.SUN_E * t._transmittance(r)
        for aim in (False, True):
            effects.AIM_ROUGH_REFRACTORS = aim
            for n in (COUNTS if aim else COUNTS[:1]):
                rows = []
                for seed in seeds:
                    scene = t._scene(r, 15.0)
                    scene.width = scene.height = res
                    film = scene.render(RenderSettings(spp=16, photons=100_000,
                                                       caustic_photons=n, seed=seed))
                    c = film.caustic.astype(np.float64).mean(axis=2)
                    b = c[:res // 8 * 8, :res // 8 * 8].reshape(
                        res // 8, 8, res // 8, 8).mean(axis=(1, 3))
                    rows.append((int(film.stats.get("caustic_photons", 0)), c.mean(),
                                 c.std() / c.mean(), b.std() / b.mean(),
                                 float(film.combined[..., :3].astype(np.float64).mean())))
                a = np.array(rows)
                m = a.mean(axis=0)
                print(f"| {r:g} | {'aimed' if aim else 'global (before)'} | "
                      f"{n if aim else '(any)'} | {int(m[0]):,} | {m[1]:.4f} "
                      f"({m[1] / want:.3f}; seeds " + " ".join(f"{x / want:.3f}" for x in a[:, 1])
                      + f") | {m[2]:.3f} | {m[3]:.3f} | {m[4]:.4f} |", flush=True)


if __name__ == "__main__":
    main()
