"""tableroom45 (docs/accuracy.md "tableroom45"): working script, run from the worktree root with
PYTHONPATH=$PWD; reads and writes /tmp/tableroom45 (masks.npy from bench/newuser44_table.py
--masks, t_def.pkl from tableroom45_variant.py export)."""
import sys, os, pickle
sys.path.insert(0, os.getcwd())
import numpy as np
from engine.jit import ensure_compiled
from engine.photonlayout import powers
from engine.render import prepare_context, shoot_photons, close_context
from engine.settings import RenderSettings
ensure_compiled()
scene, kw = pickle.load(open("/tmp/tableroom45/t_def.pkl", "rb"))
ctx = prepare_context(scene, RenderSettings(**dict(kw, workers=1)))
stats = {}
shots = shoot_photons(ctx, stats)
cm = ctx.caustic_map.photons
names = list(ctx.geo.object_names)
bw = names.index("BackWall")
surf = np.asarray(cm.surface)
pos = np.asarray(cm.position, np.float64); pw = powers(cm.power).sum(1)  # (photonlayout: either layout)
caustic = shots[1]
print("caustic map", len(pos), "aimed emitted", caustic.emitted, "glow_share", stats.get("glow_share"), "split", stats.get("glow_split"), "glow emitted", stats.get("glow_photons_emitted"))
for i, n in enumerate(names):
    k = surf == i
    if k.sum():
        print(f"{n:14s} photons {k.sum():7d} power {pw[k].sum():.3f} mean {pw[k].mean():.2e} cv {pw[k].std()/pw[k].mean():.2f}")
# back wall grid (y = 2.0 plane, x in [-1.9,1.9], z in [0.1,2.5])
m = surf == bw
P, W = pos[m], pw[m]
R = ctx.caustic_radius
print("cap", R)
from scipy.spatial import cKDTree
t = cKDTree(P[:, [0, 2]])
xs, zs = np.meshgrid(np.linspace(-1.8, 1.8, 37), np.linspace(0.2, 2.4, 23))
q = np.c_[xs.ravel(), zs.ravel()]
for cap in (R, 2 * R, 3 * R):
    N, Neff = [], []
    for idx in t.query_ball_point(q, cap):
        w = W[idx]
        N.append(len(idx)); Neff.append(w.sum() ** 2 / max((w * w).sum(), 1e-30))
    N, Neff = np.array(N), np.array(Neff)
    print(f"cap {cap:.3f}: photons in disc median {np.median(N):.0f} p10 {np.percentile(N,10):.0f}; eff median {np.median(Neff):.1f} p10 {np.percentile(Neff,10):.1f}")
qs = np.percentile(W, [10, 50, 90, 99, 99.9]); print("power quantiles", qs, "max", W.max())
o = np.sort(W)[::-1]; c = np.cumsum(o) / o.sum()
print("share of power in top 1%:", c[len(o)//100], "top 5%:", c[len(o)//20], "top 20%:", c[len(o)//5])
# distinct power levels
u, cnt = np.unique(np.round(np.log2(W), 1), return_counts=True)
print(list(zip(u[-15:], cnt[-15:])))
# aimed caustic shot photons: compare with the aimed shot's own stored photons' powers
ap = np.asarray(caustic.power, np.float64).sum(1)
print("aimed+glow shot (caustic var) len", len(caustic), "power quantiles", np.percentile(ap, [10,50,90,99]))
close_context(ctx)
