"""What a shadow catcher costs (engine/shadowcatcher.py): wall seconds of the same scene
with its floor an ordinary surface and a Shadow Catcher (the camera pass' split plus the
catcher-only photon and camera pass), and the catcher-only pass' own seconds.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_shadow_catcher.py [--size 320x240]
        [--spp 16] [--photons 200000] [--repeat 2]

The scene: tests/test_shadow_catcher.py's floor, red cube and sun, lit by the world too,
seen from above (the floor fills the image), a transparent film.
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
    a = p.parse_args(argv)
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


if __name__ == "__main__":
    main()
