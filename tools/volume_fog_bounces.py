"""The feature matrix's fog box (volume_fog_spot) at Light Paths > Volume bounces B for
both engines (volphotons38): Cycles 1024 spp (cached in OUT), ours at the case's settings,
scored by the matrix's metric.

    VB=32 SEEDS=0,1 .venv/bin/python tools/volume_fog_bounces.py
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import feature_matrix as fm  # noqa: E402

B = int(os.environ.get("VB", "32"))
OUT = os.environ.get("OUT", "/tmp/volume_fog_bounces")
NAME = "volume_fog_spot"


def main():
    os.makedirs(OUT, exist_ok=True)
    fm.CASES[NAME].cycles = dict(volume_bounces=B)
    ref_path = os.path.join(OUT, f"ref_vb{B}.npy")
    if not os.path.exists(ref_path):
        img, sec = fm.render_cycles(NAME)
        np.save(ref_path, fm.blocks(img).astype(np.float32))
        print(f"cycles vb{B} {sec:.1f} s", flush=True)
    for seed in [int(s) for s in os.environ.get("SEEDS", "0").split(",")]:
        img, sec, _ = fm.render_ours(NAME, seed)
        s = fm.score(fm.blocks(img), np.load(ref_path), fm.CASES[NAME].block)
        print(f"ours vb{B} seed {seed}: {sec:.1f} s brightness {s['brightness']:.3f} "
              f"block error {s['block_error']:.3f}", flush=True)


if __name__ == "__main__":
    main()
