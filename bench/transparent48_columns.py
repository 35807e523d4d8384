"""transparent48's measurement (docs/compatibility.md, "transparent48"): the staircase of
eight half-transparent cards over a sunlit floor of
tests/blender/test_transparent_path_limit_cycles.py (its `_scene`), Cycles against ours,
the mean per pixel column (column j under the top j + 1 cards) beside the analytic value
of Cycles' rule (the test's `expected_columns`).

    PYTHONPATH=. .venv/bin/python bench/transparent48_columns.py [T] [--root DIR]

T: Light Paths > Max Bounces > Transparent (default 4). --root: the checkout whose engine
and add-on render ours (default this one; e.g. a main worktree for the numbers before).
Cycles 256 spp, ours 64 spp, Max Bounces 0, pixel filter Gaussian 0.01 px, 8 x 8.
"""
import argparse
import importlib.util
import os
import pathlib
import sys
import tempfile

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("transparent", nargs="?", type=int, default=4)
    ap.add_argument("--root", default=HERE)
    a = ap.parse_args()
    root = os.path.abspath(a.root)
    sys.path[:0] = [os.path.join(root, "tests", "blender"), root]
    import bpy
    import addon
    addon.register()
    spec = importlib.util.spec_from_file_location("transparent_case", os.path.join(
        HERE, "tests", "blender", "test_transparent_path_limit_cycles.py"))
    case = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(case)
    from blender_helpers import cheap, cycles_plain, default_cycles, default_photonmap
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTONMAP"
    cheap(scene)
    case._scene(bpy, scene)
    c = default_cycles(scene)
    cycles_plain(scene, 256, 0)
    c.transparent_max_bounces = a.transparent
    c.pixel_filter_type, c.filter_width = "GAUSSIAN", 0.01
    pm = default_photonmap(scene)
    pm.spp, pm.photon_mapping = 64, False
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="transparent48-"))
    cyc = case._columns(bpy, scene, tmp / "cycles.exr", "CYCLES")
    ours = case._columns(bpy, scene, tmp / "ours.exr", "PHOTONMAP")
    rule = case.expected_columns(a.transparent)
    print(f"ours from {root}, Transparent {a.transparent}")
    print("| cards | " + " | ".join(str(j + 1) for j in range(case.CARDS)) + " |")
    for name, row, fmt in (("rule", rule, "{:.4f}"), ("Cycles", cyc, "{:.4f}"),
                           ("ours", ours, "{:.4f}"), ("ours / Cycles", ours / cyc, "{:.3f}")):
        print(f"| {name} | " + " | ".join(fmt.format(x) for x in row) + " |")


if __name__ == "__main__":
    main()
