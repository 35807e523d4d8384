"""Multiscatter GGX against GGX on a rough single-plane pane under a sun, both engines
(roughcaustic48, docs/accuracy.md "roughcaustic48"): does Multiscatter GGX put about twice
the GGX light on the floor in Cycles as in ours (roughphoton47, "Noticed")?

tests/blender/test_pane_sun_cycles.py's scene (a 20 m floor of albedo 0.5, an 8 m
single-plane Glass BSDF pane at 1 m, IOR 1.5, a 3 W/m^2 sun 30 degrees off the zenith, a
15 degree disc; 32 x 32 orthographic view from under the pane), Filter Glossy 0, clamps
off, Cycles at Max Bounces 12. Prints per roughness and distribution the image mean of
Cycles (SPP samples, seed 0) and ours (16 spp, photons / caustic photons PHOTONS, seed
0, the Caustic pass too), and the Multiscatter / GGX ratio of each.

    PYTHONPATH=$PWD .venv/bin/python bench/roughcaustic48_multiscatter.py [SPP] [ROUGH ...]
        (defaults: 512 spp, roughness 1.0 and 0.6)
"""
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))

PHOTONS = 100_000


def main():
    import bpy
    import addon
    import blender_helpers as bh
    import test_pane_sun_cycles as ps
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="roughcaustic48_ms_")
    args = sys.argv[1:]
    spp = int(args[0]) if args else 512
    roughs = [float(a) for a in args[1:]] or [1.0, 0.6]

    def build(rough, dist):
        bpy.ops.wm.read_homefile(use_empty=True)
        s = bpy.context.scene
        ps._scene(bpy, s)
        s.cycles.pixel_filter_type, s.cycles.filter_width = "BOX", 1.0
        g = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
        g.inputs["Roughness"].default_value = rough
        g.distribution = dist
        return s

    for rough in roughs:
        got = {}
        for dist in ("GGX", "MULTI_GGX"):
            s = build(rough, dist)
            bh.cycles_plain(s, spp, 12)
            s.render.engine = "CYCLES"
            path = bh.render_exr(bpy, s, os.path.join(tmp, f"c{rough}{dist}.exr"))
            cyc = float(bh.read_rgba(bpy, path)[..., :3].mean())
            s = build(rough, dist)
            s.cycles.blur_glossy = 0.0
            s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
            bh.cheap(s, spp=16, photons=PHOTONS, caustic_photons=PHOTONS)
            s.photonmap.seed = 0
            s.render.engine = "PHOTONMAP"
            path = bh.render_exr(bpy, s, os.path.join(tmp, f"o{rough}{dist}.exr"),
                                 multilayer=True)
            L = bh.read_layers(path)
            ours = float(L["Combined"][..., :3].mean())
            caustic = float(L["Caustic"][..., :3].mean())
            got[dist] = (cyc, ours, caustic)
            print(f"roughness {rough} {dist}: Cycles {cyc:.4f}, ours {ours:.4f} "
                  f"(Caustic pass {caustic:.4f}), ours / Cycles {ours / cyc:.4f}",
                  flush=True)
        (cg, og, kg), (cm, om, km) = got["GGX"], got["MULTI_GGX"]
        print(f"roughness {rough}: Multiscatter / GGX: Cycles {cm / cg:.4f}, ours "
              f"{om / og:.4f} (Caustic pass {km / kg:.4f})", flush=True)


if __name__ == "__main__":
    main()
