"""tableroom45 (docs/accuracy.md "tableroom45"): working script, run from the worktree root with
PYTHONPATH=$PWD; reads and writes /tmp/tableroom45 (masks.npy from bench/newuser44_table.py
--masks, t_def.pkl from tableroom45_variant.py export)."""
import sys, os, pickle, argparse, time
ROOT = os.getcwd()
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "bench"))
import bpy
import newuser44_table as T
ap = argparse.ArgumentParser()
ap.add_argument("mode"); ap.add_argument("out")
ap.add_argument("--nospec", default="")  # comma list of material names, or 'all'
ap.add_argument("--nobottle", action="store_true")
ap.add_argument("--no-clamp", action="store_true")
ap.add_argument("--fg", type=float, default=None)
a = ap.parse_args()
import addon
addon.register()
scene = T.table_scene("sky")
r = scene.render
r.resolution_x, r.resolution_y = 160, 120
r.resolution_percentage = 100
c = scene.cycles
if a.no_clamp:
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
if a.fg is not None:
    c.blur_glossy = a.fg
names = a.nospec.split(",") if a.nospec else []
for m in bpy.data.materials:
    if m.node_tree and (m.name in names or ("all" in names and m.name != "BottleGlass")):
        for n in m.node_tree.nodes:
            if n.type == "BSDF_PRINCIPLED":
                n.inputs["Specular IOR Level"].default_value = 0.0
                print("nospec", m.name)
if a.nobottle:
    bpy.data.objects.remove(bpy.data.objects["WineBottle"])
if a.mode == "export":
    from addon import export as ex
    import engine
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(r)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h, render_visibility=True)
    kw = scene.photonmap.to_settings_kwargs(r.film_transparent)
    with open(a.out, "wb") as f:
        pickle.dump((pm_scene, kw), f)
    sys.exit(0)
r.engine = "CYCLES"
c.device, c.samples, c.seed = "CPU", int(a.mode.split(":")[1]), 0
c.use_denoising = c.use_adaptive_sampling = False
fmt = r.image_settings
fmt.media_type = "IMAGE"
fmt.file_format, fmt.color_depth = "OPEN_EXR", "32"
r.filepath, r.use_file_extension = os.path.abspath(a.out), False
t0 = T.cpu()
bpy.ops.render.render(write_still=True)
print("RESULT cpu", T.cpu() - t0)
