"""Voxel grids of Volume objects (OpenVDB smoke, fire, clouds; Mesh to Volume): a grid
sampled on a regular lattice of its voxel centres, read by the material's nodes at points
inside the volume with trilinear interpolation.

Cycles renders a Volume object as a heterogeneous medium whose Principled Volume
Density multiplies the object's "density" grid and whose Attribute / Volume Info nodes
read named grids ("density", "temperature", "flame", "color", any other), each sampled
with linear interpolation by default (Cycles' image_vdb.cpp loads the grid into a
NanoVDB texture; kernel_tex_image_interp_3d interpolates trilinearly between voxel
centres, the integer points of the grid's index space). Outside the active voxels a
grid reads its background value, 0 for the grids Blender makes and the ones smoke
solvers write.

The add-on (addon/volumegrids.py) samples each grid the material reads at the voxel
centres of one lattice per object (the grid's own voxels, coarser when the lattice
would exceed a memory budget), one background voxel of padding on every side, so the
interpolated field falls to 0 at the lattice's faces; the medium's boundary
(heterogeneous.py's triangles) is the box of the grid's active voxels, padded as Cycles
pads its volume mesh (addon/volumegrids.active_box); where it reaches past the lattice
the grid reads its background 0.

`VoxelGrid` holds one grid's lattice values and its index -> world map; `GridAttribute`
is the shader node (engine/shadernodes.py terms: evaluate(geo, prim, u, v)) that reads
a named grid of the point's object (Geometry.volume_grids / PointGeometry.volume_grids:
{object: {name: VoxelGrid}}), `missing` where the object has no such grid.
`field_bounds` bounds a density tree of such nodes over boxes (the majorant cells of
engine/majorant.py: the largest and smallest voxels under each cell, which a lattice of
samples would miss on a fine grid).
"""
from __future__ import annotations

import numpy as np

_LUMA = np.array([0.2126, 0.7152, 0.0722])


class VoxelGrid:
    """One grid on a lattice of voxel centres.

    values: (nx, ny, nz) float32 (a scalar grid) or (nx, ny, nz, 3) (a vector / colour
    grid); index_to_world: (4,4) the world position of lattice index (i, j, k) (the
    grid's transform, the lattice's stride and origin and the object's matrix; m).
    name: the grid's name (for warnings)."""

    def __init__(self, values, index_to_world, name: str = ""):
        v = np.asarray(values, np.float32)
        if v.ndim not in (3, 4) or (v.ndim == 4 and v.shape[3] != 3):
            raise ValueError(f"grid '{name}': values must be (nx,ny,nz) or (nx,ny,nz,3), "
                             f"got {v.shape}")
        if min(v.shape[:3]) < 2:
            # (a single voxel: padded to 2 along that axis with the background 0)
            pad = [(0, max(0, 2 - s)) for s in v.shape[:3]] + [(0, 0)] * (v.ndim - 3)
            v = np.pad(v, pad)
        self.values = np.ascontiguousarray(v)
        self.index_to_world = np.asarray(index_to_world, np.float64).reshape(4, 4)
        self.world_to_index = np.linalg.inv(self.index_to_world)
        self.name = name

    @property
    def shape(self):
        return self.values.shape[:3]

    @property
    def channels(self) -> int:
        return 1 if self.values.ndim == 3 else 3

    def to_index(self, points) -> np.ndarray:
        """(n,3) lattice index coordinates of world points (n,3)."""
        p = np.asarray(points, np.float64)
        W = self.world_to_index
        return p @ W[:3, :3].T + W[:3, 3]

    def sample(self, points) -> np.ndarray:
        """Trilinear interpolation at world points (n,3): (n,) for a scalar grid, (n,3)
        for a vector grid; 0 outside the lattice (the background)."""
        x = self.to_index(points)
        n = len(x)
        dims = np.array(self.shape)
        inside = np.all((x >= 0.0) & (x <= dims - 1), axis=1)
        out = np.zeros((n,) if self.channels == 1 else (n, 3))
        if not inside.any():
            return out
        xi = x[inside]
        i0 = np.minimum(np.floor(xi).astype(np.int64), dims - 2)
        f = xi - i0
        v = self.values
        acc = 0.0
        for dx in (0, 1):
            wx = f[:, 0] if dx else 1.0 - f[:, 0]
            for dy in (0, 1):
                wy = f[:, 1] if dy else 1.0 - f[:, 1]
                for dz in (0, 1):
                    wz = f[:, 2] if dz else 1.0 - f[:, 2]
                    w = wx * wy * wz
                    val = v[i0[:, 0] + dx, i0[:, 1] + dy, i0[:, 2] + dz].astype(np.float64)
                    acc = acc + (w[:, None] * val if val.ndim == 2 else w * val)
        out[inside] = acc
        return out

    def corners(self) -> np.ndarray:
        """(8,3) world corners of the lattice's box (index 0 .. n-1 on each axis)."""
        hi = np.array(self.shape, np.float64) - 1.0
        c = np.array([[i, j, k] for i in (0.0, hi[0]) for j in (0.0, hi[1])
                      for k in (0.0, hi[2])])
        M = self.index_to_world
        return c @ M[:3, :3].T + M[:3, 3]

    def scalar(self) -> np.ndarray:
        """(nx,ny,nz) the grid as a value: a vector grid's channel average (Cycles'
        float3 attribute read as a float)."""
        return self.values if self.values.ndim == 3 else self.values.mean(axis=3)

    def box_ranges(self, lo, hi, luminance: bool = False):
        """(lo (C,), hi (C,)) the smallest and largest value the interpolated grid takes
        in each world box [lo_c, hi_c] (C,3): the voxels whose trilinear footprint meets
        the box (their extremes bound the interpolant); a box wholly beyond the
        lattice reads 0. A box's part beyond it reads 0 too, which the lower bound
        leaves out: the residual tracking stays unbiased with it (engine/majorant.py),
        and the upper bound, which the distance sampling needs, holds. luminance: a vector grid read through Rec.709
        weights (a colour into a value socket)."""
        lo = np.asarray(lo, np.float64)
        hi = np.asarray(hi, np.float64)
        C = len(lo)
        s = self.values if self.values.ndim == 3 else (
            self.values @ _LUMA.astype(np.float32) if luminance else self.scalar())
        # the box's corners in index space: their bounding box, widened to whole voxels
        corners = np.stack([np.where(np.array([a, b, c], bool), hi, lo)
                            for a in (0, 1) for b in (0, 1) for c in (0, 1)], axis=1)
        idx = corners.reshape(-1, 3) @ self.world_to_index[:3, :3].T + self.world_to_index[:3, 3]
        idx = idx.reshape(C, 8, 3)
        dims = np.array(self.shape)
        a = np.floor(idx.min(axis=1)).astype(np.int64)
        b = np.floor(idx.max(axis=1)).astype(np.int64) + 1
        a = np.clip(a, 0, dims - 1)
        b = np.clip(b, 0, dims - 1)
        empty = np.any(idx.max(axis=1) < 0, axis=1) | np.any(idx.min(axis=1) > dims - 1,
                                                              axis=1)
        out_lo = np.zeros(C)
        out_hi = np.zeros(C)
        # Per box: a block reduction; boxes of one majorant grid are few (<= 32^3).
        for c in np.flatnonzero(~empty):
            blk = s[a[c, 0]:b[c, 0] + 1, a[c, 1]:b[c, 1] + 1, a[c, 2]:b[c, 2] + 1]
            out_lo[c] = float(blk.min())
            out_hi[c] = float(blk.max())
        return out_lo, out_hi


class GridAttribute:
    """Attribute / Volume Info / Principled Volume attribute node reading a named voxel
    grid of the point's object (Cycles' svm_node_attr on a volume: the grid
    interpolated at the point). output FAC (a value: a vector grid's channel average),
    COLOR / VECTOR ((N,3): a scalar grid repeated) or ALPHA (1 where the grid exists).
    missing: the value where the object has no grid of that name (0 for an Attribute
    node, as Cycles' attribute not found; 1 for the Principled Volume's Density /
    Temperature Attribute, which Cycles then leaves out of the product)."""

    def __init__(self, name: str, output: str = "FAC", missing: float = 0.0):
        if output not in ("FAC", "COLOR", "VECTOR", "ALPHA"):
            raise ValueError(f"GridAttribute output {output!r}: expected FAC, COLOR, "
                             "VECTOR or ALPHA")
        self.name = str(name)
        self.output = output
        self.missing = float(missing)

    def _objects(self, geo, prim):
        obj = getattr(geo, "obj", None)
        if obj is None:
            obj = getattr(geo, "object_id", None)
        if obj is None:
            return np.full(len(prim), -1, np.int64)
        return np.asarray(obj, np.int64)[prim]

    def evaluate(self, geo, prim, u, v):
        prim = np.asarray(prim, np.int64)
        n = len(prim)
        width = 1 if self.output in ("FAC", "ALPHA") else 3
        out = np.full((n,) if width == 1 else (n, 3), self.missing)
        grids = None if geo is None else getattr(geo, "volume_grids", None)
        if not grids or n == 0:
            return out
        obj = self._objects(geo, prim)
        p = None
        for k in np.unique(obj):
            g = (grids.get(int(k)) or {}).get(self.name)
            if g is None:
                continue
            sel = obj == k
            if self.output == "ALPHA":
                out[sel] = 1.0
                continue
            if p is None:
                p = (geo.hit_points(prim, np.asarray(u, np.float64), np.asarray(v, np.float64))
                     + np.asarray(geo.offset, np.float64))
            val = g.sample(p[sel])
            if width == 1:
                out[sel] = val if val.ndim == 1 else val.mean(axis=1)
            else:
                out[sel] = val[:, None] if val.ndim == 1 else val
        return out


def field_bounds(node, obj: int, grids: dict, lo, hi):
    """(lo (C,), hi (C,)) bounds of a density tree's value over world boxes [lo, hi]
    (C,3) of object obj (grids: {name: VoxelGrid} of that object), or None when the tree
    holds a node this does not bound (the caller then keeps its sampled bounds).
    Bounded: constants, GridAttribute (FAC, or a scalar grid's COLOR / VECTOR read as a
    value), Math ADD / SUBTRACT / MULTIPLY / MAXIMUM / MINIMUM of bounded operands
    (interval arithmetic)."""
    from .shadernodes import Math
    C = len(lo)
    if not hasattr(node, "evaluate"):
        c = np.asarray(node, np.float64)
        val = float(c) if c.ndim == 0 else float(c[:3] @ _LUMA)
        return np.full(C, val), np.full(C, val)
    if isinstance(node, GridAttribute):
        g = grids.get(node.name)
        if g is None:
            m = node.missing if node.output != "ALPHA" else node.missing
            return np.full(C, m), np.full(C, m)
        if node.output == "ALPHA":
            return np.ones(C), np.ones(C)
        # (a colour into a value socket: shadernodes._eval's luminance)
        return g.box_ranges(lo, hi, luminance=node.output != "FAC")
    if isinstance(node, Math) and node.operation in ("ADD", "SUBTRACT", "MULTIPLY",
                                                     "MAXIMUM", "MINIMUM") and not node.clamp:
        a = field_bounds(node.a, obj, grids, lo, hi)
        b = field_bounds(node.b, obj, grids, lo, hi)
        if a is None or b is None:
            return None
        (al, ah), (bl, bh) = a, b
        op = node.operation
        if op == "ADD":
            return al + bl, ah + bh
        if op == "SUBTRACT":
            return al - bh, ah - bl
        if op == "MAXIMUM":
            return np.maximum(al, bl), np.maximum(ah, bh)
        if op == "MINIMUM":
            return np.minimum(al, bl), np.minimum(ah, bh)
        prods = np.stack([al * bl, al * bh, ah * bl, ah * bh])
        return prods.min(axis=0), prods.max(axis=0)
    return None


def grid_nodes(node) -> list:
    """The GridAttribute nodes of a node tree (inputs followed through any node's
    attributes, lists included)."""
    out, seen, stack = [], set(), [node]
    while stack:
        n = stack.pop()
        if id(n) in seen or not hasattr(n, "evaluate"):
            continue
        seen.add(id(n))
        if isinstance(n, GridAttribute):
            out.append(n)
            continue
        for v in vars(n).values():
            if hasattr(v, "evaluate"):
                stack.append(v)
            elif isinstance(v, (list, tuple)):
                stack.extend(x for x in v if hasattr(x, "evaluate"))
    return out


def occupied(node, grids: dict, lo, hi) -> np.ndarray | None:
    """(C,) bool: world boxes [lo, hi] (C,3) where a grid the tree reads has a nonzero
    voxel under the box (the tree may be nonzero there whatever a lattice of samples
    read); None when the tree reads no grid of the object."""
    found = [g for g in (grids.get(n.name) for n in grid_nodes(node)) if g is not None]
    if not found:
        return None
    occ = np.zeros(len(lo), bool)
    for g in found:
        a, b = g.box_ranges(lo, hi)
        occ |= (a != 0.0) | (b != 0.0)
    return occ
