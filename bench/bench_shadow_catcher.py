"""What a shadow catcher costs (engine/shadowcatcher.py): wall seconds of the same scene
with its floor an ordinary surface and a Shadow Catcher (the camera pass' split plus the
catcher-only photon and camera pass), and the catcher-only pass' own seconds.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_shadow_catcher.py [--size 320x240]
        [--spp 16] [--photons 200000] [--repeat 2]

The scene: tests/test_shadow_catcher.py's floor, red cube and sun, lit by the world too,
seen from above (the floor fills the image), a transparent film.

--viewport: what a viewport edit of another object costs the catchers-alone context
instead (engine/session.py keeps it when shadowcatcher.alone_key is unchanged): its build
(prepare_context) against the key, for the floor split into N x N quads.
"""
import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

from engine.jit import ensure_compiled  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402
from test_shadow_catcher import _scene  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(allow_abbrev=False)
    p.add_argument("--size", default="320x240")
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--photons", type=int, default=200_000)
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--viewport", action="store_true")
    a = p.parse_args(argv)
    if a.viewport:
        return viewport(a.repeat)
    w, h = (int(v) for v in a.size.split("x"))
    ensure_compiled()
    settings = RenderSettings(spp=a.spp, photons=a.photons, caustic_photons=0, seed=1,
                              film_transparent=True)
    print(f"{w}x{h}, {a.spp} spp, {a.photons:,} photons; best of {a.repeat}")
    print("| floor | total s | photon s | camera s | catcher-only pass s |")
    print("|---|---|---|---|---|")
    for catcher in (False, True):
        best = None
        for _ in range(a.repeat):
            scene = _scene(cube=True, world_light=True)
            scene.width, scene.height = w, h
            scene.meshes[0].shadow_catcher = catcher
            t0 = time.perf_counter()
            film = scene.render(settings)
            total = time.perf_counter() - t0
            st = film.stats
            row = (total, st.get("time_photons", float("nan")),
                   st.get("time_camera", float("nan")), st.get("time_shadow_catcher", 0.0))
            best = row if best is None or row[0] < best[0] else best
        name = "shadow catcher" if catcher else "ordinary"
        print(f"| {name} | {best[0]:.2f} | {best[1]:.2f} | {best[2]:.2f} | {best[3]:.2f} |")


def viewport(repeat):
    import numpy as np

    from engine import shadowcatcher
    from engine.render import prepare_context
    from engine.scene import Mesh
    ensure_compiled()
    settings = RenderSettings(spp=1, photons=20_000, caustic_photons=0, seed=1,
                              film_transparent=True)
    print(f"catchers-alone context per viewport edit, best of {repeat}")
    print("| catcher triangles | build ms | key ms |")
    print("|---|---|---|")
    for n in (1, 50, 200):
        scene = _scene(cube=True, world_light=True)
        if n > 1:  # the floor as n x n quads
            g = np.linspace(-3.0, 3.0, n + 1)
            x, y = np.meshgrid(g, g)
            v = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
            i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
            f = np.concatenate([np.stack([i, i + 1, i + n + 2], -1),
                                np.stack([i, i + n + 2, i + n + 1], -1)])
            scene.meshes[0] = Mesh(name="floor", vertices=v, faces=f,
                                   materials=scene.meshes[0].materials, shadow_catcher=True)
        build = key = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            ctx = prepare_context(shadowcatcher.alone_scene(scene),
                                  shadowcatcher.alone_settings(settings))
            build = min(build, time.perf_counter() - t0)
            ctx.accel.close()
            t0 = time.perf_counter()
            shadowcatcher.alone_key(scene, settings)
            key = min(key, time.perf_counter() - t0)
        print(f"| {len(scene.meshes[0].faces):,} | {1000 * build:.1f} | {1000 * key:.2f} |")


if __name__ == "__main__":
    main()
