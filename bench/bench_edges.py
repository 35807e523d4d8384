"""Boundary corrections for the k-NN photon estimate at a surface's edge, on synthetic
photon sets with an analytic truth (issue 14, s20 edges2; docs/performance.md "edges" and
"edges2").

    PYTHONPATH=$PWD .venv/bin/python bench/bench_edges.py [--seeds 4] [--k 64] [--R 0.17]

The surface is the half-plane y >= 0 (its edge the line y = 0, nothing beyond it), x in
[0, 2] m; queries at x in [0.5, 1.5] (away from the x ends). Every estimate is the
engine's knn_simpson (photonmap._irradiance_rows): the k nearest photons, their disc's
radius rk capped at R, Simpson kernel 3 / (pi rk^2) (1 - d^2 / rk^2)^2. Candidates:
  none        the estimate as the engine makes it (the disc's part beyond the edge lost)
  query       estimate / its own disc's share on the surface (query-side renormalisation)
  photon      each photon weighted by 1 / its own kernel's share (kernel radius: the k-NN
              radius at the photon; branch edges, photon-side normalisation)
  reflect     the reflection (mirror-image) method of kernel density estimation (Schuster
              1985; Silverman 1986 s. 2.10): every photon within R of the edge gets an
              image mirrored across it; the k-NN query runs over photons and images
  linear      local-linear boundary kernel (Jones 1993): the Simpson weight times
              (a2 - a1 t) / (a0 a2 - a1^2), a_j the kernel's j-th moment across the edge
              over the surface's part of the disc, t a photon's offset across the edge
  shrink      query share with the disc capped at the distance to the edge (floored at
              0.01 R): the disc stays on the surface, the share corrects what is left
Cases (photon powers sum to the truth):
  uniform     even light on the surface; E(y) / truth in bands of y / R (near the edge:
              dip < 1, a radius in: overshoot > 1)
  line@Y      a line of light at Y mm from the edge (Gaussian 2 mm across, clipped at
              y >= 0), sparse (rk at the cap R, as the window slab's glow photons) or
              dense (rk ~ 1.6 cm); power: the estimate integrated over y / the line's power
              per metre; w50: the y holding half the integrated estimate, mm
  blob        a 2-D Gaussian (sigma 0.3 R) centred 0.3 R inside the edge, its photons
              beyond the edge dropped; power: integrated estimate / photons' power; L1: the
              mean |E - truth| / mean truth over y < 2.5 R, |x - 1| < 2.5 R
Prints Markdown tables (means over the seeds) and the CPU seconds of each candidate.
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.spatial import cKDTree

X_LEN = 2.0
X_QUERY = (0.5, 1.5)


def _simpson_marginal_table(n=4001):
    """The Simpson kernel of unit radius integrated along the edge: m(t) = 16 / (5 pi)
    (1 - t^2)^(5/2) for |t| <= 1 (its integral is 1); returns the grid t and the cumulative
    moments M_j(t) = int_{-1}^{t} s^j m(s) ds for j = 0, 1, 2."""
    t = np.linspace(-1.0, 1.0, n)
    m = 16.0 / (5.0 * math.pi) * np.clip(1.0 - t * t, 0.0, None) ** 2.5
    cum = []
    for j in range(3):
        f = t ** j * m
        c = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))])
        cum.append(c)
    return t, cum


_T, _CUM = _simpson_marginal_table()


def moments(y, r):
    """The surface's part (s >= -y) of the Simpson kernel of radius r centred y from the
    edge: its moments a_j = int s^j K (s across the edge, in units of r): (a0, a1, a2)."""
    u = np.clip(-np.asarray(y, float) / np.asarray(r, float), -1.0, 1.0)
    return [c[-1] - np.interp(u, _T, c) for c in _CUM]


def knn_radius(tree, pts, k, R):
    d, _ = tree.query(pts, k=k, distance_upper_bound=R)
    rk = d[:, -1]
    return np.where(np.isfinite(rk), rk, R)


def estimate(photons, power, queries, k, R, method):
    """E at the queries (M, 2) from photons (N, 2) of power (N,) by `method`."""
    y_q = queries[:, 1]
    if method == "reflect":
        near = photons[:, 1] < R
        img = photons[near] * np.array([1.0, -1.0])
        photons = np.concatenate([photons, img])
        power = np.concatenate([power, power[near]])
    tree = cKDTree(photons)
    rk = knn_radius(tree, queries, k, R)
    if method == "shrink":
        rk = np.minimum(rk, np.maximum(y_q, 0.01 * R))
    wphot = power
    if method == "photon":
        rp = knn_radius(tree, photons, k, R)
        wphot = power / moments(photons[:, 1], rp)[0]
    out = np.zeros(len(queries))
    lists = tree.query_ball_point(queries, rk)
    for i, js in enumerate(lists):
        if not js:
            continue
        js = np.asarray(js)
        r = rk[i]
        d2 = ((photons[js] - queries[i]) ** 2).sum(1)
        w = 3.0 / (math.pi * r * r) * np.clip(1.0 - d2 / (r * r), 0.0, None) ** 2
        if method == "linear":
            a0, a1, a2 = moments(y_q[i], r)
            t = (photons[js, 1] - y_q[i]) / r
            w = w * (a2 - a1 * t) / (a0 * a2 - a1 * a1)
        out[i] = (w * wphot[js]).sum()
    if method in ("query", "shrink"):
        out = out / moments(y_q, rk)[0]
    return out


def query_grid(ys, nx=41):
    xs = np.linspace(*X_QUERY, nx)
    X, Y = np.meshgrid(xs, ys)
    return np.column_stack([X.ravel(), Y.ravel()]), len(xs)


METHODS = ("none", "query", "photon", "reflect", "linear", "shrink")


def _stratified(rng, n, length):
    """n positions in [0, length), one in each of n equal cells (no Poisson count noise)."""
    return (np.arange(n) + rng.uniform(0.0, 1.0, n)) * (length / n)


def case_uniform(rng, k, R, density, y_lo=0.0):
    """Photons of even light (E = 1 W/m^2) over y in [y_lo, 3 R]."""
    n = int(density * X_LEN * (3.0 * R - y_lo))
    ph = np.column_stack([rng.uniform(0, X_LEN, n), rng.uniform(y_lo, 3.0 * R, n)])
    return ph, np.full(n, 1.0 / density)


def case_line(rng, k, R, y0, per_metre):
    """A line of light (1 W per metre of edge) at y0 from the edge, 2 mm across."""
    n = int(per_metre * X_LEN)
    y = np.abs(y0 + 0.002 * rng.standard_normal(n))  # folded: every photon on the surface
    ph = np.column_stack([_stratified(rng, n, X_LEN), y])
    return ph, np.full(n, 1.0 / per_metre)


def case_blob(rng, k, R, n):
    """A 2-D Gaussian blob of 1 W (sigma 0.3 R, centred 0.3 R from the edge), the photons
    beyond the edge dropped (that light misses the surface)."""
    s = 0.3 * R
    c = np.array([1.0, 0.3 * R])
    ph = c + s * rng.standard_normal((n, 2))
    ph = ph[ph[:, 1] >= 0.0]
    return ph, np.full(len(ph), 1.0 / n), c, s


def integrate_y(prof, ys):
    return float(np.sum(0.5 * (prof[1:] + prof[:-1]) * np.diff(ys)))


FAR = 1.0  # the control's shift: the same photons 1 m from any edge (y + FAR)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--k", type=int, default=64)
    ap.add_argument("--R", type=float, default=0.17)
    a = ap.parse_args()
    k, R = a.k, a.R
    cpu = {m: 0.0 for m in METHODS}

    def run(m, ph, pw, q):
        t0 = time.process_time()
        e = estimate(ph, pw, q, k, R, m)
        cpu[m] += time.process_time() - t0
        return e

    # Uniform: bands of y / R.
    bands = [(0.0, 0.05), (0.05, 0.2), (0.2, 0.5), (0.5, 1.0), (1.0, 1.5), (1.5, 2.0)]
    for label, density in (("sparse (rk = R)", 200.0), ("dense (rk ~ 0.3 R)", 8000.0)):
        ys = np.linspace(0.0, 2.0 * R, 81)
        q, nx = query_grid(ys)
        acc = {m: np.zeros(len(ys)) for m in METHODS + ("no edge",)}
        for seed in range(a.seeds):
            rng = np.random.default_rng(seed)
            ph, pw = case_uniform(rng, k, R, density)
            for m in METHODS:
                acc[m] += run(m, ph, pw, q).reshape(len(ys), nx).mean(1) / a.seeds
            # The control: the surface continued past y = 0 (even light on both sides).
            ph, pw = case_uniform(np.random.default_rng(seed), k, R, density, -3.0 * R)
            acc["no edge"] += estimate(ph, pw, q, k, R, "none").reshape(len(ys), nx) \
                .mean(1) / a.seeds
        print(f"\nUniform light, {label}, {density:g} photons/m^2: E / truth by y / R")
        print("| method | " + " | ".join(f"{lo:g}-{hi:g}" for lo, hi in bands) + " |")
        print("|---" * (len(bands) + 1) + "|")
        for m in ("no edge",) + METHODS:
            cells = [acc[m][(ys >= lo * R) & (ys < hi * R + 1e-12)].mean() for lo, hi in bands]
            print(f"| {m} | " + " | ".join(f"{c:.3f}" for c in cells) + " |")

    # Lines near the edge: each method's integral against the control's (the same
    # photons 1 m from any edge, the estimate integrated across the whole line).
    ys = np.concatenate([np.linspace(0, 0.02, 41)[:-1], np.linspace(0.02, 1.3 * R, 120)])
    ys_far = np.concatenate([FAR - ys[:0:-1], FAR + ys])
    for label, per_metre in (("sparse", 100.0), ("dense", 2000.0)):
        print(f"\nA line of light near the edge, {label} ({per_metre:g} photons/m): "
              "integrated estimate / the same photons' with no edge (that one / the "
              "line's power in brackets), w50 mm")
        print("| method | " + " | ".join(f"{y0} mm power | w50" for y0 in (1, 3, 5)) + " |")
        print("|---" * 7 + "|")
        rows = {m: [] for m in METHODS}
        for y0 in (1, 3, 5):
            q, nx = query_grid(ys)
            q_far, _ = query_grid(ys_far)
            prof = {m: np.zeros(len(ys)) for m in METHODS}
            control = 0.0
            for seed in range(a.seeds):
                rng = np.random.default_rng(100 + seed)
                ph, pw = case_line(rng, k, R, y0 * 1e-3, per_metre)
                for m in METHODS:
                    prof[m] += run(m, ph, pw, q).reshape(len(ys), nx).mean(1) / a.seeds
                far = estimate(ph + [0.0, FAR], pw, q_far, k, R, "none")
                control += integrate_y(far.reshape(len(ys_far), nx).mean(1), ys_far) / a.seeds
            for m in METHODS:
                c = np.concatenate([[0.0], np.cumsum(0.5 * (prof[m][1:] + prof[m][:-1])
                                                     * np.diff(ys))])
                rows[m] += [c[-1] / control, 1e3 * np.interp(0.5 * c[-1], c, ys)]
            print(f"(control at {y0} mm: {control:.3f} of the line's power)")
        for m in METHODS:
            print(f"| {m} | " + " | ".join(f"{v:.3f}" if i % 2 == 0 else f"{v:.0f}"
                                           for i, v in enumerate(rows[m])) + " |")

    # A Gaussian blob near the edge.
    ys = np.linspace(0.0, 2.5 * R, 81)
    xs = np.linspace(1.0 - 2.5 * R, 1.0 + 2.5 * R, 81)
    X, Y = np.meshgrid(xs, ys)
    q = np.column_stack([X.ravel(), Y.ravel()])
    ys_full = np.concatenate([-ys[:0:-1], ys])
    Xf, Yf = np.meshgrid(xs, FAR + ys_full)
    q_far = np.column_stack([Xf.ravel(), Yf.ravel()])
    wf = np.where((Yf.ravel() == Yf.min()) | (Yf.ravel() == Yf.max()), 0.5, 1.0)
    print("\nA Gaussian blob (sigma 0.3 R) centred 0.3 R from the edge: power: integrated "
          "estimate / the same photons' with no edge; L1 / truth; E / truth at the edge "
          "(y < 0.1 R)")
    for label, n in (("sparse", 400), ("dense", 20000)):
        print(f"\n{label} ({n} photons)\n| method | power | L1 | edge |\n|---|---|---|---|")
        res = {m: np.zeros(3) for m in METHODS}
        for seed in range(a.seeds):
            rng = np.random.default_rng(200 + seed)
            ph, pw, c, s = case_blob(rng, k, R, n)
            truth = np.exp(-((q - c) ** 2).sum(1) / (2 * s * s)) / (2 * math.pi * s * s)
            cell = (xs[1] - xs[0]) * (ys[1] - ys[0])
            wy = np.where((Y.ravel() == 0) | (Y.ravel() == ys[-1]), 0.5, 1.0)
            edge = Y.ravel() < 0.1 * R
            far = estimate(ph + [0.0, FAR], pw, q_far, k, R, "none")
            control = (far * wf).sum() * cell
            for m in METHODS:
                e = run(m, ph, pw, q)
                res[m] += np.array([(e * wy).sum() * cell / control,
                                    np.abs(e - truth).mean() / truth.mean(),
                                    e[edge].sum() / truth[edge].sum()]) / a.seeds
        for m in METHODS:
            print(f"| {m} | " + " | ".join(f"{v:.3f}" for v in res[m]) + " |")
    print("\nCPU s (all cases): " + ", ".join(f"{m} {cpu[m]:.1f}" for m in METHODS))


if __name__ == "__main__":
    main()
