"""What Cryptomatte's ID mattes cost (engine/cryptomatte.py): CPU seconds and ns a ray of
render_mattes on tests/test_cryptomatte.py's two-box scene, per size and layer count, one
thread.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_cryptomatte.py [--sizes 320x240,960x540]
        [--spp 16] [--levels 6]
"""
import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

from engine import cryptomatte as cm  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.render import prepare_context  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402
from test_cryptomatte import _scene  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(allow_abbrev=False)
    p.add_argument("--sizes", default="320x240,960x540")
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--levels", type=int, default=6)
    a = p.parse_args(argv)
    ensure_compiled()
    print("| size | layers | rays | CPU s | ns a ray |")
    print("|---|---:|---:|---:|---:|")
    for size in a.sizes.split(","):
        w, h = (int(v) for v in size.split("x"))
        scene = _scene()
        scene.width, scene.height = w, h
        ctx = prepare_context(scene, RenderSettings(spp=a.spp, photons=1000,
                                                    caustic_photons=0, workers=1))
        cm.render_mattes(ctx, (0, 0, 16, 16), ("object",), a.levels, a.spp, 1)  # warm
        for kinds in (("object",), ("object", "material", "asset")):
            t = time.process_time()
            cm.render_mattes(ctx, (0, 0, w, h), kinds, a.levels, a.spp, 1)
            cpu = time.process_time() - t
            rays = w * h * min(a.spp, cm.MAX_SAMPLES)
            print(f"| {w}x{h} | {len(kinds)} | {rays:,} | {cpu:.2f} | {1e9 * cpu / rays:.0f} |")
        ctx.accel.close()


if __name__ == "__main__":
    main()
