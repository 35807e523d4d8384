"""The compact photon layout's lookup cost (docs/performance.md "compact49"): a render's
own photon-map estimates, captured by bench/bench_lookup.py --render-calls (its
$WORK/NAME-WxH.calls file: float32 maps), replayed in one process on one thread with the
maps in the float32 layout (photonlayout.COMPACT's off path: main's arithmetic) and in
the compact one (octahedral direction and normal, RGBE power, decoded in the kernels),
alternating, best of 3 CPU seconds each. Prints us per estimate row per map and caller.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_layout_lookups.py \
        /tmp/bench_kernels/figure6_box-160x120.calls

--capture NAME OUT [SETTINGS] (compact50) captures such a file without a base version:
example blend NAME (exported under $TMPDIR/film_hashes, tools/film_hashes.py's) rendered
at 160 x 120 by one worker with RenderSettings(workers=1, **SETTINGS) (a Python dict
literal, e.g. "dict(photons=2_000_000, caustic_photons=1_000_000)"), its calls into OUT:

    PYTHONPATH=$PWD .venv/bin/python bench/bench_layout_lookups.py --capture \
        figure8_caustic /tmp/compact50/fig8.calls
"""
import os
import pickle
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from engine import kdtree, photonlayout, photonmap  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402
from engine.photons import Photons  # noqa: E402


def tree(a):
    t = kdtree.KdTree.__new__(kdtree.KdTree)
    t.position, t.axis, t.split, t.leaf, t.bounds = a
    t.order = None
    return t


def main(path):
    ensure_compiled()
    with open(path, "rb") as f:
        cap = pickle.load(f)
    tot = {False: 0.0, True: 0.0}
    print(f"{os.path.basename(path)}; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores; one thread, best of 3 CPU s")
    print("| estimate at | map photons | rows | float32 us / row | compact us / row | "
          "compact / float32 |")
    print("|---|---:|---:|---:|---:|---:|")
    for (mid, caller, radius), calls in cap["calls"].items():
        rows = sum(len(c[0]) for c in calls)
        if rows == 0:
            continue
        m = cap["maps"][mid]
        pms = {}
        for compact in (False, True):
            pm = photonmap.PhotonMap.__new__(photonmap.PhotonMap)
            pm.workers, pm.structure, pm.tree = 1, "kdtree", tree(m["tree"])
            pm.photons = Photons(*m["photons"])
            if compact:
                photonlayout.compact(pm.photons)
            pms[compact] = pm

        def run(pm):
            return [pm.irradiance(p, n, radius, k, mp, est, return_boundary=rb, r_floor=rf,
                                  **({"masks": more[0]} if more and more[0] is not None
                                     else {}),
                                  **({"surface": more[1]} if len(more) > 1
                                     and more[1] is not None else {}))
                    for p, n, k, mp, est, rb, rf, *more in calls]
        best = {False: 1e9, True: 1e9}
        for _ in range(3):
            for compact in (False, True):
                t = time.process_time()
                run(pms[compact])
                best[compact] = min(best[compact], time.process_time() - t)
        for c in best:
            tot[c] += best[c]
        print(f"| {caller} | {len(pms[False].photons):,} | {rows:,} | "
              f"{best[False] / rows * 1e6:.2f} | {best[True] / rows * 1e6:.2f} | "
              f"{best[True] / best[False]:.3f} |", flush=True)
    print(f"| all | | | {tot[False]:.2f} s | {tot[True]:.2f} s | "
          f"{tot[True] / tot[False]:.3f} |")


def capture(name, out, settings="{}"):
    """bench_lookup.py's CAPTURE of example blend `name`'s render into `out`."""
    import ast
    import tempfile
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    import bench_kernels as bk
    import bench_lookup as bl
    kw = eval(settings, {"dict": dict}) if settings.startswith("dict(") else \
        ast.literal_eval(settings)
    pkl = bk.exported(name, os.path.join(tempfile.gettempdir(), "film_hashes"))
    code = bl.CAPTURE.replace("RenderSettings(workers=1)",
                              f"RenderSettings(workers=1, **{kw!r})")
    print(bk.child(code, ROOT=ROOT, PICKLE=pkl, W=160, H=120, OUT=out))


if __name__ == "__main__":
    if sys.argv[1] == "--capture":
        capture(*sys.argv[2:])
    else:
        main(sys.argv[1])
