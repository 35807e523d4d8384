"""The camera pass's stages side by side in two or more cProfile files (percost55,
docs/performance.md "percost55"): for each named function, its calls and cumulative CPU s
in each profile (bench/percost54_camera_profile.py's `run` writes them: one thread, the
CPU clock), so a before / after pair shows what a change removed stage by stage. Call
counts do not depend on the machine's load; the seconds do.

    PYTHONPATH=$PWD .venv/bin/python bench/percost55_stages.py BEFORE.prof AFTER.prof
        [--functions render_camera,gather_indirect,...]

A function name matches every function of that name (all files); the total of the
profile (render_camera's) comes first. Prints a Markdown table.
"""
import argparse
import pstats

DEFAULT = ("render_camera,_photon_terms,gather_indirect,_regather,vertex,_chain_lookups,"
           "meet,near,visible_irradiance,clamp_rows,_with_rejected,reject,reject_block,"
           "vectors,diffuse_reject_pairs,touch_near,setdiff1d")


def stage_table(path, names):
    """{name: (calls, cumulative CPU s)} of the functions named, summed over files."""
    out = {}
    for fn, (_, nc, _, ct, _) in pstats.Stats(path).stats.items():
        if fn[2] in names:
            calls, cum = out.get(fn[2], (0, 0.0))
            out[fn[2]] = (calls + nc, cum + ct)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("profiles", nargs="+")
    ap.add_argument("--functions", default=DEFAULT)
    a = ap.parse_args()
    names = [n for n in a.functions.split(",") if n]
    tables = [stage_table(p, set(names)) for p in a.profiles]
    print("| function | " + " | ".join(f"{p}: calls, CPU s" for p in a.profiles) + " |")
    print("|---|" + "---:|" * len(a.profiles))
    for n in names:
        cells = []
        for t in tables:
            calls, cum = t.get(n, (0, 0.0))
            cells.append(f"{calls}, {cum:.2f}" if calls else "-")
        print(f"| {n} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
