"""Sky Texture bake cost (engine/lights/sky.py): CPU seconds per sky type for the table,
the 1024 x 512 map, the sun disc's irradiance and the map's sampling distribution, best
of N runs (time.process_time: the machine is shared).

    python bench/bench_sky.py [--runs 2]
"""
import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine.lights import sky as sk  # noqa: E402


def _cpu(fn):
    t = time.process_time()
    out = fn()
    return time.process_time() - t, out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=2)
    args = p.parse_args()
    print(f"{'type':<22}{'table':>8}{'map':>8}{'disc':>8}{'distrib.':>10}{'total':>8}  (CPU s, "
          f"best of {args.runs})")
    for t in ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE"):
        best = None
        for _ in range(args.runs):
            sk._ms_transmittance_table.cache_clear()
            sky = sk.SkyTexture(sky_type=t, sun_elevation=math.radians(30.0),
                                sun_vector=(0.3, 0.5, 0.6))
            table = _cpu(lambda: sky.table)[0] if t not in sk.ANALYTIC_SKY_TYPES else 0.0
            bake, env = _cpu(sky.environment)
            disc = _cpu(sky.sun_irradiance)[0]
            dist = _cpu(lambda: env.distribution)[0]
            row = (table, bake - disc, disc, dist)  # environment() also sums the disc
            if best is None or sum(row) < sum(best):
                best = row
        print(f"{t:<22}" + "".join(f"{v:>8.2f}" for v in best[:3]) + f"{best[3]:>10.2f}"
              + f"{sum(best):>8.2f}")


if __name__ == "__main__":
    main()
