"""Heterogeneous media: a texture on a volume's Density (clouds, smoke puffs, patchy fog).

A material whose medium has a density field (Material.density_texture: a node tree of
engine/shadernodes.py, the same objects a Base Color texture is made of, evaluated at
points inside the object instead of at surface hits) has the extinction

    sigma_t(p) = f(p) x sigma_t_unit,   sigma_s(p) = f(p) x sigma_s_unit,

f(p) = max(program(p), 0) (Cycles clamps a volume's density at 0:
svm_node_principled_volume) and sigma_unit the material's coefficients at density 1
(Material.absorption / scattering, exported at density 1 by addon/materials.py). The
program reads Generated or Object coordinates; inside an undeformed mesh both are an
affine function of the position, recovered here from the mesh's own corners (a least
squares fit over the triangles of each object, exact for an affine map: PointGeometry).

The homogeneous machinery (engine/media.py, volumescatter.py, photons) keeps working on
a homogeneous stand-in: the material table's rows are set to the field's mean
(f_mean x sigma_unit, f_mean from FIELD_SAMPLES points in the objects' bounds). Where
light crosses the medium, the stand-in's factor is turned into an unbiased estimate of
the true one (Cycles 5.0 renders heterogeneous volumes unbiased too: null scattering
and Kettunen et al. 2021's unbiased ray-marching transmittance against octree
majorants, volume_integrate_heterogeneous in kernel/integrator/shade_volume.h), walking
a majorant grid of each object (engine/majorant.py: per cell a control density and a
bound on the field's distance from it, and a majorant for drawing distances):

- transmittance along a part [a, b] of a ray inside the medium: residual ratio tracking
  (Novak et al. 2014, "Residual ratio tracking for estimating attenuation in
  participating media") about the grid's piecewise-constant control density c(x): the
  control's optical depth integrated exactly cell by cell, tentative collisions x_i at
  each cell's rate mu = rad x max_c sigma_t_unit,c (none in cells whose neighbourhood is
  constant: empty space, saturated puffs), factors 1 - (f(x_i) - c(x_i)) sigma_t_unit,c
  / mu: T = exp(-int c sigma_t_unit) prod_i(...), divided by the stand-in's
  exp(-f_mean sigma_t_unit (b - a)) (correction()).
- camera segments and final-gather rays (integrator, through attenuated()), shadow rays
  (shadowtransmittance.ShadowTransmittance.transmittance, volumescatter.in_scattered's
  rays to a lamp inside the fog, directlight._dim_in_medium's rays of a surface inside
  the medium), photons (photons._bounces) and the camera walks' surface term
  (volumewalk): x correction over the parts inside such a medium.
- the camera segments' scattering (volumescatter.CameraScattering.radiance, and the
  walks' later scatters at Volume bounces > 0): the distance is drawn along the grid's
  majorant (pdf sig(s) exp(-int sig), sig the cell's majorant density x the channels'
  mean sigma_t_unit), so samples land in and around the puffs, with the weight T(s)
  sigma_s(s) / pdf(s) (T(s) ratio-tracked as above) (scatter()); the photons' free
  flights keep the stand-in's distances with the weight w x correction(0, s) x f(p) /
  f_mean (scatter_weights).

The stand-in's mean: the field's mean over FIELD_SAMPLES points (a jittered grid) in the
bounds of the objects that carry the material.

Random numbers: the tracking steps draw from a counter-based hash of the render's seed
and the ray itself (its origin and direction bits and the part's start, splitmix64):
the same seed gives the same image for any worker count, and no stream's draws shift
(a scene without a density texture renders exactly as before). The camera segments'
distances take the camera pass's stratified numbers (its ("volume",) dimension).

An emitting medium's emission is integrated along the field, and textured emission and
albedo (Principled Volume's Emission Strength / Color / Blackbody, its Color) are fields
of their own: engine/volumefields.py (volemit40), which this module's fields carry (a
material with only such textures is a field of constant density, whose tracking has
nothing to do: `tracked`). The World Volume keeps a constant density (warned). A
scene with shared instances (two-level tracing, engine/sharedrows.py) reads the media's
triangles through SharedRows (medium_rows): static media as without instances, and
instanced copies of a medium (an instanced cloud) each as its own object (its own
object id, world-space corners and coordinate map).
"""
from __future__ import annotations

import math

import numpy as np

from .majorant import MajorantGrid, sample_distances, track_collisions

FIELD_SAMPLES = 32 ** 3  # points per object for the stand-in's mean
MAX_CROSSINGS = 8  # medium intervals followed along one ray
MAX_STEPS = 4096  # tracking steps per interval (a runaway majorant guard)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _splitmix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser on uint64 arrays (wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        x = x + _GOLDEN
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))


def ray_keys(seed: int, o: np.ndarray, d: np.ndarray, salt: int = 0) -> np.ndarray:
    """(n,) uint64 a key per ray from the seed and the ray's float64 bits (o, d (n,3))."""
    bits = np.ascontiguousarray(np.concatenate([np.asarray(o, np.float64),
                                                np.asarray(d, np.float64)], axis=1))
    bits = bits.view(np.uint64)
    h = np.full(len(bits), np.uint64((int(seed) * 0x2545F4914F6CDD1D + salt)
                                     & 0xFFFFFFFFFFFFFFFF), np.uint64)
    for c in range(bits.shape[1]):
        h = _splitmix(h ^ bits[:, c])
    return h


def uniforms(keys: np.ndarray, step) -> np.ndarray:
    """(n,) float64 in [0, 1): number `step` ((n,) or scalar) of each key's stream."""
    with np.errstate(over="ignore"):
        x = _splitmix(keys ^ (np.asarray(step, np.uint64) * np.uint64(0xD1B54A32D192ED03)))
    return (x >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


class PointGeometry:
    """A Geometry stand-in for evaluating a node tree at points inside objects: prim is
    the point's index; coordinates(name) applies each point's object's affine map
    (world -> that texture space, fitted by HeterogeneousMedia); volume_grids the
    objects' voxel grids ({object: {name: voxelgrid.VoxelGrid}}: Volume objects, read by
    voxelgrid.GridAttribute)."""

    def __init__(self, points, obj, maps, offset, volume_grids=None):
        self.points = np.asarray(points, np.float64)
        self.obj = np.asarray(obj, np.int64)
        self.maps = maps  # {(object, name): (4,3)}
        self.offset = offset
        self.volume_grids = volume_grids

    def coordinates(self, name, prim, u, v):
        p = self.points[np.asarray(prim, np.int64)]
        ob = self.obj[np.asarray(prim, np.int64)]
        out = np.zeros((len(p), 3))
        for k in np.unique(ob):
            A = self.maps.get((int(k), name))
            if A is None:
                continue
            sel = ob == k
            out[sel] = p[sel] @ A[:3] + A[3]
        return out

    def hit_points(self, prim, u, v):
        return self.points[np.asarray(prim, np.int64)]

    def uvs(self, prim, u, v):
        return np.zeros((len(prim), 2))

    def colors(self, prim, u, v):
        return np.zeros((len(prim), 3))


class Field:
    """One material's density field: node, sigma_t_unit (3,), sigma_s_unit (3,), f_max
    (the largest value sampled in its objects' bounds) and f_mean (the stand-in's)."""

    def __init__(self, node, sigma_t_unit, sigma_s_unit):
        self.node = node
        self.sigma_t_unit = np.asarray(sigma_t_unit, np.float64)
        self.sigma_s_unit = np.asarray(sigma_s_unit, np.float64)
        self.f_max = 0.0
        self.f_mean = 0.0


class HeterogeneousMedia:
    """The scene's heterogeneous media (None from for_scene when there are none)."""

    def __init__(self, geo, table, fields: dict, seed: int = 0):
        self.geo = geo
        self.table = table
        self.fields = fields  # material row -> Field
        self.seed = int(seed)
        self.warnings: list[str] = []
        self.maps = {}
        # Volume objects' voxel grids (engine/voxelgrid.py): {object: {name: VoxelGrid}}
        self.volume_grids = getattr(geo, "volume_grids", None) or None
        rows = medium_rows(geo, fields)
        self.rows = rows  # the triangles of heterogeneous materials
        # (row gathers: a shared Geometry's RowColumn reads only these rows, instanced
        # ones placed in world space, engine/sharedrows.py)
        v0 = np.asarray(geo.v0[rows], np.float64)
        e1 = np.asarray(geo.e1[rows], np.float64)
        e2 = np.asarray(geo.e2[rows], np.float64)
        self.normal = np.cross(e1, e2)
        self.material = np.asarray(geo.material[rows]).astype(np.int64)
        self.object = np.asarray(geo.object_id[rows]).astype(np.int64)
        corners = np.stack([v0, v0 + e1, v0 + e2], axis=1)  # (R,3,3)
        self._fit_maps(corners)
        # Textured emission and albedo (engine/volumefields.py): their means, and the
        # fields' sigma_s_unit at the mean albedo, before anything reads the fields.
        from .volumefields import MediumTextures
        self.textures = MediumTextures(self, table, corners)
        self.warnings.extend(self.textures.warnings)
        self._measure(corners)
        verts = corners.reshape(-1, 3)
        from .accel import Accel
        self.accel = Accel(verts.astype(np.float32),
                           np.arange(len(verts), dtype=np.int32).reshape(-1, 3))
        # Commit the BVH on this thread: the camera pass's workers then only read it.
        self.accel.intersect(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))
        # The homogeneous stand-in: the table's rows at the mean density.
        for m, f in fields.items():
            table.absorption[m] = f.f_mean * (f.sigma_t_unit - f.sigma_s_unit)
            table.scattering[m] = f.f_mean * f.sigma_s_unit

    @classmethod
    def for_scene(cls, geo, table, seed: int = 0):
        """HeterogeneousMedia, or None when no material of the table has a density
        texture (table.density_textures) on a triangle of geo."""
        from . import volumefields
        textures = list(getattr(table, "density_textures", None) or [])
        # (materials with an emission or albedo texture: a field of constant density,
        # engine/volumefields.py)
        textured = volumefields.textured_materials(table)
        if (all(t is None for t in textures) and not textured) or geo.count == 0:
            return None
        textures += [None] * (len(table.names) - len(textures))
        fields = {}
        for m, node in enumerate(textures):
            if node is None:
                if m not in textured:
                    continue
                node = 1.0
            a = np.asarray(table.absorption[m], np.float64)
            s = np.asarray(table.scattering[m], np.float64)
            fields[m] = Field(node, a + s, s)
        # The materials some triangle carries (a shared Geometry's static rows and its
        # instances' rows through SharedRows.rows_of: never the whole expanded column).
        used = set(np.unique(np.asarray(geo.material[medium_rows(geo, fields)])).tolist())
        fields = {m: f for m, f in fields.items() if m in used}
        if not fields:
            return None
        # A tree that reads what a point inside a volume does not have (a surface's
        # normal, a camera's view...): warned, the medium homogeneous at density 1.
        warnings = []
        for m in list(fields):
            try:
                probe = PointGeometry(np.zeros((2, 3)), np.zeros(2, np.int64), {},
                                      np.asarray(geo.offset, np.float64),
                                      getattr(geo, "volume_grids", None))
                _field_values(fields[m].node, probe, 2)
            except Exception as exc:  # noqa: BLE001 - any node's failure, reported
                warnings.append(f"material '{table.names[m]}': its density texture cannot "
                                f"be evaluated inside the volume ({type(exc).__name__}: "
                                f"{exc}); rendered as a homogeneous medium of density 1")
                table.density_textures[m] = None
                volumefields.drop(table, m)
                del fields[m]
        if not fields:
            return _Warned(warnings)
        het = cls(geo, table, fields, seed)
        het.warnings[:0] = warnings
        return het

    @property
    def tracked(self) -> bool:
        """Whether some field has a density texture (the tracking has work); fields of
        constant density (node 1.0) carry only emission / albedo textures
        (volumefields)."""
        return any(hasattr(f.node, "evaluate") for f in self.fields.values())

    # -- setup ---------------------------------------------------------------------
    def _fit_maps(self, corners):
        """The affine maps world -> each corner coordinate space of each object
        (least squares over its corners; warned when the fit is not exact: a deformed
        mesh, whose coordinates are not affine in the position)."""
        cc = getattr(self.geo, "corner_coordinates", None) or {}
        for name, table in cc.items():
            if name not in ("generated", "object"):
                continue
            vals = np.asarray(table[self.rows], np.float64)  # (R,3,3)
            for k in np.unique(self.object):
                sel = self.object == k
                P = corners[sel].reshape(-1, 3)
                C = vals[sel].reshape(-1, 3)
                if len(P) > 3000:
                    pick = np.linspace(0, len(P) - 1, 3000).astype(np.int64)
                    P, C = P[pick], C[pick]
                X = np.concatenate([P, np.ones((len(P), 1))], axis=1)
                A, *_ = np.linalg.lstsq(X, C, rcond=None)
                err = float(np.max(np.abs(X @ A - C))) if len(C) else 0.0
                scale = max(float(np.max(np.abs(C))) if len(C) else 0.0, 1.0)
                if err > 1e-4 * scale:
                    self.warnings.append(
                        f"object '{self._object_name(k)}': its {name.title()} coordinates "
                        "are not an affine function of the position (a deformed mesh); "
                        f"the volume's density reads the nearest affine map (error {err:.3g})")
                self.maps[(int(k), name)] = A

    def _object_name(self, k):
        names = getattr(self.geo, "object_names", None)
        try:
            return names[int(k)]
        except (TypeError, IndexError):
            return str(k)

    def _measure(self, corners):
        """f_max and f_mean of each field over FIELD_SAMPLES jittered grid points in the
        bounds of each object that carries it; the majorant grids (engine/majorant.py)
        of each (object, material) pair over its triangles' bounds."""
        rng = np.random.default_rng([self.seed, 39, 14])
        n = round(FIELD_SAMPLES ** (1.0 / 3.0))
        g = (np.arange(n) + 0.5) / n
        grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
        pairs, bounds = [], []
        for m, f in self.fields.items():
            tot, cnt, top = 0.0, 0, 0.0
            for k in np.unique(self.object[self.material == m]):
                sel = (self.object == k) & (self.material == m)
                P = corners[sel].reshape(-1, 3)
                lo, hi = P.min(axis=0), P.max(axis=0)
                pairs.append((int(k), int(m)))
                bounds.append((lo, hi))
                jit = (rng.random(grid.shape) - 0.5) / n
                pts = lo + (hi - lo) * np.clip(grid + jit, 0.0, 1.0)
                vals = self._density(f, pts, np.full(len(pts), k))
                tot += float(vals.sum())
                cnt += len(vals)
                top = max(top, float(vals.max()) if len(vals) else 0.0)
            f.f_mean = tot / max(cnt, 1)
            f.f_max = top
        n_obj = int(self.object.max()) + 1 if len(self.object) else 1
        n_mat = max(self.fields) + 1
        self.grid = MajorantGrid.build(
            pairs, bounds, lambda m, p, o: self._density(self.fields[int(m)], p, o),
            n_obj, n_mat)
        self._fit_voxel_bounds(pairs)
        # per material row: the tracking's coefficients (0 for rows without a field)
        self._unit_t = np.zeros((n_mat, 3))
        self._unit_s = np.zeros((n_mat, 3))
        self._f_mean = np.zeros(n_mat)
        for m, f in self.fields.items():
            self._unit_t[m] = f.sigma_t_unit
            self._unit_s[m] = f.sigma_s_unit
            self._f_mean[m] = f.f_mean
        # per grid: the largest channel of sigma_t at density 1 (the tracking rate's
        # scale) and the channels' mean (the distance sampling's, as the stand-in's)
        unit = self._unit_t[np.array([m for _, m in pairs], np.int64)].reshape(-1, 3)
        self._smax = np.ascontiguousarray(unit.max(axis=1))
        self._sbar = np.ascontiguousarray(unit.mean(axis=1))

    def _fit_voxel_bounds(self, pairs):
        """The majorant cells of Volume objects' fields from their voxels: a lattice of
        field samples (MajorantGrid.build) misses the voxels between its points on a
        grid finer than it (a 256^3 grid under 32^3 cells of 3 samples each); where the
        density tree is bounded by voxelgrid.field_bounds (the grid's largest and
        smallest voxels under each cell, through the tree's arithmetic), ctrl, rad and
        sup follow those exact bounds instead (module docstring of engine/majorant.py);
        other trees (a Noise x the grid) keep the sampled bounds, raised to the largest
        sampled value in cells where a grid they read has voxels but the samples read
        nothing."""
        if not self.volume_grids:
            return
        from .voxelgrid import field_bounds, occupied
        g = self.grid
        off = np.asarray(self.geo.offset, np.float64)
        for slot, (k, m) in enumerate(pairs):
            grids = self.volume_grids.get(int(k))
            if not grids:
                continue
            dims = g.dims[slot]
            ii = np.stack(np.meshgrid(*[np.arange(int(d)) for d in dims], indexing="ij"),
                          axis=-1).reshape(-1, 3)
            lo = g.origin[slot] + ii * g.cell[slot] + off
            hi = lo + g.cell[slot]
            b = field_bounds(self.fields[m].node, k, grids, lo, hi)
            s = slice(int(g.offset[slot]), int(g.offset[slot]) + len(ii))
            if b is None:
                # A tree these bounds do not follow (a Noise x the grid): where a grid
                # it reads has voxels under a cell its sampled lattice read as empty, the
                # cell takes the largest sampled value as its bound (a distance pdf of 0
                # where the field is not would bias the scattering)
                occ = occupied(self.fields[m].node, grids, lo, hi)
                if occ is None:
                    continue
                top = max(float(np.max(g.sup[s])) if len(ii) else 0.0, 1e-6)
                empty = occ & (g.sup[s] <= 0.0)
                g.rad[s] = np.where(empty, np.maximum(g.rad[s], top), g.rad[s])
                g.sup[s] = np.where(empty, g.ctrl[s] + g.rad[s], g.sup[s])
                continue
            # the field is max(tree, 0) (_field_values)
            f_lo, f_hi = np.maximum(b[0], 0.0), np.maximum(b[1], 0.0)
            g.ctrl[s] = 0.5 * (f_lo + f_hi)
            g.rad[s] = 0.5 * (f_hi - f_lo)
            g.sup[s] = f_hi
            self.fields[m].f_max = max(self.fields[m].f_max, float(f_hi.max()))

    def _density(self, f: Field, points, obj) -> np.ndarray:
        """(n,) the field f at points (n,3) (re-centred world) of objects obj (n,)."""
        n = len(points)
        if n == 0:
            return np.zeros(0)
        pg = PointGeometry(points, obj, self.maps, np.asarray(self.geo.offset, np.float64),
                           self.volume_grids)
        return _field_values(f.node, pg, n)

    def density(self, m: int, points, obj) -> np.ndarray:
        """(n,) material m's density field at points (n,3) inside objects obj (n,)."""
        return self._density(self.fields[int(m)], points, obj)

    # -- transport -----------------------------------------------------------------
    def intervals(self, o, u, length):
        """The parts of the rays o + s u (u unit, s in [0, length]) inside heterogeneous
        media: (ray (K,), a (K,), b (K,), material (K,), object (K,)). A part starts
        at the ray's origin when the ray's first crossing is a back face (it starts
        inside), or at a front face; it ends at the next back face or at length."""
        n = len(o)
        out = ([], [], [], [], [])
        cur = np.zeros(n)
        idx = np.arange(n)
        for _ in range(2 * MAX_CROSSINGS):
            if len(idx) == 0:
                break
            start = o[idx] + u[idx] * cur[idx, None]
            t, prim, _, _ = self.accel.intersect(start, u[idx])
            hit = prim >= 0
            idx, t, prim = idx[hit], np.asarray(t)[hit], np.asarray(prim, np.int64)[hit]
            if len(idx) == 0:
                break
            back = np.einsum("ij,ij->i", u[idx], self.normal[prim]) > 0.0
            end = cur[idx] + t
            b_i = back
            if b_i.any():
                r = idx[b_i]
                a = cur[r]
                b = np.minimum(end[b_i], length[r])
                ok = b > a
                out[0].append(r[ok])
                out[1].append(a[ok])
                out[2].append(b[ok])
                out[3].append(self.material[prim[b_i]][ok])
                out[4].append(self.object[prim[b_i]][ok])
            # step just past the crossing (a relative nudge: the same face is not met
            # again)
            cur[idx] = end + 1e-6 * np.maximum(1.0, np.abs(end))
            go = cur[idx] < length[idx]
            idx = idx[go]
        if not out[0]:
            e = np.zeros(0, np.int64)
            return e, np.zeros(0), np.zeros(0), e, e
        return tuple(np.concatenate(x) for x in out)

    def track(self, o, u, keys, a, b, m, obj):
        """Residual ratio tracking over parts o + s u, s in [a, b] (K,) of material m,
        object obj (K,) against the majorant grids (engine/majorant.py): (P (K,3), D (K,))
        with T_c = exp(-sigma_t_unit,c D) P_c the estimate of exp(-integral sigma_t)
        per channel, D the control density's integral (m), P the product of the
        tentative collisions' factors, from each part's key stream (keys (K,) uint64)."""
        K = len(a)
        P = np.ones((K, 3))
        D = np.zeros(K)
        slot = self.grid.slots(obj, m)
        o = np.ascontiguousarray(o, np.float64)
        u = np.ascontiguousarray(u, np.float64)
        x = np.array(a, np.float64)
        b = np.ascontiguousarray(b, np.float64)
        alive = np.flatnonzero((slot >= 0) & (b > x))
        g = self.grid
        step = 0
        while len(alive) and step < MAX_STEPS:
            E = -np.log1p(-uniforms(keys[alive], step))
            xa, Da = x[alive], D[alive]
            hit = np.zeros(len(alive), np.bool_)
            c_at = np.zeros(len(alive))
            mu_at = np.ones(len(alive))
            track_collisions(o[alive], u[alive], xa, b[alive], slot[alive], E, g.origin,
                             g.cell, g.dims, g.offset, g.ctrl, g.rad, self._smax, Da, hit,
                             c_at, mu_at)
            x[alive], D[alive] = xa, Da
            step += 1
            h = alive[hit]
            if not len(h):
                break
            pts = o[h] + u[h] * x[h, None]
            f = np.zeros(len(h))
            for mm in np.unique(m[h]):
                sel = m[h] == mm
                f[sel] = self.density(mm, pts[sel], obj[h][sel])
            P[h] *= 1.0 - (f - c_at[hit])[:, None] * self._unit_t[m[h]] / mu_at[hit, None]
            # (a part whose estimate reached 0 stays 0: stop tracking it)
            alive = h[np.any(P[h] != 0.0, axis=1)]
        return P, D

    def correction(self, o, d, tmax, salt: int = 0) -> np.ndarray:
        """(n,3) the factor that turns the homogeneous stand-in's transmittance of the
        segments o + t d, t in [0, tmax] (units of |d|; o, d (n,3)) into the
        heterogeneous media's (the tracked T over each part inside one, divided by the
        stand-in's exp(-sigma_t_mean (b - a)) there); 1 for segments outside them."""
        o = np.asarray(o, np.float64)
        d = np.asarray(d, np.float64)
        n = len(o)
        out = np.ones((n, 3))
        if n == 0 or not self.tracked:
            return out
        dl = np.linalg.norm(d, axis=1)
        ok = dl > 0
        u = np.where(ok[:, None], d / np.where(ok, dl, 1.0)[:, None], 0.0)
        length = np.where(ok, np.maximum(np.asarray(tmax, np.float64), 0.0) * dl, 0.0)
        ray, a, b, m, obj = self.intervals(o, u, length)
        if not len(ray):
            return out
        keys = ray_keys(self.seed, o[ray], d[ray], salt) ^ (a.view(np.uint64))
        P, D = self.track(o[ray], u[ray], keys, a, b, m, obj)
        # exp(-sigma (D - f_mean (b - a))): the control's depth against the stand-in's
        # (at most exp(700): the stand-in's mean optical depth is far below 700)
        depth = self._unit_t[m] * (D - self._f_mean[m] * (b - a))[:, None]
        fac = P * np.exp(np.minimum(-depth, 700.0))
        fac[self.grid.slots(obj, m) < 0] = 1.0  # (a part outside every grid: the stand-in)
        np.multiply.at(out, ray, fac)
        return out

    def scatter(self, o, d, tseg, pts, seg_m, w, uu):
        """Scattering points of camera-path segments (radiance's first scatter, the walks'
        later ones) drawn along the majorant grid: for segments (rays o, d (K,3), lengths
        tseg (K,) in units of |d|, in media seg_m (K,)) that lie in one part of a medium
        with a density texture, the point pts (K,3) and weight w (K,3) drawn for the
        stand-in (volumescatter.sample_segments) are replaced, in place, by a distance s
        from the grid's majorant (majorant.sample_distances, from uu (K,): the stand-in's
        numbers) and T(s) sigma_s(s) / pdf(s) (T ratio-tracked, the field and a textured
        albedo's a(p) / a_mean at the point); the others (a constant density with an
        albedo texture, engine/volumefields.py) take scatter_weights. Returns (pts, w)."""
        dense = [m for m, f in self.fields.items() if hasattr(f.node, "evaluate")]
        other = np.flatnonzero(np.isin(seg_m, list(self.fields)) & ~np.isin(seg_m, dense))
        if len(other):
            w[other] = self.scatter_weights(np.asarray(o)[other], np.asarray(d)[other],
                                            pts[other], np.asarray(seg_m)[other],
                                            w[other].copy())
        het = np.flatnonzero(np.isin(seg_m, dense))
        if not len(het):
            return pts, w
        o_i = np.asarray(o, np.float64)[het]
        d_i = np.asarray(d, np.float64)[het]
        dl = np.linalg.norm(d_i, axis=1)
        ok = dl > 0
        u_i = np.where(ok[:, None], d_i / np.where(ok, dl, 1.0)[:, None], 0.0)
        S = np.where(ok, np.maximum(np.asarray(tseg, np.float64)[het], 0.0) * dl, 0.0)
        ray, a, b, m, obj = self.intervals(o_i, u_i, S)
        count = np.bincount(ray, minlength=len(het))
        one = count[ray] == 1
        ray, a, b, m, obj = ray[one], a[one], b[one], m[one], obj[one]
        slot = self.grid.slots(obj, m)
        good = (slot >= 0) & (m == np.asarray(seg_m)[het][ray])
        ray, a, b, m, obj, slot = ray[good], a[good], b[good], m[good], obj[good], slot[good]
        rest = np.ones(len(het), np.bool_)
        rest[ray] = False
        if rest.any():
            r = het[rest]
            w[r] = self.scatter_weights(np.asarray(o)[r], np.asarray(d)[r], pts[r],
                                        np.asarray(seg_m)[r], w[r].copy())
        if not len(ray):
            return pts, w
        K = len(ray)
        s = np.zeros(K)
        sig, tau, tot = np.zeros(K), np.zeros(K), np.zeros(K)
        g = self.grid
        oo = np.ascontiguousarray(o_i[ray])
        uu_ = np.ascontiguousarray(u_i[ray])
        sample_distances(oo, uu_, a, b, slot, np.ascontiguousarray(np.asarray(uu)[het][ray],
                                                                    np.float64),
                         g.origin, g.cell, g.dims, g.offset, g.sup, self._sbar, s, sig, tau,
                         tot)
        rows = het[ray]
        w[rows] = 0.0
        lit = np.flatnonzero(s >= 0.0)
        if not len(lit):
            return pts, w
        o_l, u_l, s_l = oo[lit], uu_[lit], s[lit]
        p = o_l + u_l * s_l[:, None]
        pts[rows[lit]] = p
        keys = ray_keys(self.seed, o_l, d_i[ray][lit], 1) ^ (a[lit].view(np.uint64))
        P, D = self.track(o_l, u_l, keys, a[lit], s_l, m[lit], obj[lit])
        f = np.zeros(len(lit))
        albedo = np.ones((len(lit), 3))
        for mm in np.unique(m[lit]):
            sel = m[lit] == mm
            f[sel] = self.density(mm, p[sel], obj[lit][sel])
            # a textured albedo (engine/volumefields.py): a(p) / a_mean
            albedo[sel] *= self.textures.albedo_ratio(mm, p[sel], obj[lit][sel])
        # T_c(s) sigma_s,c(s) / pdf(s), pdf = sig exp(-tau) / (1 - exp(-tot))
        log_t = tau[lit, None] - self._unit_t[m[lit]] * D[:, None]
        w[rows[lit]] = (P * self._unit_s[m[lit]] * albedo
                        * (f * -np.expm1(-tot[lit]) / sig[lit])[:, None]
                        * np.exp(np.minimum(log_t, 700.0)))
        return pts, w

    def scatter_weights(self, o, d, pts, seg_m, w):
        """Single scattering's weights w (K,3) at points pts (K,3) (rays from o along d
        (K,3)) in media seg_m (K,), drawn for the stand-in: the heterogeneous media's
        rows x correction(o -> p) x f(p) / f_mean, in place."""
        het = np.isin(seg_m, list(self.fields))
        if not het.any():
            return w
        i = np.flatnonzero(het)
        o_i = np.asarray(o, np.float64)[i]
        p_i = np.asarray(pts, np.float64)[i]
        seg = p_i - o_i
        w[i] *= self.correction(o_i, seg, np.ones(len(i)), salt=1)
        # the point's object: the medium's interval the point lies in
        s = np.linalg.norm(seg, axis=1)
        u = seg / np.maximum(s, 1e-300)[:, None]
        obj = self._object_at(o_i, u, s)
        for mm in np.unique(seg_m[i]):
            sel = seg_m[i] == mm
            f = self.fields[int(mm)]
            dens = self.density(mm, p_i[sel], obj[sel])
            w[i[sel]] *= (dens / f.f_mean)[:, None] if f.f_mean > 0 else 0.0
            # a textured albedo (engine/volumefields.py): a(p) / a_mean
            w[i[sel]] *= self.textures.albedo_ratio(mm, p_i[sel], obj[sel])
        return w

    def _object_at(self, o, u, s):
        """(n,) the object of the first heterogeneous face beyond o + s u along u (the
        face the medium's part that holds the point ends on; -1: none)."""
        t, prim, _, _ = self.accel.intersect(o + u * s[:, None], u)
        prim = np.asarray(prim, np.int64)
        return np.where(prim >= 0, self.object[np.maximum(prim, 0)], -1)

    def describe(self) -> str:
        """The effect report's line: each textured medium's density range."""
        return "; ".join([
            f"density texture of '{self.table.names[m]}': mean {f.f_mean:.3g}, largest "
            f"{f.f_max:.3g} over its objects' bounds (the homogeneous stand-in at the mean, "
            "corrected by residual ratio tracking against a majorant grid along camera "
            "segments, shadow rays and photons; single scattering's distances drawn along "
            "the grid)"
            for m, f in self.fields.items() if hasattr(f.node, "evaluate")]
            + ([self.textures.describe()] if self.textures.describe() else []))

    def limits(self, settings=None) -> list[str]:
        """This render's warnings about its heterogeneous media (a deformed mesh's
        coordinates, a tree that cannot be evaluated, an albedo texture above 1)."""
        return list(self.warnings)


def medium_rows(geo, materials) -> np.ndarray:
    """(R,) int64 the rows of geo whose material is in `materials`, ascending: the flat
    material column's, or for a Geometry with shared instances (engine/sharedrows.py)
    SharedRows.rows_of (its static rows and the instanced copies' rows, each copy with
    its own object id and world-space corners), without building the expanded column."""
    shared = getattr(geo, "shared", None)
    if shared is not None:
        return shared.rows_of(materials)
    return np.flatnonzero(np.isin(np.asarray(geo.material), list(materials)))


def _field_values(node, pg, n) -> np.ndarray:
    """(n,) max(node's value, 0) at the n points of PointGeometry pg (a colour: its
    luminance, shadernodes._eval's conversion into a value; NaN read as 0)."""
    from .shadernodes import _eval
    prim = np.arange(n, dtype=np.int64)
    z = np.zeros(n)
    val = _eval(node, pg, prim, z, z, 1)
    return np.maximum(np.nan_to_num(np.asarray(val, np.float64), nan=0.0), 0.0)


class _Warned:
    """for_scene's answer when density textures cannot be rendered heterogeneous: only
    its warnings (no field)."""

    fields: dict = {}

    def __init__(self, warnings):
        self.warnings = warnings

    def limits(self, settings=None):
        return list(self.warnings)


def attenuated(ctx, tp, o, d, t, prim) -> np.ndarray:
    """The camera or gather paths' throughput tp (n,3) after media.attenuated, with the
    heterogeneous media's correction over their last segment (o, d (n,3), t (n,) in
    units of |d|, ending on prim (n,)); tp itself without heterogeneous media."""
    het = getattr(ctx, "hetero", None)
    if het is None or not het.fields or len(tp) == 0:
        return tp
    c = het.correction(o, d, np.where(np.asarray(prim) >= 0, t, 0.0), salt=2)
    if np.all(c == 1.0):
        return tp
    return np.asarray(tp, np.float64) * c
