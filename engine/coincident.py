"""Rays that leave a glass face another surface touches meet that surface there.

A glass object resting on a floor (a bottle whose bottom cap lies in the floor's plane, as
Blender users place it) has two surfaces at the same place. A ray leaving either of them
starts a rounding-error offset to the side it leaves (pbrt-v4's OffsetRayOrigin,
engine/rayoffset.py): past the other surface too, so it never meets it. A ray refracted
out through the cap sees whatever lies under the floor (the world, in a product shot), a
photon refracted out through it is lost there, and a ray leaving the floor upwards
starts inside the glass without being refracted into it (and is then totally reflected
at the glass's far faces it would have left). Cycles offsets no origin: it skips only the
primitive the ray leaves (kernel/bvh/util.h intersection_skip_self), so the ray meets the
other surface right there. Measured (issue 14 product shot, product29): red-emitting
floor and green world, the camera ray through the top of a smooth-shaded glass cylinder
standing on the floor, pixels' colours floor / world: Cycles 0.96 / 0.04, ours 0.73 /
0.27; the cylinder lifted 3 mm: Cycles 0.92 / 0.05, ours 0.93 / 0.04. Cycles' own light
through the contact depends on its rounding there (a floor at z = 0 loses it, the same
scene moved up 1.913 m or the glass lifted 0.1 mm does not: docs/accuracy.md, contact30);
ours now reads at contact as with a small gap.

`CoincidentSurfaces` gives every ray that leaves such a pair (camera paths,
final-gather and regather continuations, photons) what Cycles gives it: a short probe
from the mirror image of the ray's origin (the other side of the face it left, as far
from it) along the ray, against a BVH of the partner surfaces; a hit within twice the
offset's reach is a surface at the point the ray left, and the ray meets it there
(t = 0). The pairs:

- a ray leaving a glass triangle (any material with a transmission lobe) outwards
  (d . n > 0, n its winding normal: refracted out, or reflected off its outside) probes
  the non-glass triangles that touch glass: the floor under a bottle;
- a ray leaving a non-glass triangle that touches glass probes the glass triangles that
  touch a non-glass one, and meets one only from its outside (d . n < 0): it is
  refracted into the bottle (or reflected back down to the floor by Fresnel);
- a ray that left a glass triangle and whose closest hit is a touching non-glass one
  where a glass face lies too, crossed outwards, meets that glass face first
  (leave_glass_first): Embree returns either of two coincident triangles, and a photon
  inside the bottle that met the floor directly kept the entry's 1 / n^2;
- a photon that met such a glass face from inside and is reflected back into the glass
  (Fresnel, total internal reflection) goes into the touching surface and ends
  (reflected_inside, meet_hits' arrived): Cycles' reflected ray starts on that surface's
  plane and meets it there in most placements (7 of 10 tried; the others pass as through
  a gap). A pane standing on a sill threw the sun's total reflection off its bottom face
  onto the ceiling as a bright line (docs/accuracy.md, streak41);
- with CYCLES_CONTACT (default): a camera or gather ray leaving such a glass face into
  the glass (reflected off its inside, or refracted in from the touching surface) meets
  the touching surface there, on its back face (meet's `inward`), and a photon refracted
  out of the glass onto the touching surface ends (meet_hits). So no light crosses the
  contact either way, as in Cycles 5.0 at every placement tried for a lathed glass on a
  table top (docs/accuracy.md, smoothglass48): the table under the glass reads dark
  (Cycles 0.040 of a white World, 0.79 raised 0.1 mm), and a Shade Smooth glass, whose
  bent normals guide camera rays down its walls to the base, loses them there (a
  kitchen's drinking glass 1.64x Cycles before). Off: contact reads as a small gap
  (contact30), but for the photons' inner reflections.

"Touch" is faces in contact: boxes that meet and the glass triangle's corners in the
other's plane, both to TOUCH_PAD of the coordinates (a cost filter: the probe's reach
decides; a ball resting on the floor touches it at a point, where no probe would find
anything, and makes no pair); each kind probes only the BVH of the other, so the probe
cannot stop at the face the ray left (embreex has no per-ray primitive filter). A scene
whose glass touches nothing gets no instance (for_context: None) and costs nothing.
Not handled (the offset's behaviour kept): glass touching glass, shared instances
(two-level BVHs), meshes whose winding points inwards, rays inside the glass that last
left something else (an object inside the bottle).
"""
from __future__ import annotations

import threading

import numpy as np

from .accel import Accel
from .closures import principled as pr
from .geometry import TRANSMISSION

# Probe reach, in offsets along the left face's normal: the mirrored origin is one
# offset behind the face; a surface within one more offset past it coincides with it.
REACH = 2.0
# Directions more grazing than this cosine to the face take this cosine's reach (a probe
# of at most REACH / MIN_COS offsets: micrometres).
MIN_COS = 1e-3
# Bounding boxes closer than this share of the largest coordinate (plus as much of the
# scene's size) touch: ~1e-5, 100x the offsets' 1e-7 (rayoffset.G32_PLANE), so every pair
# the probe can find is kept; a larger pad costs only probes that find nothing.
TOUCH_PAD = 1e-5
# leave_glass_first's window along the ray, a share of (t + the hit's largest coordinate):
# 64 float32 roundings (Embree's distances to two coincident planes differ by a few).
TIE = 64 * 2.0 ** -24
# Glass x other pairs tested in one numpy block (bounded scratch memory), and the most
# tested at all: beyond it every near triangle counts as touching (more probes, the same
# answers).
PAIR_BLOCK = 1 << 22
PAIR_LIMIT = 1 << 28
# Cycles' contact (docs/accuracy.md, smoothglass48): camera and final-gather rays leaving
# a touching glass face into the glass (reflected off its inside, or refracted in from
# the touching surface) meet the touching surface there, on its back face (meet's
# `inward`), and photons refracted out of the glass onto it end (meet_hits): no light
# crosses the contact, as in Cycles, which skips only the primitive a ray leaves and so
# meets the coincident face at t = 0 whichever way the ray goes. Photons reflected back
# inside end either way (streak41). False: contact reads as a small gap (contact30).
CYCLES_CONTACT = True

NONE, GLASS, OTHER = 0, 1, 2  # a triangle's side of a touching pair (CoincidentSurfaces.side)

_LOCK = threading.Lock()


class _Partners:
    """One kind's BVH (Accel, single-threaded: safe to share between threads), its
    triangle rows into the full table (K,) int64, their padded bounding box (2,3)."""

    def __init__(self, geo, tri, pad):
        corners = [np.take(c, tri, axis=0) for c in (geo.v0, geo.v0 + geo.e1, geo.v0 + geo.e2)]
        verts = np.stack(corners, axis=1).reshape(-1, 3).astype(np.float32)
        faces = np.arange(len(verts), dtype=np.int32).reshape(-1, 3)
        self.accel = Accel(verts, faces, threads=1)
        self.tri = tri
        self.box = np.stack([np.minimum.reduce(corners).min(axis=0) - pad,
                             np.maximum.reduce(corners).max(axis=0) + pad])


class CoincidentSurfaces:
    """The touching pairs of a prepared scene: side (T,) int8 per triangle (NONE, GLASS:
    a glass triangle some non-glass one touches, OTHER: a non-glass triangle touching
    glass), is_glass (T,) bool the glass triangles of the objects with a pair, the BVH of
    each kind (`glass`, `others`: _Partners) and the geometry."""

    def __init__(self, geo, side, is_glass, glass, others):
        self.geo = geo
        self.side = side
        self.is_glass = is_glass
        self.glass = glass
        self.others = others
        self._paired_ng = None  # (_ng: the paired triangles' rows, their normals)
        self._boxes = {}  # (near: the partners' boxes (2,2,3) by the points' dtype)

    def _ng(self, tri) -> np.ndarray:
        """(K,3) geo.ng[tri] for triangle rows tri (K,) int64: the paired triangles' (side
        not NONE: every row the probes ask for) from a table made once, any other from
        geo.ng. (geo.ng makes its rows on each read, a cross product and a norm per call:
        ~1.3 of the candles' 51 camera-pass CPU s under the profiler, docs/performance.md
        "percost54"; a row's normal depends on its triangle alone: the same bits.)"""
        tri = np.asarray(tri, np.int64)
        got = self._paired_ng
        if got is None:
            paired = np.flatnonzero(self.side != NONE).astype(np.int64)
            got = self._paired_ng = (paired, np.asarray(self.geo.ng[paired]))
        paired, ng = got
        if not len(paired):
            return self.geo.ng[tri]
        at = np.minimum(np.searchsorted(paired, tri), len(paired) - 1)
        known = np.take(paired, at) == tri
        if known.all():
            return np.take(ng, at, axis=0)
        out = np.take(ng, at, axis=0)
        out[~known] = self.geo.ng[tri[~known]]
        return out

    @classmethod
    def for_context(cls, ctx) -> "CoincidentSurfaces | None":
        """The scene's instance, built once per prepared geometry on first use; None when
        no glass triangle touches another one (no glass, nothing near it), or with shared
        instances (a two-level BVH: not handled)."""
        geo = ctx.geo
        cached = geo.__dict__.get("_coincident", False)
        if cached is not False:
            return cached
        with _LOCK:
            cached = geo.__dict__.get("_coincident", False)
            if cached is not False:
                return cached
            made = None
            params = np.asarray(ctx.table.closure_params)
            glass = params[:, pr.M_TRANS] > 0
            if (glass.any() and getattr(geo, "instances", None) is None
                    and getattr(geo, "shared", None) is None):
                made = cls._build(geo, glass)
            geo.__dict__["_coincident"] = made
            return made

    @classmethod
    def _build(cls, geo, glass_mat):
        """The touching pairs over the triangles the transmission rays see (corners from
        the Geometry's float64 v0, e1, e2; the BVHs' corners unshared). None when none."""
        seen = (np.asarray(geo.visibility, np.int64) & TRANSMISSION) != 0
        is_glass = np.take(glass_mat, np.asarray(geo.material, np.int64)) & seen
        g_tri = np.nonzero(is_glass)[0]
        o_tri = np.nonzero(seen & ~is_glass)[0]
        if not len(g_tri) or not len(o_tri):
            return None
        corners = (geo.v0, geo.v0 + geo.e1, geo.v0 + geo.e2)

        def boxes(tri):
            c = [np.take(x, tri, axis=0) for x in corners]
            return np.minimum.reduce(c), np.maximum.reduce(c)

        glo, ghi = boxes(g_tri)
        scale = max(float(np.abs(glo).max(initial=0.0)), float(np.abs(ghi).max(initial=0.0)))
        pad = TOUCH_PAD * (scale + max(float(geo.extent), 0.0))
        olo, ohi = boxes(o_tri)
        # The others that reach into the glass's box at all.
        near = np.all((ohi >= glo.min(axis=0) - pad) & (olo <= ghi.max(axis=0) + pad), axis=1)
        o_tri, olo, ohi = o_tri[near], olo[near], ohi[near]
        if not len(o_tri):
            return None
        g_touch = np.zeros(len(g_tri), bool)
        o_touch = np.zeros(len(o_tri), bool)
        if len(g_tri) * len(o_tri) > PAIR_LIMIT:
            g_touch[:] = o_touch[:] = True
        else:
            # A pair: boxes that meet, and the glass triangle in the other's plane (all
            # three corners within the pad): faces in contact. A ball resting on the
            # floor (one corner on it) or a box's side faces (an edge on it) touch only
            # along a set of no area, where no probe would find anything.
            gc = [np.take(x, g_tri, axis=0) for x in corners]
            on = np.cross(np.take(geo.e1, o_tri, axis=0), np.take(geo.e2, o_tri, axis=0))
            on /= np.maximum(np.linalg.norm(on, axis=1), 1e-300)[:, None]
            od = np.einsum("ij,ij->i", on, np.take(geo.v0, o_tri, axis=0))
            step = max(1, PAIR_BLOCK // len(o_tri))
            for a in range(0, len(g_tri), step):
                b = min(a + step, len(g_tri))
                hit = np.all((ohi[None] >= glo[a:b, None] - pad)
                             & (olo[None] <= ghi[a:b, None] + pad), axis=2)
                gi, oi = np.nonzero(hit)
                flat = np.ones(len(gi), bool)
                for c in gc:
                    dist = np.einsum("ij,ij->i", c[a + gi], on[oi]) - od[oi]
                    flat &= np.abs(dist) <= pad
                g_touch[a + gi[flat]] = True
                o_touch[oi[flat]] = True
        if not g_touch.any():
            return None
        side = np.zeros(geo.count, np.int8)
        side[g_tri[g_touch]] = GLASS
        side[o_tri[o_touch]] = OTHER
        # The triangles a ray inside a paired glass object last left: that object's glass
        # (leave_glass_first; a ray inside another glass object leaves it first).
        oid = np.asarray(geo.object_id, np.int64)
        paired = np.isin(oid, np.unique(np.take(oid, g_tri[g_touch])))
        in_pair = np.take(glass_mat, np.asarray(geo.material, np.int64)) & paired
        return cls(geo, side, in_pair, _Partners(geo, g_tri[g_touch], pad),
                   _Partners(geo, o_tri[o_touch], pad))

    def near(self, p, tri) -> np.ndarray:
        """(N,) bool: rays leaving the points p (N,3) (float32 or float64; a ray origin
        will do: the boxes' pad is ~100 offsets) on triangles tri (N,) int64 (< 0: none)
        may meet a touching surface there: tri is one of a pair and p lies in its
        partners' box (probe's first tests, one axis at a time; False everywhere lets a
        caller keep a faster path)."""
        from .gatherkernels import touch_near
        p = np.ascontiguousarray(p)
        if p.dtype != np.float32:
            p = np.ascontiguousarray(p, np.float64)
        boxes = self._boxes.get(p.dtype)
        if boxes is None:
            # (in p's dtype: numpy compared a float32 p with the float64 box in float32)
            boxes = self._boxes[p.dtype] = np.stack(
                [self.others.box, self.glass.box]).astype(p.dtype)
        out = np.empty(len(tri), bool)
        touch_near(self.side, np.ascontiguousarray(tri, np.int64), p, boxes, GLASS, OTHER,
                   out)
        return out

    def probe(self, p, off, d, from_tri):
        """Where rays leaving the points p (N,3) (hits on triangles from_tri (N,) int64,
        < 0: none), their origins moved off the face by off (N,3) (o = p + off), in
        directions d (N,3), meet a touching surface at the point they leave. Returns
        (rows (K,) int64 into the N, tri (K,) int64 the met triangles' rows, u, v (K,)
        float32 barycentrics there); K = 0 mostly."""
        side = np.take(self.side, np.maximum(from_tri, 0))
        side[from_tri < 0] = NONE
        out = []
        for kind, partners in ((GLASS, self.others), (OTHER, self.glass)):
            rows = np.nonzero(side == kind)[0]
            if not len(rows):
                continue
            pr_ = np.take(p, rows, axis=0)
            box = partners.box
            inside = np.all((pr_ >= box[0]) & (pr_ <= box[1]), axis=1)
            if not inside.any():
                continue
            rows, pr_ = rows[inside], pr_[inside]
            dr = np.take(d, rows, axis=0)
            if kind == GLASS:
                # Only rays moving out of the glass (refracted out, or reflected off its
                # outside) can meet what lies against its outside.
                out_ = np.einsum("ij,ij->i", self._ng(from_tri[rows]), dr) > 0.0
                rows, pr_, dr = rows[out_], pr_[out_], dr[out_]
                if not len(rows):
                    continue
            of = np.take(off, rows, axis=0)
            reach = np.sqrt(np.einsum("ij,ij->i", of, of))
            ok = (reach > 0) & np.isfinite(reach)
            if not ok.all():
                rows, pr_, dr, of, reach = rows[ok], pr_[ok], dr[ok], of[ok], reach[ok]
            if not len(rows):
                continue
            cos = np.abs(np.einsum("ij,ij->i", of, dr)) / reach
            tmax = REACH * reach / np.maximum(cos, MIN_COS)
            _, hp, up, vp = partners.accel.intersect(pr_ - of, dr, tmax)
            found = hp >= 0
            if not found.any():
                continue
            rows, tri = rows[found], partners.tri[hp[found]]
            up, vp = up[found], vp[found]
            if kind == OTHER:
                # Met from the glass's outside only: the ray goes into the glass (a ray
                # leaving the floor downwards has no glass in front of it).
                into = np.einsum("ij,ij->i", self._ng(tri), np.take(d, rows, axis=0)) < 0.0
                rows, tri, up, vp = rows[into], tri[into], up[into], vp[into]
            out.append((rows, tri, up, vp))
        if not out:
            return _NONE
        return tuple(np.concatenate(a) for a in zip(*out))

    def reflected_inside(self, p, off, d, from_tri):
        """Rows (K,) int64 of the rays leaving the points p (N,3) on glass triangles
        from_tri (N,) int64 (< 0: none; origins moved off the face by off (N,3)) back
        into the glass (d . n < 0: reflected off its inside, Fresnel or total internal
        reflection) where another surface touches that face: a pane standing on a sill,
        the light inside it meeting its bottom face. Cycles offsets no origin: the
        reflected ray starts on the sill's plane and meets the sill there (t = 0, its back
        face), and the light goes into it; with a gap under the pane it would be
        reflected up and out (newuser40's window threw a bright line of it onto the
        ceiling, docs/accuracy.md streak41). The same probe as probe's (from the mirror
        image of the origin along d, against the touching non-glass faces)."""
        return self.reflected_inside_hits(p, off, d, from_tri)[0]

    def reflected_inside_hits(self, p, off, d, from_tri):
        """reflected_inside with the touching surface each ray meets: (rows (K,) int64,
        tri (K,) int64 the met triangles' rows, u, v (K,) float32 barycentrics there)."""
        side = np.take(self.side, np.maximum(from_tri, 0))
        rows = np.nonzero((side == GLASS) & (from_tri >= 0))[0]
        if not len(rows):
            return _NONE
        pr_ = np.take(p, rows, axis=0)
        box = self.others.box
        inside = np.all((pr_ >= box[0]) & (pr_ <= box[1]), axis=1)
        rows, pr_ = rows[inside], pr_[inside]
        dr = np.take(d, rows, axis=0)
        into = np.einsum("ij,ij->i", self._ng(np.take(from_tri, rows)), dr) < 0.0
        rows, pr_, dr = rows[into], pr_[into], dr[into]
        if not len(rows):
            return _NONE
        of = np.take(off, rows, axis=0)
        reach = np.sqrt(np.einsum("ij,ij->i", of, of))
        ok = (reach > 0) & np.isfinite(reach)
        rows, pr_, dr, of, reach = rows[ok], pr_[ok], dr[ok], of[ok], reach[ok]
        if not len(rows):
            return _NONE
        cos = np.abs(np.einsum("ij,ij->i", of, dr)) / reach
        tmax = REACH * reach / np.maximum(cos, MIN_COS)
        _, hp, up, vp = self.others.accel.intersect(pr_ - of, dr, tmax)
        found = hp >= 0
        return rows[found], self.others.tri[hp[found]], up[found], vp[found]

    def leave_glass_first(self, o, d, t, tri, from_tri, rows=None):
        """Rays o, d (N,3) that left a glass triangle (from_tri (N,) int64, < 0: none)
        and whose closest hit (t (N,), tri (N,) int64, < 0: none) is a non-glass triangle
        touching glass, at a point where a touching glass face lies too and the ray
        crosses that face outwards (d . n > 0): a ray inside the bottle reaching its cap,
        where Embree returns the floor or the cap (the same distance) in its BVH's order.
        They meet the glass face first (refracted out there, then meeting the floor by
        probe). rows: the rows to consider (None: all). Returns (rows (K,) int64, tri, u,
        v, t (K,)): the glass hits within TIE x (t + the point's largest coordinate) of t
        (a bound on Embree's float32 distances to two coincident planes, 64 roundings).
        (A ray inside the glass last left a glass face: only those rows are read.)"""
        if rows is None:
            rows = np.nonzero(np.take(self.is_glass, np.maximum(from_tri, 0))
                              & (from_tri >= 0))[0]
        if not len(rows):
            return _NONE_T
        tri_r = np.take(tri, rows)
        rows = rows[(np.take(self.side, np.maximum(tri_r, 0)) == OTHER) & (tri_r >= 0)]
        if not len(rows):
            return _NONE_T
        tr = np.take(t, rows).astype(np.float64)
        dr = np.take(d, rows, axis=0).astype(np.float64)
        q = np.take(o, rows, axis=0) + tr[:, None] * dr
        box = self.glass.box
        inside = np.all((q >= box[0]) & (q <= box[1]), axis=1)
        if not inside.any():
            return _NONE_T
        rows, tr, dr, q = rows[inside], tr[inside], dr[inside], q[inside]
        s = TIE * (np.abs(tr) + np.abs(q).max(axis=1))
        tp, hp, up, vp = self.glass.accel.intersect(q - s[:, None] * dr, dr, 2.0 * s)
        found = hp >= 0
        if not found.any():
            return _NONE_T
        rows, tr, s, dr = rows[found], tr[found], s[found], dr[found]
        gtri, up, vp, tp = self.glass.tri[hp[found]], up[found], vp[found], tp[found]
        out_ = np.einsum("ij,ij->i", self._ng(gtri), dr) > 0.0
        return (rows[out_], gtri[out_], up[out_], vp[out_],
                np.maximum(tr - s + tp, 0.0)[out_])

    def started_inside(self, o, d):
        """Shadow rays o, d (N,3) (origins already offset off their surface) that start
        just inside a glass object, past a touching glass face they cross inwards: a
        shadow ray from the floor under a glass slab lying on it (the floor's offset takes
        its origin past the slab's bottom too). A short probe backwards (along -d, TIE x
        the origin's largest coordinate / MIN_COS: past the offset at any angle) against
        the touching glass faces; met from their outside (d . n < 0). Returns (rows (K,)
        int64, tri (K,) int64 the glass faces), for the transparent-shadow walk to start
        those rays as having entered the glass there (shadowtransmittance)."""
        o = np.asarray(o, np.float64)
        rows = np.arange(len(o))
        box = self.glass.box
        for c in range(3):
            if not len(rows):
                return _NONE[:2]
            x = o[rows, c]
            rows = rows[(x >= box[0, c]) & (x <= box[1, c])]
        if not len(rows):
            return _NONE[:2]
        orow = o[rows]
        dr = np.asarray(d, np.float64)[rows]
        s = TIE * np.abs(orow).max(axis=1) / MIN_COS
        _, hp, _, _ = self.glass.accel.intersect(orow, -dr, s)
        found = hp >= 0
        rows, tri = rows[found], self.glass.tri[hp[found]]
        into = np.einsum("ij,ij->i", self._ng(tri), dr[found]) < 0.0
        return rows[into], tri[into]

    def meet(self, o, d, org_p, org_prim, t, prim, u, v, leaving=True,
             inward=False) -> int:
        """In place on an Accel.intersect answer (t, prim, u, v (N,)) of rays o, d (N,3)
        that left the points org_p (N,3) on the triangles org_prim (N,) int64 (< 0: the
        camera; o = org_p moved off the face by its offset): the rows that meet a
        touching surface where they left (probe; leaving False: none can, may_meet) meet
        it at t = 0; the others that reach a touching floor where they should first leave
        the glass lying on it meet the glass face (leave_glass_first). inward (with
        CYCLES_CONTACT): rays leaving a touching glass face into the glass (reflected
        off its inside, or refracted in from the floor) meet the floor there too, at
        t = 0 on its back face (reflected_inside_hits), as Cycles' rays do: a camera path
        sees what that face sees (a closed table top's inside: nothing). Returns how
        many rows changed."""
        done = np.zeros(0, np.int64)
        if leaving:
            rows = np.nonzero(self.near(org_p, org_prim))[0]
            if len(rows):
                p = np.take(org_p, rows, axis=0)
                met, tri, up, vp = self.probe(p, np.take(o, rows, axis=0) - p,
                                              np.take(d, rows, axis=0),
                                              np.take(org_prim, rows))
                if len(met):
                    done = rows[met]
                    t[done] = 0.0
                    prim[done] = tri
                    u[done] = up
                    v[done] = vp
                if inward and CYCLES_CONTACT:
                    # (rows less the probe's: rows is sorted and met indexes it, so the
                    # mask keeps np.setdiff1d(rows, done)'s rows in its order, no sort)
                    rest = rows
                    if len(done):
                        left = np.ones(len(rows), bool)
                        left[met] = False
                        rest = rows[left]
                    p = np.take(org_p, rest, axis=0)
                    met, tri, up, vp = self.reflected_inside_hits(
                        p, np.take(o, rest, axis=0) - p, np.take(d, rest, axis=0),
                        np.take(org_prim, rest))
                    if len(met):
                        inner = rest[met]
                        t[inner] = 0.0
                        prim[inner] = tri
                        u[inner] = up
                        v[inner] = vp
                        done = np.concatenate((done, inner))
        tri = np.asarray(prim, np.int64)
        if len(done):
            tri = tri.copy()
            tri[done] = -1  # met by the probe: already where they belong
        rows, gtri, up, vp, tg = self.leave_glass_first(o, d, t, tri, org_prim)
        t[rows] = tg
        prim[rows] = gtri
        u[rows] = up
        v[rows] = vp
        return len(done) + len(rows)

    def meet_hits(self, o32, d, from_tri, off, geom, prim32, u32, v32, tfar, starts,
                  arrived=None) -> int:
        """meet on an Accel.intersect_hits answer (geom, prim32 (N,) int32, u32, v32, tfar
        (N,) float32, starts (G,) int64 over the full table's rows) of photon rays o32
        (N,3) float32, d (N,3) that left triangles from_tri (N,) int64 (< 0: a light) at
        o32 - off, off (N,3) the origins' offsets (photonkernels.scatter's nx_from,
        nx_off). arrived (N,) bool per ray: whether the hit each ray left was a touching
        glass face met from inside (per ray, not per photon slot: a copy passing behind
        a surface shares its photon's slot, not its hits; photons.py carries each
        continued ray's from its row, photonkernels.scatter's nx_row), overwritten with
        this bounce's hits' record: the photons reflected back inside there go into the
        touching surface (reflected_inside) and end, as a miss; None: not tracked.
        Returns how many rows changed."""
        # meet's two steps, the changed rows written back in Embree's layout.
        n = 0
        changed = []
        ft = np.maximum(from_tri, 0)
        rows = np.nonzero(self.near(o32, from_tri))[0]
        done = met_out = np.zeros(0, np.int64)
        if len(rows):
            of = np.take(off, rows, axis=0)
            met, mtri, up, vp = self.probe(np.take(o32, rows, axis=0) - of, of,
                                           np.take(d, rows, axis=0), np.take(from_tri, rows))
            if len(met):
                done = rows[met]
                if CYCLES_CONTACT:
                    # Refracted out of the glass onto the touching surface (arrived at the
                    # glass face from inside): Cycles' ray leaving that surface into the
                    # glass meets it again (its back face) and ends there, so no light
                    # reaches the surface through the contact. (A photon from the surface
                    # reflected off the glass face's outside lands back on it, as Cycles'
                    # ray from the surface reflected there meets it again on its front.)
                    out_ = np.take(self.side, np.take(ft, done)) == GLASS
                    if arrived is not None:
                        out_ &= np.take(arrived, done)
                    if out_.any():
                        gone_out = done[out_]
                        done, mtri, up, vp = done[~out_], mtri[~out_], up[~out_], vp[~out_]
                        geom[gone_out] = -1
                        n += len(gone_out)
                        met_out = gone_out
                changed.append((done, mtri, up, vp))
        # Photons reflected off the inside of a glass face another surface touches go
        # into that surface (reflected_inside): they end there, as a miss (not stored,
        # not bounced; the surface's back face, which no one sees). (Those that arrived
        # there from inside: a photon leaving the floor into the glass leaves the same
        # face the same way.)
        gone = np.zeros(0, np.int64)
        if len(rows) and arrived is not None:
            rest = rows if not len(done) else np.setdiff1d(rows, done)
            rest = rest[np.take(arrived, rest)]
            if len(rest):
                of = np.take(off, rest, axis=0)
                gone = rest[self.reflected_inside(np.take(o32, rest, axis=0) - of, of,
                                                  np.take(d, rest, axis=0),
                                                  np.take(from_tri, rest))]
        inside = np.take(self.is_glass, ft) & (from_tri >= 0)
        if len(done):
            inside[done] = False  # met by the probe: already where they belong
        if len(gone):
            inside[gone] = False
        if len(met_out):
            inside[met_out] = False
        rows = np.nonzero(inside)[0]
        if len(rows):
            g = np.take(geom, rows)
            tri = np.full(len(geom), -1, np.int64)
            tri[rows] = np.where(g >= 0, np.take(starts, np.maximum(g, 0))
                                 + np.take(prim32, rows), -1)
            rows, gtri, up, vp, _ = self.leave_glass_first(o32, d, tfar, tri, from_tri, rows)
            if len(rows):
                changed.append((rows, gtri, up, vp))
        for rows, mtri, up, vp in changed:
            g = np.searchsorted(starts, mtri, side="right") - 1
            geom[rows] = g
            prim32[rows] = mtri - np.take(starts, g)
            u32[rows] = up
            v32[rows] = vp
            n += len(rows)
        if len(gone):
            geom[gone] = -1
            n += len(gone)
        if arrived is not None:
            # This bounce's record: hits on a touching glass face crossing it outwards.
            arrived[:] = False
            tri = np.where(geom >= 0, np.take(starts, np.maximum(geom, 0)) + prim32, -1)
            at = np.nonzero((np.take(self.side, np.maximum(tri, 0)) == GLASS) & (tri >= 0))[0]
            if len(at):
                out_ = np.einsum("ij,ij->i", self._ng(tri[at]),
                                 np.take(d, at, axis=0)) > 0.0
                arrived[at[out_]] = True
        return n


_NONE = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32),
         np.zeros(0, np.float32))
_NONE_T = _NONE + (np.zeros(0),)
