"""vase47: newuser45's living-room vase against Cycles, magnified: the room of
bench/newuser45_room.py rendered by both engines at a higher resolution inside a render
border round the vase (so its sub-pixel highlights cover many pixels), one light at a
time if asked; prints the mean luminance ratio ours / Cycles over the vase's pixels
(all, those Cycles reads brightest, the rest) and over rows of the vase's image.

    PYTHONPATH=. .venv/bin/python bench/vase47_room.py [--res W H] [--lights L,...]
        [--spp N] [--cycles-spp N] [--cycles-seed S] [--set NAME=VALUE] [--keep DIR]
        [--reuse] [--seeds N] [--passes] [--no-clamp] [--filter-glossy F] [--aniso A]
        [--flat] [--pad PX]

--lights: a comma list of spot, point, lamp (the emissive shade), world; the others are
set to 0 (light energy, emission strength, world colour) in both engines; default all.
--res: the full frame's size (160 x 120 is newuser45's); the border is the vase's box
at 160 x 120 padded by --pad pixels of that size. --reuse: read DIR's renders if there
(named by lights, size, samples, seed and the scene options). --seeds N: ours at seeds
0..N-1 against the one Cycles render, and their mean. --passes: ours' effect passes
(engine/film.py) over the vase and at Cycles' brightest vase pixel.
Cycles: no denoise, no adaptive sampling, seed --cycles-seed; both engines read the
scene's Light Paths (clamp 10 indirect unless --no-clamp, Filter Glossy 1 unless set).
Findings and commands: docs/accuracy.md "vase47".
"""
from __future__ import annotations

import argparse
import ast
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402
import bpy  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "bench"))
from newuser26_scenes import cpu  # noqa: E402
from newuser26_compare import read_exr  # noqa: E402
from newuser45_room import room_scene, wood_png  # noqa: E402


def masks_in(scene, w, h, box, name):
    """(H, W) bool: the pixel centres inside box (x0, y0, x1, y1; top-left origin) whose
    camera ray hits object `name` first (Blender's scene.ray_cast, as
    newuser26_scenes.object_masks, only inside the box)."""
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    tr, br, bl, tl = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    origin = cam.matrix_world.translation
    out = np.zeros((h, w), bool)
    x0, y0, x1, y1 = box
    for j in range(y0, y1):
        v = (j + 0.5) / h
        for i in range(x0, x1):
            u = (i + 0.5) / w
            p = tl.lerp(tr, u).lerp(bl.lerp(br, u), v)
            hit, _, _, _, ob, _ = scene.ray_cast(dg, origin, (p - origin).normalized())
            out[j, i] = bool(hit) and ob.name == name
    return out


def keep_lights(scene, keep):
    for ob in scene.objects:
        if ob.type == "LIGHT" and ob.name.lower() not in keep:
            ob.data.energy = 0.0
    if "lamp" not in keep:
        nt = bpy.data.materials["LampShade"].node_tree
        for n in nt.nodes:
            if n.type == "EMISSION":
                n.inputs["Strength"].default_value = 0.0
    if "world" not in keep:
        for n in scene.world.node_tree.nodes:
            if n.type == "BACKGROUND":
                n.inputs["Strength"].default_value = 0.0


def render(scene, engine, out, a):
    """(luminance (H, W), {effect: luminance (H, W)}: ours' effect passes with --passes,
    else empty), CPU seconds."""
    r = scene.render
    r.engine = engine
    if engine == "CYCLES":
        c = scene.cycles
        c.device, c.samples, c.seed = "CPU", a.cycles_spp, a.cycles_seed
        c.use_denoising = c.use_adaptive_sampling = False
    else:
        scene.photonmap.spp = a.spp
        for k, v in (s.split("=", 1) for s in a.set):
            setattr(scene.photonmap, k, ast.literal_eval(v))
    if a.reuse and os.path.exists(out) and not (a.passes and engine != "CYCLES"):
        return (lum(read_exr(out)[..., :3]), {}), 0.0
    fmt = r.image_settings
    fmt.media_type = "IMAGE"
    fmt.file_format, fmt.color_depth = "OPEN_EXR", "32"
    r.filepath, r.use_file_extension = out, False
    import addon.engine as ae
    films = []

    def keep(event, value):  # the engine's Film of the render (addon/engine.py)
        if event == "film":
            films.append(value)
    ae.status_listeners.append(keep)
    t0 = cpu()
    bpy.ops.render.render(write_still=True)
    t = cpu() - t0
    ae.status_listeners.remove(keep)
    passes = {}
    if films and a.passes:  # ours' effect passes (engine/film.py), placed in the frame
        f = films[-1]
        x0, y0, x1, y1 = ae.last_render.get("region") or (0, 0, f.width, f.height)
        for k in ("direct", "indirect", "caustic", "specular", "emission"):
            v = getattr(f, k, None)
            if v is not None:
                full = np.zeros((r.resolution_y, r.resolution_x))
                full[y0:y1, x0:x1] = lum(np.asarray(v, np.float64)[..., :3])
                passes[k] = full
    return (lum(read_exr(out)[..., :3]), passes), t


def lum(x):
    return x @ np.array([0.2126, 0.7152, 0.0722])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, nargs=2, default=(640, 480))
    ap.add_argument("--lights", default="spot,point,lamp,world")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--cycles-spp", type=int, default=1024)
    ap.add_argument("--cycles-seed", type=int, default=0)
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--keep")
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument("--no-clamp", action="store_true")
    ap.add_argument("--filter-glossy", type=float)
    ap.add_argument("--aniso", type=float, default=0.6)
    ap.add_argument("--flat", action="store_true")
    ap.add_argument("--pad", type=int, default=2)
    ap.add_argument("--passes", action="store_true",
                    help="prints ours' effect passes (direct, indirect, caustic, specular, "
                         "emission: engine/film.py) over the vase and at its brightest pixel")
    ap.add_argument("--seeds", type=int, default=0,
                    help="ours at seeds 0 .. N-1 against one Cycles render; prints the mean")
    a = ap.parse_args()
    import addon
    addon.register()
    d = a.keep or tempfile.mkdtemp(prefix="vase47_")
    os.makedirs(d, exist_ok=True)
    scene = room_scene(wood_png(os.path.join(d, "wood.png")), a.aniso, a.flat)
    keep_lights(scene, set(a.lights.split(",")))
    c = scene.cycles
    if a.no_clamp:
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    if a.filter_glossy is not None:
        c.blur_glossy = a.filter_glossy
    # The vase's box at newuser45's 160 x 120, padded, scaled to --res.
    small = masks_in(scene, 160, 120, (0, 0, 160, 120), "Vase")
    ys, xs = np.nonzero(small)
    w, h = a.res
    sx, sy = w / 160, h / 120
    box = (int((xs.min() - a.pad) * sx), int((ys.min() - a.pad) * sy),
           int((xs.max() + 1 + a.pad) * sx), int((ys.max() + 1 + a.pad) * sy))
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    r.use_border, r.use_crop_to_border = True, False
    r.border_min_x, r.border_max_x = box[0] / w, box[2] / w
    r.border_min_y, r.border_max_y = 1.0 - box[3] / h, 1.0 - box[1] / h
    mask = masks_in(scene, w, h, box, "Vase")
    mask[:box[1] + 1] = mask[box[3] - 1:] = False  # the border's edge rows and columns:
    mask[:, :box[0] + 1] = mask[:, box[2] - 1:] = False  # the filter reads past them
    opts = (f"{'_noclamp' if a.no_clamp else ''}"
            f"{'' if a.filter_glossy is None else f'_fg{a.filter_glossy}'}"
            f"{'' if a.aniso == 0.6 else f'_an{a.aniso}'}{'_flat' if a.flat else ''}")
    ref, tc = render(scene, "CYCLES", os.path.join(
        d, f"cycles_{a.lights}_{w}_{a.cycles_spp}_{a.cycles_seed}{opts}.exr"), a)
    np.save(os.path.join(d, f"mask_{w}.npy"), mask)
    ref, ref_passes = ref
    lr = ref[mask]
    hi = lr > np.percentile(lr, 90)
    ratios = []
    base = list(a.set)
    for seed in (range(a.seeds) if a.seeds else [None]):
        if seed is not None:  # one Cycles render, ours at seeds 0 .. --seeds - 1
            a.set = base + [f"seed={seed}"]
        tag = f"lights={a.lights} res={w}x{h} spp={a.spp} cseed={a.cycles_seed} {a.set}"
        ours, to = render(scene, "PHOTONMAP", os.path.join(
            d, f"ours_{a.lights}_{w}_{a.spp}_{'_'.join(a.set)}{opts}.exr"), a)
        ours, ours_passes = ours
        lo = ours[mask]
        ratios.append(lo.sum() / lr.sum())
        print(f"VASE47 {tag}: vase {ratios[-1]:.4f}  bright10% "
              f"{lo[hi].sum() / lr[hi].sum():.4f}  rest {lo[~hi].sum() / lr[~hi].sum():.4f}"
              f"  px={mask.sum()} cyc_mean={lr.mean():.4g} cpu cycles={tc:.0f}s ours={to:.0f}s",
              flush=True)
        j, i = np.unravel_index(np.argmax(np.where(mask, ref, 0.0)), ref.shape)
        print(f"VASE47   Cycles' brightest vase pixel ({j}, {i}): ours / Cycles "
              f"{ours[j, i]:.4g} / {ref[j, i]:.4g}", flush=True)
        if ours_passes:  # ours' effects: the vase's sum and that pixel
            print("VASE47   ours' effects (vase sum, pixel): " + ", ".join(
                f"{k} {v[mask].sum():.4g} {v[j, i]:.4g}" for k, v in ours_passes.items()),
                flush=True)
    if len(ratios) > 1:
        r = np.array(ratios)
        print(f"VASE47 seeds 0-{len(r) - 1}: vase mean {r.mean():.4f} +- "
              f"{r.std(ddof=1) / np.sqrt(len(r)):.4f} (standard error)", flush=True)
    rows = np.nonzero(mask.any(axis=1))[0]
    for q in range(4):  # the vase's rows in quarters, top first
        m = mask.copy()
        lo_r = rows[0] + q * len(rows) // 4
        hi_r = rows[0] + (q + 1) * len(rows) // 4
        m[:lo_r] = m[hi_r:] = False
        print(f"VASE47 rows quarter {q}: {ours[m].sum() / ref[m].sum():.4f} "
              f"cyc_sum={ref[m].sum():.4g} px={m.sum()}", flush=True)


if __name__ == "__main__":
    main()
