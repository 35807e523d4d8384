"""A night living room lit by a floor lamp in a shade, ours against Cycles (issue 14, lamp30):
equal-time table (CPU seconds, relMSE, mean HDR-FLIP, brightness; per object ours / the
reference) for ours at default settings and two other sample counts against Cycles at
16 .. 1024 spp, all against a Cycles reference (4096 spp, seed 0). Built with bpy as a user
would: a 5 x 4 x 2.6 m room, Principled walls and floor, a sofa (Principled, Sheen Weight 1),
a black glossy TV (roughness 0.2) with an emissive screen, a 100 W point lamp (radius
0.05 m) inside an open cylinder shade: `--shade translucent` (a Translucent BSDF) or
`glass` (Principled, Transmission 1, roughness 0.5, single-sided). Cycles' default Light
Paths (12 / 4 diffuse / 4 glossy / 12 transmission) in both (the add-on reads them),
no clamping, Filter Glossy 0, no denoising or adaptive sampling.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_lamp_room.py [--shade translucent]
        [--ref REF.exr] [--save-ref REF.exr] [--ref-spp 4096] [--ours 32,default,512]
        [--cycles 16,64,256,1024] [--width 160 --height 120] [--shadelight off]

--ref reuses a reference EXR (a render by this script's --save-ref); without it the
reference is rendered first (4096 spp at 160 x 120: ~450 CPU s). CPU seconds are the
process's (all threads) over the render call alone. Cycles' low-spp renders use seed 1.
Measured (docs/accuracy.md, lamp30): translucent shade, ours 128 spp (default) relMSE
0.0144, FLIP 0.092 in 41 CPU s; Cycles 1024 spp relMSE 0.035, FLIP 0.108 in 118 CPU s.
shade32 (the lamp through the shade by next-event estimation, engine/shadelight.py;
docs/accuracy.md "## shade32", another reference): ours default relMSE 0.0133 -> 0.0120,
FLIP 0.089 -> 0.072 in 33 CPU s; Cycles 1024 spp 0.035, 0.108 in 95 CPU s.
--shadelight off: the lamp's light through the shade by caustic photons alone, as before
shade32 / roughshade33 (engine.shadelight.ENABLED; the A/B of docs/accuracy.md
"## roughshade33", whose glass shade the estimator serves since). roughshade33, --shade
glass against a Cycles 1024-spp reference (whose own noise dominates relMSE and FLIP):
walls 0.980 -> 0.984, floor 0.984 -> 0.977, CPU 36 -> 55 s at the default 128 spp; the
walls' Caustic pass 0.319 -> 0.032, Direct 0.078 -> 0.366. glossshade34 (the glossy lobes
take the shade samples, MIS with their reflected rays), --shade glass, same reference:
59.7 -> 62.7 CPU s, relMSE 1.159 -> 0.855, sofa 0.934 -> 0.973, TV body 0.789 -> 0.974
(docs/accuracy.md "## glossshade34").
"""
import argparse
import math
import os
import resource
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
sys.path.insert(0, os.path.join(ROOT, "tools"))

# pass_index of each object
OBJ = {1: "floor", 2: "walls", 3: "sofa", 4: "tv body", 5: "tv screen", 6: "shade", 7: "stem"}


def principled(bpy, name, base, rough=0.5, **inputs):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*base, 1.0)
    p.inputs["Roughness"].default_value = rough
    for k, v in inputs.items():
        p.inputs[k.replace("_", " ")].default_value = v
    return m, p


def cube(bpy, name, loc, dims, mat, index):
    bpy.ops.mesh.primitive_cube_add(size=1, location=loc)
    o = bpy.context.active_object
    o.name, o.scale, o.pass_index = name, dims, index
    o.data.materials.append(mat)
    return o


def build(bpy, shade="translucent", res=(160, 120)):
    """The room (module docstring) as a new scene; returns it."""
    from mathutils import Vector
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    vl = scene.view_layers[0]
    vl.use_pass_object_index = True
    world = bpy.data.worlds.new("Night")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0

    wall, _ = principled(bpy, "Wall", (0.8, 0.78, 0.72), 0.8)
    floor, _ = principled(bpy, "Floor", (0.35, 0.22, 0.12), 0.5)
    sofa, _ = principled(bpy, "SofaFabric", (0.12, 0.1, 0.22), 0.8, Sheen_Weight=1.0,
                         Sheen_Tint=(1.0, 1.0, 1.0, 1.0))
    black, _ = principled(bpy, "TVBody", (0.0, 0.0, 0.0), 0.2)
    screen = bpy.data.materials.new("Screen")
    if bpy.app.version < (5, 0, 0):
        screen.use_nodes = True
    nt = screen.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (0.5, 0.65, 1.0, 1.0)
    em.inputs["Strength"].default_value = 2.0
    nt.links.new(em.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    if shade == "translucent":
        sm = bpy.data.materials.new("Shade")
        if bpy.app.version < (5, 0, 0):
            sm.use_nodes = True
        nt = sm.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        tr = nt.nodes.new("ShaderNodeBsdfTranslucent")
        tr.inputs["Color"].default_value = (0.95, 0.85, 0.7, 1.0)
        nt.links.new(tr.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    else:
        sm, _ = principled(bpy, "Shade", (0.95, 0.85, 0.7), 0.5, Transmission_Weight=1.0)

    # Room 5 x 4 x 2.6 m, closed: a cube seen from inside.
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0, 0, 0))
    f = bpy.context.active_object
    f.name, f.scale, f.pass_index = "Floor", (5, 4, 1), 1
    f.data.materials.append(floor)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 1.3))
    room = bpy.context.active_object
    room.name, room.scale, room.pass_index = "Room", (5.0, 4.0, 2.6), 2
    room.data.materials.append(wall)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    # the floor face of the room box sits under the floor plane; push it 1 mm lower
    me = room.data
    for v in me.vertices:
        if v.co.z < 0:
            v.co.z -= 0.001

    # Sofa against the back wall (y = +2), two boxes.
    cube(bpy, "SofaSeat", (-0.8, 1.5, 0.25), (2.0, 0.9, 0.5), sofa, 3)
    cube(bpy, "SofaBack", (-0.8, 1.85, 0.6), (2.0, 0.25, 0.9), sofa, 3)
    # TV on the right wall (x = +2.5), screen facing -x.
    cube(bpy, "TVBody", (2.44, 0.0, 1.1), (0.1, 1.6, 0.95), black, 4)
    bpy.ops.mesh.primitive_plane_add(size=1, location=(2.385, 0.0, 1.1),
                                     rotation=(0, -math.pi / 2, 0))
    tv = bpy.context.active_object
    tv.name, tv.scale, tv.pass_index = "TVScreen", (0.62, 1.3, 1), 5
    tv.data.materials.append(screen)

    # Floor lamp in the back-right corner: stem, open cylinder shade, point light inside.
    lamp_at = (1.5, 1.4, 1.5)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.015, depth=1.3, location=(1.5, 1.4, 0.65))
    st = bpy.context.active_object
    st.name, st.pass_index = "LampStem", 7
    st.data.materials.append(black)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.22, depth=0.35, location=lamp_at,
                                        vertices=32, end_fill_type="NOTHING")
    sh = bpy.context.active_object
    sh.name, sh.pass_index = "LampShade", 6
    sh.data.materials.append(sm)
    bpy.ops.object.shade_smooth()
    bpy.ops.object.light_add(type="POINT", location=lamp_at)
    lamp = bpy.context.active_object
    lamp.name = "FloorLamp"
    lamp.data.energy, lamp.data.shadow_soft_size = 100.0, 0.05
    lamp.data.color = (1.0, 0.9, 0.75)

    bpy.ops.object.camera_add(location=(-2.0, -1.7, 1.55))
    cam = bpy.context.active_object
    cam.data.lens = 18
    cam.rotation_euler = (Vector((1.2, 1.0, 0.85)) - Vector(cam.location)).to_track_quat(
        "-Z", "Y").to_euler()
    scene.camera = cam

    # Light Paths: Cycles' defaults, written out (the add-on reads them), no clamping, no
    # glossy filter, denoising / adaptive off (Cycles reference settings, docs/units.md).
    c = scene.cycles
    c.device, c.seed = "CPU", 0
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces = 12, 4, 4
    c.transmission_bounces, c.transparent_max_bounces = 12, 8
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    return scene


def set_output(scene, path):
    s = scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "MULTI_LAYER_IMAGE"
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "32"
    scene.render.filepath = str(path)
    scene.render.use_file_extension = False


def render(bpy, scene, path):
    """Render scene to the multilayer EXR path; (passes dict, CPU seconds of the call)."""
    from blender_helpers import read_layers
    set_output(scene, path)
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    bpy.ops.render.render(write_still=True)
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
    return read_layers(path), cpu


def run(bpy, shade, size, engine, spp, seed, path):
    scene = build(bpy, shade, size)
    scene.render.engine = engine
    if engine == "CYCLES":
        scene.cycles.samples, scene.cycles.seed = spp, seed
    else:
        from blender_helpers import default_photonmap
        pm = default_photonmap(scene)
        if spp:
            pm.spp = spp
    return render(bpy, scene, path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--shade", default="translucent", choices=("translucent", "glass"))
    ap.add_argument("--ref")
    ap.add_argument("--save-ref")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--ours", default="32,default,512")
    ap.add_argument("--cycles", default="16,64,256,1024")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--shadelight", default="on", choices=("on", "off"))
    a = ap.parse_args()
    from engine import shadelight
    shadelight.ENABLED = a.shadelight == "on"
    import bpy
    import addon
    from accuracy_scenes import flip, relmse
    from blender_helpers import read_layers
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    size = (a.width, a.height)
    tmp = tempfile.mkdtemp(prefix="lamp_room_")
    if a.ref:
        ref_l = read_layers(a.ref)
    else:
        ref_l, cpu = run(bpy, a.shade, size, "CYCLES", a.ref_spp, 0,
                         a.save_ref or os.path.join(tmp, "ref.exr"))
        print(f"reference: Cycles {a.ref_spp} spp, {cpu:.1f} CPU s")
    ref = ref_l["Combined"][..., :3]
    index = ref_l["Object Index"][..., 0]
    inner = index.copy()  # pixels whose 4 neighbours are the same object
    for ax in (0, 1):
        for s in (1, -1):
            inner = np.where(np.roll(index, s, axis=ax) == index, inner, -1)
    names = [n for k, n in OBJ.items() if (inner == k).sum() >= 4]
    rows = [("ours", s) for s in a.ours.split(",") if s] + [
        ("Cycles", s) for s in a.cycles.split(",") if s]
    print(f"shade: {a.shade}, {a.width} x {a.height}, shadelight {a.shadelight}; per object: "
          "ours / reference mean")
    print("| run | CPU s | relMSE | HDR-FLIP | brightness | " + " | ".join(names) + " |")
    print("|---" * (5 + len(names)) + "|")
    for who, s in rows:
        spp = 0 if s == "default" else int(s)
        layers, cpu = run(bpy, a.shade, size, "PHOTONMAP" if who == "ours" else "CYCLES",
                          spp, 1, os.path.join(tmp, f"{who}_{s}.exr"))
        x = layers["Combined"][..., :3]
        per = []
        for k, n in OBJ.items():
            if n in names:
                m = inner == k
                per.append("%.3f" % (x[m].mean() / ref[m].mean()))
        default = bpy.context.scene.photonmap.bl_rna.properties["spp"].default
        label = f"{who} {f'default ({default} spp)' if s == 'default' else s + ' spp'}"
        print(f"| {label} | {cpu:.1f} | {relmse(x, ref):.4f} | {flip(x, ref):.4f} | "
              f"{x.mean() / ref.mean():.3f} | " + " | ".join(per) + " |", flush=True)


if __name__ == "__main__":
    main()
