"""Cycles references for tests/test_closures_cycles.py (the cases of tests/closure_cases.py).

    .venv/bin/python tools/make_closure_references.py [--samples 2048] [--only NAME,...]
    .venv/bin/python tools/make_closure_references.py --sweep --samples 1024

--sweep renders closure_cases.sweep_cases() (the sweep's corners, tests/test_closures_sweep.py)
into tests/references/closures_sweep.json instead.

Renders each case with Cycles (CPU, no clamping, no denoising, box filter, 32 bounces) in
the bpy wheel and stores the mean RGB of its pixels (the whole plane image; the furnace
ball's pixels) in tests/references/closures.json, with the samples, seconds and Blender
version. Needs the bpy wheel.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "tests"))
import accuracy_scenes as acc  # noqa: E402  (bpy session, Cycles settings, EXR read-back)
import closure_cases as cc  # noqa: E402

bpy = acc.bpy
mb = acc.mb
REF_PATH = os.path.join(ROOT, "tests", "references", "closures.json")
SWEEP_PATH = os.path.join(ROOT, "tests", "references", "closures_sweep.json")


def _material(spec):
    m, nt, out = mb.empty_material("closure")
    rgba = (*spec["base_color"], 1.0)
    node = spec["node"]
    if node == "principled":
        n = nt.nodes.new("ShaderNodeBsdfPrincipled")
        n.distribution = spec["distribution"]
        n.inputs["Base Color"].default_value = rgba
        for key, socket in (("roughness", "Roughness"), ("metallic", "Metallic"),
                            ("ior", "IOR"), ("specular_ior_level", "Specular IOR Level"),
                            ("coat_weight", "Coat Weight"),
                            ("coat_roughness", "Coat Roughness"), ("coat_ior", "Coat IOR"),
                            ("sheen_weight", "Sheen Weight"),
                            ("sheen_roughness", "Sheen Roughness")):
            n.inputs[socket].default_value = spec[key]
        for key, socket in (("specular_tint", "Specular Tint"), ("coat_tint", "Coat Tint"),
                            ("sheen_tint", "Sheen Tint")):
            n.inputs[socket].default_value = (*spec[key], 1.0)
    elif node == "glossy":
        n = nt.nodes.new("ShaderNodeBsdfGlossy")
        n.distribution = spec["distribution"]
        n.inputs["Color"].default_value = rgba
        n.inputs["Roughness"].default_value = spec["roughness"]
    elif node == "glass":
        n = nt.nodes.new("ShaderNodeBsdfGlass")
        n.distribution = spec["distribution"]
        n.inputs["Color"].default_value = rgba
        n.inputs["Roughness"].default_value = spec["roughness"]
        n.inputs["IOR"].default_value = spec["ior"]
    elif node == "diffuse":
        n = nt.nodes.new("ShaderNodeBsdfDiffuse")
        n.inputs["Color"].default_value = rgba
    else:
        raise ValueError(node)
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    return m


def _camera(view_deg, dist, fov):
    v = math.radians(view_deg)
    loc = (-math.sin(v) * dist, 0.0, math.cos(v) * dist)
    cam = mb.camera(loc, (0.0, 0.0, 0.0), fov)
    if view_deg == 0.0:  # looking straight down: keep +y up in the image
        cam.rotation_euler = (0.0, 0.0, 0.0)
    return cam


def build_plane(spec, view):
    mb.reset()
    mb.plane("Plane", 40.0, 40.0, _material(spec))
    z = math.radians(cc.SUN_ZENITH)
    # Blender's sun shines along its local -Z; turned about +Y it travels along
    # (-sin z, 0, -cos z): it comes from the +x side, mirrored towards the camera's -x side.
    mb.light("Sun", "SUN", (0, 0, 5), cc.SUN_W, rotation=(0.0, z, 0.0), angle=0.0)
    _camera(view, cc.CAM_DIST, cc.FOV_DEG)
    return cc.SIZE


def build_furnace(spec):
    mb.reset()
    mb.set_world((1.0, 1.0, 1.0), 1.0)
    mb.sphere("Ball", 1.0, _material(spec), (0.0, 0.0, 0.0), segments=96, rings=48)
    _camera(cc.FURNACE_VIEW, cc.FURNACE_DIST, cc.FURNACE_FOV)
    return cc.FURNACE_SIZE


def render(size, samples):
    scene = bpy.context.scene
    acc.set_cycles(scene, samples)
    r = scene.render
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    rgba, secs = acc.render_rgba(scene)
    return rgba, secs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2048)
    ap.add_argument("--only", default="")
    ap.add_argument("--sweep", action="store_true",
                    help="the sweep's corners (closure_cases.sweep_cases) into "
                         "closures_sweep.json")
    args = ap.parse_args(argv)
    only = set(filter(None, args.only.split(",")))
    path = SWEEP_PATH if args.sweep else REF_PATH
    refs = {}
    if os.path.exists(path):
        with open(path) as f:
            refs = json.load(f)
    planes, furnaces = (cc.sweep_cases() if args.sweep
                        else (cc.plane_cases(), cc.furnace_cases()))
    cases = {k: ("plane", v) for k, v in planes.items()}
    cases.update({k: ("furnace", v) for k, v in furnaces.items()})
    for name, (kind, spec) in cases.items():
        if only and name not in only:
            continue
        size = build_plane(*spec) if kind == "plane" else build_furnace(spec)
        rgba, secs = render(size, args.samples)
        if kind == "plane":
            mean = rgba[..., :3].reshape(-1, 3).mean(axis=0)
        else:
            mean = rgba[..., :3][cc.ball_mask(size)].mean(axis=0)
        refs[name] = {"rgb": [float(x) for x in mean], "samples": args.samples,
                      "seconds": round(secs, 2)}
        print(f"{name:32s} {np.round(mean, 4)}  {secs:.1f}s", flush=True)
    refs["_meta"] = {"blender": bpy.app.version_string, "tool": "tools/make_closure_references.py"}
    with open(path, "w") as f:
        json.dump(refs, f, indent=1, sort_keys=True)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
