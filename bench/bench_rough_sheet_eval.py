"""Very rough glass reads dark against Cycles (issue 14, lamp30 / roughlobes31): is it the
refraction's evaluation? A 3 x 3 m sheet of Principled glass (Transmission 1, plain GGX,
IOR 1.5; z = 0), a radius-0 100 W point lamp 0.3 m under it (light sampling alone in both
renderers: no continuation meets a delta light), a camera above looking at the lamp
through the sheet, black world, 48 x 36. Each render against the per-pixel prediction
eval(view, light) x I / r^2 (pixel centres, I = P / 4 pi) with

  - ours: engine/closures/ggx.glass_eval (h turned to the normal's side, pairs whose h
    no refraction produces refused), and
  - Cycles 5.0: bsdf_microfacet_eval's refraction transcribed below from the bpy wheel's
    own source (bpy/5.0/scripts/addons_core/cycles/source/kernel/closure/
    bsdf_microfacet.h): H = -(ior wo + wi) normalised, neither turned nor checked ("TODO:
    check if the refraction configuration is valid"), D of cos_NH^2, |cos_HI cos_HO|,
    Fresnel at |cos_HI|.

Also the transmitted albedo each eval integrates to over the far hemisphere (what light
sampling sees; Cycles' sampler never produces the pairs its eval adds).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_rough_sheet_eval.py [--no-render]

Measured 2026-12-04 (roughlobes31): roughness 1, ours / Cycles 0.638 over the image,
predicted 0.638; Cycles' render / its eval's prediction 1.000, ours 1.000; the outer
columns, lit in Cycles by refused pairs alone, 0 in ours. Roughness 0.5: 0.954,
predicted 0.942 (both renders 1.17-1.19 of the pixel-centre prediction: the narrower
glow under the pixel filter). Albedo by eval at roughness 1, view cosine 1 / 0.7 / 0.4:
Cycles 0.967 / 1.067 / 1.173, ours 0.876 / 0.782 / 0.691.
"""
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from engine.closures import ggx  # noqa: E402

IOR = 1.5
W, H = 48, 36
CAM = (0.5, 0.0, 1.0)
LAMP = (0.0, 0.0, -0.3)
POWER = 100.0


def _fresnel_cycles(c, eta):
    """Cycles' fresnel_dielectric (bsdf_util.h): unpolarised, at |cos|, eta unchanged."""
    s = eta * eta - (1.0 - c * c)
    out = np.ones_like(c)
    ok = s > 0
    ci = np.abs(c[ok])
    ct = -np.sqrt(s[ok]) / eta
    rs = (ci + eta * ct) / (ci - eta * ct)
    rp = (ct + eta * ci) / (eta * ci - ct)
    out[ok] = 0.5 * (rs * rs + rp * rp)
    return out


def _lambda(c, a2):
    t2 = np.maximum(1.0 / np.maximum(c * c, 1e-30) - 1.0, 0.0)
    return 0.5 * (np.sqrt(1.0 + a2 * t2) - 1.0)


def _d(cos_h, a2):
    c2 = np.minimum(cos_h * cos_h, 1.0)
    t = (1.0 - c2) + a2 * c2
    return a2 / (np.pi * t * t)


def cycles_refraction_eval(wi, wo, alpha, ior):
    """Cycles 5.0 bsdf_microfacet_eval, refraction, isotropic GGX, real Fresnel, weight 1:
    wi (N,3) the view (z > 0), wo (N,3) the light (z < 0), local frame. Returns (eval =
    f |cos wo| (N,), valid (N,) bool: h on the normal's side and the pair a refraction
    about it, as ours requires)."""
    h = -(ior * wo + wi)
    inv = 1.0 / np.linalg.norm(h, axis=1)
    h = h * inv[:, None]
    c_hi = np.sum(h * wi, 1)
    c_ho = np.sum(h * wo, 1)
    a2 = alpha * alpha
    common = _d(h[:, 2], a2) / wi[:, 2] * (ior * inv) ** 2 * np.abs(c_hi * c_ho)
    f = (1.0 - _fresnel_cycles(c_hi, ior)) * common / (
        1.0 + _lambda(wi[:, 2], a2) + _lambda(wo[:, 2], a2))
    return f, (h[:, 2] > 0) & (c_hi > 0) & (c_ho < 0)


def albedo_table(n=400_000):
    rng = np.random.default_rng(0)
    print("| roughness | view cos | Cycles 5.0 eval | its valid pairs | ours |")
    print("|---:|---:|---:|---:|---:|")
    for rough in (0.5, 0.75, 1.0):
        for mu in (1.0, 0.7, 0.4):
            wi = np.repeat([[math.sqrt(1.0 - mu * mu), 0.0, mu]], n, 0)
            z = -rng.random(n)
            r, ph = np.sqrt(1.0 - z * z), 2.0 * np.pi * rng.random(n)
            wo = np.stack([r * np.cos(ph), r * np.sin(ph), z], 1)
            fc, valid = cycles_refraction_eval(wi, wo, rough * rough, IOR)
            _, fo, _ = ggx.glass_eval_np(wi, wo, rough * rough, IOR)
            k = 2.0 * np.pi  # uniform over the hemisphere: mean x 2 pi
            print(f"| {rough} | {mu} | {k * fc.mean():.4f} | {k * (fc * valid).mean():.4f} "
                  f"| {k * fo.mean():.4f} |")


def _scene(bpy, rough):
    from mathutils import Vector
    from blender_helpers import node_material
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = W, H
    sc.render.resolution_percentage = 100
    w = bpy.data.worlds.new("W")
    sc.world = w
    next(n for n in w.node_tree.nodes if n.type == "BACKGROUND").inputs[
        "Strength"].default_value = 0.0
    m, nt, out = node_material(bpy, "Sheet")
    n = nt.nodes.new("ShaderNodeBsdfPrincipled")
    n.inputs["Roughness"].default_value = rough
    n.inputs["Transmission Weight"].default_value = 1.0
    n.inputs["IOR"].default_value = IOR
    n.inputs["Base Color"].default_value = (1, 1, 1, 1)
    n.distribution = "GGX"
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=3, location=(0, 0, 0))
    bpy.context.active_object.data.materials.append(m)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.data.energy, lamp.data.shadow_soft_size = POWER, 0.0
    lamp.location = LAMP
    sc.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = CAM
    cam.data.lens = 20
    cam.rotation_euler = (Vector(LAMP) - cam.location).to_track_quat("-Z", "Y").to_euler()
    sc.collection.objects.link(cam)
    sc.camera = cam
    return sc, cam


def _predict(bpy, sc, cam, rough):
    """Per-pixel eval(view, light) I / r^2 at the pixel centres: (Cycles', ours)."""
    from mathutils import Vector
    bpy.context.view_layer.update()
    tr, br, bl, tl = (Vector(v) for v in cam.data.view_frame(scene=sc))
    mw = cam.matrix_world
    o = np.array(mw.translation)
    pc, po = np.zeros((H, W)), np.zeros((H, W))
    for j in range(H):
        for i in range(W):
            p = tl + (tr - tl) * ((i + 0.5) / W) + (bl - tl) * ((j + 0.5) / H)
            d = np.array(mw.to_3x3() @ p)
            d /= np.linalg.norm(d)
            if d[2] >= 0:
                continue
            x = o - o[2] / d[2] * d
            if abs(x[0]) > 1.5 or abs(x[1]) > 1.5:
                continue
            ld = np.array(LAMP) - x
            r2 = ld @ ld
            ld = (ld / math.sqrt(r2))[None]
            fc, _ = cycles_refraction_eval(-d[None], ld, rough * rough, IOR)
            _, fo, _ = ggx.glass_eval_np(-d[None], ld, rough * rough, IOR)
            pc[j, i] = fc[0] * POWER / (4 * math.pi) / r2
            po[j, i] = fo[0] * POWER / (4 * math.pi) / r2
    return pc, po


def renders():
    import tempfile
    for sub in ("tests/blender", "tests"):
        sys.path.insert(0, os.path.join(ROOT, sub))
    import bpy
    import addon
    addon.register()
    from blender_helpers import cycles_plain, default_photonmap, read_rgba, render_exr
    print("| roughness | ours / Cycles | predicted | Cycles / its eval | ours / its eval "
          "| columns ours / Cycles (6 bins) |")
    print("|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for rough in (0.5, 1.0):
            img = {}
            for eng in ("PHOTONMAP", "CYCLES"):
                sc, cam = _scene(bpy, rough)
                cycles_plain(sc, 1024, 12)
                sc.render.engine = eng
                if eng == "PHOTONMAP":
                    default_photonmap(sc).spp = 64
                img[eng] = read_rgba(bpy, render_exr(bpy, sc, os.path.join(tmp, eng + ".exr"))
                                     )[..., :3].mean(-1)
            pc, po = _predict(bpy, *_scene(bpy, rough), rough)
            o, c = img["PHOTONMAP"], img["CYCLES"]
            cols = " ".join(f"{o[:, k].mean() / c[:, k].mean():.3f}"
                            for k in np.array_split(np.arange(W), 6))
            print(f"| {rough} | {o.mean() / c.mean():.3f} | {po.mean() / pc.mean():.3f} "
                  f"| {c.mean() / pc.mean():.3f} | {o.mean() / po.mean():.3f} | {cols} |",
                  flush=True)


if __name__ == "__main__":
    albedo_table()
    if "--no-render" not in sys.argv:
        renders()
