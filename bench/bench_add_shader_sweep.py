"""Add / Mix Shader pairs with a Transparent BSDF or transmissive sides, ours against
Cycles through the bpy wheel (issue 14: "Closures as Cycles defines them ... Mix and Add",
within 2 %; s44 addshader44). Two scenes:

- sphere: a smooth UV sphere (radius 1, 48 x 24) in a uniform grey world (0.5), seen by
  an orthographic camera that the sphere fills; Light Paths 8 bounces of every kind
  (Cycles' and ours; --bounces); ours with photon mapping at its defaults but 50k global photons.
- plane: a 40 m plane lit by a delta sun (3 W/m^2, 35 degrees off zenith) in a black
  world, seen at 45 degrees (the harness of tests/blender/test_add_refraction_cycles.py);
  direct light only (photon mapping off, 0 bounces).

    PYTHONPATH=. .venv/bin/python bench/bench_add_shader_sweep.py [--scene sphere plane]
        [--pairs SUBSTRING ...] [--res 24] [--spp 16] [--cycles-spp 128]

Prints one row a pair and scene: ours / Cycles of the image mean per channel, both means,
and `*` where a channel is off by more than 2 % (of the brightest channel for a faint
one: the tests' tolerance). Cycles plain: CPU, seed 0, no denoise / adaptive / clamp /
glossy blur, box pixel filter 1 px.
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


def _node(nd, kind, **inputs):
    n = nd.new(kind)
    for k, v in inputs.items():
        n.inputs[k].default_value = (*v, 1.0) if isinstance(v, tuple) else v
    return n.outputs[0]


def _refraction(nd):
    n = nd.new("ShaderNodeBsdfRefraction")  # GGX (Blender's default is Beckmann, warned)
    n.distribution = "GGX"
    n.inputs["Color"].default_value = (0.6, 0.9, 0.6, 1.0)
    n.inputs["Roughness"].default_value = 0.2
    return n.outputs[0]


# The single closures of the s42 sweep (and the Transparent BSDF), as builders of nodes.
CLOSURES = {
    "diffuse": lambda nd: _node(nd, "ShaderNodeBsdfDiffuse", Color=(0.8, 0.8, 0.8)),
    "glossy": lambda nd: _node(nd, "ShaderNodeBsdfGlossy", Color=(0.9, 0.8, 0.3),
                               Roughness=0.25),
    "glass": lambda nd: _node(nd, "ShaderNodeBsdfGlass", Color=(0.9, 0.9, 0.6),
                              Roughness=0.0),
    "rough glass": lambda nd: _node(nd, "ShaderNodeBsdfGlass", Color=(0.9, 0.9, 0.6),
                                    Roughness=0.3),
    "refraction": lambda nd: _refraction(nd),
    "principled": lambda nd: _node(nd, "ShaderNodeBsdfPrincipled",
                                   **{"Base Color": (0.1, 0.4, 0.8), "Roughness": 0.6}),
    "metal": lambda nd: _node(nd, "ShaderNodeBsdfPrincipled",
                              **{"Base Color": (0.95, 0.8, 0.4), "Roughness": 0.25,
                                 "Metallic": 1.0}),
    "translucent": lambda nd: _node(nd, "ShaderNodeBsdfTranslucent", Color=(0.8, 0.6, 0.3)),
    "sheen": lambda nd: _node(nd, "ShaderNodeBsdfSheen", Color=(0.9, 0.5, 0.5)),
    "emission": lambda nd: _node(nd, "ShaderNodeEmission", Color=(0.2, 0.9, 0.3),
                                 Strength=0.5),
    "transparent": lambda nd: _node(nd, "ShaderNodeBsdfTransparent", Color=(1.0, 1.0, 1.0)),
    "orange transparent": lambda nd: _node(nd, "ShaderNodeBsdfTransparent",
                                           Color=(0.9, 0.7, 0.4)),
}

TRANSMISSIVE = ("glass", "rough glass", "refraction")


def _pairs():
    """{name: (op, factor, a, b)}: the pairs the s42 sweep left outside 2 %."""
    out = {}
    for t in ("transparent", "orange transparent"):
        for b in ("diffuse", "glossy", "principled", "metal", "glass", "translucent",
                  "refraction", "sheen"):
            out[f"add {t}+{b}"] = ("add", None, t, b)
    for i, a in enumerate(TRANSMISSIVE):
        for b in TRANSMISSIVE[i:]:
            out[f"add {a}+{b}"] = ("add", None, a, b)
        out[f"add {a}+diffuse"] = ("add", None, a, "diffuse")
        for b in ("principled", "translucent"):
            out[f"mix 0.4 {a}+{b}"] = ("mix", 0.4, a, b)
            out[f"mix 0.4 {b}+{a}"] = ("mix", 0.4, b, a)
    return out


PAIRS = _pairs()


def surface_material(bpy, name, build):
    """A new material whose Surface is build(nodes, links) (-> the output socket)."""
    from blender_helpers import node_material
    m, nt, out = node_material(bpy, name)
    nt.links.new(build(nt.nodes, nt.links), out.inputs["Surface"])
    return m


def join(nd, ln, a, b, fac=None):
    """Add Shader of sockets a and b (fac None), else Mix Shader by the factor fac."""
    node = nd.new("ShaderNodeAddShader" if fac is None else "ShaderNodeMixShader")
    first = 0 if fac is None else 1
    if fac is not None:
        node.inputs[0].default_value = fac
    ln.new(a, node.inputs[first])
    ln.new(b, node.inputs[first + 1])
    return node.outputs[0]


def material(bpy, name, pair):
    op, fac, a, b = pair
    return surface_material(bpy, name, lambda nd, ln: join(
        nd, ln, CLOSURES[a](nd), CLOSURES[b](nd), None if op == "add" else fac))


def sphere_scene(bpy, scene, mat, res):
    """The sphere of the sweep on scene: radius 1, smooth, of material mat, filling an
    orthographic res x res view, in a uniform world of 0.5."""
    from blender_helpers import world_color
    from tools.canonical_mesh import primitive_uv_sphere_add
    scene.render.resolution_x = scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    primitive_uv_sphere_add(radius=1.0, segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(mat)
    world_color(bpy, scene, (0.5, 0.5, 0.5))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 1.2
    cam.location, cam.rotation_euler = (0.0, -5.0, 0.0), (math.radians(90), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam


def build(bpy, scene_kind, pair, res):
    """A fresh scene of kind 'sphere' or 'plane' with the pair's material."""
    from blender_helpers import sun_light, world_color
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    mat = material(bpy, "Pair", pair)
    if scene_kind == "sphere":
        sphere_scene(bpy, scene, mat, res)
        return scene
    scene.render.resolution_x = scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(mat)
    sun_light(bpy, scene, (0.0, math.radians(35.0), 0.0)).data.angle = 0.0
    world_color(bpy, scene, None, 0.0)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (-6.0, 0.0, 6.0)
    cam.rotation_euler = (math.radians(45.0), 0.0, math.radians(-90.0))
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def render(bpy, scene, engine, spp, path, bounces, photon_mapping=True, photons=50_000,
           caustic_photons=20_000):
    """(3,) the image mean of scene rendered by engine at spp samples, Light Paths
    `bounces` of every kind (Transparent 8), Cycles plain with a 1 px box filter; ours
    with `photons` global and `caustic_photons` caustic photons."""
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    c = cycles_plain(scene, spp, bounces)
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.transparent_max_bounces = 8
    c.caustics_reflective = c.caustics_refractive = True
    c.pixel_filter_type, c.filter_width = "BOX", 1.0
    scene.render.engine = engine
    if engine == "PHOTONMAP":
        cheap(scene, spp=spp, photons=photons, caustic_photons=caustic_photons)
        scene.photonmap.photon_mapping = photon_mapping
    return read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].reshape(-1, 3).mean(axis=0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", nargs="+", default=["sphere", "plane"],
                    choices=("sphere", "plane"))
    ap.add_argument("--pairs", nargs="*", default=[],
                    help="only pairs whose name contains one of these")
    ap.add_argument("--res", type=int, default=24)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--cycles-spp", type=int, default=128)
    ap.add_argument("--bounces", type=int, default=8,
                    help="the sphere's Light Paths limits (every kind)")
    a = ap.parse_args()
    import bpy
    import addon
    addon.register()
    names = [n for n in PAIRS if not a.pairs or any(s in n for s in a.pairs)]
    tmp = tempfile.mkdtemp()
    print(f"{'scene':7s} {'pair':40s} {'ours / Cycles (R G B)':24s} ours mean | Cycles mean")
    outside = 0
    for kind in a.scene:
        for name in names:
            scene = build(bpy, kind, PAIRS[name], a.res)
            bounces = a.bounces if kind == "sphere" else 0
            ref = render(bpy, scene, "CYCLES", a.cycles_spp, os.path.join(tmp, "c.exr"),
                         bounces)
            got = render(bpy, scene, "PHOTONMAP", a.spp, os.path.join(tmp, "o.exr"),
                         bounces, photon_mapping=kind == "sphere")
            ratio = got / np.maximum(ref, 1e-9)
            off = np.abs(got - ref) > np.maximum(0.02 * ref, 0.02 * ref.max())
            outside += bool(off.any())
            print(f"{kind:7s} {name:40s} "
                  + " ".join(f"{r:6.3f}{'*' if o else ' '}" for r, o in zip(ratio, off))
                  + f"   {got.round(4).tolist()} | {ref.round(4).tolist()}", flush=True)
    print(f"{outside} of {len(names) * len(a.scene)} rows outside 2 %")


if __name__ == "__main__":
    main()
