"""tableroom45 (docs/accuracy.md "tableroom45"): working script, run from the worktree root with
PYTHONPATH=$PWD; reads and writes /tmp/tableroom45 (masks.npy from bench/newuser44_table.py
--masks, t_def.pkl from tableroom45_variant.py export)."""
import sys, os, json
sys.path.insert(0, os.path.join(os.getcwd(), "bench"))
import numpy as np
from newuser26_compare import read_exr, LUM
from scipy.ndimage import uniform_filter
ids = np.load("/tmp/tableroom45/masks.npy"); names = json.load(open("/tmp/tableroom45/masks.npy.json"))
obj = os.environ.get("OBJ", "BackWall")
m = ids == names.index(obj)
inside = uniform_filter(m.astype(float), 5, mode="constant") > 0.999
def box(img):
    return uniform_filter(img, 5, mode="constant")
def lum(p, ps="combined"):
    if p.endswith(".exr"):
        return read_exr(p) @ LUM
    z = np.load(p)
    return sum(z[q][..., :3].astype(np.float64) for q in ps.split("+")) @ LUM
ref = lum(sys.argv[1]); rb = box(ref)
print(obj, "boxes", inside.sum())
for p in sys.argv[2:]:
    r = box(lum(p))[inside] / rb[inside]
    print(f"{os.path.basename(p)}: box ratio max {r.max():.3f} p99 {np.percentile(r, 99):.3f} p1 {np.percentile(r, 1):.3f} std {r.std():.4f} mean {r.mean():.4f}")
npz = [p for p in sys.argv[2:] if p.endswith(".npz")]
if len(npz) >= 2:
    for ps in ("direct", "indirect", "caustic", "specular", "emission"):
        vals = [box(lum(p, ps))[inside] / rb[inside] for p in npz]
        v = np.array(vals)
        share = v.mean()
        d = v - v.mean(0)  # deviation from the seeds' mean
        sd = np.sqrt((d ** 2).sum(0) / (len(npz) - 1))
        print(f"  {ps:9s} share {share:.4f}  LF noise (box std over seeds) rms {np.sqrt((sd**2).mean()):.4f} p99 {np.percentile(sd, 99):.4f}")
