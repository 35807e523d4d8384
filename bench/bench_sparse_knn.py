"""The sparse k-NN radius rule (photonmap.SPARSE_MIN_ACCEPTED, caustic31) in a numpy model:
where fewer than k accepted photons lie within the cap, the estimate's radius is the last
accepted photon's distance when there are at least n0 of them, else the cap.

    .venv/bin/python bench/bench_sparse_knn.py

Prints, per n0 (and the cap alone, as before caustic31): the mean estimate / truth over
queries uniform on the lit half of a sunlit sphere alone (no floor; photons Poisson with
density 882 / m^2 across the sun's beam, the bench_small_object_caustic scene's; cap
0.2434 m, k = 64, normal agreement 0.5), and on a plane with 2 photons a cap disc on
average: mean, 99.9th percentile and largest estimate / truth (the fireflies of a small
last distance). Seeded.

Measured 2026-12-04 (3 s): the cap 0.103 / 0.376 (ball R 0.05 / 0.1), plane 0.997, 5.2,
6.7; n0 = 2: 0.873 / 0.944, 0.998, 12.5, 84.4; n0 = 3 (chosen): 0.770 / 0.944, 1.000,
8.6, 30.3; n0 = 4: 0.613 / 0.942, 0.998, 7.3, 15.5.
"""
import math

import numpy as np

K = 64
AGREE = 0.5
CAP = 0.2434
RHO = 3 / 0.0034  # photons / m^2 across the beam: 3 W/m^2 sun, 0.0034 W photons
SUN = np.array([0.3, 0.2, -1.0]) / np.linalg.norm([0.3, 0.2, -1.0])


def estimate(d, n0):
    """Simpson k-NN estimate (photons of power 1) from the accepted photons' distances d."""
    d = np.sort(d)[:K]
    n = len(d)
    if n == 0:
        return 0.0
    r = d[n - 1] if n >= min(n0, K) else CAP  # (n = K: the k-th, as always)
    return float((3 / (math.pi * r * r) * np.clip(1 - (d / r) ** 2, 0, 1) ** 2).sum())


def sphere(radius, n0, rng, trials=300, per=40):
    """Mean estimate / truth on the lit half of a sunlit ball of `radius` m."""
    u = np.cross(SUN, [1, 0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(SUN, u)
    got = want = 0.0
    for _ in range(trials):
        m = rng.poisson(RHO * math.pi * radius * radius)
        r = radius * np.sqrt(rng.random(m))
        a = 2 * math.pi * rng.random(m)
        x, y = r * np.cos(a), r * np.sin(a)
        z = np.sqrt(np.maximum(radius * radius - x * x - y * y, 0))
        pts = np.outer(x, u) + np.outer(y, v) - np.outer(z, SUN)
        nrm = pts / radius
        g = rng.normal(size=(per, 3))
        g /= np.linalg.norm(g, axis=1)[:, None]
        g[g @ SUN > 0] *= -1
        for nq in g:
            d = np.linalg.norm(pts - radius * nq, axis=1)
            ok = (d <= CAP) & (nrm @ nq > AGREE)
            got += estimate(d[ok], n0)
            want += RHO * max(-(nq @ SUN), 0.0)
    return got / want


def plane(n0, rng, per_disc=2.0, trials=20000):
    """(mean, 99.9th percentile, max) of estimate / truth at a point of a sparse plane."""
    rho = per_disc / (math.pi * CAP * CAP)
    vals = np.empty(trials)
    for t in range(trials):
        d = CAP * np.sqrt(rng.random(rng.poisson(per_disc)))
        vals[t] = estimate(d, n0) / rho
    return vals.mean(), np.percentile(vals, 99.9), vals.max()


def main():
    print("| n0 | ball R 0.05 | ball R 0.1 | plane 2 a disc: mean | p99.9 | max |")
    print("|---|---:|---:|---:|---:|---:|")
    for n0 in (10 ** 9, 2, 3, 4):
        rs = np.random.default_rng(7)
        b = [sphere(r, n0, rs) for r in (0.05, 0.1)]
        m, p, x = plane(n0, np.random.default_rng(3))
        name = "cap" if n0 > K else str(n0)
        print(f"| {name} | {b[0]:.3f} | {b[1]:.3f} | {m:.3f} | {p:.1f} | {x:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
