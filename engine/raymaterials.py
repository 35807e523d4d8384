"""Materials per ray class: Cycles' Light Path node inside a material (lightpath40).

A Blender material may read the Light Path node (Is Camera Ray, Is Shadow Ray, ...): the
same surface is then a different closure for each kind of ray that meets it, e.g. a
window of Mix Shader(Is Shadow Ray, Glass, Transparent) is glass to the camera and to
every bounce but transparent to shadow rays, and a lamp of Mix Shader(Is Camera Ray,
Emission, Transparent) lights the room but the camera looks through it. The add-on
(addon/lightpath.py) converts such a tree once per ray class with the node's outputs set
to that class's constants; the engine Material it returns is the *diffuse* rays' one and
carries the classes that differ in `Material.ray_variants` ({"camera" | "glossy" |
"transmission" | "shadow": Material}).

Which material each ray meets (docs/compatibility.md, lightpath40, says why):
  camera rays, and their continuations through transparent surfaces   "camera"
  the camera chain's glossy reflections / transmission (refraction)   "glossy" / "transmission"
  next-event shadow rays (transparent shadows: shadowtransmittance)   "shadow"
  everything else: final-gather (diffuse) rays, photons, mesh lights   the material itself
Photons read the diffuse rays' material: a photon path read backwards is a camera path's
bounces, and the ray that meets a surface a photon meets is a diffuse, glossy or
transmission ray, never a camera or shadow ray (Cycles' Light Path reads 0 for
Is Camera Ray and Is Shadow Ray on every such ray).

The table (geometry.MaterialTable.build) appends the variants after the scene's
materials (and after the world medium's row) and keeps, per ray class that has any, a
remap (M,) int64 from a row to the row that class meets (variant rows map to
themselves). A scene without Light Path nodes has no remap: every query below answers
None and the renderer takes exactly the path it took before.
"""
from __future__ import annotations

import numpy as np

# Ray class bits (engine.geometry's, repeated here: geometry imports this module).
_CAMERA, _DIFFUSE, _GLOSSY, _TRANSMISSION, _SHADOW = 1, 2, 4, 8, 16
# Material.ray_variants keys -> the ray class bit that meets the variant.
VARIANT_CLASSES = {"camera": _CAMERA, "glossy": _GLOSSY, "transmission": _TRANSMISSION,
                   "shadow": _SHADOW}


def expand(materials: list) -> tuple[list, dict]:
    """(rows, remap): the table's materials (the given ones, then every variant of theirs)
    and {class bit: (len(rows),) int64 row the class meets} for the classes with a variant
    ({} when no material has one)."""
    rows = list(materials)
    picks = {}
    for i, m in enumerate(materials):
        for key, variant in (getattr(m, "ray_variants", None) or {}).items():
            cls = VARIANT_CLASSES[key]
            picks.setdefault(cls, {})[i] = len(rows)
            rows.append(variant)
    remap = {}
    for cls, pick in picks.items():
        r = np.arange(len(rows), dtype=np.int64)
        for i, j in pick.items():
            r[i] = j
        remap[cls] = r
    return rows, remap


def expanded_names(materials: list) -> list:
    """The names of expand(materials)'s rows (the table's names)."""
    return [m.name for m in expand(materials)[0]]


def remaps(table) -> dict:
    """{class bit: (M,) int64} of the table ({}: no Light Path variant in the scene)."""
    return getattr(table, "ray_remap", None) or {}


def triangle_materials(geo, table, cls):
    """(T,) the material row each triangle shows rays of class cls: geo.material itself
    when the class has no variant (the same array, so callers keep their fast paths)."""
    r = remaps(table).get(int(cls))
    if r is None or getattr(geo, "shared", None) is not None:
        return geo.material
    return r[np.asarray(geo.material, np.int64)].astype(geo.material.dtype)


def differs(table, cls) -> np.ndarray:
    """(M,) bool: the rows whose material rays of class cls see as another one."""
    r = remaps(table).get(int(cls))
    n = len(table.alpha)
    if r is None:
        return np.zeros(n, bool)
    return r != np.arange(n)


def remap_rows(table, cls, mats):
    """mats (any shape) material rows -> the rows class cls meets (mats itself if none)."""
    r = remaps(table).get(int(cls))
    if r is None:
        return mats
    return r[np.asarray(mats, np.int64)].astype(np.asarray(mats).dtype)


def path_materials(geo, table, prim, ray_cls):
    """(N,) the material row of each camera-chain hit prim (N,) met by a ray of class
    ray_cls (N,) or a scalar class (int32 as geo.material; misses 0), or None when every
    hit shows its triangle's own material (no variant for these classes or hits)."""
    r = remaps(table)
    if not r:
        return None
    prim = np.ascontiguousarray(prim, np.int64)
    rows, (tab,) = geo.hit_tables(prim, "material")
    ok = rows >= 0
    base = np.where(ok, np.take(np.asarray(tab), np.where(ok, rows, 0)), 0).astype(np.int64)
    cls = np.broadcast_to(np.asarray(ray_cls, np.int64), base.shape)
    out = base.copy()
    for c, remap in r.items():
        sel = (cls == c) & ok
        if sel.any():
            out[sel] = remap[base[sel]]
    if np.array_equal(out, base):
        return None
    return out.astype(np.asarray(tab).dtype)


def hit_materials(geo, table, prim, ray_cls) -> np.ndarray:
    """(N,) int64 the material row each hit prim (N,) (>= 0) shows its ray of class ray_cls:
    path_materials' rows, or the triangles' own."""
    rows = path_materials(geo, table, prim, ray_cls)
    if rows is not None:
        return np.asarray(rows, np.int64)
    idx, (tab,) = geo.hit_tables(np.ascontiguousarray(prim, np.int64), "material")
    return np.take(np.asarray(tab), idx).astype(np.int64)


def hit_tables(geo, prim, material, *names):
    """geo.hit_tables(prim, *names) with the "material" table replaced by the per-hit rows
    `material` (N,) (path_materials; None: geo.hit_tables itself). The compiled readers
    index every table by the same row: the hits' rows of the other tables are gathered
    (rows 0..N-1; misses -1), as for shared instances (engine/sharedrows.py)."""
    rows, tabs = geo.hit_tables(prim, *names)
    if material is None:
        return rows, tabs
    prim = np.asarray(prim, np.int64)
    n = len(prim)
    if getattr(geo, "shared", None) is None:
        ok = prim >= 0
        idx = np.where(ok, prim, 0)
        rows = np.where(ok, np.arange(n, dtype=np.int64), -1)
        tabs = tuple(t if name == "material" or len(t) == 0
                     else np.ascontiguousarray(np.take(t, idx, axis=0))
                     for name, t in zip(names, tabs))
    dtype = np.asarray(tabs[names.index("material")]).dtype
    per_hit = np.ascontiguousarray(material, dtype=dtype)
    return rows, tuple(per_hit if name == "material" else t for name, t in zip(names, tabs))
