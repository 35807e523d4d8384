"""Small exterior scenes at equal error against Cycles (exterior42; issues 13 / 14).

Three scenes built with bpy as a user builds them (`build`), saved as .blend files and
measured by bench/bench_interior.py's equal-time machinery (Cycles' ladder and ours at the
add-on's defaults, CPU seconds, relMSE / HDR-FLIP against a Cycles reference, the seeds'
variance by effect pass, stage seconds):

- sun_sky: a 4 x 4 x 3 m Principled cube house with a pyramid roof, a sphere and a
  cylinder on a 40 m ground plane, a Sun (4 W/m^2, 0.5 degrees) and a Nishita Sky Texture
  world (sun disc off: the Sun lamp is the sun) at strength 0.3;
- world: the same objects under a plain world colour (0.5, 0.65, 0.9), no lamps;
- product: a Principled sphere and a torus on a 50 m plane, a 1 x 1 m area light (150 W)
  and a world colour of strength 0.3.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_exterior.py [--out /tmp/exterior42] \\
        [--scenes sun_sky,world,product] -- [bench_interior.py arguments]

Without arguments after `--` it only saves the blends; e.g. `-- --width 160 --spp 8,16,32
--cycles 16,32,64,128 --ref-spp 2048 --seeds 0 --ref-dir /tmp/exterior42/refs` measures.
"""
from __future__ import annotations

import argparse
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
# Cycles' add-on (registered when bpy is imported) reads the arguments after "--" as its
# own: keep them from it.
ARGV, sys.argv = sys.argv[1:], sys.argv[:1]

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

from bench_product_shot import _principled  # noqa: E402
from newuser24_scenes import camera as _camera, world_colour  # noqa: E402
from tools.canonical_mesh import primitive_uv_sphere_add  # noqa: E402

SCENES = ("sun_sky", "world", "product")


def _active(name, mat):
    o = bpy.context.active_object
    o.name = name
    o.data.materials.append(mat)
    return o


def _yard(ground_size):
    bpy.ops.mesh.primitive_plane_add(size=ground_size)
    _active("Ground", _principled("Ground", (0.35, 0.33, 0.25), 0.8))
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 1.5))
    house = _active("House", _principled("Walls", (0.75, 0.7, 0.6), 0.6))
    house.scale = (4, 4, 3)
    bpy.ops.mesh.primitive_cone_add(vertices=4, radius1=3.1, depth=1.6,
                                    location=(0, 0, 3.8), rotation=(0, 0, math.pi / 4))
    _active("Roof", _principled("Roof", (0.45, 0.12, 0.08), 0.5))
    primitive_uv_sphere_add(radius=1.0, location=(4.5, -3.0, 1.0))
    bpy.ops.object.shade_smooth()
    _active("Sphere", _principled("Ball", (0.1, 0.3, 0.7), 0.3))
    bpy.ops.mesh.primitive_cylinder_add(radius=0.6, depth=2.0, location=(-4.0, -3.5, 1.0))
    _active("Cylinder", _principled("Post", (0.8, 0.8, 0.8), 0.4))
    _camera((13, -15, 5), (0, 0, 1.5), 35)


def build(kind: str, path: str, width: int = 160, height: int = 120):
    """Save scene `kind` (one of SCENES) to `path` (.blend) at width x height."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    if kind in ("sun_sky", "world"):
        _yard(40)
    if kind == "sun_sky":
        elevation, rotation = math.radians(35), math.radians(40)
        bpy.ops.object.light_add(type="SUN")
        sun = bpy.context.active_object
        sun.data.energy, sun.data.angle = 4.0, math.radians(0.5)
        # The lamp shines along -Z: from the sky's sun position towards the ground.
        to_sun = Vector((math.cos(elevation) * math.sin(rotation),
                         -math.cos(elevation) * math.cos(rotation), math.sin(elevation)))
        sun.rotation_euler = (-to_sun).to_track_quat("-Z", "Y").to_euler()
        world_colour(scene, (1, 1, 1), 0.3)
        nt = scene.world.node_tree
        sky = nt.nodes.new("ShaderNodeTexSky")
        names = [i.identifier for i in sky.bl_rna.properties["sky_type"].enum_items]
        sky.sky_type = "NISHITA" if "NISHITA" in names else sky.sky_type
        sky.sun_disc = False
        sky.sun_elevation, sky.sun_rotation = elevation, rotation
        nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    elif kind == "world":
        world_colour(scene, (0.5, 0.65, 0.9), 1.0)
    elif kind == "product":
        bpy.ops.mesh.primitive_plane_add(size=50)
        _active("Floor", _principled("Floor", (0.7, 0.7, 0.7), 0.6))
        primitive_uv_sphere_add(radius=0.5, location=(-0.4, 0, 0.5))
        bpy.ops.object.shade_smooth()
        _active("Ball", _principled("Ball", (0.8, 0.25, 0.1), 0.35))
        bpy.ops.mesh.primitive_torus_add(major_radius=0.4, minor_radius=0.15,
                                         location=(0.7, 0.3, 0.15))
        bpy.ops.object.shade_smooth()
        _active("Torus", _principled("Torus", (0.2, 0.6, 0.3), 0.5))
        bpy.ops.object.light_add(type="AREA", location=(-2.0, -2.0, 3.0))
        key = bpy.context.active_object
        key.data.energy, key.data.size = 150.0, 1.0
        key.rotation_euler = (Vector((0, 0, 0.3)) - key.location).to_track_quat(
            "-Z", "Y").to_euler()
        world_colour(scene, (0.8, 0.85, 1.0), 0.3)
        _camera((0.5, -4.5, 1.6), (0.1, 0, 0.35), 50)
    else:
        raise ValueError(f"unknown scene {kind!r}; one of {SCENES}")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path


def main(argv=None):
    argv = ARGV if argv is None else argv
    rest = []
    if "--" in argv:
        i = argv.index("--")
        argv, rest = argv[:i], argv[i + 1:]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/exterior42")
    ap.add_argument("--scenes", default=",".join(SCENES))
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    paths = [build(k, os.path.join(a.out, k + ".blend")) for k in a.scenes.split(",")]
    if rest:
        import bench_interior
        bench_interior.main(paths + rest)


if __name__ == "__main__":
    main()
