"""Does a feature-matrix case still fail a wrong render? The case's scene with one node
input changed in OUR render only (the stored Cycles reference keeps the right scene),
scored by the case's own metric (block size, block_tol, brightness) over seeds: an
engine that reads that input wrong. Run it after loosening a case's metric.

    .venv/bin/python bench/feature_sensitivity.py CASE MATERIAL NODE_TYPE "INPUT=VALUE[;...]" FIRST-LAST

e.g. closure_glass_rough_sun_behind rglass BSDF_GLASS Roughness=0.0 0-3
     closure_glass_rough_sun_behind rglass BSDF_GLASS "Color=(0.9,0.9,0.9,1)" 0-3
Prints one row per seed (block error, brightness, the case's verdict) and how many seeds
fail; a wrong render the metric passes is a metric too loose to guard the case.
"""
import ast
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, ROOT)

import feature_matrix as fm  # noqa: E402

name, material, node_type, changes, seeds = sys.argv[1:6]
first, last = (int(x) for x in seeds.split("-"))
values = {k: ast.literal_eval(v) for k, v in (c.split("=", 1) for c in changes.split(";"))}
case = fm.CASES[name]
build = case.build


def wrong():
    build()
    nodes = [n for n in fm.bpy.data.materials[material].node_tree.nodes if n.type == node_type]
    if not nodes:
        raise SystemExit(f"no {node_type} node in material '{material}'")
    for k, v in values.items():
        nodes[0].inputs[k].default_value = v


case.build = wrong
refs = fm.load_references()
print(f"| {name} | {changes} | seed | block error ({case.block} px, tol {case.block_tol}) "
      f"| brightness (tol {case.mean_tol}) | verdict |")
print("|---|---|---:|---:|---:|---|")
failed = 0
for seed in range(first, last + 1):
    img, seconds, warnings = fm.render_ours(name, seed)
    s = fm.score(fm.blocks(img), refs[name], case.block)
    fails = fm.verdict(case, s, warnings)
    failed += bool(fails)
    print(f"| {name} | {changes} | {seed} | {s['block_error']:.3f} | {s['brightness']:.4f} | "
          f"{'; '.join(fails) or 'PASSES'} |", flush=True)
print(f"{failed} of {last - first + 1} seeds fail the wrong render")
