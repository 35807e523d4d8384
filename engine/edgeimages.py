"""Image photons across a surface's open edges: the reflection (mirror-image) method of
kernel density estimation at a boundary (Schuster 1985; Silverman 1986, s. 2.10), for the
caustic map's k-NN estimates.

A k-NN estimate's disc that hangs over the edge of the surface it sits on (a wall's end,
a table's rim, a floor meeting a wall: nothing beyond takes its light, or the surface
beyond faces another way and its photons are not accepted) loses the part of each
photon's kernel that falls beyond the edge. A line of caustic light right at a window
pane's foot integrates to ~0.52 of its power that way (docs/performance.md "edges"). Each
photon within the caustic cap R of such an edge gets an image: the same photon mirrored
across the edge in its surface's plane. The k-NN query then runs over photons and images,
so the kernel mass a photon loses beyond the edge comes back as its image's mass on the
surface: on a straight edge, the estimate of even light reads as far from any edge (the
images continue it) and a line's estimate integrates to its power (at a fixed radius
exactly; with k-NN radii within ~4 %, bench/bench_edges.py).

Open edges come from the mesh: an edge of a diffuse triangle is open unless another
diffuse triangle shares it (same corner positions) with a normal that the estimate would
accept (NORMAL_AGREEMENT). An image is dropped where a diffuse surface parallel to its
own lies within R of it along the normal, first met by a probe from R above it: the
surface continues past the edge (a wall made of separate planes meeting there), or a
rug, a step or a mat lies just above or below, whose photons the estimate's sphere
already reads (an image over it would count them twice).
A photon near two open edges on different lines (a corner) gets an image across each and,
where they meet at 60-120 degrees, one across both (CORNERS; the four quadrants of the
reflection method at a right angle). Used for the caustic map (cap: the caustic radius);
the secondary CAUSTIC_DIFFUSE map takes them too (render.SECONDARY_EDGE_IMAGES, with the
gaps rule: its wide radius would carry images across a gap narrower than 2 R, below). flatness_weights
tests the reflection's assumption (the density flat across the edge) per image: off.
Not handled: scenes with shared instances (Geometry.shared: no images anywhere), a photon
near three or more edges (a strip narrower than the cap: the two nearest lines only),
corners far from a right angle (the two edge images only, no third), curved edges (each
triangle edge straight), a parallel surface behind the first one the probe meets, a
coplanar surface across a gap narrower than 2 R (a window opening: its other sides'
estimates read the images lying in the gap).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from .photonmap import NORMAL_AGREEMENT
from .photons import Photons

PLANE_TOLERANCE = 1e-3  # x R: how far a photon may sit off an edge's triangle plane
FACING = 0.9  # |photon normal . triangle normal| for the photon to lie on that triangle
# Edge points a photon looks at: the edges through them are tested exactly. Two edges
# meet at each corner and a crease's two sides share their points (4 at a corner; a
# room's floor corner: 6, the walls' vertical edges too), and a photon near a corner must
# see the points of both its edges (CORNERS: a crease's 4 nearest points were all on it).
NEAREST_POINTS = 16
# Edge points listed at most (plus two an edge): bounds the listing's memory whatever
# the radius (a 1e-9 m radius on 10 m of edges asked for 8e10 points).
EDGE_POINT_BUDGET = 1 << 22
# Neighbour-cell keys the photon pre-filter lists at most (27 per occupied cell): cells
# widen until an edge's cells fit. A 1e-9 m radius put each of the 4M points in a cell of
# its own: 113M keys, 2.7 GB of listing, ~30 CPU s of page faults a map.
NEIGHBOUR_KEY_BUDGET = 1 << 22
PROBE_LIFT = 1.0  # x R: the probe starts this far above the image point, goes twice as far
# A photon near two open edges (a corner): images across both and across the corner
# (docs/performance.md "secedges"); False: across the nearer edge only.
CORNERS = True
SAME_LINE = 1.0 - 1e-6  # |m . m'| above this (and on the same offset): one line, two segments
CORNER_COS = 0.5  # |m . m'| below this: the two edges meet at 60-120 degrees, a corner image


def open_edges(geo, diffuse: np.ndarray):
    """The open edges of the diffuse triangles (docstring above). geo: Geometry with v0,
    e1, e2 (T,3) per triangle; diffuse (T,) bool. Returns a (E,3), b (E,3) the edge's ends,
    n (E,3) its triangle's unit normal, m (E,3) the unit direction in the triangle's plane,
    perpendicular to the edge, pointing into the triangle. Float64, re-centred space."""
    tri = np.flatnonzero(diffuse)
    if not len(tri):
        z = np.zeros((0, 3))
        return z, z, z, z
    v0 = np.take(geo.v0, tri, axis=0).astype(np.float64)
    c = np.stack([v0, v0 + np.take(geo.e1, tri, axis=0), v0 + np.take(geo.e2, tri, axis=0)],
                 axis=1)  # (T,3,3)
    ng = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    length = np.linalg.norm(ng, axis=1)
    ok = length > 0.0
    c, ng = c[ok], ng[ok] / length[ok, None]
    t = len(c)
    a = np.concatenate([c[:, 0], c[:, 1], c[:, 2]])  # edge j of triangle i: row j t + i
    b = np.concatenate([c[:, 1], c[:, 2], c[:, 0]])
    opp = np.concatenate([c[:, 2], c[:, 0], c[:, 1]])
    n = np.tile(ng, (3, 1))
    # The same edge from two triangles: the corners welded where their float32 positions
    # coincide (the meshes' corners are float32 before re-centring), an edge keyed by its
    # two corners' ids in order.
    corners = np.ascontiguousarray(np.concatenate([a, b]).astype(np.float32)) + np.float32(0.0)  # -0 == 0
    _, vid = np.unique(corners.view(np.dtype((np.void, 12))).ravel(), return_inverse=True)
    vid = vid.ravel().astype(np.int64)
    ia, ib = vid[:3 * t], vid[3 * t:]
    key = np.minimum(ia, ib) * (int(vid.max()) + 1) + np.maximum(ia, ib)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    group = np.cumsum(first) - 1
    size = np.bincount(group)[group]  # triangles on each row's edge, in sorted order
    closed = np.zeros(3 * t, bool)
    # An edge two triangles share (the common case): closed for both when their normals
    # agree.
    two = np.flatnonzero(first & (size == 2))
    agree = (n[order[two]] * n[order[two + 1]]).sum(axis=1) >= NORMAL_AGREEMENT
    closed[order[two[agree]]] = True
    closed[order[two[agree] + 1]] = True
    # More than two (a fin, a non-manifold seam): every pair.
    for s in np.flatnonzero(first & (size > 2)):
        rows = order[s:s + size[s]]
        dots = n[rows] @ n[rows].T
        np.fill_diagonal(dots, -2.0)
        closed[rows] = dots.max(axis=1) >= NORMAL_AGREEMENT
    is_open = ~closed
    a, b, n, opp = a[is_open], b[is_open], n[is_open], opp[is_open]
    u = b - a
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-300)[:, None]
    m = np.cross(n, u)
    # Into the triangle: towards its third corner.
    flip = ((opp - a) * m).sum(axis=1) < 0.0
    m[flip] *= -1.0
    return a, b, n, m


def _open_edges_kept(geo, diffuse):
    """open_edges, kept on the Geometry for its next photon pass (progressive passes, a
    session's re-renders: ~1.7 CPU us a triangle). The same value whichever thread writes
    it first; keyed by the diffuse mask, which the material table decides."""
    mask = np.packbits(diffuse).tobytes()
    kept = getattr(geo, "_open_edges", None)
    if kept is not None and kept[0] == mask:
        return kept[1]
    edges = open_edges(geo, diffuse)
    try:
        geo._open_edges = (mask, edges)
    except AttributeError:  # a read-only stand-in
        pass
    return edges


def edge_images(photons: Photons, geo, diffuse: np.ndarray, accel, radius: float,
                gaps: bool = False, flatness: bool = False):
    """Images (a Photons, possibly empty) of the photons within `radius` (m, the k-NN
    estimates' cap) of an open edge of the surface they lie on, mirrored across the
    nearest such edge, and near a corner across the nearest edge on another line and
    across both (CORNERS); power, direction, normal, kind and bounce counts copied.
    gaps: also drop an image lying within `radius` outside another open edge of a coplanar
    surface (a gap narrower than 2 radius, e.g. a window opening: that surface's own
    estimates would read it).
    flatness: each image's power scaled by flatness_weights (the density's linear
    extrapolation across the edge where it falls significantly towards the edge)."""
    empty = photons.take(np.zeros(0, np.int64))
    if not len(photons) or radius <= 0.0 or getattr(geo, "shared", None) is not None \
            or not getattr(geo, "count", 0):
        return empty
    a, b, n, m = _open_edges_kept(geo, diffuse)
    if not len(a):
        return empty
    # Points along every open edge `spacing` apart (radius / 2, wider where that would
    # list more than EDGE_POINT_BUDGET points: a tiny radius on long edges): a photon
    # within `radius` of an edge lies within reach = radius + spacing / 2 of a point.
    length = np.linalg.norm(b - a, axis=1)
    spacing = max(0.5 * radius, float(length.sum()) / EDGE_POINT_BUDGET)
    steps = np.maximum(np.ceil(length / spacing).astype(np.int64), 1)
    edge = np.repeat(np.arange(len(a)), steps + 1)
    first = np.r_[0, np.cumsum(steps + 1)[:-1]]
    frac = (np.arange(len(edge)) - np.repeat(first, steps + 1)) / np.repeat(steps, steps + 1)
    pts = a[edge] + frac[:, None] * (b - a)[edge]
    reach = radius + 0.5 * spacing
    # First the photons in or beside a cell holding an edge point: one sorted lookup per
    # photon (most of a caustic map's photons lie far from any edge). Cells of side reach,
    # or wider where more than 2^20 would span the points (their keys stay in int64), or
    # where the edges' cells' neighbours would list more than NEIGHBOUR_KEY_BUDGET keys (a
    # segment of length l crosses at most sqrt(3) l / cell + 1 cells; any side >= reach
    # keeps every photon within reach of a point in a neighbour of the point's cell).
    lo = pts.min(axis=0) - 2.0 * reach
    cell = max(reach, float((pts.max(axis=0) - lo).max() + 2.0 * reach) / (1 << 20),
               27.0 * math.sqrt(3.0) * float(length.sum()) / NEIGHBOUR_KEY_BUDGET)
    cell_pts = np.floor((pts - lo) / cell).astype(np.int64)
    dims = cell_pts.max(axis=0) + 3
    shifts = np.stack(np.meshgrid(*([np.arange(-1, 2)] * 3), indexing="ij"), -1).reshape(-1, 3)
    # The occupied cells once each before their 27 neighbours are listed: many small
    # separate faces (foliage, a triangle soup) put millions of edge points in few cells.
    occupied = np.unique((cell_pts[:, 0] * dims[1] + cell_pts[:, 1]) * dims[2] + cell_pts[:, 2])
    cell_pts = np.stack([occupied // (dims[1] * dims[2]), (occupied // dims[2]) % dims[1],
                         occupied % dims[2]], axis=1)
    near_cells = (cell_pts[:, None, :] + shifts[None]).reshape(-1, 3)
    keys = np.unique((near_cells[:, 0] * dims[1] + near_cells[:, 1]) * dims[2] + near_cells[:, 2])
    cell_ph = np.floor((photons.position - lo) / cell)
    inside = np.all((cell_ph >= 0) & (cell_ph < dims), axis=1)
    cand = np.flatnonzero(inside)
    c = cell_ph[cand].astype(np.int64)
    k = (c[:, 0] * dims[1] + c[:, 1]) * dims[2] + c[:, 2]
    at = np.minimum(np.searchsorted(keys, k), len(keys) - 1)
    cand = cand[keys[at] == k]
    if not len(cand):
        return empty
    p = photons.position.astype(np.float64)
    # Each candidate's NEAREST_POINTS nearest edge points within reach, then the edges
    # through them tested exactly.
    tree = cKDTree(pts)
    _, j = tree.query(p[cand], k=NEAREST_POINTS, distance_upper_bound=reach)
    found = j < len(pts)
    if not found.any():
        return empty
    ph = np.broadcast_to(cand[:, None], j.shape)[found]
    e = edge[j[found]]
    pair = np.unique(ph * len(a) + e)  # each (photon, edge) once
    ph, e = pair // len(a), pair % len(a)
    rel = p[ph] - a[e]
    ab = b[e] - a[e]
    along = (rel * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300)
    d = (rel * m[e]).sum(axis=1)  # distance into the triangle's side of the edge
    off = np.abs((rel * n[e]).sum(axis=1))
    facing = np.abs((photons.normal[ph].astype(np.float64) * n[e]).sum(axis=1))
    keep = (along >= 0.0) & (along <= 1.0) & (d >= 0.0) & (d < radius) & \
        (off <= PLANE_TOLERANCE * radius) & (facing >= FACING)
    ph, e, d = ph[keep], e[keep], d[keep]
    if not len(ph):
        return empty
    # The nearest edge per photon.
    order = np.lexsort((d, ph))
    ph, e, d = ph[order], e[order], d[order]
    firsts = np.r_[True, ph[1:] != ph[:-1]]
    start = np.cumsum(firsts) - 1  # each row's photon group
    e1 = e[firsts][start]  # its nearest edge, on every row of the group
    ph1, e1d, d1 = ph[firsts], e[firsts], d[firsts]
    image = p[ph1] - 2.0 * d1[:, None] * m[e1d]
    images, owners, normals = [image], [ph1], [n[e1d]]
    used = [np.column_stack([e1d, e1d])]  # the edges each image is mirrored across
    parents = np.zeros((0, 2), np.int64)  # a corner image's two edge images' rows
    if CORNERS:
        # A corner: the nearest edge on another line (not the nearest's own line split
        # into segments at the mesh's vertices) gets its image too, and where the two
        # lines meet at 60-120 degrees the image across both (the photon reflected across
        # the first edge, then the second: exact for a right angle, as the reflection
        # method's four quadrants; a wedge of another angle would need more images).
        same_line = (np.abs((m[e] * m[e1]).sum(axis=1)) > SAME_LINE) & \
            (np.abs(((a[e] - a[e1]) * m[e1]).sum(axis=1)) <= PLANE_TOLERANCE * radius)
        other = np.flatnonzero(~same_line)
        if len(other):
            sec = other[np.r_[True, ph[other][1:] != ph[other][:-1]]]
            ph2, e2, d2 = ph[sec], e[sec], d[sec]
            first_of = np.searchsorted(ph1, ph2)
            images.append(p[ph2] - 2.0 * d2[:, None] * m[e2])
            owners.append(ph2)
            normals.append(n[e2])
            used.append(np.column_stack([e2, e2]))
            square = np.abs((m[e2] * m[e1d[first_of]]).sum(axis=1)) < CORNER_COS
            if square.any():
                q = image[first_of[square]]
                e2s = e2[square]
                off = ((q - a[e2s]) * m[e2s]).sum(axis=1)
                images.append(q - 2.0 * off[:, None] * m[e2s])
                owners.append(ph2[square])
                normals.append(n[e2s])
                used.append(np.column_stack([e1d[first_of[square]], e2s]))
                parents = np.column_stack([first_of[square],
                                           len(ph1) + np.flatnonzero(square)])
    image, ph, nrm = np.concatenate(images), np.concatenate(owners), np.concatenate(normals)
    used = np.concatenate(used)
    gap = np.zeros(len(ph), bool)
    if gaps:
        _, j = tree.query(image, k=NEAREST_POINTS, distance_upper_bound=reach)
        found = j < len(pts)
        im = np.broadcast_to(np.arange(len(ph))[:, None], j.shape)[found]
        g = edge[j[found]]
        rel = image[im] - a[g]
        ab = b[g] - a[g]
        along = (rel * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300)
        dg = (rel * m[g]).sum(axis=1)
        coplanar = (np.abs((n[g] * nrm[im]).sum(axis=1)) >= FACING) & \
            (np.abs((rel * n[g]).sum(axis=1)) <= PLANE_TOLERANCE * radius)
        other = np.ones(len(im), bool)
        for c in (0, 1):
            u = used[im, c]
            other &= ~((np.abs((m[g] * m[u]).sum(axis=1)) > SAME_LINE) &
                       (np.abs(((a[g] - a[u]) * m[u]).sum(axis=1)) <= PLANE_TOLERANCE * radius))
        hit = coplanar & other & (along >= 0.0) & (along <= 1.0) & (dg < 0.0) & (dg > -radius)
        gap[im[hit]] = True
    # Drop images over a parallel diffuse surface within R along the normal (the surface
    # continues, or lies close enough for the estimate's sphere to read its photons).
    lift = PROBE_LIFT * radius
    origin = image + lift * nrm
    t, prim, _, _ = accel.intersect(origin, -nrm, np.full(len(ph), 2.0 * lift))
    cont = prim >= 0
    if cont.any():
        hit = prim[cont]
        hn = np.cross(np.take(geo.e1, hit, axis=0), np.take(geo.e2, hit, axis=0))
        hn /= np.maximum(np.linalg.norm(hn, axis=1), 1e-300)[:, None]
        same = diffuse[hit] & (np.abs((hn * nrm[cont]).sum(axis=1)) >= NORMAL_AGREEMENT)
        cont[np.flatnonzero(cont)[~same]] = False
    cont |= gap
    if len(parents):
        # A corner image stands for the light beyond both edges: where either edge's own
        # image is dropped (the surface continues past that edge), that surface's photons
        # bring their own images there.
        cont[len(ph) - len(parents):] |= cont[parents[:, 0]] | cont[parents[:, 1]]
    ph, image, used = ph[~cont], image[~cont], used[~cont]
    weight = None
    if flatness and len(ph):
        weight = flatness_weights(photons, p, ph, used, a, n, m, radius)
        ph, image, weight = ph[weight > 0.0], image[weight > 0.0], weight[weight > 0.0]
    out = photons.take(ph)
    out.position = image.astype(np.float32)
    if weight is not None:
        out.power = (out.power * weight[:, None]).astype(out.power.dtype)
    return out


# flatness_weights: the strip of the surface beside an edge whose photons give the slope,
# STRIP_HALF_LENGTH x radius along the edge either side of the photon's foot, radius deep.
STRIP_HALF_LENGTH = 2.0
# A slope acts only beyond this many of its standard errors (a flat density's strip of ~80
# photons gives the slope s = f'R/f(0) a standard error ~0.4: unshrunk, the weights' noise
# would blotch every edge by ~20 %).
SLOPE_SIGMAS = 2.0
SLOPE_SE_MAX = float("inf")  # see flatness_weights (an experiment: 0.5 ~ 50 photons a strip)


def flatness_weights(photons: Photons, p: np.ndarray, ph: np.ndarray, used: np.ndarray,
                     a, n, m, radius: float) -> np.ndarray:
    """(I,) weights in [0, 1] of images of photons ph (I,) mirrored across edges used (I,2)
    (two equal columns: one edge; else a corner image across both: the product).

    The reflection method assumes the density flat across the edge (f'(0) = 0): for a
    density f(y) = f0 + f1 y (y: distance into the surface) the images continue it as
    f0 + f1 |y|, and an estimate at the edge reads f0 + ~0.42 f1 R (too bright where the
    light falls towards the edge: a room's dim corner beside a bright middle). The images
    of the linear extrapolation f(-y) = 2 f0 - f(y) instead: each image weighted by
    (2 f0 - f(y)) / f(y) = (1 - s y / R) / (1 + s y / R), s = f1 R / f0, from the power-
    weighted mean depth of the photons in the strip beside the edge (STRIP_HALF_LENGTH R
    along it, R deep; E[y] / R = (1/2 + s/3) / (1 + s/2)), shrunk by SLOPE_SIGMAS standard
    errors towards 0. Only s > 0 (darker at the edge) acts: where the light rises towards
    the edge (a line at a pane's foot, s < 0) the reflection stays (exact for a line, and
    never adds more than it)."""
    corner = used[:, 0] != used[:, 1]
    pairs = np.unique(np.concatenate([ph * len(a) + used[:, 0],
                                      ph[corner] * len(a) + used[corner, 1]]))
    pp, pe = pairs // len(a), pairs % len(a)
    d = ((p[pp] - a[pe]) * m[pe]).sum(axis=1)
    u = np.cross(n[pe], m[pe])  # along the edge
    centre = p[pp] + (0.5 * radius - d)[:, None] * m[pe]
    half = STRIP_HALF_LENGTH * radius
    tree = cKDTree(p)
    lists = tree.query_ball_point(centre, np.hypot(half, 0.5 * radius), return_sorted=False)
    count = np.fromiter((len(x) for x in lists), np.int64, len(lists))
    q = np.fromiter((i for x in lists for i in x), np.int64, int(count.sum()))
    row = np.repeat(np.arange(len(pairs)), count)
    e = pe[row]
    rel = p[q] - a[e]
    y = (rel * m[e]).sum(axis=1)
    ok = (y >= 0.0) & (y <= radius) & \
        (np.abs(((p[q] - p[pp[row]]) * u[row]).sum(axis=1)) <= half) & \
        (np.abs((rel * n[e]).sum(axis=1)) <= PLANE_TOLERANCE * radius) & \
        (np.abs((photons.normal[q].astype(np.float64) * n[e]).sum(axis=1)) >= FACING)
    row, y = row[ok], y[ok] / radius
    pw = photons.power[q[ok]].astype(np.float64).mean(axis=1)
    sw = np.bincount(row, pw, len(pairs))
    sw2 = np.bincount(row, pw * pw, len(pairs))
    mean = np.bincount(row, pw * y, len(pairs)) / np.maximum(sw, 1e-300)
    var = np.maximum(np.bincount(row, pw * y * y, len(pairs)) / np.maximum(sw, 1e-300)
                     - mean * mean, 0.0)
    n_eff = sw * sw / np.maximum(sw2, 1e-300)
    # The lower bound of the mean depth: s(mean) rises with it (12 at a flat 1/2; infinite
    # at 2/3, where f0 = 0: no image).
    se = np.sqrt(var / np.maximum(n_eff - 1.0, 1.0))
    low = mean - SLOPE_SIGMAS * se
    # Too few photons beside the edge to tell flat light from a slope (s's standard error,
    # ~12 that of the mean depth, above SLOPE_SE_MAX): no image (the reflection unchecked).
    untested = (n_eff < 4.0) | (12.0 * se > SLOPE_SE_MAX)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(low >= 2.0 / 3.0, np.inf, (0.5 - low) / (0.5 * low - 1.0 / 3.0))
        s = np.maximum(s, 0.0)
        t = s * np.clip(d / radius, 0.0, 1.0)
        pair_w = np.where(np.isinf(s) | untested, 0.0,
                          np.clip((1.0 - t) / (1.0 + t), 0.0, 1.0))
    w = pair_w[np.searchsorted(pairs, ph * len(a) + used[:, 0])]
    w[corner] *= pair_w[np.searchsorted(pairs, ph[corner] * len(a) + used[corner, 1])]
    return w
