"""One feature-matrix case rendered over many seeds: how far its brightness and block
error move with the photon maps' and the camera pass's random numbers, to tell a fault
from noise (issue 13: docs/performance.md, "Fourth slice: photon emission").

    .venv/bin/python bench/feature_seeds.py CASE FIRST-LAST [CHECKOUT]

CHECKOUT (default: this one) is put first on sys.path, so an older checkout's engine is
measured by the same script against the same stored Cycles reference
(tests/references/features.npz of CHECKOUT). Prints one line per seed (brightness =
mean ours / mean Cycles, block error) and the summary: mean +- standard error, standard
deviation per seed, range, block-error mean, median, 99th percentile and maximum (on the
case's block size) and how many seeds exceed the case's block_tol.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
name = sys.argv[1]
first, last = (int(x) for x in sys.argv[2].split("-"))
root = os.path.abspath(sys.argv[3]) if len(sys.argv) > 3 else os.path.dirname(HERE)
sys.path.insert(0, os.path.join(root, "tools"))
sys.path.insert(0, root)

import numpy as np  # noqa: E402
import feature_matrix as fm  # noqa: E402

refs = fm.load_references()
case = fm.CASES[name]
size = getattr(case, "block", fm.BLOCK)  # (an older CHECKOUT's cases have no block)
bright, block = [], []
for seed in range(first, last + 1):
    img, seconds, _ = fm.render_ours(name, seed)
    s = fm.score(fm.blocks(img), refs[name], *([size] if size != fm.BLOCK else []))
    bright.append(s["brightness"])
    block.append(s["block_error"])
    print(f"{name} seed {seed}: brightness {s['brightness']:.4f}, block error "
          f"{s['block_error']:.3f} ({seconds:.1f} s)", flush=True)
b, k = np.array(bright), np.array(block)
se = b.std(ddof=1) / np.sqrt(len(b)) if len(b) > 1 else float("nan")
sd = b.std(ddof=1) if len(b) > 1 else float("nan")
print(f"{name}, seeds {first}-{last}, {root}: brightness {b.mean():.4f} +- {se:.4f} "
      f"(s.d. {sd:.4f}, {b.min():.3f}-{b.max():.3f}); block error ({size} px blocks) "
      f"mean {k.mean():.3f}, median {np.median(k):.3f}, 99th percentile "
      f"{np.percentile(k, 99):.3f}, max {k.max():.3f}, over {case.block_tol}: "
      f"{int((k > case.block_tol).sum())} / {len(k)}")
