"""cleanuser47's scene (session 47 clean-clone trial): a drinking glass (a lathed shell,
Glass BSDF at the node's defaults, Shade Smooth) and a glossy teapot (UV sphere + cylinder
spout and lid, Principled roughness 0.15) on a Glossy BSDF tray on a wooden table by a
glazed window (a single-plane Glass pane, a Sun through it), an Area light, a World colour;
Blender's defaults (Filter Glossy 1, clamping Indirect 10).

    PYTHONPATH=. .venv/bin/python bench/cleanuser47_table.py MODE OUT.exr [--res W H]
        [--masks MASKS.npy] [--no-clamp] [--no-split] [--flat-glass]

MODE: ours | cycles:SPP (bench/newuser44_table.py render()); --no-split sets
engine/glossysplit.py ENABLED = False; --flat-glass leaves the glass Shade Flat. Compare
with bench/newuser26_compare.py and bench/newuser45_artefacts.py (docs/accuracy.md,
"cleanuser47")."""
import math
import os
import sys

WT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, WT); sys.path.insert(0, WT + "/bench")
import bpy
from mathutils import Vector
from newuser26_scenes import assign, camera, cube, cylinder, empty_scene, new_material, principled, world_colour
from newuser44_table import arguments, lathe, render
from tools.canonical_mesh import primitive_uv_sphere_add


def glass_default(name):
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    g = nt.nodes.new("ShaderNodeBsdfGlass")  # the node's defaults
    nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def glossy_default(name, color=(0.8, 0.8, 0.8)):
    m = new_material(name)
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    g = nt.nodes.new("ShaderNodeBsdfAnisotropic")  # Glossy BSDF, defaults
    g.inputs["Color"].default_value = (*color, 1)
    nt.links.new(g.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return m


def build():
    scene = empty_scene()
    wall = principled("Wall", (0.7, 0.7, 0.68), 0.5)
    floor = principled("Floor", (0.5, 0.5, 0.5), 0.5)
    wood = principled("Wood", (0.4, 0.2, 0.08), 0.5)
    teapot = principled("TeapotGlaze", (0.1, 0.3, 0.6), 0.15)
    pane = glass_default("WindowGlass")
    cup = glass_default("CupGlass")
    tray = glossy_default("TrayMetal", (0.8, 0.7, 0.5))
    cube("Floor", (0, 0, -0.05), (4, 4, 0.1), floor)
    cube("Ceiling", (0, 0, 2.65), (4, 4, 0.1), wall)
    cube("BackWall", (0, 2.05, 1.3), (4.2, 0.1, 2.6), wall)
    cube("LeftWall", (-2.05, 0, 1.3), (0.1, 4.2, 2.6), wall)
    cube("RightWall_a", (2.05, -1.1, 1.3), (0.1, 1.8, 2.6), wall)
    cube("RightWall_b", (2.05, 1.6, 1.3), (0.1, 0.8, 2.6), wall)
    cube("RightWall_c", (2.05, 0.5, 0.45), (0.1, 1.4, 0.9), wall)
    cube("RightWall_d", (2.05, 0.5, 2.25), (0.1, 1.4, 0.7), wall)
    bpy.ops.mesh.primitive_plane_add(size=1, location=(2.05, 0.5, 1.4),
                                     rotation=(0, math.radians(90), 0), scale=(1.0, 1.4, 1))
    w = bpy.context.active_object; w.name = "WindowPane"; assign(w, pane)
    cube("TableTop", (1.0, 0.6, 0.75), (1.2, 0.8, 0.04), wood)
    for i, (x, y) in enumerate([(0.5, 0.3), (1.5, 0.3), (0.5, 0.9), (1.5, 0.9)]):
        cube(f"TableLeg{i}", (x, y, 0.365), (0.05, 0.05, 0.73), wood)
    # Drinking glass: outer wall up, inner wall down (3 mm wall, 5 mm base).
    prof = [(0.03, 0.0), (0.04, 0.11), (0.037, 0.11), (0.027, 0.005)]
    g = lathe("DrinkingGlass", prof, cup, (0.75, 0.45, 0.77))
    if "--flat-glass" in sys.argv:
        for p in g.data.polygons:
            p.use_smooth = False
    # Teapot: a UV sphere body, cylinder spout and lid knob, smooth.
    primitive_uv_sphere_add(radius=0.09, location=(1.15, 0.65, 0.86), scale=(1, 1, 0.8))
    t = bpy.context.active_object; t.name = "Teapot"; bpy.ops.object.shade_smooth(); assign(t, teapot)
    bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.015, depth=0.12, location=(1.04, 0.65, 0.9),
                                        rotation=(0, math.radians(-50), 0))
    s = bpy.context.active_object; s.name = "TeapotSpout"; bpy.ops.object.shade_smooth(); assign(s, teapot)
    cylinder("TeapotLid", 0.02, 0.03, (1.15, 0.65, 0.94), teapot, vertices=24)
    cylinder("Tray", 0.16, 0.01, (1.15, 0.65, 0.775), tray, vertices=48)
    bpy.ops.object.light_add(type="SUN", location=(4, 0, 4))
    sun = bpy.context.active_object; sun.name = "Sun"; sun.data.energy = 2.0
    sun.rotation_euler = Vector((-1.0, 0.05, -0.6)).to_track_quat("-Z", "Y").to_euler()
    bpy.ops.object.light_add(type="AREA", location=(-0.5, 0.0, 2.55))
    area = bpy.context.active_object; area.name = "CeilingArea"; area.data.energy = 40.0; area.data.size = 0.5
    world_colour(scene, (0.4, 0.5, 0.7), 1.0)
    camera((-0.3, -0.7, 1.3), (1.1, 0.6, 0.85), lens=32.0)
    return scene


def main():
    ap = arguments()
    ap.add_argument("--no-split", action="store_true")
    ap.add_argument("--flat-glass", action="store_true")
    a = ap.parse_args()
    import addon
    addon.register()
    if a.no_split:
        from engine import glossysplit
        glossysplit.ENABLED = False
    import addon.engine as ae
    def listen(ev, val):
        if ev == "stats" and str(val).startswith("Done"):
            print("STATS LINE:", val, flush=True)
        elif ev == "effects":
            for line in val:
                print("Photon Mapping:", line, flush=True)
    ae.status_listeners.append(listen)
    sc = build()
    print("Filter Glossy", sc.cycles.blur_glossy)
    render(sc, a)


if __name__ == "__main__":
    main()
