"""Where a camera pass's CPU goes, by kind of work (percost54, docs/performance.md
"percost54"): a cProfile of engine.render's camera pass alone (integrator.render_camera,
one thread, CPU clock) of a .blend rendered through the add-on at its saved settings,
its functions' own time put in classes: the compiled kernels (engine's @kernel
functions), Embree (accel's packet kernels), numpy (its C functions and methods, and its
Python wrappers), the engine's Python (every other engine function's own time: the glue
per chunk and bounce), the rest (Python's builtins, the threads' locks, bpy). Prints the
classes' CPU s and shares, then the largest functions of each.

    PYTHONPATH=$PWD .venv/bin/python bench/percost54_camera_profile.py run FILE.blend OUT.prof
        [--percent 100] [--spp N] [--root BASE]
    PYTHONPATH=$PWD .venv/bin/python bench/percost54_camera_profile.py table OUT.prof [--top 8]

`run` needs bpy (the bpy wheel); it opens FILE.blend, registers the add-on of this
checkout (or of --root, another checkout: its engine and add-on, this script's clock),
renders with one thread (kernels loaded before the clock) and writes OUT.prof; `table`
reads it. The profiler's own cost falls mostly on the Python side (each call timed):
the classes' shares overstate the glue against an unprofiled render.
"""
import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = r"""
import cProfile, os, sys, time
ROOT, BLEND, OUT, PERCENT, SPP = sys.argv[1:6]
import bpy
bpy.ops.wm.open_mainfile(filepath=BLEND)
sys.path.insert(0, ROOT)
import addon
import engine
import engine.jit as jit
jit.ensure_compiled()
er = sys.modules["engine.render"]
inner = er.render_camera
prof = cProfile.Profile(time.process_time)

def render_camera(ctx, region, film, progress=None, should_cancel=None, **k):
    # (no should_cancel: with one thread the chunks then run inline, on this thread,
    # engine.parallel.ordered_map)
    return prof.runcall(inner, ctx, region, film, progress, None, **k)

er.render_camera = render_camera
addon.register()
sc = bpy.context.scene
sc.render.engine = "PHOTONMAP"
sc.render.resolution_percentage = int(sc.render.resolution_percentage * int(PERCENT) / 100)
sc.photonmap.threads = 1  # (the chunks run on the profiled thread)
if int(SPP):
    sc.photonmap.spp = int(SPP)
bpy.ops.render.render(write_still=False)
prof.dump_stats(OUT)
print("spp", sc.photonmap.spp, "load", os.getloadavg()[0])
"""

CLASSES = ("kernels", "Embree", "numpy", "engine Python", "other")
EMBREE = {"_occluded_packets", "_intersect_packets", "_intersect_rows"}


def kernel_names(root):
    """{(file name, function name)} of the engine's @kernel functions."""
    out = set()
    for dirpath, _, files in os.walk(os.path.join(root, "engine")):
        for f in files:
            if f.endswith(".py"):
                text = open(os.path.join(dirpath, f), encoding="utf-8").read()
                for m in re.finditer(r"@kernel\s*\n\s*def\s+(\w+)", text):
                    out.add((f, m.group(1)))
    return out


def classify(key, kernels):
    path, _, name = key
    base = os.path.basename(path)
    if name in EMBREE and base == "accel.py":
        return "Embree"
    if (base, name) in kernels:
        return "kernels"
    if path == "~":
        if "numpy" in name or "ndarray" in name or "ufunc" in name:
            return "numpy"
        return "other"
    if os.sep + "numpy" + os.sep in path:
        return "numpy"
    if os.sep + "engine" + os.sep in path:
        return "engine Python"
    return "other"


def short(key):
    """file:function, or a builtin's short name (ndarray.take, numpy.empty, ufunc.reduce)."""
    path, _, name = key
    if path != "~":
        return f"{os.path.basename(path)}:{name}"
    m = re.match(r"<method '(\w+)' of '(?:numpy\.)?([\w.]+)' objects>", name)
    if m:
        return f"{m.group(2).split('.')[-1]}.{m.group(1)}"
    m = re.match(r"<built-in method ([\w.]+)>", name)
    return m.group(1).split(".")[0] + "." + m.group(1).split(".")[-1] if m else name


def table(prof, top):
    import pstats
    st = pstats.Stats(prof)
    kernels = kernel_names(HERE)
    sums = dict.fromkeys(CLASSES, 0.0)
    funcs = {c: [] for c in CLASSES}
    for key, (_, _, tottime, _, _) in st.stats.items():
        c = classify(key, kernels)
        sums[c] += tottime
        funcs[c].append((tottime, short(key)))
    total = sum(sums.values())
    print(f"camera pass under the profiler: {total:.2f} CPU s\n")
    print("| class | CPU s | share | largest (own CPU s) |")
    print("|---|---:|---:|---|")
    for c in CLASSES:
        lead = ", ".join(f"{n} {t:.2f}" for t, n in sorted(funcs[c], reverse=True)[:top])
        print(f"| {c} | {sums[c]:.2f} | {100 * sums[c] / total:.0f} % | {lead} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("blend")
    r.add_argument("out")
    r.add_argument("--percent", type=int, default=100)
    r.add_argument("--spp", type=int, default=0, help="0: the blend's")
    r.add_argument("--root", default=HERE, help="the checkout to profile")
    t = sub.add_parser("table")
    t.add_argument("prof")
    t.add_argument("--top", type=int, default=8)
    a = ap.parse_args()
    if a.cmd == "run":
        root = os.path.abspath(a.root)
        out = subprocess.run([sys.executable, "-c", CHILD, root, os.path.abspath(a.blend),
                              os.path.abspath(a.out), str(a.percent), str(a.spp)],
                             env=dict(os.environ, PYTHONPATH=root), cwd=root,
                             capture_output=True, text=True)
        if out.returncode or not os.path.exists(a.out):
            sys.exit(out.stdout[-2000:] + out.stderr[-3000:])
        print(out.stdout.strip().splitlines()[-1])
    else:
        table(a.prof, a.top)


if __name__ == "__main__":
    main()
