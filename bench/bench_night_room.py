"""Night rooms lit by lamps alone (issues 13 / 14, night42): saves two .blend files for
bench/bench_interior.py (ours against Cycles at equal CPU time, the seeds' variance by
pass and region) and prints the commands that measured docs/accuracy.md "## night42".

    PYTHONPATH=$PWD .venv/bin/python bench/bench_night_room.py [--out /tmp/night42/scenes]

- lamp_room.blend: bench/bench_lamp_room.py's living room (Translucent shade), as built
  there, at 160 x 120;
- night_room.blend: a simpler room as a user would build it: 4 x 3 x 2.6 m, Principled
  walls (0.75, roughness 0.7), floor, a sofa against the back wall with a 40 W point lamp
  behind it (the wall above lit, the room only indirectly), a desk with a small 15 W area
  lamp facing the left wall, a 60 W spot in the ceiling pointing down (60 degrees); the
  world black; Cycles' default Light Paths, no clamping, Filter Glossy 0, no denoising or
  adaptive sampling; 160 x 120.

Then, e.g. (the variant "off": the cosine gather, as before night42):

    PYTHONPATH=$PWD .venv/bin/python bench/bench_interior.py OUT/night_room.blend \\
        --width 80 --spp 16,64 --seeds 0,1 --cycles 16,64,256,1024 --ref-spp 2048 \\
        --ref-dir /tmp/night42/refs --window none --variant "off:gather_guiding=False"
"""
import argparse
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, HERE)


def build_night_room(bpy, res=(160, 120)):
    """The simpler night room (module docstring) as a new scene; returns it."""
    import bench_lamp_room as L
    from mathutils import Vector
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = res
    sc.render.resolution_percentage = 100
    world = bpy.data.worlds.new("Night")
    sc.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    wall, _ = L.principled(bpy, "Wall", (0.75, 0.75, 0.72), 0.7)
    floor, _ = L.principled(bpy, "Floor", (0.4, 0.3, 0.2), 0.6)
    sofa, _ = L.principled(bpy, "Sofa", (0.3, 0.15, 0.1), 0.9)
    desk, _ = L.principled(bpy, "Desk", (0.5, 0.45, 0.4), 0.5)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 1.3))
    room = bpy.context.active_object
    room.name, room.scale = "Room", (4.0, 3.0, 2.6)
    room.data.materials.append(wall)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0, 0, 0.001))
    f = bpy.context.active_object
    f.name, f.scale = "Floor", (4, 3, 1)
    f.data.materials.append(floor)
    # sofa against the back wall (y = +1.5), a lamp behind it
    # The seat ends 1 cm inside the back (y 0.54 .. 1.34): with both at y = 1.35 their
    # back faces coincided, facing the lamp, and Cycles' shadow rays from one met the
    # other (night43: the lamp's light in the room 2 % darker in Cycles for that alone).
    L.cube(bpy, "SofaSeat", (-0.6, 0.94, 0.22), (1.8, 0.8, 0.44), sofa, 3)
    L.cube(bpy, "SofaBack", (-0.6, 1.25, 0.5), (1.8, 0.2, 1.0), sofa, 3)
    bpy.ops.object.light_add(type="POINT", location=(-0.6, 1.42, 0.3))
    o = bpy.context.active_object
    o.data.energy, o.data.shadow_soft_size, o.data.color = 40.0, 0.05, (1.0, 0.8, 0.6)
    # a desk by the left wall (x = -2), a small area lamp on it facing the wall
    L.cube(bpy, "Desk", (-1.7, -0.6, 0.72), (0.6, 1.2, 0.04), desk, 4)
    bpy.ops.object.light_add(type="AREA", location=(-1.75, -0.6, 0.95),
                             rotation=(0, math.pi / 2, 0))
    o = bpy.context.active_object
    o.data.energy, o.data.size, o.data.color = 15.0, 0.15, (1.0, 0.9, 0.8)
    # a downlight in the ceiling: a spot pointing down
    bpy.ops.object.light_add(type="SPOT", location=(0.8, -0.3, 2.55))
    o = bpy.context.active_object
    o.data.energy, o.data.shadow_soft_size = 60.0, 0.05
    o.data.spot_size, o.data.spot_blend = math.radians(60), 0.3
    bpy.ops.object.camera_add(location=(1.7, -1.3, 1.5))
    cam = bpy.context.active_object
    cam.data.lens = 16
    cam.rotation_euler = (Vector((-1.0, 0.8, 1.1)) - Vector(cam.location)).to_track_quat(
        "-Z", "Y").to_euler()
    sc.camera = cam
    c = sc.cycles
    c.device, c.seed = "CPU", 0
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces = 12, 4, 4
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    return sc


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="/tmp/night42/scenes")
    a = ap.parse_args()
    import bpy
    import bench_lamp_room as L
    os.makedirs(a.out, exist_ok=True)
    L.build(bpy, "translucent", (160, 120))
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(a.out, "lamp_room.blend"))
    build_night_room(bpy)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(a.out, "night_room.blend"))
    print(f"saved {a.out}/lamp_room.blend and night_room.blend")


if __name__ == "__main__":
    main()
