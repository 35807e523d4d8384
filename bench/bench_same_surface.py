"""Which photons an estimate accepts near object contacts (issue 14, surfaceid32): the
k-NN caustic estimate (k = 64, Simpson, cap 0.25 m) and the gather map's lookups on
photons uniform on synthetic surfaces, each ratio estimate / true irradiance (1 = right).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_same_surface.py [--seed 14] [--speed]

Candidates (columns):
  normal    the normal test alone (before: Photons.surface unknown)
  object    only the query's own object's photons (each query reads a map of its object's
            photons alone: the same estimator, nothing else accepted)
  coplanar  the query's object's photons, and another object's where it continues the
            query's plane (engine/samesurface.py: what the engine does now)
Scenes (rows):
  ball      400 balls of 5 cm resting on a floor (~20 photons in a ball's accepted cap,
            100 in the cap's disc on the floor): the ball's top (n_z > 0.9), the band
            0.5 < n_z < 0.9, its lower half, the floor within 0.15 m of a ball
  seam      a floor of two tiles (x < 0, x >= 0) and of four (quadrants): queries by their
            distance to the seam
  fold      a floor and a wall of ONE object (a box's inside corner): floor queries by their
            distance to the wall (the true irradiance is the floor's density)
  corner    the same floor and wall as two objects
  ramp      a floor and a 45-degree ramp as two objects (normals 0.71 apart: the normal
            test accepts the other's photons)
The "boundary" columns give the share of rows flagged as boundary (return_boundary: the
estimate's disc is not whole; a gather point's flag sends its lookups to gather again).
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from engine.photonmap import GatherMap, PhotonMap
from engine.photons import Photons

P = 1e-3  # W a photon
K = 64
CAP = 0.25


def photons(pos, nrm, surface):
    n = len(pos)
    nrm = np.broadcast_to(np.asarray(nrm, np.float32), (n, 3))
    return Photons(np.asarray(pos, np.float32), np.full((n, 3), P, np.float32), -nrm,
                   nrm.copy(), np.zeros(n, np.uint8), n,
                   surface=np.broadcast_to(np.asarray(surface, np.int32), (n,)).copy())


def joined(parts):
    return Photons(*(np.concatenate([getattr(p, f) for p in parts])
                     for f in ("position", "power", "direction", "normal", "kind")),
                   sum(len(p) for p in parts),
                   surface=np.concatenate([p.surface for p in parts]))


def plane(rng, density, origin, u, v, su, sv, normal, surface):
    """Photons uniform on the rectangle origin + [0, su] u + [0, sv] v."""
    n = rng.poisson(density * su * sv)
    a, b = rng.uniform(0, su, n), rng.uniform(0, sv, n)
    pos = np.asarray(origin) + a[:, None] * np.asarray(u) + b[:, None] * np.asarray(v)
    return photons(pos, normal, surface)


def estimate(ph, q, qn, qs, candidate):
    """(E (M,), boundary (M,)) by candidate (module docstring)."""
    if candidate == "object":
        E = np.zeros(len(q))
        bnd = np.ones(len(q), bool)
        for s in np.unique(qs):
            rows = np.flatnonzero(qs == s)
            pm = PhotonMap(ph.select(ph.surface == s))
            e, b = pm.irradiance(q[rows], qn[rows], CAP, K, 1, "knn_simpson",
                                 return_boundary=True)
            E[rows], bnd[rows] = e[:, 0], b
        return E, bnd
    pm = PhotonMap(ph)
    e, b = pm.irradiance(q, qn, CAP, K, 1, "knn_simpson", return_boundary=True,
                         surface=qs if candidate == "coplanar" else None)
    return e[:, 0], b


def gather(ph, q, qn, qs, candidate):
    """The gather map's lookups (no Accel): E (M,) and boundary (M,)."""
    if candidate == "object":
        return np.full(len(q), np.nan), np.zeros(len(q), bool)
    use = candidate == "coplanar"
    g = GatherMap(ph if use else Photons(ph.position, ph.power, ph.direction, ph.normal,
                                        ph.kind, ph.emitted), CAP, K, 1, "knn_simpson")
    E, b = g.lookup(q, qn, surface=qs if use else None)
    return E[:, 0], b


CANDIDATES = ("normal", "object", "coplanar")


def row(label, ph, q, qn, qs, truth, groups, with_gather=True):
    """Print one line per group (name, mask over the queries)."""
    got = {c: estimate(ph, q, qn, qs, c) for c in CANDIDATES}
    gat = {c: gather(ph, q, qn, qs, c) for c in CANDIDATES} if with_gather else {}
    for name, m in groups:
        cells = [f"{got[c][0][m].mean() / truth:.3f}" for c in CANDIDATES]
        cells += [f"{got[c][1][m].mean():.2f}" for c in CANDIDATES]
        if with_gather:
            cells += [f"{gat[c][0][m].mean() / truth:.3f}" if c != "object" else "-"
                      for c in CANDIDATES]
        else:
            cells += ["-"] * 3
        print(f"| {label} | {name} | {m.sum()} | " + " | ".join(cells) + " |", flush=True)


def ball_scene(rng):
    radius = 0.05
    density = 20 / (math.pi * radius * radius)
    count, spacing = 400, 1.0
    side = int(math.ceil(math.sqrt(count)))
    g = np.arange(count)
    centres = np.c_[(g % side) * spacing, (g // side) * spacing, np.full(count, radius)]
    m = rng.poisson(density * 4 * math.pi * radius * radius, count)
    u = rng.normal(size=(m.sum(), 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    balls = photons(np.repeat(centres, m, axis=0) + radius * u, u,
                    np.repeat(1 + g, m).astype(np.int32))
    floor_density = 100 / (math.pi * CAP * CAP)
    ext = side * spacing + 1.0
    floor = plane(rng, floor_density, (-0.5, -0.5, 0.0), (1, 0, 0), (0, 1, 0), ext, ext,
                  (0, 0, 1), 0)
    ph = joined([balls, floor])
    per = 16
    qu = rng.normal(size=(count * per, 3))
    qu /= np.linalg.norm(qu, axis=1)[:, None]
    q = np.repeat(centres, per, axis=0) + radius * qu
    qs = np.repeat(1 + g, per).astype(np.int32)
    nz = qu[:, 2]
    row("ball", ph, q, qu, qs, density * P,
        [("top n_z > 0.9", nz > 0.9), ("band 0.5-0.9", (nz > 0.5) & (nz <= 0.9)),
         ("lower half", nz < 0)])
    a = rng.uniform(0, 2 * math.pi, count)
    r = rng.uniform(radius, 0.15, count)
    qf = np.c_[centres[:, 0] + r * np.cos(a), centres[:, 1] + r * np.sin(a), np.zeros(count)]
    row("ball", ph, qf, np.tile([0.0, 0.0, 1.0], (count, 1)), np.zeros(count, np.int32),
        floor_density * P, [("floor within 0.15 m", np.ones(count, bool))])


def seam_scene(rng, tiles):
    density = 100 / (math.pi * CAP * CAP)
    h = 2.0
    parts = []
    if tiles == 2:
        parts.append(plane(rng, density, (-h, -h, 0), (1, 0, 0), (0, 1, 0), h, 2 * h,
                           (0, 0, 1), 0))
        parts.append(plane(rng, density, (0, -h, 0), (1, 0, 0), (0, 1, 0), h, 2 * h,
                           (0, 0, 1), 1))
    else:
        for i, (x0, y0) in enumerate([(-h, -h), (0, -h), (-h, 0), (0, 0)]):
            parts.append(plane(rng, density, (x0, y0, 0), (1, 0, 0), (0, 1, 0), h, h,
                               (0, 0, 1), i))
    ph = joined(parts)
    m = 4000
    q = np.c_[rng.uniform(-1.2, 1.2, (m, 2)), np.zeros(m)]
    qs = ((q[:, 0] >= 0).astype(np.int32) if tiles == 2 else
          ((q[:, 0] >= 0).astype(np.int32) + 2 * (q[:, 1] >= 0)).astype(np.int32))
    dist = np.abs(q[:, 0]) if tiles == 2 else np.minimum(np.abs(q[:, 0]), np.abs(q[:, 1]))
    row(f"seam, {tiles} tiles", ph, q, np.tile([0.0, 0.0, 1.0], (m, 1)), qs, density * P,
        [("seam < 0.05 m", dist < 0.05), ("0.05-0.15 m", (dist >= 0.05) & (dist < 0.15)),
         ("0.15-0.3 m", (dist >= 0.15) & (dist < 0.3)), ("beyond 0.3 m", dist >= 0.3)])


def fold_scene(rng, angle_deg, same_object, label):
    """A floor z = 0, x >= 0 and a second plane through the y axis rising at angle_deg from
    the floor over x < 0 (90: a wall), uniform photons on both; floor queries by distance
    to the fold."""
    density = 100 / (math.pi * CAP * CAP)
    h = 2.0
    floor = plane(rng, density, (0, -h, 0), (1, 0, 0), (0, 1, 0), h, 2 * h, (0, 0, 1), 0)
    t = math.radians(angle_deg)
    # the second plane: from the fold line, direction (-cos t, 0, sin t); its normal
    # faces the floor's side: (sin t, 0, cos t)
    u = (-math.cos(t), 0.0, math.sin(t))
    wall = plane(rng, density, (0, -h, 0), u, (0, 1, 0), h, 2 * h,
                 (math.sin(t), 0.0, math.cos(t)), 0 if same_object else 1)
    ph = joined([floor, wall])
    m = 3000
    q = np.c_[rng.uniform(0.0, 0.6, m), rng.uniform(-1.2, 1.2, m), np.zeros(m)]
    qs = np.zeros(m, np.int32)
    dist = q[:, 0]
    row(label, ph, q, np.tile([0.0, 0.0, 1.0], (m, 1)), qs, density * P,
        [("< 0.05 m", dist < 0.05), ("0.05-0.15 m", (dist >= 0.05) & (dist < 0.15)),
         ("0.15-0.3 m", (dist >= 0.15) & (dist < 0.3)), ("beyond 0.3 m", dist >= 0.3)])


def speed(rng):
    """CPU ns a k-NN row (k = 64, radius 0.1 m, best of 3) on 1M photons uniform on a
    plane of one object or two tiles, queries with and without their surfaces. Run it on
    another checkout (without surfaces: Photons has no surface there) for a before."""
    import time
    n, m = 1_000_000, 100_000
    pos = np.c_[rng.uniform(-2, 2, (n, 2)), np.zeros(n)].astype(np.float32)
    q = np.c_[rng.uniform(-1.5, 1.5, (m, 2)), np.zeros(m)]
    qn = np.tile([0.0, 0.0, 1.0], (m, 1))
    print("| photons' objects | queries | ns a row |\n|---|---|---:|")
    for tiles in (1, 2):
        surf = (pos[:, 0] >= 0).astype(np.int32) if tiles == 2 else np.zeros(n, np.int32)
        pm = PhotonMap(photons(pos, (0, 0, 1), surf))
        qs = (q[:, 0] >= 0).astype(np.int32) if tiles == 2 else np.zeros(m, np.int32)
        for label, kw in (("no surface", {}), ("with surfaces", {"surface": qs})):
            best = 1e9
            for _ in range(3):
                t = time.process_time()
                pm.irradiance(q, qn, 0.1, K, 1, "knn_simpson", True, **kw)
                best = min(best, time.process_time() - t)
            print(f"| {tiles} | {label} | {best / m * 1e9:.0f} |", flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=14)
    p.add_argument("--speed", action="store_true", help="the k-NN rows' cost instead")
    a = p.parse_args()
    rng = np.random.default_rng(a.seed)
    if a.speed:
        speed(rng)
        return
    print("| scene | queries | n | " + " | ".join(f"E {c}" for c in CANDIDATES) + " | "
          + " | ".join(f"boundary {c}" for c in CANDIDATES) + " | "
          + " | ".join(f"gather {c}" for c in CANDIDATES) + " |")
    print("|---|---|---:|" + "---:|" * 9)
    ball_scene(rng)
    seam_scene(rng, 2)
    seam_scene(rng, 4)
    fold_scene(rng, 90.0, True, "fold (one object)")
    fold_scene(rng, 90.0, False, "corner (wall + floor)")
    fold_scene(rng, 45.0, True, "45-degree fold (one object)")
    fold_scene(rng, 45.0, False, "ramp (two objects)")


if __name__ == "__main__":
    main()
