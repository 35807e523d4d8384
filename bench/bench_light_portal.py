"""The world's light through an open window with a Cycles light portal, on the camera
side (lightportal34, issue 14): a closed 4 x 4 x 2.6 m grey room (single-plane walls)
with a 1.2 x 1.0 m hole in one wall and a light portal in it, lit by a uniform world
(L = 1), a small HDRI (a sky with a sun-like patch) or an HDRI with a small sun seen
through the window from the floor (portalenv35), ours with the world's shadow rays
sampling the portal (modes below) and without (off: engine.lights.SHADOW_PORTALS = False,
as on trial34), optionally against Cycles (with the portal).

    .venv/bin/python bench/bench_light_portal.py [--spp 16] [--seeds 0,1]
        [--worlds uniform,hdri,sun] [--modes off,solid,on] [--cycles 1024]
        [--size 96x64] [--save DIR] [--load DIR] [--glossy]

Per case: floor / walls mean (combined), the Direct pass's mean, pixel std/mean and 8x8
block spread (std of the block means' difference between two seeds / sqrt 2 / mean) of
the combined image and of the Direct pass, the share of the combined pixel variance that
is the Direct pass's, CPU s per render. Regions come from the camera's rays against the
room's box (floor, walls; the window's pixels left out). Modes: off (no portal shadow
rays), solid (the portals sampled uniformly in solid angle, lightportal34), on (an
environment map sampled through the portals, portalenv35; a uniform world as solid).
Cycles: bench/cycles_scene.py's
scene plus an Area light with Portal on (the HDRI as a packed float image in an
Environment Texture).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

HALF, HEIGHT = 2.0, 2.6            # room half width, height (m)
WIN_Y, WIN_Z = (-0.6, 0.6), (0.8, 1.8)  # the hole in the wall x = +HALF (m)


def _rect(lo, hi, axis, at, flip=False):
    """A rectangle in the plane coordinate[axis] = at spanning lo..hi (2,) in the other two
    axes (in order), as (vertices (4,3), faces (2,3))."""
    a, b = [k for k in range(3) if k != axis]
    v = np.zeros((4, 3))
    for i, (x, y) in enumerate(((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]),
                                (lo[0], hi[1]))):
        v[i, axis], v[i, a], v[i, b] = at, x, y
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return v, (f[:, ::-1] if flip else f)


def hdri(H=32, W=64):
    """A small equirectangular sky: 0.6 above the horizon, 0.15 below, a 5x5-texel patch
    of 40 low in the sky (a soft sun)."""
    img = np.full((H, W, 3), 0.6, np.float32)
    img[:, :, 2] = 0.8
    img[H // 2:] = 0.15
    img[11:16, 20:25] = (40.0, 36.0, 30.0)
    return img


def sun_hdri(H=128, W=256, elevation=30.0, radius=1.5, L_sun=2000.0):
    """An equirectangular sky with a small sun (portalenv35): 0.6/0.8 blue-ish sky, 0.15
    ground, a disc of angular radius `radius` degrees and radiance L_sun at `elevation`
    degrees over the horizon towards +X (seen through the window from the floor), drawn
    by the texels' centres (2-3 texels across at 128 x 256)."""
    img = np.full((H, W, 3), 0.6, np.float32)
    img[:, :, 2] = 0.8
    img[H // 2:] = 0.15
    theta = math.pi * (np.arange(H) + 0.5) / H
    phi = 2.0 * math.pi * (0.5 - (np.arange(W) + 0.5) / W)
    st = np.sin(theta)[:, None]
    d = np.stack([st * np.cos(phi)[None], st * np.sin(phi)[None],
                  np.broadcast_to(np.cos(theta)[:, None], (H, W))], -1)
    e = math.radians(elevation)
    sun = np.array([math.cos(e), 0.0, math.sin(e)])
    disc = d @ sun > math.cos(math.radians(radius))
    img[disc] = (L_sun, 0.95 * L_sun, 0.85 * L_sun)
    return img


WORLD_MAPS = {"hdri": hdri, "sun": sun_hdri}
GLOSSY = False  # --glossy: the walls and floor Principled, specular 1, roughness 0.3


def room(world="uniform", width=96, height=64, portal=True):
    """The room (module docstring) as an engine Scene (GLOSSY: rough specular surfaces,
    whose glossy lobes take the world's samples by MIS with their continuation)."""
    from engine.scene import Camera, LightPortal, Material, Mesh, Scene
    from engine.lights.environment import Environment
    h, H = HALF, HEIGHT
    parts = {"Floor": _rect((-h, -h), (h, h), 2, 0.0),
             "Ceiling": _rect((-h, -h), (h, h), 2, H, True),
             "WallNeg": _rect((-h, 0.0), (h, H), 0, -h),
             "WallY0": _rect((-h, 0.0), (h, H), 1, -h),
             "WallY1": _rect((-h, 0.0), (h, H), 1, h, True),
             # the window wall round the hole
             "WinBelow": _rect((-h, 0.0), (h, WIN_Z[0]), 0, h, True),
             "WinAbove": _rect((-h, WIN_Z[1]), (h, H), 0, h, True),
             "WinLeft": _rect((-h, WIN_Z[0]), (WIN_Y[0], WIN_Z[1]), 0, h, True),
             "WinRight": _rect((WIN_Y[1], WIN_Z[0]), (h, WIN_Z[1]), 0, h, True)}
    meshes = [Mesh(n, v, f, materials=["Grey"]) for n, (v, f) in parts.items()]
    mats = {"Grey": Material("Grey", (0.6, 0.6, 0.6), **(
        dict(specular=1.0, roughness=0.3) if GLOSSY else {}))}
    # from inside near the back wall, looking down at the floor towards the window wall
    eye, at = np.array([-1.7, -0.3, 2.1]), np.array([1.0, 0.2, 0.2])
    back = eye - at
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    cam = Camera(position=eye, rotation=np.column_stack([right, up, back]),
                 fov=math.radians(80.0))
    s = Scene(meshes=meshes, materials=mats, lights=[], camera=cam, width=width,
              height=height, background=np.ones(3), background_is_light=True)
    if world in WORLD_MAPS:
        s.environment = Environment(WORLD_MAPS[world]())
    if portal:
        x = h
        s.portals.append(LightPortal("Portal", [(x, WIN_Y[0], WIN_Z[0]), (x, WIN_Y[1], WIN_Z[0]),
                                                (x, WIN_Y[1], WIN_Z[1]), (x, WIN_Y[0], WIN_Z[1])],
                                     (-1.0, 0.0, 0.0)))
    return s


def regions(scene):
    """(floor, walls) boolean (H, W) masks of the pixels whose camera ray's first surface
    is the floor / a wall or the ceiling (the window's pixels in neither)."""
    from engine.integrator import camera_rays
    W, H = scene.width, scene.height
    py, px = np.mgrid[0:H, 0:W]
    px, py = px.ravel().astype(np.float64), py.ravel().astype(np.float64)
    half = np.full(len(px), 0.5)
    o, d, _ = camera_rays(scene.camera, np.zeros(3), W, H, px, py, half, half)
    lo = np.array([-HALF, -HALF, 0.0])
    hi = np.array([HALF, HALF, HEIGHT])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (hi - o) / d, (lo - o) / d)
    t = np.where(np.isfinite(t) & (t > 0), t, np.inf)
    k = np.argmin(t, axis=1)
    y = o + np.min(t, axis=1)[:, None] * d
    floor = (k == 2) & (d[:, 2] < 0)
    window = ((k == 0) & (d[:, 0] > 0) & (y[:, 1] > WIN_Y[0]) & (y[:, 1] < WIN_Y[1])
              & (y[:, 2] > WIN_Z[0]) & (y[:, 2] < WIN_Z[1]))
    return floor.reshape(H, W), (~floor & ~window).reshape(H, W)


def render_ours(world, mode, seed, spp, size):
    """(combined (H,W,3), direct (H,W,3), CPU s) for mode "off" (no portal shadow
    rays), "solid" (the portals sampled uniformly in solid angle: lightportal34) or "on"
    (an environment map sampled through them: portalenv35)."""
    import engine.lights as el
    import engine.lights.world as wl
    from engine.render import render
    from engine.settings import RenderSettings
    el.SHADOW_PORTALS = mode != "off"
    wl.PORTAL_MAP_SAMPLING = mode == "on"
    scene = room(world, *size)
    c0 = time.process_time()
    film = render(scene, RenderSettings(spp=spp, seed=seed, workers=1))
    cpu = time.process_time() - c0
    passes = film.passes()
    return (film.combined[..., :3].astype(np.float64),
            passes["direct"][..., :3].astype(np.float64), cpu)


def _cycles_world(bpy, sc, pixels):
    """The world's node tree: Environment Texture of `pixels` (H,W,3) linear, row 0 the
    top (+Z; docs/lights.md orientation, as Cycles') -> Background of strength 1."""
    H, W = pixels.shape[:2]
    img = bpy.data.images.new("sky", W, H, float_buffer=True, alpha=True)
    img.colorspace_settings.name = "Linear Rec.709"
    rgba = np.ones((H, W, 4), np.float32)
    rgba[..., :3] = pixels[::-1]  # Blender's rows bottom-up
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    nt = sc.world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = img
    env.interpolation = "Linear"
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.0


def render_cycles(spp, size, seed=0, world="uniform"):
    """Cycles' combined image (H,W,3) of the room with its portal, CPU s."""
    import bpy
    import mathutils
    sys.path.insert(0, HERE)
    import cycles_scene
    scene = room("uniform", *size, portal=True)
    build = cycles_scene.build
    orig = cycles_scene.build

    def with_portal(sc_in):
        sc = orig(sc_in)
        if world in WORLD_MAPS:
            if sc.world.node_tree is None:
                sc.world.use_nodes = True
            _cycles_world(bpy, sc, WORLD_MAPS[world]())
        ld = bpy.data.lights.new("Portal", "AREA")
        ld.shape = "RECTANGLE"
        ld.size, ld.size_y = WIN_Y[1] - WIN_Y[0], WIN_Z[1] - WIN_Z[0]
        ld.cycles.is_portal = True
        ob = bpy.data.objects.new("Portal", ld)
        # local -Z (the portal's direction) into the room: -x; local X along y
        x_ax, z_ax = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])
        y_ax = np.cross(z_ax, x_ax)
        M = np.eye(4)
        M[:3, 0], M[:3, 1], M[:3, 2] = x_ax, y_ax, z_ax
        M[:3, 3] = (HALF, 0.5 * sum(WIN_Y), 0.5 * sum(WIN_Z))
        ob.matrix_world = mathutils.Matrix(M.tolist())
        sc.collection.objects.link(ob)
        return sc

    cycles_scene.build = with_portal
    try:
        c0 = time.process_time()
        img, _ = cycles_scene.render(scene, spp, seed)
        cpu = time.process_time() - c0
    finally:
        cycles_scene.build = build
    return np.asarray(img, np.float64)[..., :3], cpu


def sample_cost(world, mode, n=200_000, repeat=5):
    """ns per world shadow-ray sample of directlight.sample_lights (the best of `repeat`
    calls) at n points on the room's floor (a grid over it, normal up) for mode as
    render_ours', and the seconds the portal tables took to build (0 without)."""
    import engine.lights as el
    import engine.lights.world as wl
    from engine.bsdf import surface_hit
    from engine.directlight import DirectLightBuffers, sample_lights
    from engine.integrator import NO_HROWS, NO_ROWS3, _hit_arrays
    from engine.lights.packing import pack_lights
    from engine.lights.selection import empty_tree
    from engine.render import prepare_context
    from engine.settings import RenderSettings
    el.SHADOW_PORTALS = mode != "off"
    wl.PORTAL_MAP_SAMPLING = mode == "on"
    ctx = prepare_context(room(world, 16, 16), RenderSettings(workers=1,
                                                              photon_mapping=False))
    li = next(i for i, x in enumerate(ctx.lights) if x.kind == "WORLD")
    light = ctx.lights[li]
    build = 0.0
    if light.portal_tables is not None:
        from engine.lights.portalmap import build_portal_tables
        t0 = time.perf_counter()
        build_portal_tables(light.environment, light.portal_rects)
        build = time.perf_counter() - t0
    side = int(math.sqrt(n))
    g = (np.arange(side) + 0.5) / side * (2 * HALF - 0.2) - (HALF - 0.1)
    X, Y = np.meshgrid(g, g)
    o = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, 0.5)]) - ctx.geo.offset
    down = np.tile([0.0, 0.0, -1.0], (len(o), 1))
    _, prim, u, v = ctx.accel.intersect(o, down)
    hit = surface_hit(ctx.geo, ctx.table, prim, u, v, down)
    m = len(hit.p)
    rng = np.random.default_rng(1)
    u1, u2, sel = rng.random((3, 1, m))
    buf = DirectLightBuffers().ensure(m)
    codes, params, mesh = pack_lights(ctx.lights)
    arrays = _hit_arrays(ctx.geo, hit)
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        sample_lights(*arrays, codes, params, *mesh, *empty_tree(),
                      np.ones(len(codes), np.bool_), np.array([li], np.int64),
                      np.ones(1, np.bool_), u1, u2, sel, buf.contrib, buf.row, buf.kidx,
                      buf.ray, buf.o32, buf.d32, buf.t32, buf.wdir, buf.lpdf, buf.bump,
                      NO_HROWS, NO_ROWS3)
        best = min(best, time.perf_counter() - t0)
    return best / m * 1e9, build


def table_build_seconds(rows):
    """Seconds to build one portal's table (lights/portalmap.py) under a rows x 2 rows
    map (bench's sun_hdri resampled), and the table's side N."""
    from engine.lights.environment import Environment
    from engine.lights.portalmap import build_portal_tables, table_size
    env = Environment(sun_hdri(rows, 2 * rows))
    rect = np.array([[[HALF, WIN_Y[0], WIN_Z[0]], [0.0, WIN_Y[1] - WIN_Y[0], 0.0],
                      [0.0, 0.0, WIN_Z[1] - WIN_Z[0]], [-1.0, 0.0, 0.0]]])
    build_portal_tables(Environment(sun_hdri(8, 16)), rect)  # (compiled or loaded)
    t0 = time.perf_counter()
    build_portal_tables(env, rect)
    return time.perf_counter() - t0, table_size(rows)[0]


def noise(a, b, mask, block=8):
    """(pixel std/mean, 8x8 block std/mean) of two seeds' images over mask (luminance)."""
    la, lb = a.mean(axis=2), b.mean(axis=2)
    m = 0.5 * (la + lb)[mask].mean()
    px = np.std((la - lb)[mask]) / math.sqrt(2) / m
    H, W = la.shape
    H8, W8 = H // block * block, W // block * block
    da = (la - lb)[:H8, :W8].reshape(H8 // block, block, W8 // block, block)
    mk = mask[:H8, :W8].reshape(H8 // block, block, W8 // block, block)
    full = mk.all(axis=(1, 3))
    blk = da.mean(axis=(1, 3))[full]
    return px, (np.std(blk) / math.sqrt(2) / m if len(blk) > 1 else float("nan"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--worlds", default="uniform,hdri")
    ap.add_argument("--modes", default="off,solid,on",
                    help="off: no portal shadow rays; solid: uniform in the portals' solid "
                    "angle (lightportal34); on: by the map through them (portalenv35)")
    ap.add_argument("--cycles", type=int, default=0, help="Cycles spp (0: none)")
    ap.add_argument("--size", default="96x64")
    ap.add_argument("--save", default=None)
    ap.add_argument("--load", default=None, help="a --save DIR: its Cycles images (same "
                    "--cycles and --size) instead of rendering them again")
    ap.add_argument("--glossy", action="store_true", help="rough specular surfaces")
    ap.add_argument("--cost", action="store_true", help="only the world shadow rays' "
                    "ns per sample by mode and world, and the portal table's build time "
                    "by map size")
    args = ap.parse_args(argv)
    global GLOSSY
    GLOSSY = args.glossy
    size = tuple(int(x) for x in args.size.split("x"))
    seeds = [int(x) for x in args.seeds.split(",")]
    from engine import jit
    jit.ensure_compiled()
    if args.cost:
        print("world    mode  ns/sample  table build s")
        for world in args.worlds.split(","):
            for mode in args.modes.split(","):
                ns, build = sample_cost(world, mode)
                print(f"{world:8s} {mode:5s} {ns:9.1f}  {build:.3f}")
        print("map rows  table N  build s (one portal)")
        for rows in (32, 128, 512, 1024, 2048):
            sec, n = table_build_seconds(rows)
            print(f"{rows:8d} {n:8d}  {sec:.3f}")
        return
    floor, walls = regions(room("uniform", *size))
    print(f"{size[0]}x{size[1]}, {args.spp} spp, seeds {seeds}; floor {floor.sum()} px, "
          f"walls {walls.sum()} px")
    refs = {}
    for world in args.worlds.split(",") if args.cycles else ():
        saved = args.load and os.path.join(args.load, f"cycles_{world}_{args.cycles}.npy")
        if saved and os.path.exists(saved):
            ref, ccpu = np.load(saved), float("nan")
        else:
            ref, ccpu = render_cycles(args.cycles, size, world=world)
        refs[world] = ref
        print(f"Cycles {args.cycles} spp (portal), {world}: floor {ref[floor].mean():.4f} "
              f"walls {ref[walls].mean():.4f}  CPU {ccpu:.1f} s")
        if args.save:
            os.makedirs(args.save, exist_ok=True)
            np.save(os.path.join(args.save, f"cycles_{world}_{args.cycles}.npy"), ref)
    print("world    mode floor   walls   /Cyc.fl /Cyc.wa direct  px-noise blk-noise "
          "dir.px  dir.blk  var.dir  CPU s")
    for world in args.worlds.split(","):
        for mode in args.modes.split(","):
            imgs = [render_ours(world, mode, s, args.spp, size) for s in seeds]
            a, b = imgs[0][0], imgs[1][0] if len(imgs) > 1 else imgs[0][0]
            da, db = imgs[0][1], imgs[1][1] if len(imgs) > 1 else imgs[0][1]
            mean = 0.5 * (a + b)
            room_px = floor | walls
            px, blk = noise(a, b, room_px)
            dpx, dblk = noise(da, db, room_px)
            # share of the combined pixel variance that is the Direct pass's
            vc = np.var((a - b).mean(axis=2)[room_px])
            vd = np.var((da - db).mean(axis=2)[room_px])
            cpu = np.mean([x[2] for x in imgs])
            rf = rw = float("nan")
            ref = refs.get(world)
            if ref is not None:
                rf = mean[floor].mean() / ref[floor].mean()
                rw = mean[walls].mean() / ref[walls].mean()
            print(f"{world:8s} {mode:4s} {mean[floor].mean():.4f}  {mean[walls].mean():.4f}  "
                  f"{rf:.4f}  {rw:.4f}  {0.5 * (da + db)[room_px].mean():.4f}  "
                  f"{px:.4f}   {blk:.4f}    {dpx:.4f}  {dblk:.4f}  {vd / vc:.3f}    "
                  f"{cpu:.1f}")
            if args.save:
                os.makedirs(args.save, exist_ok=True)
                for s, (c, d, _) in zip(seeds, imgs):
                    np.save(os.path.join(args.save, f"{world}_{mode}_s{s}.npy"), c)


if __name__ == "__main__":
    main()
