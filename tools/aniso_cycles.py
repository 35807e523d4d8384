"""Brushed metal against Cycles (issue 14, anisotropic GGX): a Principled metal plane
(roughness 0.35, Anisotropic 0.8, Rotation `rot`) under a small area light, black world,
rendered by our engine and by the bpy wheel's Cycles at the same samples. Prints the
per-region brightness ratios (4 x 4 regions holding the highlight) and the highlight's
second moments (the elongation direction and the two lengths, pixels).

    NUMBA_CACHE_DIR=... PYTHONPATH=$PWD python tools/aniso_cycles.py [--spp 64] [--rot 0]
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 96, 72


def build(bpy, aniso, rot, node="principled", wall=False, spin=0.0, uv_angle=None,
          named=False):
    """uv_angle (radians): the plate gets a UV map whose u axis is turned that far from the
    plate's x axis, and a Tangent node (UV Map mode) feeds the lobe's Tangent: the
    highlight follows the UV map's tangent instead of the radial default. named: that map
    is a second one ('brush', after an unturned render map 'UVMap'), which the Tangent
    node names."""
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    m, nt, out = mb.empty_material("Brushed")
    if node == "principled":
        n = nt.nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (0.9, 0.7, 0.5, 1.0)
        n.inputs["Metallic"].default_value = 1.0
        n.inputs["Roughness"].default_value = 0.35
        n.inputs["Anisotropic"].default_value = aniso
        n.inputs["Anisotropic Rotation"].default_value = rot
    else:
        n = nt.nodes.new("ShaderNodeBsdfAnisotropic" if hasattr(bpy.types, "ShaderNodeBsdfAnisotropic")
                         else "ShaderNodeBsdfGlossy")
        n.inputs["Color"].default_value = (0.9, 0.7, 0.5, 1.0)
        n.inputs["Roughness"].default_value = 0.35
        n.inputs["Anisotropy"].default_value = aniso
        n.inputs["Rotation"].default_value = rot
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    if uv_angle is not None:
        tan = nt.nodes.new("ShaderNodeTangent")
        tan.direction_type = "UV_MAP"
        if named:
            tan.uv_map = "brush"
        nt.links.new(tan.outputs["Tangent"], n.inputs["Tangent"])
    # spin (radians) turns the plate about its own Z: the radial tangent turns with the
    # object (its normal transform), the highlight stays where it was.
    plate = mb.plane("Plate", 4.0, 4.0, m, location=(0.3, 0.2, 0.0), rotation=(0.0, 0.0, spin))
    if uv_angle is not None:
        c, s_ = math.cos(uv_angle), math.sin(uv_angle)
        if named:  # the render map first, unturned
            plain = plate.data.uv_layers.new(name="UVMap")
            for loop in plate.data.loops:
                x, y, _ = plate.data.vertices[loop.vertex_index].co
                plain.data[loop.index].uv = (0.5 + x / 4.0, 0.5 + y / 4.0)
            plain.active_render = True
        uv = plate.data.uv_layers.new(name="brush")
        for loop in plate.data.loops:
            x, y, _ = plate.data.vertices[loop.vertex_index].co
            uv.data[loop.index].uv = (0.5 + (x * c + y * s_) / 4.0,
                                      0.5 + (-x * s_ + y * c) / 4.0)
    mb.set_world((0.0, 0.0, 0.0))
    if wall:
        # A white wall the plate's glossy reflection lights (photon pass: caustic photons
        # off the anisotropic lobe), the light hidden from it behind a blocker.
        white = mb.material("white", "diffuse", (0.8, 0.8, 0.8))
        mb.plane("Wall", 4.0, 2.0, white, (0.3, 2.2, 1.0), (math.pi / 2, 0, 0))
        mb.light("Area", "AREA", (0.3, 0.2, 1.2), 300.0, look_at=(0.3, -0.4, 0.0), size=0.2)
        mb.plane("Blocker", 1.0, 0.6, white, (0.3, 0.45, 1.2), (math.pi / 2, 0, 0))
        mb.camera((0.0, -3.2, 2.0), (0.3, 1.5, 0.8), fov_deg=60.0)
    else:
        mb.light("Area", "AREA", (0.9, 0.6, 1.6), 150.0, look_at=(0.9, 0.6, 0.0), size=0.25)
        mb.camera((0.0, -3.2, 2.6), (0.3, 0.3, 0.0), fov_deg=50.0)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    return scene


def render(bpy, scene, engine, spp, photons=2_000):
    sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
    import blender_helpers as bh
    if engine == "cycles":
        scene.render.engine = "CYCLES"
        bh.cycles_plain(scene, spp, 2)
    else:
        scene.render.engine = "PHOTONMAP"
        bh.default_photonmap(scene)
        bh.cheap(scene, spp=spp, photons=photons, caustic_photons=photons)
    path = os.path.join(tempfile.mkdtemp(prefix="aniso_"), f"{engine}.exr")
    bh.render_exr(bpy, scene, path)
    return bh.read_rgba(bpy, path)[..., :3].astype(np.float64)


def moments(lum, frac=0.25):
    """The highlight (pixels above frac x the peak): (angle of the long axis, degrees,
    long and short standard deviations, pixels), luminance-weighted."""
    m = lum >= frac * lum.max()
    y, x = np.nonzero(m)
    w = lum[m]
    cx, cy = np.average(x, weights=w), np.average(y, weights=w)
    c = np.cov(np.stack([x - cx, y - cy]), aweights=w)
    ev, evec = np.linalg.eigh(c)
    ang = np.degrees(np.arctan2(evec[1, 1], evec[0, 1])) % 180.0
    return ang, float(np.sqrt(ev[1])), float(np.sqrt(ev[0])), (cx, cy)


def regions(img, n=4):
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    h, w = lum.shape
    return np.array([[lum[i * h // n:(i + 1) * h // n, j * w // n:(j + 1) * w // n].mean()
                      for j in range(n)] for i in range(n)])


def compare(bpy, spp=64, aniso=0.8, rot=0.0, node="principled", wall=False, photons=2_000,
            spin=0.0, uv_angle=None, named=False):
    scene = build(bpy, aniso, rot, node, wall, spin, uv_angle, named)
    ours = render(bpy, scene, "ours", spp, photons)
    cyc = render(bpy, scene, "cycles", spp)
    lo, lc = (a @ np.array([0.2126, 0.7152, 0.0722]) for a in (ours, cyc))
    return {"total": float(lo.sum() / lc.sum()), "regions_ours": regions(ours),
            "regions_cycles": regions(cyc), "moments_ours": moments(lo),
            "moments_cycles": moments(lc)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--aniso", type=float, default=0.8)
    ap.add_argument("--rot", type=float, default=0.0)
    ap.add_argument("--node", default="principled")
    ap.add_argument("--wall", action="store_true")
    ap.add_argument("--spin", type=float, default=0.0)
    ap.add_argument("--photons", type=int, default=2_000)
    ap.add_argument("--uv-angle", type=float, default=None,
                    help="degrees: the tangent from a UV map turned that far (Tangent node)")
    a = ap.parse_args()
    sys.path.insert(0, ROOT)
    import bpy
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    r = compare(bpy, a.spp, a.aniso, a.rot, a.node, a.wall, a.photons, a.spin,
                None if a.uv_angle is None else math.radians(a.uv_angle))
    np.set_printoptions(precision=4, suppress=True)
    print("total ours/cycles", round(r["total"], 4))
    print("regions ours\n", r["regions_ours"])
    print("regions cycles\n", r["regions_cycles"])
    print("ratio\n", r["regions_ours"] / np.maximum(r["regions_cycles"], 1e-12))
    print("moments ours   (angle, long, short, centre)", r["moments_ours"])
    print("moments cycles (angle, long, short, centre)", r["moments_cycles"])


if __name__ == "__main__":
    main()
