"""A shadow-sampled emissive panel over window glass against Cycles at Filter Glossy 0 and 1,
by the panel's size and height (passages48, docs/compatibility.md "passages48", step 4):
Cycles blurs the slab's refraction after the floor's diffuse bounce at Filter Glossy 1,
while our shadow rays cross the passage unblurred. Prints one line per panel.

    PYTHONPATH=$PWD .venv/bin/python bench/passages48_panel.py [SIZE:HEIGHT ...]

tests/blender/test_window_unsampled_cycles.py's scene (a grey floor, a 1 cm slab at
1 m, an emissive panel of radiance 10 facing the floor, Emission Sampling Auto; 16 x 16,
an orthographic camera under the slab), the panel SIZE m square at HEIGHT m (default:
0.5:1.5 2:1.5 4:1.5 8:1.5 2:3 2:6 sun:0 sun:45 world:0; sun:ANGLE a sun of strength 5
at ANGLE degrees from the zenith instead, world:0 a white world), and without the slab
for scale; Cycles 1024 spp
(seed 0), ours 16 spp, 20k + 20k photons. The ratios are ours / Cycles at each Filter
Glossy and Cycles' own 1 / 0; "ours now / Cycles 1" with engine/blurredpassage.py's
factor on the window passage (fgslab49, docs/compatibility.md "fgslab49"), "ours 1 /
Cycles 1" with it off (engine.blurredpassage.CYCLES_BLUR False: as before). Cycles' renders
are cached under $TMPDIR/passages48_cycles (delete to re-render).
"""
import math
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
    import test_window_unsampled_cycles as tw
    from engine import blurredpassage
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    tmp = tempfile.mkdtemp(prefix="passages48_")
    cache = os.path.join(tempfile.gettempdir(), "passages48_cycles")
    os.makedirs(cache, exist_ok=True)
    cases = sys.argv[1:] or ["0.5:1.5", "2:1.5", "4:1.5", "8:1.5", "2:3", "2:6", "sun:0",
                             "sun:45", "world:0"]

    def build(size, height, slab=True):
        """size, height: the panel's; size "sun": a sun of strength 5 at height degrees
        from the zenith instead; "world": a white world of strength 1."""
        bpy.ops.wm.read_homefile(use_empty=True)
        s = bpy.context.scene
        tw._scene(bpy, s, mode="AUTO")
        panel = next(o for o in s.objects if o.active_material is not None
                     and o.active_material.name == "Panel")
        if size == "sun":
            bpy.data.objects.remove(panel, do_unlink=True)
            sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
            sun.data.energy, sun.data.angle = 5.0, 0.0
            sun.rotation_euler = (math.radians(height), 0.0, 0.0)
            s.collection.objects.link(sun)
        elif size == "world":
            bpy.data.objects.remove(panel, do_unlink=True)
            bh.world_color(bpy, s, (1.0, 1.0, 1.0), 1.0)
        else:
            panel.scale = (size / 2.0, size / 2.0, 1.0)
            panel.location.z = height
        if not slab:
            bpy.data.objects.remove(bpy.data.objects["Cube"], do_unlink=True)
        s.cycles.pixel_filter_type, s.cycles.filter_width = "BOX", 1.0
        return s

    def mean(s, engine, name):
        s.render.engine = engine
        path = os.path.join(cache if engine == "CYCLES" else tmp, name)
        if not (engine == "CYCLES" and os.path.exists(path)):
            path = bh.render_exr(bpy, s, path)
        return float(bh.read_rgba(bpy, path)[..., :3].mean())

    print("size m | height m | Cycles bare | Cycles 0 | Cycles 1 | Cycles 1/0 | "
          "ours 0 / Cycles 0 | ours 1 / Cycles 1 | ours now / Cycles 1")
    for case in cases:
        size, height = case.split(":")
        size = size if size in ("sun", "world") else float(size)
        height = float(height)
        out = {}
        s = build(size, height, slab=False)
        bh.cycles_plain(s, 1024, 12)
        out["bare"] = mean(s, "CYCLES", f"{case}_bare.exr")
        for fg in (0.0, 1.0):
            s = build(size, height)
            bh.cycles_plain(s, 1024, 12).blur_glossy = fg
            out[f"C{fg:g}"] = mean(s, "CYCLES", f"{case}_c{fg:g}.exr")
            for on in ((False, True) if fg > 0 else (True,)):
                s = build(size, height)
                bh.cycles_plain(s, 1024, 12).blur_glossy = fg
                bh.cheap(s, spp=16, photons=20_000, caustic_photons=20_000)
                was = blurredpassage.CYCLES_BLUR
                blurredpassage.CYCLES_BLUR = on
                try:
                    key = f"O{fg:g}" + ("n" if on and fg > 0 else "")
                    out[key] = mean(s, "PHOTONMAP", f"o{fg}{on}.exr")
                finally:
                    blurredpassage.CYCLES_BLUR = was
        print(f"{size} | {height:g} | {out['bare']:.4f} | {out['C0']:.4f} | "
              f"{out['C1']:.4f} | {out['C1'] / out['C0']:.3f} | "
              f"{out['O0'] / out['C0']:.3f} | {out['O1'] / out['C1']:.3f} | "
              f"{out['O1n'] / out['C1']:.3f}", flush=True)


if __name__ == "__main__":
    main()
