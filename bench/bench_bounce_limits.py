"""Photon pass CPU time and stored photons with Cycles' default bounce limits (12 / 4 / 4 /
12) against limits no path reaches, in a closed Lambertian box (tests/test_energy.py's,
albedo 0.8: the photons' Russian roulette alone would give ~5 bounces on average).
Interleaved, best of 3 by thread CPU time (time.thread_time: one worker).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_bounce_limits.py [photons]

Mode `ab`: a whole render's CPU seconds (getrusage after jit.ensure_compiled, one worker,
16 spp) of two checkouts, each run in its own process, interleaved, best of REPS; the scenes
are pickles of exported blends ($TMPDIR/film_hashes/NAME.pkl, as tools/film_hashes.py
writes them); SETTINGS a JSON dict of RenderSettings (e.g. '{"glossy_bounces": 1}'):

    .venv/bin/python bench/bench_bounce_limits.py ab ROOT_A ROOT_B NAME[,NAME] REPS [WxH] [SETTINGS]
"""
import json
import os
import subprocess
import sys
import tempfile
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


_CHILD = r"""
import json, pickle, resource, sys
from engine.jit import ensure_compiled
from engine.render import render
from engine.settings import RenderSettings
ensure_compiled()
scene = pickle.load(open(sys.argv[1], "rb"))
scene.width, scene.height = map(int, sys.argv[2].split("x"))
r0 = resource.getrusage(resource.RUSAGE_SELF)
render(scene, RenderSettings(workers=1, spp=16, **json.loads(sys.argv[3])))
r1 = resource.getrusage(resource.RUSAGE_SELF)
print(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
"""


def ab(root_a, root_b, names, reps, size="160x120", settings="{}"):
    cpu = {}
    pickles = {name: os.path.join(tempfile.gettempdir(), "film_hashes", f"{name}.pkl")
               for name in names.split(",")}
    for name, path in pickles.items():
        if not os.path.isfile(path):
            sys.exit(f"{path} missing: run tools/film_hashes.py --blends {name} first")
    print(f"load before: {os.getloadavg()}")
    for _ in range(int(reps)):
        for name in names.split(","):
            for root in (root_a, root_b):
                out = subprocess.run([sys.executable, "-c", _CHILD, pickles[name], size, settings],
                                     capture_output=True, text=True, check=True,
                                     env=dict(os.environ, PYTHONPATH=root))
                cpu.setdefault((name, root), []).append(float(out.stdout.split()[-1]))
    print(f"load after: {os.getloadavg()}; {size}, 16 spp, 1 worker, settings {settings}")
    for name in names.split(","):
        a, b = min(cpu[(name, root_a)]), min(cpu[(name, root_b)])
        print(f"{name}: A {a:.2f} s, B {b:.2f} s, B/A {b / a:.3f} (best of {reps})")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "ab":
        ab(*sys.argv[2:])
    else:
        main()
