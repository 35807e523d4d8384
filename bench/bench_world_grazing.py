"""A grazing HDRI sun (issue 14): the per-sample relative variance of the world's shadow-ray
irradiance (directlight.sample_lights, no visibility) under the bright-sun map of
tests/test_environment_texelwarp.py (a 2-degree sun of 1200 at 40 degrees elevation), for
shading normals 0-92 degrees from the sun at six azimuths each; mean / quadrature checks
the bias. Where the sun grazes a normal's horizon but has set for its cluster centre's
(engine/lights/environment.py, SPREAD_SHARE) the variance showed the fireflies.

    .venv/bin/python bench/bench_world_grazing.py [--shares 0 0.05 0.1 0.15] [--n 100000]

(from the repository root; SPREAD_SHARE 0 is the table before the grazing-sun fix).
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from helpers import sphere_grid  # noqa: E402
from test_environment_cosine import _world_light_samples  # noqa: E402
from test_environment_texelwarp import sun_sky_map  # noqa: E402

from engine.lights import environment  # noqa: E402
from engine.sampling import luminance  # noqa: E402

ANGLES = (0, 45, 70, 80, 85, 88, 90, 92)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shares", type=float, nargs="+", default=[environment.SPREAD_SHARE])
    ap.add_argument("--n", type=int, default=100_000, help="shadow rays per normal")
    args = ap.parse_args()
    d, sin_t, cell = sphere_grid(1000, 2000)
    print("| SPREAD_SHARE | angle from sun | mean / quadrature | rel. variance max | median |")
    print("|---:|---:|---|---:|---:|")
    for share in args.shares:
        environment.SPREAD_SHARE = share   # read when the tables are built
        env = environment.Environment(sun_sky_map())
        L = luminance(env.radiance(d))
        sun = d[np.argmax(L)]
        a = np.cross(sun, [0, 0, 1.0])
        a /= np.linalg.norm(a)
        b = np.cross(sun, a)
        for ang in ANGLES:
            rows = []
            t = np.radians(ang)
            for az in np.linspace(0, 2 * np.pi, 7)[:-1]:
                n = np.cos(t) * sun + np.sin(t) * (np.cos(az) * a + np.sin(az) * b)
                n /= np.linalg.norm(n)
                row, contrib, _, _, _ = _world_light_samples(env, np.tile(n, (args.n, 1)),
                                                             n=args.n, seed=9)
                x = np.zeros(args.n)
                np.add.at(x, row, luminance(contrib))
                quad = float(np.sum(L * np.maximum(d @ n, 0) * sin_t) * cell)
                rows.append((x.mean() / quad, x.var() / x.mean() ** 2))
            r = np.array(rows)
            print(f"| {share:g} | {ang} | {r[:, 0].min():.3f}-{r[:, 0].max():.3f} | "
                  f"{r[:, 1].max():.3f} | {np.median(r[:, 1]):.3f} |", flush=True)


if __name__ == "__main__":
    main()
