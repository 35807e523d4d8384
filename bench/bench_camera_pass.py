"""Camera + shadow stages, before / after: this checkout against another tree, CPU time,
minor page faults and the share of raw Embree on the same rays.

The direct-only camera pass of bench_scaling.py's `rays` section (Figure 6 box, and the box
with a 1M-triangle sphere; photon mapping off, 160x120, 64 spp) runs in a fresh child
process per tree and case, trees alternating, best of --repeat renders in each child and
best over --rounds children. Each child also replays the render's logged Embree queries
straight through embreex (bench_core.raw_embree_time) for the ceiling ratio, and hashes the
film (same bits before / after, and for 1 and 2 workers).

    .venv/bin/python bench/bench_camera_pass.py [--before DIR | --base COMMIT]
        [--workers 1,2] [--scenes box,box1m] [--rounds 2] [--repeat 3]

--before: a checkout whose numba cache is warm (else its first child compiles for minutes);
--base: a commit, unpacked with git archive into --work.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = r"""
import hashlib, json, resource, sys, time
sys.path.insert(0, ROOT)
sys.path.insert(0, ROOT + "/bench")
import numpy as np
from engine.jit import ensure_compiled
ensure_compiled()
from engine import RenderSettings
from engine.film import Film
from engine.integrator import render_camera
from bench_scaling import box, make_ctx
from bench_core import raw_embree_time, recording
scene = box(160, 120, sphere_tris=1_000_000 if SCENE == "box1m" else None)
ctx = make_ctx(scene, RenderSettings(photon_mapping=False, spp=64, workers=WORKERS))
rec = recording(ctx.accel)
film = Film(160, 120)
render_camera(ctx, (0, 0, 160, 120), film)  # loads what the first call needs; logs rays
log = list(rec.log)
rec.log.clear()
rec.enabled = False
cpu = faults = sys_s = None
for _ in range(REPEAT):
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    c0 = time.process_time()
    render_camera(ctx, (0, 0, 160, 120), Film(160, 120))
    c = time.process_time() - c0
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    if cpu is None or c < cpu:
        cpu, faults, sys_s = c, r1.ru_minflt - r0.ru_minflt, r1.ru_stime - r0.ru_stime
raw = None
for _ in range(REPEAT):
    c0 = time.process_time()
    raw_embree_time(rec, log)
    c = time.process_time() - c0
    raw = c if raw is None else min(raw, c)
h = hashlib.sha1()
for k in ("direct", "specular", "emission", "alpha", "depth", "normal"):
    h.update(np.ascontiguousarray(getattr(film, k)).tobytes())
print(json.dumps(dict(cpu=cpu, faults=faults, sys=sys_s, raw=raw,
                      rays=sum(len(e[1]) for e in log), hash=h.hexdigest())))
"""


def child(root, scene, workers, repeat):
    head = f"ROOT={root!r}\nSCENE={scene!r}\nWORKERS={workers}\nREPEAT={repeat}\n"
    out = subprocess.run([sys.executable, "-c", head + CHILD], capture_output=True, text=True,
                         cwd=root)
    if out.returncode != 0:
        raise RuntimeError(f"child failed ({root}):\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def base_tree(commit, where):
    path = os.path.join(where, f"base-{commit}")
    if not os.path.isdir(path):
        os.makedirs(path)
        archive = subprocess.run(["git", "-C", ROOT, "archive", commit], capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", path], input=archive, check=True)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", help="a checkout to compare with (warm numba cache)")
    ap.add_argument("--base", default="HEAD~1", help="else this commit (git archive)")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--scenes", default="box,box1m")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "bench_camera_pass"))
    a = ap.parse_args(argv)
    before = a.before or base_tree(a.base, a.work)
    trees = {"before": before, "after": ROOT}
    heads = {k: subprocess.run(["git", "-C", r, "rev-parse", "--short", "HEAD"],
                               capture_output=True, text=True).stdout.strip() or r
             for k, r in trees.items()}
    print(f"before = {before} ({heads['before']}), after = {ROOT} ({heads['after']}); "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores\n")
    print("| scene | workers | rays | CPU s before -> after | minor faults before -> after | "
          "raw Embree CPU s | CPU % of raw Embree before -> after | image |")
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    hashes = {}
    for scene in a.scenes.split(","):
        for workers in [int(w) for w in a.workers.split(",")]:
            res = {"before": [], "after": []}
            for _ in range(a.rounds):
                for label, root in trees.items():
                    res[label].append(child(root, scene, workers, a.repeat))
            b = min(res["before"], key=lambda r: r["cpu"])
            f = min(res["after"], key=lambda r: r["cpu"])
            raw = min(r["raw"] for r in res["before"] + res["after"])
            hashes.setdefault(scene, set()).add(f["hash"])
            same = "same bits" if b["hash"] == f["hash"] else "DIFFERS"
            print(f"| {scene} | {workers} | {f['rays']:,} | {b['cpu']:.3f} -> {f['cpu']:.3f} | "
                  f"{b['faults']:,} -> {f['faults']:,} | {raw:.3f} | "
                  f"{100 * raw / b['cpu']:.1f} -> {100 * raw / f['cpu']:.1f} | {same} |",
                  flush=True)
    if "," in a.workers:
        for scene, hs in hashes.items():
            print(f"\n{scene}, after: the same film for every worker count" if len(hs) == 1
                  else f"\n{scene}, after: worker counts DIFFER")
    print(f"(load average at the end {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
