"""Russian roulette on the regathers (integrator.REGATHER_SURVIVAL): error and CPU per
survival setting on the accuracy scenes, in one process, against the stored Cycles
references (tests/references/). Prints a table.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_regather_survival.py \
        [--scenes figure6_box,principled_spheres] [--settings 1:1,1:0.25,0.25:0.25]
        [--seeds 0,1] [--spp 0]

Per scene and setting (level-1 share : level-2 share): process CPU s of one render at the
defaults (1 worker; --spp 0 keeps the scene's samples), relMSE, HDR-FLIP, brightness,
the level-1 / level-2 ends regathered, averaged over the seeds; and efficiency
1 / (relMSE x CPU) relative to the first setting's.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", default="figure6_box,figure7_blocker,principled_spheres")
    ap.add_argument("--settings", default="1:1,1:0.25,0.5:0.5,0.25:0.25")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--spp", type=int, default=0)
    a = ap.parse_args(argv)
    import accuracy_scenes as A
    A.ensure_addon()
    from engine.jit import ensure_compiled
    ensure_compiled()
    import engine.integrator as integ
    from engine.render import render
    from engine.settings import RenderSettings
    settings_list = [tuple(float(x) for x in s.split(":")) for s in a.settings.split(",")]
    seeds = [int(s) for s in a.seeds.split(",")]
    print(f"{'scene':20s} {'survival':>10s} {'CPU s':>7s} {'relMSE':>8s} {'FLIP':>7s} "
          f"{'bright':>7s} {'ends 1':>8s} {'ends 2':>8s} {'effic.':>7s}", flush=True)
    for name in a.scenes.split(","):
        scene, kw = A.export_ours(name)
        ref = A.load_reference(name)
        kw = dict(kw, workers=1)
        if a.spp:
            kw["spp"] = a.spp
        render(scene, RenderSettings(**dict(kw, spp=1)))  # warm caches
        base = None
        for surv in settings_list:
            integ.REGATHER_SURVIVAL = surv
            rows = []
            for seed in seeds:
                t0 = time.process_time()
                film = render(scene, RenderSettings(**dict(kw, seed=seed)))
                cpu = time.process_time() - t0
                img = np.asarray(film.combined, np.float64)
                rs = film.stats.get("ray_stages", {})
                rows.append((cpu, A.relmse(img, ref), A.flip(img, ref), A.brightness(img, ref),
                             rs.get("regathered 1", 0), rs.get("regathered 2", 0)))
            cpu, rel, fl, br, e1, e2 = np.mean(rows, axis=0)
            eff = 1.0 / (rel * cpu)
            base = base or eff
            print(f"{name:20s} {surv[0]:>4g}:{surv[1]:<5g} {cpu:7.1f} {rel:8.5f} {fl:7.4f} "
                  f"{br:7.4f} {e1:8.0f} {e2:8.0f} {eff / base:7.3f}", flush=True)
    integ.REGATHER_SURVIVAL = (1.0, 1.0)


if __name__ == "__main__":
    main()
