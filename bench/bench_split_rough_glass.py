"""Where the Filter Glossy split's chains and Cycles part at Filter Glossy 1 through glass
(splitpane47, docs/compatibility.md "splitpane47", "Left"). Prints one line per case.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_split_rough_glass.py water [flat|smooth]
        the glass of water, the water alone and the glass alone: Cycles (4096 spp, seed 0)
        and ours (64 spp, seeds 0-1, as the test renders it) at Filter Glossy 0 and 1
    PYTHONPATH=$PWD .venv/bin/python bench/bench_split_rough_glass.py pane ROUGH [GGX|MULTI_GGX] [flip] [world]
        tests/blender/test_pane_sun_cycles.py's scene (or test_pane_world_cycles.py's
        white world) with its pane made rough (Cycles 2048 spp at 0 and 1; ours 16 spp at
        0 and 1, clamps off, its passes: the Caustic pass is the photons' light at 0 and
        the chains' at 1); flip: the pane's normal down (the floor on its air side)
"""
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))


def main():
    import bpy
    import addon
    import blender_helpers as bh
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="splitrough_")
    args = sys.argv[1:]

    def mean(s, engine, name, passes=False):
        s.render.engine = engine
        path = bh.render_exr(bpy, s, os.path.join(tmp, name), multilayer=passes)
        if passes:
            L = bh.read_layers(path)
            return (float(L["Combined"][..., :3].mean()),
                    {k: round(float(v[..., :3].mean()), 4) for k, v in L.items()
                     if k not in ("Combined", "Photon Hits")})
        return float(bh.read_rgba(bpy, path)[..., :3].mean())

    if args[0] == "water":
        import test_glass_of_water_cycles as gw
        shading = args[1] if len(args) > 1 else "flat"

        def build(v):
            bpy.ops.wm.read_homefile(use_empty=True)
            s = bpy.context.scene
            gw._scene(bpy, s, shading, water=(v != "glass"))
            if v == "water":
                bpy.data.objects.remove(bpy.data.objects["Glass"], do_unlink=True)
            return s
        for v in ("full", "water", "glass"):
            s = build(v)
            c = bh.cycles_plain(s, 4096, 12)
            out = {}
            for fg in (0.0, 1.0):
                c.blur_glossy = fg
                out[f"C{fg:g}"] = mean(s, "CYCLES", f"{v}c{fg}.exr")
            for fg in (0.0, 1.0):
                s = build(v)
                s.cycles.blur_glossy = fg
                bh.cheap(s, spp=64, photons=20_000, caustic_photons=100_000)
                vals = []
                for seed in (0, 1):
                    s.photonmap.seed = seed
                    vals.append(mean(s, "PHOTONMAP", f"{v}o{fg}{seed}.exr"))
                out[f"O{fg:g}"] = sum(vals) / 2
            print(f"{shading} {v:6s} " + " ".join(f"{k} {x:.4f}" for k, x in out.items())
                  + f"  ours / Cycles at 0 {out['O0'] / out['C0']:.4f}, at 1 "
                  f"{out['O1'] / out['C1']:.4f}", flush=True)
        return
    rough = float(args[1])
    dist = next((a for a in args[2:] if a in ("GGX", "MULTI_GGX")), "MULTI_GGX")
    world = "world" in args

    def build():
        bpy.ops.wm.read_homefile(use_empty=True)
        s = bpy.context.scene
        if world:
            import test_pane_world_cycles as pw
            pw._scene(bpy, s, "white")
        else:
            import test_pane_sun_cycles as ps
            ps._scene(bpy, s)
        s.cycles.pixel_filter_type, s.cycles.filter_width = "BOX", 1.0
        g = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
        g.inputs["Roughness"].default_value = rough
        g.distribution = dist
        if "flip" in args:
            bpy.data.objects["Pane"].rotation_euler = (3.141592653589793, 0.0, 0.0)
        return s
    s = build()
    c = bh.cycles_plain(s, 2048, 12)
    C = {}
    for fg in (0.0, 1.0):
        c.blur_glossy = fg
        C[fg] = mean(s, "CYCLES", f"c{fg}.exr")
    for fg in (0.0, 1.0):
        s = build()
        s.cycles.blur_glossy = fg
        s.cycles.sample_clamp_indirect = s.cycles.sample_clamp_direct = 0.0
        bh.cheap(s, spp=16, photons=100_000, caustic_photons=100_000)
        s.photonmap.seed = 0
        o, passes = mean(s, "PHOTONMAP", f"o{fg}.exr", passes=True)
        print(f"rough {rough} {dist}{' flip' if 'flip' in args else ''}"
              f"{' world' if world else ''} FG {fg:g}: Cycles {C[fg]:.4f}, ours {o:.4f} "
              f"({o / C[fg]:.4f}) {passes}", flush=True)


if __name__ == "__main__":
    main()
