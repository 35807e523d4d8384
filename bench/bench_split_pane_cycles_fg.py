"""Cycles' image means of the split's pane and glass-of-water scenes at Filter Glossy 0
and 1 (splitpane47, docs/compatibility.md "splitpane47"): the tests compare ours (at
the scene's Filter Glossy 1) with Cycles at Filter Glossy 0; this says whether that is
the same target. Prints a table.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_split_pane_cycles_fg.py [--ours]

--ours also renders ours (at the scene's Filter Glossy 1, the split as
glossysplit.ENABLED says; --split on, --no-split off; --no-panes: engine/panelight.py
off) and prints ours / each. Names given select the scenes (substrings).
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
    import test_glass_of_water_cycles as gw
    import test_pane_sun_cycles as ps
    import test_pane_world_cycles as pw
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    ours = "--ours" in sys.argv
    from engine import glossysplit
    if "--split" in sys.argv:
        glossysplit.ENABLED = True
    if "--no-split" in sys.argv:
        glossysplit.ENABLED = False
    if "--no-panes" in sys.argv:
        # (A/B: no next-event panes, the light through them caustic as before pane31)
        from engine import panelight
        panelight.ENABLED = False
    tmp = tempfile.mkdtemp(prefix="splitpane47_")

    def mean(scene, engine, name):
        scene.render.engine = engine
        img = bh.read_rgba(bpy, bh.render_exr(bpy, scene, os.path.join(tmp, name)))
        return float(img[..., :3].mean())

    # (name, build(scene), Cycles spp, ours' cheap settings as its test)
    cases = [
        ("pane_sun", lambda s: ps._scene(bpy, s), 2048,
         dict(spp=16, photons=100_000, caustic_photons=100_000)),
        ("pane_world[white]", lambda s: pw._scene(bpy, s, "white"), 2048,
         dict(spp=16, photons=100_000, caustic_photons=100_000)),
        ("pane_world[sky map]", lambda s: pw._scene(bpy, s, "sky map"), 2048,
         dict(spp=16, photons=100_000, caustic_photons=100_000)),
        ("glass_of_water[flat]", lambda s: gw._scene(bpy, s, "flat"), 4096,
         dict(spp=4, photons=20_000, caustic_photons=100_000)),
        ("glass_of_water[smooth]", lambda s: gw._scene(bpy, s, "smooth"), 4096,
         dict(spp=4, photons=20_000, caustic_photons=100_000)),
    ]
    only = [a for a in sys.argv[1:] if not a.startswith("--")]
    print(f"{'scene':24s} {'Cycles FG0':>10s} {'Cycles FG1':>10s} {'FG1/FG0':>8s}"
          + (f" {'ours':>8s} {'ours/FG0':>8s} {'ours/FG1':>8s}" if ours else ""))
    for name, build, spp, cheap in cases:
        if only and not any(o in name for o in only):
            continue
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = bpy.context.scene
        build(scene)
        scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
        got = {}
        if ours:
            scene.render.engine = "PHOTONMAP"
            bh.cheap(scene, **cheap)
            scene.photonmap.seed = 0
            fg = scene.cycles.blur_glossy
            o = mean(scene, "PHOTONMAP", f"{name}_ours.exr")
        c = bh.cycles_plain(scene, spp, 12)
        for fg in (0.0, 1.0):
            c.blur_glossy = fg
            got[fg] = mean(scene, "CYCLES", f"{name}_fg{fg:g}.exr")
        line = f"{name:24s} {got[0.0]:10.4f} {got[1.0]:10.4f} {got[1.0] / got[0.0]:8.4f}"
        if ours:
            line += f" {o:8.4f} {o / got[0.0]:8.4f} {o / got[1.0]:8.4f}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
