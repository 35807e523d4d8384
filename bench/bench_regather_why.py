"""Why the final gather regathers, and what the regathers change (regather29): per gather
level, the regathered rows by reason (boundary with a point / boundary with no point /
short ray / both), the sum of their lookups' values (tp x wd / G x Ey) against the sum of
what their regathers added, and each reason's share of the level's gathered light; then
the regathered value's parts (direct light, the recursive gather, the secondary caustic)
summed with the same weights. One 1-worker render of a blend exported by bench_kernels.py.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_regather_why.py figure7_blocker"""
import collections, pickle, sys, time, os
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import numpy as np
from engine.jit import ensure_compiled
ensure_compiled()
import engine.integrator as I
from engine.render import render
from engine.settings import RenderSettings
name = sys.argv[1]
import tempfile
scene = pickle.load(open(os.path.join(tempfile.gettempdir(), "bench_kernels", f"{name}.pkl"), "rb"))
scene.width, scene.height = 320, 240
# level -> [(w x Ey (K,3), boundary (K,), short (K,), point found (K,))]
look = collections.defaultdict(list)
sub = collections.defaultdict(list)    # level -> w*Esub
parts = collections.defaultdict(lambda: np.zeros(3))
total = collections.defaultdict(lambda: np.zeros(3))
orig_add = I.add_gathered
def counted_add(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, again_ok, again):
    fr = sys._getframe(1)
    lvl = fr.f_locals["level"]
    if again_ok:
        b = boundary.astype(bool); s = lt < short
        a = b | s
        j = rows[a]
        w = tp[j] * wd[j] / G
        look[lvl].append((w * Ey[a], b[a], s[a], Ey[a].max(axis=1) > 0))
        total[lvl] += (tp[rows[~a]] * wd[rows[~a]] * Ey[~a] / G).sum(axis=0)
    elif fr.f_code.co_name == "_regather_batch":
        w = tp * wd / G
        sub[lvl].append(w * Ey)
    return orig_add(E, idx, rows, tp, wd, Ey, G, boundary, lt, short, again_ok, again)
I.add_gathered = counted_add
stack = []
rb = I._regather_batch
def rb_w(ctx, E, target, tp, wd, prim, u, v, d, G, rng, counters, level, *a, **kw):
    stack.append((tp * wd / G, level))
    try:
        return rb(ctx, E, target, tp, wd, prim, u, v, d, G, rng, counters, level, *a, **kw)
    finally:
        stack.pop()
I._regather_batch = rb_w
for fname in ("_secondary_irradiance", "direct_irradiance", "gather_indirect"):
    f = getattr(I, fname)
    def g(*a, _f=f, _n=fname, **kw):
        out = _f(*a, **kw)
        if sys._getframe(1).f_code.co_name == "_regather_batch" and stack:
            w, lvl = stack[-1]
            parts[(lvl, _n)] += (w * out).sum(axis=0)
        return out
    setattr(I, fname, g)
t0 = time.process_time()
render(scene, RenderSettings(workers=1))
print(f"{name}: render CPU {time.process_time() - t0:.2f}")
print("\n| level | reason | rows | lookups' sum | regathers' sum | lookup / regather | "
      "share of the level's gathered light |")
print("|---:|---|---:|---:|---:|---:|---:|")
for lvl in sorted(look):
    wEy, b, s, found = (np.concatenate([x[i] for x in look[lvl]]) for i in range(4))
    S = np.concatenate(sub[lvl]) if sub[lvl] else np.zeros((0, 3))
    assert len(S) == len(wEy), "regathers out of step with their lookups"
    tot_all = total[lvl].sum() + S.sum()
    for lab, m in (("boundary, a point", b & ~s & found), ("boundary, no point", b & ~s & ~found),
                   ("short only", s & ~b), ("boundary and short", s & b)):
        print(f"| {lvl} | {lab} | {int(m.sum()):,} | {wEy[m].sum():.4g} | {S[m].sum():.4g} | "
              f"{wEy[m].sum() / max(S[m].sum(), 1e-30):.4f} | {S[m].sum() / tot_all:.4f} |")
print("\n| level of the regather | part | sum (tp x wd / G weights) |")
print("|---:|---|---:|")
for k in sorted(parts):
    print(f"| {k[0]} | {k[1]} | {parts[k].sum():.4g} |")
