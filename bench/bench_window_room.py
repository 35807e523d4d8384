"""A room lit by the sun through a glass window (issues 13 / 14, new-user trial s15 case
d_window): rays per stage and depth, CPU seconds and peak RSS, against the same room lit
by an area light without the window (case a_plain), optionally before / after a revision.

    .venv/bin/python bench/bench_window_room.py [--width 160] [--height 120] [--spp 128]
        [--workers 2] [--cases d_window,a_plain] [--base REV] [--repeat 1]
        [--seed 0] [--save DIR]

Case o_open is d_window with the window open (no glass slab): Cycles can render it, so
it is the room to check an estimate against (docs/performance.md, "backside"). --save DIR
keeps each render's image (DIR/TAG_CASE_sSEED.npy, (H, W, 3) float32) for comparisons.

Each (checkout, case) renders in a fresh child process (its VmHWM is the render's peak,
engine/resources.estimate_memory's prediction beside it), this checkout's first and --base
REV's (extracted with git archive into a temporary folder) after; interleaved, best CPU
time of --repeat. The scenes are built here with the engine's own classes (the trial's
bpy scene exported, same numbers), so no Blender is needed. Set NUMBA_CACHE_DIR to a
folder of your own: a base checkout compiles its kernels once (minutes).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def _rect(c, u, v):
    """Vertices (4,3) and faces of the rectangle c + s u + t v, s, t in [-1, 1]: a
    Blender plane of size 1 scaled and rotated, its normal u x v."""
    c, u, v = (np.asarray(a, np.float64) for a in (c, u, v))
    verts = np.array([c - u - v, c + u - v, c - u + v, c + u + v])
    return verts, np.array([[0, 1, 3], [0, 3, 2]])


def _box(lo, hi, yaw=0.0):
    """A box [lo, hi] (rotated by yaw about z round its centre), Blender's cube faces."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    c = 0.5 * (lo + hi)
    cs, sn = math.cos(yaw), math.sin(yaw)
    r = corners - c
    corners = c + np.column_stack([cs * r[:, 0] - sn * r[:, 1], sn * r[:, 0] + cs * r[:, 1],
                                   r[:, 2]])
    faces = np.array([[0, 1, 3], [0, 3, 2], [2, 3, 7], [2, 7, 6], [6, 7, 5], [6, 5, 4],
                      [4, 5, 1], [4, 1, 0], [2, 6, 4], [2, 4, 0], [7, 3, 1], [7, 1, 5]])
    return corners, faces


def room_scene(window: bool = True, width: int = 160, height: int = 120,
               glass: bool = True):
    """The trial's 4 x 4 x 3 m room of Principled-default walls (planes, one-sided
    geometry seen from both sides) with a red box. window=True (d_window): the right wall
    has a 1 x 1 m window closed by a 2 cm Glass BSDF slab (IOR 1.5, roughness 0), a sun
    (strength 5, angle 1 degree) shines in, the world is (0.05, 0.07, 0.1); False
    (a_plain): the right wall is whole, a 1 m square area light of 200 W hangs under the
    ceiling, the world is black. glass=False (o_open): the window has no slab."""
    from engine.scene import Camera, Light, Material, Mesh, Scene
    L, W, H = 4.0, 4.0, 3.0
    default = Material("Default", (0.8, 0.8, 0.8), roughness=0.5, specular=1.0)
    box_mat = Material("BoxMat", (0.8, 0.2, 0.1), roughness=0.5, specular=1.0)
    mats = {"Default": default, "BoxMat": box_mat}
    planes = [("Floor", (0, 0, 0), (W / 2, 0, 0), (0, L / 2, 0)),
              ("Ceiling", (0, 0, H), (W / 2, 0, 0), (0, -L / 2, 0)),
              ("BackWall", (0, L / 2, H / 2), (W / 2, 0, 0), (0, 0, H / 2)),
              ("FrontWall", (0, -L / 2, H / 2), (W / 2, 0, 0), (0, 0, -H / 2)),
              ("LeftWall", (-W / 2, 0, H / 2), (0, 0, -H / 2), (0, L / 2, 0))]
    x = W / 2
    if window:
        planes += [("WallBelow", (x, 0, 0.5), (0, 0, 0.5), (0, L / 2, 0)),
                   ("WallAbove", (x, 0, 2.5), (0, 0, 0.5), (0, L / 2, 0)),
                   ("WallFront", (x, -1.25, 1.5), (0, 0, 0.5), (0, 0.75, 0)),
                   ("WallBack", (x, 1.25, 1.5), (0, 0, 0.5), (0, 0.75, 0))]
    else:
        planes.append(("RightWall", (x, 0, H / 2), (0, 0, H / 2), (0, L / 2, 0)))
    meshes = [Mesh(name, *_rect(c, u, v), materials=["Default"]) for name, c, u, v in planes]
    meshes.append(Mesh("Box", *_box((0.5, 0.5, 0.0), (1.1, 1.1, 0.8), 0.4),
                       materials=["BoxMat"]))
    if window and glass:
        mats["Glass"] = Material("Glass", (1, 1, 1), roughness=0.0, transmission=1.0,
                                 ior=1.5, specular=1.0, node="glass")
        meshes.append(Mesh("WindowSlab", *_box((x - 0.01, -0.5, 1.0), (x + 0.01, 0.5, 2.0)),
                           materials=["Glass"]))
    if window:
        sun_dir = np.array([0.0, 0.0, 0.0]) - np.array([6.0, 0.5, 5.0])
        lights = [Light("Sun", "SUN", power=5.0, position=np.array([6.0, 0.5, 5.0]),
                        direction=sun_dir / np.linalg.norm(sun_dir),
                        angle=math.radians(1.0), visible_camera=False)]
        background = (0.05, 0.07, 0.1)
    else:
        lights = [Light("Area", "AREA", power=200.0, position=np.array([0.0, 0.0, H - 0.05]),
                        direction=np.array([0.0, 0.0, -1.0]), size_x=1.0, size_y=1.0,
                        visible_camera=False)]
        background = (0.0, 0.0, 0.0)
    # The trial's camera: at (0.3, -1.9, 1.6) looking at (-0.1, 0.5, 1.0), 18 mm lens.
    eye, at = np.array([0.3, -1.9, 1.6]), np.array([-0.1, 0.5, 1.0])
    back = eye - at
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    cam = Camera(position=eye, rotation=np.column_stack([right, up, back]),
                 fov=2 * math.atan(36.0 / 2 / 18.0), clip_start=0.1, clip_end=1000.0)
    return Scene(meshes=meshes, materials=mats, lights=lights, camera=cam, width=width,
                 height=height, background=np.array(background, np.float64),
                 background_is_light=True)


CASES = {"d_window": (True, True), "a_plain": (False, True), "o_open": (True, False)}


def child(case, width, height, spp, workers, photons, seed=0, save=None):
    """Render one case in this process (the checkout on sys.path[0]); print one JSON line."""
    import time
    sys.path.insert(0, os.getcwd())
    from engine import jit
    from engine.render import render
    from engine.settings import RenderSettings
    jit.ensure_compiled()
    sys.path.insert(0, HERE)
    from procmem import hwm
    window, glass = CASES[case]
    scene = room_scene(window, width, height, glass=glass)
    kw = dict(workers=workers, spp=spp, seed=seed)
    if photons:
        kw["photons"] = photons
    settings = RenderSettings(**kw)
    estimate = None
    try:
        from engine.resources import estimate_memory
        estimate = estimate_memory(scene, settings)
        estimate = getattr(estimate, "total", estimate)
    except Exception:  # noqa: BLE001 (an older checkout: no estimate)
        estimate = None
    # The peak of the render itself (writing 5 to clear_refs resets VmHWM).
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    base_rss = hwm()
    c0, t0 = time.process_time(), time.perf_counter()
    film = render(scene, settings)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    st = film.stats
    out = {k: st.get(k) for k in ("camera_rays", "shadow_rays", "gather_rays",
                                  "specular_rays", "time_camera", "time_photons",
                                  "time_photon_map", "global_photons", "gather_rays_used",
                                  "ray_stages")}
    img = film.combined[..., :3].astype(np.float64)
    if save:
        np.save(save, img.astype(np.float32))
    out.update(cpu=cpu, wall=wall, peak=hwm(), start_rss=base_rss,
               estimate=None if estimate is None else float(estimate),
               mean=float(img.mean()), engine=os.path.dirname(jit.__file__))
    print("RESULT " + json.dumps(out, default=float))


def run(root, case, args, tag="this"):
    env = dict(os.environ)
    cmd = [sys.executable, os.path.abspath(__file__), "--child", case, "--width",
           str(args.width), "--height", str(args.height), "--spp", str(args.spp),
           "--workers", str(args.workers), "--photons", str(args.photons),
           "--seed", str(args.seed)]
    if args.save:
        os.makedirs(args.save, exist_ok=True)
        cmd += ["--save", os.path.join(os.path.abspath(args.save),
                                       f"{tag}_{case}_s{args.seed}.npy")]
    p = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True)
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(f"{root} {case}: {p.stderr[-2000:]}")


def checkout(rev):
    dest = tempfile.mkdtemp(prefix=f"window_room_{rev[:8]}_")
    data = subprocess.run(["git", "-C", ROOT, "archive", rev], check=True,
                          capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", dest], input=data, check=True)
    return dest


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--photons", type=int, default=0, help="0: the default")
    ap.add_argument("--cases", default="d_window,a_plain")
    ap.add_argument("--base", default=None, help="a revision to compare with (git archive)")
    ap.add_argument("--base-root", default=None,
                    help="an extracted checkout to compare with (its kernels compiled)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--save", default=None, help="a folder to keep the images in")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.width, args.height, args.spp, args.workers, args.photons,
              args.seed, args.save)
        return
    roots = [("this", ROOT)]
    if args.base:
        roots.append((args.base, checkout(args.base)))
    elif args.base_root:
        roots.append(("base", os.path.abspath(args.base_root)))
    cases = args.cases.split(",")
    results = {}
    for _ in range(args.repeat):
        for case in cases:
            for tag, root in roots:
                r = run(root, case, args, tag)
                best = results.get((tag, case))
                if best is None or r["cpu"] < best["cpu"]:
                    results[(tag, case)] = r
    load = open("/proc/loadavg").read().split()[:3]
    print(f"{args.width}x{args.height}, {args.spp} spp, {args.workers} worker(s); "
          f"load {' '.join(load)}; best CPU of {args.repeat}")
    head = (f"{'checkout':>10} {'case':>9} {'CPU s':>7} {'wall s':>7} {'camera s':>8} "
            f"{'shadow M':>8} {'gather M':>8} {'spec M':>7} {'peak MB':>8} {'est MB':>7} "
            f"{'mean':>7}")
    print(head)
    for (tag, case), r in results.items():
        est = r["estimate"]
        print(f"{tag[:10]:>10} {case:>9} {r['cpu']:7.1f} {r['wall']:7.1f} "
              f"{r['time_camera']:8.1f} {r['shadow_rays'] / 1e6:8.2f} "
              f"{r['gather_rays'] / 1e6:8.2f} {r['specular_rays'] / 1e6:7.2f} "
              f"{r['peak'] / 2**20:8.0f} {'-' if est is None else f'{est / 2**20:7.0f}':>7} "
              f"{r['mean']:7.4f}")
    print("\nrays per stage and depth (M): stage depth -> count")
    for (tag, case), r in results.items():
        stages = r.get("ray_stages") or {}
        if stages:
            print(f"  {tag} {case}: " + ", ".join(f"{k} {v / 1e6:.3f}"
                                                 for k, v in stages.items()))


if __name__ == "__main__":
    main()
