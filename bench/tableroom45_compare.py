"""tableroom45 (docs/accuracy.md "tableroom45"): working script, run from the worktree root with
PYTHONPATH=$PWD; reads and writes /tmp/tableroom45 (masks.npy from bench/newuser44_table.py
--masks, t_def.pkl from tableroom45_variant.py export)."""
import sys, os, json
sys.path.insert(0, os.path.join(os.getcwd(), "bench"))
import numpy as np
from newuser26_compare import read_exr, rel_mse, LUM
ids = np.load("/tmp/tableroom45/masks.npy"); names = json.load(open("/tmp/tableroom45/masks.npy.json"))
def load(p):
    p, _, ps = p.partition(":")
    if p.endswith(".exr"):
        return read_exr(p)
    z = np.load(p)
    if ps:
        return sum(z[q][..., :3] for q in ps.split("+")).astype(np.float64)
    return z["combined"][..., :3].astype(np.float64)
ref = load(sys.argv[1]); imgs = [load(p) for p in sys.argv[2:]]
sel = ["BackWall", "RightWall_c", "RightWall_a", "Floor", "TableTop", "Curtain", "WineBottle", "Mug"]
print("| object | px | ref | " + " | ".join(os.path.basename(p) for p in sys.argv[2:]) + " |")
rows = [(n, ids == names.index(n)) for n in sel if n in names] + [("whole", ids > -9)]
for n, m in rows:
    lr = (ref[m] @ LUM).mean()
    print(f"| {n} | {m.sum()} | {lr:.4f} | " + " | ".join(f"{(im[m] @ LUM).mean() / lr:.4f} / {rel_mse(im[m], ref[m]):.4f}" for im in imgs) + " |")
