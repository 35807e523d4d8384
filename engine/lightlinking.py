"""Light Linking (Blender 4.0+, Object > Shading > Light Linking) as Cycles renders it.

A light with receivers lights only those objects directly; the rest of the scene still
sees it through other surfaces (indirect light is not linked). Cycles' scheme
(intern/cycles/kernel/light/light.h, depsgraph_light_linking.cc; docs/compatibility.md,
"linking38"): every object carries a receiver light set (0: the default, lit by every
light), every emitter a membership mask of the sets it lights, and

- next-event estimation at a surface lights it only from emitters whose mask holds the
  surface object's set (light_link_receiver_nee: the shaded object; Cycles' light tree is
  specialised per set and never picks the others; here their samples are zero);
- a BSDF-sampled ray that meets a lamp (MIS) takes its light only if the lamp lights the
  object the ray left (light_link_receiver_forward: mis_ray_object); camera rays see
  every lamp (PATH_RAY_CAMERA);
- the photon map: a photon's first hit on an object its light does not link ends the
  photon there (not stored, not bounced), or the gather would carry light the object
  never received.

Here the sets are the distinct columns of the (lights x meshes) table "light i lights mesh
m", so any number of them works (Cycles stops at 64). The emissive meshes and the world
light every object (Blender links emitting objects too: the add-on warns).
"""
from __future__ import annotations

import numpy as np

from .lights import packing as pk


class LightLinks:
    """Which light lights which object, for a prepared scene.

    lit (L, M) bool: ctx.lights[i] lights scene.meshes[m] directly.
    mesh_set (M,) int64: each mesh's receiver set, sets (S, L) bool: the lights of each
    set (rows of lit's transposed distinct columns; set 0 the first mesh's)."""

    def __init__(self, lit: np.ndarray):
        self.lit = np.ascontiguousarray(lit, np.bool_)
        cols = self.lit.T
        uniq, inverse = np.unique(cols, axis=0, return_inverse=True) if len(cols) else (
            np.ones((1, self.lit.shape[0]), np.bool_), np.zeros(0, np.int64))
        self.sets = np.ascontiguousarray(uniq, np.bool_)
        self.mesh_set = np.asarray(inverse, np.int64).reshape(-1)
        self._packs = {}

    @classmethod
    def for_scene(cls, scene, lights) -> "LightLinks | None":
        """The links of the prepared lights (engine/lights/: a declared light's `source`,
        its scene Light, holds receivers and non_receivers), or None when no light is
        linked."""
        names = [m.name for m in scene.meshes]
        index = {}
        for m, name in enumerate(names):
            index.setdefault(name, []).append(m)
        M = len(names)
        rows = []
        linked = False
        for light in lights:
            row = np.ones(M, np.bool_)
            source = getattr(light, "source", None)  # the scene Light (declared lights)
            recv = getattr(source, "receivers", None)
            excl = getattr(source, "non_receivers", None) or ()
            if recv is not None:
                row[:] = False
                for name in recv:
                    row[index.get(name, [])] = True
                linked = True
            for name in excl:
                if recv is not None and name in recv:
                    continue
                row[index.get(name, [])] = False
                linked = True
            rows.append(row)
        if not linked:
            return None
        return cls(np.array(rows, np.bool_).reshape(len(lights), M))

    def receiver_set(self, geo, prim: np.ndarray) -> np.ndarray:
        """(n,) int64 receiver set of the objects hit at triangles prim (-1 or -2, a
        miss or a lamp: set of no object, -1)."""
        prim = np.asarray(prim, np.int64)
        out = np.full(len(prim), -1, np.int64)
        ok = prim >= 0
        if ok.any():
            out[ok] = self.mesh_set[object_of(geo, prim[ok])]
        return out

    def lights_hit(self, li: int, geo, prim: np.ndarray) -> np.ndarray:
        """(n,) bool: light li lights the objects of triangles prim (True where prim < 0:
        no object, Cycles' OBJECT_NONE, the default set lit by every light)."""
        prim = np.asarray(prim, np.int64)
        out = np.ones(len(prim), np.bool_)
        ok = prim >= 0
        if ok.any():
            out[ok] = self.lit[li][object_of(geo, prim[ok])]
        return out

    def packed_for(self, packed, s: int):
        """The packed lights (lights.packing.pack_lights) as receiver set s sees them:
        the lights it is not linked to with zero colour, so the shadow-ray kernel makes
        no entry (and no ray) for their samples. Cached per packing."""
        key = (id(packed), int(s))
        hit = self._packs.get(key)
        if hit is not None and hit[0] is packed:
            return hit[1]
        codes, params, mesh = packed
        off = ~self.sets[s]
        if off.any():
            params = params.copy()
            params[off, pk.RGB:pk.RGB + 3] = 0.0
        out = (codes, params, mesh)
        self._packs[key] = (packed, out)
        return out


def receiver_link(ctx, hit, rows=None):
    """directlight.direct_light's link for the hits (at rows; None: all): (ctx.links,
    the receiver set (n,) of each hit's object), or None when no light is linked
    (Cycles' light_link_receiver_nee: the shaded object)."""
    links = getattr(ctx, "links", None)
    if links is None:
        return None
    prim = hit.prim if rows is None else np.take(hit.prim, rows)
    return links, links.receiver_set(ctx.geo, prim)


def link_row_of(ctx, emitter):
    """(M,) bool: the objects a photon emitter (a light of ctx.lights or a
    lights.group.LightGroup of lights linked alike) lights; None: every object."""
    links = getattr(ctx, "links", None)
    if links is None:
        return None
    light = emitter.lights[0] if hasattr(emitter, "lights") else emitter
    # Aimed photon emitters wrap the light (visualimportance.RegionEmitter,
    # portal.PortalEmitter: .light); a declared light is known by its scene Light.
    for _ in range(4):
        inner = getattr(light, "light", None)
        if inner is None:
            break
        light = inner
    source = getattr(light, "source", None)
    for li, other in enumerate(ctx.lights):
        if other is light or (source is not None and other.source is source):
            row = links.lit[li]
            return None if row.all() else row
    return None


def unlinked_first_hits(geo, link_row, geom, prim32, starts) -> int:
    """Turn the photons' first hits on objects their light does not light into misses:
    geom (m,) int32 Embree geometry ids (-1: a miss) set to -1 there, in place. Returns
    how many."""
    ok = np.nonzero(geom >= 0)[0]
    if not len(ok):
        return 0
    prim = np.take(starts, geom[ok]).astype(np.int64) + prim32[ok]
    cut = ok[~link_row[object_of(geo, prim)]]
    geom[cut] = -1
    return len(cut)


def object_of(geo, prim: np.ndarray) -> np.ndarray:
    """Object (scene mesh) index of triangles prim >= 0, shared instances included."""
    rows, (object_id,) = geo.hit_tables(prim, "object_id")
    return np.take(object_id, rows).astype(np.int64)
