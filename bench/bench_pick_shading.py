"""Per-hit shading cost of a Mix Shader that picks one of two surfaces per hit (mixsides,
issue 14): CPU nanoseconds per hit of bsdf.surface_hit (the camera's surface data: hit
geometry, the colour texture and the per-hit closure rows, textures.scalar_params) on a
plane, best of --repeats, process time. Each material is timed with the closure pick's
batch cache (engine.shadernodes.ClosurePick: one evaluation of the factor and the hash per
hit set) and without it (every reader re-evaluates), interleaved; a plain Principled
plane gives the floor. --root runs another checkout's engine and add-on (e.g. main).

    .venv/bin/python bench/bench_pick_shading.py [--hits 100000] [--repeats 5] [--root DIR]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _principled(nt, rgb, roughness, metallic=0.0, ior=1.5, coat=None):
    n = nt.nodes.new("ShaderNodeBsdfPrincipled")
    n.inputs["Base Color"].default_value = (*rgb, 1.0)
    n.inputs["Roughness"].default_value = roughness
    n.inputs["Metallic"].default_value = metallic
    n.inputs["IOR"].default_value = ior
    if coat is not None:
        n.inputs["Coat Weight"].default_value = 1.0
        n.inputs["Coat Tint"].default_value = (*coat, 1.0)
    return n.outputs[0]


def _material(bpy, name, sides):
    """A material: Principled side(s); two sides are mixed by a Noise Texture (scale 6)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    socks = [_principled(nt, *s[0], **s[1]) for s in sides]
    if len(socks) == 1:
        nt.links.new(socks[0], out.inputs["Surface"])
        return mat
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 6.0
    ms = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(noise.outputs["Fac"], ms.inputs[0])
    nt.links.new(socks[0], ms.inputs[1])
    nt.links.new(socks[1], ms.inputs[2])
    nt.links.new(ms.outputs[0], out.inputs["Surface"])
    return mat


MATERIALS = {
    "plain Principled": [(((0.1, 0.4, 0.8), 0.6), {})],
    "dielectric+metal (noise)": [(((0.1, 0.4, 0.8), 0.6), {}),
                                 (((0.95, 0.8, 0.4), 0.25), {"metallic": 1.0})],
    "IOR 1.5 coated + IOR 2.4 (noise)": [(((0.8, 0.1, 0.1), 0.3), {"coat": (0.3, 0.9, 0.2)}),
                                         (((0.1, 0.1, 0.8), 0.3), {"ior": 2.4})],
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hits", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--root", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    a = ap.parse_args(argv)
    sys.path.insert(0, a.root)
    import bpy
    import numpy as np
    from addon.core import load_engine
    from addon.materials import MaterialConverter
    pm = load_engine()
    from engine.bsdf import surface_hit
    from engine import shadernodes as sn
    from engine.scene import Mesh, Scene
    from engine.geometry import prepare

    bpy.ops.wm.read_homefile(use_empty=True)
    conv = MaterialConverter(pm)
    mats = {k: conv.convert(_material(bpy, k, v)) for k, v in MATERIALS.items()}
    rng = np.random.default_rng(1)
    n = a.hits
    # A 4 m plane of 2 x 64 x 64 triangles with Generated coordinates (the Noise's input).
    k = 64
    xs = np.linspace(-2.0, 2.0, k + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    verts = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    i = np.arange(k)[:, None] * (k + 1) + np.arange(k)[None, :]
    i = i.ravel()
    faces = np.concatenate([np.stack([i, i + k + 1, i + k + 2], 1),
                            np.stack([i, i + k + 2, i + 1], 1)])
    gen = (verts[faces] + 2.0) / 4.0  # (T,3,3) per-corner generated coordinates
    cached = getattr(sn, "_PickBatch", None)
    setups = {}
    for name, m in mats.items():
        mesh = Mesh(name=name, vertices=verts, faces=faces, materials=[m.name],
                    coordinates={"generated": gen, "object": gen})
        scene = Scene(meshes=[mesh], materials={m.name: m}, lights=[])
        setups[name] = prepare(scene)
    prim = rng.integers(0, 2 * k * k, n)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    u, v = s * (1 - r2), s * r2
    d = np.tile([0.3, 0.0, -1.0], (n, 1)) / np.hypot(0.3, 1.0)
    best = {(name, mode): np.inf for name in mats for mode in ("cache", "no cache")}
    original = cached.matches if cached is not None else None
    for name, (geo, table) in setups.items():
        surface_hit(geo, table, prim[:1000], u[:1000], v[:1000], d[:1000])  # warm up
    for _ in range(a.repeats):
        for mode in ("cache", "no cache"):
            if cached is not None:
                cached.matches = original if mode == "cache" else (lambda *args: False)
            for name, (geo, table) in setups.items():
                t0 = cpu()
                surface_hit(geo, table, prim, u, v, d)
                best[name, mode] = min(best[name, mode], cpu() - t0)
    if cached is not None:
        cached.matches = original
    load = os.getloadavg()[0]
    print(f"# root {a.root}, {n} hits, best of {a.repeats}, load {load:.1f}")
    print("| material | per-hit columns | ns/hit, pick cached | ns/hit, not cached |")
    print("|---|---|---|---|")
    for name, (geo, table) in setups.items():
        cols = table.scalar_textures[0]
        print(f"| {name} | {0 if cols is None else len(cols)} | "
              f"{1e9 * best[name, 'cache'] / n:.0f} | {1e9 * best[name, 'no cache'] / n:.0f} |")


if __name__ == "__main__":
    main()
