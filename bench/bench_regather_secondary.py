"""The regathered ends' secondary caustic, before / after (issue 13, regather29): end-to-end
CPU s of 1-worker renders (default settings) with integrator.SECONDARY_FROM_GATHER_POINTS
False (the k-NN estimate of the secondary map at a tenth of the ends: the base's code
path and bits) and True (the share of the ends' lookup points, GatherMap.secondary_E),
alternated in fresh processes, each film's hash; then per setting one render's CPU s in
_secondary_irradiance and the GatherMap build, and the secondary-caustic term's sum at
the level-0 regathers' ends (tp x wd / G x E) against all the light level 0 gathered.

    .venv/bin/python bench/bench_regather_secondary.py [--blends figure7_blocker,figure3_sphere]
        [--repeat 2] [--seeds 0]

Blends are exported as bench_kernels.py exports them (bpy), into --work."""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_kernels as bk  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

RUN = r"""
import hashlib, json, pickle, resource, sys, time
sys.path.insert(0, ROOT)
import numpy as np
from engine.jit import ensure_compiled
ensure_compiled()
import engine.integrator as I
import engine.photonmap as PM
from engine.render import render
from engine.settings import RenderSettings
I.SECONDARY_FROM_GATHER_POINTS = FLAG
t = {"secondary s": 0.0, "gather map s": 0.0, "sec sum": 0.0, "gathered sum": 0.0}
if SPLIT:
    sec, init, add = I._secondary_irradiance, PM.GatherMap.__init__, I.add_gathered
    stack = []
    def sec_w(*a, **kw):
        c0 = time.process_time()
        out = sec(*a, **kw)
        t["secondary s"] += time.process_time() - c0
        if len(stack) == 1:  # (the level-0 regathers' ends: weights tp x wd / G)
            t["sec sum"] += float((stack[-1] * out).sum())
        return out
    def init_w(self, *a, **kw):
        c0 = time.process_time()
        init(self, *a, **kw)
        t["gather map s"] += time.process_time() - c0
    rb = I._regather_batch
    def rb_w(ctx, E, target, tp, wd, prim, u, v, d, G, *a, **kw):
        stack.append(tp * wd / G)
        try:
            return rb(ctx, E, target, tp, wd, prim, u, v, d, G, *a, **kw)
        finally:
            stack.pop()
    def add_w(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, again_ok, again):
        n = add(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, again_ok, again)
        if sys._getframe(1).f_code.co_name == "gather_indirect" and \
                sys._getframe(1).f_locals["level"] == 0:
            keep = np.ones(len(rows), bool)
            keep[again[:n]] = False
            j = rows[keep]
            t["gathered sum"] += float((tp[j] * wd[j] * Ey[keep] / G).sum())
        elif sys._getframe(1).f_code.co_name == "_regather_batch" and len(stack) == 1:
            t["gathered sum"] += float((tp * wd * Ey / G).sum())
        return n
    I._secondary_irradiance, PM.GatherMap.__init__, I.add_gathered = sec_w, init_w, add_w
    I._regather_batch = rb_w
with open(PICKLE, "rb") as f:
    scene = pickle.load(f)
scene.width, scene.height = W, H
ru0 = resource.getrusage(resource.RUSAGE_SELF)
film = render(scene, RenderSettings(workers=1, seed=SEED))
ru = resource.getrusage(resource.RUSAGE_SELF)
h = hashlib.sha1()
for k in ("direct", "indirect", "caustic", "specular", "emission"):
    h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
t.update(cpu=(ru.ru_utime + ru.ru_stime) - (ru0.ru_utime + ru0.ru_stime), hash=h.hexdigest(),
         mean=float(np.mean(film.indirect)))
print(json.dumps(t))
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blends", default="figure7_blocker,figure3_sphere")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_kernels"))
    args = ap.parse_args(argv)
    os.makedirs(args.work, exist_ok=True)
    print(f"1 worker, {args.width}x{args.height}, min of {args.repeat} (alternated); load "
          f"average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores\n")
    print("| blend | seed | before CPU s (k-NN at a tenth) | after CPU s (point share) | gain "
          "| film hash before / after |")
    print("|---|---:|---|---|---:|---|")
    seeds = [int(s) for s in args.seeds.split(",")]
    for name in args.blends.split(","):
        pkl = bk.exported(name, args.work)
        for seed in seeds:
            res = {False: [], True: []}
            for _ in range(args.repeat):
                for flag in (False, True):
                    res[flag].append(bk.child(RUN, ROOT=ROOT, PICKLE=pkl, W=args.width,
                                              H=args.height, FLAG=flag, SPLIT=False,
                                              SEED=seed))
            b = [r["cpu"] for r in res[False]]
            a = [r["cpu"] for r in res[True]]
            print(f"| {name} | {seed} | {' / '.join(f'{x:.2f}' for x in b)} | "
                  f"{' / '.join(f'{x:.2f}' for x in a)} | {min(b) / min(a):.3f}x | "
                  f"{res[False][0]['hash'][:8]} / {res[True][0]['hash'][:8]} |", flush=True)
    print("\n| blend | setting | render CPU s | _secondary_irradiance s | GatherMap build s | "
          "secondary at level-1 ends / level-0 gathered light | indirect pass mean |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name in args.blends.split(","):
        pkl = bk.exported(name, args.work)
        for flag in (False, True):
            t = bk.child(RUN, ROOT=ROOT, PICKLE=pkl, W=args.width, H=args.height, FLAG=flag,
                         SPLIT=True, SEED=seeds[0])
            label = "after (point share)" if flag else "before (k-NN at a tenth)"
            print(f"| {name} | {label} | {t['cpu']:.2f} | {t['secondary s']:.2f} | "
                  f"{t['gather map s']:.2f} | {t['sec sum'] / max(t['gathered sum'], 1e-30):.5f}"
                  f" | {t['mean']:.6f} |", flush=True)


if __name__ == "__main__":
    main()
