"""Cost of an environment map's radiance lookup, linear texels against an sRGB-stored
map (interpolated encoded, decoded after: three powers more a lookup; envcs33). CPU ns a
lookup over 1M random directions (Environment.radiance, one thread), a 1024 x 512 map.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_env_srgb_lookup.py
"""
import time

import numpy as np

from engine import Environment


def main(n=1_000_000, repeats=5):
    rng = np.random.default_rng(0)
    px = (rng.random((512, 1024, 3)) * 2.0).astype(np.float32)
    d = rng.normal(size=(n, 3))
    print("| map | interpolation | ns / lookup |")
    print("|---|---|---:|")
    for interp in ("Linear", "Closest"):
        for srgb in (False, True):
            env = Environment(px, interpolation=interp, srgb=srgb)
            env.radiance(d[:10])  # compiled before timing
            t = time.process_time()
            for _ in range(repeats):
                env.radiance(d)
            ns = (time.process_time() - t) / (repeats * n) * 1e9
            print(f"| {'sRGB-stored' if srgb else 'linear'} | {interp} | {ns:.0f} |")


if __name__ == "__main__":
    main()
