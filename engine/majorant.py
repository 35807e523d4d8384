"""Majorant grids of heterogeneous media: a coarse 3-D grid of the density field's local
bounds per object, walked cell by cell (a DDA) by the tracking and sampling kernels.

A textured density (engine/heterogeneous.py) is mostly empty space and dense puffs. One
bound for the whole object makes every ray take tracking steps everywhere (the rate of
the largest |f - f_mean|) and draws scattering distances for the mean density, wherever
the puffs are. Cycles 5.0 walks an octree of majorants instead (kernel/integrator/
shade_volume.h volume_integrate_heterogeneous, volume_sample_channel; scene/
volume.cpp's octree). Here each (object, material) pair gets a grid of
GRID_CELLS^3 cells over its world bounds (fewer for many objects: LATTICE_BUDGET), from
the field evaluated on a lattice of SUB + 1 points along each cell edge (shared faces):

- lo, hi (per cell): the smallest and largest lattice values of the cell;
- ctrl = (lo + hi) / 2: the residual tracking's control density in the cell (its optical
  depth integrated exactly: the control transmittance), and rad = (hi - lo) / 2 x MARGIN
  + half the largest change between two adjacent lattice points of the cell (a peak
  between lattice points): the bound on |f - ctrl| that sets the tentative collisions'
  rate. Cells whose lattice values are all equal (empty space, saturated puff
  interiors) have rad 0: no steps.
- sup = ctrl + rad, the cell's bound on the field (it holds wherever the residual bound
  does): the majorant that scattering distances are drawn from (pdf proportional to
  sup(s) exp(-int sup), sup x the channels' mean sigma_t at density 1), so samples land
  in and around the puffs; 0 where the cell reads 0.

Unbiased with any bounds: residual ratio tracking stays unbiased where |f - ctrl| > rad
(a factor below 0: noisier), and a distance pdf is unbiased wherever it is positive; the
one assumption is that a cell whose (SUB + 1)^3 lattice points read one value holds that
value throughout (a puff smaller than a lattice spacing, between lattice points of an
empty cell, would be missed: 2.5 cm for a 1.6 m cloud at 32 cells).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up

GRID_CELLS = 32  # cells per axis of one object's grid
SUB = 2  # lattice intervals per cell edge
LATTICE_BUDGET = 800_000  # field evaluations for all grids of a scene
MARGIN = 1.25  # on the residual bound (a peak between lattice points)


class MajorantGrid:
    """The grids of a scene's heterogeneous media, packed for the kernels.

    slot_of (O, M) int32: the grid of object o, material m (-1: none); per grid g:
    origin (G,3), cell (G,3) m, dims (G,3) int64, offset (G,) into the cell arrays;
    per cell: ctrl, rad, sup (C,) densities (see the module's docstring)."""

    def __init__(self, slot_of, origin, cell, dims, offset, ctrl, rad, sup):
        self.slot_of = slot_of
        self.origin = origin
        self.cell = cell
        self.dims = dims
        self.offset = offset
        self.ctrl = ctrl
        self.rad = rad
        self.sup = sup

    @classmethod
    def build(cls, pairs, bounds, density, n_objects, n_materials):
        """pairs: [(object, material)], bounds: [(lo (3,), hi (3,))] world bounds of each
        pair's triangles; density(material, points (n,3), objects (n,)) -> (n,) the field."""
        slot_of = np.full((n_objects, n_materials), -1, np.int32)
        per = LATTICE_BUDGET / max(len(pairs), 1)
        n = int(max(4, min(GRID_CELLS, math.floor((per ** (1 / 3) - 1) / SUB))))
        L = n * SUB + 1
        origin, cell, dims, offset = [], [], [], []
        ctrl, rad, sup = [], [], []
        total = 0
        for g, ((k, m), (lo, hi)) in enumerate(zip(pairs, bounds)):
            slot_of[k, m] = g
            lo = np.asarray(lo, np.float64)
            hi = np.asarray(hi, np.float64)
            pad = 1e-3 * np.maximum(hi - lo, 1e-6) + 1e-6
            lo, hi = lo - pad, hi + pad
            axes = [np.linspace(lo[a], hi[a], L) for a in range(3)]
            P = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            v = np.asarray(density(m, P, np.full(len(P), k)), np.float64).reshape(L, L, L)
            c_lo, c_hi, step = cell_bounds(v, n)
            c = 0.5 * (c_lo + c_hi)
            origin.append(lo)
            cell.append((hi - lo) / n)
            dims.append((n, n, n))
            offset.append(total)
            ctrl.append(c.ravel())
            r = 0.5 * (c_hi - c_lo) * MARGIN + 0.5 * step
            rad.append(r.ravel())
            sup.append((c + r).ravel())
            total += n ** 3
        f = np.float64
        return cls(slot_of, np.array(origin, f).reshape(-1, 3), np.array(cell, f).reshape(-1, 3),
                   np.array(dims, np.int64).reshape(-1, 3), np.array(offset, np.int64),
                   np.concatenate(ctrl) if ctrl else np.zeros(0),
                   np.concatenate(rad) if rad else np.zeros(0),
                   np.concatenate(sup) if sup else np.zeros(0))

    def slots(self, obj, m) -> np.ndarray:
        """(K,) int64 the grids of parts in objects obj (K,) of materials m (K,)."""
        obj = np.asarray(obj, np.int64)
        m = np.asarray(m, np.int64)
        ok = (obj >= 0) & (obj < self.slot_of.shape[0]) & (m >= 0) & (m < self.slot_of.shape[1])
        out = np.full(len(obj), -1, np.int64)
        out[ok] = self.slot_of[obj[ok], m[ok]]
        return out


def cell_bounds(v, n):
    """(lo, hi, step) (n,n,n): min and max of each cell's (SUB+1)^3 lattice values v
    (L,L,L), and the largest change between two adjacent lattice points of the cell."""
    lo = _block(v, n, (SUB + 1,) * 3, np.minimum, np.inf)
    hi = _block(v, n, (SUB + 1,) * 3, np.maximum, -np.inf)
    step = np.zeros((n, n, n))
    for axis in range(3):
        ext = tuple(SUB if a == axis else SUB + 1 for a in range(3))
        step = np.maximum(step, _block(np.abs(np.diff(v, axis=axis)), n, ext, np.maximum,
                                       0.0))
    return lo, hi, step


def _block(a, n, ext, op, start):
    """op over each cell's block of a: offsets 0..ext[axis]-1 from the cell's first
    lattice index (cell i starts at i x SUB)."""
    out = np.full((n, n, n), start)
    span = n * SUB
    for i in range(ext[0]):
        for j in range(ext[1]):
            for k in range(ext[2]):
                out = op(out, a[i:i + span:SUB, j:j + span:SUB, k:k + span:SUB])
    return out


@kernel
def _cell_span(ox, oy, oz, ux, uy, uz, x, b, origin, cell, dims, g):
    """(flat cell index within grid g, the ray's parameter where it leaves that cell) for
    the point o + x u (cells clamped to the grid; outside it: the clamped cell to b)."""
    px, py, pz = ox + ux * x, oy + uy * x, oz + uz * x
    idx = 0
    t = math.inf
    for a in range(3):
        p = px if a == 0 else (py if a == 1 else pz)
        d = ux if a == 0 else (uy if a == 1 else uz)
        n = dims[g, a]
        c = cell[g, a]
        i = int(math.floor((p - origin[g, a]) / c))
        i = min(max(i, 0), n - 1)
        idx = idx * n + i
        if d > 0.0:
            t = min(t, (origin[g, a] + (i + 1) * c - p) / d)
        elif d < 0.0:
            t = min(t, (origin[g, a] + i * c - p) / d)
    small = 1e-9 * (cell[g, 0] + cell[g, 1] + cell[g, 2])
    if not t > small:
        # on a cell face (rounding) or outside the grid: step past it; beyond the grid's
        # last face the clamped cell reaches to b
        t = small if t > -small else b - x
    return idx, x + t


@kernel
def track_collisions(o, u, x, b, slot, E, origin, cell, dims, offset, ctrl, rad, smax,
                     D, hit, c_at, mu_at):
    """Residual ratio tracking's next tentative collision of each part: from x (K,) along
    o + s u (K,3) towards b (K,) in grid slot (K,), spending the unit exponential E (K,)
    at the local rate rad x smax[slot] (1/m). Adds the control density's integral over
    the distance walked to D (K,); x becomes the collision (hit True, with the cell's
    control c_at and rate mu_at) or b (hit False)."""
    for i in range(x.shape[0]):
        g = slot[i]
        xi = x[i]
        e = E[i]
        hit[i] = False
        base = offset[g]
        while xi < b[i]:
            idx, t_exit = _cell_span(o[i, 0], o[i, 1], o[i, 2], u[i, 0], u[i, 1], u[i, 2],
                                     xi, b[i], origin, cell, dims, g)
            end = min(t_exit, b[i])
            mu = rad[base + idx] * smax[g]
            c = ctrl[base + idx]
            seg = end - xi
            if mu * seg > e:
                step = e / mu
                D[i] += c * step
                xi += step
                hit[i] = True
                c_at[i] = c
                mu_at[i] = mu
                break
            e -= mu * seg
            D[i] += c * seg
            xi = end
        x[i] = min(xi, b[i])


@kernel
def sample_distances(o, u, a, b, slot, uu, origin, cell, dims, offset, sup, sbar, s_out,
                     sig_at, tau_at, tau_tot):
    """One distance per part [a, b] (K,) of o + s u (K,3) in grid slot (K,), drawn from
    the majorant sup x sbar[slot] (1/m) by inversion with the numbers uu (K,): pdf(s) =
    sig(s) exp(-tau(s)) / (1 - exp(-tau_tot)), tau the majorant's optical depth from a.
    Writes s_out (K,) (-1: the majorant is 0 along the part), sig_at (sig(s)), tau_at
    (tau(s)) and tau_tot."""
    for i in range(a.shape[0]):
        g = slot[i]
        base = offset[g]
        tot = 0.0
        xi = a[i]
        while xi < b[i]:
            idx, t_exit = _cell_span(o[i, 0], o[i, 1], o[i, 2], u[i, 0], u[i, 1], u[i, 2],
                                     xi, b[i], origin, cell, dims, g)
            end = min(t_exit, b[i])
            tot += sup[base + idx] * sbar[g] * (end - xi)
            xi = end
        tau_tot[i] = tot
        s_out[i] = -1.0
        if not tot > 0.0:
            continue
        target = -math.log1p(-uu[i] * -math.expm1(-tot))
        acc = 0.0
        xi = a[i]
        last_end, last_sig, last_acc = -1.0, 0.0, 0.0
        while xi < b[i]:
            idx, t_exit = _cell_span(o[i, 0], o[i, 1], o[i, 2], u[i, 0], u[i, 1], u[i, 2],
                                     xi, b[i], origin, cell, dims, g)
            end = min(t_exit, b[i])
            sg = sup[base + idx] * sbar[g]
            if sg > 0.0:
                if acc + sg * (end - xi) >= target:
                    s_out[i] = min(xi + (target - acc) / sg, end)
                    sig_at[i] = sg
                    tau_at[i] = target
                    break
                last_end, last_sig = end, sg
                last_acc = acc + sg * (end - xi)
            acc += sg * (end - xi)
            xi = end
        if s_out[i] < 0.0 and last_sig > 0.0:
            # (the target a rounding past the total: the last cell of positive majorant)
            s_out[i] = last_end
            sig_at[i] = last_sig
            tau_at[i] = last_acc


@register_warm_up
def _warm_up():
    """Compile (or load) the kernels on one ray through a 2^3 grid."""
    origin = np.zeros((1, 3))
    cell = np.full((1, 3), 0.5)
    dims = np.full((1, 3), 2, np.int64)
    offset = np.zeros(1, np.int64)
    vals = np.ones(8)
    o = np.array([[0.5, 0.5, -1.0]])
    u = np.array([[0.0, 0.0, 1.0]])
    a, b = np.array([1.0]), np.array([2.0])
    slot = np.zeros(1, np.int64)
    one = np.ones(1)
    x = a.copy()
    D = np.zeros(1)
    hit = np.zeros(1, np.bool_)
    c_at, mu_at = np.zeros(1), np.zeros(1)
    track_collisions(o, u, x, b, slot, one, origin, cell, dims, offset, vals, vals, one, D,
                     hit, c_at, mu_at)
    s, sig, tau, tot = np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1)
    sample_distances(o, u, a, b, slot, 0.5 * one, origin, cell, dims, offset, vals, one, s,
                     sig, tau, tot)
