"""A lamp in a single-surface rough glass shade (issue 14, roughshade33): how y is chosen
and which roughnesses engine/shadelight.py serves. Scene: tests/test_rough_glass_shade_light.py's
(a 100 W point lamp in an open 16-sided glass tube, Principled Transmission 1, IOR 1.5,
over a grey floor).

Table 1, the choice of y (per shading point, 40,000 samples, seed 11): the estimator's
mean / the grid integral, per-sample std / mean and max / mean at three points, for the
lamp-side choice alone (GLASS_PEAK_SHARE 0) and mixtures with the lobe about the
refracted peak (share, width k = GLASS_PEAK_WIDTH: the lamp has radius 0, so the lobe is
GGX's distribution of slope 0.5 k alpha).

Table 2, the roughness range: the floor beside the tube (x = 1.3 .. 2.7 m), 64 spp seed 1,
the estimator on (GLASS_ROUGH_MIN lowered to serve every roughness) and off (caustic
photons, as main), against a converged render of the estimator on (1024 spp, 10x the
photons, seed 7): image / reference mean, pixel std / mean and 8 x 8 blocks' max / min,
CPU seconds of the render.

Table 3, points around bench/bench_lamp_room.py's shade (a 32-sided smooth open
cylinder, radius 0.22 m, 0.35 m tall, roughness 0.5, the lamp at its centre, radius 0 and
0.05 m; 100,000 samples, seed 3): mean irradiance, std / mean, max / mean for a
Translucent shade and for the glass with the lamp-side choice alone, the peaked lobe
without its start from the nearest glass triangle (GLASS_START_POINTS 0: points above
and below the shade, whose ray from the lamp leaves through an opening, get no peak),
with one point on the lamp per y (GLASS_LAMP_SAMPLES 1), and as served.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_glass_shade.py [--rough 0.1,0.2,0.3,0.5,1]
        [--skip-y] [--skip-floor] [--skip-room]
"""
import argparse
import math
import os
import resource
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

POINTS = (((0.6, 0.2, 0.0), (0, 0, 1)), ((1.5, -0.3, 0.0), (0, 0, 1)),
          ((0.8, 0.0, 1.3), (-1, 0, 0.2)))


def cpu():
    """CPU seconds of this process's threads and its finished children."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def y_choice(rough, m=40_000):
    from engine import shadelight
    import test_rough_glass_shade_light as T
    ctx = T._context(rough)
    shades = shadelight.find_shades(ctx.geo, ctx.table, ctx.lights)
    want = [T._integral(ctx.table, np.array(x, float), np.array(n, float) / np.linalg.norm(n))[1]
            for x, n in POINTS]
    old = shadelight.GLASS_PEAK_SHARE, shadelight.GLASS_PEAK_WIDTH
    try:
        for share, width in ((0.0, 1.0), (0.5, 1.0), (0.75, 1.0), (0.9, 0.7), (0.9, 1.0),
                             (0.9, 1.4)):
            shadelight.GLASS_PEAK_SHARE, shadelight.GLASS_PEAK_WIDTH = share, width
            cells = []
            for (x, n), wv in zip(POINTS, want):
                e = _irradiance_samples(ctx, shades, x, n, m, 11)
                cells.append(f"{e.mean() / wv:.3f} / {e.std() / e.mean():.2f} / "
                             f"{e.max() / e.mean():.0f}")
            print(f"| {rough} | {share} | {width} | " + " | ".join(cells) + " |", flush=True)
    finally:
        shadelight.GLASS_PEAK_SHARE, shadelight.GLASS_PEAK_WIDTH = old


def floor(rough):
    from engine import RenderSettings, shadelight
    import test_rough_glass_shade_light as T
    old = shadelight.ENABLED, shadelight.GLASS_ROUGH_MIN
    shadelight.GLASS_ROUGH_MIN = min(rough, old[1])
    imgs, secs = {}, {}
    try:
        for key, on, kw in (("ref", True, dict(spp=1024, photons=4_000_000,
                                               caustic_photons=2_000_000, seed=7)),
                            ("on", True, {}), ("off", False, {})):
            shadelight.ENABLED = on
            c0 = cpu()
            film = T._scene(rough, cx=T.FAR).render(
                RenderSettings(**{"spp": 64, "seed": 1, **kw}))
            secs[key] = cpu() - c0
            imgs[key] = film.combined.reshape(T.W, T.W, 3)[..., 1]
    finally:
        shadelight.ENABLED, shadelight.GLASS_ROUGH_MIN = old
    for key in ("on", "off"):
        r = imgs[key] / imgs["ref"]
        noise, spread = T._ratio_stats(r)
        print(f"| {rough} | {key} | {imgs[key].mean() / imgs['ref'].mean():.4f} | "
              f"{noise:.3f} | {spread:.3f} | {secs[key]:.1f} |", flush=True)


ROOM_POINTS = (((1.5, 2.0, 1.5), (0, -1, 0)), ((1.5, 2.0, 2.4), (0, -1, 0)),
               ((2.5, 1.0, 1.0), (-1, 0, 0)), ((0.5, 0.0, 0.0), (0, 0, 1)),
               ((0.2, 1.0, 1.5), (1, 0, 0)))


def room_shade(kind, radius):
    """(Context, Shades) of the lamp room's shade alone over a floor."""
    from engine import RenderSettings, shadelight
    from engine.accel import Accel
    from engine.api import PaperScene
    from engine.geometry import prepare
    from engine.lights import prepare_lights
    from engine.render import Context
    from engine.scene import Material
    from engine.visibility import VisibilityAccel
    sides, r, depth, c = 32, 0.22, 0.35, np.array([1.5, 1.4, 1.5])
    a = 2 * math.pi * np.arange(sides) / sides
    ring = np.stack([r * np.cos(a), r * np.sin(a), np.zeros(sides)], 1)
    v = np.concatenate([c + ring - [0, 0, depth / 2], c + ring + [0, 0, depth / 2]])
    f = [(i, (i + 1) % sides, sides + (i + 1) % sides) for i in range(sides)]
    f += [(i, sides + (i + 1) % sides, sides + i) for i in range(sides)]
    s = PaperScene(width=8, height=8)
    if kind == "glass":
        s.add_material(Material("shade", (0.95, 0.85, 0.7), roughness=0.5, transmission=1.0))
    else:
        s.add_material(Material("shade", (0.95, 0.85, 0.7), translucent=1.0))
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30, "grey", name="floor")
    s.add_triangles(v, np.asarray(f), "shade", name="shade",
                    normals=np.concatenate([ring / r, ring / r]))
    s.add_point_light(tuple(c), power=100, radius=radius)
    s.set_camera((0, -3, 1.5), tuple(c), up=(0, 0, 1), view_angle=40)
    s.validate()
    geo, table = prepare(s)
    accel = VisibilityAccel(geo.vertices32, geo.faces32, geo.visibility, Accel, threads=1)
    lights = prepare_lights(s, geo, table)
    ctx = Context(s, RenderSettings(photons=1000, seed=3), geo, table, accel, lights)
    return ctx, shadelight.find_shades(geo, table, lights)


def room(m=100_000):
    from engine import shadelight
    old = (shadelight.GLASS_PEAK_SHARE, shadelight.GLASS_START_POINTS,
           shadelight.GLASS_LAMP_SAMPLES)
    try:
        for label, kind, share, starts, k in (
                ("translucent", "translucent", old[0], old[1], old[2]),
                ("glass, lamp side alone", "glass", 0.0, old[1], old[2]),
                ("glass, no nearest-triangle start", "glass", old[0], 0, old[2]),
                ("glass, one point on the lamp per y", "glass", old[0], old[1], 1),
                ("glass, as served", "glass", old[0], old[1], old[2])):
            (shadelight.GLASS_PEAK_SHARE, shadelight.GLASS_START_POINTS,
             shadelight.GLASS_LAMP_SAMPLES) = share, starts, k
            for radius in (0.0, 0.05):
                ctx, shades = room_shade(kind, radius)
                cells = []
                for x, n in ROOM_POINTS:
                    e = _irradiance_samples(ctx, shades, x, n, m, 3)
                    cells.append(f"{e.mean():.3g} / {e.std() / e.mean():.1f} / "
                                 f"{e.max() / e.mean():.0f}")
                print(f"| {label} | {radius} | " + " | ".join(cells) + " |", flush=True)
    finally:
        (shadelight.GLASS_PEAK_SHARE, shadelight.GLASS_START_POINTS,
         shadelight.GLASS_LAMP_SAMPLES) = old


def _irradiance_samples(ctx, shades, x, n, m, seed):
    """(m,) green-channel shade irradiance samples at point x (world space) with normal n
    (normalised here), one light sample each (shadelight.shade_irradiance)."""
    from engine import shadelight
    rng = np.random.default_rng(seed)
    N = np.array(n, float) / np.linalg.norm(n)
    p = np.tile(np.array(x, float) - ctx.geo.offset, (m, 1))
    ns = np.tile(N, (m, 1))
    u1, u2 = rng.random((2, m))
    return shadelight.shade_irradiance(ctx, shades, p, ns, ns.copy(), np.full(m, 1e-6),
                                       [(0, True, 1, u1, u2, None)], rng)[0][:, 1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rough", default="0.1,0.2,0.3,0.5,1")
    ap.add_argument("--skip-y", action="store_true")
    ap.add_argument("--skip-floor", action="store_true")
    ap.add_argument("--skip-room", action="store_true")
    a = ap.parse_args()
    roughs = [float(x) for x in a.rough.split(",") if x]
    if not a.skip_y:
        print("| roughness | peak share | width k | mean / integral, std / mean, max / mean "
              "at 3 points | | |")
        print("|---|---|---|---|---|---|")
        for r in roughs:
            if r >= 0.3 - 1e-9:
                y_choice(r)
    if not a.skip_floor:
        print("\n| roughness | estimator | mean / ref | pixel std / mean | blocks max / min "
              "| CPU s |")
        print("|---|---|---|---|---|---|")
        for r in roughs:
            floor(r)
    if not a.skip_room:
        print("\n| shade | lamp radius | " + " | ".join(
            f"{x} n {n}" for x, n in ROOM_POINTS) + " |")
        print("|---" * (2 + len(ROOM_POINTS)) + "|")
        room()


if __name__ == "__main__":
    main()
