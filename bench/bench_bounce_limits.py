"""Photon pass CPU time and stored photons with Cycles' default bounce limits (12 / 4 / 4 /
12) against limits no path reaches, in a closed Lambertian box (tests/test_energy.py's,
albedo 0.8: the photons' Russian roulette alone would give ~5 bounces on average).
Interleaved, best of 3 by thread CPU time (time.thread_time: one worker).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_bounce_limits.py [photons]
"""
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "tests"))

from engine import RenderSettings  # noqa: E402
from test_energy import closed_box, shoot  # noqa: E402

HIGH = dict(max_bounces=1024, diffuse_bounces=1024, glossy_bounces=1024,
            transmission_bounces=1024)


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 400_000
    scene = closed_box(0.8)
    cases = {"cycles defaults": {}, "no limit": HIGH}
    best = {k: float("inf") for k in cases}
    stored = {}
    shoot(scene, RenderSettings(photons=1000, workers=1))  # warm
    for _ in range(3):
        for name, kw in cases.items():
            t = time.thread_time()
            ph = shoot(scene, RenderSettings(photons=n, workers=1, **kw))
            best[name] = min(best[name], time.thread_time() - t)
            stored[name] = (len(ph), ph.nbytes)
    print(f"closed box, albedo 0.8, {n:,} photons, 1 worker; load: {os.getloadavg()[0]:.1f}")
    print(f"{'limits':<18}{'CPU s (best of 3)':>18}{'stored':>12}{'bytes/photon':>14}")
    for name in cases:
        k, b = stored[name]
        print(f"{name:<18}{best[name]:>18.3f}{k:>12,}{b / max(k, 1):>14.1f}")


if __name__ == "__main__":
    main()
