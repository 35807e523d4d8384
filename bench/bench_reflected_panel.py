"""A white panel lit only by a rough floor's reflection of a shielded point lamp: ours /
Cycles, for a metal floor (Principled Metallic 1) and a dielectric one (Principled, white
base), roughness 0.5 and 1, Multiscatter GGX and plain GGX (issue 14: does a photon take
the reflective lobes' energy compensation at the right side, as photonkernels.glass_adjoint
makes rough glass do?).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_reflected_panel.py [metal|dielectric ...]

48x36; ours at default settings and 16 spp, Cycles 1024 spp; the same Light Paths (12 / 4
diffuse / 4 glossy / 12 transmission). Prints a Markdown table of the image means.
Measured 2026-12-04 on 5af50e4 (docs: closing note s30): metal 0.992 / 1.037 / 1.010,
dielectric 0.984 / 0.984 / 0.965 (roughness 0.5 Multiscatter, 1 Multiscatter, 1 GGX).
"""
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for sub in ("tests/blender", "tests", ""):
    sys.path.insert(0, os.path.join(ROOT, sub))
import bpy
from mathutils import Vector
import addon
addon.register()
from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr, node_material

def mat(name, build):
    m, nt, out = node_material(bpy, name)
    nt.links.new(build(nt.nodes), out.inputs["Surface"])
    return m

def scene_for(rough, dist, kind):
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "PHOTONMAP"
    sc.render.resolution_x, sc.render.resolution_y = 48, 36
    sc.render.resolution_percentage = 100
    w = bpy.data.worlds.new("W"); sc.world = w
    bg = next(n for n in w.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = 0.0
    def metal(nodes):
        n = nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (0.9, 0.9, 0.9, 1)
        n.inputs["Roughness"].default_value = rough
        if kind == "metal":
            n.inputs["Metallic"].default_value = 1.0
        n.distribution = dist
        return n.outputs[0]
    def diffuse(nodes, c=0.8):
        n = nodes.new("ShaderNodeBsdfDiffuse")
        n.inputs["Color"].default_value = (c, c, c, 1)
        return n.outputs[0]
    bpy.ops.mesh.primitive_plane_add(size=4, location=(0, 0, 0))
    bpy.context.active_object.data.materials.append(mat("Floor", metal))
    bpy.ops.mesh.primitive_plane_add(size=1, location=(1.5, 0, 1.25), rotation=(0, -math.pi / 2, 0))
    p = bpy.context.active_object; p.scale = (1.5, 3, 1)
    p.data.materials.append(mat("Panel", diffuse))
    bpy.ops.mesh.primitive_plane_add(size=0.8, location=(-1.0, 0, 0.35))
    bpy.context.active_object.data.materials.append(mat("Shield", lambda nd: diffuse(nd, 0.0)))
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.data.energy, lamp.data.shadow_soft_size = 100.0, 0.02
    lamp.location = (-1.0, 0, 0.3)
    sc.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (-0.5, 0, 1.3); cam.data.lens = 30
    cam.rotation_euler = (Vector((1.5, 0, 1.3)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    sc.collection.objects.link(cam); sc.camera = cam
    return sc

def mean(sc, engine, path):
    c = cycles_plain(sc, 1024, 12)
    c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 4, 4, 12
    sc.render.engine = engine
    if engine == "PHOTONMAP":
        default_photonmap(sc).spp = 16
    return float(read_rgba(bpy, render_exr(bpy, sc, path))[..., :3].mean())

def main():
    import tempfile
    kinds = sys.argv[1:] or ["metal", "dielectric"]
    print("| floor | roughness | distribution | ours | Cycles | ours / Cycles |")
    print("|---|---:|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in kinds:
            for rough, dist in ((0.5, "MULTI_GGX"), (1.0, "MULTI_GGX"), (1.0, "GGX")):
                r = {}
                for eng in ("PHOTONMAP", "CYCLES"):
                    sc = scene_for(rough, dist, kind)
                    r[eng] = mean(sc, eng, os.path.join(tmp, f"{kind}_{eng}_{rough}_{dist}.exr"))
                print(f"| {kind} | {rough} | {dist} | {r['PHOTONMAP']:.5f} | {r['CYCLES']:.5f} "
                      f"| {r['PHOTONMAP'] / r['CYCLES']:.4f} |", flush=True)


if __name__ == "__main__":
    main()
