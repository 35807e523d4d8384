"""bump50 (issue 14): a bumped plane under a sun, direct light only, ours against Cycles -
the minimal case of roomglossy49's "ours' Bump darkens the room" (docs/accuracy.md,
"### bump50").

    PYTHONPATH=. .venv/bin/python bench/bump50_plane.py MODE OUT.exr
        [--height brick|noise|wave] [--no-bump] [--bsdf diffuse|principled:ROUGH]
        [--sun DEG] [--ortho SCALE | --lens MM] [--filter-width FW] [--res W H]

The plane: 2 x 2 m (a grid of 4 x 4 quads, its UV map 0..1) at z = 0 seen from 3 m
above (orthographic, 2 m wide: --ortho; or perspective: --lens), lit by a Sun of strength
3 tilted --sun degrees from the normal (towards -x), World black, Light Paths Max
Bounces 0 in both (direct light only). The height into a Bump node (Strength 1,
Distance 1, Invert on: bathroom49's tiles) is
  brick  bathroom49's tiles' Brick Texture Fac (square 0.25 bricks, Scale 16 on the UV
         map: 16 tiles of 12.5 cm a side, 1 cm grout with its default Mortar Smooth 0.1:
         a 1 mm ramp of height 1 - far steeper than any step can resolve);
  noise  a Noise Texture Fac (Scale 8 on the UV map), Distance 0.02 (smooth);
  wave   Wave bands along x (Scale 4), Distance 0.02 (smooth).
--filter-width sets the Bump node's Filter Width (Blender's default 0.1).
The material: a Diffuse BSDF (0.8) or a Principled BSDF (Base Color 0.8, roughness R).

MODE: ours | cycles:SPP. Prints `PLANE mode height bump bsdf sun: mean lum L` over the
image and RESULT with the render's CPU seconds.
"""
from __future__ import annotations

import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from newuser26_compare import read_exr  # noqa: E402
from newuser26_scenes import new_material, world_colour  # noqa: E402
from newuser44_table import arguments, render  # noqa: E402

LUM = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of linear RGB


def material(height, bump, bsdf, filter_width=None):
    m = new_material("Plane")
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    if bsdf.startswith("principled"):
        s = nt.nodes.new("ShaderNodeBsdfPrincipled")
        s.inputs["Roughness"].default_value = float(bsdf.split(":")[1])
        s.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    else:
        s = nt.nodes.new("ShaderNodeBsdfDiffuse")
        s.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(s.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    if not bump:
        return m
    uv = nt.nodes.new("ShaderNodeTexCoord")
    bu = nt.nodes.new("ShaderNodeBump")
    bu.invert = True
    if height == "brick":
        t = nt.nodes.new("ShaderNodeTexBrick")
        t.offset = 0.0
        t.inputs["Scale"].default_value = 16.0
        t.inputs["Brick Width"].default_value = 0.25
        t.inputs["Row Height"].default_value = 0.25
    elif height == "noise":
        t = nt.nodes.new("ShaderNodeTexNoise")
        t.inputs["Scale"].default_value = 8.0
        bu.inputs["Distance"].default_value = 0.02
    else:
        t = nt.nodes.new("ShaderNodeTexWave")
        t.wave_type, t.bands_direction = "BANDS", "X"
        t.inputs["Scale"].default_value = 4.0
        bu.inputs["Distance"].default_value = 0.02
    if filter_width is not None:
        bu.inputs["Filter Width"].default_value = filter_width
    nt.links.new(uv.outputs["UV"], t.inputs["Vector"])
    nt.links.new(t.outputs["Fac"], bu.inputs["Height"])
    nt.links.new(bu.outputs["Normal"], s.inputs["Normal"])
    return m


def main():
    ap = arguments(__doc__.splitlines()[0])
    ap.set_defaults(res=(64, 64))
    ap.add_argument("--height", default="brick", choices=("brick", "noise", "wave"))
    ap.add_argument("--no-bump", action="store_true")
    ap.add_argument("--bsdf", default="diffuse")
    ap.add_argument("--sun", type=float, default=45.0, help="degrees from the normal")
    ap.add_argument("--ortho", type=float, default=2.0)
    ap.add_argument("--lens", type=float, help="a perspective camera instead")
    ap.add_argument("--filter-width", type=float)
    a = ap.parse_args()
    import addon
    addon.register()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2.0)
    bpy.context.object.data.materials.append(
        material(a.height, not a.no_bump, a.bsdf, a.filter_width))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.0, math.radians(a.sun), 0.0)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    if a.lens:
        cam.data.lens = a.lens
    else:
        cam.data.type, cam.data.ortho_scale = "ORTHO", a.ortho
    cam.location = (0.0, 0.0, 3.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    world_colour(scene, (0, 0, 0), 0.0)
    c = scene.cycles
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = 0
    c.transmission_bounces = c.transparent_max_bounces = 0
    render(scene, a)
    img = read_exr(os.path.abspath(a.out))
    lum = img.reshape(-1, 3).mean(0) @ LUM
    print(f"PLANE {a.mode} {a.height} bump={not a.no_bump} {a.bsdf} sun={a.sun} "
          f"fw={a.filter_width}: mean lum {lum:.5f}", flush=True)


if __name__ == "__main__":
    main()
