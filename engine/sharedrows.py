"""Hit tables of instanced geometry stored once per prototype (issue 16).

When instances are traced two-level (engine/instancing.py, chosen by
engine/resources.two_level_instances), engine/geometry.prepare keeps the triangles of no
instance in ordinary tables and, for the instanced triangles, one object-space table per
prototype (positions as v0, e1, e2; corner normals; UVs; colours; material slot per
triangle; smoothness) plus per instance its matrix, material slots, object, visibility and
holdout. The merged table's row numbering is unchanged: an instance's triangles are the
rows [base, base + F) in the prototype's face order, which is what two-level tracing
returns as prim. SharedRows.column(name, prim) is the one place that turns such rows into
world-space values:

- points by M (re-centred world = M[:, :3] p + M[:, 3]); edges by M[:, :3];
- normals by the inverse transpose of M[:, :3], renormalised;
- mirrored instances (det M < 0) keep the expanded copies' convention (corners 0, 2, 1):
  e1 and e2 swap, and so do corners 1 and 2 of every per-corner value;
- material = the instance's material slots (Mesh.materials) at the prototype row's slot.

Memory: the tables of one prototype (what an expanded copy costs, ~150 B a triangle) plus
~150 B per instance, instead of the tables of every copy (docs/performance.md,
"Instancing").
"""
from __future__ import annotations

import numpy as np

from .sampling import normalize

PIECE_ROWS = 1 << 16  # rows gathered at once when a whole column is read


class SharedRows:
    """Row lookup for a Geometry whose instanced rows are shared (module docstring).

    segments: per mesh with triangles, in row order: start row, kind (-1: static rows,
    else the instance index) and, for static segments, the first row in the static
    tables. static: dict name -> (S, ...) arrays of the triangles of no instance, in row
    order. tables: dict name -> per-prototype-table arrays concatenated (rows of table k
    start at table_start[k]). Per instance: table (I,) int, to_world (I,3,4) re-centred,
    flip (I,) bool, slots (I,K) int32 material indices per material slot (padded with
    -1), object_id, visibility, holdout (I,)."""

    def __init__(self, count, seg_start, seg_kind, seg_static, static, tables, table_start,
                 table, to_world, flip, slots, object_id, visibility, holdout):
        self.count = int(count)
        self.seg_start = np.asarray(seg_start, np.int64)
        self.seg_kind = np.asarray(seg_kind, np.int64)
        self.seg_static = np.asarray(seg_static, np.int64)
        self.static = static
        self.tables = tables
        self.table_start = np.asarray(table_start, np.int64)
        self.table = np.asarray(table, np.int64)
        self.to_world = np.asarray(to_world, np.float64)
        A = self.to_world[:, :, :3]
        # Normals go by the inverse transpose; a singular instance (flat, never hit: two-
        # level tracing leaves it out) gets zeros, which normalise to the fallback below.
        det = np.linalg.det(A) if len(A) else np.zeros(0)
        ok = np.isfinite(det) & (np.abs(det) > 0)
        self.normal_matrix = np.zeros_like(A)
        if ok.any():
            self.normal_matrix[ok] = np.transpose(np.linalg.inv(A[ok]), (0, 2, 1))
        self.flip = np.asarray(flip, bool)
        self.slots = np.asarray(slots, np.int32)
        self.object_id = np.asarray(object_id, np.int32)
        self.visibility = np.asarray(visibility, np.uint8)
        self.holdout = np.asarray(holdout, bool)

    @property
    def nbytes(self) -> int:
        arrays = [*self.static.values(), *self.tables.values(), self.to_world,
                  self.normal_matrix, self.slots]
        return int(sum(a.nbytes for a in arrays if a is not None))

    def locate(self, prim):
        """(inst, static_row, table_row, instance) for rows prim (N,) int64 >= 0: inst
        (N,) bool marks instanced rows; static_row indexes the static tables (where not
        inst), table_row the concatenated prototype tables and instance the instance
        (where inst; 0 elsewhere)."""
        seg = np.searchsorted(self.seg_start, prim, side="right") - 1
        local = prim - self.seg_start[seg]
        kind = self.seg_kind[seg]
        inst = kind >= 0
        instance = np.where(inst, kind, 0)
        static_row = np.where(inst, 0, self.seg_static[seg] + local)
        table_row = np.where(inst, self.table_start[self.table[instance]] + local, 0)
        return inst, static_row, table_row, instance

    def column(self, name, prim):
        """World-space values of column `name` at rows prim (N,) int (module docstring):
        (N, ...) with the static table's dtype."""
        prim = np.asarray(prim, np.int64).reshape(-1)
        st = self.static[name]
        out = np.empty((len(prim),) + st.shape[1:], st.dtype)
        if not len(prim):
            return out
        inst, srow, trow, which = self.locate(prim)
        s = ~inst
        if s.any():
            out[s] = np.take(st, srow[s], axis=0)
        if not inst.any():
            return out
        i = which[inst]
        r = trow[inst]
        flip = self.flip[i]
        if name in ("object_id", "visibility", "holdout"):
            out[inst] = getattr(self, name)[i]
        elif name == "material":
            out[inst] = self.slots[i, np.take(self.tables["slot"], r)]
        elif name == "smooth":
            out[inst] = np.take(self.tables["smooth"], r)
        elif name in ("v0", "e1", "e2"):
            if name != "v0":
                # Mirrored copies have corners (0, 2, 1): their edges swap.
                other = "e2" if name == "e1" else "e1"
                x = np.where(flip[:, None], np.take(self.tables[other], r, axis=0),
                             np.take(self.tables[name], r, axis=0))
            else:
                x = np.take(self.tables["v0"], r, axis=0)
            M = self.to_world[i]
            y = np.einsum("nij,nj->ni", M[:, :, :3], x)
            if name == "v0":
                y += M[:, :, 3]
            out[inst] = y
        else:
            c = np.take(self.tables[name], r, axis=0)   # (n,3,C) per corner
            c = np.where(flip[:, None, None], c[:, [0, 2, 1]], c)
            if name == "corner_normals":
                N = self.normal_matrix[i]
                w = normalize(np.einsum("nij,nkj->nki", N, c.astype(np.float64)))
                c = w
            out[inst] = c
        return out


    def full_column(self, name):
        """The whole (T, ...) column `name`, built a segment (mesh) at a time: static
        rows copied, per-instance values filled, instanced rows placed per instance."""
        st = self.static[name]
        out = np.empty((self.count,) + st.shape[1:], st.dtype)
        ends = np.append(self.seg_start[1:], self.count)
        for a, b, kind, first in zip(self.seg_start, ends, self.seg_kind, self.seg_static):
            if kind < 0:
                out[a:b] = st[first:first + (b - a)]
            elif name in ("object_id", "visibility", "holdout"):
                out[a:b] = getattr(self, name)[kind]
            elif name == "material":
                t0 = self.table_start[self.table[kind]]
                out[a:b] = self.slots[kind][self.tables["slot"][t0:t0 + (b - a)]]
            else:
                out[a:b] = self.column(name, np.arange(a, b))
        return out

    def rows_of(self, materials) -> np.ndarray:
        """(R,) int64 the rows, ascending, whose material is in `materials` (material
        indices): static rows by the static table, an instance's rows where its
        material slot at the prototype row's slot is one of them (only the segments
        that hold one are visited; the whole material column is never built)."""
        mats = np.asarray(sorted(int(m) for m in materials), np.int64)
        if not len(mats) or not len(self.seg_start):
            return np.zeros(0, np.int64)
        ends = np.append(self.seg_start[1:], self.count)
        static = np.isin(self.static["material"], mats)
        slot_hit = np.isin(self.slots, mats)            # (I, K): which slots are media
        kind = self.seg_kind
        inst_hit = slot_hit.any(axis=1) if len(slot_hit) else np.zeros(0, bool)
        out = []
        for s in np.flatnonzero(kind < 0):
            a, b, first = self.seg_start[s], ends[s], self.seg_static[s]
            m = static[first:first + (b - a)]
            if m.any():
                out.append(a + np.flatnonzero(m))
        for s in np.flatnonzero(kind >= 0):
            k = kind[s]
            if not inst_hit[k]:
                continue
            a, b = self.seg_start[s], ends[s]
            t0 = self.table_start[self.table[k]]
            out.append(a + np.flatnonzero(slot_hit[k][self.tables["slot"][t0:t0 + (b - a)]]))
        if not out:
            return np.zeros(0, np.int64)
        return np.sort(np.concatenate(out).astype(np.int64))

    def area_sum(self, mask) -> float:
        """Total world-space area (m^2) of the rows where mask (T,) bool is True:
        |A^-T c| |det A| / 2 per instanced row (c the object-space e1 x e2)."""
        total = 0.0
        ends = np.append(self.seg_start[1:], self.count)
        st = self.static
        cross = {}
        for a, b, kind, first in zip(self.seg_start, ends, self.seg_kind, self.seg_static):
            m = np.asarray(mask[a:b], bool)
            if not m.any():
                continue
            if kind < 0:
                r = first + np.nonzero(m)[0]
                c = np.cross(st["e1"][r], st["e2"][r])
                total += float(np.linalg.norm(c, axis=1).sum()) / 2.0
                continue
            t = int(self.table[kind])
            if t not in cross:
                t0 = self.table_start[t]
                cross[t] = np.cross(self.tables["e1"][t0:t0 + (b - a)],
                                    self.tables["e2"][t0:t0 + (b - a)])
            A = self.to_world[kind, :, :3]
            w = cross[t][m] @ self.normal_matrix[kind].T
            total += float(np.linalg.norm(w, axis=1).sum()) * abs(np.linalg.det(A)) / 2.0
        return total


class RowColumn:
    """A per-triangle column of a shared Geometry read as if it were an (T, ...) array:
    x[prim], x[mask], x[a:b], np.take(x, prim, axis=0) gather only those rows;
    np.asarray(x) builds the whole expanded column (costly: what sharing avoids; used
    only by whole-scene analyses, a piece at a time)."""

    def __init__(self, rows: SharedRows, name: str):
        self._rows = rows
        self._name = name
        st = rows.static[name]
        self.dtype = st.dtype
        self.shape = (rows.count,) + st.shape[1:]
        self.ndim = len(self.shape)

    def __len__(self) -> int:
        return self._rows.count

    def __getitem__(self, key):
        if isinstance(key, tuple):
            return np.asarray(self[key[0]])[(slice(None),) + key[1:]]
        if isinstance(key, (int, np.integer)):
            k = int(key) + (self._rows.count if key < 0 else 0)
            return self._rows.column(self._name, np.array([k]))[0]
        if isinstance(key, slice):
            if key == slice(None):
                return self._rows.full_column(self._name)
            idx = np.arange(self._rows.count)[key]
        else:
            key = np.asarray(key)
            idx = np.nonzero(key)[0] if key.dtype == np.bool_ else key.astype(np.int64)
        flat = idx.reshape(-1)
        if len(flat) <= PIECE_ROWS:
            out = self._rows.column(self._name, flat)
        else:
            out = np.concatenate([self._rows.column(self._name, flat[a:a + PIECE_ROWS])
                                  for a in range(0, len(flat), PIECE_ROWS)])
        return out.reshape(idx.shape + out.shape[1:])

    def take(self, indices, axis=None, out=None, mode="raise"):
        if out is not None or mode != "raise" or axis not in (0, None):
            raise ValueError("RowColumn.take: only axis=0 without out or mode")
        return self[np.asarray(indices)]

    def __array__(self, dtype=None, copy=None):
        out = self._rows.full_column(self._name)
        return out if dtype is None else out.astype(dtype)

    def any(self):
        rows = self._rows
        if self._name in ("object_id", "visibility", "holdout"):
            return bool(rows.static[self._name].any() or getattr(rows, self._name).any())
        return bool(np.asarray(self).any())

    # Whole-column comparisons build the column (never an identity test by mistake).
    def __eq__(self, other):
        return np.asarray(self) == other

    def __ne__(self, other):
        return np.asarray(self) != other

    def __lt__(self, other):
        return np.asarray(self) < other

    def __le__(self, other):
        return np.asarray(self) <= other

    def __gt__(self, other):
        return np.asarray(self) > other

    def __ge__(self, other):
        return np.asarray(self) >= other

    def __and__(self, other):
        return np.asarray(self) & other

    def __or__(self, other):
        return np.asarray(self) | other

    def astype(self, dtype, copy=True):
        return np.asarray(self).astype(dtype)

    __hash__ = None


__all__ = ["SharedRows", "RowColumn", "PIECE_ROWS"]
