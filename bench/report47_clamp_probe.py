"""What Cycles' Indirect clamp cuts, the effect report's probe against Cycles
(effects.clamped_bounce_light; docs/accuracy.md, report47).

    PYTHONPATH=. .venv/bin/python bench/report47_clamp_probe.py room HEIGHT [--spp 256]
    PYTHONPATH=. .venv/bin/python bench/report47_clamp_probe.py blend FILE.blend [--seeds 1 2]

room: the test's room (a 6 m floor of Diffuse 0.8, a back wall, a 400 W 1 x 1 m area
light HEIGHT m over the floor facing down, a World of (0.2, 0.3, 0.4)), built with bpy;
prints the probe's shares (the engine scene exported by the add-on, Indirect 10) and
Cycles' Diffuse Indirect x Diffuse Color and Combined image means at Indirect 10 over
off (96 x 72, same seed, no denoise / adaptive / glossy blur). blend: the probe's
shares for a saved scene at its own Light Paths settings, the caustics' and the
seen-through-glass probes' (effects.clamped_caustics, clamped_through_glass), and its
clamping line.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in (ROOT, os.path.join(ROOT, "tests", "blender")):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402


def build_room(bpy, height):
    import mathutils
    from blender_helpers import world_color
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 96, 72
    scene.render.resolution_percentage = 100
    mat = bpy.data.materials.new("White")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nt = mat.node_tree
    for n in [n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"]:
        nt.nodes.remove(n)
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(d.outputs[0], next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
                 .inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=6)
    bpy.context.object.data.materials.append(mat)
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0, 2.0, 1.5),
                                     rotation=(math.radians(90), 0, 0))
    bpy.context.object.scale = (6, 3, 1)
    bpy.context.object.data.materials.append(mat)
    light = bpy.data.lights.new("Area", "AREA")
    light.energy, light.size = 400.0, 1.0
    lo = bpy.data.objects.new("Area", light)
    lo.location = (0, 0.5, height)
    scene.collection.objects.link(lo)
    world_color(bpy, scene, (0.2, 0.3, 0.4))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0, -5, 2.5)
    cam.rotation_euler = (mathutils.Vector((0, 0.5, 0.5)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    cam.data.angle = math.radians(50)
    scene.cycles.sample_clamp_indirect = 10.0
    return scene


def probe(bpy, seeds):
    from addon import export
    from addon.core import load_engine
    pm = load_engine()
    scene = bpy.context.scene
    pm_scene, _ = export.export_scene(pm, bpy.context.evaluated_depsgraph_get())
    kw = scene.photonmap.to_settings_kwargs(scene.render.film_transparent)
    kw.update(workers=1)
    settings = pm.RenderSettings(**kw)
    from engine.effects import clamped_bounce_light
    from engine.render import prepare_context
    ctx = prepare_context(pm_scene, settings)
    for seed in seeds:
        got = clamped_bounce_light(ctx.scene, ctx.geo, ctx.table, ctx.lights, ctx.accel,
                                   3.0 * settings.clamp_indirect, np.random.default_rng(seed))
        print(f"probe (seed {seed}, Indirect {settings.clamp_indirect:g}): "
              + (", ".join(f"{k} {100 * v:.2f} %" for k, v in got.items()) or "none"))
    # (the caustics' and the seen-through-glass probes, clampnote51: the plan's own seed)
    for what, got in (("caustics", ctx.plan.clamped_caustics),
                      ("through glass", ctx.plan.clamped_glass)):
        print(f"{what} probe: " + (", ".join(f"{k} {100 * v:.2f} %" for k, v in got.items())
                                   or "none"))
    line = next((r for r in ctx.plan.report() if r.startswith("clamping")), "")
    print("report:", line)
    ctx.accel.close()


def cycles(bpy, scene, spp):
    from blender_helpers import cycles_plain, read_layers, render_exr
    vl = scene.view_layers[0]
    vl.use_pass_diffuse_indirect = vl.use_pass_diffuse_color = True
    tmp = tempfile.mkdtemp()
    out = {}
    for clamp in (10.0, 0.0):
        c = cycles_plain(scene, spp, 12)
        c.sample_clamp_indirect = clamp
        scene.render.engine = "CYCLES"
        layers = read_layers(render_exr(bpy, scene, os.path.join(tmp, f"c{clamp}.exr"),
                                        multilayer=True))
        out[clamp] = ((layers["Diffuse Indirect"][..., :3]
                       * layers["Diffuse Color"][..., :3]).mean(),
                      layers["Combined"][..., :3].mean())
    print(f"Cycles {spp} spp, Indirect 10 / off: Diffuse Indirect "
          f"{out[10.0][0] / out[0.0][0]:.4f}, Combined {out[10.0][1] / out[0.0][1]:.4f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("kind", choices=("room", "blend"))
    ap.add_argument("what", help="the area light's height (room) or a .blend (blend)")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    a = ap.parse_args()
    import bpy
    import addon
    addon.register()
    if a.kind == "room":
        scene = build_room(bpy, float(a.what))
        probe(bpy, a.seeds)
        cycles(bpy, scene, a.spp)
    else:
        bpy.ops.wm.open_mainfile(filepath=a.what)
        probe(bpy, a.seeds)


if __name__ == "__main__":
    main()
